#include "clod_haptics/device/simulated_device.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <sstream>

namespace clod_haptics {
namespace device {

namespace {
double steadySeconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}
}  // namespace

SimulatedDevice::SimulatedDevice(std::vector<ScriptSample> script, bool loop, Clock clock)
    : script_(std::move(script)), loop_(loop), clock_(std::move(clock)) {
  if (script_.empty()) throw DeviceError("simulated device: the motion script is empty");
  for (std::size_t i = 0; i < script_.size(); ++i) {
    const ScriptSample& s = script_[i];
    if (!std::isfinite(s.time) || !s.position.allFinite() || !s.orientation.coeffs().allFinite() ||
        s.orientation.norm() < 1e-9) {
      throw DeviceError("simulated device: keyframe " + std::to_string(i) + " is not finite");
    }
    if (i > 0 && !(s.time > script_[i - 1].time)) {
      throw DeviceError("simulated device: keyframe times must increase (keyframe " + std::to_string(i) + ")");
    }
    script_[i].orientation.normalize();
  }
  // Scripts start at time zero, whatever their first keyframe says.
  const double t0 = script_.front().time;
  for (ScriptSample& s : script_) s.time -= t0;
}

double SimulatedDevice::now() const { return clock_ ? clock_() : steadySeconds(); }

void SimulatedDevice::start() {
  startTime_ = now();
  running_ = true;
}

void SimulatedDevice::stop() {
  if (running_) commandForce(Eigen::Vector3d::Zero());
  running_ = false;
}

DeviceState SimulatedDevice::sample(double t) const {
  DeviceState state;
  const double duration = script_.back().time;
  if (loop_ && duration > 0.0) {
    t = std::fmod(t, duration);
    if (t < 0.0) t += duration;
  }
  t = std::clamp(t, 0.0, duration);
  auto upper = std::upper_bound(script_.begin(), script_.end(), t,
                                [](double value, const ScriptSample& s) { return value < s.time; });
  if (upper == script_.end()) {
    const ScriptSample& last = script_.back();
    state.position = last.position;
    state.orientation = last.orientation;
    state.buttons = last.buttons;
  } else {
    const ScriptSample& b = *upper;
    const ScriptSample& a = *(upper - 1);  // upper > begin because t >= 0 = first time
    const double u = (t - a.time) / (b.time - a.time);
    state.position = a.position + u * (b.position - a.position);
    state.orientation = a.orientation.slerp(u, b.orientation);
    state.buttons = a.buttons;  // buttons switch at keyframes
  }
  state.time = t;
  return state;
}

bool SimulatedDevice::read(DeviceState& state) {
  if (!running_) return false;
  const double t = now() - startTime_;
  state = sample(t);
  state.time = t;
  return true;
}

void SimulatedDevice::commandForce(const Eigen::Vector3d& force) {
  const double t = running_ ? now() - startTime_ : 0.0;
  std::lock_guard<std::mutex> lock(forcesMutex_);
  if (forces_.size() >= maxRecorded) forces_.erase(forces_.begin(), forces_.begin() + maxRecorded / 2);
  RecordedForce record;
  record.time = t;
  record.force = force;
  forces_.push_back(record);
  lastForce_ = force;
  ++forceCount_;
}

std::vector<RecordedForce> SimulatedDevice::recordedForces() const {
  std::lock_guard<std::mutex> lock(forcesMutex_);
  return forces_;
}

Eigen::Vector3d SimulatedDevice::lastForce() const {
  std::lock_guard<std::mutex> lock(forcesMutex_);
  return lastForce_;
}

std::size_t SimulatedDevice::forceCount() const {
  std::lock_guard<std::mutex> lock(forcesMutex_);
  return forceCount_;
}

std::vector<ScriptSample> SimulatedDevice::circleScript(const Eigen::Vector3d& centre, double radius, double period,
                                                        int keyframes) {
  if (!(radius >= 0.0) || !(period > 0.0) || keyframes < 2 || !centre.allFinite()) {
    throw DeviceError("simulated device: a circle needs a finite centre, radius >= 0, period > 0");
  }
  std::vector<ScriptSample> script(static_cast<std::size_t>(keyframes) + 1);
  for (int i = 0; i <= keyframes; ++i) {
    const double a = 2.0 * M_PI * i / keyframes;
    script[i].time = period * i / keyframes;
    script[i].position = centre + radius * Eigen::Vector3d(std::cos(a), std::sin(a), 0.0);
  }
  return script;
}

std::vector<ScriptSample> SimulatedDevice::loadCsvScript(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw DeviceError("simulated device: cannot open motion script '" + path + "'");
  std::vector<ScriptSample> script;
  std::string line;
  int lineNumber = 0;
  while (std::getline(in, line)) {
    ++lineNumber;
    const auto hash = line.find('#');
    if (hash != std::string::npos) line.erase(hash);
    std::replace(line.begin(), line.end(), ',', ' ');
    std::istringstream fields(line);
    std::vector<double> values;
    double v;
    while (fields >> v) values.push_back(v);
    if (!fields.eof()) {
      throw DeviceError("simulated device: '" + path + "' line " + std::to_string(lineNumber) +
                        ": not a number (expected t, x, y, z[, buttons])");
    }
    if (values.empty()) continue;
    if (values.size() != 4 && values.size() != 5) {
      throw DeviceError("simulated device: '" + path + "' line " + std::to_string(lineNumber) + ": " +
                        std::to_string(values.size()) + " values, expected t, x, y, z[, buttons]");
    }
    ScriptSample s;
    s.time = values[0];
    s.position = Eigen::Vector3d(values[1], values[2], values[3]);
    s.buttons = values.size() == 5 ? static_cast<std::uint32_t>(values[4]) : 0u;
    script.push_back(s);
  }
  if (script.empty()) throw DeviceError("simulated device: motion script '" + path + "' has no keyframe");
  return script;
}

}  // namespace device
}  // namespace clod_haptics
