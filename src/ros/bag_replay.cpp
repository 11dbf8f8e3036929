#include "clod_haptics/ros/bag_replay.h"

#include <geometry_msgs/PoseStamped.h>
#include <sensor_msgs/JointState.h>
#include <sensor_msgs/Joy.h>
#include <std_msgs/UInt64.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <thread>

#include "clod_haptics/ros/pose_msg.h"

namespace clod_haptics {
namespace device {

namespace {

bool readVector(const ros::NodeHandle& pnh, const std::string& key, Eigen::Vector3d& out) {
  std::vector<double> values;
  if (!pnh.getParam(key, values)) {
    if (pnh.hasParam(key)) throw std::invalid_argument("~" + key + " must be a list of 3 numbers");
    return false;
  }
  if (values.size() != 3) {
    throw std::invalid_argument("~" + key + " must be a list of 3 numbers, got " + std::to_string(values.size()));
  }
  out = Eigen::Vector3d(values[0], values[1], values[2]);
  if (!out.allFinite()) throw std::invalid_argument("~" + key + " must be finite");
  return true;
}

void requireFinite(double value, const char* name, bool positive) {
  if (!std::isfinite(value) || (positive ? value <= 0.0 : value < 0.0)) {
    throw std::invalid_argument(std::string("~") + name + " must be finite and " +
                                (positive ? "positive" : "non-negative") + ", got " + std::to_string(value));
  }
}

/** A relative ~bag is the user's: found relative to $PWD first, since roslaunch runs nodes in $ROS_HOME. */
BagReplayParams withBagResolved(const BagReplayParams& params) {
  BagReplayParams p = params;
  p.bag = resolveBagPath(p.bag);
  return p;
}

}  // namespace

BagReplayParams BagReplay::readParameters(const ros::NodeHandle& pnh) {
  BagReplayParams p;
  if (!pnh.getParam("bag", p.bag) || p.bag.empty()) {
    throw std::invalid_argument("~bag is required: the path of a rosbag with the stylus motion");
  }
  pnh.param("topic", p.read.topic, p.read.topic);
  pnh.param("joint_topic", p.read.jointTopic, p.read.jointTopic);
  pnh.param("position_scale", p.read.positionScale, p.read.positionScale);
  if (!pnh.getParam("omni_name", p.name)) pnh.param("name", p.name, p.name);
  pnh.param("frame_id", p.frameId, p.frameId);
  pnh.param("rate", p.rate, p.rate);
  pnh.param("rate_scale", p.rateScale, p.rateScale);
  pnh.param("loop", p.loop, p.loop);
  pnh.param("scale", p.transform.scale, p.transform.scale);
  readVector(pnh, "offset", p.transform.offset);
  Eigen::Vector3d rpy = Eigen::Vector3d::Zero();
  readVector(pnh, "rotation_rpy", rpy);
  p.transform.rotation = WorkspaceTransform::fromRpy(rpy.x(), rpy.y(), rpy.z());
  pnh.param("fit_size", p.fitSize, p.fitSize);
  readVector(pnh, "fit_center", p.fitCenter);
  pnh.param("start_delay", p.startDelay, p.startDelay);
  pnh.param("wait_for_subscribers", p.waitForSubscribers, p.waitForSubscribers);
  pnh.param("wait_timeout", p.waitTimeout, p.waitTimeout);
  pnh.param("exit_delay", p.exitDelay, p.exitDelay);

  if (p.name.empty()) throw std::invalid_argument("~omni_name must not be empty");
  requireFinite(p.rate, "rate", false);
  if (p.rate > 20000.0) throw std::invalid_argument("~rate above 20 kHz makes no sense for a haptic stream");
  requireFinite(p.rateScale, "rate_scale", true);
  requireFinite(p.transform.scale, "scale", true);
  requireFinite(p.fitSize, "fit_size", false);
  requireFinite(p.startDelay, "start_delay", false);
  requireFinite(p.waitTimeout, "wait_timeout", false);
  requireFinite(p.exitDelay, "exit_delay", false);
  if (p.waitForSubscribers < 0) throw std::invalid_argument("~wait_for_subscribers must be >= 0");
  p.fit = p.fitSize > 0.0;
  return p;
}

BagReplay::BagReplay(ros::NodeHandle nh, ros::NodeHandle pnh)
    : nh_(nh),
      pnh_(pnh),
      params_(withBagResolved(readParameters(pnh))),
      motion_(readStylusBag(params_.bag, params_.read)) {
  if (params_.fit) {
    params_.transform = motion_.trajectory.fitInto(params_.fitCenter, params_.fitSize, params_.transform.rotation);
  }
  const StylusTrajectory source = motion_.trajectory.transformed(params_.transform);
  trajectory_ = params_.rate > 0.0 ? source.resampled(params_.rate) : source;
  if (params_.frameId.empty()) params_.frameId = motion_.frameId.empty() ? "world" : motion_.frameId;

  const Eigen::AlignedBox3d box = trajectory_.bounds();
  ROS_INFO(
      "bag_replay: '%s' topic %s (%s): %zu messages, %.2f s, %.0f Hz recorded, %zu dropped; "
      "%zu poses at %.0f Hz x%.2f%s; positions x%.4g to metres, then scale %.4g, offset (%.4f, %.4f, %.4f); "
      "workspace [%.4f %.4f %.4f] .. [%.4f %.4f %.4f] m in frame '%s'",
      params_.bag.c_str(), motion_.topic.c_str(), motion_.type.c_str(), motion_.messages, motion_.trajectory.duration(),
      motion_.trajectory.meanRate(), motion_.trajectory.dropped(), trajectory_.size(),
      params_.rate > 0 ? params_.rate : motion_.trajectory.meanRate(), params_.rateScale,
      params_.loop ? ", looping" : "", motion_.positionScale, params_.transform.scale, params_.transform.offset.x(),
      params_.transform.offset.y(), params_.transform.offset.z(), box.min().x(), box.min().y(), box.min().z(),
      box.max().x(), box.max().y(), box.max().z(), params_.frameId.c_str());

  posePub_ = nh_.advertise<geometry_msgs::PoseStamped>(params_.name + "/pose", 1000);
  buttonPub_ = nh_.advertise<sensor_msgs::Joy>(params_.name + "/button", 1, true);
  jointPub_ = nh_.advertise<sensor_msgs::JointState>(params_.name + "/joint_states", 100);
  donePub_ = pnh_.advertise<std_msgs::UInt64>("done", 1, true);
}

void BagReplay::run() {
  publishReleasedButton();
  waitForSubscribers();
  std::this_thread::sleep_for(std::chrono::duration<double>(params_.startDelay));
  const auto start = Clock::now();
  const std::uint64_t passes = play(start);
  reportDone(std::chrono::duration<double>(Clock::now() - start).count(), passes);
  if (ros::ok()) std::this_thread::sleep_for(std::chrono::duration<double>(params_.exitDelay));
}

void BagReplay::publishReleasedButton() {
  // A recording has no buttons: publish "released" once (the bridge publishes on change).
  sensor_msgs::Joy button;
  button.header.stamp = ros::Time::now();
  button.header.frame_id = params_.frameId;
  button.buttons = {0, 0};
  buttonPub_.publish(button);
}

void BagReplay::waitForSubscribers() {
  if (params_.waitForSubscribers <= 0) return;
  const auto wanted = static_cast<std::uint32_t>(params_.waitForSubscribers);
  const auto deadline = Clock::now() + std::chrono::duration<double>(params_.waitTimeout);
  while (ros::ok() && posePub_.getNumSubscribers() < wanted && Clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  if (posePub_.getNumSubscribers() < wanted) {
    ROS_WARN("bag_replay: %u of %d subscribers on %s after %.1f s; starting anyway", posePub_.getNumSubscribers(),
             params_.waitForSubscribers, posePub_.getTopic().c_str(), params_.waitTimeout);
  }
}

std::uint64_t BagReplay::play(Clock::time_point start) {
  const StylusSamples& samples = trajectory_.samples();
  const bool haveJoints = !motion_.joints.empty();
  // Joint states at the recorded joint rate at most (they are not on the haptic path).
  const double jointPeriod =
      haveJoints && motion_.joints.size() > 1
          ? std::max(0.0, (motion_.joints.back().time - motion_.joints.front().time) / (motion_.joints.size() - 1))
          : 0.0;
  geometry_msgs::PoseStamped pose;
  pose.header.frame_id = params_.frameId;
  double passOffset = 0.0;  // recorded seconds played by earlier passes
  std::uint64_t passes = 0;
  do {
    double nextJoint = 0.0;
    for (std::size_t k = 0; k < samples.size() && ros::ok(); ++k) {
      const StylusSample& s = samples[k];
      const auto due = start + std::chrono::duration_cast<Clock::duration>(
                                   std::chrono::duration<double>((passOffset + s.time) / params_.rateScale));
      std::this_thread::sleep_until(due);
      pose.header.stamp = ros::Time::now();
      pose.header.seq = static_cast<std::uint32_t>(published_);
      toPoseMsg(s.position, s.orientation, pose.pose);
      posePub_.publish(pose);
      ++published_;
      if (haveJoints && s.time >= nextJoint) {
        publishJoints(s.time, pose.header.stamp);
        nextJoint = s.time + jointPeriod;
      }
    }
    ++passes;
    // The next pass starts one sample period after this one's last sample.
    passOffset += trajectory_.duration() + (params_.rate > 0.0 ? 1.0 / params_.rate : 0.0);
  } while (params_.loop && ros::ok());
  return passes;
}

void BagReplay::publishJoints(double t, const ros::Time& stamp) {
  const JointSample j = interpolateJoints(motion_.joints, t);
  sensor_msgs::JointState joints;
  joints.header.stamp = stamp;
  joints.name = j.names;
  joints.position = j.positions;
  jointPub_.publish(joints);
}

void BagReplay::reportDone(double elapsed, std::uint64_t passes) {
  char summary[256];
  std::snprintf(summary, sizeof(summary),
                "bag_replay: published %llu poses in %.2f s (%.0f Hz achieved, %.0f Hz intended), %llu pass(es)%s",
                static_cast<unsigned long long>(published_), elapsed, elapsed > 0 ? published_ / elapsed : 0.0,
                (params_.rate > 0 ? params_.rate : motion_.trajectory.meanRate()) * params_.rateScale,
                static_cast<unsigned long long>(passes), ros::ok() ? "" : ", interrupted");
  // After shutdown (Ctrl-C) rosconsole prints nothing: the summary goes to stdout then.
  if (ros::ok()) {
    ROS_INFO("%s", summary);
  } else {
    std::printf("%s\n", summary);
    std::fflush(stdout);
  }
  std_msgs::UInt64 done;
  done.data = published_;
  donePub_.publish(done);
}

}  // namespace device
}  // namespace clod_haptics
