#include "clod_haptics/core/sphere_set_io.h"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <sstream>

#include "clod_haptics/core/errors.h"

namespace clod_haptics {

void writeSphereSetYaml(const ClodSphereSet& set, std::ostream& out) {
  out << std::setprecision(17);
  out << "format: clod_haptics/sphere_set/2\n";
  out << "mesh: \"" << set.meshName << "\"\n";
  out << "scale: " << set.scale << "\n";
  out << "origin: [" << set.origin.x() << ", " << set.origin.y() << ", " << set.origin.z() << "]\n";
  out << "clustering_distance: " << set.distance << "\n";
  const BuildStats& s = set.stats;
  out << "stats: {triangles: " << s.triangles << ", centres: " << s.centres << ", spheres: " << s.spheres
      << ", unpaired: " << s.unpaired << ", degenerate: " << s.degenerate << ", placement_ms: " << s.placementMs
      << ", clustering_ms: " << s.clusteringMs << "}\n";
  out << "spheres:\n";
  for (std::size_t i = 0; i < set.size(); ++i) {
    const Vec3& c = set.centres[i];
    out << "  - {centre: [" << c.x() << ", " << c.y() << ", " << c.z() << "], radius: " << set.radii[i]
        << ", triangles: [";
    for (const std::uint32_t* t = set.begin(i); t != set.end(i); ++t) out << (t == set.begin(i) ? "" : ", ") << *t;
    out << "]}\n";
  }
}

void writeSphereSetYaml(const ClodSphereSet& set, const std::string& path) {
  std::ofstream out(path);
  if (!out) throw FormatError("cannot open '" + path + "' for writing");
  writeSphereSetYaml(set, out);
  out.flush();
  if (!out) throw FormatError("writing '" + path + "' failed");
}

namespace {

std::string afterKey(const std::string& line, const std::string& key, std::size_t lineNo) {
  if (line.compare(0, key.size() + 2, key + ": ") != 0)
    throw FormatError("line " + std::to_string(lineNo) + ": expected '" + key + ":'");
  return line.substr(key.size() + 2);
}

double toDouble(const std::string& text, std::size_t lineNo) {
  std::size_t used = 0;
  double v = 0.0;
  try {
    v = std::stod(text, &used);
  } catch (const std::exception&) {
    throw FormatError("line " + std::to_string(lineNo) + ": '" + text + "' is not a number");
  }
  return v;
}

// One "  - {centre: [x, y, z], radius: r, triangles: [a, b, ...]}" line, appended to set; where prefixes errors.
void readSphereLine(const std::string& line, const std::string& where, ClodSphereSet& set) {
  double x, y, z, r;
  int used = 0;
  if (std::sscanf(line.c_str(), "  - {centre: [%lf, %lf, %lf], radius: %lf, triangles: [%n", &x, &y, &z, &r, &used) !=
          4 ||
      used == 0)
    throw FormatError(where + "malformed sphere");
  if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z)) throw FormatError(where + "non-finite centre");
  if (!std::isfinite(r) || r < 0.0) throw FormatError(where + "radius must be finite and >= 0");
  set.centres.emplace_back(x, y, z);
  set.radii.push_back(r);
  std::istringstream list(line.substr(static_cast<std::size_t>(used)));
  std::string item;
  bool closed = false;
  while (std::getline(list, item, ',')) {
    const std::size_t end = item.find(']');
    std::string number = item.substr(0, end);
    number.erase(0, number.find_first_not_of(' '));
    number.erase(number.find_last_not_of(' ') + 1);
    if (!number.empty()) {
      if (number.find_first_not_of("0123456789") != std::string::npos || number.size() > 10)
        throw FormatError(where + "triangle index '" + number + "' is not an unsigned integer");
      const unsigned long long index = std::stoull(number);
      if (index > 0xffffffffull) throw FormatError(where + "triangle index " + number + " out of range");
      set.triangles.push_back(static_cast<std::uint32_t>(index));
    }
    if (end != std::string::npos) {
      closed = true;
      break;
    }
  }
  if (!closed) throw FormatError(where + "unterminated triangle list");
  set.offsets.push_back(static_cast<std::uint32_t>(set.triangles.size()));
}

}  // namespace

ClodSphereSet readSphereSetYaml(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw FormatError("cannot open '" + path + "'");
  ClodSphereSet set;
  std::string line;
  std::size_t lineNo = 0;
  auto next = [&]() {
    if (!std::getline(in, line)) throw FormatError(path + ": ends early after line " + std::to_string(lineNo));
    ++lineNo;
  };
  next();
  // Version 1 had no origin line: its centres are in the model frame, a zero origin.
  const bool hasOrigin = line == "format: clod_haptics/sphere_set/2";
  if (!hasOrigin && line != "format: clod_haptics/sphere_set/1")
    throw FormatError(path + ": not a clod_haptics sphere set");
  next();
  std::string mesh = afterKey(line, "mesh", lineNo);
  if (mesh.size() >= 2 && mesh.front() == '"' && mesh.back() == '"') mesh = mesh.substr(1, mesh.size() - 2);
  set.meshName = mesh;
  next();
  set.scale = toDouble(afterKey(line, "scale", lineNo), lineNo);
  next();
  if (hasOrigin) {
    const std::string origin = afterKey(line, "origin", lineNo);
    int used = 0;
    if (std::sscanf(origin.c_str(), "[%lf, %lf, %lf]%n", &set.origin.x(), &set.origin.y(), &set.origin.z(), &used) !=
            3 ||
        used != static_cast<int>(origin.size()) || !set.origin.allFinite())
      throw FormatError(path + ": line " + std::to_string(lineNo) + ": malformed origin");
    next();
  }
  set.distance = toDouble(afterKey(line, "clustering_distance", lineNo), lineNo);
  next();
  const std::string stats = afterKey(line, "stats", lineNo);
  std::size_t triangleCount = 0;
  {
    unsigned long long n = 0;
    if (std::sscanf(stats.c_str(), "{triangles: %llu", &n) == 1) triangleCount = static_cast<std::size_t>(n);
  }
  next();
  if (line != "spheres:") throw FormatError(path + ": line " + std::to_string(lineNo) + ": expected 'spheres:'");
  while (std::getline(in, line)) {
    ++lineNo;
    if (!line.empty()) readSphereLine(line, path + ": line " + std::to_string(lineNo) + ": ", set);
  }
  if (triangleCount > 0)
    for (std::uint32_t t : set.triangles)
      if (t >= triangleCount)
        throw FormatError(path + ": triangle index " + std::to_string(t) + " >= the mesh's " +
                          std::to_string(triangleCount) + " triangles");
  set.stats.spheres = set.size();
  set.stats.triangles = triangleCount;
  return set;
}

}  // namespace clod_haptics
