// The detector as a standalone node: the same class as the nodelet.
#include <ros/ros.h>

#include "clod_haptics/ros/haptic_detector.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "detector");
  ros::NodeHandle nh;
  ros::NodeHandle pnh("~");
  std::unique_ptr<clod_haptics::HapticDetector> detector;
  try {
    detector = std::make_unique<clod_haptics::HapticDetector>(nh, pnh);
  } catch (const std::exception& e) {
    ROS_ERROR("detector: %s", e.what());
    return 1;
  }
  ros::spin();  // poses on this thread; display and levels run on their own threads
  return 0;
}
