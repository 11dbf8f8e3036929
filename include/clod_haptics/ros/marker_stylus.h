#pragma once

#include <geometry_msgs/PoseStamped.h>
#include <interactive_markers/interactive_marker_server.h>
#include <ros/ros.h>
#include <visualization_msgs/InteractiveMarkerFeedback.h>

#include <Eigen/Geometry>
#include <atomic>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

namespace clod_haptics {

/**
 * \brief A pose that follows a target at bounded speeds, one step per servo tick: the position moves along the
 * straight line to the target by at most maxSpeed * dt, the orientation turns along the shortest arc by at most
 * maxAngularSpeed * dt. A jump of the target (a dragged marker) becomes a motion a haptic loop can follow.
 */
class StylusInterpolator {
 public:
  /** \brief Starts at rest at start; speeds in m/s and rad/s (finite, positive). */
  StylusInterpolator(const Eigen::Isometry3d& start, double maxSpeed, double maxAngularSpeed);
  /** \brief The pose to move toward from the next step on. */
  void setTarget(const Eigen::Isometry3d& target);
  /** \brief Advances by dt seconds (dt <= 0: no motion) and returns the new pose. */
  const Eigen::Isometry3d& step(double dt);
  /** \brief The current pose. */
  const Eigen::Isometry3d& pose() const { return pose_; }
  /** \brief The pose moved toward. */
  const Eigen::Isometry3d& target() const { return target_; }

 private:
  Eigen::Isometry3d pose_, target_;
  double maxSpeed_, maxAngularSpeed_;
};

/** \brief Where the marker starts and how large it is drawn, from the bounds of the mesh it is meant to touch. */
struct StylusPlacement {
  Eigen::Vector3d start = Eigen::Vector3d::Zero();  ///< above the mesh's top face, centred over it
  double markerScale = 0.05;                         ///< the interactive marker's size (m)
  double maxSpeed = 0.1;                             ///< m/s: crosses the model in about two seconds
};

/** \brief The placement for a mesh whose bounds are box (model frame, metres). */
StylusPlacement placementForBounds(const Eigen::AlignedBox3d& box);

/**
 * \brief The stylus driven from RViz: an interactive marker (server namespace ~server, default "stylus_marker":
 * add an InteractiveMarkers display on /stylus_marker/update) whose dragged pose is the target of a
 * StylusInterpolator; a thread publishes the interpolated geometry_msgs/PoseStamped on ~pose_topic
 * (default /phantom/pose) at ~rate Hz (default 1000) with consecutive header.seq, so the detector sees a
 * device-like 1 kHz stream. A geometry_msgs/PoseStamped on ~goal (in ~frame_id) moves the target too
 * (scripts, tests). The marker starts above the mesh named by ~mesh (~scale, ~normalize: as the detector's),
 * sized to it; without ~mesh at ~start [x, y, z] with ~marker_scale and ~max_speed.
 * \throws std::invalid_argument for a non-positive rate or speed; MeshLoadError for an unreadable ~mesh.
 */
class MarkerStylus {
 public:
  MarkerStylus(ros::NodeHandle& nh, ros::NodeHandle& pnh);
  ~MarkerStylus();
  MarkerStylus(const MarkerStylus&) = delete;
  MarkerStylus& operator=(const MarkerStylus&) = delete;

 private:
  void makeMarker(const Eigen::Vector3d& start, double scale);
  void onFeedback(const visualization_msgs::InteractiveMarkerFeedbackConstPtr& feedback);
  void onGoal(const geometry_msgs::PoseStampedConstPtr& goal);
  void setTarget(const geometry_msgs::Pose& pose);
  void servoLoop();

  std::string frameId_;
  double rate_ = 1000.0;
  ros::Publisher posePub_;
  ros::Subscriber goalSub_;
  std::unique_ptr<interactive_markers::InteractiveMarkerServer> server_;
  std::mutex targetMutex_;
  Eigen::Isometry3d target_ = Eigen::Isometry3d::Identity();
  bool targetChanged_ = false;
  std::unique_ptr<StylusInterpolator> interpolator_;
  std::atomic<bool> running_{true};
  std::thread servo_;
};

}  // namespace clod_haptics
