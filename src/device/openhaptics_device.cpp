// Compiled only when CMake finds the OpenHaptics HD headers and library (CLOD_WITH_OPENHAPTICS).
#include "clod_haptics/device/openhaptics_device.h"

#include <HD/hd.h>

#include <chrono>
#include <thread>

namespace clod_haptics {
namespace device {

namespace {

std::string hdErrorText(const HDErrorInfo& error) {
  const char* text = hdGetErrorString(error.errorCode);
  return std::string(text ? text : "unknown HD error") + " (HD error " + std::to_string(error.errorCode) +
         ", internal " + std::to_string(error.internalErrorCode) + ")";
}

HDCallbackCode HDCALLBACK servoCallback(void* data) {
  return static_cast<OpenHapticsDevice*>(data)->servo() ? HD_CALLBACK_CONTINUE : HD_CALLBACK_DONE;
}

// Device axes (x right, y up, z towards the user) to ROS axes (z up): (x, y, z) -> (x, -z, y).
const Eigen::Matrix3d& deviceToRos() {
  static const Eigen::Matrix3d c = (Eigen::Matrix3d() << 1, 0, 0, 0, 0, -1, 0, 1, 0).finished();
  return c;
}

}  // namespace

OpenHapticsDevice::OpenHapticsDevice(std::string deviceName) : deviceName_(std::move(deviceName)) {}

OpenHapticsDevice::~OpenHapticsDevice() { stop(); }

std::string OpenHapticsDevice::name() const {
  return "openhaptics:" + (deviceName_.empty() ? std::string("default device") : deviceName_);
}

void OpenHapticsDevice::start() {
  if (started_) return;
  HHD hhd = hdInitDevice(deviceName_.empty() ? HD_DEFAULT_DEVICE : deviceName_.c_str());
  HDErrorInfo error = hdGetError();
  if (HD_DEVICE_ERROR(error)) {
    throw DeviceError("OpenHaptics: cannot initialise " + name() + ": " + hdErrorText(error) +
                      " (is the device plugged in and configured with Geomagic Touch Setup?)");
  }
  handle_ = hhd;
  hdMakeCurrentDevice(hhd);
  hdEnable(HD_FORCE_OUTPUT);
  callback_ = hdScheduleAsynchronous(servoCallback, this, HD_MAX_SCHEDULER_PRIORITY);
  hdStartScheduler();
  error = hdGetError();
  if (HD_DEVICE_ERROR(error)) {
    hdUnschedule(callback_);
    hdDisableDevice(hhd);
    throw DeviceError("OpenHaptics: cannot start the scheduler: " + hdErrorText(error));
  }
  started_ = true;
}

void OpenHapticsDevice::stop() {
  if (!started_) return;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    force_.setZero();
  }
  // Let the servo loop render the zero force before it stops.
  std::this_thread::sleep_for(std::chrono::milliseconds(5));
  hdStopScheduler();
  hdUnschedule(callback_);
  hdDisableDevice(static_cast<HHD>(handle_));
  started_ = false;
}

bool OpenHapticsDevice::servo() {
  const HHD hhd = static_cast<HHD>(handle_);
  hdBeginFrame(hhd);
  HDdouble transform[16];
  HDdouble joints[3];
  HDdouble gimbal[3];
  HDint buttons = 0;
  hdGetDoublev(HD_CURRENT_TRANSFORM, transform);
  hdGetDoublev(HD_CURRENT_JOINT_ANGLES, joints);
  hdGetDoublev(HD_CURRENT_GIMBAL_ANGLES, gimbal);
  hdGetIntegerv(HD_CURRENT_BUTTONS, &buttons);

  // Column-major 4x4, translation in millimetres.
  Eigen::Matrix3d rotation;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) rotation(r, c) = transform[c * 4 + r];
  const Eigen::Vector3d positionMm(transform[12], transform[13], transform[14]);

  Eigen::Vector3d force;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    state_.time = hdGetSchedulerTimeStamp();
    state_.position = deviceToRos() * positionMm * 0.001;
    state_.orientation = Eigen::Quaterniond(deviceToRos() * rotation * deviceToRos().transpose()).normalized();
    for (int i = 0; i < 3; ++i) {
      state_.joints[i] = joints[i];
      state_.joints[3 + i] = gimbal[i];
    }
    state_.buttons =
        ((buttons & HD_DEVICE_BUTTON_1) ? kGreyButton : 0u) | ((buttons & HD_DEVICE_BUTTON_2) ? kWhiteButton : 0u);
    haveState_ = true;
    force = force_;
  }
  const Eigen::Vector3d deviceForce = deviceToRos().transpose() * force;
  const HDdouble out[3] = {deviceForce.x(), deviceForce.y(), deviceForce.z()};
  hdSetDoublev(HD_CURRENT_FORCE, out);
  hdEndFrame(hhd);

  const HDErrorInfo error = hdGetError();
  if (HD_DEVICE_ERROR(error)) {
    std::lock_guard<std::mutex> lock(mutex_);
    lastError_ = hdErrorText(error);
    haveState_ = false;  // the bridge warns "no state"; the scheduler keeps trying
  }
  return true;
}

bool OpenHapticsDevice::read(DeviceState& state) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!started_ || !haveState_) return false;
  state = state_;
  return true;
}

void OpenHapticsDevice::commandForce(const Eigen::Vector3d& force) {
  std::lock_guard<std::mutex> lock(mutex_);
  force_ = force;
}

}  // namespace device
}  // namespace clod_haptics
