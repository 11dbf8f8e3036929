// HapticDetector: the display thread's work (status heartbeat, markers, freeing replaced levels).
#include <cmath>
#include <limits>

#include "clod_haptics/DetectorStatus.h"
#include "clod_haptics/ros/haptic_detector.h"

namespace clod_haptics {

void HapticDetector::onStatusTimer(const ros::SteadyTimerEvent&) {
  // Loss is never silent: warn (at most every 5 s per kind) whenever a counter grew.
  const std::uint64_t lost = lostUpstream_.load(), skipped = skippedStale_.load();
  if (lost > warnedLost_) {
    ROS_WARN_THROTTLE(5.0,
                      "detector: %lu poses lost before reaching the detector (gaps in the pose stream's "
                      "header.seq; %lu in all): a publisher or roscpp queue dropped them",
                      static_cast<unsigned long>(lost - warnedLost_), static_cast<unsigned long>(lost));
  }
  if (skipped > warnedSkipped_) {
    ROS_WARN_THROTTLE(5.0,
                      "detector: skipped %lu stale poses (pose_policy latest: a newer pose was waiting; %lu "
                      "in all): the detector falls behind the stream",
                      static_cast<unsigned long>(skipped - warnedSkipped_), static_cast<unsigned long>(skipped));
  }
  warnedLost_ = lost;
  warnedSkipped_ = skipped;
  publishStatus();
}

void HapticDetector::publishStatus() {
  auto status = boost::make_shared<DetectorStatus>();
  status->header.stamp = ros::Time::now();
  status->header.frame_id = config_.frameId;
  {
    std::lock_guard<std::mutex> lock(statusMutex_);
    status->sequence = ++statusSequence_;
  }
  status->poses_received = received_.load();
  status->contacts_published = answered_.load();
  status->dropped_non_finite = droppedNonFinite_.load();
  status->dropped_unknown_frame = droppedFrame_.load();
  status->poses_lost_upstream = lostUpstream_.load();
  status->poses_skipped_stale = skippedStale_.load();
  status->pose_policy = toString(params_.posePolicy);
  status->pose_queue_size = static_cast<std::uint32_t>(params_.poseQueueSize);
  status->publish_queue_size = static_cast<std::uint32_t>(params_.publishQueueSize);
  status->pose_path_p50_us = posePath_.percentileUs(50.0);
  status->pose_path_p99_us = posePath_.percentileUs(99.0);
  status->pose_path_p999_us = posePath_.percentileUs(99.9);
  status->pose_path_max_us = posePath_.maxUs();
  status->pose_path_period_max_us = posePath_.takePeriodMaxUs();
  status->answered_without_level = bruteForce_.load();
  status->level_swaps = swaps_.load();
  status->requested_distance = requestedDistance_.load();
  std::shared_ptr<const Levels> levels;
  {
    std::lock_guard<std::mutex> lock(levelsMutex_);
    levels = levels_;
  }
  // The distance every object's level shares (NaN while one has none or they differ), their spheres in all.
  double distance = std::numeric_limits<double>::quiet_NaN();
  double gridRadius = levels && !levels->detectors.empty() ? std::numeric_limits<double>::infinity() : 0.0;
  std::uint32_t spheres = 0;
  bool complete = levels != nullptr;
  for (std::size_t i = 0; levels && i < levels->detectors.size(); ++i) {
    const auto& level = levels->detectors[i];
    gridRadius = std::min(gridRadius, level ? level->gridRadius() : 0.0);
    if (!level) {
      complete = false;
      continue;
    }
    spheres += static_cast<std::uint32_t>(level->spheres()->size());
    const double d = level->spheres()->distance;
    if (i == 0) distance = d;
    if (d != distance) complete = false;
  }
  status->clustering_distance = complete ? distance : std::numeric_limits<double>::quiet_NaN();
  status->level_spheres = spheres;
  status->grid_radius = gridRadius;
  status->level_source = levels ? levels->source : "";
  status->level_ready_ms = levels ? levels->readyMs : 0.0;
  statusPub_.publish(status);
}

void HapticDetector::onDisplayTimer(const ros::SteadyTimerEvent&) {
  freeRetiredLevels();
  if (statusDirty_.exchange(false)) publishStatus();  // a new level: say so now, not at the next second
  const bool wanted = markerPub_.getNumSubscribers() > 0;
  markersWanted_.store(wanted, std::memory_order_relaxed);
  if (!wanted) return;
  std::vector<std::shared_ptr<const ClodDetector>> levels;
  {
    std::lock_guard<std::mutex> lock(levelsMutex_);
    if (levels_) levels = levels_->detectors;
  }
  DisplayFrame frame;
  {
    std::lock_guard<std::mutex> lock(lastMutex_);
    frame = last_;
  }
  auto array = boost::make_shared<visualization_msgs::MarkerArray>();
  display_->update(levels, frame, *array);
  if (!array->markers.empty()) markerPub_.publish(array);
}

}  // namespace clod_haptics
