#pragma once

#include <ros/ros.h>

#include <cstddef>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <string>

#include "clod_haptics/GetSphereSet.h"
#include "clod_haptics/core/clustering.h"
#include "clod_haptics/core/sphere_cache.h"
#include "clod_haptics/core/sphere_set.h"

namespace clod_haptics {

/**
 * \brief The sphere_builder node: loads ~mesh once, serves ~get_sphere_set and publishes the
 * default level latched on ~sphere_set. Each level is built once and cached; a request for a level
 * being built waits for that build instead of starting a second one.
 */
class SphereBuilderNode {
 public:
  /**
   * \brief Reads the parameters, loads the mesh (from the disk cache with ~use_cache), reads or builds the default
   * level and starts serving. The placement runs on the first level the disk cache does not hold.
   * \throws MeshLoadError when ~mesh is missing, unresolvable or unreadable.
   * \throws InvalidParameter for a bad ~scale, ~default_distance or ~clustering.
   */
  SphereBuilderNode(ros::NodeHandle nh, ros::NodeHandle pnh);

  /**
   * \brief The level for d, built once (by the first caller) and cached. builtHere tells whether
   * this call ran the build. Thread-safe.
   * \throws InvalidParameter for a negative or non-finite d.
   */
  std::shared_ptr<const ClodSphereSet> level(double d, bool* builtHere = nullptr);

  /** \brief How many builds ran (cache misses). */
  std::size_t buildCount() const;

  /** \brief Whether the placement ran (a level was not in the disk cache). Read it from the thread that asked. */
  bool placementRan() const { return builder_ != nullptr; }

  /** \brief The loaded mesh. */
  const std::shared_ptr<const TriangleMesh>& mesh() const { return mesh_; }

 private:
  using Future = std::shared_future<std::shared_ptr<const ClodSphereSet>>;

  void readParameters();
  bool onGetSphereSet(GetSphereSet::Request& request, GetSphereSet::Response& response);
  void evictIfFull();
  ClodBuilder& builder();

  ros::NodeHandle nh_;
  ros::NodeHandle pnh_;
  std::string meshUri_;
  std::string frameId_;
  double scale_ = 1.0;
  bool normalize_ = false;
  double defaultDistance_ = 0.003;
  std::string clustering_ = "single-link";  // the strategy's name (makeClustering)
  int cacheSize_ = 32;
  bool useCache_ = true;  // ~use_cache: the mesh and levels through the disk caches the detector uses
  std::string cacheDir_;  // ~cache_dir ("": defaultSphereCacheDirectory())

  std::shared_ptr<const TriangleMesh> mesh_;
  std::shared_ptr<const Clustering> clusteringStrategy_;
  std::shared_ptr<SphereSetCache> setCache_;  // null without ~use_cache
  std::uint64_t meshHash_ = 0;
  std::once_flag builderOnce_;
  std::unique_ptr<ClodBuilder> builder_;  // made by builder() on the first level the disk cache does not hold
  mutable std::mutex cacheMutex_;
  std::map<double, Future> cache_;
  std::size_t builds_ = 0;

  ros::Publisher setPub_;
  ros::ServiceServer service_;
};

}  // namespace clod_haptics
