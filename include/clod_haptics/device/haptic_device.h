#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <stdexcept>
#include <string>

namespace clod_haptics {
namespace device {

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
  double time = 0.0;                                                ///< device clock, seconds
  Eigen::Vector3d position = Eigen::Vector3d::Zero();               ///< stylus tip, metres
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  ///< stylus orientation
  std::array<double, 6> joints{};                                   ///< joint angles, radians
  std::uint32_t buttons = 0;                                        ///< DeviceButton bits
};

/**
 * \brief A haptic device seen by the bridge: read the stylus, command a force. The bridge's logic
 * (clamp, rate limit, NaN and stale handling) only talks to this interface, so it is tested with
 * SimulatedDevice and runs unchanged on OpenHapticsDevice.
 *
 * read() and commandForce() are called from the bridge's servo thread only; implementations that
 * run their own servo loop (OpenHaptics' scheduler) hand data across with their own locking.
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
};

}  // namespace device
}  // namespace clod_haptics
