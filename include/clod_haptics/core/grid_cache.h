#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <string>

#include "clod_haptics/core/cell_grid.h"
#include "clod_haptics/core/detector.h"
#include "clod_haptics/core/mesh.h"
#include "clod_haptics/core/sphere_cache.h"
#include "clod_haptics/core/sphere_set.h"

namespace clod_haptics {

/**
 * \brief Version of the binary grid cache format; part of every grid file's name and header. Bump it whenever
 * CellGrid's layout or its build (cell sizing, candidates, slabs) changes: a file answers as the build that wrote it.
 * 4: the detector's trees over the spheres follow the grid (SphereTrees), and the checksum is cacheChecksum.
 * 5: a grid of large triangles takes coarser cells to fit the detector's memory target (gridBytesPerTriangle).
 */
constexpr std::uint32_t kGridCacheFormatVersion = 5;

/** \brief What a cached grid was built from: the level (mesh, d, its sphere set) and CellGrid's parameters. */
struct GridCacheKey {
  std::uint64_t meshHash = 0;        ///< meshContentHash of the mesh
  double distance = 0.0;             ///< the level's clustering distance
  std::uint64_t setHash = 0;         ///< sphereSetHash of the level's set (the cells' sphere counts come from it)
  double radius = 0.0;               ///< the grid radius (CellGrid's radius)
  double entriesPerTriangle = 24.0;  ///< CellGrid's memory budget
  CellGrid::Index index = CellGrid::Index::Auto;
};

/**
 * \brief A 64-bit hash of what a grid takes from a sphere set: its sphere count, offsets and triangle lists.
 * Two sets of one mesh and distance built by different clustering strategies differ in it.
 */
std::uint64_t sphereSetHash(const ClodSphereSet& set);

/**
 * \brief Writes a Grid detector's parts in the binary cache format: magic, format version, byte order, the key, the
 * mesh's triangle count, then the grid (CellGrid::writeTo), the trees over the spheres and a checksum of everything
 * before it.
 * \throws FormatError when the file cannot be written.
 */
void writeCellGridBinary(const ClodDetector::GridParts& parts, const GridCacheKey& key, std::size_t triangles,
                         const std::string& path);

/**
 * \brief Reads a grid file and checks it against what the caller expects: checksum, magic, format version, byte
 * order, every field of the key (bit for bit), the mesh's triangle count, then CellGrid::readFrom's checks and that
 * the trees serve set over mesh (sphereTreesProblem; set is the level whose hash the key holds). The file is read
 * with its arrays copied in one piece each (no per-element parsing beyond the checks).
 * \throws FormatError naming the first check that failed.
 */
ClodDetector::GridParts readCellGridBinary(const std::string& path, const GridCacheKey& key, const TriangleMesh& mesh,
                                           const ClodSphereSet& set);

/**
 * \brief A disk cache of grids (the Grid fast level) and the detector's trees over the level's spheres (a restart
 * then builds neither), one file per (mesh content hash, clustering distance, grid
 * radius, CellGrid options, format version), beside the sphere sets in the same directory. The file name
 * "mesh-<hash>-d<bits>-grid-r<bits>-o<options>-v<version>.clodgrid" starts as the sphere set's. Same rules as
 * SphereSetCache: a stale or corrupt file is deleted and rebuilt, files are stored atomically, thread-safe.
 *
 * Grids are large (about 8 bytes per candidate, 24 candidates per triangle: 190 MB for a million triangles) and a
 * reconfigure loop over distances and radii makes one per pair, so the grid files of the directory are kept within
 * a byte budget: after a store, the least recently used ones (by modification time, which a hit refreshes) are
 * deleted until the rest fit. The file just stored is never deleted.
 */
class CellGridCache : public DiskCache {
 public:
  /** \brief The default budget of grid files per directory: 2 GiB, or $CLOD_GRID_CACHE_MAX_MB when set. */
  static std::uint64_t defaultMaxBytes();

  /**
   * \brief A cache in directory (created on the first store); empty means defaultSphereCacheDirectory(). maxBytes:
   * the budget of the directory's grid files (0: defaultMaxBytes()).
   */
  explicit CellGridCache(std::string directory = "", std::uint64_t maxBytes = 0);

  /** \brief The file that holds the grid of key. */
  std::string pathFor(const GridCacheKey& key) const;

  /**
   * \brief The grid and trees of key (for set over mesh) from the cache, or from build() when there is no valid
   * file, which is then stored. build is called at most once and only on a miss. A failure to store is reported in
   * outcome->problem.
   * \throws InvalidParameter for a bad distance or radius; whatever build() throws.
   */
  ClodDetector::GridParts getOrBuild(const TriangleMesh& mesh, const ClodSphereSet& set, const GridCacheKey& key,
                                     const std::function<ClodDetector::GridParts()>& build,
                                     CacheOutcome* outcome = nullptr);
  /**
   * \brief Whether a file for key exists (getOrBuild would read it; it is checked then, and rebuilt if bad).
   */
  bool has(const GridCacheKey& key) const;

  /** \brief Grids built because no file existed. */
  std::uint64_t misses() const { return misses_.load(); }

 private:
  void prune(const std::string& keep) const;

  std::uint64_t maxBytes_;
  std::atomic<std::uint64_t> misses_{0};
};

}  // namespace clod_haptics
