#pragma once

#include <ros/ros.h>

#include <exception>
#include <memory>

namespace clod_haptics {

/**
 * \brief The main of a standalone node around a glue class T (constructed from the node handle and the
 * private one, as its nodelet does): a construction error is logged as an ERROR naming the node and the node
 * exits 1; otherwise the global queue is served by `threads` threads until shutdown.
 */
template <class T>
int runNode(int argc, char** argv, const char* name, unsigned threads = 1) {
  ros::init(argc, argv, name);
  ros::NodeHandle nh;
  ros::NodeHandle pnh("~");
  std::unique_ptr<T> node;
  try {
    node = std::make_unique<T>(nh, pnh);
  } catch (const std::exception& e) {
    ROS_ERROR("%s: %s", name, e.what());
    return 1;
  }
  ros::AsyncSpinner spinner(threads);
  spinner.start();
  ros::waitForShutdown();
  return 0;
}

}  // namespace clod_haptics
