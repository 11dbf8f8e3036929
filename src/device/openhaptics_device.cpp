// Built with the OpenHaptics SDK (CLOD_WITH_OPENHAPTICS), and in the tests against the fake libHD of
// test/device/fake_libhd.
#include "clod_haptics/device/openhaptics_device.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <mutex>
#include <thread>

#include "openhaptics_sdk.h"  // last: see there

namespace clod_haptics {
namespace device {

namespace {

double steadySeconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

double wallSeconds() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

std::string hdErrorText(unsigned int code, int internal) {
  const char* text = hdGetErrorString(code);
  char numbers[64];
  std::snprintf(numbers, sizeof numbers, " (HD error 0x%04x, internal %d)", code, internal);
  return std::string(text ? text : "unknown HD error") + numbers;
}

// The most recent error on this thread's HD error stack, which is emptied (a stack left full would report
// this frame's error again in the next one); a scheduler error wins over the others.
HDErrorInfo takeErrors(bool* schedulerError) {
  HDErrorInfo first{HD_SUCCESS, 0, 0};
  *schedulerError = false;
  for (int i = 0; i < 16; ++i) {
    const HDErrorInfo e = hdGetError();
    if (!HD_DEVICE_ERROR(e)) break;
    if (i == 0) first = e;
    if (hduIsSchedulerError(&e) && !*schedulerError) {
      *schedulerError = true;
      first = e;
    }
  }
  return first;
}

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wattributes"  // HDCALLBACK is stdcall on Linux, ignored on x86-64
HDCallbackCode HDCALLBACK servoCallback(void* data) {
  return static_cast<OpenHapticsDevice*>(data)->servo() ? HD_CALLBACK_CONTINUE : HD_CALLBACK_DONE;
}
#pragma GCC diagnostic pop

// Device axes (x right, y up, z towards the user) to ROS axes (z up): (x, y, z) -> (x, -z, y).
const Eigen::Matrix3d& deviceToRos() {
  static const Eigen::Matrix3d c = (Eigen::Matrix3d() << 1, 0, 0, 0, 0, -1, 0, 1, 0).finished();
  return c;
}

// The HD scheduler is one per process, shared by every device: started with the first, stopped with the last.
std::mutex gSchedulerMutex;
int gSchedulerUsers = 0;

}  // namespace

OpenHapticsDevice::OpenHapticsDevice(OpenHapticsOptions options) : options_(std::move(options)) {}

OpenHapticsDevice::~OpenHapticsDevice() { stop(); }

std::string OpenHapticsDevice::name() const {
  return "openhaptics:" + (options_.deviceName.empty() ? std::string("default device") : options_.deviceName);
}

void OpenHapticsDevice::start() {
  if (started_) return;
  bool schedulerError = false;
  const HHD hhd = hdInitDevice(options_.deviceName.empty() ? HD_DEFAULT_DEVICE : options_.deviceName.c_str());
  HDErrorInfo error = takeErrors(&schedulerError);
  if (HD_DEVICE_ERROR(error)) {
    throw DeviceError("OpenHaptics: cannot initialise " + name() + ": " +
                      hdErrorText(error.errorCode, error.internalErrorCode) +
                      " (is the device plugged in and configured with Geomagic Touch Setup under this name?)");
  }
  handle_ = hhd;
  hdMakeCurrentDevice(hhd);
  const char* model = hdGetString(HD_DEVICE_MODEL_TYPE);
  model_ = model ? model : "unknown model";
  HDint styles = 0;
  hdGetIntegerv(HD_CALIBRATION_STYLE, &styles);
  // The drivers' preference: automatic, else the inkwell, else an encoder reset.
  calibrationStyle_ = (styles & HD_CALIBRATION_AUTO)      ? HD_CALIBRATION_AUTO
                      : (styles & HD_CALIBRATION_INKWELL) ? HD_CALIBRATION_INKWELL
                                                          : HD_CALIBRATION_ENCODER_RESET;
  HDdouble peak = 0.0, continuous = 0.0;
  hdGetDoublev(HD_NOMINAL_MAX_FORCE, &peak);
  hdGetDoublev(HD_NOMINAL_MAX_CONTINUOUS_FORCE, &continuous);
  if (peak > 0.0) ratings_.peak = peak;
  if (continuous > 0.0) ratings_.continuous = continuous;
  maxForce_ = std::min(options_.maxForce, ratings_.peak);
  takeErrors(&schedulerError);  // a device without these parameters leaves the defaults
  hdEnable(HD_FORCE_OUTPUT);
  stopping_ = false;
  failed_ = false;
  callback_ = hdScheduleAsynchronous(servoCallback, this, HD_MAX_SCHEDULER_PRIORITY);
  startScheduler();
  error = takeErrors(&schedulerError);
  if (HD_DEVICE_ERROR(error)) {
    hdUnschedule(callback_);
    stopScheduler();
    hdDisableDevice(hhd);
    takeErrors(&schedulerError);
    throw DeviceError("OpenHaptics: cannot start the servo loop of " + name() + ": " +
                      hdErrorText(error.errorCode, error.internalErrorCode));
  }
  started_ = true;
}

void OpenHapticsDevice::startScheduler() {
  std::lock_guard<std::mutex> lock(gSchedulerMutex);
  if (gSchedulerUsers++ == 0) hdStartScheduler();
}

void OpenHapticsDevice::stopScheduler() {
  std::lock_guard<std::mutex> lock(gSchedulerMutex);
  if (--gSchedulerUsers == 0) hdStopScheduler();
}

void OpenHapticsDevice::stop() {
  if (!started_) return;
  // The servo callback renders zero force from now on; wait (up to 50 ms) for a frame that did.
  stopping_ = true;
  const std::uint64_t frame = renderedFrames_.load();
  for (int i = 0; i < 50 && !failed_ && renderedFrames_.load() < frame + 2; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  if (!failed_) hdUnschedule(callback_);  // a callback that returned DONE is unscheduled already
  stopScheduler();
  hdDisableDevice(static_cast<HHD>(handle_));
  bool schedulerError = false;
  takeErrors(&schedulerError);
  started_ = false;
}

bool OpenHapticsDevice::attachServoRenderer(std::shared_ptr<ServoRenderer> renderer) {
  if (started_) throw DeviceError("OpenHaptics: a servo renderer must be attached before start()");
  servoRenderer_ = std::move(renderer);
  return true;
}

Eigen::Vector3d OpenHapticsDevice::rosPosition(const double transform[16]) const {
  // Column-major 4x4, translation in millimetres.
  Eigen::Matrix3d rotation;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) rotation(r, c) = transform[c * 4 + r];
  const Eigen::Vector3d positionMm(transform[12], transform[13], transform[14]);
  const Eigen::Matrix3d rosRotation = deviceToRos() * rotation * deviceToRos().transpose();
  return deviceToRos() * positionMm * 0.001 + rosRotation * options_.tipOffset;
}

bool OpenHapticsDevice::commandedForce(double now, double wallNow, const double transform[16],
                                       Eigen::Vector3d& ros) noexcept {
  if (servoRenderer_) {
    // The force of the position read in this frame: the loop closes within the tick.
    if (servoRenderer_->render(rosPosition(transform), now, ros, wallNow)) {
      latency_.record(static_cast<std::int64_t>((steadySeconds() - now) * 1e9));
      return true;
    }
  }
  if (commands_.update()) {
    const Command& fresh = commands_.front();
    if (fresh.poseStamp > 0.0 && fresh.poseStamp != lastPoseStamp_) {
      latency_.record(static_cast<std::int64_t>((wallNow - fresh.poseStamp) * 1e9));
      lastPoseStamp_ = fresh.poseStamp;
    }
  }
  const Command& command = commands_.front();
  if (command.writtenAt <= 0.0) return false;
  if (!(now - command.writtenAt <= options_.forceTimeout)) {
    staleFrames_.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  ros = Eigen::Vector3d(command.force[0], command.force[1], command.force[2]);
  return true;
}

void OpenHapticsDevice::renderForce(double now, double wallNow, bool calibrated, const double transform[16],
                                    const double velocity[3], double out[3]) noexcept {
  out[0] = out[1] = out[2] = 0.0;
  Eigen::Vector3d ros;
  if (stopping_.load(std::memory_order_relaxed) || !calibrated || !commandedForce(now, wallNow, transform, ros)) {
    if (!servoRenderer_) commands_.update();  // keep the freshest command; nothing rendered from it
    return;
  }
  // Damping in the device frame: velocity in mm/s, damping in N s/m.
  Eigen::Vector3d f = deviceToRos().transpose() * ros -
                      options_.damping * 1e-3 * Eigen::Vector3d(velocity[0], velocity[1], velocity[2]);
  const double magnitude = f.norm();
  if (!std::isfinite(magnitude)) return;
  if (magnitude > maxForce_) f *= maxForce_ / magnitude;
  out[0] = f.x();
  out[1] = f.y();
  out[2] = f.z();
}

bool OpenHapticsDevice::servo() noexcept {
  const HHD hhd = static_cast<HHD>(handle_);
  hdMakeCurrentDevice(hhd);
  // As the drivers: an update the device can do by itself is done here, every tick it is needed.
  if (hdCheckCalibration() == HD_CALIBRATION_NEEDS_UPDATE) hdUpdateCalibration(calibrationStyle_);
  const HDenum calibration = hdCheckCalibration();

  Sample& s = samples_.back();
  HDdouble velocity[3] = {0.0, 0.0, 0.0};
  HDint buttons = 0;
  hdBeginFrame(hhd);
  hdGetDoublev(HD_CURRENT_TRANSFORM, s.transform);
  hdGetDoublev(HD_CURRENT_JOINT_ANGLES, s.joints);
  hdGetDoublev(HD_CURRENT_GIMBAL_ANGLES, s.gimbal);
  hdGetDoublev(HD_CURRENT_VELOCITY, velocity);
  hdGetIntegerv(HD_CURRENT_BUTTONS, &buttons);
  const double now = steadySeconds();
  const double wallNow = wallSeconds();
  HDdouble force[3];
  renderForce(now, wallNow, calibration == HD_CALIBRATION_OK, s.transform, velocity, force);
  hdSetDoublev(HD_CURRENT_FORCE, force);
  hdEndFrame(hhd);

  bool schedulerError = false;
  const HDErrorInfo error = takeErrors(&schedulerError);
  s.buttons = buttons;
  s.steadyTime = now;
  s.wallTime = wallNow;
  s.errorCode = error.errorCode;
  s.internalError = error.internalErrorCode;
  s.calibration = calibration;
  s.valid = !HD_DEVICE_ERROR(error) && calibration == HD_CALIBRATION_OK;
  s.frame = ++frames_;
  samples_.publish();
  renderedFrames_.fetch_add(1, std::memory_order_release);
  if (schedulerError) {
    failCode_.store(error.errorCode, std::memory_order_relaxed);
    failInternal_.store(error.internalErrorCode, std::memory_order_relaxed);
    failed_.store(true, std::memory_order_release);
    return false;
  }
  return true;
}

bool OpenHapticsDevice::read(DeviceState& state) {
  samples_.update();
  const Sample& s = samples_.front();
  if (!started_ || failed_.load(std::memory_order_acquire) || s.frame == 0 || !s.valid) return false;
  Eigen::Matrix3d rotation;  // column-major 4x4
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) rotation(r, c) = s.transform[c * 4 + r];
  const Eigen::Matrix3d rosRotation = deviceToRos() * rotation * deviceToRos().transpose();
  state.time = s.steadyTime;
  state.stamp = s.wallTime;
  state.position = rosPosition(s.transform);
  state.orientation = Eigen::Quaterniond(rosRotation).normalized();
  state.joints = driverJointStates(s.joints, s.gimbal, options_.joints);
  state.buttons =
      ((s.buttons & HD_DEVICE_BUTTON_1) ? kGreyButton : 0u) | ((s.buttons & HD_DEVICE_BUTTON_2) ? kWhiteButton : 0u);
  return true;
}

DeviceCondition OpenHapticsDevice::condition() const {
  if (failed_.load(std::memory_order_acquire)) return DeviceCondition::Failed;
  const Sample& s = samples_.front();
  if (!started_ || s.frame == 0) return DeviceCondition::NotStarted;
  if (s.errorCode != HD_SUCCESS) return DeviceCondition::FrameError;
  if (s.calibration != HD_CALIBRATION_OK) return DeviceCondition::Calibrating;
  return DeviceCondition::Ok;
}

std::string OpenHapticsDevice::conditionText() const {
  const Sample& s = samples_.front();
  switch (condition()) {
    case DeviceCondition::Ok:
      return {};
    case DeviceCondition::NotStarted:
      return name() + ": no servo frame yet";
    case DeviceCondition::FrameError:
      return name() + ": device error in the last servo frame: " + hdErrorText(s.errorCode, s.internalError);
    case DeviceCondition::Failed:
      return name() + ": the servo loop stopped on " + hdErrorText(failCode_.load(), failInternal_.load()) +
             ": communication with the device is lost (unplugged, powered off, or its driver stopped)";
    case DeviceCondition::Calibrating:
      break;
  }
  const char* what = calibrationStyle_ == HD_CALIBRATION_INKWELL ? "put the stylus in the inkwell"
                     : calibrationStyle_ == HD_CALIBRATION_AUTO
                         ? "move the stylus through the workspace (automatic calibration)"
                         : "hold the arm in its reset position (encoder reset)";
  return name() + " (" + model_ + ") needs calibration: " + what +
         "; no pose is published and no force rendered until it is calibrated";
}

void OpenHapticsDevice::commandForce(const Eigen::Vector3d& force) { commandForceFor(force, 0.0); }

void OpenHapticsDevice::commandForceFor(const Eigen::Vector3d& force, double poseStamp) {
  Command& c = commands_.back();
  c.force[0] = force.x();
  c.force[1] = force.y();
  c.force[2] = force.z();
  c.writtenAt = steadySeconds();
  c.poseStamp = poseStamp;
  commands_.publish();
}

}  // namespace device
}  // namespace clod_haptics
