#pragma once

#include <geometry_msgs/Pose.h>

#include <Eigen/Geometry>

namespace clod_haptics {
namespace device {

/** \brief Writes a stylus position and orientation into a pose message (the one conversion the
 * device bridge and the bag replay share). */
inline void toPoseMsg(const Eigen::Vector3d& position, const Eigen::Quaterniond& orientation,
                      geometry_msgs::Pose& msg) {
  msg.position.x = position.x();
  msg.position.y = position.y();
  msg.position.z = position.z();
  msg.orientation.w = orientation.w();
  msg.orientation.x = orientation.x();
  msg.orientation.y = orientation.y();
  msg.orientation.z = orientation.z();
}

}  // namespace device
}  // namespace clod_haptics
