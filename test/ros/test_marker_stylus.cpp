// StylusInterpolator and placementForBounds (src/ros/marker_stylus.cpp) against hand-computed motions.
#include <gtest/gtest.h>

#include <cmath>

#include "clod_haptics/ros/marker_stylus.h"

namespace clod_haptics {
namespace {

Eigen::Isometry3d at(double x, double y, double z) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.translation() = Eigen::Vector3d(x, y, z);
  return t;
}

TEST(StylusInterpolator, MovesAlongTheLineAtTheSpeedLimitAndStopsOnTheTarget) {
  StylusInterpolator s(at(0, 0, 0), 2.0, 1.0);
  s.setTarget(at(1.0, 0, 0));
  for (int k = 1; k <= 5; ++k) {
    s.step(0.1);  // 0.2 m a step
    EXPECT_NEAR(s.pose().translation().x(), std::min(0.2 * k, 1.0), 1e-12) << k;
    EXPECT_EQ(s.pose().translation().y(), 0.0);
  }
  EXPECT_EQ(s.pose().translation(), Eigen::Vector3d(1.0, 0, 0));  // exactly on it, not overshooting
  s.step(0.1);
  EXPECT_EQ(s.pose().translation(), Eigen::Vector3d(1.0, 0, 0));
}

TEST(StylusInterpolator, DiagonalStepsHaveTheSpeedLimitAsLength) {
  StylusInterpolator s(at(0, 0, 0), 0.1, 1.0);
  s.setTarget(at(3.0, 4.0, 0));  // direction (0.6, 0.8)
  s.step(0.001);
  EXPECT_NEAR(s.pose().translation().x(), 0.6e-4, 1e-15);
  EXPECT_NEAR(s.pose().translation().y(), 0.8e-4, 1e-15);
}

TEST(StylusInterpolator, TurnsAtTheAngularLimit) {
  StylusInterpolator s(at(0, 0, 0), 1.0, M_PI);
  Eigen::Isometry3d target = at(0, 0, 0);
  target.linear() = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  s.setTarget(target);
  s.step(0.25);  // pi/4 of pi/2
  EXPECT_NEAR(Eigen::AngleAxisd(s.pose().linear()).angle(), M_PI / 4, 1e-12);
  s.step(0.25);
  s.step(0.25);
  EXPECT_TRUE(s.pose().linear().isApprox(target.linear(), 1e-12));
}

TEST(StylusInterpolator, NoTimeNoMotion) {
  StylusInterpolator s(at(0, 0, 0), 1.0, 1.0);
  s.setTarget(at(1, 1, 1));
  s.step(0.0);
  s.step(-1.0);
  s.step(std::nan(""));
  EXPECT_EQ(s.pose().translation(), Eigen::Vector3d::Zero());
}

TEST(StylusPlacement, StartsAboveTheBoxCentreSizedToIt) {
  const Eigen::AlignedBox3d box(Eigen::Vector3d(-1, 0, 2), Eigen::Vector3d(1, 2, 4));  // diagonal sqrt(12)
  const StylusPlacement p = placementForBounds(box);
  EXPECT_EQ(p.start.x(), 0.0);
  EXPECT_EQ(p.start.y(), 1.0);
  EXPECT_GT(p.start.z(), 4.0);  // outside the box: the stylus starts off the mesh
  EXPECT_NEAR(p.markerScale, 0.1 * std::sqrt(12.0), 1e-12);
  EXPECT_GT(p.maxSpeed, 0.0);
}

}  // namespace
}  // namespace clod_haptics

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
