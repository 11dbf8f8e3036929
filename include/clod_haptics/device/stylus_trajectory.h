#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/StdVector>
#include <array>
#include <string>
#include <vector>

namespace clod_haptics {
namespace device {

/** \brief One recorded stylus sample, in metres, the time in seconds from the recording start. */
struct StylusSample {
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
  double time = 0.0;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
};

using StylusSamples = std::vector<StylusSample, Eigen::aligned_allocator<StylusSample>>;

/** \brief Joint angles recorded with the motion (waist, shoulder, elbow, yaw, pitch, roll). */
struct JointSample {
  double time = 0.0;
  std::vector<std::string> names;
  std::vector<double> positions;
};

/**
 * \brief Places a recorded workspace over a mesh: p' = offset + scale * rotation * p, the
 * orientation rotated by the same rotation.
 */
struct WorkspaceTransform {
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
  double scale = 1.0;
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();

  Eigen::Vector3d apply(const Eigen::Vector3d& p) const { return offset + scale * (rotation * p); }
  /** \brief From roll, pitch, yaw (radians, fixed axes x, y, z as in tf). */
  static Eigen::Quaterniond fromRpy(double roll, double pitch, double yaw);
};

/**
 * \brief A stylus motion as a time-ordered list of samples: sorted, validated, resampled to a
 * haptic rate by interpolation (linear in position, slerp in orientation) and transformed.
 */
class StylusTrajectory {
 public:
  StylusTrajectory() = default;
  /**
   * \brief Sorts by time, drops samples with non-finite values or a repeated time (counted in
   * dropped()), shifts times to start at zero.
   * \throws std::invalid_argument when fewer than one valid sample remains.
   */
  explicit StylusTrajectory(StylusSamples samples);

  const StylusSamples& samples() const { return samples_; }
  std::size_t size() const { return samples_.size(); }
  double duration() const { return samples_.empty() ? 0.0 : samples_.back().time; }
  /** \brief Samples discarded by the constructor (non-finite, duplicate time). */
  std::size_t dropped() const { return dropped_; }
  /** \brief Mean sample rate, Hz (0 for a single sample). */
  double meanRate() const;

  /** \brief The interpolated sample at time t (clamped to [0, duration]). */
  StylusSample at(double t) const;

  /**
   * \brief Samples at exactly rate Hz from 0 to duration: k / rate for k = 0 .. floor(duration * rate),
   * interpolated between the recorded samples (a recording already at or above the rate is
   * resampled too, so the output is uniform).
   * \throws std::invalid_argument for a rate that is not finite and positive.
   */
  StylusTrajectory resampled(double rate) const;

  /** \brief Every sample moved by the transform. */
  StylusTrajectory transformed(const WorkspaceTransform& transform) const;

  /** \brief Axis-aligned bounds of the positions. */
  Eigen::AlignedBox3d bounds() const;

  /**
   * \brief The transform (keeping rotation) that maps these positions, rotated, so their bounds'
   * largest side becomes size and their centre lands on centre: fits a recorded workspace over a
   * mesh of known size.
   * \throws std::invalid_argument for size <= 0 or a trajectory that does not move.
   */
  WorkspaceTransform fitInto(const Eigen::Vector3d& centre, double size,
                             const Eigen::Quaterniond& rotation = Eigen::Quaterniond::Identity()) const;

 private:
  StylusSamples samples_;
  std::size_t dropped_ = 0;
};

/** \brief Linear interpolation of recorded joint samples at time t (names from the first sample). */
JointSample interpolateJoints(const std::vector<JointSample>& joints, double t);

}  // namespace device
}  // namespace clod_haptics
