#pragma once

#include <geometry_msgs/WrenchStamped.h>
#include <ros/ros.h>

#include <atomic>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "clod_haptics/device/force_safety.h"
#include "clod_haptics/device/haptic_device.h"

namespace clod_haptics {
namespace device {

/** \brief The Geomagic Touch's force ratings, newtons (the bridge refuses a max_force above the peak). */
constexpr double kTouchContinuousForce = 0.88;
constexpr double kTouchPeakForce = 3.3;

/** \brief Everything the bridge reads from the parameter server. */
struct PhantomBridgeParams {
  std::string name = "phantom";   ///< topic prefix, as omni_common's ~omni_name
  std::string frameId = "world";  ///< frame of the published pose
  double rate = 1000.0;           ///< servo and publish rate, Hz
  ForceSafetyParams safety;       ///< clamp, rate limit, stale timeout
};

/**
 * \brief ROS glue between a HapticDevice and the topics the Phantom / Geomagic Touch ROS drivers
 * use (omni_common's omni_state and the Geomagic_Touch_ROS_Drivers, `~omni_name` default
 * "phantom"):
 *   publishes  <name>/pose          geometry_msgs/PoseStamped, metres, every servo tick (1 kHz)
 *              <name>/button        sensor_msgs/Joy, buttons = [grey, white], on change (latched)
 *              <name>/joint_states  sensor_msgs/JointState waist, shoulder, elbow, yaw, pitch, roll
 *              ~rendered_force      geometry_msgs/WrenchStamped, the force the device got (when subscribed)
 *   subscribes <name>/force_feedback geometry_msgs/WrenchStamped, newtons, in the pose frame
 * The drivers use omni_msgs/OmniButtonEvent and omni_msgs/OmniFeedback for the button and force;
 * those are not in Debian, so the same topic names carry the standard types above.
 *
 * A servo thread at `rate` reads the device, publishes, and renders the latest force command
 * through ForceSafety: clamped to max_force, slew-limited to max_force_rate, zero (with a
 * throttled warning) for a NaN/Inf command or one older than force_timeout.
 */
class PhantomBridge {
 public:
  /**
   * \brief Reads parameters from pnh, advertises and subscribes in nh (so <name>/... resolves in
   * the node's namespace). Does not start the device.
   * \throws std::invalid_argument for bad parameters.
   */
  PhantomBridge(ros::NodeHandle nh, ros::NodeHandle pnh, std::unique_ptr<HapticDevice> device);
  ~PhantomBridge();

  /** \brief Reads the parameters; required ones fail loudly, optional ones default. */
  static PhantomBridgeParams readParameters(const ros::NodeHandle& pnh);
  /**
   * \brief The device named by ~backend: "simulated" (scripted motion from ~sim/script CSV or a
   * circle ~sim/centre, ~sim/radius, ~sim/period) or "openhaptics" (~device_name, only when built
   * with CLOD_WITH_OPENHAPTICS). \throws DeviceError naming the problem.
   */
  static std::unique_ptr<HapticDevice> createDevice(const ros::NodeHandle& pnh);

  /** \brief Starts the device and the servo thread. \throws DeviceError when the device does not start. */
  void start();
  /** \brief Stops the servo thread, commands zero force and stops the device. */
  void stop();

  const PhantomBridgeParams& params() const { return params_; }
  /** \brief Servo ticks run so far. */
  std::uint64_t ticks() const { return ticks_; }

 private:
  void servoLoop();
  void onForce(const geometry_msgs::WrenchStamped::ConstPtr& msg);
  void tick(double now);

  ros::NodeHandle nh_;
  ros::NodeHandle pnh_;
  PhantomBridgeParams params_;
  std::unique_ptr<HapticDevice> device_;
  ForceSafety safety_;

  ros::Publisher posePub_;
  ros::Publisher buttonPub_;
  ros::Publisher jointPub_;
  ros::Publisher renderedPub_;
  ros::Subscriber forceSub_;

  std::mutex commandMutex_;
  ForceCommand command_;  // guarded by commandMutex_

  std::thread servo_;
  std::atomic<bool> running_{false};
  std::atomic<std::uint64_t> ticks_{0};
  std::uint64_t posesPublished_ = 0;  // tick thread only: header.seq of the poses
  bool buttonsKnown_ = false;
  std::uint32_t lastButtons_ = 0;
  ForceStatus lastStatus_ = ForceStatus::NoCommand;
  double startWall_ = 0.0;
};

}  // namespace device
}  // namespace clod_haptics
