#include "clod_haptics/device/force_safety.h"

#include <cmath>
#include <cstddef>
#include <stdexcept>
#include <string>

namespace clod_haptics {
namespace device {

void validate(const ForceSafetyParams& params) {
  auto check = [](double value, const char* name, bool allowZero) {
    if (!std::isfinite(value) || value < 0.0 || (!allowZero && value == 0.0)) {
      throw std::invalid_argument(std::string("force safety: ") + name + " must be finite and " +
                                  (allowZero ? "non-negative" : "positive") + ", got " + std::to_string(value));
    }
  };
  check(params.maxForce, "max_force", false);
  check(params.maxForceRate, "max_force_rate", true);
  check(params.staleTimeout, "force_timeout", false);
}

const char* toString(ForceStatus status) {
  // In the order of the enum.
  static const char* const kNames[] = {"ok", "no command", "non-finite", "stale", "clamped", "rate limited"};
  const auto i = static_cast<std::size_t>(status);
  return i < sizeof kNames / sizeof kNames[0] ? kNames[i] : "unknown";
}

ForceSafety::ForceSafety(const ForceSafetyParams& params) : params_(params) { validate(params_); }

void ForceSafety::reset() {
  last_.setZero();
  hasLast_ = false;
}

Eigen::Vector3d ForceSafety::update(const ForceCommand& command, double now, ForceStatus* status) {
  ++counters_.updates;
  ForceStatus result = ForceStatus::Ok;
  Eigen::Vector3d target = Eigen::Vector3d::Zero();
  bool dropToZero = false;
  if (!command.valid) {
    result = ForceStatus::NoCommand;
    dropToZero = true;
  } else if (!command.force.allFinite()) {
    result = ForceStatus::NonFinite;
    ++counters_.nonFinite;
    dropToZero = true;
  } else if (!(now - command.receivedAt <= params_.staleTimeout)) {
    result = ForceStatus::Stale;
    ++counters_.stale;
    dropToZero = true;
  } else {
    target = command.force;
    const double magnitude = target.norm();
    if (magnitude > params_.maxForce) {
      target *= params_.maxForce / magnitude;
      result = ForceStatus::Clamped;
      ++counters_.clamped;
    }
  }

  Eigen::Vector3d output = target;
  if (!dropToZero && params_.maxForceRate > 0.0) {
    // The first tick starts from rest; a clock that runs backwards allows no change at all.
    const Eigen::Vector3d previous = hasLast_ ? last_ : Eigen::Vector3d::Zero();
    const double dt = hasLast_ ? std::max(0.0, now - lastTime_) : 0.0;
    const double maxStep = params_.maxForceRate * dt;
    const Eigen::Vector3d step = target - previous;
    const double stepNorm = step.norm();
    if (stepNorm > maxStep) {
      output = previous + step * (maxStep / stepNorm);
      if (result == ForceStatus::Ok) result = ForceStatus::RateLimited;
      ++counters_.rateLimited;
    }
  }
  last_ = output;
  lastTime_ = now;
  hasLast_ = true;
  if (status) *status = result;
  return output;
}

}  // namespace device
}  // namespace clod_haptics
