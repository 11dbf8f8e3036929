#pragma once

#include <stdexcept>
#include <string>
#include <vector>

#include "clod_haptics/device/stylus_trajectory.h"

namespace clod_haptics {
namespace device {

/** \brief A bag cannot be used as a stylus source: unreadable, truncated, no usable topic. */
class BagReadError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/** \brief Which topic to read and how to scale it. */
struct BagReadOptions {
  /**
   * \brief The stylus topic. Empty: the first geometry_msgs/PoseStamped topic (one named .../pose
   * preferred), else the first sensor_msgs/JointState topic whose names include x, y, z (the
   * Geomagic Touch end_effector_pose recording).
   */
  std::string topic;
  /**
   * \brief Factor from the bag's position unit to metres. 0 (default): 1 for PoseStamped (REP 103
   * metres), 0.001 for the x, y, z JointState recordings (millimetres).
   */
  double positionScale = 0.0;
  /** \brief Joint angles topic; empty: a JointState topic with six names other than the stylus topic. */
  std::string jointTopic;
};

/** \brief What a bag holds for replay. */
struct BagMotion {
  StylusTrajectory trajectory;      ///< positions in metres, times from the first sample
  std::vector<JointSample> joints;  ///< joint angles on the same time axis (may be empty)
  std::string topic;                ///< the stylus topic read
  std::string type;                 ///< its message type
  std::string frameId;              ///< frame of the first PoseStamped (empty for JointState)
  std::string jointTopic;           ///< the joint topic read, empty if none
  double positionScale = 1.0;       ///< the factor applied to the positions
  std::size_t messages = 0;         ///< stylus messages read
};

/**
 * \brief Reads a stylus motion from a rosbag (v2). Times are the message header stamps, or the
 * bag's receive times when the header is empty.
 * \throws BagReadError naming the path and the reason: missing or unreadable file, a truncated
 * or unindexed bag (run `rosbag reindex`), no usable or the requested topic missing (the
 * message lists the topics present), a JointState without x, y, z names, no finite sample.
 */
BagMotion readStylusBag(const std::string& path, const BagReadOptions& options = {});

/**
 * \brief The bag a user named (bag_replay's ~bag, CLOD_BAG) as a file path: an absolute path as it
 * is (readStylusBag reports a missing one); a relative or `~/` path looked for relative to the
 * directory roslaunch was started from ($PWD), then the node's working directory ($ROS_HOME under
 * roslaunch): the same rule as mesh parameters (resolveUserPath, core/user_path.h).
 * \throws BagReadError when a relative path exists in none of them; the message names every path tried.
 */
std::string resolveBagPath(const std::string& path);

}  // namespace device
}  // namespace clod_haptics
