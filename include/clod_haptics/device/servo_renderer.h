#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <memory>

#include "clod_haptics/core/haptic_renderer.h"
#include "clod_haptics/core/swept_scene.h"
#include "clod_haptics/device/triple_buffer.h"

namespace clod_haptics {
namespace device {

/** \brief What the servo renderer renders with; changed by the bridge thread while the servo loop runs. */
struct ServoRenderSettings {
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
  bool enabled = true;         ///< false: the device renders the bridge's force commands instead
  ProxyParameters proxy;       ///< radius, stiffness, damping, clamp, friction, shading
  /** \brief The scene's frame from the device's (ROS axes, metres): where a device position lies in the scene. */
  Eigen::Isometry3d sceneFromDevice = Eigen::Isometry3d::Identity();
};

/** \brief The proxy of one servo tick, for the bridge thread to publish (scene frame, as ProxyTick). */
struct ServoRenderTick {
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
  ProxyTick tick;
  Eigen::Vector3d deviceForce = Eigen::Vector3d::Zero();  ///< the force render() returned, device frame
  bool active = false;  ///< the proxy runs (false: it waits for the device to leave every object)
  double time = 0.0;    ///< the servo loop's clock, seconds
  double stamp = 0.0;   ///< the wall-clock stamp render() was given (the device read's, as its pose carries)
  std::uint64_t frame = 0;
};

/**
 * \brief The god-object proxy updated inside a device's servo loop: each servo tick the device hands its
 * position and gets the force at once (no round trip through ROS), against a fixed SweptScene built off the
 * servo thread. The proxy starts only where the device touches nothing and is inside nothing
 * (SweptScene::clearAt): until then, and while disabled, the force is zero (render() says so).
 *
 * Threads: render() on the servo thread only; configure() and latest() on one other thread (the bridge's).
 * Settings and ticks cross through lock-free triple buffers; render() never blocks, never allocates, never throws.
 */
class ServoRenderer {
 public:
  /** \throws InvalidParameter when scene is null. */
  explicit ServoRenderer(std::shared_ptr<const SweptScene> scene, const ServoRenderSettings& settings = {});

  /** \brief New settings for the next servo tick (bridge thread). A new radius or frame restarts the proxy. */
  void configure(const ServoRenderSettings& settings) noexcept;

  /**
   * \brief One servo tick (servo thread): the device position (ROS axes, metres) at time (seconds, any steady
   * clock) gives the force in the same frame, newtons. stamp: the read's wall-clock time, kept in the tick (0:
   * unknown). \return false when disabled (force zero, untouched proxy): the caller renders something else.
   */
  bool render(const Eigen::Vector3d& devicePosition, double time, Eigen::Vector3d& force, double stamp = 0.0) noexcept;

  /** \brief The latest servo tick, if a newer one was rendered since the last call (bridge thread). */
  bool latest(ServoRenderTick& out) noexcept;

 private:
  std::shared_ptr<const SweptScene> scene_;
  TripleBuffer<ServoRenderSettings> settings_;  // bridge -> servo
  TripleBuffer<ServoRenderTick> ticks_;         // servo -> bridge
  // Servo thread only.
  HapticRenderer renderer_;
  ServoRenderSettings current_;
  bool active_ = false;
  double lastTime_ = 0.0;
  std::uint64_t frame_ = 0;
};

}  // namespace device
}  // namespace clod_haptics
