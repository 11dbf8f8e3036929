// Reads the recorded stylus trajectory with the rosbag C++ API and resamples it at a fixed rate.
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/JointState.h>

#include <algorithm>
#include <cmath>

#include "bench_common.h"

namespace clod_bench {

std::vector<Vec3> readTrajectory(const std::string& bagPath, const std::string& topic, double rateHz,
                                 std::string& error, double& seconds, std::size_t& messages) {
  std::vector<double> times;
  std::vector<Vec3> points;
  seconds = 0.0;
  messages = 0;
  try {
    rosbag::Bag bag(bagPath, rosbag::bagmode::Read);
    rosbag::View view(bag, rosbag::TopicQuery(topic));
    for (const rosbag::MessageInstance& m : view) {
      sensor_msgs::JointState::ConstPtr js = m.instantiate<sensor_msgs::JointState>();
      if (!js) continue;
      double xyz[3];
      int found = 0;
      for (std::size_t i = 0; i < js->name.size() && i < js->position.size(); ++i) {
        const std::string& n = js->name[i];
        const int k = n == "x" ? 0 : n == "y" ? 1 : n == "z" ? 2 : -1;
        if (k >= 0) {
          xyz[k] = js->position[i];
          found |= 1 << k;
        }
      }
      if (found != 7) continue;
      const double t = (js->header.stamp.isZero() ? m.getTime() : js->header.stamp).toSec();
      if (!times.empty() && !(t > times.back())) continue;  // keep strictly increasing stamps
      times.push_back(t);
      points.emplace_back(xyz[0], xyz[1], xyz[2]);
    }
  } catch (const std::exception& e) {
    error = e.what();
    return {};
  }
  messages = points.size();
  if (points.size() < 2) {
    error = "fewer than two usable messages on " + topic;
    return {};
  }
  seconds = times.back() - times.front();
  const std::size_t n = static_cast<std::size_t>(std::floor(seconds * rateHz)) + 1;
  std::vector<Vec3> out;
  out.reserve(n);
  std::size_t j = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double t = times.front() + i / rateHz;
    while (j + 2 < times.size() && times[j + 1] < t) ++j;
    const double a = std::clamp((t - times[j]) / (times[j + 1] - times[j]), 0.0, 1.0);
    out.push_back((1.0 - a) * points[j] + a * points[j + 1]);
  }
  return out;
}

}  // namespace clod_bench
