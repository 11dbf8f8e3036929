// The detector as a nodelet: onInit constructs the glue class and returns.
#include <nodelet/nodelet.h>

#include <memory>
#include <pluginlib/class_list_macros.hpp>

#include "clod_haptics/ros/haptic_detector.h"

namespace clod_haptics {

/** \brief Nodelet wrapper of HapticDetector (intra-process poses in, contacts out without copies). */
class DetectorNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    try {
      detector_ = std::make_unique<HapticDetector>(getNodeHandle(), getPrivateNodeHandle());
    } catch (const std::exception& e) {
      NODELET_FATAL("detector: %s", e.what());
      throw;  // the manager reports the load as failed
    }
  }

  std::unique_ptr<HapticDetector> detector_;
};

}  // namespace clod_haptics

PLUGINLIB_EXPORT_CLASS(clod_haptics::DetectorNodelet, nodelet::Nodelet)
