// static_frame node: broadcasts one static transform, identity by default, so a frame that only markers and poses
// use (the mesh's frame_id) exists in tf2 and RViz can take it as its Fixed Frame without a warning. Debian's
// ROS has no static_transform_publisher binary.
//   ~parent (default world), ~child (default <parent>_static), ~xyz [x, y, z] (m), ~rpy [roll, pitch, yaw] (rad)
#include <geometry_msgs/TransformStamped.h>
#include <ros/ros.h>
#include <tf2/LinearMath/Quaternion.h>
#include <tf2_ros/static_transform_broadcaster.h>

#include <string>
#include <vector>

int main(int argc, char** argv) {
  ros::init(argc, argv, "static_frame");
  ros::NodeHandle pnh("~");
  geometry_msgs::TransformStamped t;
  t.header.stamp = ros::Time::now();
  t.header.frame_id = pnh.param<std::string>("parent", "world");
  t.child_frame_id = pnh.param<std::string>("child", t.header.frame_id + "_static");
  std::vector<double> xyz{0.0, 0.0, 0.0}, rpy{0.0, 0.0, 0.0};
  pnh.param("xyz", xyz, xyz);
  pnh.param("rpy", rpy, rpy);
  if (xyz.size() != 3 || rpy.size() != 3 || t.header.frame_id == t.child_frame_id || t.child_frame_id.empty()) {
    ROS_ERROR("static_frame: ~xyz and ~rpy need 3 numbers each, ~child a name other than ~parent");
    return 1;
  }
  t.transform.translation.x = xyz[0];
  t.transform.translation.y = xyz[1];
  t.transform.translation.z = xyz[2];
  tf2::Quaternion q;
  q.setRPY(rpy[0], rpy[1], rpy[2]);
  t.transform.rotation.x = q.x();
  t.transform.rotation.y = q.y();
  t.transform.rotation.z = q.z();
  t.transform.rotation.w = q.w();
  tf2_ros::StaticTransformBroadcaster broadcaster;
  broadcaster.sendTransform(t);
  ros::spin();
  return 0;
}
