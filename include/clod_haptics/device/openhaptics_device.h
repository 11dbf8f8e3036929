#pragma once

#include <mutex>
#include <string>

#include "clod_haptics/device/haptic_device.h"

namespace clod_haptics {
namespace device {

/**
 * \brief A Phantom / Geomagic Touch through the OpenHaptics HD API (compiled only with
 * CLOD_WITH_OPENHAPTICS). The HD scheduler's servo callback (about 1 kHz) reads the device and
 * renders the latest force; read() and commandForce() exchange data with it under a mutex held
 * for a copy only. Positions are converted as the omni_common driver does: device (x, y, z) in
 * millimetres, y up, becomes ROS (x, -z, y) in metres, z up; forces go the opposite way.
 * Joint angles are HD_CURRENT_JOINT_ANGLES then HD_CURRENT_GIMBAL_ANGLES, radians, unmodified.
 */
class OpenHapticsDevice : public HapticDevice {
 public:
  /** \brief deviceName as configured in Geomagic Touch Setup; empty for the default device. */
  explicit OpenHapticsDevice(std::string deviceName = {});
  ~OpenHapticsDevice() override;

  /** \throws DeviceError with the HD error text when the device cannot be initialised or started. */
  void start() override;
  void stop() override;
  bool read(DeviceState& state) override;
  void commandForce(const Eigen::Vector3d& force) override;
  std::string name() const override;

  /** \brief The servo callback's body; public only for the C callback trampoline. */
  bool servo();

 private:
  std::string deviceName_;
  unsigned int handle_ = 0;     // HHD
  unsigned long callback_ = 0;  // HDSchedulerHandle
  bool started_ = false;
  std::mutex mutex_;
  DeviceState state_;                                // guarded by mutex_
  bool haveState_ = false;                           // guarded by mutex_
  Eigen::Vector3d force_ = Eigen::Vector3d::Zero();  // guarded by mutex_, ROS frame
  std::string lastError_;                            // guarded by mutex_
};

}  // namespace device
}  // namespace clod_haptics
