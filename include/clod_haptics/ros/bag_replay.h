#pragma once

#include <ros/ros.h>

#include <chrono>
#include <cstdint>
#include <string>

#include "clod_haptics/device/stylus_trajectory.h"
#include "clod_haptics/ros/bag_source.h"

namespace clod_haptics {
namespace device {

/** \brief Everything bag_replay reads from the parameter server. */
struct BagReplayParams {
  std::string bag;               ///< ~bag, required; the constructor makes a relative one absolute (resolveBagPath)
  BagReadOptions read;           ///< ~topic, ~joint_topic, ~position_scale
  std::string name = "phantom";  ///< ~omni_name: topic prefix, as the bridge
  std::string frameId;           ///< ~frame_id; empty: the bag's PoseStamped frame, else "world"
  double rate = 1000.0;          ///< ~rate: output rate, Hz (upsampled by interpolation); 0 = as recorded
  double rateScale = 1.0;        ///< ~rate_scale: 2 plays twice as fast
  bool loop = false;             ///< ~loop
  WorkspaceTransform transform;  ///< ~offset, ~scale, ~rotation_rpy
  bool fit = false;              ///< set when ~fit_size > 0: fit the workspace into a box
  Eigen::Vector3d fitCenter = Eigen::Vector3d::Zero();  ///< ~fit_center
  double fitSize = 0.0;                                 ///< ~fit_size, metres
  double startDelay = 0.5;                              ///< ~start_delay, seconds before the first pose
  int waitForSubscribers = 0;                           ///< ~wait_for_subscribers on <name>/pose before starting
  double waitTimeout = 10.0;                            ///< ~wait_timeout, seconds
  double exitDelay = 1.0;  ///< ~exit_delay after the last pose (the latched ~done reaches listeners)
};

/**
 * \brief Replays a recorded stylus motion on the bridge's topics (<name>/pose, <name>/button,
 * <name>/joint_states), so the detector cannot tell it from a device: PoseStamped bags and the
 * Geomagic Touch JointState x, y, z recordings (millimetres, about 100 Hz), upsampled to `rate`
 * by interpolation, played at rate_scale times the recorded speed, once or looping, through a
 * workspace transform placing the recording over the mesh. Publishes ~done (std_msgs/UInt64,
 * latched: poses published) when a single pass ends.
 */
class BagReplay {
 public:
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
  /**
   * \brief Reads the parameters and the bag.
   * \throws std::invalid_argument for a bad parameter, BagReadError for a bag that cannot be used (a
   * relative ~bag found neither relative to $PWD nor to the working directory: every path tried is named).
   */
  BagReplay(ros::NodeHandle nh, ros::NodeHandle pnh);

  static BagReplayParams readParameters(const ros::NodeHandle& pnh);

  /** \brief Plays the motion; returns when done (not looping) or on shutdown. */
  void run();

  /** \brief The motion as it is published: resampled and transformed. */
  const StylusTrajectory& trajectory() const { return trajectory_; }
  const BagMotion& motion() const { return motion_; }
  std::uint64_t published() const { return published_; }

 private:
  using Clock = std::chrono::steady_clock;

  /** \brief Publishes the button state once: a recording has none, so "released". */
  void publishReleasedButton();
  /** \brief Waits up to ~wait_timeout for ~wait_for_subscribers pose subscribers (a warning if fewer came). */
  void waitForSubscribers();
  /** \brief Publishes the poses (and joints) on the recorded schedule from start; returns the passes played. */
  std::uint64_t play(Clock::time_point start);
  /** \brief Publishes the joint angles at recorded time t. */
  void publishJoints(double t, const ros::Time& stamp);
  /** \brief Logs the summary and publishes ~done. */
  void reportDone(double elapsed, std::uint64_t passes);

  ros::NodeHandle nh_;
  ros::NodeHandle pnh_;
  BagReplayParams params_;
  BagMotion motion_;
  StylusTrajectory trajectory_;
  ros::Publisher posePub_, buttonPub_, jointPub_, donePub_;
  std::uint64_t published_ = 0;
};

}  // namespace device
}  // namespace clod_haptics
