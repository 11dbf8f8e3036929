#pragma once

#include <geometry_msgs/WrenchStamped.h>
#include <ros/ros.h>

#include <atomic>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "clod_haptics/device/force_safety.h"
#include "clod_haptics/device/haptic_device.h"
#include "clod_haptics/device/openhaptics_device.h"
#include "clod_haptics/ros/servo_render_link.h"

namespace clod_haptics {
namespace device {

/** \brief Everything the bridge reads from the parameter server. */
struct PhantomBridgeParams {
  std::string name = "phantom";   ///< topic prefix, as omni_common's ~omni_name
  std::string frameId = "world";  ///< frame of the published pose
  double rate = 1000.0;           ///< servo and publish rate, Hz
  ForceSafetyParams safety;       ///< clamp, rate limit, stale timeout
  /** \brief Seconds without a state (device errors, no frames; calibration excepted) before the bridge gives up. */
  double deviceTimeout = 1.0;
  /**
   * \brief Render the proxy in the device's servo loop against the detector's mesh (ServoRenderLink), so the force
   * answers the position of the same servo tick; false, or when it cannot run: render ~force_feedback.
   */
  bool servoRender = true;
  std::string detector = "/detector";  ///< the detector whose parameters servo rendering follows
};

/** \brief Makes the OpenHaptics device; empty in a build without OpenHaptics. */
using OpenHapticsFactory = std::function<std::unique_ptr<HapticDevice>(const OpenHapticsOptions&)>;

/**
 * \brief ROS glue between a HapticDevice and the topics the Phantom / Geomagic Touch ROS drivers
 * use (omni_common's omni_state and the Geomagic_Touch_ROS_Drivers, `~omni_name` default
 * "phantom"):
 *   publishes  <name>/pose          geometry_msgs/PoseStamped, metres, every servo tick (1 kHz)
 *              <name>/button        sensor_msgs/Joy, buttons = [grey, white], on change (latched)
 *              <name>/joint_states  sensor_msgs/JointState waist, shoulder, elbow, yaw, pitch, roll
 *              ~rendered_force      geometry_msgs/WrenchStamped, the force the device got (when subscribed); with
 *                                   servo rendering in the device's loop, the proxy's force before the device's clamp,
 *                                   stamped as the pose of the servo frame it answers
 *   subscribes <name>/force_feedback geometry_msgs/WrenchStamped, newtons, in the pose frame
 * The drivers use omni_msgs/OmniButtonEvent and omni_msgs/OmniFeedback for the button and force;
 * those are not in Debian, so the same topic names carry the standard types above.
 *
 * A servo thread at `rate` reads the device, publishes, and renders the latest force command
 * through ForceSafety: clamped to max_force, slew-limited to max_force_rate, zero (with a
 * throttled warning) for a NaN/Inf command or one older than force_timeout.
 *
 * The pose is stamped with the moment the device was read (DeviceState::stamp), and the force that answers
 * it is handed to the device with that stamp, so the device can measure the force loop. A device that
 * fails (condition() Failed, or no state for ~device_timeout outside calibration) stops the bridge:
 * failure() gives the reason and the node exits non-zero, for roslaunch's respawn or required.
 *
 * Servo rendering (~servo_render, default true, with a detector running: ~detector names it): the bridge loads
 * the detector's mesh and runs the god-object proxy where the device is read (ServoRenderLink, ServoRenderer):
 * in OpenHaptics' servo callback, or in this thread for a device without one (simulated). The force then
 * answers the position of the same tick, and <name>/force_feedback is rendered only while the detector's
 * force_model is penalty. The detector still answers every pose for contacts, markers and its own ~proxy.
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
   * circle ~sim/centre, ~sim/radius, ~sim/period) or "openhaptics" (readOpenHapticsOptions(), made by
   * openhaptics; the default backend when openhaptics is set). \throws DeviceError naming the problem.
   */
  static std::unique_ptr<HapticDevice> createDevice(const ros::NodeHandle& pnh,
                                                    const OpenHapticsFactory& openhaptics = {});
  /**
   * \brief ~device_name, ~damping (N s/m), ~joint_convention, ~tip_offset (m, stylus frame), ~max_force and
   * ~force_timeout for the OpenHaptics backend. \throws std::invalid_argument for bad values.
   */
  static OpenHapticsOptions readOpenHapticsOptions(const ros::NodeHandle& pnh);

  /** \brief Starts the device and the servo thread. \throws DeviceError when the device does not start. */
  void start();
  /** \brief Stops the servo thread, commands zero force and stops the device. */
  void stop();

  const PhantomBridgeParams& params() const { return params_; }
  /** \brief Servo ticks run so far. */
  std::uint64_t ticks() const { return ticks_; }
  /** \brief Why the bridge stopped on its own (device failure); empty while it runs or after a normal stop. */
  std::string failure() const;

 private:
  void servoLoop();
  void onForce(const geometry_msgs::WrenchStamped::ConstPtr& msg);
  void tick(double now);
  void publishState(const DeviceState& state);
  void noState(double now);
  void fail(const std::string& reason);
  void checkRatings();
  void startServoRender();
  /** The force to hand the device this tick: the servo renderer's (devices without a servo loop) or the topic's. */
  ForceCommand nextCommand(double now, const DeviceState* state, double& commandStamp);

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
  std::unique_ptr<ServoRenderLink> servoLink_;  // null: servo rendering off
  bool deviceRenders_ = false;                  // the device runs servoLink_'s renderer in its own servo loop
  Eigen::Vector3d lastServoForce_ = Eigen::Vector3d::Zero();  // tick thread: the servo loop's latest force
  double lastServoStamp_ = 0.0;                               // and the wall-clock stamp of its device read

  std::mutex commandMutex_;
  ForceCommand command_;       // guarded by commandMutex_
  double commandStamp_ = 0.0;  // guarded by commandMutex_: header.stamp of the command (the pose it answers)

  std::thread servo_;
  std::atomic<bool> running_{false};
  bool deviceStarted_ = false;
  std::atomic<std::uint64_t> ticks_{0};
  std::uint64_t posesPublished_ = 0;  // tick thread only: header.seq of the poses
  bool buttonsKnown_ = false;
  std::uint32_t lastButtons_ = 0;
  ForceStatus lastStatus_ = ForceStatus::NoCommand;
  double startWall_ = 0.0;
  double lastStateAt_ = 0.0;  // tick thread: when read() last gave a state (or the start)
  // Where the force loop's time goes (devices that time their states, OpenHaptics): from the device read to
  // the pose's publication, and from a force's arrival to its hand-over to the device. Tick thread.
  // And from the device read to the force's hand-over (the loop without the servo callback's next tick).
  LatencyHistogram poseWait_;
  LatencyHistogram forceWait_;
  LatencyHistogram handOver_;
  double lastHandedStamp_ = 0.0;
  mutable std::mutex failureMutex_;
  std::string failure_;  // guarded by failureMutex_
};

}  // namespace device
}  // namespace clod_haptics
