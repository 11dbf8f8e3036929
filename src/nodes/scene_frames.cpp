// Demo frames for scene files (config/scene_example_frames.yaml): static frames latched on /tf_static
// and frames moving on a circle on /tf. Debian's ROS has no static_transform_publisher binary; a real
// setup gets these frames from its robot, tracker or device driver instead.
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <geometry_msgs/TransformStamped.h>
#include <ros/ros.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_broadcaster.h>
#include <Eigen/Geometry>
#include <xmlrpcpp/XmlRpcValue.h>

namespace {

struct Frame {
  std::string parent, child;
  double xyz[3] = {0, 0, 0};
  double rpy[3] = {0, 0, 0};
  double radius = 0.0, period = 10.0;
};

double number(XmlRpc::XmlRpcValue& v) {
  if (v.getType() == XmlRpc::XmlRpcValue::TypeInt) return static_cast<int>(v);
  if (v.getType() == XmlRpc::XmlRpcValue::TypeDouble) return static_cast<double>(v);
  throw std::runtime_error("expected a number");
}

std::vector<Frame> readFrames(ros::NodeHandle& pnh, const std::string& key) {
  std::vector<Frame> frames;
  XmlRpc::XmlRpcValue list;
  if (!pnh.getParam(key, list)) return frames;
  if (list.getType() != XmlRpc::XmlRpcValue::TypeArray) throw std::runtime_error("~" + key + " must be a list");
  for (int i = 0; i < list.size(); ++i) {
    XmlRpc::XmlRpcValue& f = list[i];
    Frame frame;
    frame.parent = static_cast<std::string>(f["parent"]);
    frame.child = static_cast<std::string>(f["child"]);
    for (int k = 0; k < 3; ++k) {
      if (f.hasMember("xyz")) frame.xyz[k] = number(f["xyz"][k]);
      if (f.hasMember("rpy")) frame.rpy[k] = number(f["rpy"][k]);
    }
    if (f.hasMember("radius")) frame.radius = number(f["radius"]);
    if (f.hasMember("period")) frame.period = number(f["period"]);
    if (!(frame.period > 0.0)) throw std::runtime_error("~" + key + "[" + std::to_string(i) + "] period must be > 0");
    frames.push_back(frame);
  }
  return frames;
}

geometry_msgs::TransformStamped toMsg(const Frame& f, double dx, double dy, double yaw, const ros::Time& stamp) {
  geometry_msgs::TransformStamped t;
  t.header.stamp = stamp;
  t.header.frame_id = f.parent;
  t.child_frame_id = f.child;
  t.transform.translation.x = f.xyz[0] + dx;
  t.transform.translation.y = f.xyz[1] + dy;
  t.transform.translation.z = f.xyz[2];
  const Eigen::Quaterniond q = Eigen::AngleAxisd(f.rpy[2] + yaw, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(f.rpy[1], Eigen::Vector3d::UnitY()) *
                               Eigen::AngleAxisd(f.rpy[0], Eigen::Vector3d::UnitX());
  t.transform.rotation.w = q.w();
  t.transform.rotation.x = q.x();
  t.transform.rotation.y = q.y();
  t.transform.rotation.z = q.z();
  return t;
}

}  // namespace

int main(int argc, char** argv) {
  std::setvbuf(stdout, nullptr, _IOLBF, 0);  // INFO lines live under roslaunch (see ros/node_main.h)
  ros::init(argc, argv, "scene_frames");
  ros::NodeHandle pnh("~");
  std::vector<Frame> fixed, moving;
  double rate = 100.0;
  try {
    fixed = readFrames(pnh, "static_frames");
    moving = readFrames(pnh, "moving_frames");
    pnh.param("rate", rate, 100.0);
    if (!(rate > 0.0)) throw std::runtime_error("~rate must be > 0");
  } catch (const std::exception& e) {
    ROS_ERROR("scene_frames: bad parameters: %s", e.what());
    return 1;
  }
  tf2_ros::StaticTransformBroadcaster staticBroadcaster;
  std::vector<geometry_msgs::TransformStamped> latched;
  for (const Frame& f : fixed) latched.push_back(toMsg(f, 0, 0, 0, ros::Time::now()));
  if (!latched.empty()) staticBroadcaster.sendTransform(latched);
  tf2_ros::TransformBroadcaster broadcaster;
  const ros::WallTime start = ros::WallTime::now();
  ros::Rate loop(rate);
  while (ros::ok() && !moving.empty()) {
    const double t = (ros::WallTime::now() - start).toSec();
    const ros::Time stamp = ros::Time::now();
    for (const Frame& f : moving) {
      const double a = 2.0 * M_PI * t / f.period;
      broadcaster.sendTransform(toMsg(f, f.radius * std::cos(a), f.radius * std::sin(a), a, stamp));
    }
    loop.sleep();
  }
  ros::spin();  // static frames only: stay alive (the latched message needs its publisher)
  return 0;
}
