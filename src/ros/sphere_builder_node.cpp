#include "clod_haptics/ros/sphere_builder_node.h"

#include <chrono>
#include <cmath>
#include <sstream>

#include "clod_haptics/SphereSet.h"
#include "clod_haptics/core/clustering.h"
#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/mesh_cache.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/sphere_cache.h"
#include "clod_haptics/ros/conversions.h"
#include "clod_haptics/ros/mesh_resource.h"

namespace clod_haptics {

SphereBuilderNode::SphereBuilderNode(ros::NodeHandle nh, ros::NodeHandle pnh) : nh_(nh), pnh_(pnh) {
  readParameters();
  const std::string path = resolveMeshPath(meshUri_);
  MeshLoadOptions options;
  options.scale = scale_;
  options.normalize = normalize_;
  clusteringStrategy_ = requireClustering(clustering_, pnh_.resolveName("clustering"));
  const auto start = std::chrono::steady_clock::now();
  CacheOutcome meshOutcome;
  if (useCache_) {
    // The detector's caches (same directory and layout): a restart reads the mesh and its levels instead of
    // parsing and placing, and leaves the CPU to the detector's own restart.
    mesh_ = std::make_shared<const TriangleMesh>(MeshCache(cacheDir_).load(path, options, &meshOutcome));
    setCache_ = std::make_shared<SphereSetCache>(sphereCacheDirectoryFor(cacheDir_, clustering_));
    meshHash_ = meshContentHash(*mesh_);
  } else {
    mesh_ = std::make_shared<const TriangleMesh>(loadMesh(path, options));
  }
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  ROS_INFO("sphere_builder: loaded '%s' (%zu triangles, %s) in %.1f ms%s; %s clustering", path.c_str(), mesh_->size(),
           normalize_ ? "normalised to the unit cube" : ("scale " + std::to_string(scale_)).c_str(), ms,
           !useCache_ ? "" : (meshOutcome.source == CacheSource::Hit ? " from the mesh cache" : ", cached"),
           clustering_.c_str());

  auto set = level(defaultDistance_);
  SphereSet msg;
  std_msgs::Header header;
  header.frame_id = frameId_;
  header.stamp = ros::Time::now();
  toMsg(*set, header, msg);
  setPub_ = pnh_.advertise<SphereSet>("sphere_set", 1, true);
  setPub_.publish(msg);
  service_ = pnh_.advertiseService("get_sphere_set", &SphereBuilderNode::onGetSphereSet, this);
  ROS_INFO("sphere_builder: default level d = %g has %zu spheres; serving %s", defaultDistance_, set->size(),
           service_.getService().c_str());
}

void SphereBuilderNode::readParameters() {
  if (!pnh_.getParam("mesh", meshUri_) || meshUri_.empty()) {
    throw MeshLoadError(
        "", "required parameter " + pnh_.resolveName("mesh") + " is not set (a mesh path or a package:// URI)");
  }
  pnh_.param<std::string>("frame_id", frameId_, "world");
  pnh_.param("scale", scale_, 1.0);
  pnh_.param("normalize", normalize_, false);
  pnh_.param("default_distance", defaultDistance_, 0.003);
  pnh_.param("cache_size", cacheSize_, 32);
  pnh_.param<std::string>("clustering", clustering_, "single-link");
  pnh_.param("use_cache", useCache_, true);
  pnh_.param<std::string>("cache_dir", cacheDir_, "");
  if (!std::isfinite(scale_) || scale_ <= 0.0) throw InvalidParameter("~scale must be finite and positive");
  requireNonNegative(defaultDistance_, "~default_distance");
}

std::shared_ptr<const ClodSphereSet> SphereBuilderNode::level(double d, bool* builtHere) {
  requireNonNegative(d, "clustering distance");
  if (d == 0.0) d = 0.0;  // one key for -0.0 and 0.0
  std::promise<std::shared_ptr<const ClodSphereSet>> promise;
  Future future;
  bool mine = false;
  {
    std::lock_guard<std::mutex> lock(cacheMutex_);
    auto it = cache_.find(d);
    if (it != cache_.end()) {
      future = it->second;
    } else {
      evictIfFull();
      future = promise.get_future().share();
      cache_.emplace(d, future);
      ++builds_;
      mine = true;
    }
  }
  if (builtHere) *builtHere = mine;
  if (mine) {
    // The caller that inserted the entry builds (outside the lock); the others wait on its future.
    try {
      if (setCache_) {
        CacheOutcome outcome;
        promise.set_value(setCache_->getOrBuild(
            *mesh_, meshHash_, d, [&] { return builder().build(d); }, &outcome));
        if (!outcome.problem.empty()) ROS_WARN("sphere_builder: d = %g: %s", d, outcome.problem.c_str());
      } else {
        promise.set_value(std::make_shared<const ClodSphereSet>(builder().build(d)));
      }
    } catch (...) {
      promise.set_exception(std::current_exception());
      std::lock_guard<std::mutex> lock(cacheMutex_);
      cache_.erase(d);  // a later request retries
    }
  }
  return future.get();
}

ClodBuilder& SphereBuilderNode::builder() {
  // The placement (ray casts over the mesh) runs once, on the first level not found in the disk cache.
  std::call_once(builderOnce_, [this] {
    const auto start = std::chrono::steady_clock::now();
    builder_ = std::make_unique<ClodBuilder>(mesh_, std::make_shared<PaperPlacement>(), clusteringStrategy_);
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    ROS_INFO("sphere_builder: placed %zu spheres in %.1f ms", builder_->centres(), ms);
  });
  return *builder_;
}

std::size_t SphereBuilderNode::buildCount() const {
  std::lock_guard<std::mutex> lock(cacheMutex_);
  return builds_;
}

void SphereBuilderNode::evictIfFull() {
  // Called with cacheMutex_ held: drop finished levels other than the default one, oldest key first.
  for (auto it = cache_.begin(); it != cache_.end() && static_cast<int>(cache_.size()) >= std::max(cacheSize_, 1);) {
    if (it->first != defaultDistance_ && it->second.wait_for(std::chrono::seconds(0)) == std::future_status::ready) {
      it = cache_.erase(it);
    } else {
      ++it;
    }
  }
}

bool SphereBuilderNode::onGetSphereSet(GetSphereSet::Request& request, GetSphereSet::Response& response) {
  const auto start = std::chrono::steady_clock::now();
  try {
    bool built = false;
    auto set = level(request.distance, &built);
    std_msgs::Header header;
    header.frame_id = frameId_;
    header.stamp = ros::Time::now();
    toMsg(*set, header, response.sphere_set);
    if (request.brief) {
      response.triangle_counts.reserve(response.sphere_set.spheres.size());
      for (const auto& sphere : response.sphere_set.spheres) {
        response.triangle_counts.push_back(static_cast<uint32_t>(sphere.triangles.size()));
      }
      response.sphere_set.spheres.clear();
    }
    response.success = true;
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    std::ostringstream text;
    text << (built ? "built" : "cached") << ": d = " << set->distance << ", " << set->size() << " spheres (" << ms
         << " ms)";
    response.message = text.str();
    ROS_DEBUG("sphere_builder: %s", response.message.c_str());
  } catch (const ClodError& e) {
    response.success = false;
    response.message = e.what();
    ROS_WARN_THROTTLE(1.0, "sphere_builder: request for d = %g refused: %s", request.distance, e.what());
  } catch (const std::exception& e) {
    response.success = false;
    response.message = std::string("build failed: ") + e.what();
    ROS_ERROR_THROTTLE(1.0, "sphere_builder: build for d = %g failed: %s", request.distance, e.what());
  }
  return true;  // the answer carries success; the call itself succeeded
}

}  // namespace clod_haptics
