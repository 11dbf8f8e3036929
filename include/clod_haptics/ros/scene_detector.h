#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <geometry_msgs/PoseStamped.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include "clod_haptics/core/contact.h"
#include "clod_haptics/core/scene.h"
#include "clod_haptics/core/scene_assets.h"
#include "clod_haptics/ros/scene_config.h"

namespace clod_haptics {

/**
 * \brief The scene detector glue shared by the nodelet and the standalone node: stylus pose in, one
 * ContactArray (every object the pointer touches) and one combined WrenchStamped out per pose.
 *
 * Parameters: ~scene (a scene file loaded with rosparam, see SceneConfig), ~pose_topic,
 * ~pointer_radius, ~detection_mode, ~stiffness, ~max_force, ~cache_dir, ~fast_level, ~marker_rate,
 * ~marker_objects (names to draw; empty: all), ~pose_queue_size, ~static_retry (s), ~quick_start,
 * ~grid_on_demand, ~detectors_on_demand, ~prefetch_margin (m), ~cache_meshes (loaded meshes in the
 * cache too, so a restart skips the mesh parser).
 *
 * Threads: poses arrive on the caller's node handle (the haptic path: one tf2 lookup for the pose's
 * frame when it differs from the scene frame, one per moving object, then one allocation-free
 * SceneDetector query). Static frames other than the scene frame are looked up once and cached. A
 * worker thread prepares each object's level (disk cache, or a build) and hands it over; the pose
 * thread swaps it in, so no pose waits for a build (objects without a level are answered by brute
 * force). Objects the pointer comes near (~prefetch_margin) are prepared first. With ~quick_start
 * and the grid fast level, every object first gets a hierarchy detector (cheap to construct from
 * the cached spheres), then the grid one replaces it in the background: for every object, or with
 * ~grid_on_demand only for the objects the pointer comes within ~prefetch_margin of. Every object's
 * sphere set is read (or built) at start-up; ~detectors_on_demand defers even the hierarchy
 * detectors of objects the pointer has not come near. Markers run on a private display queue, only while subscribed and only when changed.
 */
class SceneHapticDetector {
 public:
  /**
   * \brief Reads the parameters and loads every mesh; levels arrive asynchronously.
   * \throws InvalidParameter for a bad scene or parameter; MeshLoadError for a mesh that cannot be loaded.
   */
  SceneHapticDetector(ros::NodeHandle nh, ros::NodeHandle pnh);
  ~SceneHapticDetector();

  SceneHapticDetector(const SceneHapticDetector&) = delete;
  SceneHapticDetector& operator=(const SceneHapticDetector&) = delete;

 private:
  /** Per object, what the glue adds to the core scene. */
  struct ObjectState {
    SceneObjectConfig config;
    std::string meshPath;
    bool viaTf = false;           ///< frame differs from the scene frame
    bool poseKnown = false;       ///< static: looked up (or the scene frame); moving: last lookup succeeded
    ros::WallTime nextRetry;      ///< static frames not yet known: when to try again
    bool drawn = true;            ///< in ~marker_objects
    EIGEN_MAKE_ALIGNED_OPERATOR_NEW
  };
  /** What the display thread needs of the last answered pose. */
  struct LastQuery {
    std::uint64_t seq = 0;
    Vec3 pointer = Vec3::Zero();
    double radius = 0.0;
    std::vector<SceneContact> contacts;
    std::vector<std::uint32_t> nearObjects;  // objects whose bound the pointer reached
    std::vector<Eigen::Isometry3d, Eigen::aligned_allocator<Eigen::Isometry3d>> poses;  // world-from-object
  };

  void readParameters();
  void onPose(const geometry_msgs::PoseStampedConstPtr& msg);
  bool updatePoses(const ros::Time& stamp);
  void swapInReadyLevels();
  void freeRetiredLevels();
  void levelWorker();
  void onDisplayTimer(const ros::SteadyTimerEvent& event);
  void publishMarkers();

  ros::NodeHandle nh_;
  ros::NodeHandle pnh_;
  ros::CallbackQueue displayQueue_;
  ros::NodeHandle displayPnh_;
  std::unique_ptr<ros::AsyncSpinner> displaySpinner_;

  // Parameters.
  SceneConfig config_;
  std::string poseTopic_;
  std::string cacheDir_;
  double radius_ = 0.002;
  double stiffness_ = 500.0;
  double maxForce_ = 0.0;
  DetectionMode mode_ = DetectionMode::Exact;
  FastLevel fastLevel_ = FastLevel::Grid;
  double markerRate_ = 30.0;
  double staticRetry_ = 0.5;
  double prefetchMargin_ = 0.05;
  bool quickStart_ = true;
  bool cacheMeshes_ = true;
  bool gridOnDemand_ = true;
  bool detectorsOnDemand_ = false;
  int poseQueueSize_ = 5000;

  // Core.
  std::unique_ptr<SceneAssets> assets_;
  SceneDetector scene_;  // pose thread only (after construction)
  std::vector<ObjectState, Eigen::aligned_allocator<ObjectState>> objects_;
  std::vector<SceneContact> contacts_;  // pose thread: query output
  std::vector<QueryCache> caches_;      // pose thread: one per object

  // Levels handed from the worker to the pose thread.
  std::thread worker_;
  std::atomic<bool> stop_{false};
  std::mutex readyMutex_;
  std::vector<std::shared_ptr<const ClodDetector>> ready_;  // guarded by readyMutex_
  // Levels the pose thread swapped out, freed by the display thread (a level is megabytes of small arrays: its
  // free never runs on the haptic path). Guarded by readyMutex_; capacity for every object, so no allocation.
  std::vector<std::shared_ptr<const ClodDetector>> retired_;
  std::atomic<bool> readyPending_{false};
  std::atomic<std::uint32_t> levelsReady_{0};
  // Per object, set by the pose thread: the pointer is near and the final level is not in place yet,
  // so the worker prepares this object next ("asked for" by the stylus).
  std::unique_ptr<std::atomic<bool>[]> wanted_;

  // Counters.
  std::atomic<std::uint64_t> received_{0}, published_{0}, droppedNonFinite_{0}, droppedFrame_{0};

  // Last query, for markers.
  std::mutex lastMutex_;
  LastQuery last_;
  std::atomic<bool> staticDirty_{true};
  std::atomic<bool> levelsDirty_{true};

  // Display state (display thread only).
  std::uint64_t shownSeq_ = 0;
  std::vector<std::shared_ptr<const ClodDetector>> shownLevels_;
  std::vector<std::size_t> shownSpheres_, shownHit_;
  std::vector<char> shownContact_;
  std::vector<std::uint32_t> hitBuffer_;

  tf2_ros::Buffer tfBuffer_;
  std::unique_ptr<tf2_ros::TransformListener> tfListener_;

  ros::Subscriber poseSub_;
  ros::Publisher contactsPub_;
  ros::Publisher forcePub_;
  ros::Publisher markerPub_;
  ros::SteadyTimer displayTimer_;
};

}  // namespace clod_haptics
