// HapticDetector: dynamic_reconfigure and the levels (the worker thread prepares, the pose thread adopts).
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>

#include "clod_haptics/GetSphereSet.h"
#include "clod_haptics/core/sphere_cache.h"
#include "clod_haptics/ros/conversions.h"
#include "clod_haptics/ros/haptic_detector.h"

namespace clod_haptics {

namespace {

enum Step : std::uint8_t { kNone, kSet, kQuick, kFinal };

// The level worker yields the CPU to the pose thread: on a 2-core machine a level build would otherwise take the
// core the pose thread needs. Raising one's own nice value needs no privilege. Only a thread that shares no lock
// with the pose thread may run lower: roscpp holds one process-wide lock while it serialises any message, so a
// preempted low-priority publisher would stall the pose thread's publish. The worker publishes nothing.
void lowerThisThreadPriority(int nice) {
  // The manager may run real-time (clod_haptics.launch): back to the default scheduler first, which needs no
  // privilege either.
  sched_param normal{};
  normal.sched_priority = 0;
  pthread_setschedparam(pthread_self(), SCHED_OTHER, &normal);
  const auto tid = static_cast<id_t>(::syscall(SYS_gettid));
  if (::setpriority(PRIO_PROCESS, tid, nice) != 0) {
    ROS_DEBUG("detector: could not lower the level worker's priority: %s", std::strerror(errno));
  }
}

const char* sourceOf(const SceneAssets::LevelInfo& info) {
  if (info.shared) return "memory";
  if (info.remote) return "service";
  return info.cache.source == CacheSource::Hit ? "cache" : "local";
}

}  // namespace

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
  keepFinite(config.damping, damping_.load(), "damping");
  keepFinite(config.mu_static, muStatic_.load(), "mu_static");
  keepFinite(config.mu_dynamic, muDynamic_.load(), "mu_dynamic");
  if (config.force_model != "proxy" && config.force_model != "penalty") {
    ROS_WARN("detector: unknown force_model '%s' (proxy or penalty); keeping %s", config.force_model.c_str(),
             proxyModel_.load() ? "proxy" : "penalty");
    config.force_model = proxyModel_.load() ? "proxy" : "penalty";
  }
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
  proxyModel_ = config.force_model == "proxy";
  damping_ = config.damping;
  muStatic_ = config.mu_static;
  muDynamic_ = config.mu_dynamic;
  forceShading_ = config.force_shading;
  DisplaySwitches switches;
  switches.mesh = config.show_mesh;
  switches.spheres = config.show_spheres;
  switches.hitSpheres = config.show_hit_spheres;
  switches.contact = config.show_contact;
  switches.pointer = config.show_pointer;
  display_->setSwitches(switches);  // the display thread runs this callback too

  followPointerRadius(config.pointer_radius);

  // At start-up a scene keeps the distances of its file; a later change applies to every object.
  const bool first = !configured_;
  configured_ = true;
  if (first || config.clustering_distance == requestedDistance_.load()) {
    requestedDistance_ = config.clustering_distance;
    return;
  }
  requestedDistance_ = config.clustering_distance;
  {
    std::lock_guard<std::mutex> lock(workerMutex_);
    distanceChanged_ = true;
  }
  workerCv_.notify_all();
}

void HapticDetector::followPointerRadius(double radius) {
  // The grids serve the pointer radius: a new one rebuilds them off the haptic path, as a level swap (the old
  // grids answer meanwhile, a larger radius through their hierarchy: slower, never wrong).
  if (!gridFollowsPointer_ || !assets_ || params_.fastLevel != FastLevel::Grid || !(radius > 0.0) ||
      radius == gridTarget_.load())
    return;
  assets_->setGridRadius(radius);
  gridTarget_ = radius;
  ROS_INFO("detector: pointer radius %g: rebuilding the grids for it", radius);
  {
    std::lock_guard<std::mutex> lock(workerMutex_);
    radiusChanged_ = true;
  }
  workerCv_.notify_all();
}

void HapticDetector::levelWorker() {
  lowerThisThreadPriority(10);
  std::vector<LevelPlan> plan(objects_.size());
  for (std::size_t i = 0; i < plan.size(); ++i) plan[i].distance = objects_[i].config.distance;
  for (;;) {
    {
      std::unique_lock<std::mutex> lock(workerMutex_);
      if (stop_) return;
      if (distanceChanged_) {
        distanceChanged_ = false;
        for (LevelPlan& p : plan) {
          p = LevelPlan();
          p.distance = requestedDistance_.load();
          p.quick = false;
        }
      }
      if (radiusChanged_) {  // built grids are for the old radius: back one step, the next one builds the grid
        radiusChanged_ = false;
        for (LevelPlan& p : plan)
          if (p.step == kFinal) p.step = kQuick;
      }
    }
    if (prepareNextLevel(plan)) continue;
    // Nothing to do until the pointer asks for an object, the distance changes or the node stops.
    std::unique_lock<std::mutex> lock(workerMutex_);
    workerCv_.wait_for(lock, std::chrono::milliseconds(20),
                       [this] { return stop_ || distanceChanged_ || radiusChanged_; });
  }
}

bool HapticDetector::prepareNextLevel(std::vector<LevelPlan>& plan) {
  // Per object, step by step: its sphere set, a hierarchy detector (cheap to construct: ~quick_start), then the
  // configured fast level. Objects the pointer comes near (wanted_) go first; sets are read for every object at
  // once; detectors of objects nobody approaches wait with ~detectors_on_demand, grids with ~grid_on_demand.
  auto eager = [&](const LevelPlan& p) {
    if (p.step == kNone) return true;
    if (p.step == kSet) return !params_.detectorsOnDemand;
    return !params_.gridOnDemand && !params_.detectorsOnDemand;
  };
  const std::size_t n = plan.size();
  std::size_t i = n;
  for (std::size_t k = 0; k < n && i == n; ++k)
    if (plan[k].step != kFinal && wanted_[k].load()) i = k;
  for (std::size_t k = 0; k < n && i == n; ++k)
    if (plan[k].step != kFinal && eager(plan[k])) i = k;
  if (i == n) return false;

  LevelPlan& p = plan[i];
  const std::string& name = objects_[i].config.name;
  const auto mesh = scene_.mesh(static_cast<std::uint32_t>(i));  // fixed after construction
  const auto start = std::chrono::steady_clock::now();
  try {
    SceneAssets::LevelInfo info;
    if (p.step == kNone) {
      const auto set = assets_->spheres(mesh, p.distance, &info);
      if (!info.remoteProblem.empty()) ROS_WARN("detector: '%s': %s", name.c_str(), info.remoteProblem.c_str());
      if (!info.cache.problem.empty()) ROS_WARN("detector: '%s': %s", name.c_str(), info.cache.problem.c_str());
      p.step = kSet;
      p.source = sourceOf(info);
      p.setMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
      ROS_INFO("detector: '%s' spheres d = %g: %zu from %s (%.1f ms)", name.c_str(), p.distance, set->size(),
               p.source.c_str(), p.setMs);
      return true;
    }
    // The quick hierarchy is for grids that must be built: a grid the disk cache holds is about as quick to read,
    // and it comes next anyway when grids are eager or the pointer is near.
    const bool quick = p.step == kSet && p.quick && params_.quickStart && params_.fastLevel != FastLevel::Hierarchy &&
                       !((!params_.gridOnDemand || wanted_[i].load()) && assets_->gridCached(mesh, p.distance));
    const FastLevel fast = quick ? FastLevel::Hierarchy : params_.fastLevel;
    auto level = assets_->level(mesh, p.distance, fast, &info);
    p.step = quick ? kQuick : kFinal;
    publishLevel(i, std::move(level), p.source, p.setMs + info.detectorMs);
    if (!info.grid.problem.empty()) ROS_WARN("detector: '%s': %s", name.c_str(), info.grid.problem.c_str());
    ROS_INFO("detector: '%s' level d = %g in use (%s detector, %.1f ms%s)%s", name.c_str(), p.distance, toString(fast),
             info.detectorMs,
             info.gridFromCache() ? ", grid from cache"
             : info.gridFromLevel ? ", grid from the level before"
                                  : "",
             wanted_[i].load() ? ", asked for by the pointer" : "");
  } catch (const std::exception& e) {
    ROS_ERROR("detector: '%s': cannot prepare level d = %g: %s; keeping its current level (or brute force)",
              name.c_str(), p.distance, e.what());
    p.step = kFinal;  // not retried in a loop
  }
  if (p.step == kFinal) wanted_[i] = false;
  return true;
}

void HapticDetector::publishLevel(std::size_t object, std::shared_ptr<const ClodDetector> detector,
                                  const std::string& source, double ms) {
  // The proxy's swept query walks the level's grid; its own tree is built here, off the haptic path.
  auto sweep = detector ? std::make_shared<const SweptSphereQuery>(detector->mesh(), detector) : nullptr;
  std::lock_guard<std::mutex> lock(levelsMutex_);
  auto next = std::make_shared<Levels>();
  next->detectors = levels_ ? levels_->detectors : std::vector<std::shared_ptr<const ClodDetector>>(objects_.size());
  next->sweeps = levels_ ? levels_->sweeps : std::vector<std::shared_ptr<const SweptSphereQuery>>(objects_.size());
  next->sweeps[object] = std::move(sweep);
  next->detectors[object] = std::move(detector);
  next->id = nextLevelsId_++;
  next->source = source;
  next->readyMs = ms;
  if (levels_) retired_.push_back(std::move(levels_));
  levels_ = std::move(next);
  published_.store(levels_.get(), std::memory_order_release);
  swaps_.fetch_add(1, std::memory_order_relaxed);
  statusDirty_ = true;  // the display thread publishes the status: a publish holds roscpp's process-wide lock
}

void HapticDetector::freeRetiredLevels() {
  // A snapshot the pose thread has moved past (it adopted a newer one) is read by nobody any more; its levels
  // (megabytes of small arrays) are freed here, never on the haptic path.
  std::vector<std::shared_ptr<const Levels>> drop;
  {
    std::lock_guard<std::mutex> lock(levelsMutex_);
    const std::uint64_t adopted = adopted_.load(std::memory_order_acquire);
    auto keep = std::partition(retired_.begin(), retired_.end(),
                               [&](const std::shared_ptr<const Levels>& l) { return l->id >= adopted; });
    drop.assign(std::make_move_iterator(keep), std::make_move_iterator(retired_.end()));
    retired_.erase(keep, retired_.end());
  }
}

std::shared_ptr<const ClodSphereSet> HapticDetector::fetchFromService(const TriangleMesh& /*mesh*/, double distance,
                                                                      std::string& why) {
  ros::ServiceClient client = nh_.serviceClient<GetSphereSet>(params_.sphereService);
  if (!client.waitForExistence(ros::Duration(params_.serviceTimeout))) {
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
  try {
    return std::make_shared<const ClodSphereSet>(fromMsg(srv.response.sphere_set));  // SceneAssets checks the fit
  } catch (const std::exception& e) {
    why = std::string("the served set is malformed: ") + e.what();
    return nullptr;
  }
}

}  // namespace clod_haptics
