#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <tuple>
#include <utility>

#include "clod_haptics/core/clustering.h"
#include "clod_haptics/core/detector.h"
#include "clod_haptics/core/grid_cache.h"
#include "clod_haptics/core/mesh_cache.h"
#include "clod_haptics/core/mesh.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/sphere_cache.h"
#include "clod_haptics/core/sphere_set.h"

namespace clod_haptics {

/**
 * \brief The one source of CLOD levels: loads the meshes and levels of a scene, each at most once. A mesh
 * used by several objects (same file, same load options) is loaded once; a level (same mesh content, same
 * clustering distance) comes from memory (another object or an earlier request still holds it), else the
 * disk cache, else the remote source (setRemote: the ROS layer's sphere_builder service), else a build,
 * and is shared. A Grid detector's grid likewise comes from the disk cache (CellGridCache, beside the levels)
 * or is built and stored. Builders (the ray casts) are made only when a level must be built. Levels nobody holds
 * any more are dropped from memory when another distance of the same mesh is asked for, so changing the
 * distance again and again does not accumulate levels. Thread-safe (one mutex; loads and builds run under it).
 */
class SceneAssets {
 public:
  /** \brief What level() did. */
  struct LevelInfo {
    CacheOutcome cache;        ///< disk cache outcome (source Hit when shared in memory too)
    bool shared = false;       ///< the level was already in memory (another object asked first)
    double detectorMs = 0.0;   ///< time to construct the ClodDetector
    bool remote = false;       ///< the sphere set came from the remote source
    std::string remoteProblem; ///< why the remote source gave no set (the level was then built here)
    /// The grid's disk cache outcome (Hit: the grid was read, not built). Its path is empty when no grid file was
    /// looked up: another fast level, no disk cache, or the detector shared in memory.
    CacheOutcome grid;
    /// The grid was made from another level's grid of the mesh (CellGrid::forLevel: its cells, this level's sphere
    /// counts) instead of built.
    bool gridFromLevel = false;
    /** \brief Whether the grid was read from the disk cache. */
    bool gridFromCache() const { return !grid.path.empty() && grid.source == CacheSource::Hit; }
  };

  /**
   * \brief Asks another process for the sphere set of (mesh, d): the set, or null with why filled in. Called
   * on a disk-cache miss before building; a set that does not fit the mesh (fitProblem) is refused.
   */
  using RemoteSource = std::function<std::shared_ptr<const ClodSphereSet>(const TriangleMesh& mesh, double distance,
                                                                          std::string& why)>;

  /**
   * \brief Levels go through cache (null: no disk cache), and so do the grids of FastLevel::Grid detectors
   * (CellGridCache, files beside the levels in the cache's directory); detectors use fastLevel and gridRadius (the
   * largest pointer radius the grid serves, see ClodDetector). keepBuilders keeps each mesh's ClodBuilder
   * after a build so another level of that mesh only clusters; false frees the placement's memory.
   * clustering is the strategy of the builds (null: single-link); a cache holds the levels of one
   * strategy, so give each strategy its own directory.
   */
  SceneAssets(std::shared_ptr<SphereSetCache> cache, FastLevel fastLevel = FastLevel::Grid, double gridRadius = 0.0,
              bool keepBuilders = true, std::shared_ptr<const Clustering> clustering = nullptr);

  /** \brief The source asked on a disk-cache miss before building (empty function: none). */
  void setRemote(RemoteSource remote);

  /**
   * \brief Also keep loaded meshes in a disk cache (keyed by the source file's bytes and the load
   * options), so a restart skips the mesh parser. Off by default; null switches it off.
   */
  void setMeshCache(std::shared_ptr<MeshCache> meshCache);

  /** \brief What the last mesh() call did when a mesh cache is set (Hit, Built or Rebuilt). */
  struct MeshInfo {
    bool shared = false;  ///< already in memory (another object uses the same file and options)
    CacheOutcome cache;   ///< the mesh cache outcome (source Built without a mesh cache)
  };

  /**
   * \brief The mesh at path loaded with options, shared with earlier calls asking for the same.
   * \throws MeshLoadError, InvalidParameter as loadMesh.
   */
  std::shared_ptr<const TriangleMesh> mesh(const std::string& path, const MeshLoadOptions& options = {},
                                           MeshInfo* info = nullptr);

  /**
   * \brief The level of mesh for clustering distance d: from memory, else the disk cache, else built
   * (and stored); a Grid detector's grid likewise from the disk cache, else built and stored (info->grid).
   * Lazy: nothing is built before it is asked for.
   * \throws InvalidParameter for a bad d; ClodError from the build.
   */
  std::shared_ptr<const ClodDetector> level(const std::shared_ptr<const TriangleMesh>& mesh, double distance,
                                            LevelInfo* info = nullptr) {
    return level(mesh, distance, fastLevel_, info);
  }

  /**
   * \brief The same with another fast level. The sphere set is read or built once and shared by the
   * detectors of every fast level: a caller can answer quickly with a Hierarchy detector (cheap to
   * construct) and swap in the Grid one (O(1) queries, slower to construct) when it is ready.
   */
  std::shared_ptr<const ClodDetector> level(const std::shared_ptr<const TriangleMesh>& mesh, double distance,
                                            FastLevel fastLevel, LevelInfo* info = nullptr);

  /**
   * \brief Whether level(mesh, d) would read its grid from the disk cache rather than build it: the Grid fast
   * level, a disk cache, and a grid file for the current grid radius (the file is checked when read). A node
   * that answers with a quick hierarchy detector first can skip it then: the grid is about as quick to read.
   * Reads or builds the sphere set of (mesh, d) as spheres() does (the grid's key names it).
   * \throws as spheres().
   */
  bool gridCached(const std::shared_ptr<const TriangleMesh>& mesh, double distance);

  /**
   * \brief Only the sphere set of (mesh, d), from memory, the disk cache or a build: what a restart
   * reads back cheaply. A detector (level()) built later shares it.
   * \throws as level().
   */
  std::shared_ptr<const ClodSphereSet> spheres(const std::shared_ptr<const TriangleMesh>& mesh, double distance,
                                               LevelInfo* info = nullptr);

  /** \brief The fast level of level(mesh, d). */
  FastLevel fastLevel() const { return fastLevel_; }

  /**
   * \brief The grid radius of the detectors built from now on (the pointer radius they serve; 0: 1% of the
   * model's diagonal). Detectors already handed out keep theirs; level() builds a new grid for the new radius
   * and drops the grids of other radii that nobody holds any more.
   * \throws InvalidParameter for a negative or non-finite radius.
   */
  void setGridRadius(double radius);
  /** \brief The grid radius of the next detectors. */
  double gridRadius() const;

  /** \brief Content hash of a mesh (computed once per mesh). */
  std::uint64_t hash(const std::shared_ptr<const TriangleMesh>& mesh);

  /** \brief Number of ClodBuilder constructions (ray-cast placements) so far. */
  std::uint64_t placements() const { return placements_; }
  /** \brief The disk cache (may be null). */
  const std::shared_ptr<SphereSetCache>& cache() const { return cache_; }
  /** \brief The mesh cache (may be null). */
  const std::shared_ptr<MeshCache>& meshCache() const { return meshCache_; }

 private:
  std::uint64_t hashLocked(const std::shared_ptr<const TriangleMesh>& mesh);
  std::shared_ptr<const ClodSphereSet> spheresLocked(const std::shared_ptr<const TriangleMesh>& mesh, double distance,
                                                     LevelInfo& out);
  GridCacheKey gridKeyLocked(const std::shared_ptr<const TriangleMesh>& mesh, double distance,
                             const ClodSphereSet& set, double radius);
  ClodSphereSet fetchOrBuild(const std::shared_ptr<const TriangleMesh>& mesh, std::uint64_t hash, double distance,
                             LevelInfo& out);
  void dropUnusedLevels(const TriangleMesh* mesh, std::uint64_t keepDistanceBits);

  std::shared_ptr<SphereSetCache> cache_;
  std::shared_ptr<CellGridCache> gridCache_;  // in cache_'s directory (null without cache_)
  std::shared_ptr<MeshCache> meshCache_;
  std::shared_ptr<const Clustering> clustering_;
  RemoteSource remote_;
  FastLevel fastLevel_;
  double gridRadius_;
  bool keepBuilders_;
  mutable std::mutex mutex_;
  std::map<std::string, std::shared_ptr<const TriangleMesh>> meshes_;        // key: path + options
  // key: the mesh's address, checked against the weak pointer (an address can be reused after a free)
  std::map<const TriangleMesh*, std::pair<std::weak_ptr<const TriangleMesh>, std::uint64_t>> hashes_;
  std::map<std::uint64_t, std::shared_ptr<const ClodBuilder>> builders_;     // key: content hash
  using LevelKey = std::pair<const TriangleMesh*, std::uint64_t>;  // (mesh, bits of d)
  std::map<LevelKey, std::pair<std::weak_ptr<const TriangleMesh>, std::shared_ptr<const ClodSphereSet>>> sets_;
  // Detectors by (mesh, d), fast level and the bits of the grid radius (0 for the other fast levels).
  std::map<std::tuple<LevelKey, FastLevel, std::uint64_t>, std::shared_ptr<const ClodDetector>> levels_;
  std::uint64_t placements_ = 0;
};

}  // namespace clod_haptics
