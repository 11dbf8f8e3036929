#pragma once

#include <array>
#include <string>

namespace clod_haptics {
namespace device {

/**
 * \brief How the six Phantom / Touch angles are published on <name>/joint_states (waist, shoulder, elbow,
 * yaw, pitch, roll) so the drivers' URDFs look right in RViz. From HD_CURRENT_JOINT_ANGLES j and
 * HD_CURRENT_GIMBAL_ANGLES g (radians):
 *   OmniCommon       (omni_common omni_state, phantom_omni and Geomagic_Touch_ROS_Drivers; omni_description):
 *                    waist = -j0, shoulder = j1, elbow = j2 - j1, yaw = -g0 + pi, pitch = -g1 - 3pi/4,
 *                    roll = -g2 - pi
 *   GeomagicControl  (WPI-AIM ros_geomagic geomagic_control device_node; geomagic_description): the same but
 *                    roll = g2 + pi
 *   Raw              j0, j1, j2, g0, g1, g2 unchanged
 */
enum class JointConvention { OmniCommon, GeomagicControl, Raw };

/** \brief waist, shoulder, elbow, yaw, pitch, roll in the given convention. */
std::array<double, 6> driverJointStates(const double joints[3], const double gimbal[3], JointConvention convention);

/** \brief "omni_common", "geomagic_control" or "raw". \throws std::invalid_argument for anything else. */
JointConvention parseJointConvention(const std::string& name);

}  // namespace device
}  // namespace clod_haptics
