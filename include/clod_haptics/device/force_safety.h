#pragma once

#include <Eigen/Core>
#include <cstdint>

namespace clod_haptics {
namespace device {

/**
 * \brief Limits that keep a commanded force safe to render. The defaults sit inside the
 * Geomagic Touch's ratings (0.88 N continuous, 3.3 N peak).
 */
struct ForceSafetyParams {
  /** \brief Largest force magnitude sent to the device, newtons; larger commands are scaled down. */
  double maxForce = 0.8;
  /**
   * \brief Largest change of the rendered force per second, newtons per second (a slew-rate
   * limit, so a contact that starts deep does not kick the stylus). 0 disables it.
   */
  double maxForceRate = 100.0;
  /** \brief A command older than this, seconds, is stale: the device gets zero force. */
  double staleTimeout = 0.05;
};

/** \brief Throws std::invalid_argument naming the bad field (not finite, negative, max force 0). */
void validate(const ForceSafetyParams& params);

/** \brief The latest force command the bridge received. */
struct ForceCommand {
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
  Eigen::Vector3d force = Eigen::Vector3d::Zero();  ///< newtons, may be anything (NaN, huge)
  double receivedAt = 0.0;                          ///< when it arrived, same clock as update()'s now
  bool valid = false;                               ///< false until the first command arrives
};

/** \brief What update() did to the command, worst case first. */
enum class ForceStatus : std::uint8_t {
  Ok,          ///< rendered as commanded
  NoCommand,   ///< nothing received yet: zero force, not an error
  NonFinite,   ///< NaN or Inf component: zero force and a warning
  Stale,       ///< command older than staleTimeout: zero force and a warning
  Clamped,     ///< magnitude above maxForce: scaled down to maxForce
  RateLimited  ///< within limits but moved towards the target by at most maxForceRate * dt
};

/** \brief Lower-case name of a status, for logs. */
const char* toString(ForceStatus status);

/** \brief Counters of what the filter did since construction. */
struct ForceSafetyCounters {
  std::uint64_t updates = 0;
  std::uint64_t nonFinite = 0;
  std::uint64_t stale = 0;
  std::uint64_t clamped = 0;
  std::uint64_t rateLimited = 0;
};

/**
 * \brief Turns the latest force command into the force the device renders this servo tick:
 * NaN/Inf or stale -> zero at once (dropping force is always safe), magnitude clamped to
 * maxForce keeping the direction, then the change since the last tick limited to
 * maxForceRate * dt. Pure logic, no clock and no ROS: the bridge passes the time, tests too.
 * Not thread-safe: one servo thread calls update().
 */
class ForceSafety {
 public:
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
  /** \throws std::invalid_argument for bad parameters (see validate()). */
  explicit ForceSafety(const ForceSafetyParams& params = {});

  /** \brief The force to render at time now (seconds); status says what was done to the command. */
  Eigen::Vector3d update(const ForceCommand& command, double now, ForceStatus* status = nullptr);

  /** \brief Forgets the last output (the next update starts from zero force). */
  void reset();

  const ForceSafetyParams& params() const { return params_; }
  const ForceSafetyCounters& counters() const { return counters_; }
  /** \brief The force returned by the last update(). */
  const Eigen::Vector3d& lastOutput() const { return last_; }

 private:
  ForceSafetyParams params_;
  ForceSafetyCounters counters_;
  Eigen::Vector3d last_ = Eigen::Vector3d::Zero();
  double lastTime_ = 0.0;
  bool hasLast_ = false;
};

}  // namespace device
}  // namespace clod_haptics
