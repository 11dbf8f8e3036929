#pragma once

#include <ros/ros.h>

#include <cstdio>
#include <exception>
#include <memory>

namespace clod_haptics {

/**
 * \brief Makes stdout line-buffered, so a node's INFO lines appear as they are logged when roslaunch (or a
 * pipe, or a file) takes its output: stdout is block-buffered there and would hold them until exit.
 */
inline void lineBufferStdout() { std::setvbuf(stdout, nullptr, _IOLBF, 0); }

/**
 * \brief The main of a standalone node around a glue class T (constructed from the node handle and the
 * private one, as its nodelet does): a construction error is logged as an ERROR naming the node and the node
 * exits 1; otherwise the global queue is served by `threads` threads until shutdown.
 */
template <class T>
int runNode(int argc, char** argv, const char* name, unsigned threads = 1) {
  lineBufferStdout();
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
