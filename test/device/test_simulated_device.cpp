// SimulatedDevice: scripted motion and force recording, and a servo loop of the bridge's logic
// (device -> ForceSafety -> device) run on it with a manual clock.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>

#include "clod_haptics/device/force_safety.h"
#include "clod_haptics/device/simulated_device.h"

using namespace clod_haptics::device;
using Eigen::Vector3d;

namespace {

std::vector<ScriptSample> lineScript() {
  std::vector<ScriptSample> s(3);
  s[0].time = 0.0;
  s[0].position = Vector3d(0, 0, 0);
  s[1].time = 1.0;
  s[1].position = Vector3d(1, 0, 0);
  s[1].buttons = kGreyButton;
  s[2].time = 3.0;
  s[2].position = Vector3d(1, 2, 0);
  return s;
}

std::string writeTemp(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + name;
  std::ofstream(path) << text;
  return path;
}

}  // namespace

TEST(SimulatedDevice, InterpolatesBetweenKeyframesAndHoldsTheEnds) {
  SimulatedDevice device(lineScript());
  EXPECT_EQ(device.sample(0.5).position, Vector3d(0.5, 0, 0));
  EXPECT_EQ(device.sample(2.0).position, Vector3d(1, 1, 0));
  EXPECT_EQ(device.sample(-1.0).position, Vector3d(0, 0, 0));
  EXPECT_EQ(device.sample(10.0).position, Vector3d(1, 2, 0));
  EXPECT_EQ(device.sample(0.5).buttons, 0u);
  EXPECT_EQ(device.sample(1.5).buttons, static_cast<std::uint32_t>(kGreyButton));
}

TEST(SimulatedDevice, LoopsWhenAsked) {
  SimulatedDevice device(lineScript(), true);
  EXPECT_NEAR((device.sample(3.5).position - Vector3d(0.5, 0, 0)).norm(), 0.0, 1e-12);
  EXPECT_NEAR((device.sample(6.0 + 2.0).position - Vector3d(1, 1, 0)).norm(), 0.0, 1e-12);
}

TEST(SimulatedDevice, ReadsOnlyWhileRunningOnItsClock) {
  double now = 100.0;
  SimulatedDevice device(lineScript(), false, [&] { return now; });
  DeviceState state;
  EXPECT_FALSE(device.read(state));
  device.start();
  now += 0.25;
  ASSERT_TRUE(device.read(state));
  EXPECT_NEAR(state.time, 0.25, 1e-12);
  EXPECT_NEAR(state.position.x(), 0.25, 1e-12);
  device.stop();
  EXPECT_FALSE(device.read(state));
}

TEST(SimulatedDevice, RecordsEveryForceWithItsTime) {
  double now = 0.0;
  SimulatedDevice device(lineScript(), false, [&] { return now; });
  device.start();
  for (int i = 0; i < 10; ++i) {
    now = 0.001 * i;
    device.commandForce(Vector3d(i, 0, 0));
  }
  const auto forces = device.recordedForces();
  ASSERT_EQ(forces.size(), 10u);
  EXPECT_EQ(forces[3].force, Vector3d(3, 0, 0));
  EXPECT_NEAR(forces[3].time, 0.003, 1e-12);
  EXPECT_EQ(device.lastForce(), Vector3d(9, 0, 0));
  device.stop();  // stopping commands zero force
  EXPECT_EQ(device.lastForce(), Vector3d::Zero());
  EXPECT_EQ(device.forceCount(), 11u);
}

TEST(SimulatedDevice, RejectsBadScripts) {
  EXPECT_THROW(SimulatedDevice({}), DeviceError);
  auto s = lineScript();
  s[2].time = 1.0;
  EXPECT_THROW(SimulatedDevice{s}, DeviceError);
  s = lineScript();
  s[1].position.y() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(SimulatedDevice{s}, DeviceError);
  EXPECT_THROW(SimulatedDevice::circleScript(Vector3d::Zero(), 0.1, 0.0), DeviceError);
}

TEST(SimulatedDevice, CircleScriptStaysOnTheCircle) {
  const Vector3d centre(0.01, 0.02, 0.05);
  SimulatedDevice device(SimulatedDevice::circleScript(centre, 0.03, 2.0, 256), true);
  for (double t = 0.0; t < 4.0; t += 0.0137) {
    const Vector3d p = device.sample(t).position;
    EXPECT_NEAR(p.z(), centre.z(), 1e-12);
    // Chords of a 256-gon: within r (1 - cos(pi / 256)) of the circle.
    EXPECT_NEAR((p - centre).norm(), 0.03, 0.03 * (1 - std::cos(M_PI / 256)) + 1e-12);
  }
}

TEST(SimulatedDevice, LoadsCsvScriptsAndNamesBadLines) {
  const auto good =
      writeTemp("good.csv", "# t, x, y, z, buttons\n0, 0, 0, 0\n0.5, 0.1, 0, 0, 2\n\n1.0 0.1 0.1 0 # ok\n");
  const auto script = SimulatedDevice::loadCsvScript(good);
  ASSERT_EQ(script.size(), 3u);
  EXPECT_EQ(script[1].buttons, 2u);
  EXPECT_EQ(script[2].position, Vector3d(0.1, 0.1, 0));
  try {
    SimulatedDevice::loadCsvScript(writeTemp("bad.csv", "0, 0, 0, 0\n1, 2, x, 3\n"));
    FAIL() << "no exception";
  } catch (const DeviceError& e) {
    EXPECT_NE(std::string(e.what()).find("line 2"), std::string::npos) << e.what();
  }
  EXPECT_THROW(SimulatedDevice::loadCsvScript(writeTemp("short.csv", "0, 1, 2\n")), DeviceError);
  EXPECT_THROW(SimulatedDevice::loadCsvScript("/nonexistent/script.csv"), DeviceError);
}

// The bridge's servo tick on the simulated device: whatever the commands, the device never
// receives more than max force, never a NaN, and zero once commands stop.
TEST(SimulatedDevice, ServoLoopThroughForceSafetyKeepsTheDeviceSafe) {
  double now = 0.0;
  SimulatedDevice device(SimulatedDevice::circleScript(Vector3d::Zero(), 0.02, 1.0), true, [&] { return now; });
  ForceSafetyParams params;
  ForceSafety safety(params);
  device.start();
  ForceCommand cmd;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (int k = 0; k < 3000; ++k) {
    now = 0.001 * k;
    if (k < 1000) {  // a spring pulling to the origin, far too stiff: needs clamping
      DeviceState s;
      ASSERT_TRUE(device.read(s));
      cmd.force = -500.0 * s.position;
      cmd.receivedAt = now;
      cmd.valid = true;
    } else if (k < 1500) {  // NaN commands
      cmd.force = Vector3d(nan, 0, 0);
      cmd.receivedAt = now;
    } else if (k < 2000) {
      cmd.force = Vector3d(0, 0, 0.3);
      cmd.receivedAt = now;
    }  // from 2000 on: no new command, it goes stale
    device.commandForce(safety.update(cmd, now));
  }
  const auto forces = device.recordedForces();
  ASSERT_EQ(forces.size(), 3000u);
  for (std::size_t k = 0; k < forces.size(); ++k) {
    ASSERT_TRUE(forces[k].force.allFinite()) << k;
    ASSERT_LE(forces[k].force.norm(), params.maxForce + 1e-12) << k;
  }
  EXPECT_NEAR(forces[999].force.norm(), params.maxForce, 1e-9);
  for (int k = 1000; k < 1500; ++k) EXPECT_EQ(forces[k].force, Vector3d::Zero());
  EXPECT_NEAR(forces[1999].force.z(), 0.3, 1e-9);
  const int staleFrom = 1999 + static_cast<int>(std::ceil(params.staleTimeout / 0.001)) + 1;
  for (int k = staleFrom; k < 3000; ++k) EXPECT_EQ(forces[k].force, Vector3d::Zero()) << k;
  EXPECT_EQ(safety.counters().nonFinite, 500u);
  EXPECT_GT(safety.counters().stale, 900u);
}
