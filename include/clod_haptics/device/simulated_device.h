#pragma once

#include <functional>
#include <mutex>
#include <string>
#include <vector>

#include "clod_haptics/device/haptic_device.h"

namespace clod_haptics {
namespace device {

/** \brief One keyframe of a scripted stylus motion. */
struct ScriptSample {
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
  double time = 0.0;                                                ///< seconds from the script start
  Eigen::Vector3d position = Eigen::Vector3d::Zero();               ///< metres
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  ///< unit quaternion
  std::uint32_t buttons = 0;                                        ///< DeviceButton bits
};

/** \brief A force the simulated device received, with the device time it arrived at. */
struct RecordedForce {
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
  double time = 0.0;
  Eigen::Vector3d force = Eigen::Vector3d::Zero();
};

/**
 * \brief A device without hardware: plays a scripted motion (keyframes, linearly interpolated,
 * held at the ends or looped) and records every force it is commanded, so the bridge's logic is
 * tested end to end. Time comes from a clock function, by default a steady clock started by
 * start(); tests pass their own.
 */
class SimulatedDevice : public HapticDevice {
 public:
  using Clock = std::function<double()>;

  /**
   * \param script keyframes with increasing times (at least one)
   * \param loop   restart the script after its last keyframe instead of holding it
   * \param clock  seconds; empty for a steady clock whose zero is start()
   * \throws DeviceError for an empty script, non-increasing times or non-finite values
   */
  explicit SimulatedDevice(std::vector<ScriptSample> script, bool loop = false, Clock clock = {});

  void start() override;
  void stop() override;
  bool read(DeviceState& state) override;
  void commandForce(const Eigen::Vector3d& force) override;
  std::string name() const override { return "simulated"; }

  /** \brief The scripted state at time t (seconds from the script start). */
  DeviceState sample(double t) const;
  /** \brief Every force received since start (at most maxRecorded, the oldest dropped first). */
  std::vector<RecordedForce> recordedForces() const;
  /** \brief The last force received (zero before any). */
  Eigen::Vector3d lastForce() const;
  /** \brief Number of forces received since construction. */
  std::size_t forceCount() const;
  /** \brief Script duration, seconds. */
  double duration() const { return script_.back().time; }
  bool running() const { return running_; }

  /** \brief A horizontal circle of the given radius around centre, one turn per period, looped. */
  static std::vector<ScriptSample> circleScript(const Eigen::Vector3d& centre, double radius, double period,
                                                int keyframes = 64);
  /**
   * \brief Reads a CSV script: lines "t, x, y, z[, buttons]" (seconds, metres), '#' comments.
   * \throws DeviceError naming the file and line for anything else.
   */
  static std::vector<ScriptSample> loadCsvScript(const std::string& path);

  /** \brief How many recorded forces are kept (a ring: the newest stay). */
  static constexpr std::size_t maxRecorded = 1u << 20;

 private:
  double now() const;

  std::vector<ScriptSample> script_;
  bool loop_;
  Clock clock_;
  double startTime_ = 0.0;
  bool running_ = false;
  mutable std::mutex forcesMutex_;
  std::vector<RecordedForce> forces_;
  std::size_t forceCount_ = 0;
  Eigen::Vector3d lastForce_ = Eigen::Vector3d::Zero();
};

}  // namespace device
}  // namespace clod_haptics
