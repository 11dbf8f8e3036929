// The scene detector as a standalone node: the same class as the nodelet.
#include <memory>

#include <ros/ros.h>

#include "clod_haptics/ros/scene_detector.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "scene_detector");
  ros::NodeHandle nh;
  ros::NodeHandle pnh("~");
  std::unique_ptr<clod_haptics::SceneHapticDetector> detector;
  try {
    detector = std::make_unique<clod_haptics::SceneHapticDetector>(nh, pnh);
  } catch (const std::exception& e) {
    ROS_ERROR("scene_detector: %s", e.what());
    return 1;
  }
  ros::spin();  // poses on this thread; levels and display run on their own threads
  return 0;
}
