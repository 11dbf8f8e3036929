// rostest: bag_replay and phantom_bridge given a bag or parameters they cannot use log a clear
// error and exit non-zero, never hang. Runs the real binaries (paths configured by CMake) against
// the test's master.
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "clod_haptics/test_config.h"
#include "run_command.h"

namespace {

using clod_haptics_test::Outcome;
using clod_haptics_test::run;

void expectCleanFailure(const Outcome& o, const std::string& mention) {
  EXPECT_EQ(o.exitCode, 1) << "expected exit code 1 (124: hung, -1: crashed): " << o.output;
  EXPECT_NE(o.output.find(mention), std::string::npos) << "the error should mention '" << mention << "': " << o.output;
  EXPECT_NE(o.output.find("FATAL"), std::string::npos) << o.output;
}

const std::string kReplay = CLOD_BAG_REPLAY_PATH;
const std::string kBridge = CLOD_PHANTOM_BRIDGE_PATH;
const std::string kGoodBag = CLOD_PACKAGE_DATA_DIR "/bags/torus_stylus.bag";

std::string truncatedCopy(double fraction) {
  const std::string path = ::testing::TempDir() + "clod_truncated_" + std::to_string(int(fraction * 100)) + ".bag";
  std::ifstream in(kGoodBag, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::ofstream(path, std::ios::binary | std::ios::trunc)
      .write(bytes.data(), static_cast<std::streamsize>(bytes.size() * fraction));
  return path;
}

TEST(DeviceBadInputs, BagReplayWithoutBagParameter) {
  expectCleanFailure(run(kReplay + " __name:=br_no_bag"), "~bag is required");
}

TEST(DeviceBadInputs, BagReplayWithMissingFile) {
  expectCleanFailure(run(kReplay + " __name:=br_missing _bag:=/nonexistent/stylus.bag"), "/nonexistent/stylus.bag");
}

TEST(DeviceBadInputs, BagReplayWithTruncatedBag) {
  for (double fraction : {0.02, 0.5, 0.95}) {
    const std::string path = truncatedCopy(fraction);
    const Outcome o = run(kReplay + " __name:=br_truncated _bag:=" + path);
    expectCleanFailure(o, path);
  }
}

TEST(DeviceBadInputs, BagReplayWithMissingTopic) {
  const Outcome o = run(kReplay + " __name:=br_topic _bag:=" + kGoodBag + " _topic:=/omni1/pose");
  expectCleanFailure(o, "no topic '/omni1/pose'");
  EXPECT_NE(o.output.find("/phantom/pose (geometry_msgs/PoseStamped)"), std::string::npos) << o.output;
}

TEST(DeviceBadInputs, BagReplayWithBadParameters) {
  expectCleanFailure(run(kReplay + " __name:=br_rate _bag:=" + kGoodBag + " _rate_scale:=-2.0"), "rate_scale");
  expectCleanFailure(run(kReplay + " __name:=br_offset _bag:=" + kGoodBag + " _offset:=[1.0,2.0]"), "offset");
}

TEST(DeviceBadInputs, BagReplayWithAGoodBagPlaysOnceAndExitsZero) {
  // The control: the bundled bag, ten times faster, no waiting: every pose published, exit 0.
  const Outcome o = run(kReplay + " __name:=br_good _bag:=" + kGoodBag +
                            " _rate_scale:=10.0 _start_delay:=0.0 _exit_delay:=0.0 _wait_for_subscribers:=0",
                        60.0);
  EXPECT_EQ(o.exitCode, 0) << o.output;
  EXPECT_NE(o.output.find("published 7501 poses"), std::string::npos) << o.output;
}

TEST(DeviceBadInputs, BagReplayLoopsUntilInterrupted) {
  // 7.5 s of motion at 20x is 0.375 s a pass: in 3 s it loops several times, then Ctrl-C ends it.
  const Outcome o =
      run(kReplay + " __name:=br_loop _bag:=" + kGoodBag +
              " _loop:=true _rate_scale:=20.0 _start_delay:=0.0 _exit_delay:=0.0 _wait_for_subscribers:=0",
          3.0, "INT");
  const auto at = o.output.find("bag_replay: published ");
  ASSERT_NE(at, std::string::npos) << o.output;
  unsigned long long poses = 0, passes = 0;
  ASSERT_EQ(std::sscanf(o.output.c_str() + at,
                        "bag_replay: published %llu poses in %*f s (%*f Hz achieved, %*f Hz "
                        "intended), %llu pass(es)",
                        &poses, &passes),
            2)
      << o.output;
  EXPECT_GE(passes, 3u) << o.output;
  EXPECT_GE(poses, 2 * 7501u) << o.output;
  EXPECT_NE(o.output.find("interrupted"), std::string::npos) << o.output;
}

TEST(DeviceBadInputs, PhantomBridgeRefusesAMaxForceAboveTheTouchPeak) {
  expectCleanFailure(run(kBridge + " __name:=pb_force _backend:=simulated _max_force:=5.0"), "peak");
  expectCleanFailure(run(kBridge + " __name:=pb_nan _backend:=simulated _max_force:=-1.0"), "max_force");
}

TEST(DeviceBadInputs, PhantomBridgeRejectsAnUnknownBackend) {
  expectCleanFailure(run(kBridge + " __name:=pb_backend _backend:=falcon"), "falcon");
}

// The bridge on the fake libHD (phantom_bridge_fake_hd): a device that fails while running stops the bridge
// with exit code 1 and the HD error text, so the launch file's respawn (or required) takes over.
const std::string kFakeBridge = CLOD_PHANTOM_BRIDGE_FAKE_HD_PATH;

TEST(DeviceBadInputs, PhantomBridgeExitsWhenTheDeviceIsUnplugged) {
  expectCleanFailure(run("env CLOD_FAKE_HD_UNPLUG_AFTER_MS=300 " + kFakeBridge + " __name:=pb_unplug"),
                     "Communication error");
}

TEST(DeviceBadInputs, PhantomBridgeExitsWhenEveryFrameHasAnError) {
  // HD_DEVICE_FAULT (0x300) in every frame: no state for ~device_timeout.
  expectCleanFailure(
      run("env CLOD_FAKE_HD_ERROR=0x300:persistent " + kFakeBridge + " __name:=pb_fault _device_timeout:=0.5"),
      "Device fault");
}

TEST(DeviceBadInputs, PhantomBridgeRefusesAMaxForceAboveTheDevicesPeak) {
  expectCleanFailure(run("env CLOD_FAKE_HD_NOMINAL_FORCES=0.5,0.3 " + kFakeBridge + " __name:=pb_peak _max_force:=0.6"),
                     "peak");
}

TEST(DeviceBadInputs, PhantomBridgeWithAnUnknownDeviceNameSaysSo) {
  expectCleanFailure(run(kFakeBridge + " __name:=pb_name \"_device_name:=missing arm\""), "missing arm");
}

#ifndef CLOD_WITH_OPENHAPTICS
TEST(DeviceBadInputs, PhantomBridgeWithoutOpenHapticsSaysHowToGetIt) {
  expectCleanFailure(run(kBridge + " __name:=pb_oh _backend:=openhaptics"), "CLOD_WITH_OPENHAPTICS");
}
#endif

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_device_bad_inputs");
  return RUN_ALL_TESTS();
}
