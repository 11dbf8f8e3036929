#pragma once

#include <dynamic_reconfigure/server.h>
#include <geometry_msgs/PoseStamped.h>
#include <ros/callback_queue.h>
#include <ros/message_event.h>
#include <ros/ros.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "clod_haptics/DetectorConfig.h"
#include "clod_haptics/core/contact.h"
#include "clod_haptics/core/detector.h"
#include "clod_haptics/core/latency_histogram.h"
#include "clod_haptics/core/sphere_set.h"

namespace clod_haptics {

/** \brief What the detector does with poses that arrive faster than it answers (~pose_policy). */
enum class PosePolicy {
  All,     ///< answer every pose in order (recorded input, tests): nothing skipped, a backlog is worked off
  Latest,  ///< a live device: a pose with a newer one already waiting is skipped (counted), never answered late
};

/**
 * \brief The detector glue shared by the nodelet and the standalone node: stylus pose in, contact
 * and penalty force out, one of each per answered pose.
 *
 * Threads: poses arrive on a callback queue of their own, served by the pose thread (the haptic path:
 * a tf2 lookup when the frames differ, one allocation-free core query, two publishes), so nothing else
 * queued in the nodelet manager delays a pose. Markers, status and dynamic_reconfigure run on a private
 * display queue with its own thread. A worker thread (at a lower scheduling priority) fetches a new level
 * from sphere_builder (or builds it locally), swaps it in with an atomic shared_ptr exchange and frees the
 * old one itself, so no pose waits for a build or a free.
 *
 * Loss accounting (DetectorStatus): poses_lost_upstream counts gaps in the pose stream's header.seq
 * (poses that never reached the detector), poses_skipped_stale the poses the Latest policy skipped; the
 * answers carry consecutive header.seq numbers, so a subscriber sees any answer lost on the way to it.
 */
class HapticDetector {
 public:
  /**
   * \brief Reads the parameters, loads the mesh and starts the threads; the first level arrives
   * asynchronously (poses before it are answered by the brute-force reference).
   * \throws MeshLoadError when ~mesh is missing, unresolvable or unreadable.
   * \throws InvalidParameter for a bad ~scale, ~fast_level, ~detection_mode or ~clustering.
   */
  HapticDetector(ros::NodeHandle nh, ros::NodeHandle pnh);
  ~HapticDetector();

  HapticDetector(const HapticDetector&) = delete;
  HapticDetector& operator=(const HapticDetector&) = delete;

 private:
  /** \brief One level as the hot path sees it. Immutable once published. */
  struct Level {
    std::shared_ptr<const ClodDetector> detector;
    double distance = 0.0;
    std::uint32_t spheres = 0;
    std::string source;
    double readyMs = 0.0;
  };
  /** \brief What the display thread needs of the last answered pose. */
  struct LastQuery {
    bool valid = false;
    Vec3 pointer = Vec3::Zero();
    double radius = 0.0;
    ContactResult result;
    EIGEN_MAKE_ALIGNED_OPERATOR_NEW
  };

  void readParameters();
  void poseLoop();
  void onPose(const ros::MessageEvent<const geometry_msgs::PoseStamped>& event);
  void answer(const ros::MessageEvent<const geometry_msgs::PoseStamped>& event);
  void countSequence(const ros::MessageEvent<const geometry_msgs::PoseStamped>& event);
  std::shared_ptr<const Level> currentLevel();
  void waitUntilThePoseThreadLetsGo();
  void onReconfigure(DetectorConfig& config, std::uint32_t level);
  void requestLevel(double distance);
  void levelWorker();
  std::shared_ptr<const Level> makeLevel(double distance);
  std::shared_ptr<const ClodSphereSet> fetchFromService(double distance, std::string& why);
  void onDisplayTimer(const ros::SteadyTimerEvent& event);
  void onStatusTimer(const ros::SteadyTimerEvent& event);
  void publishStatus();
  void publishMarkers();

  ros::NodeHandle nh_;
  ros::NodeHandle pnh_;
  ros::CallbackQueue poseQueue_;  // the pose subscription alone: its emptiness means no newer pose waits
  ros::NodeHandle poseNh_;
  std::thread poseThread_;
  ros::MessageEvent<const geometry_msgs::PoseStamped> newestPose_;  // pose thread, pose_policy latest: the newest pose
  bool newestValid_ = false;
  std::atomic<bool> poseStop_{false};
  ros::CallbackQueue displayQueue_;
  ros::NodeHandle displayPnh_;
  std::unique_ptr<ros::AsyncSpinner> displaySpinner_;

  // Parameters (fixed after construction).
  std::string meshUri_;
  std::string meshFrame_;
  std::string poseTopic_;
  std::string serviceName_;
  double scale_ = 1.0;
  bool normalize_ = false;
  double serviceTimeout_ = 5.0;
  bool useService_ = true;
  PosePolicy posePolicy_ = PosePolicy::All;
  int poseQueueSize_ = 5000;     // poses roscpp keeps for the detector (5 s at 1 kHz); a gap beyond it is counted
  int publishQueueSize_ = 5000;  // contacts and forces kept per subscriber that reads too slowly
  int realtimePriority_ = 0;     // SCHED_FIFO priority of the pose thread; 0: the default scheduler
  double markerRate_ = 30.0;
  FastLevel fastLevel_ = FastLevel::Grid;
  double gridRadius_ = 0.0;  // 0: the core's default (1% of the model's diagonal)

  std::shared_ptr<const TriangleMesh> mesh_;
  std::shared_ptr<const Clustering> clustering_;  // ~clustering, for levels built here when the service is absent
  std::unique_ptr<ClodBuilder> localBuilder_;  // lazily, on the worker thread only

  // Settings the hot path reads (written by dynamic_reconfigure).
  std::atomic<double> radius_{0.002};
  std::atomic<double> stiffness_{500.0};
  std::atomic<double> maxForce_{0.0};
  std::atomic<int> mode_{static_cast<int>(DetectionMode::Exact)};
  std::atomic<bool> showMesh_{true}, showSpheres_{true}, showHit_{true}, showContact_{true}, showPointer_{true};

  // The current level. The pose thread reads a raw pointer: no lock and no reference count, nothing it could
  // wait for behind a preempted background thread. The worker owns the level (level_) and lets a replaced one
  // go only once the pose thread has left every callback that may still use it: poseEpoch_ is odd while a
  // callback runs (a single reader's read-copy-update).
  std::atomic<const Level*> poseLevel_{nullptr};
  std::atomic<std::uint64_t> poseEpoch_{0};
  // The same level for the worker, the display thread and the status, under a mutex the pose thread never takes.
  std::mutex levelMutex_;
  std::shared_ptr<const Level> level_;
  // Temporal coherence of the pose stream; used only by onPose, which one thread runs at a time
  // (ros::spin in the node, the nodelet's single-threaded handle). A new level ignores the old entry.
  QueryCache queryCache_;

  // Level worker.
  std::thread worker_;
  std::mutex workerMutex_;
  std::condition_variable workerCv_;
  bool stop_ = false;
  bool pending_ = false;
  double pendingDistance_ = 0.0;
  std::atomic<double> requestedDistance_{0.0};

  // Counters.
  std::atomic<std::uint64_t> received_{0}, published_{0}, droppedNonFinite_{0}, droppedFrame_{0}, bruteForce_{0},
      swaps_{0}, skippedStale_{0}, lostUpstream_{0};
  // Pose thread only: the last header.seq per publisher, for gaps.
  std::string lastPublisher_;
  std::uint32_t lastSeq_ = 0;
  bool haveSeq_ = false;
  // Pose path: receipt by roscpp to both answers published (microseconds), and the status heartbeat.
  LatencyHistogram posePath_;
  std::uint64_t statusSequence_ = 0;  // display thread and worker, under statusMutex_
  std::mutex statusMutex_;
  std::uint64_t warnedSkipped_ = 0, warnedLost_ = 0;  // display thread
  std::atomic<bool> markersWanted_{false};
  std::atomic<bool> statusDirty_{false};  // the worker swapped a level: the display thread publishes the status  // someone subscribes to ~markers: keep the last query for them

  // Last query, for markers.
  std::mutex lastMutex_;
  LastQuery last_;

  // Display state (display thread only, except the dirty flags). The mesh (megabytes for a large model) is sent
  // when a subscriber connects or show_mesh changes, the level's spheres when the level or show_spheres changes.
  std::atomic<bool> meshDirty_{true};
  std::atomic<bool> spheresDirty_{true};
  bool shownMesh_ = false;
  bool shownSpheresOn_ = false;
  std::uint64_t shownLevelId_ = 0;  // ClodDetector::id() of the level drawn last (an id is never reused)
  std::size_t shownSpheres_ = 0;
  std::size_t shownHit_ = 0;
  std::vector<std::uint32_t> hitBuffer_;

  tf2_ros::Buffer tfBuffer_;
  std::unique_ptr<tf2_ros::TransformListener> tfListener_;

  boost::recursive_mutex configMutex_;
  std::unique_ptr<dynamic_reconfigure::Server<DetectorConfig>> reconfigure_;

  ros::Subscriber poseSub_;
  ros::Publisher contactPub_;
  ros::Publisher forcePub_;
  ros::Publisher markerPub_;
  ros::Publisher statusPub_;
  ros::SteadyTimer displayTimer_;
  ros::SteadyTimer statusTimer_;
};

}  // namespace clod_haptics
