#include "clod_haptics/ros/phantom_bridge.h"

#include <geometry_msgs/PoseStamped.h>
#include <sensor_msgs/JointState.h>
#include <sensor_msgs/Joy.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#include "clod_haptics/device/simulated_device.h"
#include "clod_haptics/ros/pose_msg.h"

namespace clod_haptics {
namespace device {

namespace {

double steadyNow() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

const char* kJointNames[6] = {"waist", "shoulder", "elbow", "yaw", "pitch", "roll"};

double wallNow() { return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count(); }

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
  pnh.param("device_timeout", p.deviceTimeout, p.deviceTimeout);
  pnh.param("servo_render", p.servoRender, p.servoRender);
  pnh.param("detector", p.detector, p.detector);
  if (p.name.empty()) throw std::invalid_argument("~omni_name must not be empty");
  if (!std::isfinite(p.rate) || p.rate < 1.0 || p.rate > 10000.0) {
    throw std::invalid_argument("~rate must be between 1 and 10000 Hz, got " + std::to_string(p.rate));
  }
  if (!std::isfinite(p.deviceTimeout) || p.deviceTimeout <= 0.0) {
    throw std::invalid_argument("~device_timeout must be a positive number of seconds, got " +
                                std::to_string(p.deviceTimeout));
  }
  validate(p.safety);
  return p;
}

OpenHapticsOptions PhantomBridge::readOpenHapticsOptions(const ros::NodeHandle& pnh) {
  OpenHapticsOptions o;
  pnh.param("device_name", o.deviceName, o.deviceName);
  pnh.param("damping", o.damping, o.damping);
  pnh.param("max_force", o.maxForce, o.maxForce);
  pnh.param("force_timeout", o.forceTimeout, o.forceTimeout);
  std::string convention = "omni_common";
  pnh.param("joint_convention", convention, convention);
  o.joints = parseJointConvention(convention);
  o.tipOffset = readVector(pnh, "tip_offset", o.tipOffset);
  if (!std::isfinite(o.damping) || o.damping < 0.0 || o.damping > 10.0) {
    throw std::invalid_argument("~damping must be between 0 and 10 N s/m (the drivers use 1.0), got " +
                                std::to_string(o.damping));
  }
  if (!o.tipOffset.allFinite() || o.tipOffset.norm() > 0.2) {
    throw std::invalid_argument("~tip_offset must be finite and shorter than 0.2 m");
  }
  return o;
}

std::unique_ptr<HapticDevice> PhantomBridge::createDevice(const ros::NodeHandle& pnh,
                                                          const OpenHapticsFactory& openhaptics) {
  std::string backend;
  pnh.param("backend", backend, std::string(openhaptics ? "openhaptics" : "simulated"));
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
    if (openhaptics) {
      try {
        return openhaptics(readOpenHapticsOptions(pnh));
      } catch (const std::invalid_argument& e) {
        throw DeviceError(e.what());
      }
    }
    throw DeviceError(
        "~backend 'openhaptics': this build has no OpenHaptics support (the HD headers and library were not "
        "found at configure time). Install the OpenHaptics SDK and rebuild with -DCLOD_WITH_OPENHAPTICS=ON "
        "(-DOPENHAPTICS_ROOT=<dir> if it is not under /usr or /opt/OpenHaptics); or run the simulated device: "
        "roslaunch clod_haptics clod_haptics.launch device:=phantom backend:=simulated, or "
        "CLOD_PHANTOM_BACKEND=simulated roslaunch clod_haptics clod_haptics.launch device:=phantom");
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

void PhantomBridge::startServoRender() {
  servoLink_.reset();
  deviceRenders_ = false;
  if (!params_.servoRender) return;
  try {
    servoLink_ = std::make_unique<ServoRenderLink>(nh_, params_.detector, params_.frameId);
  } catch (const std::exception& e) {
    ROS_WARN("phantom_bridge: servo rendering off, rendering %s/force_feedback instead: %s", params_.name.c_str(),
             e.what());
    return;
  }
  deviceRenders_ = device_->attachServoRenderer(servoLink_->renderer());
  ROS_INFO("phantom_bridge: the proxy is rendered in the %s against %s; %s/force_feedback is used while %s's "
           "force_model is penalty",
           deviceRenders_ ? "device's servo loop" : "bridge's loop", servoLink_->description().c_str(),
           params_.name.c_str(), params_.detector.c_str());
}

void PhantomBridge::start() {
  if (running_) return;
  startServoRender();
  device_->start();
  deviceStarted_ = true;
  try {
    checkRatings();
  } catch (...) {
    deviceStarted_ = false;
    device_->stop();
    throw;
  }
  {
    DeviceState ignored;
    device_->read(ignored);
  }
  if (device_->condition() == DeviceCondition::Calibrating) {
    ROS_WARN("phantom_bridge: %s", device_->conditionText().c_str());
  }
  running_ = true;
  startWall_ = steadyNow();
  lastStateAt_ = startWall_;
  servo_ = std::thread(&PhantomBridge::servoLoop, this);
}

void PhantomBridge::checkRatings() {
  const ForceRatings r = device_->ratings();
  const double maxForce = params_.safety.maxForce;
  if (maxForce > r.peak) {
    throw DeviceError("~max_force " + std::to_string(maxForce) + " N exceeds the device's peak force (" +
                      std::to_string(r.peak) + " N, HD_NOMINAL_MAX_FORCE for OpenHaptics)");
  }
  if (maxForce > r.continuous) {
    ROS_WARN("~max_force %.2f N is above the device's continuous rating (%.2f N): only for short contacts", maxForce,
             r.continuous);
  }
}

std::string PhantomBridge::failure() const {
  std::lock_guard<std::mutex> lock(failureMutex_);
  return failure_;
}

void PhantomBridge::fail(const std::string& reason) {
  ROS_FATAL("phantom_bridge: %s; stopping (exit code 1, for the launch file's respawn or required)", reason.c_str());
  {
    std::lock_guard<std::mutex> lock(failureMutex_);
    failure_ = reason;
  }
  running_ = false;
  ros::requestShutdown();
}

void PhantomBridge::stop() {
  running_ = false;
  if (servo_.joinable()) servo_.join();
  if (!deviceStarted_) return;
  deviceStarted_ = false;
  device_->commandForce(Eigen::Vector3d::Zero());
  device_->stop();
  const double elapsed = steadyNow() - startWall_;
  const ForceSafetyCounters& c = safety_.counters();
  char summary[1024];
  int n = std::snprintf(summary, sizeof(summary),
                        "phantom_bridge: %llu ticks in %.1f s (%.0f Hz); forces clamped %llu, non-finite %llu, "
                        "stale %llu, rate-limited %llu",
                        static_cast<unsigned long long>(ticks_.load()), elapsed, elapsed > 0 ? ticks_ / elapsed : 0.0,
                        static_cast<unsigned long long>(c.clamped), static_cast<unsigned long long>(c.nonFinite),
                        static_cast<unsigned long long>(c.stale), static_cast<unsigned long long>(c.rateLimited));
  const LatencyHistogram* loop = device_->forceLoopLatency();
  if (loop && loop->count() > 0 && n > 0 && static_cast<std::size_t>(n) < sizeof(summary)) {
    std::snprintf(summary + n, sizeof(summary) - static_cast<std::size_t>(n),
                  "; force loop (pose read in the servo loop -> its force back there) over %llu forces: "
                  "p50 %.0f us, p99 %.0f us, p99.9 %.0f us, max %.0f us",
                  static_cast<unsigned long long>(loop->count()), loop->percentileUs(50), loop->percentileUs(99),
                  loop->percentileUs(99.9), loop->maxUs());
    n = static_cast<int>(std::strlen(summary));
    std::snprintf(summary + n, sizeof(summary) - static_cast<std::size_t>(n),
                  "; device read -> force handed to the device p50 %.0f us, p99 %.0f us, max %.0f us; of which "
                  "device read -> pose published p50 %.0f us, p99 %.0f us, force received -> handed over p50 %.0f "
                  "us, p99 %.0f us",
                  handOver_.percentileUs(50), handOver_.percentileUs(99), handOver_.maxUs(), poseWait_.percentileUs(50),
                  poseWait_.percentileUs(99), forceWait_.percentileUs(50), forceWait_.percentileUs(99));
  }
  // After shutdown (Ctrl-C) rosconsole prints nothing: the summary goes to stdout then.
  if (ros::ok()) {
    ROS_INFO("%s", summary);
  } else {
    std::printf("%s\n", summary);
    std::fflush(stdout);
  }
}

void PhantomBridge::onForce(const geometry_msgs::WrenchStamped::ConstPtr& msg) {
  const double now = steadyNow();
  std::lock_guard<std::mutex> lock(commandMutex_);
  commandStamp_ = msg->header.stamp.toSec();
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
  // A thread that stops on its own (the device failed) leaves the device at zero force.
  device_->commandForce(Eigen::Vector3d::Zero());
}

void PhantomBridge::publishState(const DeviceState& state) {
  // The moment the device was read, when the device knows it (OpenHaptics' servo frame): the detector copies
  // it into the force, which the device then measures its force loop with.
  const ros::Time stamp = (state.stamp > 0.0 && !ros::Time::isSimTime()) ? ros::Time(state.stamp) : ros::Time::now();
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
}

void PhantomBridge::noState(double now) {
  const DeviceCondition condition = device_->condition();
  if (condition == DeviceCondition::Failed) {
    fail(device_->conditionText());
    return;
  }
  if (condition == DeviceCondition::Calibrating) {
    lastStateAt_ = now;  // waiting for the user, not a fault
    ROS_WARN_THROTTLE(5.0, "phantom_bridge: %s", device_->conditionText().c_str());
    return;
  }
  const std::string text = device_->conditionText();
  if (now - lastStateAt_ > params_.deviceTimeout) {
    char what[96];
    std::snprintf(what, sizeof what, "no state from the device for %.1f s (~device_timeout): ", now - lastStateAt_);
    fail(what + (text.empty() ? device_->name() : text));
    return;
  }
  if (condition != DeviceCondition::NotStarted) {  // the first servo frames: only the timeout above counts
    ROS_WARN_THROTTLE(1.0, "phantom_bridge: no state: %s", text.empty() ? device_->name().c_str() : text.c_str());
  }
}

ForceCommand PhantomBridge::nextCommand(double now, const DeviceState* state, double& commandStamp) {
  if (servoLink_ && !deviceRenders_ && state != nullptr) {
    // This loop is the device's servo loop: the force answers the state just read.
    ForceCommand rendered;
    if (servoLink_->renderer()->render(state->position, state->time, rendered.force, state->stamp)) {
      rendered.receivedAt = now;
      rendered.valid = true;
      commandStamp = 0.0;
      return rendered;
    }
  }
  std::lock_guard<std::mutex> lock(commandMutex_);
  commandStamp = commandStamp_;
  return command_;
}

void PhantomBridge::tick(double now) {
  ++ticks_;
  DeviceState state;
  const bool haveState = device_->read(state);
  if (haveState) {
    lastStateAt_ = now;
    publishState(state);
    if (state.stamp > 0.0) poseWait_.record(static_cast<std::int64_t>((steadyNow() - state.time) * 1e9));
  } else {
    noState(now);
    if (!running_) return;
  }

  double commandStamp = 0.0;
  const ForceCommand command = nextCommand(now, haveState ? &state : nullptr, commandStamp);
  ForceStatus status;
  const Eigen::Vector3d force = safety_.update(command, now, &status);
  device_->commandForceFor(force, ros::Time::isSimTime() ? 0.0 : commandStamp);
  if (command.valid && commandStamp != lastHandedStamp_) {
    forceWait_.record(static_cast<std::int64_t>((steadyNow() - command.receivedAt) * 1e9));
    if (commandStamp > 0.0) handOver_.record(static_cast<std::int64_t>((wallNow() - commandStamp) * 1e9));
    lastHandedStamp_ = commandStamp;
  }

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

  Eigen::Vector3d shown = force;
  ros::Time shownStamp = ros::Time::now();
  if (servoLink_ && deviceRenders_) {  // what the servo loop renders (before the device's own clamp)
    ServoRenderTick servoTick;
    if (servoLink_->renderer()->latest(servoTick)) {
      lastServoForce_ = servoTick.deviceForce;
      lastServoStamp_ = servoTick.stamp;
    }
    if (servoLink_->enabled()) {
      shown = lastServoForce_;
      // The stamp of the device read it answers, as that frame's pose carries it.
      if (lastServoStamp_ > 0.0 && !ros::Time::isSimTime()) shownStamp = ros::Time(lastServoStamp_);
    }
  }
  if (renderedPub_.getNumSubscribers() > 0) {
    geometry_msgs::WrenchStamped rendered;
    rendered.header.stamp = shownStamp;
    rendered.header.frame_id = params_.frameId;
    rendered.wrench.force.x = shown.x();
    rendered.wrench.force.y = shown.y();
    rendered.wrench.force.z = shown.z();
    renderedPub_.publish(rendered);
  }
}

}  // namespace device
}  // namespace clod_haptics
