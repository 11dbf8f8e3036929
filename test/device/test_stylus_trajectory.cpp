// StylusTrajectory: sorting and cleaning, 1 kHz resampling checked against motions whose exact
// position is known at every time, workspace transforms and fitting.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>

#include "clod_haptics/device/stylus_trajectory.h"

using namespace clod_haptics::device;
using Eigen::Vector3d;

namespace {

StylusSample sample(double t, const Vector3d& p) {
  StylusSample s;
  s.time = t;
  s.position = p;
  return s;
}

}  // namespace

TEST(StylusTrajectory, SortsDropsInvalidAndDuplicateSamplesAndStartsAtZero) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  StylusSamples in = {sample(10.2, Vector3d(2, 0, 0)),   sample(10.0, Vector3d(0, 0, 0)),
                      sample(10.1, Vector3d(nan, 0, 0)), sample(10.1, Vector3d(1, 0, 0)),
                      sample(10.1, Vector3d(5, 5, 5)),   sample(nan, Vector3d(0, 0, 0))};
  StylusTrajectory traj(in);
  ASSERT_EQ(traj.size(), 3u);
  EXPECT_EQ(traj.dropped(), 3u);
  EXPECT_NEAR(traj.duration(), 0.2, 1e-12);
  EXPECT_EQ(traj.samples()[0].time, 0.0);
  EXPECT_EQ(traj.samples()[1].position, Vector3d(1, 0, 0));  // the first of the duplicate times is kept
  EXPECT_THROW(StylusTrajectory(StylusSamples{}), std::invalid_argument);
  EXPECT_THROW(StylusTrajectory(StylusSamples{sample(0, Vector3d(nan, 0, 0))}), std::invalid_argument);
}

TEST(StylusTrajectory, UpsamplingALinearMotionIsExact) {
  // A recording at about 100 Hz with jittered stamps of p(t) = a + b t: interpolation must
  // reproduce p at every 1 kHz sample.
  const Vector3d a(0.01, -0.02, 0.03), b(0.05, 0.02, -0.01);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> jitter(-0.002, 0.002);
  StylusSamples in;
  for (int i = 0; i <= 277; ++i) {
    const double t = 0.01 * i + (i > 0 && i < 277 ? jitter(rng) : 0.0);
    in.push_back(sample(t, a + b * t));
  }
  const StylusTrajectory traj(in);
  const StylusTrajectory up = traj.resampled(1000.0);
  ASSERT_EQ(up.size(), static_cast<std::size_t>(std::floor(2.77 * 1000.0 + 1e-9)) + 1);
  EXPECT_NEAR(up.meanRate(), 1000.0, 1e-6);
  for (std::size_t k = 0; k < up.size(); ++k) {
    const double t = k / 1000.0;
    ASSERT_NEAR(up.samples()[k].time, t, 1e-12);
    ASSERT_NEAR((up.samples()[k].position - (a + b * t)).norm(), 0.0, 1e-12) << k;
  }
}

TEST(StylusTrajectory, UpsampledCircleStaysWithinTheChordError) {
  // Keyframes on a circle at 100 Hz: every interpolated point lies on a chord, so within the
  // sagitta r (1 - cos(dtheta / 2)) of the circle and never outside it.
  const double r = 0.05, omega = 2.0;  // rad/s
  StylusSamples in;
  for (int i = 0; i <= 300; ++i) {
    const double t = 0.01 * i;
    in.push_back(sample(t, r * Vector3d(std::cos(omega * t), std::sin(omega * t), 0)));
  }
  const StylusTrajectory up = StylusTrajectory(in).resampled(1000.0);
  const double sagitta = r * (1 - std::cos(omega * 0.01 / 2));
  for (const StylusSample& s : up.samples()) {
    const double radius = s.position.norm();
    EXPECT_LE(radius, r + 1e-12);
    EXPECT_GE(radius, r - sagitta - 1e-12);
    const double angle = std::atan2(s.position.y(), s.position.x());
    const double expected = std::remainder(omega * s.time, 2 * M_PI);
    EXPECT_NEAR(std::remainder(angle - expected, 2 * M_PI), 0.0, 1e-3);
  }
}

TEST(StylusTrajectory, InterpolatesOrientationBySlerp) {
  StylusSample s0 = sample(0.0, Vector3d::Zero()), s1 = sample(1.0, Vector3d::Zero());
  s1.orientation = Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Vector3d::UnitZ()));
  const StylusTrajectory traj(StylusSamples{s0, s1});
  const Eigen::Quaterniond mid = traj.at(0.5).orientation;
  EXPECT_NEAR(mid.angularDistance(Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 4, Vector3d::UnitZ()))), 0.0, 1e-12);
}

TEST(StylusTrajectory, RejectsBadRates) {
  const StylusTrajectory traj(StylusSamples{sample(0, Vector3d::Zero()), sample(1, Vector3d::Ones())});
  EXPECT_THROW(traj.resampled(0.0), std::invalid_argument);
  EXPECT_THROW(traj.resampled(-5.0), std::invalid_argument);
  EXPECT_THROW(traj.resampled(std::numeric_limits<double>::quiet_NaN()), std::invalid_argument);
  EXPECT_EQ(traj.resampled(10.0).size(), 11u);
}

TEST(StylusTrajectory, TransformAppliesScaleRotationThenOffset) {
  WorkspaceTransform tf;
  tf.scale = 2.0;
  tf.rotation = WorkspaceTransform::fromRpy(0.0, 0.0, M_PI / 2);  // yaw 90 degrees: x -> y
  tf.offset = Vector3d(1, 2, 3);
  EXPECT_NEAR((tf.apply(Vector3d(1, 0, 0)) - Vector3d(1, 4, 3)).norm(), 0.0, 1e-12);
  // roll 90 degrees: y -> z
  EXPECT_NEAR((WorkspaceTransform::fromRpy(M_PI / 2, 0, 0) * Vector3d::UnitY() - Vector3d::UnitZ()).norm(), 0.0, 1e-12);
  const StylusTrajectory traj(StylusSamples{sample(0, Vector3d(1, 0, 0)), sample(1, Vector3d(0, 1, 0))});
  const StylusTrajectory moved = traj.transformed(tf);
  EXPECT_NEAR((moved.samples()[1].position - Vector3d(-1, 2, 3)).norm(), 0.0, 1e-12);
  EXPECT_NEAR(moved.samples()[1].orientation.angularDistance(tf.rotation), 0.0, 1e-12);
}

TEST(StylusTrajectory, FitPlacesTheWorkspaceInTheBox) {
  // A workspace in millimetre-like numbers, fitted into a 0.1 m box at (0.5, 0.5, 0.5).
  StylusSamples in;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int i = 0; i < 200; ++i) in.push_back(sample(0.01 * i, Vector3d(120 * u(rng), 70 * u(rng), 45 + 40 * u(rng))));
  const StylusTrajectory traj(in);
  const Vector3d centre(0.5, 0.5, 0.5);
  const WorkspaceTransform tf = traj.fitInto(centre, 0.1);
  const Eigen::AlignedBox3d box = traj.transformed(tf).bounds();
  EXPECT_NEAR(box.sizes().maxCoeff(), 0.1, 1e-12);
  EXPECT_NEAR((box.center() - centre).norm(), 0.0, 1e-12);
  // With a rotation the fitted bounds are those of the rotated motion.
  const auto rot = WorkspaceTransform::fromRpy(0.0, 0.0, M_PI / 2);
  const Eigen::AlignedBox3d rotated = traj.transformed(traj.fitInto(centre, 0.1, rot)).bounds();
  EXPECT_NEAR(rotated.sizes().maxCoeff(), 0.1, 1e-12);
  EXPECT_GT(rotated.sizes().y(), rotated.sizes().x());  // the long x axis became y
  EXPECT_NEAR((rotated.center() - centre).norm(), 0.0, 1e-12);
  const StylusTrajectory still(StylusSamples{sample(0, Vector3d::Ones()), sample(1, Vector3d::Ones())});
  EXPECT_THROW(still.fitInto(centre, 0.1), std::invalid_argument);
  EXPECT_THROW(traj.fitInto(centre, 0.0), std::invalid_argument);
}

TEST(StylusTrajectory, InterpolatesJointSamples) {
  std::vector<JointSample> joints(2);
  joints[0].time = 0.0;
  joints[0].names = {"waist", "shoulder"};
  joints[0].positions = {0.0, 1.0};
  joints[1] = joints[0];
  joints[1].time = 0.1;
  joints[1].positions = {1.0, 0.0};
  const JointSample mid = interpolateJoints(joints, 0.025);
  ASSERT_EQ(mid.positions.size(), 2u);
  EXPECT_NEAR(mid.positions[0], 0.25, 1e-12);
  EXPECT_NEAR(mid.positions[1], 0.75, 1e-12);
  EXPECT_EQ(interpolateJoints(joints, 5.0).positions[0], 1.0);
  EXPECT_EQ(interpolateJoints(joints, -5.0).positions[0], 0.0);
  EXPECT_TRUE(interpolateJoints({}, 0.0).positions.empty());
}
