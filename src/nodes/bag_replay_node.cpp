// bag_replay: recorded stylus motion on the Phantom bridge's topics. See
// include/clod_haptics/ros/bag_replay.h. Exits 1 with a clear message for a missing,
// truncated or unreadable bag, a missing topic or a bad parameter.
#include <ros/ros.h>

#include "clod_haptics/ros/bag_replay.h"
#include "clod_haptics/ros/node_main.h"

int main(int argc, char** argv) {
  clod_haptics::lineBufferStdout();
  ros::init(argc, argv, "bag_replay");
  ros::NodeHandle nh;
  ros::NodeHandle pnh("~");
  try {
    clod_haptics::device::BagReplay replay(nh, pnh);
    ros::AsyncSpinner spinner(1);  // serves subscriber connections while run() sleeps between poses
    spinner.start();
    replay.run();
  } catch (const std::exception& e) {
    ROS_FATAL("bag_replay: %s", e.what());
    return 1;
  }
  return 0;
}
