#include "clod_haptics/device/stylus_trajectory.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace clod_haptics {
namespace device {

Eigen::Quaterniond WorkspaceTransform::fromRpy(double roll, double pitch, double yaw) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                            Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                            Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()));
}

StylusTrajectory::StylusTrajectory(StylusSamples samples) {
  const std::size_t input = samples.size();
  samples.erase(std::remove_if(samples.begin(), samples.end(),
                               [](const StylusSample& s) {
                                 return !std::isfinite(s.time) || !s.position.allFinite() ||
                                        !s.orientation.coeffs().allFinite() || s.orientation.norm() < 1e-9;
                               }),
                samples.end());
  std::stable_sort(samples.begin(), samples.end(),
                   [](const StylusSample& a, const StylusSample& b) { return a.time < b.time; });
  samples.erase(std::unique(samples.begin(), samples.end(),
                            [](const StylusSample& a, const StylusSample& b) { return a.time == b.time; }),
                samples.end());
  if (samples.empty()) throw std::invalid_argument("stylus trajectory: no valid sample");
  const double t0 = samples.front().time;
  for (StylusSample& s : samples) {
    s.time -= t0;
    s.orientation.normalize();
  }
  dropped_ = input - samples.size();
  samples_ = std::move(samples);
}

double StylusTrajectory::meanRate() const {
  return samples_.size() < 2 || duration() <= 0.0 ? 0.0 : (samples_.size() - 1) / duration();
}

StylusSample StylusTrajectory::at(double t) const {
  if (samples_.empty()) return StylusSample{};
  t = std::clamp(t, 0.0, duration());
  auto upper = std::upper_bound(samples_.begin(), samples_.end(), t,
                                [](double value, const StylusSample& s) { return value < s.time; });
  if (upper == samples_.end()) {
    StylusSample s = samples_.back();
    s.time = t;
    return s;
  }
  const StylusSample& b = *upper;
  const StylusSample& a = *(upper - 1);
  const double u = (t - a.time) / (b.time - a.time);
  StylusSample s;
  s.time = t;
  s.position = a.position + u * (b.position - a.position);
  s.orientation = a.orientation.slerp(u, b.orientation);
  return s;
}

StylusTrajectory StylusTrajectory::resampled(double rate) const {
  if (!std::isfinite(rate) || rate <= 0.0) throw std::invalid_argument("stylus trajectory: rate must be positive");
  const auto count = static_cast<std::size_t>(std::floor(duration() * rate + 1e-9)) + 1;
  StylusSamples out;
  out.reserve(count);
  for (std::size_t k = 0; k < count; ++k) out.push_back(at(static_cast<double>(k) / rate));
  StylusTrajectory result;
  result.samples_ = std::move(out);
  result.dropped_ = dropped_;
  return result;
}

StylusTrajectory StylusTrajectory::transformed(const WorkspaceTransform& transform) const {
  StylusTrajectory result = *this;
  for (StylusSample& s : result.samples_) {
    s.position = transform.apply(s.position);
    s.orientation = (transform.rotation * s.orientation).normalized();
  }
  return result;
}

Eigen::AlignedBox3d StylusTrajectory::bounds() const {
  Eigen::AlignedBox3d box;
  for (const StylusSample& s : samples_) box.extend(s.position);
  return box;
}

WorkspaceTransform StylusTrajectory::fitInto(const Eigen::Vector3d& centre, double size,
                                             const Eigen::Quaterniond& rotation) const {
  if (!std::isfinite(size) || size <= 0.0 || !centre.allFinite()) {
    throw std::invalid_argument("stylus trajectory: fit size must be positive and the centre finite");
  }
  Eigen::AlignedBox3d box;
  for (const StylusSample& s : samples_) box.extend(rotation * s.position);
  const double extent = box.sizes().maxCoeff();
  if (!(extent > 0.0)) throw std::invalid_argument("stylus trajectory: the stylus does not move, nothing to fit");
  WorkspaceTransform transform;
  transform.rotation = rotation;
  transform.scale = size / extent;
  transform.offset = centre - transform.scale * box.center();
  return transform;
}

JointSample interpolateJoints(const std::vector<JointSample>& joints, double t) {
  if (joints.empty()) return JointSample{};
  auto upper = std::upper_bound(joints.begin(), joints.end(), t,
                                [](double value, const JointSample& s) { return value < s.time; });
  if (upper == joints.begin()) return joints.front();
  if (upper == joints.end()) return joints.back();
  const JointSample& b = *upper;
  const JointSample& a = *(upper - 1);
  JointSample out = a;
  out.time = t;
  if (a.positions.size() == b.positions.size() && b.time > a.time) {
    const double u = (t - a.time) / (b.time - a.time);
    for (std::size_t i = 0; i < out.positions.size(); ++i) out.positions[i] += u * (b.positions[i] - a.positions[i]);
  }
  return out;
}

}  // namespace device
}  // namespace clod_haptics
