#include "clod_haptics/device/joint_conventions.h"

#include <cmath>
#include <stdexcept>

namespace clod_haptics {
namespace device {

std::array<double, 6> driverJointStates(const double joints[3], const double gimbal[3], JointConvention convention) {
  if (convention == JointConvention::Raw) return {joints[0], joints[1], joints[2], gimbal[0], gimbal[1], gimbal[2]};
  const double roll = convention == JointConvention::OmniCommon ? -gimbal[2] - M_PI : gimbal[2] + M_PI;
  return {-joints[0], joints[1], joints[2] - joints[1], -gimbal[0] + M_PI, -gimbal[1] - 3.0 * M_PI / 4.0, roll};
}

JointConvention parseJointConvention(const std::string& name) {
  if (name == "omni_common") return JointConvention::OmniCommon;
  if (name == "geomagic_control") return JointConvention::GeomagicControl;
  if (name == "raw") return JointConvention::Raw;
  throw std::invalid_argument("~joint_convention must be omni_common, geomagic_control or raw, got '" + name + "'");
}

}  // namespace device
}  // namespace clod_haptics
