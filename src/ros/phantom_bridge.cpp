#include "clod_haptics/ros/phantom_bridge.h"

#include <geometry_msgs/PoseStamped.h>
#include <sensor_msgs/JointState.h>
#include <sensor_msgs/Joy.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "clod_haptics/device/simulated_device.h"
#include "clod_haptics/ros/pose_msg.h"
#ifdef CLOD_WITH_OPENHAPTICS
#include "clod_haptics/device/openhaptics_device.h"
#endif

namespace clod_haptics {
namespace device {

namespace {

double steadyNow() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

const char* kJointNames[6] = {"waist", "shoulder", "elbow", "yaw", "pitch", "roll"};

Eigen::Vector3d readVector(const ros::NodeHandle& pnh, const std::string& key, const Eigen::Vector3d& fallback) {
  std::vector<double> values;
  if (!pnh.getParam(key, values)) return fallback;
  if (values.size() != 3) {
    throw std::invalid_argument("~" + key + " must be a list of 3 numbers, got " + std::to_string(values.size()));
  }
  return Eigen::Vector3d(values[0], values[1], values[2]);
}

}  // namespace

PhantomBridgeParams PhantomBridge::readParameters(const ros::NodeHandle& pnh) {
  PhantomBridgeParams p;
  // omni_common's name for the topic prefix; ~name is accepted too.
  if (!pnh.getParam("omni_name", p.name)) pnh.param("name", p.name, p.name);
  pnh.param("frame_id", p.frameId, p.frameId);
  pnh.param("rate", p.rate, p.rate);
  pnh.param("max_force", p.safety.maxForce, p.safety.maxForce);
  pnh.param("max_force_rate", p.safety.maxForceRate, p.safety.maxForceRate);
  pnh.param("force_timeout", p.safety.staleTimeout, p.safety.staleTimeout);
  if (p.name.empty()) throw std::invalid_argument("~omni_name must not be empty");
  if (!std::isfinite(p.rate) || p.rate < 1.0 || p.rate > 10000.0) {
    throw std::invalid_argument("~rate must be between 1 and 10000 Hz, got " + std::to_string(p.rate));
  }
  validate(p.safety);
  if (p.safety.maxForce > kTouchPeakForce) {
    throw std::invalid_argument("~max_force " + std::to_string(p.safety.maxForce) +
                                " N exceeds the Geomagic Touch's peak force (3.3 N)");
  }
  if (p.safety.maxForce > kTouchContinuousForce) {
    ROS_WARN("~max_force %.2f N is above the Geomagic Touch's continuous rating (%.2f N): only for short contacts",
             p.safety.maxForce, kTouchContinuousForce);
  }
  return p;
}

std::unique_ptr<HapticDevice> PhantomBridge::createDevice(const ros::NodeHandle& pnh) {
  std::string backend;
#ifdef CLOD_WITH_OPENHAPTICS
  pnh.param("backend", backend, std::string("openhaptics"));
#else
  pnh.param("backend", backend, std::string("simulated"));
#endif
  if (backend == "simulated") {
    std::string script;
    bool loop = true;
    pnh.param("sim/loop", loop, loop);
    if (pnh.getParam("sim/script", script) && !script.empty()) {
      return std::make_unique<SimulatedDevice>(SimulatedDevice::loadCsvScript(script), loop);
    }
    double radius = 0.03, period = 4.0;
    pnh.param("sim/radius", radius, radius);
    pnh.param("sim/period", period, period);
    Eigen::Vector3d centre;
    try {
      centre = readVector(pnh, "sim/centre", Eigen::Vector3d(0.0, 0.0, 0.05));
    } catch (const std::invalid_argument& e) {
      throw DeviceError(e.what());
    }
    return std::make_unique<SimulatedDevice>(SimulatedDevice::circleScript(centre, radius, period), loop);
  }
  if (backend == "openhaptics") {
#ifdef CLOD_WITH_OPENHAPTICS
    std::string deviceName;
    pnh.param("device_name", deviceName, std::string());
    return std::make_unique<OpenHapticsDevice>(deviceName);
#else
    throw DeviceError(
        "~backend 'openhaptics': this build has no OpenHaptics support (the HD headers and library were not "
        "found at configure time). Install the OpenHaptics SDK and rebuild with -DCLOD_WITH_OPENHAPTICS=ON "
        "(-DOPENHAPTICS_ROOT=<dir> if it is not under /usr or /opt/OpenHaptics); or run the simulated device: "
        "roslaunch clod_haptics clod_haptics.launch device:=phantom backend:=simulated, or "
        "CLOD_PHANTOM_BACKEND=simulated roslaunch clod_haptics clod_haptics.launch device:=phantom");
#endif
  }
  throw DeviceError("~backend must be 'simulated' or 'openhaptics', got '" + backend + "'");
}

PhantomBridge::PhantomBridge(ros::NodeHandle nh, ros::NodeHandle pnh, std::unique_ptr<HapticDevice> device)
    : nh_(nh), pnh_(pnh), params_(readParameters(pnh)), device_(std::move(device)), safety_(params_.safety) {
  if (!device_) throw std::invalid_argument("phantom bridge: no device");
  posePub_ = nh_.advertise<geometry_msgs::PoseStamped>(params_.name + "/pose", 100);
  buttonPub_ = nh_.advertise<sensor_msgs::Joy>(params_.name + "/button", 10, true);
  jointPub_ = nh_.advertise<sensor_msgs::JointState>(params_.name + "/joint_states", 100);
  renderedPub_ = pnh_.advertise<geometry_msgs::WrenchStamped>("rendered_force", 100);
  forceSub_ = nh_.subscribe(params_.name + "/force_feedback", 10, &PhantomBridge::onForce, this,
                            ros::TransportHints().tcpNoDelay());
  ROS_INFO(
      "phantom_bridge: device %s, %s/pose at %.0f Hz in frame '%s'; force clamp %.2f N, rate limit %.0f N/s, "
      "timeout %.0f ms",
      device_->name().c_str(), params_.name.c_str(), params_.rate, params_.frameId.c_str(), params_.safety.maxForce,
      params_.safety.maxForceRate, 1000.0 * params_.safety.staleTimeout);
}

PhantomBridge::~PhantomBridge() { stop(); }

void PhantomBridge::start() {
  if (running_) return;
  device_->start();
  running_ = true;
  startWall_ = steadyNow();
  servo_ = std::thread(&PhantomBridge::servoLoop, this);
}

void PhantomBridge::stop() {
  const bool wasRunning = running_.exchange(false);
  if (servo_.joinable()) servo_.join();
  if (wasRunning) {
    device_->commandForce(Eigen::Vector3d::Zero());
    device_->stop();
    const double elapsed = steadyNow() - startWall_;
    const ForceSafetyCounters& c = safety_.counters();
    char summary[256];
    std::snprintf(summary, sizeof(summary),
                  "phantom_bridge: %llu ticks in %.1f s (%.0f Hz); forces clamped %llu, non-finite %llu, stale %llu, "
                  "rate-limited %llu",
                  static_cast<unsigned long long>(ticks_.load()), elapsed, elapsed > 0 ? ticks_ / elapsed : 0.0,
                  static_cast<unsigned long long>(c.clamped), static_cast<unsigned long long>(c.nonFinite),
                  static_cast<unsigned long long>(c.stale), static_cast<unsigned long long>(c.rateLimited));
    // After shutdown (Ctrl-C) rosconsole prints nothing: the summary goes to stdout then.
    if (ros::ok()) {
      ROS_INFO("%s", summary);
    } else {
      std::printf("%s\n", summary);
      std::fflush(stdout);
    }
  }
}

void PhantomBridge::onForce(const geometry_msgs::WrenchStamped::ConstPtr& msg) {
  const double now = steadyNow();
  std::lock_guard<std::mutex> lock(commandMutex_);
  command_.force = Eigen::Vector3d(msg->wrench.force.x, msg->wrench.force.y, msg->wrench.force.z);
  command_.receivedAt = now;
  command_.valid = true;
}

void PhantomBridge::servoLoop() {
  using Clock = std::chrono::steady_clock;
  const auto period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / params_.rate));
  auto next = Clock::now();
  while (running_ && ros::ok()) {
    tick(steadyNow());
    next += period;
    const auto now = Clock::now();
    if (now > next + 10 * period) next = now;  // fell far behind (machine busy): do not burst to catch up
    std::this_thread::sleep_until(next);
  }
}

void PhantomBridge::tick(double now) {
  ++ticks_;
  DeviceState state;
  const bool haveState = device_->read(state);
  const ros::Time stamp = ros::Time::now();
  if (haveState) {
    geometry_msgs::PoseStamped pose;
    // Consecutive numbers, as bag_replay gives them: the detector counts a gap as poses lost on the way.
    pose.header.seq = static_cast<std::uint32_t>(++posesPublished_);
    pose.header.stamp = stamp;
    pose.header.frame_id = params_.frameId;
    toPoseMsg(state.position, state.orientation, pose.pose);
    posePub_.publish(pose);

    sensor_msgs::JointState joints;
    joints.header.stamp = stamp;
    joints.name.assign(kJointNames, kJointNames + 6);
    joints.position.assign(state.joints.begin(), state.joints.end());
    jointPub_.publish(joints);

    if (!buttonsKnown_ || state.buttons != lastButtons_) {
      sensor_msgs::Joy button;
      button.header.stamp = stamp;
      button.header.frame_id = params_.frameId;
      button.buttons = {(state.buttons & kGreyButton) ? 1 : 0, (state.buttons & kWhiteButton) ? 1 : 0};
      buttonPub_.publish(button);
      buttonsKnown_ = true;
      lastButtons_ = state.buttons;
    }
  } else {
    ROS_WARN_THROTTLE(1.0, "phantom_bridge: no state from device %s", device_->name().c_str());
  }

  ForceCommand command;
  {
    std::lock_guard<std::mutex> lock(commandMutex_);
    command = command_;
  }
  ForceStatus status;
  const Eigen::Vector3d force = safety_.update(command, now, &status);
  device_->commandForce(force);

  if (status == ForceStatus::NonFinite) {
    ROS_WARN_THROTTLE(1.0, "phantom_bridge: non-finite force command (%g, %g, %g): rendering zero force",
                      command.force.x(), command.force.y(), command.force.z());
  } else if (status == ForceStatus::Stale && lastStatus_ != ForceStatus::Stale) {
    ROS_WARN_THROTTLE(1.0, "phantom_bridge: force command is %.0f ms old (timeout %.0f ms): rendering zero force",
                      1000.0 * (now - command.receivedAt), 1000.0 * params_.safety.staleTimeout);
  } else if (status == ForceStatus::Clamped) {
    ROS_WARN_THROTTLE(1.0, "phantom_bridge: force %.2f N clamped to %.2f N", command.force.norm(),
                      params_.safety.maxForce);
  }
  lastStatus_ = status;

  if (renderedPub_.getNumSubscribers() > 0) {
    geometry_msgs::WrenchStamped rendered;
    rendered.header.stamp = stamp;
    rendered.header.frame_id = params_.frameId;
    rendered.wrench.force.x = force.x();
    rendered.wrench.force.y = force.y();
    rendered.wrench.force.z = force.z();
    renderedPub_.publish(rendered);
  }
}

}  // namespace device
}  // namespace clod_haptics
