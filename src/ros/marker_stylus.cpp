#include "clod_haptics/ros/marker_stylus.h"

#include <visualization_msgs/InteractiveMarker.h>
#include <visualization_msgs/InteractiveMarkerControl.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <vector>

#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/ros/conversions.h"
#include "clod_haptics/ros/mesh_resource.h"

namespace clod_haptics {

namespace {

constexpr const char* kMarkerName = "stylus";

void requirePositive(const char* name, double value) {
  if (!(std::isfinite(value) && value > 0.0))
    throw std::invalid_argument(std::string("~") + name + " must be finite and positive, not " +
                                std::to_string(value));
}

Eigen::Isometry3d fromPoseMsg(const geometry_msgs::Pose& p) {
  Eigen::Quaterniond q(p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z);
  if (!(q.norm() > 1e-9) || !q.coeffs().allFinite()) q = Eigen::Quaterniond::Identity();
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = q.normalized().toRotationMatrix();
  t.translation() = Eigen::Vector3d(p.position.x, p.position.y, p.position.z);
  return t;
}

visualization_msgs::InteractiveMarkerControl axisControl(const char* name, double x, double y, double z,
                                                         std::uint8_t mode) {
  visualization_msgs::InteractiveMarkerControl c;
  c.name = name;
  const double n = std::sqrt(1.0 + x * x + y * y + z * z);  // (w, x, y, z) = (1, axis): the axis, normalised
  c.orientation.w = 1.0 / n;
  c.orientation.x = x / n;
  c.orientation.y = y / n;
  c.orientation.z = z / n;
  c.interaction_mode = mode;
  return c;
}

}  // namespace

StylusInterpolator::StylusInterpolator(const Eigen::Isometry3d& start, double maxSpeed, double maxAngularSpeed)
    : pose_(start), target_(start), maxSpeed_(maxSpeed), maxAngularSpeed_(maxAngularSpeed) {}

void StylusInterpolator::setTarget(const Eigen::Isometry3d& target) { target_ = target; }

const Eigen::Isometry3d& StylusInterpolator::step(double dt) {
  if (!(dt > 0.0)) return pose_;
  const Eigen::Vector3d gap = target_.translation() - pose_.translation();
  const double reach = maxSpeed_ * dt;
  const double length = gap.norm();
  pose_.translation() = length <= reach ? target_.translation() : Eigen::Vector3d(pose_.translation() + gap * (reach / length));
  const Eigen::Quaterniond from(pose_.linear()), to(target_.linear());
  const double angle = from.angularDistance(to);
  const double turn = maxAngularSpeed_ * dt;
  pose_.linear() = (angle <= turn ? to : from.slerp(turn / angle, to)).toRotationMatrix();
  return pose_;
}

StylusPlacement placementForBounds(const Eigen::AlignedBox3d& box) {
  StylusPlacement p;
  const double size = std::max(box.diagonal().norm(), 1e-6);
  p.start = box.center();
  p.start.z() = box.max().z() + 0.08 * size;  // in the launch file's view, above the mesh
  p.markerScale = 0.1 * size;
  p.maxSpeed = 0.5 * size;
  return p;
}

MarkerStylus::MarkerStylus(ros::NodeHandle& nh, ros::NodeHandle& pnh) {
  pnh.param<std::string>("frame_id", frameId_, "world");
  pnh.param("rate", rate_, 1000.0);
  requirePositive("rate", rate_);
  StylusPlacement place;
  std::string mesh;
  if (pnh.getParam("mesh", mesh) && !mesh.empty()) {
    MeshLoadOptions options;
    pnh.param("scale", options.scale, 1.0);
    pnh.param("normalize", options.normalize, false);
    place = placementForBounds(loadMesh(resolveMeshPath(mesh), options).modelBounds());
  }
  std::vector<double> start;
  if (pnh.getParam("start", start) && start.size() == 3) place.start = Eigen::Vector3d(start[0], start[1], start[2]);
  pnh.param("marker_scale", place.markerScale, place.markerScale);
  pnh.param("max_speed", place.maxSpeed, place.maxSpeed);
  double maxAngularSpeed = 2.0 * M_PI;
  pnh.param("max_angular_speed", maxAngularSpeed, maxAngularSpeed);
  requirePositive("marker_scale", place.markerScale);
  requirePositive("max_speed", place.maxSpeed);
  requirePositive("max_angular_speed", maxAngularSpeed);

  target_ = Eigen::Isometry3d::Identity();
  target_.translation() = place.start;
  interpolator_ = std::make_unique<StylusInterpolator>(target_, place.maxSpeed, maxAngularSpeed);
  posePub_ = nh.advertise<geometry_msgs::PoseStamped>(pnh.param<std::string>("pose_topic", "/phantom/pose"), 100);
  const std::string serverName = pnh.param<std::string>("server", "stylus_marker");
  server_ = std::make_unique<interactive_markers::InteractiveMarkerServer>(serverName, "", false);
  makeMarker(place.start, place.markerScale);
  goalSub_ = pnh.subscribe("goal", 10, &MarkerStylus::onGoal, this);
  ROS_INFO("marker_stylus: drag the marker on %s/update (frame %s), %.0f Hz on %s, at most %.3f m/s",
           serverName.c_str(), frameId_.c_str(), rate_, posePub_.getTopic().c_str(),
           place.maxSpeed);
  servo_ = std::thread(&MarkerStylus::servoLoop, this);
}

MarkerStylus::~MarkerStylus() {
  running_ = false;
  if (servo_.joinable()) servo_.join();
}

void MarkerStylus::makeMarker(const Eigen::Vector3d& start, double scale) {
  visualization_msgs::InteractiveMarker m;
  m.header.frame_id = frameId_;
  m.name = kMarkerName;
  m.description = "stylus (drag)";
  m.scale = static_cast<float>(scale);
  m.pose.orientation.w = 1.0;
  m.pose.position = toPoint(start);
  // A small sphere dragged in the view plane, and an arrow pair per axis for precise moves.
  visualization_msgs::InteractiveMarkerControl free =
      axisControl("move_3d", 0, 0, 0, visualization_msgs::InteractiveMarkerControl::MOVE_3D);
  free.always_visible = true;
  visualization_msgs::Marker ball;
  ball.type = visualization_msgs::Marker::SPHERE;
  ball.scale.x = ball.scale.y = ball.scale.z = 0.15 * scale;
  ball.color.r = 0.1f;
  ball.color.g = 0.8f;
  ball.color.b = 0.9f;
  ball.color.a = 0.5f;
  ball.pose.orientation.w = 1.0;
  free.markers.push_back(ball);
  m.controls.push_back(free);
  const auto axis = visualization_msgs::InteractiveMarkerControl::MOVE_AXIS;
  m.controls.push_back(axisControl("move_x", 1, 0, 0, axis));
  m.controls.push_back(axisControl("move_z", 0, 1, 0, axis));
  m.controls.push_back(axisControl("move_y", 0, 0, 1, axis));
  server_->insert(m, [this](const visualization_msgs::InteractiveMarkerFeedbackConstPtr& f) { onFeedback(f); });
  server_->applyChanges();
}

void MarkerStylus::onFeedback(const visualization_msgs::InteractiveMarkerFeedbackConstPtr& feedback) {
  if (feedback->marker_name != kMarkerName) return;
  setTarget(feedback->pose);
}

void MarkerStylus::onGoal(const geometry_msgs::PoseStampedConstPtr& goal) {
  if (!goal->header.frame_id.empty() && goal->header.frame_id != frameId_) {
    ROS_WARN_THROTTLE(5.0, "marker_stylus: ~goal in frame '%s' ignored (expected '%s')",
                      goal->header.frame_id.c_str(), frameId_.c_str());
    return;
  }
  setTarget(goal->pose);
  server_->setPose(kMarkerName, goal->pose);
  server_->applyChanges();
}

void MarkerStylus::setTarget(const geometry_msgs::Pose& pose) {
  const Eigen::Isometry3d t = fromPoseMsg(pose);
  if (!t.translation().allFinite()) return;
  std::lock_guard<std::mutex> lock(targetMutex_);
  target_ = t;
  targetChanged_ = true;
}

void MarkerStylus::servoLoop() {
  using Clock = std::chrono::steady_clock;
  const auto period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / rate_));
  const double dt = 1.0 / rate_;
  auto next = Clock::now();
  std::uint32_t seq = 0;
  while (running_ && ros::ok()) {
    {
      std::lock_guard<std::mutex> lock(targetMutex_);
      if (targetChanged_) interpolator_->setTarget(target_);
      targetChanged_ = false;
    }
    auto msg = boost::make_shared<geometry_msgs::PoseStamped>();
    msg->header.seq = ++seq;
    msg->header.stamp = ros::Time::now();
    msg->header.frame_id = frameId_;
    msg->pose = toPose(interpolator_->step(dt));
    posePub_.publish(msg);
    next += period;
    const auto now = Clock::now();
    if (now - next > 50 * period) next = now;  // stalled (suspended, overloaded): resume without a burst
    std::this_thread::sleep_until(next);
  }
}

}  // namespace clod_haptics
