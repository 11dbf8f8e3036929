// OpenHapticsDevice (src/device/openhaptics_device.cpp) linked against the fake libHD (test/device/fake_libhd):
// the servo callback runs in the fake's 1 kHz scheduler thread, the test plays the hardware through the
// control API. Expected values come from the driver conventions written out by hand (axes (x, -z, y),
// millimetres to metres, the drivers' joint formulas), never from the backend's own output. Waits poll
// with a generous deadline; nothing asserts on speed.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <thread>

#include "box_scene.h"
#include "clod_haptics/device/openhaptics_device.h"
// The fake's headers carry the SDK's traps: stdcall attributes (ignored on x86-64) and min/max macros.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wattributes"
#include "fake_libhd/fake_hd_control.h"
#pragma GCC diagnostic pop
#undef min
#undef max

using namespace clod_haptics::device;
using Eigen::Vector3d;

namespace {

constexpr double kPi = 3.14159265358979323846;

bool waitFor(const std::function<bool()>& condition, double seconds = 5.0) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < deadline) {
    if (condition()) return true;
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  return condition();
}

void sleepMs(int ms) { std::this_thread::sleep_for(std::chrono::milliseconds(ms)); }

Vector3d lastForce(HHD h) {
  double f[3];
  fakeHdLastForce(h, f);
  return Vector3d(f[0], f[1], f[2]);
}

class OpenHapticsDeviceTest : public ::testing::Test {
 protected:
  void TearDown() override {
    device_.reset();
    fakeHdReset();
    unsetenv("CLOD_FAKE_HD_CALIBRATION");
    unsetenv("CLOD_FAKE_HD_NOMINAL_FORCES");
  }
  OpenHapticsDevice& start(OpenHapticsOptions options = {}) {
    device_ = std::make_unique<OpenHapticsDevice>(options);
    device_->start();
    handle_ = fakeHdFindDevice(options.deviceName.c_str());
    EXPECT_NE(handle_, HD_INVALID_HANDLE);
    return *device_;
  }
  bool readState(DeviceState& state) {
    return waitFor([&] { return device_->read(state); });
  }
  std::unique_ptr<OpenHapticsDevice> device_;
  HHD handle_ = HD_INVALID_HANDLE;
};

}  // namespace

TEST_F(OpenHapticsDeviceTest, NoStateBeforeTheFirstServoFrame) {
  OpenHapticsDevice device;
  DeviceState state;
  EXPECT_FALSE(device.read(state));
  EXPECT_EQ(device.condition(), DeviceCondition::NotStarted);
}

TEST_F(OpenHapticsDeviceTest, PoseInRosAxesAndMetres) {
  start();
  // A rotation of 90 degrees about the device's y (up) axis, column-major, translation (10, 20, 30) mm.
  const double t[16] = {0, 0, -1, 0, 0, 1, 0, 0, 1, 0, 0, 0, 10, 20, 30, 1};
  fakeHdSetTransform(handle_, t);
  fakeHdSetButtons(handle_, HD_DEVICE_BUTTON_2);
  DeviceState s;
  ASSERT_TRUE(waitFor([&] { return device_->read(s) && s.position.x() > 0.0; }));
  EXPECT_NEAR(s.position.x(), 0.010, 1e-12);   // x
  EXPECT_NEAR(s.position.y(), -0.030, 1e-12);  // -z
  EXPECT_NEAR(s.position.z(), 0.020, 1e-12);   // y
  // Device y is ROS z: a rotation about ROS z by 90 degrees.
  const Eigen::AngleAxisd expected(kPi / 2, Vector3d::UnitZ());
  EXPECT_NEAR(s.orientation.angularDistance(Eigen::Quaterniond(expected)), 0.0, 1e-9);
  EXPECT_EQ(s.buttons, static_cast<std::uint32_t>(kWhiteButton));
  EXPECT_GT(s.stamp, 1.5e9);  // wall clock seconds (after 2017)
  EXPECT_EQ(device_->condition(), DeviceCondition::Ok);
}

TEST_F(OpenHapticsDeviceTest, TipOffsetIsAppliedInTheStylusFrame) {
  OpenHapticsOptions options;
  options.tipOffset = Vector3d(0.0, 0.0, -0.04);
  start(options);
  const double t[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};  // identity at the origin
  fakeHdSetTransform(handle_, t);
  DeviceState s;
  ASSERT_TRUE(readState(s));
  EXPECT_NEAR((s.position - Vector3d(0.0, 0.0, -0.04)).norm(), 0.0, 1e-12);
}

TEST_F(OpenHapticsDeviceTest, JointStatesFollowTheOmniCommonConvention) {
  start();
  const double joints[3] = {0.1, 0.2, 0.5}, gimbal[3] = {0.3, -0.4, 1.0};
  fakeHdSetAngles(handle_, joints, gimbal);
  DeviceState s;
  ASSERT_TRUE(waitFor([&] { return device_->read(s) && s.joints[0] != 0.0; }));
  const double expected[6] = {-0.1, 0.2, 0.3, kPi - 0.3, 0.4 - 0.75 * kPi, -1.0 - kPi};
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(s.joints[i], expected[i], 1e-12) << i;
}

TEST_F(OpenHapticsDeviceTest, ManualCalibrationWithholdsStatesUntilTheInkwellThenUpdatesInTheServoLoop) {
  setenv("CLOD_FAKE_HD_CALIBRATION", "manual", 1);
  start();
  fakeHdSetPosition(handle_, 5.0, 0.0, 0.0);
  const unsigned long frames = fakeHdFrames(handle_);
  ASSERT_TRUE(waitFor([&] { return fakeHdFrames(handle_) > frames + 20; }));
  DeviceState s;
  EXPECT_FALSE(device_->read(s));
  EXPECT_EQ(device_->condition(), DeviceCondition::Calibrating);
  EXPECT_NE(device_->conditionText().find("inkwell"), std::string::npos) << device_->conditionText();
  device_->commandForce(Vector3d(0.3, 0.0, 0.0));
  ASSERT_TRUE(waitFor([&] { return fakeHdFrames(handle_) > frames + 40; }));
  EXPECT_EQ(lastForce(handle_), Vector3d::Zero()) << "no force while uncalibrated";
  EXPECT_EQ(fakeHdCalibrationUpdates(handle_), 0u);

  fakeHdSetInkwell(handle_, 1);  // NEEDS_MANUAL_INPUT -> NEEDS_UPDATE: the callback updates it
  ASSERT_TRUE(readState(s));
  EXPECT_EQ(fakeHdCalibrationUpdates(handle_), 1u);
  EXPECT_NEAR(s.position.x(), 0.005, 1e-12) << "the calibrated position, not the uncalibrated offset";
}

TEST_F(OpenHapticsDeviceTest, CalibrationThatNeedsAnUpdateIsUpdatedByTheServoLoop) {
  setenv("CLOD_FAKE_HD_CALIBRATION", "update", 1);
  start();
  DeviceState s;
  ASSERT_TRUE(readState(s));
  EXPECT_EQ(fakeHdCalibrationUpdates(handle_), 1u);
}

TEST_F(OpenHapticsDeviceTest, PersistentErrorWithholdsEveryStateAndSaysWhy) {
  start();
  DeviceState s;
  ASSERT_TRUE(readState(s));
  fakeHdInjectError(handle_, HD_DEVICE_FAULT, 1);
  const unsigned long frames = fakeHdFrames(handle_);
  ASSERT_TRUE(waitFor([&] { return fakeHdFrames(handle_) > frames + 2; }));
  int states = 0, polls = 0;
  const unsigned long until = fakeHdFrames(handle_) + 200;
  while (fakeHdFrames(handle_) < until) {
    states += device_->read(s) ? 1 : 0;
    ++polls;
    std::this_thread::sleep_for(std::chrono::microseconds(300));
  }
  EXPECT_EQ(states, 0) << "of " << polls << " polls";
  EXPECT_EQ(device_->condition(), DeviceCondition::FrameError);
  EXPECT_NE(device_->conditionText().find("Device fault"), std::string::npos) << device_->conditionText();
  fakeHdInjectError(handle_, HD_SUCCESS, 1);
  EXPECT_TRUE(readState(s)) << "states come back when the error clears";
}

TEST_F(OpenHapticsDeviceTest, UnplugEndsTheServoCallbackAndFails) {
  start();
  DeviceState s;
  ASSERT_TRUE(readState(s));
  fakeHdUnplug(handle_);
  ASSERT_TRUE(waitFor([&] {
    device_->read(s);
    return device_->condition() == DeviceCondition::Failed;
  }));
  EXPECT_FALSE(device_->read(s)) << "no stale pose after the device is gone";
  EXPECT_NE(device_->conditionText().find("Communication error"), std::string::npos) << device_->conditionText();
  // The callback returned HD_CALLBACK_DONE: the scheduler no longer runs it, no frame is begun.
  const unsigned long frames = fakeHdFrames(handle_);
  sleepMs(30);
  EXPECT_EQ(fakeHdFrames(handle_), frames);
}

TEST_F(OpenHapticsDeviceTest, ForceInDeviceAxesPlusDampingCappedAtMaxForce) {
  OpenHapticsOptions options;
  options.forceTimeout = 1.0;
  start(options);
  // ROS (x, y, z) is device (x, z, -y).
  device_->commandForce(Vector3d(0.0, 0.2, 0.3));
  ASSERT_TRUE(waitFor([&] { return (lastForce(handle_) - Vector3d(0.0, 0.3, -0.2)).norm() < 1e-12; }))
      << lastForce(handle_).transpose();
  // The drivers' damping: 0.001 N per mm/s against the device velocity.
  fakeHdSetVelocity(handle_, 100.0, 0.0, 0.0);
  device_->commandForce(Vector3d::Zero());
  ASSERT_TRUE(waitFor([&] { return std::abs(lastForce(handle_).x() + 0.1) < 1e-12; }))
      << lastForce(handle_).transpose();
  fakeHdSetVelocity(handle_, 0.0, 0.0, 0.0);
  device_->commandForce(Vector3d(5.0, 0.0, 0.0));
  ASSERT_TRUE(waitFor([&] { return std::abs(lastForce(handle_).x() - 0.8) < 1e-12; }))
      << lastForce(handle_).transpose();
}

// A servo renderer runs in the servo callback: with no force command at all, the device pressed into the box's
// top renders the proxy's spring (400 N/m times the depth, straight up: device +y), from the position of the
// frame that rendered it; the force loop's latency is recorded within the frame. Disabled, the commands come back.
TEST_F(OpenHapticsDeviceTest, AServoRendererAnswersThePositionOfTheSameFrame) {
  ServoRenderSettings settings;
  settings.proxy.radius = clod_haptics_test::kRadius;
  settings.proxy.stiffness = 400.0;
  auto renderer = std::make_shared<ServoRenderer>(clod_haptics_test::boxScene(), settings);
  device_ = std::make_unique<OpenHapticsDevice>();
  ASSERT_TRUE(device_->attachServoRenderer(renderer));
  device_->start();
  handle_ = fakeHdFindDevice("");
  // ROS (0.01, 0.02, z) is device (10, 1000 z, -20) mm. Above the box, then 1 mm and 1.5 mm into its top.
  fakeHdSetPosition(handle_, 10.0, 10.0, -20.0);
  ASSERT_TRUE(waitFor([&] { return fakeHdFrames(handle_) > 5; }));
  EXPECT_EQ(lastForce(handle_).norm(), 0.0);
  for (const double depthMm : {1.0, 1.5}) {
    fakeHdSetPosition(handle_, 10.0, 2.0 - depthMm, -20.0);
    const unsigned long frame = fakeHdFrames(handle_);
    ASSERT_TRUE(waitFor([&] { return fakeHdFrames(handle_) >= frame + 2; }));
    // Within the two frames since the position changed, with no command: the servo loop answered it.
    EXPECT_LT((lastForce(handle_) - Vector3d(0.0, 0.4 * depthMm, 0.0)).norm(), 1e-8) << lastForce(handle_).transpose();
  }
  EXPECT_GT(device_->forceLoopLatency()->count(), 0u);
  ServoRenderSettings off = settings;
  off.enabled = false;
  renderer->configure(off);
  device_->commandForceFor(Vector3d(0.0, 0.2, 0.0), 0.0);  // ROS y is device -z
  ASSERT_TRUE(waitFor([&] { return (lastForce(handle_) - Vector3d(0.0, 0.0, -0.2)).norm() < 1e-12; }))
      << lastForce(handle_).transpose();
}

TEST_F(OpenHapticsDeviceTest, StalledBridgeThreadGetsItsForceZeroedWhileTheServoLoopRuns) {
  OpenHapticsOptions options;
  options.forceTimeout = 0.05;
  options.damping = 0.0;
  start(options);
  device_->commandForce(Vector3d(0.4, 0.0, 0.0));
  ASSERT_TRUE(waitFor([&] { return lastForce(handle_).x() > 0.39; }));
  // The bridge thread stalls: it neither reads nor commands. The servo loop keeps running and, once the
  // command is older than forceTimeout, sends zero by itself.
  const unsigned long frames = fakeHdFrames(handle_);
  ASSERT_TRUE(waitFor([&] { return lastForce(handle_) == Vector3d::Zero(); }));
  EXPECT_GT(device_->staleFrames(), 0u);
  ASSERT_TRUE(waitFor([&] { return fakeHdFrames(handle_) > frames + 100; })) << "the servo loop kept running";
}

TEST_F(OpenHapticsDeviceTest, RatingsComeFromTheDeviceAndCapTheForce) {
  setenv("CLOD_FAKE_HD_NOMINAL_FORCES", "0.5,0.3", 1);
  OpenHapticsOptions options;
  options.maxForce = 2.0;
  options.forceTimeout = 1.0;
  start(options);
  EXPECT_DOUBLE_EQ(device_->ratings().peak, 0.5);
  EXPECT_DOUBLE_EQ(device_->ratings().continuous, 0.3);
  device_->commandForce(Vector3d(0.0, 0.0, -3.0));  // device -y
  ASSERT_TRUE(waitFor([&] { return std::abs(lastForce(handle_).y() + 0.5) < 1e-12; }))
      << lastForce(handle_).transpose();
}

TEST_F(OpenHapticsDeviceTest, StopSendsZeroForceAndDisablesTheDevice) {
  OpenHapticsOptions options;
  options.forceTimeout = 1.0;
  start(options);
  device_->commandForce(Vector3d(0.3, 0.0, 0.0));
  ASSERT_TRUE(waitFor([&] { return lastForce(handle_).x() > 0.29; }));
  device_->stop();
  EXPECT_EQ(lastForce(handle_), Vector3d::Zero());
  EXPECT_EQ(fakeHdFindDevice(""), HD_INVALID_HANDLE) << "hdDisableDevice was called";
}

TEST_F(OpenHapticsDeviceTest, AnUnknownDeviceNameFailsToStartWithTheHdError) {
  OpenHapticsOptions options;
  options.deviceName = "missing arm";
  OpenHapticsDevice device(options);
  try {
    device.start();
    FAIL() << "started a device that does not exist";
  } catch (const DeviceError& e) {
    EXPECT_NE(std::string(e.what()).find("missing arm"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("Communication configuration error"), std::string::npos) << e.what();
  }
}

TEST_F(OpenHapticsDeviceTest, TwoDevicesShareTheSchedulerAndStopIndependently) {
  OpenHapticsOptions left, right;
  left.deviceName = "Left";
  right.deviceName = "Right";
  OpenHapticsDevice a(left), b(right);
  a.start();
  b.start();
  const HHD ha = fakeHdFindDevice("Left"), hb = fakeHdFindDevice("Right");
  fakeHdSetPosition(ha, 10.0, 0.0, 0.0);
  fakeHdSetPosition(hb, -10.0, 0.0, 0.0);
  DeviceState sa, sb;
  ASSERT_TRUE(waitFor([&] { return a.read(sa) && sa.position.x() != 0.0; }));
  ASSERT_TRUE(waitFor([&] { return b.read(sb) && sb.position.x() != 0.0; }));
  EXPECT_NEAR(sa.position.x(), 0.010, 1e-12);
  EXPECT_NEAR(sb.position.x(), -0.010, 1e-12);
  a.stop();
  const unsigned long frames = fakeHdFrames(hb);
  EXPECT_TRUE(waitFor([&] { return fakeHdFrames(hb) > frames + 20; })) << "stopping one device stopped the other";
  b.stop();
}
