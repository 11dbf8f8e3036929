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
#include "clod_haptics/core/haptic_renderer.h"
#include "clod_haptics/core/latency_histogram.h"
#include "clod_haptics/core/scene.h"
#include "clod_haptics/core/scene_assets.h"
#include "clod_haptics/ros/detector_display.h"
#include "clod_haptics/ros/scene_config.h"

namespace clod_haptics {

/** \brief What the detector does with poses that arrive faster than it answers (~pose_policy). */
enum class PosePolicy {
  All,     ///< answer every pose in order (recorded input, tests): nothing skipped, a backlog is worked off
  Latest,  ///< a live device: a pose with a newer one already waiting is skipped (counted), never answered late
};

/** \brief The ~pose_policy name of a policy: "all" or "latest". */
inline const char* toString(PosePolicy policy) { return policy == PosePolicy::Latest ? "latest" : "all"; }

/**
 * \brief The detector's fixed parameters (read once by readParameters) with their defaults, the one place
 * the code keeps them; config/detector.yaml documents the same values. The settings dynamic_reconfigure
 * changes (distance, radius, stiffness, ...) take their defaults from cfg/Detector.cfg.
 */
struct DetectorParameters {
  std::string mesh;               ///< ~mesh: one object (a scene of one); or ~scene, a scene file
  std::string frameId = "world";  ///< ~frame_id: the frame of ~mesh
  double scale = 1.0;             ///< ~scale of ~mesh (file units to metres)
  bool normalize = false;         ///< ~normalize ~mesh into the unit cube
  std::string poseTopic = "/phantom/pose";
  std::string sphereService = "sphere_builder/get_sphere_set";
  bool useService = true;       ///< ask sphere_builder for levels the disk cache lacks
  double serviceTimeout = 5.0;  ///< s to wait for sphere_builder before building here
  bool useCache = true;         ///< keep levels in a disk cache (~cache_dir)
  std::string cacheDir;         ///< "": $CLOD_CACHE_DIR, else $ROS_HOME/clod_haptics_cache, else ~/.ros/...
  bool cacheMeshes = true;      ///< also cache parsed meshes (a restart skips the parser)
  std::string clustering = "single-link";
  FastLevel fastLevel = FastLevel::Grid;
  /// Largest pointer radius the grid serves; 0: the pointer radius, followed when it is reconfigured (the grids
  /// are rebuilt off the haptic path, the old ones answering meanwhile, larger radii through the hierarchy).
  double gridRadius = 0.0;
  PosePolicy posePolicy = PosePolicy::All;
  int poseQueueSize = 5000;        ///< poses roscpp keeps for the detector (5 s at 1 kHz)
  int publishQueueSize = 5000;     ///< answers kept per subscriber that reads too slowly
  int realtimePriority = 50;       ///< SCHED_FIFO priority of the pose thread where allowed; 0: the default scheduler
  double markerRate = 30.0;        ///< Hz, only while ~markers has subscribers
  double staticRetry = 0.5;        ///< s between lookups of a static frame tf2 does not know yet
  double prefetchMargin = 0.05;    ///< m: objects this close to the pointer get their levels first
  bool quickStart = false;         ///< answer with hierarchy detectors first, then swap in the final ones
  bool gridOnDemand = false;       ///< grid detectors only for objects the pointer comes near
  bool detectorsOnDemand = false;  ///< no detector before the pointer comes near (sets are always read)
};

/**
 * \brief The detector glue the nodelet and the node share: stylus pose in; per pose one Contact (~contact:
 * the deepest contact), one ContactArray (~contacts: every object touched) and one force (~force): with
 * force_model proxy the god-object proxy's spring (HapticRenderer over a SweptScene of the same objects, its
 * centre on ~proxy while someone listens; it starts at the first pose that touches nothing, the penalty force
 * answering until then), with penalty the combined penalty spring; a DetectorStatus
 * heartbeat (~status) and markers (~markers, the proxy beside the pointer) at display rate.
 *
 * A single mesh (~mesh) is a scene of one object in ~frame_id; a scene file (~scene) gives several, on
 * static or moving tf2 frames (see SceneConfig). Either way one core SceneDetector answers.
 *
 * Threads: poses arrive on a callback queue of their own, served by the pose thread (tf2 lookups where
 * frames differ, one allocation-free core query, the publishes). Markers, status and dynamic_reconfigure run
 * on a display queue with its own thread. A worker thread (at a lower priority) prepares each object's level
 * through SceneAssets (memory, disk cache, sphere_builder service, local build, in that order) and publishes
 * an immutable snapshot of all levels; the pose thread adopts a new snapshot between poses (and at least
 * every 50 ms when no pose comes), so the scene is touched by one thread only. A replaced snapshot is freed by
 * the display thread once the pose thread has adopted a newer one: no pose waits for a build or a free, and
 * the pose thread never takes a lock a lower-priority thread could hold.
 *
 * Loss accounting (DetectorStatus): poses_lost_upstream counts gaps in the pose stream's header.seq,
 * poses_skipped_stale the poses the Latest policy skipped; answers carry consecutive header.seq numbers.
 */
class HapticDetector {
 public:
  /**
   * \brief Reads the parameters, loads the meshes and starts the threads; levels arrive asynchronously
   * (objects without one are answered by the brute-force reference).
   * \throws MeshLoadError for a missing or unreadable mesh; InvalidParameter for a bad parameter or scene.
   */
  HapticDetector(ros::NodeHandle nh, ros::NodeHandle pnh);
  ~HapticDetector();

  HapticDetector(const HapticDetector&) = delete;
  HapticDetector& operator=(const HapticDetector&) = delete;

 private:
  /** \brief Per object, what the glue adds to the core scene. */
  struct ObjectState {
    SceneObjectConfig config;
    std::string meshPath;
    bool viaTf = false;      ///< its frame differs from the scene frame
    bool poseKnown = false;  ///< static: looked up (or the scene frame); moving: the last lookup succeeded
    ros::WallTime nextRetry;
    EIGEN_MAKE_ALIGNED_OPERATOR_NEW
  };
  /** \brief Every object's level, as the worker hands them to the pose thread. Immutable once published. */
  struct Levels {
    std::uint64_t id = 0;
    std::vector<std::shared_ptr<const ClodDetector>> detectors;   ///< per object; null: brute force
    std::vector<std::shared_ptr<const SweptSphereQuery>> sweeps;  ///< per object: the proxy's query over that level
    std::string source;                                           ///< where the newest level came from
    double readyMs = 0.0;                                         ///< how long it took
  };
  /** \brief The worker's plan for one object: the distance it wants and how far its level has come. */
  struct LevelPlan {
    double distance = 0.0;
    std::uint8_t step = 0;  ///< kNone, kSet, kQuick, kFinal (haptic_detector_levels.cpp)
    bool quick = true;      ///< a hierarchy detector first (~quick_start): at start-up, not after a distance change
    std::string source;     ///< where the sphere set came from
    double setMs = 0.0;     ///< how long reading or building it took
  };

  void readParameters();
  void loadObjects();
  void advertise();
  void startThreads();

  // Pose thread (haptic_detector.cpp).
  void poseLoop();
  void onPose(const ros::MessageEvent<const geometry_msgs::PoseStamped>& event);
  void countSequence(const ros::MessageEvent<const geometry_msgs::PoseStamped>& event);
  void answer(const ros::MessageEvent<const geometry_msgs::PoseStamped>& event);
  bool pointerInSceneFrame(const geometry_msgs::PoseStamped& msg, Vec3& p, Eigen::Isometry3d& sceneFromPose);
  void updateObjectPoses(const ros::Time& stamp);
  void adoptPublishedLevels();
  bool isFinal(const ClodDetector& level) const;
  void askForNearLevels(const Vec3& p);
  /** \brief Publishes the contact, the contacts and the force; returns the force (scene frame). */
  Vec3 publishAnswer(const geometry_msgs::PoseStamped& msg, const Vec3& p, double radius,
                     const Eigen::Isometry3d& sceneFromPose, const SceneQueryResult& out, std::int64_t detectionNs,
                     const ProxyTick* proxy);
  void keepForDisplay(const Vec3& p, double radius, std::uint32_t contacts, const ProxyTick* proxy, const Vec3& force);
  void publishProxyPose(const geometry_msgs::PoseStamped& msg, const std_msgs::Header& header,
                        const Eigen::Isometry3d& sceneFromPose, const Vec3& proxy);
  bool renderProxy(const geometry_msgs::PoseStamped& msg, const Vec3& p, double radius, bool touching, ProxyTick& tick);
  /// The pointer neither touches nor lies deep inside any object (a deep search from the point): where a proxy may
  /// start. A proxy started inside a closed mesh would stay trapped behind its surface.
  bool outsideEverything(const Vec3& p, double radius);

  // Levels (haptic_detector_levels.cpp).
  void onReconfigure(DetectorConfig& config, std::uint32_t level);
  void levelWorker();
  void followPointerRadius(double radius);
  bool prepareNextLevel(std::vector<LevelPlan>& plan);
  void publishLevel(std::size_t object, std::shared_ptr<const ClodDetector> detector, const std::string& source,
                    double ms);
  std::shared_ptr<const ClodSphereSet> fetchFromService(const TriangleMesh& mesh, double distance, std::string& why);
  void freeRetiredLevels();

  // Display thread (haptic_detector_status.cpp).
  void onDisplayTimer(const ros::SteadyTimerEvent& event);
  void onStatusTimer(const ros::SteadyTimerEvent& event);
  void publishStatus();

  ros::NodeHandle nh_;
  ros::NodeHandle pnh_;
  DetectorParameters params_;
  SceneConfig config_;
  bool singleMesh_ = false;  // ~mesh: the markers draw it as triangles, the namespaces carry no object name

  // Pose thread.
  ros::CallbackQueue poseQueue_;
  ros::NodeHandle poseNh_;
  std::thread poseThread_;
  std::atomic<bool> poseStop_{false};
  ros::MessageEvent<const geometry_msgs::PoseStamped> newestPose_;  // pose_policy latest: the newest pose
  bool newestValid_ = false;
  std::string lastPublisher_;  // the last header.seq per publisher, for gaps
  std::uint32_t lastSeq_ = 0;
  bool haveSeq_ = false;

  // Core (pose thread only, after construction).
  std::unique_ptr<SceneAssets> assets_;
  SceneDetector scene_;
  std::vector<ObjectState, Eigen::aligned_allocator<ObjectState>> objects_;
  std::vector<SceneContact> contacts_;                                // query output, one slot per object
  SceneCaches caches_;  // temporal coherence: per object, and near the pointer
  std::vector<SceneContact> startContacts_;                           // outsideEverything's query, one per object
  std::vector<QueryCache> startCaches_;                               // reset to "inside" for its deep search
  SweptScene sweptScene_;                                             // the same objects for the proxy's swept queries
  std::vector<std::shared_ptr<const SweptSphereQuery>> firstSweeps_;  // held so no swap frees them on the pose thread
  HapticRenderer renderer_;                                           // the proxy (force_model proxy)
  ros::Time lastStamp_;                    // the previous pose's stamp: the proxy's tick length
  bool proxyActive_ = false;               // the last pose was rendered by the proxy
  double proxyRadius_ = 0.0;               // the radius it was rendered with
  std::uint64_t adoptedId_ = 0;            // the Levels the scene uses (pose thread)
  std::atomic<std::uint64_t> adopted_{0};  // the same, for the thread that frees replaced Levels

  // Settings the hot path reads (written by dynamic_reconfigure).
  std::atomic<double> radius_{0.002};
  std::atomic<double> stiffness_{400.0};
  std::atomic<double> maxForce_{0.0};
  std::atomic<bool> proxyModel_{true};  // force_model: proxy (else penalty)
  std::atomic<double> damping_{0.0}, muStatic_{0.0}, muDynamic_{0.0};
  std::atomic<bool> forceShading_{false};
  std::atomic<int> mode_{static_cast<int>(DetectionMode::Exact)};
  std::atomic<double> requestedDistance_{0.0};
  bool configured_ = false;  // the first reconfigure call (start-up) keeps a scene's own distances

  // Levels: the worker publishes, the pose thread adopts, the display thread frees.
  std::thread worker_;
  std::mutex workerMutex_;
  std::condition_variable workerCv_;
  bool stop_ = false;
  bool distanceChanged_ = false;
  bool radiusChanged_ = false;                          // the grids must follow a new pointer radius
  bool gridFollowsPointer_ = false;                     // ~grid_radius 0: grids serve the pointer radius
  std::atomic<double> gridTarget_{0.0};                 // the radius final grids serve (when following)
  std::unique_ptr<std::atomic<bool>[]> wanted_;         // per object: the pointer is near, prepare it first
  std::atomic<const Levels*> published_{nullptr};       // the newest snapshot (owned by levels_)
  std::mutex levelsMutex_;                              // never taken by the pose thread
  std::shared_ptr<const Levels> levels_;                // the newest snapshot
  std::vector<std::shared_ptr<const Levels>> retired_;  // replaced snapshots, freed once a newer one is adopted
  std::uint64_t nextLevelsId_ = 1;

  // Counters.
  std::atomic<std::uint64_t> received_{0}, answered_{0}, droppedNonFinite_{0}, droppedFrame_{0}, bruteForce_{0},
      swaps_{0}, skippedStale_{0}, lostUpstream_{0};
  LatencyHistogram posePath_;  // receipt by roscpp to the answers published (microseconds)
  std::mutex statusMutex_;
  std::uint64_t statusSequence_ = 0;
  std::uint64_t warnedSkipped_ = 0, warnedLost_ = 0;
  std::atomic<bool> statusDirty_{false};

  // Display.
  ros::CallbackQueue displayQueue_;
  ros::NodeHandle displayPnh_;
  std::unique_ptr<ros::AsyncSpinner> displaySpinner_;
  std::atomic<bool> markersWanted_{false};
  std::mutex lastMutex_;
  DisplayFrame last_;  // the last answered pose, for the markers (try-locked by the pose thread)
  std::unique_ptr<DetectorDisplay> display_;

  tf2_ros::Buffer tfBuffer_;
  std::unique_ptr<tf2_ros::TransformListener> tfListener_;
  boost::recursive_mutex configMutex_;
  std::unique_ptr<dynamic_reconfigure::Server<DetectorConfig>> reconfigure_;

  ros::Subscriber poseSub_;
  ros::Publisher contactPub_;
  ros::Publisher contactsPub_;
  ros::Publisher forcePub_;
  ros::Publisher proxyPub_;
  ros::Publisher markerPub_;
  ros::Publisher statusPub_;
  ros::SteadyTimer displayTimer_;
  ros::SteadyTimer statusTimer_;
};

}  // namespace clod_haptics
