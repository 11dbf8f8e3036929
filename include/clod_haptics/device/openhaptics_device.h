#pragma once

#include <atomic>
#include <string>

#include "clod_haptics/device/haptic_device.h"
#include "clod_haptics/device/joint_conventions.h"
#include "clod_haptics/device/servo_renderer.h"
#include "clod_haptics/device/triple_buffer.h"

namespace clod_haptics {
namespace device {

/** \brief What the OpenHaptics backend renders and publishes besides the raw device state. */
struct OpenHapticsOptions {
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
  std::string deviceName;  ///< as configured in Geomagic Touch Setup; empty: the default device
  /** \brief A command older than this (seconds, from the bridge writing it) is not rendered: zero force. */
  double forceTimeout = 0.05;
  /** \brief Device-side damping, N s/m, while a command is rendered (the drivers' 0.001 N per mm/s = 1.0). */
  double damping = 1.0;
  /** \brief Largest force sent to the motors, newtons (also capped at HD_NOMINAL_MAX_FORCE). */
  double maxForce = 0.8;
  JointConvention joints = JointConvention::OmniCommon;  ///< how joint angles are published
  /** \brief Added to the gimbal centre in the stylus frame (ROS axes), metres; zero: the gimbal centre. */
  Eigen::Vector3d tipOffset = Eigen::Vector3d::Zero();
};

/**
 * \brief A Phantom / Geomagic Touch through the OpenHaptics HD API. The HD scheduler's servo callback (1 kHz)
 * checks and updates calibration as the ROS drivers do, reads the device in a frame, renders the latest
 * force and checks hdGetError after every frame; a scheduler error (communication lost) ends the callback
 * and condition() becomes Failed. It never blocks and never allocates: states go out and force commands
 * come in through lock-free triple buffers. The force is zero while uncalibrated, stopping, or when the
 * last command is older than forceTimeout (the bridge thread stalled); otherwise the command plus damping,
 * capped at maxForce. Positions as the omni_common driver: device (x, y, z) in millimetres, y up, becomes
 * ROS (x, -z, y) in metres, z up; forces the opposite way. A frame with an error, or taken while
 * uncalibrated, gives no state.
 */
class OpenHapticsDevice : public HapticDevice {
 public:
  explicit OpenHapticsDevice(OpenHapticsOptions options = {});
  ~OpenHapticsDevice() override;

  /** \throws DeviceError with the HD error text when the device cannot be initialised or started. */
  void start() override;
  void stop() override;
  bool read(DeviceState& state) override;
  void commandForce(const Eigen::Vector3d& force) override;
  void commandForceFor(const Eigen::Vector3d& force, double poseStamp) override;
  std::string name() const override;
  DeviceCondition condition() const override;
  std::string conditionText() const override;
  ForceRatings ratings() const override { return ratings_; }
  const LatencyHistogram* forceLoopLatency() const override { return &latency_; }
  /** \brief Runs renderer in the servo callback (before start()); its force then replaces the commands. */
  bool attachServoRenderer(std::shared_ptr<ServoRenderer> renderer) override;

  /** \brief The servo callback's body (scheduler thread); true: run again next tick. Public for the C trampoline. */
  bool servo() noexcept;
  /** \brief Servo frames rendered with zero force because the last command was older than forceTimeout. */
  std::uint64_t staleFrames() const { return staleFrames_.load(std::memory_order_relaxed); }

 private:
  /** One servo frame's reading, handed to the bridge thread (plain data). */
  struct Sample {
    double transform[16];
    double joints[3];
    double gimbal[3];
    int buttons;
    double steadyTime;
    double wallTime;
    unsigned int errorCode;
    int internalError;
    unsigned int calibration;
    bool valid;
    std::uint64_t frame;
  };
  /** The bridge's latest force command, handed to the servo callback (ROS frame, newtons). */
  struct Command {
    double force[3];
    double writtenAt;  // steady clock seconds; 0: none yet
    double poseStamp;  // wall clock seconds of the pose it answers; 0: unknown
  };

  void renderForce(double now, double wallNow, bool calibrated, const double transform[16], const double velocity[3],
                   double out[3]) noexcept;
  /** The commanded (or servo-rendered) force, ROS frame; false when none is to be rendered (zero force). */
  bool commandedForce(double now, double wallNow, const double transform[16], Eigen::Vector3d& ros) noexcept;
  Eigen::Vector3d rosPosition(const double transform[16]) const;
  void startScheduler();
  void stopScheduler();

  OpenHapticsOptions options_;
  unsigned int handle_ = 0;     // HHD
  unsigned long callback_ = 0;  // HDSchedulerHandle
  unsigned int calibrationStyle_ = 0;
  bool started_ = false;
  std::string model_;
  ForceRatings ratings_;
  double maxForce_ = 0.0;

  TripleBuffer<Sample> samples_;    // servo thread -> bridge thread
  TripleBuffer<Command> commands_;  // bridge thread -> servo thread
  LatencyHistogram latency_;        // recorded by the servo thread
  std::shared_ptr<ServoRenderer> servoRenderer_;  // set before start(); used by the servo thread
  double lastPoseStamp_ = 0.0;      // servo thread
  std::uint64_t frames_ = 0;        // servo thread
  std::atomic<bool> stopping_{false};
  std::atomic<std::uint64_t> renderedFrames_{0};
  std::atomic<std::uint64_t> staleFrames_{0};
  std::atomic<bool> failed_{false};
  std::atomic<unsigned int> failCode_{0};
  std::atomic<int> failInternal_{0};
};

}  // namespace device
}  // namespace clod_haptics
