#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>

#include "clod_haptics/core/latency_histogram.h"

namespace clod_haptics {
namespace device {

class ServoRenderer;

/** \brief A device could not be opened, started or read; the message says which and why. */
class DeviceError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/** \brief Button bits of DeviceState::buttons, in the order the Phantom drivers report them. */
enum DeviceButton : std::uint32_t {
  kGreyButton = 1u << 0,   ///< the first (dark grey) stylus button
  kWhiteButton = 1u << 1,  ///< the second (white) stylus button
};

/**
 * \brief One sample of the stylus, already in ROS conventions: metres, z up (REP 103), the
 * orientation as a unit quaternion, joint angles in radians in the order waist, shoulder, elbow,
 * yaw, pitch, roll (the names the Geomagic Touch ROS drivers use).
 */
struct DeviceState {
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
  double time = 0.0;   ///< the device's clock when read, seconds (OpenHaptics: steady clock; simulated: script time)
  double stamp = 0.0;  ///< the same moment on the wall clock (system_clock, seconds since 1970); 0: unknown
  /** \brief The point the device reports, metres: for OpenHaptics the gimbal centre plus the tip offset. */
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  ///< stylus orientation
  std::array<double, 6> joints{};                                   ///< joint angles, radians
  std::uint32_t buttons = 0;                                        ///< DeviceButton bits
};

/** \brief Why read() gives no state, worst last. */
enum class DeviceCondition : std::uint8_t {
  Ok,           ///< read() gives states
  NotStarted,   ///< not started, or no servo frame yet
  Calibrating,  ///< waiting for calibration (the stylus in the inkwell, say): no state, zero force
  FrameError,   ///< the last servo frame reported an error: its state is withheld
  Failed        ///< the servo loop stopped for good (communication lost, device unplugged)
};

/** \brief A device's force ratings, newtons. The defaults are the Geomagic Touch's. */
struct ForceRatings {
  double peak = 3.3;         ///< nominal maximum force (HD_NOMINAL_MAX_FORCE)
  double continuous = 0.88;  ///< nominal maximum continuous force (HD_NOMINAL_MAX_CONTINUOUS_FORCE)
};

/**
 * \brief A haptic device seen by the bridge: read the stylus, command a force. The bridge's logic
 * (clamp, rate limit, NaN and stale handling) only talks to this interface, so it is tested with
 * SimulatedDevice and runs unchanged on OpenHapticsDevice.
 *
 * read(), commandForce(), commandForceFor(), condition() and conditionText() are called from one thread,
 * the bridge's; implementations that run their own servo loop (OpenHaptics' scheduler) hand data across
 * without blocking that loop.
 */
class HapticDevice {
 public:
  virtual ~HapticDevice() = default;
  /** \brief Opens the device and starts its servo loop. \throws DeviceError when it cannot. */
  virtual void start() = 0;
  /** \brief Commands zero force and stops the device; safe to call twice. */
  virtual void stop() = 0;
  /** \brief The latest stylus sample; false when none is available (not started, device fault). */
  virtual bool read(DeviceState& state) = 0;
  /** \brief The force to render at the stylus tip, newtons, ROS frame. Already made safe by the bridge. */
  virtual void commandForce(const Eigen::Vector3d& force) = 0;
  /** \brief A short name for logs ("simulated", "openhaptics:Default Device"). */
  virtual std::string name() const = 0;

  /**
   * \brief commandForce() for the answer to the pose stamped poseStamp (wall clock seconds, DeviceState::stamp
   * of that pose; 0 when unknown), so a device can measure its force loop's latency.
   */
  virtual void commandForceFor(const Eigen::Vector3d& force, double poseStamp) {
    (void)poseStamp;
    commandForce(force);
  }
  /** \brief The device's condition after the last read() (bridge thread). */
  virtual DeviceCondition condition() const { return DeviceCondition::Ok; }
  /** \brief What condition() means for the user, with the device's error text; empty when Ok. */
  virtual std::string conditionText() const { return {}; }
  /** \brief The force ratings, read from the device where it reports them; valid after start(). */
  virtual ForceRatings ratings() const { return {}; }
  /**
   * \brief Time from a pose leaving the device's servo loop to the force answering it reaching the servo
   * loop (see commandForceFor()); null when the device does not measure it.
   */
  virtual const LatencyHistogram* forceLoopLatency() const { return nullptr; }
  /**
   * \brief Hands the device a renderer to run inside its own servo loop (the force computed in the tick that read
   * the position, no round trip), before start(). While the renderer is enabled its force replaces the commands.
   * \return false when the device has no servo loop of its own (the caller then runs the renderer itself).
   */
  virtual bool attachServoRenderer(std::shared_ptr<ServoRenderer> renderer) {
    (void)renderer;
    return false;
  }
};

}  // namespace device
}  // namespace clod_haptics
