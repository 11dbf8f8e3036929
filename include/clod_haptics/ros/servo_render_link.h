#pragma once

#include <clod_haptics/DetectorConfig.h>
#include <dynamic_reconfigure/Config.h>
#include <ros/ros.h>

#include <atomic>
#include <memory>
#include <string>

#include "clod_haptics/device/servo_renderer.h"

namespace clod_haptics {
namespace device {

/**
 * \brief The bridge's side of servo-loop rendering: builds the ServoRenderer's scene from the detector's own
 * parameters (its ~mesh, ~scale, ~normalize, ~frame_id, so the device feels what the detector reports) and keeps
 * the renderer's settings equal to the detector's as they are reconfigured (its ~parameter_updates: pointer_radius,
 * stiffness, damping, max_force, mu_static, mu_dynamic, force_shading; force_model penalty disables it).
 * Built off the servo thread; the scene is fixed (a single static mesh).
 */
class ServoRenderLink {
 public:
  /**
   * \param detectorNs the detector's private namespace ("/detector")
   * \param deviceFrame the frame of the device's poses; another frame than the detector's is looked up in TF once
   * \throws std::runtime_error naming why servo rendering cannot run (no ~mesh, a scene file, a mesh that does not
   * load, no transform between the frames)
   */
  ServoRenderLink(ros::NodeHandle nh, const std::string& detectorNs, const std::string& deviceFrame);

  /** \brief The renderer to attach to the device, or to run in the bridge's tick. */
  const std::shared_ptr<ServoRenderer>& renderer() const { return renderer_; }
  /** \brief Whether the detector's force model is proxy, so the renderer renders (ROS callback thread's view). */
  bool enabled() const { return enabled_.load(std::memory_order_relaxed); }
  /** \brief One line for the log: mesh, triangles, frames, build time. */
  const std::string& description() const { return description_; }

  /** \brief Applies a dynamic_reconfigure update of the detector (exposed for tests). */
  void apply(const dynamic_reconfigure::Config& config);

 private:
  void follow();  // settings_ from config_

  DetectorConfig config_;         // the detector's parameters as last seen (ROS callback thread after construction)
  ServoRenderSettings settings_;  // ROS callback thread after construction
  std::atomic<bool> enabled_{true};
  std::shared_ptr<ServoRenderer> renderer_;
  ros::Subscriber updates_;
  std::string description_;
};

}  // namespace device
}  // namespace clod_haptics
