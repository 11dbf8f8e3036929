// sphere_builder node: serves CLOD levels of one mesh (see SphereBuilderNode).
#include <ros/ros.h>

#include "clod_haptics/core/errors.h"
#include "clod_haptics/ros/sphere_builder_node.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "sphere_builder");
  ros::NodeHandle nh;
  ros::NodeHandle pnh("~");
  std::unique_ptr<clod_haptics::SphereBuilderNode> node;
  try {
    node = std::make_unique<clod_haptics::SphereBuilderNode>(nh, pnh);
  } catch (const std::exception& e) {
    ROS_ERROR("sphere_builder: %s", e.what());
    return 1;
  }
  // Several threads, so that a long build does not block requests for cached levels.
  ros::AsyncSpinner spinner(4);
  spinner.start();
  ros::waitForShutdown();
  return 0;
}
