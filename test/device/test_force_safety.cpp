// ForceSafety: the bridge's clamp, slew-rate limit, NaN and stale handling, checked against the
// definitions computed directly in the test (no device, no ROS, explicit times).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>

#include "clod_haptics/device/force_safety.h"

using clod_haptics::device::ForceCommand;
using clod_haptics::device::ForceSafety;
using clod_haptics::device::ForceSafetyParams;
using clod_haptics::device::ForceStatus;
using Eigen::Vector3d;

namespace {

ForceCommand command(const Vector3d& force, double at) {
  ForceCommand c;
  c.force = force;
  c.receivedAt = at;
  c.valid = true;
  return c;
}

ForceSafetyParams noRateLimit() {
  ForceSafetyParams p;
  p.maxForceRate = 0.0;
  return p;
}

}  // namespace

TEST(ForceSafety, DefaultMaxForceIsWithinTheTouchContinuousRating) {
  const ForceSafetyParams p;
  EXPECT_GT(p.maxForce, 0.0);
  EXPECT_LE(p.maxForce, 0.88);  // Geomagic Touch: 0.88 N continuous, 3.3 N peak
  EXPECT_GT(p.staleTimeout, 0.0);
  EXPECT_GT(p.maxForceRate, 0.0);
}

TEST(ForceSafety, ForceWithinLimitPassesUnchanged) {
  ForceSafety safety(noRateLimit());
  ForceStatus status;
  const Vector3d f(0.1, -0.2, 0.3);
  const Vector3d out = safety.update(command(f, 0.0), 0.001, &status);
  EXPECT_EQ(status, ForceStatus::Ok);
  EXPECT_EQ(out, f);
}

TEST(ForceSafety, ClampKeepsDirectionAndCapsMagnitude) {
  ForceSafetyParams p = noRateLimit();
  p.maxForce = 0.5;
  ForceSafety safety(p);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-20.0, 20.0);
  for (int i = 0; i < 1000; ++i) {
    const Vector3d f(u(rng), u(rng), u(rng));
    ForceStatus status;
    const Vector3d out = safety.update(command(f, 0.0), 0.0, &status);
    if (f.norm() > p.maxForce) {
      EXPECT_EQ(status, ForceStatus::Clamped);
      EXPECT_NEAR(out.norm(), p.maxForce, 1e-12);
      EXPECT_NEAR(out.normalized().dot(f.normalized()), 1.0, 1e-12);
    } else {
      EXPECT_EQ(out, f);
    }
  }
  EXPECT_GT(safety.counters().clamped, 900u);
}

TEST(ForceSafety, NonFiniteCommandGivesZeroAtOnce) {
  ForceSafety safety;  // rate limit on: zero must still come at once, not ramp down
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  double t = 0.0;
  for (int i = 0; i < 100; ++i, t += 0.001) safety.update(command(Vector3d(0.3, 0.0, 0.0), t), t);
  ASSERT_GT(safety.lastOutput().norm(), 0.25);
  for (const Vector3d& bad :
       {Vector3d(nan, 0, 0), Vector3d(0, inf, 0), Vector3d(0, 0, -inf), Vector3d(nan, nan, nan)}) {
    ForceStatus status;
    const Vector3d out = safety.update(command(bad, t), t, &status);
    EXPECT_EQ(status, ForceStatus::NonFinite);
    EXPECT_EQ(out, Vector3d::Zero());
    EXPECT_TRUE(out.allFinite());
  }
  EXPECT_EQ(safety.counters().nonFinite, 4u);
}

TEST(ForceSafety, StaleCommandGivesZero) {
  ForceSafetyParams p = noRateLimit();
  p.staleTimeout = 0.05;
  ForceSafety safety(p);
  const Vector3d f(0.0, 0.0, 0.4);
  ForceStatus status;
  EXPECT_EQ(safety.update(command(f, 1.0), 1.0 + 0.049, &status), f);
  EXPECT_EQ(status, ForceStatus::Ok);
  EXPECT_EQ(safety.update(command(f, 1.0), 1.0 + 0.051, &status), Vector3d::Zero());
  EXPECT_EQ(status, ForceStatus::Stale);
  EXPECT_EQ(safety.update(command(f, 1.0), 100.0, &status), Vector3d::Zero());
  EXPECT_EQ(status, ForceStatus::Stale);
  EXPECT_EQ(safety.counters().stale, 2u);
  // A fresh command renders again.
  EXPECT_EQ(safety.update(command(f, 100.0), 100.001, &status), f);
  EXPECT_EQ(status, ForceStatus::Ok);
}

TEST(ForceSafety, NoCommandYetGivesZeroWithoutCountingAnError) {
  ForceSafety safety;
  ForceStatus status;
  EXPECT_EQ(safety.update(ForceCommand{}, 5.0, &status), Vector3d::Zero());
  EXPECT_EQ(status, ForceStatus::NoCommand);
  EXPECT_EQ(safety.counters().stale + safety.counters().nonFinite, 0u);
}

TEST(ForceSafety, RateLimitBoundsEveryStepAndReachesTheTarget) {
  ForceSafetyParams p;
  p.maxForce = 0.8;
  p.maxForceRate = 100.0;  // N/s: 0.1 N per 1 ms tick
  p.staleTimeout = 10.0;
  ForceSafety safety(p);
  const Vector3d target(0.0, 0.6, 0.0);
  Vector3d previous = Vector3d::Zero();
  double t = 0.0;
  int ticks = 0;
  for (; ticks < 100; ++ticks, t += 0.001) {
    const Vector3d out = safety.update(command(target, 0.0), t);
    // Reference: the first tick starts at rest, then each step moves at most rate * dt.
    const double allowed = ticks == 0 ? 0.0 : p.maxForceRate * 0.001;
    EXPECT_LE((out - previous).norm(), allowed + 1e-12) << "tick " << ticks;
    const Vector3d expected = target.normalized() * std::min(target.norm(), 0.1 * ticks);
    EXPECT_NEAR((out - expected).norm(), 0.0, 1e-9) << "tick " << ticks;
    previous = out;
  }
  EXPECT_NEAR((previous - target).norm(), 0.0, 1e-12);
  // Reversal: the force swings through zero at the same rate.
  const Vector3d back = -target;
  for (int i = 1; i <= 12; ++i, t += 0.001) {
    const Vector3d out = safety.update(command(back, 0.0), t);
    EXPECT_LE((out - previous).norm(), p.maxForceRate * 0.001 + 1e-9);
    previous = out;
  }
  EXPECT_NEAR((previous - back).norm(), 0.0, 1e-9);
}

TEST(ForceSafety, RateLimitAppliesAfterTheClamp) {
  ForceSafetyParams p;
  p.maxForce = 0.5;
  p.maxForceRate = 1000.0;
  ForceSafety safety(p);
  double t = 0.0;
  Vector3d out;
  for (int i = 0; i < 50; ++i, t += 0.001) out = safety.update(command(Vector3d(30.0, 0, 0), t), t);
  EXPECT_NEAR(out.x(), 0.5, 1e-12);
}

TEST(ForceSafety, ClockGoingBackwardsAllowsNoChange) {
  ForceSafetyParams p;
  p.staleTimeout = 10.0;
  ForceSafety safety(p);
  safety.update(command(Vector3d(0.2, 0, 0), 1.0), 1.0);
  const Vector3d before = safety.update(command(Vector3d(0.2, 0, 0), 1.0), 1.01);
  const Vector3d after = safety.update(command(Vector3d(0.2, 0, 0), 1.0), 0.5);
  EXPECT_EQ(before, after);
}

TEST(ForceSafety, AfterZeroingTheForceRampsUpFromRest) {
  ForceSafetyParams p;
  p.maxForceRate = 100.0;
  p.staleTimeout = 0.05;
  ForceSafety safety(p);
  double t = 0.0;
  for (int i = 0; i < 20; ++i, t += 0.001) safety.update(command(Vector3d(0, 0, 0.5), t), t);
  ASSERT_NEAR(safety.lastOutput().z(), 0.5, 1e-12);
  // Stale: zero at once.
  EXPECT_EQ(safety.update(command(Vector3d(0, 0, 0.5), t - 1.0), t), Vector3d::Zero());
  t += 0.001;
  const Vector3d out = safety.update(command(Vector3d(0, 0, 0.5), t), t);
  EXPECT_NEAR(out.z(), 0.1, 1e-9);
}

TEST(ForceSafety, RejectsBadParameters) {
  auto make = [](double maxForce, double rate, double timeout) {
    ForceSafetyParams p;
    p.maxForce = maxForce;
    p.maxForceRate = rate;
    p.staleTimeout = timeout;
    return ForceSafety(p);
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(make(0.0, 100, 0.05), std::invalid_argument);
  EXPECT_THROW(make(-1.0, 100, 0.05), std::invalid_argument);
  EXPECT_THROW(make(nan, 100, 0.05), std::invalid_argument);
  EXPECT_THROW(make(0.5, -1, 0.05), std::invalid_argument);
  EXPECT_THROW(make(0.5, 100, 0.0), std::invalid_argument);
  EXPECT_THROW(make(0.5, 100, nan), std::invalid_argument);
  EXPECT_NO_THROW(make(0.5, 0.0, 0.05));
}
