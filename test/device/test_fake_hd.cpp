// The fake libHD itself (test/device/fake_libhd) against the HD API's documented semantics, so the backend's
// tests run against the SDK's behaviour rather than the fake's whims: the error stack (most recent first,
// HD_SUCCESS when empty), nested frames, synchronous callbacks run until they return DONE while the caller
// waits, asynchronous ones every tick by priority until DONE or unscheduled, and the calibration states.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wattributes"  // HDCALLBACK and HDAPIENTRY are stdcall on Linux
#include <HDU/hduError.h>

#include "fake_libhd/fake_hd_control.h"
#pragma GCC diagnostic pop
#undef min
#undef max

namespace {

class FakeHd : public ::testing::Test {
 protected:
  void SetUp() override {
    handle_ = hdInitDevice(HD_DEFAULT_DEVICE);
    ASSERT_FALSE(HD_DEVICE_ERROR(hdGetError()));
  }
  void TearDown() override { fakeHdReset(); }
  HHD handle_ = HD_INVALID_HANDLE;
};

struct Counter {
  std::atomic<int> calls{0};
  int doneAfter = 3;
  std::vector<int>* order = nullptr;
  int id = 0;
};

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wattributes"
HDCallbackCode HDCALLBACK countUntilDone(void* data) {
  auto* c = static_cast<Counter*>(data);
  if (c->order) c->order->push_back(c->id);
  return ++c->calls >= c->doneAfter ? HD_CALLBACK_DONE : HD_CALLBACK_CONTINUE;
}
#pragma GCC diagnostic pop

}  // namespace

TEST_F(FakeHd, ErrorStackGivesTheMostRecentFirstThenSuccess) {
  hdEndFrame(handle_);                          // HD_ILLEGAL_END (no frame begun)
  hdSetDoublev(HD_CURRENT_TRANSFORM, nullptr);  // HD_INVALID_ENUM (not settable)
  EXPECT_EQ(hdGetError().errorCode, static_cast<HDerror>(HD_INVALID_ENUM));
  EXPECT_EQ(hdGetError().errorCode, static_cast<HDerror>(HD_ILLEGAL_END));
  EXPECT_FALSE(HD_DEVICE_ERROR(hdGetError()));
}

TEST_F(FakeHd, OnlyTheOutermostFrameSendsTheForce) {
  hdEnable(HD_FORCE_OUTPUT);
  const double force[3] = {0.1, 0.2, 0.3};
  hdBeginFrame(handle_);
  hdBeginFrame(handle_);
  hdSetDoublev(HD_CURRENT_FORCE, force);
  hdEndFrame(handle_);
  double sent[3];
  fakeHdLastForce(handle_, sent);
  EXPECT_EQ(sent[0], 0.0) << "sent by an inner frame";
  hdEndFrame(handle_);
  fakeHdLastForce(handle_, sent);
  EXPECT_EQ(sent[2], 0.3);
  EXPECT_EQ(fakeHdFrames(handle_), 1u);
  EXPECT_FALSE(HD_DEVICE_ERROR(hdGetError()));
}

TEST_F(FakeHd, SynchronousCallbackRunsUntilDoneBeforeTheCallReturns) {
  hdStartScheduler();
  Counter c;
  c.doneAfter = 5;
  hdScheduleSynchronous(countUntilDone, &c, HD_DEFAULT_SCHEDULER_PRIORITY);
  EXPECT_EQ(c.calls.load(), 5);
  hdStopScheduler();
}

TEST_F(FakeHd, AsynchronousCallbacksRunByPriorityUntilDone) {
  std::vector<int> order;
  Counter low, high;
  low.doneAfter = high.doneAfter = 2;
  low.order = high.order = &order;
  low.id = 1;
  high.id = 2;
  hdScheduleAsynchronous(countUntilDone, &low, HD_MIN_SCHEDULER_PRIORITY);
  const HDSchedulerHandle h = hdScheduleAsynchronous(countUntilDone, &high, HD_MAX_SCHEDULER_PRIORITY);
  hdStartScheduler();
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (low.calls < 2 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  hdStopScheduler();
  ASSERT_EQ(order, (std::vector<int>{2, 1, 2, 1}));  // each tick: high priority first; both done after 2
  EXPECT_EQ(hdWaitForCompletion(h, HD_WAIT_CHECK_STATUS), HD_FALSE);
}

TEST_F(FakeHd, CalibrationNeedsTheInkwellThenAnUpdate) {
  fakeHdSetCalibration(handle_, HD_CALIBRATION_NEEDS_MANUAL_INPUT, HD_CALIBRATION_INKWELL);
  hdUpdateCalibration(HD_CALIBRATION_INKWELL);
  EXPECT_EQ(hdCheckCalibration(), static_cast<HDenum>(HD_CALIBRATION_NEEDS_MANUAL_INPUT));
  fakeHdSetInkwell(handle_, 1);
  EXPECT_EQ(hdCheckCalibration(), static_cast<HDenum>(HD_CALIBRATION_NEEDS_UPDATE));
  hdUpdateCalibration(HD_CALIBRATION_AUTO);  // a style the device does not support
  EXPECT_EQ(hdGetError().errorCode, static_cast<HDerror>(HD_INVALID_VALUE));
  hdUpdateCalibration(HD_CALIBRATION_INKWELL);
  EXPECT_EQ(hdCheckCalibration(), static_cast<HDenum>(HD_CALIBRATION_OK));
}

TEST_F(FakeHd, UnpluggedDeviceReportsASchedulerErrorAndStaleValues) {
  fakeHdSetPosition(handle_, 1.0, 2.0, 3.0);
  hdBeginFrame(handle_);
  hdEndFrame(handle_);
  fakeHdUnplug(handle_);
  fakeHdSetPosition(handle_, 9.0, 9.0, 9.0);
  hdBeginFrame(handle_);
  double p[3];
  hdGetDoublev(HD_CURRENT_POSITION, p);
  hdEndFrame(handle_);
  EXPECT_EQ(p[0], 1.0) << "the last value read before the unplug";
  const HDErrorInfo e = hdGetError();
  EXPECT_EQ(e.errorCode, static_cast<HDerror>(HD_COMM_ERROR));
  EXPECT_TRUE(hduIsSchedulerError(&e));
  EXPECT_FALSE(hduIsForceError(&e));
}
