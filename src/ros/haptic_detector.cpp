// HapticDetector: parameters, start-up and the haptic path (the pose thread).
#include "clod_haptics/ros/haptic_detector.h"

#include <geometry_msgs/WrenchStamped.h>
#include <pthread.h>
#include <sched.h>
#include <tf2/exceptions.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>

#include "clod_haptics/Contact.h"
#include "clod_haptics/ContactArray.h"
#include "clod_haptics/DetectorStatus.h"
#include "clod_haptics/core/clustering.h"
#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/mesh_cache.h"
#include "clod_haptics/core/sphere_cache.h"
#include "clod_haptics/ros/conversions.h"
#include "clod_haptics/ros/mesh_resource.h"

namespace clod_haptics {

namespace {

/** The transform target <- source at stamp, or the latest one when stamp is newer than tf2 knows. */
geometry_msgs::TransformStamped lookup(const tf2_ros::Buffer& buffer, const std::string& target,
                                       const std::string& source, const ros::Time& stamp) {
  try {
    return buffer.lookupTransform(target, source, stamp);
  } catch (const tf2::ExtrapolationException&) {
    return buffer.lookupTransform(target, source, ros::Time(0));
  }
}

}  // namespace

HapticDetector::HapticDetector(ros::NodeHandle nh, ros::NodeHandle pnh) : nh_(nh), pnh_(pnh), displayPnh_(pnh) {
  displayPnh_.setCallbackQueue(&displayQueue_);
  readParameters();
  loadObjects();
  advertise();
  startThreads();
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
  DetectorParameters& p = params_;
  XmlRpc::XmlRpcValue scene;
  const bool haveScene = pnh_.getParam("scene", scene);
  const bool haveMesh = pnh_.getParam("mesh", p.mesh) && !p.mesh.empty();
  if (!haveScene && !haveMesh) {
    throw MeshLoadError("", "required parameter " + pnh_.resolveName("mesh") + " (a mesh path or package:// URI) or " +
                                pnh_.resolveName("scene") +
                                " (a scene file: <rosparam file=\"scene.yaml\" ns=\"scene\"/>) is not set");
  }
  pnh_.param("frame_id", p.frameId, p.frameId);
  pnh_.param("scale", p.scale, p.scale);
  pnh_.param("normalize", p.normalize, p.normalize);
  pnh_.param("pose_topic", p.poseTopic, p.poseTopic);
  pnh_.param("sphere_service", p.sphereService, p.sphereService);
  pnh_.param("use_service", p.useService, haveMesh && !haveScene);
  pnh_.param("service_timeout", p.serviceTimeout, p.serviceTimeout);
  pnh_.param("use_cache", p.useCache, p.useCache);
  pnh_.param("cache_dir", p.cacheDir, p.cacheDir);
  pnh_.param("cache_meshes", p.cacheMeshes, p.cacheMeshes);
  pnh_.param("clustering", p.clustering, p.clustering);
  pnh_.param("grid_radius", p.gridRadius, p.gridRadius);
  pnh_.param("pose_queue_size", p.poseQueueSize, p.poseQueueSize);
  pnh_.param("publish_queue_size", p.publishQueueSize, p.publishQueueSize);
  pnh_.param("realtime_priority", p.realtimePriority, p.realtimePriority);
  pnh_.param("marker_rate", p.markerRate, p.markerRate);
  pnh_.param("static_retry", p.staticRetry, p.staticRetry);
  pnh_.param("prefetch_margin", p.prefetchMargin, p.prefetchMargin);
  pnh_.param("quick_start", p.quickStart, p.quickStart);
  pnh_.param("grid_on_demand", p.gridOnDemand, p.gridOnDemand);
  pnh_.param("detectors_on_demand", p.detectorsOnDemand, p.detectorsOnDemand);
  std::string policy = toString(p.posePolicy), fast = "grid";
  pnh_.param("pose_policy", policy, policy);
  pnh_.param("fast_level", fast, fast);

  if (policy == "all" || policy == "latest") {
    p.posePolicy = policy == "all" ? PosePolicy::All : PosePolicy::Latest;
  } else {
    throw InvalidParameter(
        "~pose_policy must be all (answer every pose) or latest (skip a pose a newer one waits "
        "behind), not '" +
        policy + "'");
  }
  if (!parseFastLevel(fast.c_str(), p.fastLevel)) {
    throw InvalidParameter("~fast_level must be grid, hierarchy or flat, not '" + fast + "'");
  }
  if (!std::isfinite(p.scale) || p.scale <= 0.0) throw InvalidParameter("~scale must be finite and positive");
  if (p.realtimePriority < 0 || p.realtimePriority > 99) throw InvalidParameter("~realtime_priority must be in 0..99");
  if (!(p.markerRate > 0.0) || p.markerRate > 200.0) throw InvalidParameter("~marker_rate must be in (0, 200] Hz");
  if (!(p.staticRetry > 0.0)) throw InvalidParameter("~static_retry must be positive");
  if (p.poseQueueSize < 1) throw InvalidParameter("~pose_queue_size must be at least 1");
  if (p.publishQueueSize < 1) throw InvalidParameter("~publish_queue_size must be at least 1");
  requireNonNegative(p.gridRadius, "~grid_radius");
  requireNonNegative(p.prefetchMargin, "~prefetch_margin");
  requireClustering(p.clustering, pnh_.resolveName("clustering"));
  std::string mode;
  DetectionMode parsed;
  if (pnh_.getParam("detection_mode", mode) && !parseDetectionMode(mode.c_str(), parsed)) {
    throw InvalidParameter("~detection_mode must be exact, paper or spheres, not '" + mode + "'");
  }

  if (haveScene) {
    double defaultDistance = DetectorConfig::__getDefault__().clustering_distance;
    pnh_.param("default_distance", defaultDistance, defaultDistance);
    config_ = parseSceneConfig(scene, defaultDistance);
    return;
  }
  singleMesh_ = true;  // a scene of one: the mesh in ~frame_id at the distance dynamic_reconfigure asks for
  SceneObjectConfig object;
  object.name = p.mesh.substr(p.mesh.find_last_of('/') + 1);
  object.mesh = p.mesh;
  object.frameId = p.frameId;
  object.scale = p.scale;
  pnh_.param("clustering_distance", object.distance, DetectorConfig::__getDefault__().clustering_distance);
  config_.frameId = p.frameId;
  config_.objects.push_back(object);
}

void HapticDetector::loadObjects() {
  const DetectorParameters& p = params_;
  std::shared_ptr<SphereSetCache> cache;
  if (p.useCache) {
    cache = std::make_shared<SphereSetCache>(sphereCacheDirectoryFor(p.cacheDir, p.clustering));
  }
  // Grids serve the pointer radius (and follow it when it is reconfigured) unless ~grid_radius says otherwise.
  double gridRadius = p.gridRadius;
  gridFollowsPointer_ = gridRadius == 0.0;
  if (gridFollowsPointer_) pnh_.param("pointer_radius", gridRadius, radius_.load());
  if (!(gridRadius > 0.0) || !std::isfinite(gridRadius)) gridRadius = 0.0;  // 1% of the model, as the core does
  gridTarget_ = gridRadius;
  assets_ = std::make_unique<SceneAssets>(cache, p.fastLevel, gridRadius, true, makeClustering(p.clustering));
  if (p.useCache && p.cacheMeshes) assets_->setMeshCache(std::make_shared<MeshCache>(p.cacheDir));
  if (p.useService) {
    assets_->setRemote(
        [this](const TriangleMesh& mesh, double d, std::string& why) { return fetchFromService(mesh, d, why); });
  }
  const auto start = std::chrono::steady_clock::now();
  std::size_t triangles = 0;
  std::vector<DisplayObject, Eigen::aligned_allocator<DisplayObject>> drawn;
  std::vector<std::string> only;
  pnh_.getParam("marker_objects", only);
  for (const SceneObjectConfig& object : config_.objects) {
    ObjectState state;
    state.config = object;
    state.meshPath = resolveMeshPath(object.mesh);
    MeshLoadOptions options;
    options.scale = object.scale;
    options.normalize = singleMesh_ && p.normalize;
    SceneAssets::MeshInfo info;
    auto mesh = assets_->mesh(state.meshPath, options, &info);  // shared when several objects use one file
    if (!info.cache.problem.empty()) ROS_WARN("detector: '%s': %s", object.name.c_str(), info.cache.problem.c_str());
    triangles += mesh->size();
    state.viaTf = object.frameId != config_.frameId;
    state.poseKnown = !state.viaTf;
    const auto index = scene_.addObject(object.name, mesh, nullptr, object.offset);
    scene_.setActive(index, state.poseKnown);
    firstSweeps_.push_back(std::make_shared<const SweptSphereQuery>(mesh));  // its own tree until a level comes
    sweptScene_.add(firstSweeps_.back(), object.offset);
    sweptScene_.setActive(index, state.poseKnown);
    objects_.push_back(state);

    DisplayObject d;
    d.name = object.name;
    d.frameId = object.frameId;
    d.offset = object.offset;
    d.meshResource = object.mesh.rfind("package://", 0) == 0 ? object.mesh : "file://" + state.meshPath;
    d.scale = object.scale;
    d.mesh = mesh;
    d.drawn = only.empty() || std::find(only.begin(), only.end(), object.name) != only.end();
    drawn.push_back(d);
  }
  const std::size_t n = objects_.size();
  contacts_.resize(n);
  caches_.resize(n);
  startContacts_.resize(n);
  startCaches_.resize(n);
  last_.contacts.reserve(n);
  last_.near.resize(n);
  last_.poses.resize(n);
  wanted_ = std::make_unique<std::atomic<bool>[]>(n);
  for (std::size_t i = 0; i < n; ++i) wanted_[i] = false;
  display_ = std::make_unique<DetectorDisplay>(config_.frameId, std::move(drawn), singleMesh_);
  ROS_INFO(
      "detector: %zu object%s (%zu triangles) loaded in %.0f ms in frame '%s'; poses from %s; levels from %s%s"
      "a local build",
      n, n == 1 ? "" : "s", triangles,
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count(),
      config_.frameId.c_str(), nh_.resolveName(p.poseTopic).c_str(),
      cache ? ("the cache " + cache->directory() + ", ").c_str() : "",
      p.useService ? ("the service " + nh_.resolveName(p.sphereService) + ", ").c_str() : "");
}

void HapticDetector::advertise() {
  const auto queue = static_cast<std::uint32_t>(params_.publishQueueSize);
  contactPub_ = pnh_.advertise<Contact>("contact", queue);
  contactsPub_ = pnh_.advertise<ContactArray>("contacts", queue);
  forcePub_ = pnh_.advertise<geometry_msgs::WrenchStamped>("force", queue);
  proxyPub_ = pnh_.advertise<geometry_msgs::PoseStamped>("proxy", queue);
  statusPub_ = pnh_.advertise<DetectorStatus>("status", 1, true);
  // A new marker subscriber gets the meshes and levels once; afterwards only what changes.
  markerPub_ = displayPnh_.advertise<visualization_msgs::MarkerArray>(
      "markers", 10,
      [this](const ros::SingleSubscriberPublisher&) { display_->invalidate(); },  // on the display thread
      ros::SubscriberStatusCallback());
  tfListener_ = std::make_unique<tf2_ros::TransformListener>(tfBuffer_, nh_);
}

void HapticDetector::startThreads() {
  worker_ = std::thread(&HapticDetector::levelWorker, this);
  // Calls onReconfigure with the ~ parameters (config/detector.yaml), which sets the first distance.
  reconfigure_ = std::make_unique<dynamic_reconfigure::Server<DetectorConfig>>(configMutex_, displayPnh_);
  reconfigure_->setCallback([this](DetectorConfig& config, std::uint32_t level) { onReconfigure(config, level); });

  poseNh_ = nh_;
  poseNh_.setCallbackQueue(&poseQueue_);
  poseSub_ = poseNh_.subscribe(params_.poseTopic, static_cast<std::uint32_t>(params_.poseQueueSize),
                               &HapticDetector::onPose, this, ros::TransportHints().tcpNoDelay());
  poseThread_ = std::thread(&HapticDetector::poseLoop, this);
  ROS_INFO("detector: pose policy '%s', pose queue %d, publish queue %d", toString(params_.posePolicy),
           params_.poseQueueSize, params_.publishQueueSize);
  displayTimer_ =
      displayPnh_.createSteadyTimer(ros::WallDuration(1.0 / params_.markerRate), &HapticDetector::onDisplayTimer, this);
  statusTimer_ = displayPnh_.createSteadyTimer(ros::WallDuration(1.0), &HapticDetector::onStatusTimer, this);
  displaySpinner_ = std::make_unique<ros::AsyncSpinner>(1, &displayQueue_);
  displaySpinner_->start();
  publishStatus();
}

// ------------------------------------------------------------------------------------------------
// The haptic path: the pose thread alone touches the scene.

void HapticDetector::poseLoop() {
  const int priority = params_.realtimePriority;
  if (priority > 0) {
    sched_param param{};
    param.sched_priority = priority;
    const int err = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param);
    if (err != 0) {
      // Not a warning: most desktops allow no real-time priority, and the detector works without it.
      ROS_INFO(
          "detector: ~realtime_priority %d not granted (%s): the pose thread stays on the default "
          "scheduler; allow it with 'ulimit -r %d' or an rtprio line in /etc/security/limits.conf",
          priority, std::strerror(err), priority);
    } else {
      ROS_INFO("detector: pose thread at SCHED_FIFO priority %d", priority);
    }
  }
  while (!poseStop_.load(std::memory_order_relaxed)) {
    adoptPublishedLevels();  // also when no pose comes: a new level is in use within 50 ms
    if (params_.posePolicy == PosePolicy::All) {
      poseQueue_.callOne(ros::WallDuration(0.05));  // every pose, in order
      continue;
    }
    // Latest: take every pose that arrived while the last one was answered (onPose keeps the newest, counting
    // the others as skipped), then answer that one.
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
  if (haveSeq_ && publisher == lastPublisher_) {
    const std::uint32_t step = seq - lastSeq_;  // modulo 2^32: a wrapped counter still steps by 1
    // A step back (a restarted publisher, a replay looping) starts counting again; a step forward by k > 1
    // means k - 1 poses were published that never reached this callback.
    if (step > 1u && step < (1u << 31)) lostUpstream_.fetch_add(step - 1u, std::memory_order_relaxed);
  } else {
    lastPublisher_ = publisher;  // allocates only when the publisher changes
  }
  lastSeq_ = seq;
  haveSeq_ = true;
}

void HapticDetector::onPose(const ros::MessageEvent<const geometry_msgs::PoseStamped>& event) {
  received_.fetch_add(1, std::memory_order_relaxed);
  countSequence(event);
  if (params_.posePolicy == PosePolicy::All) {
    answer(event);
    return;
  }
  // Latest: poseLoop answers the newest pose of each batch; one it replaces here is never answered.
  if (newestValid_) skippedStale_.fetch_add(1, std::memory_order_relaxed);
  newestPose_ = event;
  newestValid_ = true;
}

bool HapticDetector::pointerInSceneFrame(const geometry_msgs::PoseStamped& msg, Vec3& p,
                                         Eigen::Isometry3d& sceneFromPose) {
  if (!isFinite(msg.pose)) {
    droppedNonFinite_.fetch_add(1, std::memory_order_relaxed);
    ROS_WARN_THROTTLE(1.0, "detector: dropped a pose with a NaN or Inf component (%lu so far)",
                      static_cast<unsigned long>(droppedNonFinite_.load()));
    return false;
  }
  p = Vec3(msg.pose.position.x, msg.pose.position.y, msg.pose.position.z);
  sceneFromPose.setIdentity();
  const std::string& frame = msg.header.frame_id;
  if (frame.empty() || frame == config_.frameId) return true;
  try {
    sceneFromPose = toIsometry(lookup(tfBuffer_, config_.frameId, frame, msg.header.stamp).transform);
  } catch (const tf2::TransformException& e) {
    droppedFrame_.fetch_add(1, std::memory_order_relaxed);
    ROS_WARN_THROTTLE(1.0, "detector: dropped a pose in frame '%s': %s (%lu so far)", frame.c_str(), e.what(),
                      static_cast<unsigned long>(droppedFrame_.load()));
    return false;
  }
  p = sceneFromPose * p;
  // A huge but finite pose (1e308) can overflow to Inf when transformed: not a position either.
  if (p.allFinite()) return true;
  droppedNonFinite_.fetch_add(1, std::memory_order_relaxed);
  ROS_WARN_THROTTLE(1.0, "detector: dropped a pose in frame '%s' that is not finite in frame '%s' (%lu so far)",
                    frame.c_str(), config_.frameId.c_str(), static_cast<unsigned long>(droppedNonFinite_.load()));
  return false;
}

void HapticDetector::updateObjectPoses(const ros::Time& stamp) {
  for (std::uint32_t i = 0; i < objects_.size(); ++i) {
    ObjectState& o = objects_[i];
    if (!o.viaTf || (o.poseKnown && !o.config.moving)) continue;
    const ros::WallTime now = ros::WallTime::now();
    if (!o.config.moving && now < o.nextRetry) continue;  // a static frame tf2 did not know: retried now and then
    try {
      const auto tf = lookup(tfBuffer_, config_.frameId, o.config.frameId, o.config.moving ? stamp : ros::Time(0));
      const Eigen::Isometry3d pose = toIsometry(tf.transform) * o.config.offset;
      scene_.setPose(i, pose);
      scene_.setActive(i, true);
      sweptScene_.setPose(i, pose);
      sweptScene_.setActive(i, true);
      if (!o.poseKnown && !o.config.moving) {
        ROS_INFO("detector: '%s' placed in static frame '%s'", o.config.name.c_str(), o.config.frameId.c_str());
      }
      o.poseKnown = true;
    } catch (const std::exception& e) {  // tf2 errors, or a non-rigid transform
      scene_.setActive(i, false);
      sweptScene_.setActive(i, false);
      o.poseKnown = false;
      o.nextRetry = now + ros::WallDuration(params_.staticRetry);
      ROS_WARN_THROTTLE(2.0, "detector: '%s' skipped: %s frame '%s': %s", o.config.name.c_str(),
                        o.config.moving ? "moving" : "static", o.config.frameId.c_str(), e.what());
    }
  }
}

void HapticDetector::adoptPublishedLevels() {
  const Levels* levels = published_.load(std::memory_order_acquire);
  if (!levels || levels->id == adoptedId_) return;
  for (std::uint32_t i = 0; i < levels->detectors.size(); ++i) {
    // Never the last reference: the snapshot that held the replaced level is freed by the display thread.
    if (scene_.detector(i) != levels->detectors[i]) scene_.setDetector(i, levels->detectors[i]);
    if (levels->sweeps[i] && sweptScene_.query(i) != levels->sweeps[i]) sweptScene_.setQuery(i, levels->sweeps[i]);
  }
  adoptedId_ = levels->id;
  adopted_.store(adoptedId_, std::memory_order_release);
}

bool HapticDetector::isFinal(const ClodDetector& level) const {
  if (level.fastLevel() != params_.fastLevel) return false;  // the quick hierarchy of ~quick_start
  // A grid built for another pointer radius is replaced when the pointer comes near (grid_on_demand).
  return !gridFollowsPointer_ || params_.fastLevel != FastLevel::Grid || gridTarget_.load() == 0.0 ||
         level.gridRadius() == gridTarget_.load(std::memory_order_relaxed);
}

void HapticDetector::askForNearLevels(const Vec3& p) {
  const double reachOut = radius_.load(std::memory_order_relaxed) + params_.prefetchMargin;
  for (std::uint32_t i = 0; i < scene_.size(); ++i) {
    const auto& level = scene_.detector(i);
    if ((level && isFinal(*level)) || wanted_[i].load(std::memory_order_relaxed)) continue;
    const double reach = scene_.boundRadius(i) + reachOut;
    if ((scene_.boundCentre(i) - p).squaredNorm() <= reach * reach) {
      wanted_[i].store(true, std::memory_order_relaxed);
      workerCv_.notify_one();
    }
  }
}

void HapticDetector::answer(const ros::MessageEvent<const geometry_msgs::PoseStamped>& event) {
  const geometry_msgs::PoseStamped& msg = *event.getConstMessage();
  Vec3 p;
  Eigen::Isometry3d sceneFromPose;
  if (!pointerInSceneFrame(msg, p, sceneFromPose)) return;
  updateObjectPoses(msg.header.stamp);
  adoptPublishedLevels();
  askForNearLevels(p);

  const double radius = radius_.load(std::memory_order_relaxed);
  const auto mode = static_cast<DetectionMode>(mode_.load(std::memory_order_relaxed));
  SceneQueryResult out;
  const auto start = std::chrono::steady_clock::now();
  scene_.query(p, radius, mode, contacts_.data(), contacts_.size(), out, caches_);
  const auto elapsed = std::chrono::steady_clock::now() - start;
  if (out.bruteForce > 0) bruteForce_.fetch_add(1, std::memory_order_relaxed);
  ProxyTick tick;
  const bool proxy = renderProxy(msg, p, radius, out.contact, tick);
  const Vec3 force = publishAnswer(msg, p, radius, sceneFromPose, out,
                                   std::chrono::duration_cast<std::chrono::nanoseconds>(elapsed).count(),
                                   proxy ? &tick : nullptr);
  if (!ros::Time::isSimTime()) posePath_.record((ros::Time::now() - event.getReceiptTime()).toNSec());
  if (markersWanted_.load(std::memory_order_relaxed))
    keepForDisplay(p, radius, out.contacts, proxy ? &tick : nullptr, force);
}

bool HapticDetector::outsideEverything(const Vec3& p, double radius) {
  // A cache that says "the last answer was inside" makes the exact query search for the nearest triangle beyond
  // the radius (ClodDetector::query): a centre behind it is inside. Only while the proxy waits to start.
  for (QueryCache& c : startCaches_) {
    c = QueryCache();
    c.lastInside = true;
  }
  SceneQueryResult deep;
  scene_.query(p, radius, DetectionMode::Exact, startContacts_.data(), startContacts_.size(), deep,
               startCaches_.data());
  return !deep.contact;
}

bool HapticDetector::renderProxy(const geometry_msgs::PoseStamped& msg, const Vec3& p, double radius, bool touching,
                                 ProxyTick& tick) {
  // The proxy starts (again after a switch to it, a new radius, or a stamp going back: a replay restarted) at a
  // pointer that touches nothing and is not deep inside an object, so that it never starts inside one; until then
  // the penalty force answers.
  const ros::Time& stamp = msg.header.stamp;
  if (proxyActive_ && (radius != proxyRadius_ || stamp < lastStamp_)) proxyActive_ = false;
  if (!proxyModel_.load(std::memory_order_relaxed) || (!proxyActive_ && (touching || !outsideEverything(p, radius)))) {
    proxyActive_ = false;
    return false;
  }
  ProxyParameters params;
  params.radius = radius;
  params.stiffness = stiffness_.load(std::memory_order_relaxed);
  params.maxForce = maxForce_.load(std::memory_order_relaxed);
  params.damping = damping_.load(std::memory_order_relaxed);
  params.muStatic = muStatic_.load(std::memory_order_relaxed);
  params.muDynamic = muDynamic_.load(std::memory_order_relaxed);
  params.forceShading = forceShading_.load(std::memory_order_relaxed);
  renderer_.setParameters(params);
  if (!proxyActive_) renderer_.reset(p);
  const double dt = proxyActive_ && stamp > lastStamp_ ? (stamp - lastStamp_).toSec() : 1e-3;
  lastStamp_ = stamp;
  proxyRadius_ = radius;
  proxyActive_ = true;
  renderer_.update(sweptScene_, p, dt, tick);
  return true;
}

Vec3 HapticDetector::publishAnswer(const geometry_msgs::PoseStamped& msg, const Vec3& p, double radius,
                                   const Eigen::Isometry3d& sceneFromPose, const SceneQueryResult& out,
                                   std::int64_t detectionNs, const ProxyTick* proxy) {
  std_msgs::Header header;
  header.stamp = msg.header.stamp;
  header.frame_id = config_.frameId;
  // Consecutive numbers: a subscriber that sees a gap knows an answer was lost on the way to it.
  header.seq = static_cast<std::uint32_t>(answered_.load(std::memory_order_relaxed) + 1);
  ros::Duration detectionTime;
  detectionTime.fromNSec(detectionNs);

  auto array = boost::make_shared<ContactArray>();
  array->header = header;
  array->pointer = toPoint(p);
  array->pointer_radius = radius;
  array->in_contact = out.contact;
  array->contacts.resize(out.contacts);
  array->objects.resize(out.contacts);
  array->object_indices.resize(out.contacts);
  for (std::uint32_t k = 0; k < out.contacts; ++k) {
    const SceneContact& c = contacts_[k];
    Contact& m = array->contacts[k];
    m.header = header;
    toMsg(c.local, p, radius, m);
    m.point = toPoint(c.point);  // scene frame
    m.normal = toVector3(c.normal);
    m.detection_time = detectionTime;
    if (proxy) m.proxy = toPoint(proxy->proxy);
    m.proxy_active = proxy != nullptr;
    const auto& level = scene_.detector(c.object);
    m.clustering_distance = level ? level->spheres()->distance : std::numeric_limits<double>::quiet_NaN();
    m.level_spheres = level ? static_cast<std::uint32_t>(level->spheres()->size()) : 0;
    array->objects[k] = objects_[c.object].config.name;
    array->object_indices[k] = c.object;
  }
  const Vec3 force = proxy ? proxy->force
                           : penaltyForce(out.penetration, stiffness_.load(std::memory_order_relaxed),
                                          maxForce_.load(std::memory_order_relaxed));
  array->penetration = toVector3(out.penetration);
  array->max_depth = out.maxDepth;
  array->deepest = out.deepest;
  array->force = toVector3(force);
  array->objects_queried = out.objectsQueried;
  array->objects_rejected = out.objectsRejected;
  array->objects_without_pose = out.objectsInactive;
  array->objects_brute_force = out.bruteForce;
  array->detection_time = detectionTime;

  // ~contact: the deepest contact; without one, the pointer and the level of the first object.
  auto contact = boost::make_shared<Contact>();
  if (out.deepest >= 0) {
    *contact = array->contacts[static_cast<std::size_t>(out.deepest)];
  } else {
    toMsg(ContactResult(), p, radius, *contact);
    contact->header = header;
    contact->detection_time = detectionTime;
    const auto& level = scene_.detector(0);
    contact->clustering_distance = level ? level->spheres()->distance : std::numeric_limits<double>::quiet_NaN();
    contact->level_spheres = level ? static_cast<std::uint32_t>(level->spheres()->size()) : 0;
    if (proxy) contact->proxy = toPoint(proxy->proxy);
    contact->proxy_active = proxy != nullptr;
  }

  // The force in the pose's frame, where the device renders it.
  auto wrench = boost::make_shared<geometry_msgs::WrenchStamped>();
  wrench->header = header;
  if (!msg.header.frame_id.empty()) wrench->header.frame_id = msg.header.frame_id;
  toMsg(Vec3(sceneFromPose.linear().transpose() * force), wrench->wrench);

  if (proxy && proxyPub_.getNumSubscribers() > 0) publishProxyPose(msg, header, sceneFromPose, proxy->proxy);
  contactPub_.publish(contact);
  contactsPub_.publish(array);
  forcePub_.publish(wrench);
  answered_.fetch_add(1, std::memory_order_relaxed);
  return force;
}

void HapticDetector::publishProxyPose(const geometry_msgs::PoseStamped& msg, const std_msgs::Header& header,
                                      const Eigen::Isometry3d& sceneFromPose, const Vec3& proxy) {
  // At the proxy, with the stylus's orientation brought into the scene frame.
  auto pose = boost::make_shared<geometry_msgs::PoseStamped>();
  pose->header = header;
  const geometry_msgs::Quaternion& o = msg.pose.orientation;
  const Eigen::Quaterniond q(o.w, o.x, o.y, o.z);
  Eigen::Isometry3d stylus = Eigen::Isometry3d::Identity();
  if (q.norm() > 0.0) stylus.linear() = sceneFromPose.linear() * q.normalized().toRotationMatrix();
  stylus.translation() = proxy;
  pose->pose = toPose(stylus);
  proxyPub_.publish(pose);
}

void HapticDetector::keepForDisplay(const Vec3& p, double radius, std::uint32_t contacts, const ProxyTick* proxy,
                                    const Vec3& force) {
  // For the markers only: if the display thread is copying it right now, this pose is not drawn rather than
  // waiting for a thread of lower priority. Capacities were reserved at start-up: nothing allocates here.
  std::unique_lock<std::mutex> lock(lastMutex_, std::try_to_lock);
  if (!lock.owns_lock()) return;
  ++last_.seq;
  last_.pointer = p;
  last_.radius = radius;
  last_.force = force;
  last_.haveProxy = proxy != nullptr;
  if (proxy) last_.proxy = proxy->proxy;
  last_.contacts.assign(contacts_.begin(), contacts_.begin() + contacts);
  for (std::uint32_t i = 0; i < scene_.size(); ++i) {
    last_.poses[i] = scene_.pose(i);
    const double reach = scene_.boundRadius(i) + radius;
    last_.near[i] = scene_.active(i) && (scene_.boundCentre(i) - p).squaredNorm() <= reach * reach;
  }
}

}  // namespace clod_haptics
