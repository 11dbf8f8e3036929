// set: changes detector parameters with one dynamic_reconfigure call (no dynparam start-up), e.g.
//   rosrun clod_haptics set distance 0.005 mode paper
//   rosrun clod_haptics set                      (prints every current value)
//   rosrun clod_haptics set --detector /ns/detector radius 0.003
// Prints each value the detector now holds. Exit 0: done; 1: the service did not answer; 2: bad arguments.
#include <dynamic_reconfigure/Reconfigure.h>
#include <ros/ros.h>

#include <chrono>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

#include "clod_haptics/ros/reconfigure_request.h"

namespace {

void printValues(const dynamic_reconfigure::Config& request, const dynamic_reconfigure::Config& now) {
  std::vector<std::string> names;
  for (const auto& p : request.bools) names.push_back(p.name);
  for (const auto& p : request.ints) names.push_back(p.name);
  for (const auto& p : request.doubles) names.push_back(p.name);
  for (const auto& p : request.strs) names.push_back(p.name);
  if (names.empty()) {  // no name given: everything
    for (const auto& p : now.doubles) names.push_back(p.name);
    for (const auto& p : now.ints) names.push_back(p.name);
    for (const auto& p : now.strs) names.push_back(p.name);
    for (const auto& p : now.bools) names.push_back(p.name);
  }
  for (const std::string& n : names) std::printf("%s: %s\n", n.c_str(), clod_haptics::configValue(now, n).c_str());
}

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "clod_set", ros::init_options::AnonymousName | ros::init_options::NoRosout);
  std::vector<std::string> args(argv + 1, argv + argc);
  std::string detector = "/detector";
  if (args.size() >= 2 && args[0] == "--detector") {
    detector = args[1];
    args.erase(args.begin(), args.begin() + 2);
  }
  if (!args.empty() && (args[0] == "-h" || args[0] == "--help")) {
    std::printf("usage: set [--detector NS] [name value ...]   (aliases: distance, radius, mode)\n");
    return 0;
  }
  dynamic_reconfigure::Reconfigure srv;
  try {
    if (!args.empty()) srv.request.config = clod_haptics::detectorReconfigureRequest(args);
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "set: %s\n", e.what());
    return 2;
  }
  const std::string service = detector + "/set_parameters";
  const auto t0 = std::chrono::steady_clock::now();
  if (!ros::service::call(service, srv)) {
    std::fprintf(stderr, "set: %s did not answer (is the detector running? ROS_MASTER_URI=%s)\n", service.c_str(),
                 ros::master::getURI().c_str());
    return 1;
  }
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  printValues(srv.request.config, srv.response.config);
  std::fprintf(stderr, "(%s answered in %.1f ms)\n", service.c_str(), ms);
  return 0;
}
