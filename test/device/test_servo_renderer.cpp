// ServoRenderer (src/device/servo_renderer.cpp): the proxy run in a servo loop, against analytic answers on a
// closed box (its top face at z = 0): the force of a device pressed d into the top is stiffness * d straight up;
// a device that starts inside gets no force until it has left the box (the proxy never starts inside); the
// device's frame differs from the scene's; disabling hands the force back to the caller; and no allocation.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <vector>

#include "../core/allocation_counter.h"
#include "clod_haptics/device/servo_renderer.h"
#include "box_scene.h"

using namespace clod_haptics;
using namespace clod_haptics::device;
using Eigen::Vector3d;
using clod_haptics_test::boxScene;
using clod_haptics_test::kRadius;

namespace {

constexpr double kStiffness = 400.0;
// The proxy rests a hair (1e-9 r and rounding) above the surface it holds: 1e-8 N is 2.5e-11 m of spring.

ServoRenderSettings stylus() {
  ServoRenderSettings s;
  s.proxy.radius = kRadius;
  s.proxy.stiffness = kStiffness;
  return s;
}

// From 1 cm above the top straight down to `depth` below the surface (the sphere's surface: centre at r - depth),
// one tick per 0.1 mm; returns the last force.
Vector3d pressInto(ServoRenderer& renderer, const Eigen::Isometry3d& deviceFromScene, double depth, double& time) {
  Vector3d force = Vector3d::Zero();
  for (int i = 0; i <= 100; ++i) {
    const double z = 0.01 + (kRadius - depth - 0.01) * i / 100.0;
    time += 1e-3;
    EXPECT_TRUE(renderer.render(deviceFromScene * Vector3d(0.01, 0.02, z), time, force));
  }
  return force;
}

}  // namespace

TEST(ServoRenderer, PressingIntoTheTopGivesTheSpringStraightUp) {
  ServoRenderer renderer(boxScene(), stylus());
  double time = 0.0;
  const Vector3d f = pressInto(renderer, Eigen::Isometry3d::Identity(), 0.0015, time);
  EXPECT_NEAR(f.z(), kStiffness * 0.0015, 1e-8);
  EXPECT_NEAR(f.x(), 0.0, 1e-8);
  EXPECT_NEAR(f.y(), 0.0, 1e-8);
  ServoRenderTick tick;
  ASSERT_TRUE(renderer.latest(tick));
  EXPECT_TRUE(tick.active);
  EXPECT_NEAR(tick.tick.proxy.z(), kRadius, 1e-9);  // resting on the top
  EXPECT_FALSE(renderer.latest(tick)) << "no newer tick since";
}

TEST(ServoRenderer, TheForceIsInTheDevicesFrame) {
  // The device's frame: turned 90 degrees about x and moved; the scene's up is the device's -y.
  Eigen::Isometry3d sceneFromDevice = Eigen::Isometry3d::Identity();
  sceneFromDevice.rotate(Eigen::AngleAxisd(M_PI / 2, Vector3d::UnitX()));
  sceneFromDevice.pretranslate(Vector3d(0.3, -0.1, 0.2));
  ServoRenderSettings s = stylus();
  s.sceneFromDevice = sceneFromDevice;
  ServoRenderer renderer(boxScene(), s);
  double time = 0.0;
  const Vector3d f = pressInto(renderer, sceneFromDevice.inverse(), 0.001, time);
  const Vector3d expected = sceneFromDevice.linear().transpose() * Vector3d(0.0, 0.0, kStiffness * 0.001);
  EXPECT_LT((f - expected).norm(), 1e-8) << f.transpose();
}

TEST(ServoRenderer, NoForceUntilADeviceThatStartsInsideHasLeft) {
  ServoRenderer renderer(boxScene(), stylus());
  Vector3d f;
  double time = 0.0;
  // 8 mm deep (4 r): no triangle within r, inside the box.
  for (int i = 0; i < 10; ++i) {
    ASSERT_TRUE(renderer.render(Vector3d(0.0, 0.0, -0.008), time += 1e-3, f));
    EXPECT_EQ(f.norm(), 0.0);
  }
  ServoRenderTick tick;
  ASSERT_TRUE(renderer.latest(tick));
  EXPECT_FALSE(tick.active) << "the proxy started inside the box";
  // Out through the top, then back in: the proxy started outside and holds the surface.
  for (int i = 0; i <= 100; ++i) renderer.render(Vector3d(0.0, 0.0, -0.008 + 0.02 * i / 100.0), time += 1e-3, f);
  for (int i = 0; i <= 100; ++i) renderer.render(Vector3d(0.0, 0.0, 0.012 - 0.02 * i / 100.0), time += 1e-3, f);
  EXPECT_NEAR(f.z(), kStiffness * (kRadius + 0.008), 1e-8);
  ASSERT_TRUE(renderer.latest(tick));
  EXPECT_TRUE(tick.active);
}

TEST(ServoRenderer, DisabledHandsTheForceBackAndANewRadiusRestartsTheProxy) {
  ServoRenderer renderer(boxScene(), stylus());
  double time = 0.0;
  pressInto(renderer, Eigen::Isometry3d::Identity(), 0.001, time);
  ServoRenderSettings off = stylus();
  off.enabled = false;
  renderer.configure(off);
  Vector3d f;
  EXPECT_FALSE(renderer.render(Vector3d(0.0, 0.0, 0.001), time += 1e-3, f));
  EXPECT_EQ(f.norm(), 0.0);
  // On again with a larger radius, the device 1 mm into the top: touching at the start, so no proxy yet.
  ServoRenderSettings wide = stylus();
  wide.proxy.radius = 2.0 * kRadius;
  renderer.configure(wide);
  EXPECT_TRUE(renderer.render(Vector3d(0.0, 0.0, 2.0 * kRadius - 0.001), time += 1e-3, f));
  EXPECT_EQ(f.norm(), 0.0);
  // Lifted clear and pressed again: the spring of the new radius.
  for (int i = 0; i <= 100; ++i) renderer.render(Vector3d(0.0, 0.0, 0.02 - 0.0169 * i / 100.0), time += 1e-3, f);
  EXPECT_NEAR(f.z(), kStiffness * (2.0 * kRadius - 0.0031), 1e-8);
}

TEST(ServoRenderer, AllocatesNothingPerTick) {
  ServoRenderer renderer(boxScene(), stylus());
  double time = 0.0;
  pressInto(renderer, Eigen::Isometry3d::Identity(), 0.001, time);  // warm
  renderer.configure(stylus());
  Vector3d f;
  ServoRenderTick tick;
  gAllocations = 0;
  gCounting = true;
  for (int i = 0; i < 200; ++i) {
    renderer.render(Vector3d(0.001 * std::sin(i * 0.1), 0.0, 0.001 - 0.00001 * i), time += 1e-3, f);
    renderer.latest(tick);
  }
  gCounting = false;
  EXPECT_EQ(gAllocations.load(), 0);
}
