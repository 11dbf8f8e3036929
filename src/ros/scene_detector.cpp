#include "clod_haptics/ros/scene_detector.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include <geometry_msgs/WrenchStamped.h>
#include <tf2/exceptions.h>
#include <visualization_msgs/MarkerArray.h>

#include "clod_haptics/ContactArray.h"
#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/ros/conversions.h"
#include "clod_haptics/ros/markers.h"
#include "clod_haptics/ros/mesh_resource.h"

namespace clod_haptics {

namespace {

Eigen::Isometry3d toIsometry(const geometry_msgs::Transform& t) {
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.translate(Vec3(t.translation.x, t.translation.y, t.translation.z));
  out.rotate(Eigen::Quaterniond(t.rotation.w, t.rotation.x, t.rotation.y, t.rotation.z).normalized());
  return out;
}

/** Moves sphere markers from mesh coordinates to the object's frame (the offset is rigid). */
void applyOffset(const Eigen::Isometry3d& offset, std::size_t first, visualization_msgs::MarkerArray& array) {
  for (std::size_t k = first; k < array.markers.size(); ++k) {
    auto& m = array.markers[k];
    if (m.action != visualization_msgs::Marker::ADD) continue;
    if (m.type == visualization_msgs::Marker::SPHERE_LIST) {
      // A list's points are in the object's frame: the marker's pose carries the offset, rotation included.
      const Eigen::Quaterniond q(offset.linear());
      m.pose.position = toPoint(offset.translation());
      m.pose.orientation.x = q.x();
      m.pose.orientation.y = q.y();
      m.pose.orientation.z = q.z();
      m.pose.orientation.w = q.w();
      continue;
    }
    m.pose.position = toPoint(offset * fromPoint(m.pose.position));
  }
}

}  // namespace

SceneHapticDetector::SceneHapticDetector(ros::NodeHandle nh, ros::NodeHandle pnh)
    : nh_(nh), pnh_(pnh), displayPnh_(pnh) {
  displayPnh_.setCallbackQueue(&displayQueue_);
  readParameters();

  assets_ = std::make_unique<SceneAssets>(std::make_shared<SphereSetCache>(cacheDir_), fastLevel_, radius_);
  if (cacheMeshes_) assets_->setMeshCache(std::make_shared<MeshCache>(cacheDir_));
  const auto start = std::chrono::steady_clock::now();
  std::size_t triangles = 0;
  for (const SceneObjectConfig& object : config_.objects) {
    ObjectState state;
    state.config = object;
    state.meshPath = resolveMeshPath(object.mesh);
    MeshLoadOptions options;
    options.scale = object.scale;
    SceneAssets::MeshInfo meshInfo;
    auto mesh = assets_->mesh(state.meshPath, options, &meshInfo);  // shared when several objects use the same file
    if (!meshInfo.cache.problem.empty()) {
      ROS_WARN("scene_detector: '%s': %s", object.name.c_str(), meshInfo.cache.problem.c_str());
    }
    triangles += mesh->size();
    state.viaTf = object.frameId != config_.frameId;
    state.poseKnown = !state.viaTf;
    const auto index = scene_.addObject(object.name, mesh, nullptr, object.offset);
    scene_.setActive(index, state.poseKnown);
    objects_.push_back(state);
  }
  std::vector<std::string> drawn;
  if (pnh_.getParam("marker_objects", drawn) && !drawn.empty()) {
    for (auto& o : objects_) o.drawn = std::find(drawn.begin(), drawn.end(), o.config.name) != drawn.end();
  }
  const std::size_t n = objects_.size();
  contacts_.resize(n);
  caches_.resize(n);
  ready_.resize(n);
  retired_.reserve(2 * n);
  wanted_ = std::make_unique<std::atomic<bool>[]>(n);
  for (std::size_t i = 0; i < n; ++i) wanted_[i] = false;
  shownLevels_.resize(n);
  shownSpheres_.assign(n, 0);
  shownHit_.assign(n, 0);
  shownContact_.assign(n, 0);
  ROS_INFO("scene_detector: %zu objects (%zu triangles) loaded in %.0f ms (%lu meshes from the mesh cache), scene "
           "frame '%s', cache %s",
           n, triangles, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count(),
           static_cast<unsigned long>(assets_->meshCache() ? assets_->meshCache()->hits() : 0), config_.frameId.c_str(),
           assets_->cache()->directory().c_str());

  contactsPub_ = pnh_.advertise<ContactArray>("contacts", 5000);  // 5 s at 1 kHz for a slow subscriber
  forcePub_ = pnh_.advertise<geometry_msgs::WrenchStamped>("force", 5000);
  // A new marker subscriber gets the meshes and levels once; afterwards only what changes.
  markerPub_ = displayPnh_.advertise<visualization_msgs::MarkerArray>(
      "markers", 10, [this](const ros::SingleSubscriberPublisher&) { staticDirty_ = true; },
      ros::SubscriberStatusCallback());
  tfListener_ = std::make_unique<tf2_ros::TransformListener>(tfBuffer_, nh_);

  worker_ = std::thread(&SceneHapticDetector::levelWorker, this);
  poseSub_ = nh_.subscribe(poseTopic_, static_cast<std::uint32_t>(poseQueueSize_), &SceneHapticDetector::onPose, this,
                           ros::TransportHints().tcpNoDelay());
  displayTimer_ = displayPnh_.createSteadyTimer(ros::WallDuration(1.0 / markerRate_),
                                                &SceneHapticDetector::onDisplayTimer, this);
  displaySpinner_ = std::make_unique<ros::AsyncSpinner>(1, &displayQueue_);
  displaySpinner_->start();
}

SceneHapticDetector::~SceneHapticDetector() {
  poseSub_.shutdown();
  displayTimer_.stop();
  if (displaySpinner_) displaySpinner_->stop();
  stop_ = true;
  if (worker_.joinable()) worker_.join();
}

void SceneHapticDetector::readParameters() {
  XmlRpc::XmlRpcValue scene;
  if (!pnh_.getParam("scene", scene)) {
    throw InvalidParameter("required parameter " + pnh_.resolveName("scene") +
                           " is not set (load a scene file: <rosparam file=\"scene.yaml\" ns=\"scene\"/>)");
  }
  double defaultDistance;
  pnh_.param("default_distance", defaultDistance, 0.003);
  config_ = parseSceneConfig(scene, defaultDistance);
  pnh_.param<std::string>("pose_topic", poseTopic_, "/phantom/pose");
  pnh_.param<std::string>("cache_dir", cacheDir_, "");
  pnh_.param("pointer_radius", radius_, 0.002);
  pnh_.param("stiffness", stiffness_, 500.0);
  pnh_.param("max_force", maxForce_, 0.0);
  pnh_.param("marker_rate", markerRate_, 30.0);
  pnh_.param("static_retry", staticRetry_, 0.5);
  pnh_.param("prefetch_margin", prefetchMargin_, 0.05);
  pnh_.param("quick_start", quickStart_, true);
  pnh_.param("cache_meshes", cacheMeshes_, true);
  pnh_.param("grid_on_demand", gridOnDemand_, true);
  pnh_.param("detectors_on_demand", detectorsOnDemand_, false);
  pnh_.param("pose_queue_size", poseQueueSize_, 5000);
  std::string mode, fast;
  pnh_.param<std::string>("detection_mode", mode, "exact");
  pnh_.param<std::string>("fast_level", fast, "grid");
  if (!parseDetectionMode(mode.c_str(), mode_)) {
    throw InvalidParameter("~detection_mode must be exact, paper or spheres, not '" + mode + "'");
  }
  if (!parseFastLevel(fast.c_str(), fastLevel_)) {
    throw InvalidParameter("~fast_level must be grid, hierarchy or flat, not '" + fast + "'");
  }
  if (!std::isfinite(radius_) || radius_ < 0.0) throw InvalidParameter("~pointer_radius must be finite and >= 0");
  if (!std::isfinite(stiffness_) || stiffness_ < 0.0) throw InvalidParameter("~stiffness must be finite and >= 0");
  if (!std::isfinite(maxForce_) || maxForce_ < 0.0) throw InvalidParameter("~max_force must be finite and >= 0");
  if (!(markerRate_ > 0.0) || markerRate_ > 200.0) throw InvalidParameter("~marker_rate must be in (0, 200] Hz");
  if (!(staticRetry_ > 0.0)) throw InvalidParameter("~static_retry must be positive");
  if (!std::isfinite(prefetchMargin_) || prefetchMargin_ < 0.0) {
    throw InvalidParameter("~prefetch_margin must be finite and >= 0");
  }
  if (poseQueueSize_ < 1) throw InvalidParameter("~pose_queue_size must be at least 1");
}

// ------------------------------------------------------------------------------------------------
// Levels: prepared by the worker (disk cache or build), swapped in by the pose thread.

void SceneHapticDetector::levelWorker() {
  // Per object, step by step: its sphere set (disk cache, or a build), a hierarchy detector (cheap to
  // construct: ~quick_start), then the configured fast level (grid: O(1) queries, slower to
  // construct). Objects the pointer comes near (wanted_) advance first; every object gets its set at
  // start-up; detectors of objects nobody approaches wait with ~detectors_on_demand, grids with
  // ~grid_on_demand. Until an object has a detector, the pose thread answers it by brute force.
  enum Step : std::uint8_t { kNone, kSet, kQuick, kFinal };
  const std::size_t n = objects_.size();
  const bool quick = quickStart_ && fastLevel_ != FastLevel::Hierarchy;
  std::vector<std::uint8_t> step(n, kNone);
  const auto start = std::chrono::steady_clock::now();
  auto elapsedMs = [&] {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  };
  auto name = [](FastLevel f) { return f == FastLevel::Grid ? "grid" : f == FastLevel::Hierarchy ? "hierarchy" : "flat"; };
  // May this object advance now without being asked for?
  auto eager = [&](std::size_t i) {
    if (step[i] == kNone) return true;  // sets for everyone: that is what the cache makes cheap
    if (step[i] == kSet) return !detectorsOnDemand_;
    return !gridOnDemand_ && !detectorsOnDemand_;
  };
  bool announced = false;
  while (!stop_) {
    std::size_t i = n;
    for (std::size_t k = 0; k < n && i == n; ++k)
      if (step[k] != kFinal && wanted_[k].load()) i = k;
    for (std::size_t k = 0; k < n && i == n; ++k)
      if (step[k] != kFinal && eager(k)) i = k;
    if (i == n) {
      if (!announced) {
        announced = true;
        std::size_t sets = 0, detectors = 0, finals = 0;
        for (auto s : step) {
          sets += s >= kSet;
          detectors += s >= kQuick || (s == kFinal);
          finals += s == kFinal;
        }
        ROS_INFO("scene_detector: %zu of %zu objects with their levels (%zu with a detector, %zu %s) %.0f ms after "
                 "start-up; the rest when the pointer comes near (cache %s: %lu hits, %lu built, %lu rejected)",
                 sets, n, detectors, finals, name(fastLevel_), elapsedMs(), assets_->cache()->directory().c_str(),
                 static_cast<unsigned long>(assets_->cache()->hits()),
                 static_cast<unsigned long>(assets_->cache()->misses()),
                 static_cast<unsigned long>(assets_->cache()->rejected()));
      }
      if (std::all_of(step.begin(), step.end(), [](std::uint8_t s) { return s == kFinal; })) return;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));  // wait for the pointer to ask
      continue;
    }
    announced = false;
    const auto& object = objects_[i];
    const auto mesh = scene_.mesh(static_cast<std::uint32_t>(i));
    try {
      SceneAssets::LevelInfo info;
      if (step[i] == kNone) {
        auto set = assets_->spheres(mesh, object.config.distance, &info);
        step[i] = kSet;
        if (!info.cache.problem.empty()) {
          ROS_WARN("scene_detector: '%s': %s", object.config.name.c_str(), info.cache.problem.c_str());
        }
        ROS_INFO("scene_detector: '%s' spheres d = %g: %zu, %s%s (%.0f ms)", object.config.name.c_str(),
                 object.config.distance, set->size(), info.shared ? "shared" : toString(info.cache.source),
                 info.shared ? "" : (" " + info.cache.path).c_str(), info.cache.ms);
        continue;
      }
      const FastLevel fast = step[i] == kSet && quick ? FastLevel::Hierarchy : fastLevel_;
      auto level = assets_->level(mesh, object.config.distance, fast, &info);
      step[i] = fast == fastLevel_ ? kFinal : kQuick;
      {
        std::lock_guard<std::mutex> lock(readyMutex_);
        ready_[i] = level;
      }
      readyPending_ = true;
      levelsDirty_ = true;
      ROS_INFO("scene_detector: '%s' %s detector ready (%.0f ms)%s", object.config.name.c_str(), name(fast),
               info.detectorMs, wanted_[i].load() ? ", asked for by the pointer" : "");
    } catch (const std::exception& e) {
      ROS_ERROR("scene_detector: '%s': cannot prepare level d = %g: %s; answering it by brute force",
                object.config.name.c_str(), object.config.distance, e.what());
      step[i] = kFinal;  // do not retry in a loop; the object stays on brute force
    }
    if (step[i] == kFinal) {
      wanted_[i] = false;
      levelsReady_.fetch_add(1);
    }
  }
}

void SceneHapticDetector::swapInReadyLevels() {
  if (!readyPending_.exchange(false)) return;
  std::lock_guard<std::mutex> lock(readyMutex_);
  for (std::uint32_t i = 0; i < ready_.size(); ++i) {
    if (ready_[i] && scene_.detector(i) != ready_[i]) {
      std::shared_ptr<const ClodDetector> old = scene_.detector(i);
      scene_.setDetector(i, ready_[i]);
      if (old && retired_.size() < retired_.capacity()) retired_.push_back(std::move(old));
    }
  }
}

void SceneHapticDetector::freeRetiredLevels() {
  std::vector<std::shared_ptr<const ClodDetector>> drop;
  {
    std::lock_guard<std::mutex> lock(readyMutex_);
    if (retired_.empty()) return;
    drop.reserve(retired_.capacity());
    drop.swap(retired_);  // retired_ keeps drop's capacity: the pose thread's push_back never allocates
  }
}

// ------------------------------------------------------------------------------------------------
// The haptic path.

bool SceneHapticDetector::updatePoses(const ros::Time& stamp) {
  bool allKnown = true;
  for (std::uint32_t i = 0; i < objects_.size(); ++i) {
    ObjectState& o = objects_[i];
    if (!o.viaTf || (o.poseKnown && !o.config.moving)) continue;
    if (!o.config.moving) {
      // A static frame: looked up once, retried now and then until tf2 knows it.
      const ros::WallTime now = ros::WallTime::now();
      if (now < o.nextRetry) {
        allKnown = false;
        continue;
      }
      try {
        const auto tf = tfBuffer_.lookupTransform(config_.frameId, o.config.frameId, ros::Time(0));
        scene_.setPose(i, toIsometry(tf.transform) * o.config.offset);
        scene_.setActive(i, true);
        o.poseKnown = true;
        ROS_INFO("scene_detector: '%s' placed in static frame '%s'", o.config.name.c_str(), o.config.frameId.c_str());
      } catch (const tf2::TransformException& e) {
        o.nextRetry = now + ros::WallDuration(staticRetry_);
        allKnown = false;
        ROS_WARN_THROTTLE(2.0, "scene_detector: '%s' skipped: static frame '%s' unknown: %s", o.config.name.c_str(),
                          o.config.frameId.c_str(), e.what());
      }
      continue;
    }
    // A moving frame: one lookup per pose, at the pose's stamp (the latest when the stamp is newer).
    try {
      geometry_msgs::TransformStamped tf;
      try {
        tf = tfBuffer_.lookupTransform(config_.frameId, o.config.frameId, stamp);
      } catch (const tf2::ExtrapolationException&) {
        tf = tfBuffer_.lookupTransform(config_.frameId, o.config.frameId, ros::Time(0));
      }
      scene_.setPose(i, toIsometry(tf.transform) * o.config.offset);
      scene_.setActive(i, true);
      o.poseKnown = true;
    } catch (const std::exception& e) {  // tf2 errors, or a non-rigid transform
      scene_.setActive(i, false);
      o.poseKnown = false;
      allKnown = false;
      ROS_WARN_THROTTLE(2.0, "scene_detector: '%s' skipped: moving frame '%s': %s", o.config.name.c_str(),
                        o.config.frameId.c_str(), e.what());
    }
  }
  return allKnown;
}

void SceneHapticDetector::onPose(const geometry_msgs::PoseStampedConstPtr& msg) {
  received_.fetch_add(1, std::memory_order_relaxed);
  if (!isFinite(msg->pose)) {
    droppedNonFinite_.fetch_add(1, std::memory_order_relaxed);
    ROS_WARN_THROTTLE(1.0, "scene_detector: dropped a pose with a NaN or Inf component (%lu so far)",
                      static_cast<unsigned long>(droppedNonFinite_.load()));
    return;
  }
  Vec3 p(msg->pose.position.x, msg->pose.position.y, msg->pose.position.z);
  const std::string& poseFrame = msg->header.frame_id;
  const bool transformed = !poseFrame.empty() && poseFrame != config_.frameId;
  Eigen::Isometry3d sceneFromPose = Eigen::Isometry3d::Identity();
  if (transformed) {
    try {
      geometry_msgs::TransformStamped tf;
      try {
        tf = tfBuffer_.lookupTransform(config_.frameId, poseFrame, msg->header.stamp);
      } catch (const tf2::ExtrapolationException&) {
        tf = tfBuffer_.lookupTransform(config_.frameId, poseFrame, ros::Time(0));
      }
      sceneFromPose = toIsometry(tf.transform);
    } catch (const tf2::TransformException& e) {
      droppedFrame_.fetch_add(1, std::memory_order_relaxed);
      ROS_WARN_THROTTLE(1.0, "scene_detector: dropped a pose in frame '%s': %s (%lu so far)", poseFrame.c_str(),
                        e.what(), static_cast<unsigned long>(droppedFrame_.load()));
      return;
    }
    p = sceneFromPose * p;
    // A huge but finite pose (1e308) can overflow to Inf when transformed: not a position either.
    if (!p.allFinite()) {
      droppedNonFinite_.fetch_add(1, std::memory_order_relaxed);
      ROS_WARN_THROTTLE(1.0, "scene_detector: dropped a pose in frame '%s' that is not finite in frame '%s' (%lu so far)",
                        poseFrame.c_str(), config_.frameId.c_str(), static_cast<unsigned long>(droppedNonFinite_.load()));
      return;
    }
  }

  updatePoses(msg->header.stamp);
  swapInReadyLevels();
  if (levelsReady_.load(std::memory_order_relaxed) < scene_.size()) {
    // Objects the pointer approaches and whose final level is missing are prepared first.
    for (std::uint32_t i = 0; i < scene_.size(); ++i) {
      const auto& level = scene_.detector(i);
      if (level && level->fastLevel() == fastLevel_) continue;
      const double reach = scene_.boundRadius(i) + radius_ + prefetchMargin_;
      if ((scene_.boundCentre(i) - p).squaredNorm() <= reach * reach) wanted_[i] = true;
    }
  }

  SceneQueryResult out;
  const auto start = std::chrono::steady_clock::now();
  scene_.query(p, radius_, mode_, contacts_.data(), contacts_.size(), out, caches_.data());
  const auto elapsed = std::chrono::steady_clock::now() - start;

  auto array = boost::make_shared<ContactArray>();
  array->header.stamp = msg->header.stamp;
  array->header.frame_id = config_.frameId;
  array->pointer = toPoint(p);
  array->pointer_radius = radius_;
  array->in_contact = out.contact;
  array->contacts.resize(out.contacts);
  array->objects.resize(out.contacts);
  array->object_indices.resize(out.contacts);
  for (std::uint32_t k = 0; k < out.contacts; ++k) {
    const SceneContact& c = contacts_[k];
    Contact& m = array->contacts[k];
    m.header = array->header;
    toMsg(c.local, p, radius_, m);
    m.point = toPoint(c.point);  // scene frame
    m.normal = toVector3(c.normal);
    const auto& level = scene_.detector(c.object);
    m.clustering_distance = level ? level->spheres()->distance : std::numeric_limits<double>::quiet_NaN();
    m.level_spheres = level ? static_cast<std::uint32_t>(level->spheres()->size()) : 0;
    array->objects[k] = objects_[c.object].config.name;
    array->object_indices[k] = c.object;
  }
  array->penetration = toVector3(out.penetration);
  array->max_depth = out.maxDepth;
  array->deepest = out.deepest;
  Vec3 force = stiffness_ * out.penetration;
  if (maxForce_ > 0.0 && force.norm() > maxForce_) force *= maxForce_ / force.norm();
  if (!force.allFinite()) force.setZero();
  array->force = toVector3(force);
  array->objects_queried = out.objectsQueried;
  array->objects_rejected = out.objectsRejected;
  array->objects_without_pose = out.objectsInactive;
  array->objects_brute_force = out.bruteForce;
  array->detection_time.fromNSec(std::chrono::duration_cast<std::chrono::nanoseconds>(elapsed).count());

  // The force in the pose's frame, where the device renders it.
  auto wrench = boost::make_shared<geometry_msgs::WrenchStamped>();
  wrench->header.stamp = msg->header.stamp;
  wrench->header.frame_id = transformed ? poseFrame : config_.frameId;
  toMsg(Vec3(sceneFromPose.linear().transpose() * force), wrench->wrench);

  contactsPub_.publish(array);
  forcePub_.publish(wrench);
  published_.fetch_add(1, std::memory_order_relaxed);

  if (markerPub_.getNumSubscribers() == 0) return;  // nobody looks: keep nothing for the display
  std::lock_guard<std::mutex> lock(lastMutex_);
  ++last_.seq;
  last_.pointer = p;
  last_.radius = radius_;
  last_.contacts.assign(contacts_.begin(), contacts_.begin() + out.contacts);
  last_.nearObjects.clear();
  last_.poses.resize(scene_.size());
  for (std::uint32_t i = 0; i < scene_.size(); ++i) {
    last_.poses[i] = scene_.pose(i);
    const double reach = scene_.boundRadius(i) + radius_;
    if (scene_.active(i) && (scene_.boundCentre(i) - p).squaredNorm() <= reach * reach) last_.nearObjects.push_back(i);
  }
}

// ------------------------------------------------------------------------------------------------
// Display (its own thread): only while subscribed, only what changed.

void SceneHapticDetector::onDisplayTimer(const ros::SteadyTimerEvent&) {
  freeRetiredLevels();
  if (markerPub_.getNumSubscribers() == 0) return;
  publishMarkers();
}

void SceneHapticDetector::publishMarkers() {
  auto array = boost::make_shared<visualization_msgs::MarkerArray>();
  const bool all = staticDirty_.exchange(false);
  const bool levelsChanged = levelsDirty_.exchange(false);
  std::vector<std::shared_ptr<const ClodDetector>> levels;
  {
    std::lock_guard<std::mutex> lock(readyMutex_);
    levels = ready_;
  }
  for (std::size_t i = 0; i < objects_.size(); ++i) {
    const ObjectState& o = objects_[i];
    if (!o.drawn) continue;
    std_msgs::Header header;
    header.frame_id = o.config.frameId;  // RViz follows the frame, moving or not: no republish on motion
    if (all) {
      // The mesh by reference (RViz loads the file): a few bytes whatever the triangle count.
      visualization_msgs::Marker m;
      m.header = header;
      m.ns = "scene_mesh";
      m.id = static_cast<int>(i);
      m.type = visualization_msgs::Marker::MESH_RESOURCE;
      m.action = visualization_msgs::Marker::ADD;
      m.mesh_resource = o.config.mesh.rfind("package://", 0) == 0 ? o.config.mesh : "file://" + o.meshPath;
      const Eigen::Quaterniond q(o.config.offset.linear());
      m.pose.position = toPoint(o.config.offset.translation());
      m.pose.orientation.w = q.w();
      m.pose.orientation.x = q.x();
      m.pose.orientation.y = q.y();
      m.pose.orientation.z = q.z();
      m.scale.x = m.scale.y = m.scale.z = o.config.scale;
      m.color = makeColor(0.75f, 0.75f, 0.78f, 1.0f);
      m.frame_locked = true;
      array->markers.push_back(std::move(m));
    }
    if ((all || levelsChanged) && (all || levels[i] != shownLevels_[i])) {
      const std::string ns = "spheres/" + o.config.name;
      static const ClodSphereSet empty;
      const std::size_t first = array->markers.size();
      shownSpheres_[i] = appendSphereMarkers(levels[i] ? *levels[i]->spheres() : empty, nullptr, ns.c_str(), header,
                                             makeColor(0.2f, 0.45f, 1.0f, 0.18f), shownSpheres_[i], *array);
      applyOffset(o.config.offset, first, *array);
      for (std::size_t k = first; k < array->markers.size(); ++k) array->markers[k].frame_locked = true;
      shownLevels_[i] = levels[i];
    }
  }

  LastQuery last;
  {
    std::lock_guard<std::mutex> lock(lastMutex_);
    if (last_.seq != shownSeq_) last = last_;
  }
  if (last.seq != 0 && last.seq != shownSeq_) {
    shownSeq_ = last.seq;
    std_msgs::Header sceneHeader;
    sceneHeader.frame_id = config_.frameId;
    const bool touching = !last.contacts.empty();
    array->markers.push_back(pointerMarker(last.pointer, last.radius, sceneHeader,
                                           touching ? makeColor(1.0f, 0.2f, 0.2f, 0.9f)
                                                    : makeColor(0.1f, 0.9f, 0.2f, 0.9f)));
    for (std::uint32_t i = 0; i < objects_.size(); ++i) {
      const ObjectState& o = objects_[i];
      if (!o.drawn) continue;
      // Hit spheres: only objects near the pointer are asked; the others get deletes once.
      const bool near = std::find(last.nearObjects.begin(), last.nearObjects.end(), i) != last.nearObjects.end();
      hitBuffer_.clear();
      if (near && levels[i]) levels[i]->hitSpheres(last.poses[i].inverse(Eigen::Isometry) * last.pointer, last.radius,
                                                   hitBuffer_);
      if (!hitBuffer_.empty() || shownHit_[i] > 0) {
        std_msgs::Header header;
        header.frame_id = o.config.frameId;
        const std::string ns = "hit_spheres/" + o.config.name;
        const std::size_t first = array->markers.size();
        shownHit_[i] = appendSphereMarkers(*levels[i]->spheres(), &hitBuffer_, ns.c_str(), header,
                                           makeColor(1.0f, 0.55f, 0.0f, 0.55f), shownHit_[i], *array);
        applyOffset(o.config.offset, first, *array);
      }
      // Contact point and normal per object, in the scene frame; deleted once when the contact ends.
      const SceneContact* contact = nullptr;
      for (const SceneContact& c : last.contacts)
        if (c.object == i) contact = &c;
      if (contact || shownContact_[i]) {
        ContactResult shown;
        if (contact) {
          shown = contact->local;
          shown.point = contact->point;
          shown.normal = contact->normal;
        }
        const std::size_t first = array->markers.size();
        appendContactMarkers(shown, std::max(8.0 * last.radius, 0.01), sceneHeader, *array);
        for (std::size_t k = first; k < array->markers.size(); ++k) array->markers[k].id = static_cast<int>(i);
        shownContact_[i] = contact != nullptr;
      }
    }
  }
  if (!array->markers.empty()) markerPub_.publish(array);
}

}  // namespace clod_haptics
