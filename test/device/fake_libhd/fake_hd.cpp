// A fake libHD (and the two HDU error helpers) with the OpenHaptics HD API's semantics, for linking the real
// backend (src/device/openhaptics_device.cpp) in tests: devices opened by name, a scheduler thread ticking
// at 1 kHz that runs asynchronous callbacks every tick (highest priority first) until they return
// HD_CALLBACK_DONE and synchronous ones until done while the caller waits, frames (nested, outermost
// reads the device and sends the force), a per-thread error stack read most recent first, calibration
// states, and a test control API (fake_hd_control.h). Semantics not checked against a device are
// marked "assumed".
#include <HD/hd.h>
#include <HDU/hduError.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>
#undef min
#undef max

#include "fake_hd_control.h"

namespace {

using Clock = std::chrono::steady_clock;

struct Device {
  std::string name;
  bool enabled = true;  // false after hdDisableDevice
  // The "hardware": what the next outermost frame reads. Guarded by g.mutex.
  double transform[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  double velocity[3] = {0, 0, 0};
  double joints[3] = {0, 0, 0};
  double gimbal[3] = {0, 0, 0};
  int buttons = 0;
  bool unplugged = false;
  Clock::time_point unplugAt = Clock::time_point::max();
  // CLOD_FAKE_HD_PATH: the stylus goes from pathFrom to pathTo and back every pathPeriod seconds (0: it stays).
  double pathFrom[3] = {0, 0, 0}, pathTo[3] = {0, 0, 0}, pathPeriod = 0.0;
  Clock::time_point pathStart = Clock::now();
  HDerror persistentError = HD_SUCCESS;
  HDerror oneShotError = HD_SUCCESS;
  HDenum calibration = HD_CALIBRATION_OK;
  int calibrationStyles = HD_CALIBRATION_INKWELL;
  unsigned long calibrationUpdates = 0;
  bool inInkwell = false;
  double peakForce = 3.3, continuousForce = 0.88;
  bool forceOutput = false;
  // Frame state: the values the current (or last) frame read, the force it is going to send.
  int frameDepth = 0;
  double frameTransform[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  double frameVelocity[3] = {0, 0, 0};
  double frameJoints[3] = {0, 0, 0};
  double frameGimbal[3] = {0, 0, 0};
  int frameButtons = 0;
  double pendingForce[3] = {0, 0, 0};
  double sentForce[3] = {0, 0, 0};
  unsigned long frames = 0;
};

struct Operation {
  HDSchedulerHandle handle;
  HDSchedulerCallback callback;
  void* data;
  HDushort priority;
  bool synchronous;
  bool done;
};

struct State {
  std::mutex mutex;  // devices and operations
  std::condition_variable doneCv;
  std::vector<std::unique_ptr<Device>> devices;  // handle = index
  std::vector<Operation> operations;
  HDSchedulerHandle nextHandle = 1;
  std::atomic<HHD> current{HD_INVALID_HANDLE};
  std::atomic<bool> running{false};
  std::thread thread;
  Clock::time_point tickStart;
};

State g;
thread_local std::vector<HDErrorInfo> tErrors;  // assumed per thread, like the SDK's error stack

void pushError(HDerror code, HHD device) {
  tErrors.push_back(HDErrorInfo{code, static_cast<int>(code) + 0x10000, device});
}

Device* deviceLocked(HHD handle) {
  if (handle >= g.devices.size() || !g.devices[handle] || !g.devices[handle]->enabled) return nullptr;
  return g.devices[handle].get();
}

Device* currentLocked() { return deviceLocked(g.current.load()); }

// Runs every operation once (synchronous ones until they return DONE), highest priority first.
void runTick() {
  std::vector<Operation> ops;
  {
    std::lock_guard<std::mutex> lock(g.mutex);
    ops = g.operations;
  }
  std::stable_sort(ops.begin(), ops.end(),
                   [](const Operation& a, const Operation& b) { return a.priority > b.priority; });
  g.tickStart = Clock::now();
  for (const Operation& op : ops) {
    {
      std::lock_guard<std::mutex> lock(g.mutex);
      auto it = std::find_if(g.operations.begin(), g.operations.end(),
                             [&](const Operation& o) { return o.handle == op.handle; });
      if (it == g.operations.end() || it->done) continue;  // unscheduled meanwhile
    }
    const HDCallbackCode code = op.callback(op.data);
    if (code == HD_CALLBACK_DONE) {
      std::lock_guard<std::mutex> lock(g.mutex);
      for (Operation& o : g.operations)
        if (o.handle == op.handle) o.done = true;
      g.operations.erase(std::remove_if(g.operations.begin(), g.operations.end(),
                                        [](const Operation& o) { return o.done && !o.synchronous; }),
                         g.operations.end());
      g.doneCv.notify_all();
    }
  }
}

void schedulerLoop() {
  auto next = Clock::now();
  while (g.running.load()) {
    runTick();
    next += std::chrono::milliseconds(1);
    const auto now = Clock::now();
    if (now > next + std::chrono::milliseconds(10)) next = now;
    std::this_thread::sleep_until(next);
  }
}

void applyEnvironment(Device& d) {
  if (const char* c = std::getenv("CLOD_FAKE_HD_CALIBRATION")) {
    const std::string s(c);
    if (s == "update") d.calibration = HD_CALIBRATION_NEEDS_UPDATE;
    if (s == "manual") d.calibration = HD_CALIBRATION_NEEDS_MANUAL_INPUT;
  }
  if (const char* u = std::getenv("CLOD_FAKE_HD_UNPLUG_AFTER_MS")) {
    d.unplugAt = Clock::now() + std::chrono::milliseconds(std::atol(u));
  }
  if (const char* e = std::getenv("CLOD_FAKE_HD_ERROR")) {
    char* end = nullptr;
    const auto code = static_cast<HDerror>(std::strtoul(e, &end, 0));
    if (end && std::strcmp(end, ":persistent") == 0) {
      d.persistentError = code;
    } else {
      d.oneShotError = code;
    }
  }
  if (const char* f = std::getenv("CLOD_FAKE_HD_NOMINAL_FORCES")) {
    std::sscanf(f, "%lf,%lf", &d.peakForce, &d.continuousForce);
  }
  if (const char* p = std::getenv("CLOD_FAKE_HD_PATH")) {
    double* a = d.pathFrom;
    double* b = d.pathTo;
    if (std::sscanf(p, "%lf,%lf,%lf,%lf,%lf,%lf,%lf", &a[0], &a[1], &a[2], &b[0], &b[1], &b[2], &d.pathPeriod) != 7)
      d.pathPeriod = 0.0;
    d.pathStart = Clock::now();
  }
  if (const char* p = std::getenv("CLOD_FAKE_HD_POSITION")) {
    double x = 0, y = 0, z = 0;
    if (std::sscanf(p, "%lf,%lf,%lf", &x, &y, &z) == 3) {
      d.transform[12] = x;
      d.transform[13] = y;
      d.transform[14] = z;
    }
  }
}

// The reading an uncalibrated device gives: the position off by 25 mm along x (assumed; real devices are
// off by an unknown amount until calibrated).
constexpr double kUncalibratedOffsetMm = 25.0;

void beginFrameLocked(Device& d, HHD handle) {
  if (d.frameDepth++ > 0) return;  // nested: the outermost frame read the device already
  if (!d.unplugged && Clock::now() >= d.unplugAt) d.unplugged = true;
  if (d.unplugged) return;  // the frame keeps the last values read: stale
  if (d.pathPeriod > 0.0) {  // a triangle wave between the path's ends
    const double phase = std::fmod(std::chrono::duration<double>(Clock::now() - d.pathStart).count() / d.pathPeriod, 1.0);
    const double w = phase < 0.5 ? 2.0 * phase : 2.0 - 2.0 * phase;
    for (int k = 0; k < 3; ++k) d.transform[12 + k] = d.pathFrom[k] + w * (d.pathTo[k] - d.pathFrom[k]);
  }
  std::memcpy(d.frameTransform, d.transform, sizeof d.transform);
  if (d.calibration != HD_CALIBRATION_OK) d.frameTransform[12] += kUncalibratedOffsetMm;
  std::memcpy(d.frameVelocity, d.velocity, sizeof d.velocity);
  std::memcpy(d.frameJoints, d.joints, sizeof d.joints);
  std::memcpy(d.frameGimbal, d.gimbal, sizeof d.gimbal);
  d.frameButtons = d.buttons;
  (void)handle;
}

void endFrameLocked(Device& d, HHD handle) {
  if (d.frameDepth == 0) {
    pushError(HD_ILLEGAL_END, handle);
    return;
  }
  if (--d.frameDepth > 0) return;
  if (d.unplugged) {
    pushError(HD_COMM_ERROR, handle);
    return;
  }
  if (d.persistentError != HD_SUCCESS) pushError(d.persistentError, handle);
  if (d.oneShotError != HD_SUCCESS) {
    pushError(d.oneShotError, handle);
    d.oneShotError = HD_SUCCESS;
  }
  const double* f = d.pendingForce;
  const double magnitude = std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
  if (magnitude > d.peakForce) {
    pushError(HD_EXCEEDED_MAX_FORCE, handle);  // the motors get nothing (assumed; the SDK may clamp)
    std::fill(d.sentForce, d.sentForce + 3, 0.0);
  } else {
    for (int i = 0; i < 3; ++i) d.sentForce[i] = d.forceOutput ? f[i] : 0.0;
  }
  ++d.frames;
}

// The values of parameter pname on device d (at most 16) and their count; 0 for a parameter the fake lacks.
int parameterValues(const Device& d, HDenum pname, double values[16]) {
  const double* array = nullptr;
  int n = 3;
  if (pname == HD_CURRENT_TRANSFORM) {
    array = d.frameTransform;
    n = 16;
  } else if (pname == HD_CURRENT_POSITION) {
    array = d.frameTransform + 12;  // the translation column
  } else if (pname == HD_CURRENT_VELOCITY) {
    array = d.frameVelocity;
  } else if (pname == HD_CURRENT_JOINT_ANGLES) {
    array = d.frameJoints;
  } else if (pname == HD_CURRENT_GIMBAL_ANGLES) {
    array = d.frameGimbal;
  } else if (pname == HD_CURRENT_FORCE) {
    array = d.pendingForce;
  } else if (pname == HD_LAST_FORCE) {
    array = d.sentForce;
  }
  if (array) {
    std::copy(array, array + n, values);
    return n;
  }
  const struct {
    HDenum name;
    double value;
  } scalars[] = {{HD_NOMINAL_MAX_FORCE, d.peakForce},
                 {HD_NOMINAL_MAX_CONTINUOUS_FORCE, d.continuousForce},
                 {HD_CURRENT_BUTTONS, static_cast<double>(d.frameButtons)},
                 {HD_CALIBRATION_STYLE, static_cast<double>(d.calibrationStyles)},
                 {HD_CURRENT_INKWELL_SWITCH, d.inInkwell ? 0.0 : 1.0},  // assumed: 0 = in the inkwell
                 {HD_UPDATE_RATE, 1000.0}};
  for (const auto& s : scalars) {
    if (s.name == pname) {
      values[0] = s.value;
      return 1;
    }
  }
  return 0;
}

template <typename T>
void getValues(HDenum pname, T* out) {
  std::lock_guard<std::mutex> lock(g.mutex);
  Device* d = currentLocked();
  double values[16];
  const int n = d ? parameterValues(*d, pname, values) : 0;
  if (!d) {
    pushError(HD_BAD_HANDLE, g.current.load());
  } else if (n == 0) {
    pushError(HD_INVALID_ENUM, g.current.load());
  }
  for (int i = 0; i < n; ++i) out[i] = static_cast<T>(values[i]);
}

// Runs f(device) under the lock, or reports HD_BAD_HANDLE for a handle that is not an open device.
template <typename F>
void withDevice(HHD handle, F f) {
  std::lock_guard<std::mutex> lock(g.mutex);
  if (Device* d = deviceLocked(handle)) {
    f(*d);
  } else {
    pushError(HD_BAD_HANDLE, handle);
  }
}

Device* controlled(HHD handle) { return handle < g.devices.size() ? g.devices[handle].get() : nullptr; }

}  // namespace

extern "C" {

HHD HDAPIENTRY hdInitDevice(HDstring name) {
  const std::string key = name ? name : "Default Device";
  std::lock_guard<std::mutex> lock(g.mutex);
  for (const auto& d : g.devices) {
    if (d && d->enabled && d->name == key) {
      pushError(HD_DEVICE_ALREADY_INITIATED, HD_INVALID_HANDLE);
      return HD_INVALID_HANDLE;
    }
  }
  if (key.rfind("missing", 0) == 0) {  // a name no device is configured under
    pushError(HD_COMM_CONFIG_ERROR, HD_INVALID_HANDLE);
    return HD_INVALID_HANDLE;
  }
  auto device = std::make_unique<Device>();
  device->name = key;
  applyEnvironment(*device);
  g.devices.push_back(std::move(device));
  const HHD handle = static_cast<HHD>(g.devices.size() - 1);
  g.current = handle;
  return handle;
}

void HDAPIENTRY hdMakeCurrentDevice(HHD handle) {
  withDevice(handle, [&](Device&) { g.current = handle; });
}

void HDAPIENTRY hdDisableDevice(HHD handle) {
  withDevice(handle, [](Device& d) {
    d.enabled = false;
    std::fill(d.sentForce, d.sentForce + 3, 0.0);
  });
}

HHD HDAPIENTRY hdGetCurrentDevice() { return g.current.load(); }

void HDAPIENTRY hdBeginFrame(HHD handle) {
  withDevice(handle, [&](Device& d) {
    g.current = handle;
    beginFrameLocked(d, handle);
  });
}

void HDAPIENTRY hdEndFrame(HHD handle) {
  withDevice(handle, [&](Device& d) { endFrameLocked(d, handle); });
}

HDErrorInfo HDAPIENTRY hdGetError() {
  if (tErrors.empty()) return HDErrorInfo{HD_SUCCESS, 0, HD_INVALID_HANDLE};
  const HDErrorInfo e = tErrors.back();
  tErrors.pop_back();
  return e;
}

HDstring HDAPIENTRY hdGetErrorString(HDerror code) {
  static const struct {
    HDerror code;
    const char* text;
  } kTexts[] = {{HD_SUCCESS, "No error"},
                {HD_INVALID_ENUM, "Invalid enumerant"},
                {HD_INVALID_VALUE, "Invalid value"},
                {HD_INVALID_OPERATION, "Invalid operation"},
                {HD_BAD_HANDLE, "Invalid device handle"},
                {HD_WARM_MOTORS, "Motors are overheating"},
                {HD_EXCEEDED_MAX_FORCE, "Exceeded maximum force"},
                {HD_EXCEEDED_MAX_VELOCITY, "Exceeded maximum velocity"},
                {HD_DEVICE_FAULT, "Device fault"},
                {HD_DEVICE_ALREADY_INITIATED, "Device already initiated"},
                {HD_COMM_ERROR, "Communication error"},
                {HD_COMM_CONFIG_ERROR, "Communication configuration error"},
                {HD_TIMER_ERROR, "Timer error"},
                {HD_ILLEGAL_BEGIN, "Illegal begin frame"},
                {HD_ILLEGAL_END, "Illegal end frame"},
                {HD_SCHEDULER_FULL, "Scheduler full"}};
  for (const auto& t : kTexts)
    if (t.code == code) return t.text;
  return "Unknown error";
}

void HDAPIENTRY hdEnable(HDenum cap) {
  std::lock_guard<std::mutex> lock(g.mutex);
  if (Device* d = currentLocked()) {
    if (cap == HD_FORCE_OUTPUT) d->forceOutput = true;
  } else {
    pushError(HD_BAD_HANDLE, g.current.load());
  }
}

void HDAPIENTRY hdDisable(HDenum cap) {
  std::lock_guard<std::mutex> lock(g.mutex);
  if (Device* d = currentLocked()) {
    if (cap == HD_FORCE_OUTPUT) d->forceOutput = false;
  }
}

HDboolean HDAPIENTRY hdIsEnabled(HDenum cap) {
  std::lock_guard<std::mutex> lock(g.mutex);
  Device* d = currentLocked();
  return (d && cap == HD_FORCE_OUTPUT && d->forceOutput) ? HD_TRUE : HD_FALSE;
}

void HDAPIENTRY hdGetBooleanv(HDenum pname, HDboolean* params) { getValues(pname, params); }
void HDAPIENTRY hdGetIntegerv(HDenum pname, HDint* params) { getValues(pname, params); }
void HDAPIENTRY hdGetFloatv(HDenum pname, HDfloat* params) { getValues(pname, params); }
void HDAPIENTRY hdGetDoublev(HDenum pname, HDdouble* params) { getValues(pname, params); }
void HDAPIENTRY hdGetLongv(HDenum pname, HDlong* params) { getValues(pname, params); }

HDstring HDAPIENTRY hdGetString(HDenum pname) {
  if (pname == HD_DEVICE_MODEL_TYPE) return "Touch (fake libHD)";
  if (pname == HD_DEVICE_VENDOR) return "clod_haptics test fake";
  if (pname == HD_DEVICE_SERIAL_NUMBER) return "00000";
  pushError(HD_INVALID_ENUM, g.current.load());
  return nullptr;
}

void HDAPIENTRY hdSetDoublev(HDenum pname, const HDdouble* params) {
  std::lock_guard<std::mutex> lock(g.mutex);
  Device* d = currentLocked();
  if (!d) {
    pushError(HD_BAD_HANDLE, g.current.load());
  } else if (pname != HD_CURRENT_FORCE) {
    pushError(HD_INVALID_ENUM, g.current.load());
  } else if (d->frameDepth == 0) {
    pushError(HD_INVALID_OPERATION, g.current.load());  // state is set inside a frame only
  } else {
    std::copy(params, params + 3, d->pendingForce);
  }
}

void HDAPIENTRY hdSetFloatv(HDenum pname, const HDfloat* params) {
  const HDdouble values[3] = {params[0], params[1], params[2]};
  hdSetDoublev(pname, values);
}
void HDAPIENTRY hdSetBooleanv(HDenum, const HDboolean*) { pushError(HD_INVALID_ENUM, g.current.load()); }
void HDAPIENTRY hdSetIntegerv(HDenum, const HDint*) { pushError(HD_INVALID_ENUM, g.current.load()); }
void HDAPIENTRY hdSetLongv(HDenum, const HDlong*) { pushError(HD_INVALID_ENUM, g.current.load()); }

HDenum HDAPIENTRY hdCheckCalibration() {
  std::lock_guard<std::mutex> lock(g.mutex);
  Device* d = currentLocked();
  return d ? d->calibration : HD_CALIBRATION_NEEDS_MANUAL_INPUT;
}

HDenum HDAPIENTRY hdCheckCalibrationStyle() {
  std::lock_guard<std::mutex> lock(g.mutex);
  Device* d = currentLocked();
  return d ? static_cast<HDenum>(d->calibrationStyles) : 0u;
}

void HDAPIENTRY hdUpdateCalibrationMessage(HDenum) {}

void HDAPIENTRY hdUpdateCalibration(HDenum style) {
  std::lock_guard<std::mutex> lock(g.mutex);
  Device* d = currentLocked();
  if (!d) {
    pushError(HD_BAD_HANDLE, g.current.load());
  } else if (!(static_cast<int>(style) & d->calibrationStyles)) {
    pushError(HD_INVALID_VALUE, g.current.load());
  } else if (d->calibration == HD_CALIBRATION_NEEDS_UPDATE) {
    d->calibration = HD_CALIBRATION_OK;
    ++d->calibrationUpdates;
  }
}

void HDAPIENTRY hdStartScheduler() {
  if (g.running.exchange(true)) return;
  g.thread = std::thread(schedulerLoop);
}

void HDAPIENTRY hdStopScheduler() {
  if (!g.running.exchange(false)) return;
  if (g.thread.joinable()) g.thread.join();
  std::lock_guard<std::mutex> lock(g.mutex);
  for (Operation& o : g.operations) o.done = true;  // a waiting synchronous caller returns
  g.operations.clear();
  g.doneCv.notify_all();
}

void HDAPIENTRY hdSetSchedulerRate(HDulong) {}

HDSchedulerHandle HDAPIENTRY hdScheduleAsynchronous(HDSchedulerCallback callback, void* data, HDushort priority) {
  std::lock_guard<std::mutex> lock(g.mutex);
  const HDSchedulerHandle handle = g.nextHandle++;
  g.operations.push_back(Operation{handle, callback, data, priority, false, false});
  return handle;
}

void HDAPIENTRY hdScheduleSynchronous(HDSchedulerCallback callback, void* data, HDushort priority) {
  if (!g.running.load()) {  // no scheduler thread: nothing would run it (assumed; the SDK's behaviour unverified)
    pushError(HD_INVALID_OPERATION, g.current.load());
    return;
  }
  std::unique_lock<std::mutex> lock(g.mutex);
  const HDSchedulerHandle handle = g.nextHandle++;
  g.operations.push_back(Operation{handle, callback, data, priority, true, false});
  g.doneCv.wait(lock, [&] {
    auto it =
        std::find_if(g.operations.begin(), g.operations.end(), [&](const Operation& o) { return o.handle == handle; });
    return it == g.operations.end() || it->done;
  });
  g.operations.erase(
      std::remove_if(g.operations.begin(), g.operations.end(), [&](const Operation& o) { return o.handle == handle; }),
      g.operations.end());
}

void HDAPIENTRY hdUnschedule(HDSchedulerHandle handle) {
  std::lock_guard<std::mutex> lock(g.mutex);
  const auto before = g.operations.size();
  g.operations.erase(
      std::remove_if(g.operations.begin(), g.operations.end(), [&](const Operation& o) { return o.handle == handle; }),
      g.operations.end());
  if (g.operations.size() == before) pushError(HD_INVALID_OPERATION, g.current.load());
}

HDboolean HDAPIENTRY hdWaitForCompletion(HDSchedulerHandle handle, HDWaitCode code) {
  std::unique_lock<std::mutex> lock(g.mutex);
  auto active = [&] {
    return std::any_of(g.operations.begin(), g.operations.end(),
                       [&](const Operation& o) { return o.handle == handle && !o.done; });
  };
  if (code == HD_WAIT_CHECK_STATUS) return active() ? HD_TRUE : HD_FALSE;
  g.doneCv.wait(lock, [&] { return !active() || !g.running.load(); });
  return HD_TRUE;
}

HDdouble HDAPIENTRY hdGetSchedulerTimeStamp() {
  return std::chrono::duration<double>(Clock::now() - g.tickStart).count();
}

void hduPrintError(FILE* stream, const HDErrorInfo* error, const char* message) {
  std::fprintf(stream, "HD Error: %s\n%s\nHD_errorCode: 0x%04x, Internal: %d\n", message,
               hdGetErrorString(error->errorCode), error->errorCode, error->internalErrorCode);
}

HDboolean hduIsForceError(const HDErrorInfo* error) {
  switch (error->errorCode) {
    case HD_WARM_MOTORS:
    case HD_EXCEEDED_MAX_FORCE:
    case HD_EXCEEDED_MAX_VELOCITY:
    case HD_FORCE_ERROR:
      return HD_TRUE;
    default:
      return HD_FALSE;
  }
}

HDboolean hduIsSchedulerError(const HDErrorInfo* error) {
  switch (error->errorCode) {
    case HD_COMM_ERROR:
    case HD_COMM_CONFIG_ERROR:
    case HD_TIMER_ERROR:
    case HD_INVALID_PRIORITY:
    case HD_SCHEDULER_FULL:
      return HD_TRUE;
    default:
      return HD_FALSE;
  }
}

// ---- test control ----

HHD fakeHdFindDevice(const char* name) {
  const std::string key = (name && *name) ? name : "Default Device";
  std::lock_guard<std::mutex> lock(g.mutex);
  for (std::size_t i = 0; i < g.devices.size(); ++i)
    if (g.devices[i] && g.devices[i]->enabled && g.devices[i]->name == key) return static_cast<HHD>(i);
  return HD_INVALID_HANDLE;
}

#define FAKE_HD_CONTROL(handle, body)          \
  do {                                         \
    std::lock_guard<std::mutex> lock(g.mutex); \
    if (Device* d = controlled(handle)) body;  \
  } while (0)

void fakeHdSetTransform(HHD h, const double t[16]) { FAKE_HD_CONTROL(h, std::copy(t, t + 16, d->transform)); }
void fakeHdSetPosition(HHD h, double x, double y, double z) {
  FAKE_HD_CONTROL(h, (d->transform[12] = x, d->transform[13] = y, d->transform[14] = z));
}
void fakeHdSetVelocity(HHD h, double vx, double vy, double vz) {
  FAKE_HD_CONTROL(h, (d->velocity[0] = vx, d->velocity[1] = vy, d->velocity[2] = vz));
}
void fakeHdSetAngles(HHD h, const double joints[3], const double gimbal[3]) {
  FAKE_HD_CONTROL(h, (std::copy(joints, joints + 3, d->joints), std::copy(gimbal, gimbal + 3, d->gimbal)));
}
void fakeHdSetButtons(HHD h, int buttons) { FAKE_HD_CONTROL(h, d->buttons = buttons); }
void fakeHdLastForce(HHD h, double force[3]) {
  std::fill(force, force + 3, 0.0);
  FAKE_HD_CONTROL(h, std::copy(d->sentForce, d->sentForce + 3, force));
}
unsigned long fakeHdFrames(HHD h) {
  unsigned long frames = 0;
  FAKE_HD_CONTROL(h, frames = d->frames);
  return frames;
}
void fakeHdInjectError(HHD h, HDerror code, int persistent) {
  FAKE_HD_CONTROL(h, (persistent ? d->persistentError : d->oneShotError) = code);
}
void fakeHdUnplug(HHD h) { FAKE_HD_CONTROL(h, d->unplugged = true); }
void fakeHdSetCalibration(HHD h, HDenum status, int styles) {
  FAKE_HD_CONTROL(h, (d->calibration = status, d->calibrationStyles = styles));
}
void fakeHdSetInkwell(HHD h, int in) {
  FAKE_HD_CONTROL(h, {
    d->inInkwell = in != 0;
    if (d->inInkwell && d->calibration == HD_CALIBRATION_NEEDS_MANUAL_INPUT)
      d->calibration = HD_CALIBRATION_NEEDS_UPDATE;
  });
}
unsigned long fakeHdCalibrationUpdates(HHD h) {
  unsigned long n = 0;
  FAKE_HD_CONTROL(h, n = d->calibrationUpdates);
  return n;
}
void fakeHdSetNominalForces(HHD h, double peak, double continuous) {
  FAKE_HD_CONTROL(h, (d->peakForce = peak, d->continuousForce = continuous));
}

void fakeHdReset(void) {
  hdStopScheduler();
  std::lock_guard<std::mutex> lock(g.mutex);
  g.devices.clear();
  g.operations.clear();
  g.current = HD_INVALID_HANDLE;
  tErrors.clear();
}

}  // extern "C"
