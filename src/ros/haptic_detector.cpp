#include "clod_haptics/ros/haptic_detector.h"

#include <geometry_msgs/WrenchStamped.h>
#include <tf2/exceptions.h>
#include <visualization_msgs/MarkerArray.h>

#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <chrono>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <limits>

#include "clod_haptics/Contact.h"
#include "clod_haptics/DetectorStatus.h"
#include "clod_haptics/GetSphereSet.h"
#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/clustering.h"
#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/ros/conversions.h"
#include "clod_haptics/ros/markers.h"
#include "clod_haptics/ros/mesh_resource.h"

namespace clod_haptics {

namespace {
double msSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

// The level worker yields the CPU to the pose thread: on a 2-core machine a level build would otherwise take the
// core the pose thread needs. Raising one's own nice value needs no privilege. Only a thread that shares no lock
// with the pose thread may run lower: the display thread publishes, and roscpp holds one process-wide lock while
// it serialises any message, so a preempted low-priority publisher would stall the pose thread's publish.
void lowerThisThreadPriority(int nice) {
  thread_local bool done = false;
  if (done) return;
  done = true;
  // The manager may run real-time (clod_haptics.launch): back to the default scheduler first, which needs no
  // privilege either.
  sched_param normal{};
  normal.sched_priority = 0;
  pthread_setschedparam(pthread_self(), SCHED_OTHER, &normal);
  const auto tid = static_cast<id_t>(::syscall(SYS_gettid));
  if (::setpriority(PRIO_PROCESS, tid, nice) != 0) {
    ROS_DEBUG("detector: could not lower a background thread's priority: %s", std::strerror(errno));
  }
}

const char* toString(PosePolicy policy) { return policy == PosePolicy::Latest ? "latest" : "all"; }
}  // namespace

HapticDetector::HapticDetector(ros::NodeHandle nh, ros::NodeHandle pnh) : nh_(nh), pnh_(pnh), displayPnh_(pnh) {
  displayPnh_.setCallbackQueue(&displayQueue_);
  readParameters();

  const std::string path = resolveMeshPath(meshUri_);
  MeshLoadOptions options;
  options.scale = scale_;
  options.normalize = normalize_;
  mesh_ = std::make_shared<const TriangleMesh>(loadMesh(path, options));
  ROS_INFO("detector: loaded '%s' (%zu triangles) in frame '%s'; poses from %s", path.c_str(), mesh_->size(),
           meshFrame_.c_str(), nh_.resolveName(poseTopic_).c_str());

  poseNh_ = nh_;
  poseNh_.setCallbackQueue(&poseQueue_);
  contactPub_ = pnh_.advertise<Contact>("contact", static_cast<std::uint32_t>(publishQueueSize_));
  forcePub_ = pnh_.advertise<geometry_msgs::WrenchStamped>("force", static_cast<std::uint32_t>(publishQueueSize_));
  statusPub_ = pnh_.advertise<DetectorStatus>("status", 1, true);
  // A new marker subscriber gets the mesh and spheres again.
  markerPub_ = displayPnh_.advertise<visualization_msgs::MarkerArray>(
      "markers", 10,
      [this](const ros::SingleSubscriberPublisher&) {
        meshDirty_ = true;
        spheresDirty_ = true;
      },
      ros::SubscriberStatusCallback());
  tfListener_ = std::make_unique<tf2_ros::TransformListener>(tfBuffer_, nh_);

  worker_ = std::thread(&HapticDetector::levelWorker, this);

  // Calls onReconfigure with the ~ parameters (config/detector.yaml), which requests the first level.
  reconfigure_ = std::make_unique<dynamic_reconfigure::Server<DetectorConfig>>(configMutex_, displayPnh_);
  reconfigure_->setCallback([this](DetectorConfig& config, std::uint32_t level) { onReconfigure(config, level); });

  poseSub_ = poseNh_.subscribe(poseTopic_, static_cast<std::uint32_t>(poseQueueSize_), &HapticDetector::onPose, this,
                               ros::TransportHints().tcpNoDelay());
  poseThread_ = std::thread(&HapticDetector::poseLoop, this);
  ROS_INFO("detector: pose policy '%s', pose queue %d, publish queue %d", toString(posePolicy_), poseQueueSize_,
           publishQueueSize_);
  displayTimer_ =
      displayPnh_.createSteadyTimer(ros::WallDuration(1.0 / markerRate_), &HapticDetector::onDisplayTimer, this);
  statusTimer_ = displayPnh_.createSteadyTimer(ros::WallDuration(1.0), &HapticDetector::onStatusTimer, this);
  displaySpinner_ = std::make_unique<ros::AsyncSpinner>(1, &displayQueue_);
  displaySpinner_->start();
  publishStatus();
}

HapticDetector::~HapticDetector() {
  poseSub_.shutdown();
  poseStop_ = true;
  if (poseThread_.joinable()) poseThread_.join();
  displayTimer_.stop();
  statusTimer_.stop();
  if (displaySpinner_) displaySpinner_->stop();
  {
    std::lock_guard<std::mutex> lock(workerMutex_);
    stop_ = true;
  }
  workerCv_.notify_all();
  if (worker_.joinable()) worker_.join();
}

void HapticDetector::readParameters() {
  if (!pnh_.getParam("mesh", meshUri_) || meshUri_.empty()) {
    throw MeshLoadError(
        "", "required parameter " + pnh_.resolveName("mesh") + " is not set (a mesh path or a package:// URI)");
  }
  pnh_.param<std::string>("frame_id", meshFrame_, "world");
  pnh_.param<std::string>("pose_topic", poseTopic_, "/phantom/pose");
  pnh_.param<std::string>("sphere_service", serviceName_, "sphere_builder/get_sphere_set");
  pnh_.param("scale", scale_, 1.0);
  pnh_.param("normalize", normalize_, false);
  pnh_.param("use_service", useService_, true);
  pnh_.param("service_timeout", serviceTimeout_, 5.0);
  pnh_.param("pose_queue_size", poseQueueSize_, 5000);
  pnh_.param("publish_queue_size", publishQueueSize_, 5000);
  pnh_.param("realtime_priority", realtimePriority_, 0);
  std::string policy;
  pnh_.param<std::string>("pose_policy", policy, "all");
  if (policy == "all") {
    posePolicy_ = PosePolicy::All;
  } else if (policy == "latest") {
    posePolicy_ = PosePolicy::Latest;
  } else {
    throw InvalidParameter("~pose_policy must be all (answer every pose) or latest (skip a pose a newer one waits "
                           "behind), not '" + policy + "'");
  }
  if (realtimePriority_ < 0 || realtimePriority_ > 99) throw InvalidParameter("~realtime_priority must be in 0..99");
  pnh_.param("marker_rate", markerRate_, 30.0);
  std::string fast;
  pnh_.param<std::string>("fast_level", fast, "grid");
  pnh_.param("grid_radius", gridRadius_, 0.0);
  if (!std::isfinite(scale_) || scale_ <= 0.0) throw InvalidParameter("~scale must be finite and positive");
  if (!parseFastLevel(fast.c_str(), fastLevel_)) {
    throw InvalidParameter("~fast_level must be grid, hierarchy or flat, not '" + fast + "'");
  }
  if (!std::isfinite(gridRadius_) || gridRadius_ < 0.0) throw InvalidParameter("~grid_radius must be >= 0");
  std::string clustering;
  pnh_.param<std::string>("clustering", clustering, "single-link");
  clustering_ = requireClustering(clustering, pnh_.resolveName("clustering"));
  if (!(markerRate_ > 0.0) || markerRate_ > 200.0) throw InvalidParameter("~marker_rate must be in (0, 200] Hz");
  if (poseQueueSize_ < 1) throw InvalidParameter("~pose_queue_size must be at least 1");
  if (publishQueueSize_ < 1) throw InvalidParameter("~publish_queue_size must be at least 1");
  std::string mode;
  if (pnh_.getParam("detection_mode", mode)) {
    DetectionMode parsed;
    if (!parseDetectionMode(mode.c_str(), parsed)) {
      throw InvalidParameter("~detection_mode must be exact, paper or spheres, not '" + mode + "'");
    }
  }
}

// ------------------------------------------------------------------------------------------------
// The haptic path.

void HapticDetector::poseLoop() {
  if (realtimePriority_ > 0) {
    sched_param param{};
    param.sched_priority = realtimePriority_;
    const int err = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param);
    if (err != 0) {
      // Not a warning: most desktops allow no real-time priority, and the detector works without it (its tail
      // latency then depends on what else runs; see the README).
      ROS_INFO("detector: ~realtime_priority %d not granted (%s): the pose thread stays on the default "
               "scheduler; allow it with 'ulimit -r %d' or an rtprio line in /etc/security/limits.conf",
               realtimePriority_, std::strerror(err), realtimePriority_);
    } else {
      ROS_INFO("detector: pose thread at SCHED_FIFO priority %d", realtimePriority_);
    }
  }
  while (!poseStop_.load(std::memory_order_relaxed)) {
    if (posePolicy_ == PosePolicy::All) {
      poseQueue_.callOne(ros::WallDuration(0.05));  // every pose, in order
      continue;
    }
    // Latest: take every pose that arrived while the last one was answered (onPose keeps the newest, counting the
    // others as skipped), then answer that one.
    poseQueue_.callAvailable(ros::WallDuration(0.05));
    if (!newestValid_) continue;
    newestValid_ = false;
    answer(newestPose_);
    newestPose_ = ros::MessageEvent<const geometry_msgs::PoseStamped>();
  }
}

void HapticDetector::countSequence(const ros::MessageEvent<const geometry_msgs::PoseStamped>& event) {
  const std::uint32_t seq = event.getConstMessage()->header.seq;
  const std::string& publisher = event.getPublisherName();
  if (seq == 0) {  // roscpp publishers leave it 0 unless the code numbers its poses: nothing to count by
    haveSeq_ = false;
    return;
  }
  const bool samePublisher = haveSeq_ && publisher == lastPublisher_;
  if (samePublisher) {
    const std::uint32_t step = seq - lastSeq_;  // modulo 2^32: a wrapped counter still steps by 1
    // A step back (a restarted publisher, a replay looping) starts counting again; a step forward by k > 1
    // means k - 1 poses were published that never reached this callback.
    if (step > 1u && step < (1u << 31)) {
      lostUpstream_.fetch_add(step - 1u, std::memory_order_relaxed);
    }
  } else {
    lastPublisher_ = publisher;  // allocates only when the publisher changes
  }
  lastSeq_ = seq;
  haveSeq_ = true;
}

void HapticDetector::onPose(const ros::MessageEvent<const geometry_msgs::PoseStamped>& event) {
  received_.fetch_add(1, std::memory_order_relaxed);
  countSequence(event);
  if (posePolicy_ == PosePolicy::All) {
    answer(event);
    return;
  }
  // Latest: poseLoop answers the newest pose of each batch; one it replaces here is never answered.
  if (newestValid_) skippedStale_.fetch_add(1, std::memory_order_relaxed);
  newestPose_ = event;
  newestValid_ = true;
}

void HapticDetector::answer(const ros::MessageEvent<const geometry_msgs::PoseStamped>& event) {
  const geometry_msgs::PoseStampedConstPtr& msg = event.getConstMessage();
  if (!isFinite(msg->pose)) {
    droppedNonFinite_.fetch_add(1, std::memory_order_relaxed);
    ROS_WARN_THROTTLE(1.0, "detector: dropped a pose with a NaN or Inf component (%lu so far)",
                      static_cast<unsigned long>(droppedNonFinite_.load()));
    return;
  }
  const auto& position = msg->pose.position;
  Vec3 p(position.x, position.y, position.z);
  const std::string& poseFrame = msg->header.frame_id;
  const bool transformed = !poseFrame.empty() && poseFrame != meshFrame_;
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  if (transformed) {
    geometry_msgs::TransformStamped tf;
    try {
      try {
        tf = tfBuffer_.lookupTransform(meshFrame_, poseFrame, msg->header.stamp);
      } catch (const tf2::ExtrapolationException&) {
        tf = tfBuffer_.lookupTransform(meshFrame_, poseFrame, ros::Time(0));  // latest known
      }
    } catch (const tf2::TransformException& e) {
      droppedFrame_.fetch_add(1, std::memory_order_relaxed);
      ROS_WARN_THROTTLE(1.0, "detector: dropped a pose in frame '%s': %s (%lu so far)", poseFrame.c_str(), e.what(),
                        static_cast<unsigned long>(droppedFrame_.load()));
      return;
    }
    const auto& q = tf.transform.rotation;
    const auto& t = tf.transform.translation;
    rotation = Eigen::Quaterniond(q.w, q.x, q.y, q.z).normalized();
    p = rotation * p + Vec3(t.x, t.y, t.z);
    // A huge but finite pose (1e308) can overflow to Inf when rotated: not a position either.
    if (!p.allFinite()) {
      droppedNonFinite_.fetch_add(1, std::memory_order_relaxed);
      ROS_WARN_THROTTLE(1.0, "detector: dropped a pose in frame '%s' that is not finite in frame '%s' (%lu so far)",
                        poseFrame.c_str(), meshFrame_.c_str(), static_cast<unsigned long>(droppedNonFinite_.load()));
      return;
    }
  }

  const double radius = radius_.load(std::memory_order_relaxed);
  const auto mode = static_cast<DetectionMode>(mode_.load(std::memory_order_relaxed));
  // Inside: the worker will not free the level read below until this callback has returned.
  poseEpoch_.fetch_add(1, std::memory_order_seq_cst);
  struct Leave {
    std::atomic<std::uint64_t>& epoch;
    ~Leave() { epoch.fetch_add(1, std::memory_order_release); }
  } leave{poseEpoch_};
  const Level* level = poseLevel_.load(std::memory_order_seq_cst);

  ContactResult result;
  const auto start = std::chrono::steady_clock::now();
  if (level) {
    level->detector->query(p, radius, mode, result, &queryCache_);  // one stream: this callback
  } else {
    result = bruteForceQuery(*mesh_, p, radius);  // no level yet: the reference answers
    bruteForce_.fetch_add(1, std::memory_order_relaxed);
  }
  const auto elapsed = std::chrono::steady_clock::now() - start;

  auto contact = boost::make_shared<Contact>();
  contact->header.stamp = msg->header.stamp;
  contact->header.frame_id = meshFrame_;
  toMsg(result, p, radius, *contact);
  contact->detection_time.fromNSec(std::chrono::duration_cast<std::chrono::nanoseconds>(elapsed).count());
  contact->clustering_distance = level ? level->distance : std::numeric_limits<double>::quiet_NaN();
  contact->level_spheres = level ? level->spheres : 0;

  // The force in the pose's frame, where the device renders it.
  const Vec3 forceMesh =
      penaltyForce(result, stiffness_.load(std::memory_order_relaxed), maxForce_.load(std::memory_order_relaxed));
  auto wrench = boost::make_shared<geometry_msgs::WrenchStamped>();
  wrench->header.stamp = msg->header.stamp;
  wrench->header.frame_id = poseFrame.empty() ? meshFrame_ : poseFrame;
  toMsg(transformed ? Vec3(rotation.conjugate() * forceMesh) : forceMesh, wrench->wrench);

  // Consecutive numbers: a subscriber that sees a gap knows an answer was lost on the way to it.
  const auto answer = static_cast<std::uint32_t>(published_.load(std::memory_order_relaxed) + 1);
  contact->header.seq = answer;
  wrench->header.seq = answer;
  contactPub_.publish(contact);
  forcePub_.publish(wrench);
  published_.fetch_add(1, std::memory_order_relaxed);
  if (!ros::Time::isSimTime()) posePath_.record((ros::Time::now() - event.getReceiptTime()).toNSec());

  if (!markersWanted_.load(std::memory_order_relaxed)) return;
  // For the markers only: if the display thread is copying it right now, this pose is not drawn rather than
  // waiting for a thread of lower priority.
  std::unique_lock<std::mutex> lock(lastMutex_, std::try_to_lock);
  if (!lock.owns_lock()) return;
  last_.valid = true;
  last_.pointer = p;
  last_.radius = radius;
  last_.result = result;
}

// ------------------------------------------------------------------------------------------------
// Reconfigure and levels.

void HapticDetector::onReconfigure(DetectorConfig& config, std::uint32_t /*level*/) {
  // dynamic_reconfigure clamps values to the ranges of cfg/Detector.cfg, but NaN passes every clamp
  // (comparisons with NaN are false): a NaN radius would answer "no contact" to every pose, a NaN
  // distance would ask for a level nobody can build. Keep the current value; the client gets it back.
  auto keepFinite = [](double& value, double current, const char* name) {
    if (std::isfinite(value)) return;
    ROS_WARN("detector: %s must be a finite number, not %g; keeping %g", name, value, current);
    value = current;
  };
  keepFinite(config.clustering_distance, requestedDistance_.load(), "clustering_distance");
  keepFinite(config.pointer_radius, radius_.load(), "pointer_radius");
  keepFinite(config.stiffness, stiffness_.load(), "stiffness");
  keepFinite(config.max_force, maxForce_.load(), "max_force");
  DetectionMode mode;
  if (parseDetectionMode(config.detection_mode.c_str(), mode)) {
    mode_ = static_cast<int>(mode);
  } else {
    ROS_WARN("detector: unknown detection_mode '%s' (exact, paper or spheres); keeping %s",
             config.detection_mode.c_str(), toString(static_cast<DetectionMode>(mode_.load())));
    config.detection_mode = toString(static_cast<DetectionMode>(mode_.load()));
  }
  radius_ = config.pointer_radius;
  stiffness_ = config.stiffness;
  maxForce_ = config.max_force;
  showMesh_ = config.show_mesh;
  showSpheres_ = config.show_spheres;
  showHit_ = config.show_hit_spheres;
  showContact_ = config.show_contact;
  showPointer_ = config.show_pointer;
  if (config.show_mesh != shownMesh_) meshDirty_ = true;
  if (config.show_spheres != shownSpheresOn_) spheresDirty_ = true;
  requestLevel(config.clustering_distance);
}

void HapticDetector::requestLevel(double distance) {
  requestedDistance_ = distance;
  {
    std::lock_guard<std::mutex> lock(workerMutex_);
    pendingDistance_ = distance;
    pending_ = true;
  }
  workerCv_.notify_all();
}

std::shared_ptr<const HapticDetector::Level> HapticDetector::currentLevel() {
  std::lock_guard<std::mutex> lock(levelMutex_);
  return level_;
}

void HapticDetector::waitUntilThePoseThreadLetsGo() {
  // poseLevel_ was stored before this load (both sequentially consistent): a callback that starts after it
  // reads the new level; one that was inside (odd epoch) may hold the old one until the epoch moves on.
  const std::uint64_t epoch = poseEpoch_.load(std::memory_order_seq_cst);
  if ((epoch & 1u) == 0u) return;
  while (poseEpoch_.load(std::memory_order_acquire) == epoch && !poseStop_.load(std::memory_order_relaxed)) {
    std::this_thread::sleep_for(std::chrono::microseconds(50));
  }
}

void HapticDetector::levelWorker() {
  lowerThisThreadPriority(10);
  for (;;) {
    double distance;
    {
      std::unique_lock<std::mutex> lock(workerMutex_);
      workerCv_.wait(lock, [this] { return stop_ || pending_; });
      if (stop_) return;
      distance = pendingDistance_;
      pending_ = false;
    }
    const auto current = currentLevel();
    if (current && current->distance == distance) continue;
    try {
      std::shared_ptr<const Level> level = makeLevel(distance);
      std::shared_ptr<const Level> old;
      {
        std::lock_guard<std::mutex> lock(levelMutex_);
        old = std::move(level_);
        level_ = level;
      }
      poseLevel_.store(level.get(), std::memory_order_seq_cst);
      waitUntilThePoseThreadLetsGo();
      swaps_.fetch_add(1, std::memory_order_relaxed);
      spheresDirty_ = true;
      ROS_INFO("detector: level d = %g with %u spheres in use (%s, %.1f ms)", level->distance, level->spheres,
               level->source.c_str(), level->readyMs);
      statusDirty_ = true;  // published by the display thread: a publish holds roscpp's process-wide lock
      // The old level (megabytes of small arrays) is freed here, off the haptic path, unless the display
      // thread still draws it (then there, when it lets go).
      old.reset();
    } catch (const std::exception& e) {
      ROS_ERROR("detector: could not prepare level d = %g: %s; keeping the current level", distance, e.what());
    }
  }
}

std::shared_ptr<const ClodSphereSet> HapticDetector::fetchFromService(double distance, std::string& why) {
  ros::ServiceClient client = nh_.serviceClient<GetSphereSet>(serviceName_);
  if (!client.waitForExistence(ros::Duration(serviceTimeout_))) {
    why = "service " + client.getService() + " not available";
    return nullptr;
  }
  GetSphereSet srv;
  srv.request.distance = distance;
  if (!client.call(srv)) {
    why = "call to " + client.getService() + " failed";
    return nullptr;
  }
  if (!srv.response.success) {
    why = "sphere_builder refused: " + srv.response.message;
    return nullptr;
  }
  auto set = std::make_shared<ClodSphereSet>(fromMsg(srv.response.sphere_set));
  const std::string mismatch = fitProblem(*mesh_, *set);
  if (!mismatch.empty()) {
    why = "the served set does not fit this detector's mesh: " + mismatch;
    return nullptr;
  }
  return set;
}

std::shared_ptr<const HapticDetector::Level> HapticDetector::makeLevel(double distance) {
  const auto start = std::chrono::steady_clock::now();
  auto level = std::make_shared<Level>();
  std::shared_ptr<const ClodSphereSet> set;
  if (useService_) {
    std::string why;
    set = fetchFromService(distance, why);
    if (set) {
      level->source = "service";
    } else {
      ROS_WARN("detector: %s; building level d = %g locally", why.c_str(), distance);
    }
  }
  if (!set) {
    if (!localBuilder_) localBuilder_ = std::make_unique<ClodBuilder>(mesh_, std::make_shared<PaperPlacement>(), clustering_);
    set = std::make_shared<const ClodSphereSet>(localBuilder_->build(distance));
    level->source = "local";
  }
  level->detector = std::make_shared<const ClodDetector>(mesh_, set, fastLevel_, gridRadius_);
  level->distance = distance;
  level->spheres = static_cast<std::uint32_t>(set->size());
  level->readyMs = msSince(start);
  return level;
}

// ------------------------------------------------------------------------------------------------
// Display and status (display thread).

void HapticDetector::onStatusTimer(const ros::SteadyTimerEvent&) {
  // Loss is never silent: warn (at most every 5 s) whenever a counter grew.
  const std::uint64_t skipped = skippedStale_.load(), lost = lostUpstream_.load();
  if (lost > warnedLost_) {
    ROS_WARN_THROTTLE(5.0, "detector: %lu poses lost before reaching the detector (gaps in the pose stream's "
                      "header.seq; %lu in all): a publisher or roscpp queue dropped them",
                      static_cast<unsigned long>(lost - warnedLost_), static_cast<unsigned long>(lost));
    warnedLost_ = lost;
  }
  if (skipped > warnedSkipped_) {
    ROS_WARN_THROTTLE(5.0, "detector: skipped %lu stale poses (pose_policy latest: a newer pose was waiting; %lu "
                      "in all): the detector falls behind the stream",
                      static_cast<unsigned long>(skipped - warnedSkipped_), static_cast<unsigned long>(skipped));
    warnedSkipped_ = skipped;
  }
  publishStatus();
}

void HapticDetector::publishStatus() {
  auto status = boost::make_shared<DetectorStatus>();
  status->header.stamp = ros::Time::now();
  status->header.frame_id = meshFrame_;
  {
    std::lock_guard<std::mutex> lock(statusMutex_);  // the worker publishes on a swap, the display thread each second
    status->sequence = ++statusSequence_;
  }
  status->poses_received = received_.load();
  status->contacts_published = published_.load();
  status->dropped_non_finite = droppedNonFinite_.load();
  status->dropped_unknown_frame = droppedFrame_.load();
  status->poses_lost_upstream = lostUpstream_.load();
  status->poses_skipped_stale = skippedStale_.load();
  status->pose_policy = toString(posePolicy_);
  status->pose_queue_size = static_cast<std::uint32_t>(poseQueueSize_);
  status->publish_queue_size = static_cast<std::uint32_t>(publishQueueSize_);
  status->pose_path_p50_us = posePath_.percentileUs(50.0);
  status->pose_path_p99_us = posePath_.percentileUs(99.0);
  status->pose_path_p999_us = posePath_.percentileUs(99.9);
  status->pose_path_max_us = posePath_.maxUs();
  status->pose_path_period_max_us = posePath_.takePeriodMaxUs();
  status->answered_without_level = bruteForce_.load();
  status->level_swaps = swaps_.load();
  status->requested_distance = requestedDistance_.load();
  const auto level = currentLevel();
  status->clustering_distance = level ? level->distance : std::numeric_limits<double>::quiet_NaN();
  status->level_spheres = level ? level->spheres : 0;
  status->level_source = level ? level->source : "";
  status->level_ready_ms = level ? level->readyMs : 0.0;
  statusPub_.publish(status);
}

void HapticDetector::onDisplayTimer(const ros::SteadyTimerEvent&) {
  if (statusDirty_.exchange(false)) publishStatus();  // a new level: say so now, not at the next second
  const bool wanted = markerPub_.getNumSubscribers() > 0;
  markersWanted_.store(wanted, std::memory_order_relaxed);
  if (!wanted) return;
  publishMarkers();
}

void HapticDetector::publishMarkers() {
  LastQuery last;
  {
    std::lock_guard<std::mutex> lock(lastMutex_);
    last = last_;
  }
  const auto level = currentLevel();
  auto array = boost::make_shared<visualization_msgs::MarkerArray>();
  std_msgs::Header header;
  header.frame_id = meshFrame_;
  header.stamp = ros::Time(0);

  if (meshDirty_.exchange(false)) {
    shownMesh_ = showMesh_;
    if (shownMesh_) {
      array->markers.push_back(meshMarker(*mesh_, header, makeColor(0.75f, 0.75f, 0.78f, 1.0f)));
    } else {
      array->markers.push_back(deleteMarker(marker_ns::kMesh, 0, header));
    }
  }
  const std::uint64_t levelId = level ? level->detector->id() : 0;
  if (spheresDirty_.exchange(false) || levelId != shownLevelId_) {
    shownSpheresOn_ = showSpheres_;
    if (level && shownSpheresOn_) {
      shownSpheres_ = appendSphereMarkers(*level->detector->spheres(), nullptr, marker_ns::kSpheres, header,
                                          makeColor(0.2f, 0.45f, 1.0f, 0.18f), shownSpheres_, *array);
    } else {
      static const ClodSphereSet empty;
      shownSpheres_ =
          appendSphereMarkers(empty, nullptr, marker_ns::kSpheres, header, makeColor(0, 0, 0, 0), shownSpheres_, *array);
    }
    shownLevelId_ = levelId;
  }

  if (last.valid) {
    hitBuffer_.clear();
    if (level && showHit_) level->detector->hitSpheres(last.pointer, last.radius, hitBuffer_);
    const ClodSphereSet* set = level ? level->detector->spheres().get() : nullptr;
    static const ClodSphereSet empty;
    shownHit_ = appendSphereMarkers(set ? *set : empty, &hitBuffer_, marker_ns::kHitSpheres, header,
                                    makeColor(1.0f, 0.55f, 0.0f, 0.55f), shownHit_, *array);

    ContactResult shown = last.result;
    if (!showContact_) shown.contact = false;
    appendContactMarkers(shown, std::max(8.0 * last.radius, 0.01), header, *array);
    if (showPointer_) {
      array->markers.push_back(
          pointerMarker(last.pointer, last.radius, header,
                        last.result.contact ? makeColor(1.0f, 0.2f, 0.2f, 0.9f) : makeColor(0.1f, 0.9f, 0.2f, 0.9f)));
    } else {
      array->markers.push_back(deleteMarker(marker_ns::kPointer, 0, header));
    }
  }
  if (!array->markers.empty()) markerPub_.publish(array);
}

}  // namespace clod_haptics
