// The scene detector as a nodelet: onInit constructs the glue class and returns.
#include <memory>

#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>

#include "clod_haptics/ros/scene_detector.h"

namespace clod_haptics {

/** \brief Nodelet wrapper of SceneHapticDetector (several objects, intra-process poses in). */
class SceneDetectorNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    try {
      detector_ = std::make_unique<SceneHapticDetector>(getNodeHandle(), getPrivateNodeHandle());
    } catch (const std::exception& e) {
      NODELET_FATAL("scene_detector: %s", e.what());
      throw;  // the manager reports the load as failed
    }
  }

  std::unique_ptr<SceneHapticDetector> detector_;
};

}  // namespace clod_haptics

PLUGINLIB_EXPORT_CLASS(clod_haptics::SceneDetectorNodelet, nodelet::Nodelet)
