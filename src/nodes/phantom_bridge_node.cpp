// phantom_bridge: a Phantom / Geomagic Touch (OpenHaptics) or a simulated device on the topics
// of the omni_common / Geomagic Touch ROS drivers. See include/clod_haptics/ros/phantom_bridge.h.
// Exit code 1 when the device cannot start or fails while running (the reason on stderr).
#include <ros/ros.h>

#include <cstdio>

#include "clod_haptics/ros/node_main.h"
#include "clod_haptics/ros/phantom_bridge.h"
#ifdef CLOD_WITH_OPENHAPTICS
#include "clod_haptics/device/openhaptics_device.h"
#endif

int main(int argc, char** argv) {
  using clod_haptics::device::PhantomBridge;
  clod_haptics::lineBufferStdout();
  ros::init(argc, argv, "phantom_bridge");
  ros::NodeHandle nh;
  ros::NodeHandle pnh("~");
  clod_haptics::device::OpenHapticsFactory openhaptics;
#ifdef CLOD_WITH_OPENHAPTICS
  openhaptics = [](const clod_haptics::device::OpenHapticsOptions& options) {
    return std::make_unique<clod_haptics::device::OpenHapticsDevice>(options);
  };
#endif
  try {
    PhantomBridge bridge(nh, pnh, PhantomBridge::createDevice(pnh, openhaptics));
    bridge.start();
    ros::spin();
    bridge.stop();
    const std::string failure = bridge.failure();
    if (!failure.empty()) {
      // rosconsole is shut down by now: the reason goes to stderr (it was logged as FATAL when it happened).
      std::fprintf(stderr, "phantom_bridge: exiting with code 1: %s\n", failure.c_str());
      return 1;
    }
  } catch (const std::exception& e) {
    ROS_FATAL("phantom_bridge: %s", e.what());
    return 1;
  }
  return 0;
}
