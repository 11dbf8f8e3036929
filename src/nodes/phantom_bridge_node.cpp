// phantom_bridge: a Phantom / Geomagic Touch (OpenHaptics) or a simulated device on the topics
// of the omni_common / Geomagic Touch ROS drivers. See include/clod_haptics/ros/phantom_bridge.h.
#include <ros/ros.h>

#include "clod_haptics/ros/phantom_bridge.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "phantom_bridge");
  ros::NodeHandle nh;
  ros::NodeHandle pnh("~");
  try {
    clod_haptics::device::PhantomBridge bridge(nh, pnh, clod_haptics::device::PhantomBridge::createDevice(pnh));
    bridge.start();
    ros::spin();
    bridge.stop();
  } catch (const std::exception& e) {
    ROS_FATAL("phantom_bridge: %s", e.what());
    return 1;
  }
  return 0;
}
