// Joint states as the Phantom ROS drivers publish them, checked against the drivers' formulas written out
// by hand for chosen angles (omni_common omni_state.cpp and WPI-AIM geomagic_control device_node.cpp).
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "clod_haptics/device/joint_conventions.h"

using namespace clod_haptics::device;

namespace {
const double kJoints[3] = {0.1, 0.2, 0.5};
const double kGimbal[3] = {0.3, -0.4, 1.0};
constexpr double kPi = 3.14159265358979323846;
}  // namespace

TEST(JointConventions, OmniCommonNegatesTheWaistAndTakesTheElbowRelativeToTheShoulder) {
  const auto q = driverJointStates(kJoints, kGimbal, JointConvention::OmniCommon);
  EXPECT_DOUBLE_EQ(q[0], -0.1);              // waist = -j0
  EXPECT_DOUBLE_EQ(q[1], 0.2);               // shoulder = j1
  EXPECT_DOUBLE_EQ(q[2], 0.3);               // elbow = j2 - j1
  EXPECT_DOUBLE_EQ(q[3], kPi - 0.3);         // yaw = -g0 + pi
  EXPECT_DOUBLE_EQ(q[4], 0.4 - 0.75 * kPi);  // pitch = -g1 - 3 pi / 4
  EXPECT_DOUBLE_EQ(q[5], -1.0 - kPi);        // roll = -g2 - pi
}

TEST(JointConventions, GeomagicControlDiffersOnlyInTheRollSign) {
  const auto omni = driverJointStates(kJoints, kGimbal, JointConvention::OmniCommon);
  const auto touch = driverJointStates(kJoints, kGimbal, JointConvention::GeomagicControl);
  for (int i = 0; i < 5; ++i) EXPECT_DOUBLE_EQ(touch[i], omni[i]) << i;
  EXPECT_DOUBLE_EQ(touch[5], 1.0 + kPi);  // roll = g2 + pi
}

TEST(JointConventions, RawKeepsTheDeviceAngles) {
  const auto q = driverJointStates(kJoints, kGimbal, JointConvention::Raw);
  const double expected[6] = {0.1, 0.2, 0.5, 0.3, -0.4, 1.0};
  for (int i = 0; i < 6; ++i) EXPECT_DOUBLE_EQ(q[i], expected[i]) << i;
}

TEST(JointConventions, ParsesTheParameterAndRejectsOtherNames) {
  EXPECT_EQ(parseJointConvention("omni_common"), JointConvention::OmniCommon);
  EXPECT_EQ(parseJointConvention("geomagic_control"), JointConvention::GeomagicControl);
  EXPECT_EQ(parseJointConvention("raw"), JointConvention::Raw);
  EXPECT_THROW(parseJointConvention("touch"), std::invalid_argument);
}
