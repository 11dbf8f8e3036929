#include "clod_haptics/ros/reconfigure_request.h"

#include <clod_haptics/DetectorConfig.h>

#include <cmath>
#include <cstdlib>
#include <map>
#include <sstream>
#include <stdexcept>

namespace clod_haptics {

namespace {

const std::map<std::string, std::string>& aliases() {
  static const std::map<std::string, std::string> a = {
      {"distance", "clustering_distance"}, {"radius", "pointer_radius"}, {"mode", "detection_mode"}};
  return a;
}

template <class T>
const T* find(const std::vector<T>& values, const std::string& name) {
  for (const T& v : values)
    if (v.name == name) return &v;
  return nullptr;
}

double parseNumber(const std::string& name, const std::string& text) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0' || !std::isfinite(v))
    throw std::invalid_argument(name + ": '" + text + "' is not a finite number");
  return v;
}

void checkRange(const std::string& name, double v, double lo, double hi) {
  if (v < lo || v > hi) {
    std::ostringstream s;
    s << name << ": " << v << " outside [" << lo << ", " << hi << "]";
    throw std::invalid_argument(s.str());
  }
}

void addValue(const dynamic_reconfigure::ParamDescription& p, const std::string& text,
              const dynamic_reconfigure::ConfigDescription& d, dynamic_reconfigure::Config& out) {
  if (p.type == "bool") {
    if (text != "true" && text != "false" && text != "1" && text != "0")
      throw std::invalid_argument(p.name + ": '" + text + "' is not true or false");
    dynamic_reconfigure::BoolParameter b;
    b.name = p.name;
    b.value = text == "true" || text == "1";
    out.bools.push_back(b);
  } else if (p.type == "str") {
    dynamic_reconfigure::StrParameter s;
    s.name = p.name;
    s.value = text;
    out.strs.push_back(s);
  } else if (p.type == "int") {
    const double v = parseNumber(p.name, text);
    if (v != std::floor(v)) throw std::invalid_argument(p.name + ": '" + text + "' is not an integer");
    checkRange(p.name, v, find(d.min.ints, p.name)->value, find(d.max.ints, p.name)->value);
    dynamic_reconfigure::IntParameter i;
    i.name = p.name;
    i.value = static_cast<int>(v);
    out.ints.push_back(i);
  } else {
    const double v = parseNumber(p.name, text);
    checkRange(p.name, v, find(d.min.doubles, p.name)->value, find(d.max.doubles, p.name)->value);
    dynamic_reconfigure::DoubleParameter x;
    x.name = p.name;
    x.value = v;
    out.doubles.push_back(x);
  }
}

}  // namespace

dynamic_reconfigure::Config detectorReconfigureRequest(const std::vector<std::string>& args) {
  if (args.empty() || args.size() % 2 != 0)
    throw std::invalid_argument("expected name value pairs, got " + std::to_string(args.size()) + " words");
  const dynamic_reconfigure::ConfigDescription& d = DetectorConfig::__getDescriptionMessage__();
  dynamic_reconfigure::Config out;
  for (std::size_t k = 0; k < args.size(); k += 2) {
    const auto alias = aliases().find(args[k]);
    const std::string name = alias == aliases().end() ? args[k] : alias->second;
    const dynamic_reconfigure::ParamDescription* p = nullptr;
    std::string known;
    for (const auto& group : d.groups) {
      for (const auto& param : group.parameters) {
        if (param.name == name) p = &param;
        known += " " + param.name;
      }
    }
    if (!p) throw std::invalid_argument("unknown parameter '" + args[k] + "'; known:" + known +
                                        " (aliases: distance, radius, mode)");
    addValue(*p, args[k + 1], d, out);
  }
  return out;
}

std::string configValue(const dynamic_reconfigure::Config& config, const std::string& name) {
  if (const auto* b = find(config.bools, name)) return b->value ? "true" : "false";
  if (const auto* s = find(config.strs, name)) return s->value;
  if (const auto* i = find(config.ints, name)) return std::to_string(i->value);
  if (const auto* x = find(config.doubles, name)) {
    std::ostringstream s;
    s << x->value;
    return s.str();
  }
  return "";
}

}  // namespace clod_haptics
