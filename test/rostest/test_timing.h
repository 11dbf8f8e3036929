#pragma once

// Deadlines of the rostests scale with CLOD_TIME_SCALE (1 in a normal build, 4 under -DCLOD_SANITIZE=ON; the
// devel space exports it, see cmake/50.clod_haptics_test_env.sh.in), as their .test time-limit does. A deadline
// only bounds how long a test waits for something that must happen; it never passes a test by itself.

#include <ros/ros.h>

#include <cmath>
#include <cstdlib>

namespace clod_haptics_test {

/** \brief CLOD_TIME_SCALE from the environment; 1 when unset or not a finite number >= 1. */
inline double timeScale() {
  const char* value = std::getenv("CLOD_TIME_SCALE");
  const double scale = value ? std::strtod(value, nullptr) : 1.0;
  return std::isfinite(scale) && scale >= 1.0 ? scale : 1.0;
}

/** \brief A deadline (seconds) of the normal build scaled for this build. */
inline double scaled(double seconds) { return seconds * timeScale(); }

/** \brief Polls pred every poll seconds until it holds (true) or the scaled deadline passes (false). */
template <class Pred>
bool waitUntil(Pred pred, double seconds, double poll = 0.005) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(scaled(seconds));
  while (ros::ok() && ros::WallTime::now() < end) {
    if (pred()) return true;
    ros::WallDuration(poll).sleep();
  }
  return false;
}

}  // namespace clod_haptics_test
