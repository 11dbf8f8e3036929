#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "clod_haptics/core/checksum.h"
#include "clod_haptics/core/mesh.h"
#include "clod_haptics/core/sphere_set.h"

namespace clod_haptics {

/**
 * \brief Version of the binary sphere-set cache format; part of every cache key and file header. 2: tight sets split
 * long triangles over several spheres (a level cached by version 1 still fits its mesh, but is not the level this
 * version builds, so it is not read). 3: tight sets take another principal axis only where it cuts clearly more
 * compact halves (same reason). 4: the checksum is cacheChecksum (four lanes) instead of fnv1a64. 5: tight sets'
 * thin patches get k-centre rounds and a wider thin test (same reason; the thin-patch settling and the hollow rule,
 * which came after 4, had not bumped it, so a level cached between them could be read as the current one). 6: tight
 * sets' thin patches stop Lloyd's rounds once under 1% of their items move and take 4 k-centre rounds (same reason).
 */
constexpr std::uint32_t kSphereCacheFormatVersion = 6;

/**
 * \brief A 64-bit content hash of a loaded mesh: FNV-1a over the vertex coordinates (after scaling)
 * and the triangle indices (after orientation), word by word, plus the counts. Two meshes with the
 * same hash have, barring a collision, the same geometry, so they share cached sphere sets whatever
 * their file name. The cache check of coverage catches a collision all the same.
 */
std::uint64_t meshContentHash(const TriangleMesh& mesh);

/**
 * \brief Writes a sphere set in the binary cache format: a header (magic, format version, mesh hash,
 * clustering distance, counts), the flat arrays, the build statistics and the mesh name, then a
 * checksum of everything before it.
 * \throws FormatError when the file cannot be written.
 */
void writeSphereSetBinary(const ClodSphereSet& set, std::uint64_t meshHash, const std::string& path);

/**
 * \brief Reads a cache file and checks it against what the caller expects: magic, format version,
 * mesh hash, clustering distance (bit for bit), sizes, checksum, then that the set fits the mesh
 * (indices in range, every triangle listed by a sphere whose radius reaches its vertices). A file
 * that passes can be used exactly like a freshly built set.
 * \throws FormatError naming the first check that failed.
 */
ClodSphereSet readSphereSetBinary(const std::string& path, std::uint64_t meshHash, double distance,
                                  const TriangleMesh& mesh);

/**
 * \brief The default cache directory: $CLOD_CACHE_DIR if set, else $ROS_HOME/clod_haptics_cache,
 * else $HOME/.ros/clod_haptics_cache, else a directory under the system temp directory.
 */
std::string defaultSphereCacheDirectory();

/**
 * \brief Where the levels of a clustering strategy are kept under a cache directory (empty: the default one): the
 * directory itself for single-link (the paper's), a subdirectory named after any other strategy, since the file
 * names do not say which strategy built a level. The detector and the sphere_builder share it.
 */
std::string sphereCacheDirectoryFor(const std::string& directory, const std::string& clustering);

/** \brief Where a level came from. */
enum class CacheSource : std::uint8_t {
  Hit,      ///< read from a valid cache file
  Built,    ///< no cache file: built and stored
  Rebuilt,  ///< the cache file was stale or corrupt: deleted, built and stored again
};

/** \brief The lower-case name of a source ("hit", "built", "rebuilt"). */
const char* toString(CacheSource source);

/** \brief What one getOrBuild did, for logs and statistics. */
struct CacheOutcome {
  CacheSource source = CacheSource::Built;
  std::string path;     ///< the cache file
  std::string problem;  ///< why a file was rejected (Rebuilt), or why storing failed (empty: none)
  double ms = 0.0;      ///< time spent reading or building and writing
};

/**
 * \brief What the disk caches (SphereSetCache, CellGridCache, MeshCache) share: a directory of files named by key, a
 * file that fails its checks deleted and its content built again, files stored atomically, and counters.
 */
class DiskCache {
 public:
  /** \brief The directory. */
  const std::string& directory() const { return directory_; }
  /** \brief Entries read from disk. */
  std::uint64_t hits() const { return hits_.load(); }
  /** \brief Files rejected as stale or corrupt (and built again). */
  std::uint64_t rejected() const { return rejected_.load(); }

 protected:
  /** \brief A cache in directory (created on the first store); empty means defaultSphereCacheDirectory(). */
  explicit DiskCache(std::string directory);

  /**
   * \brief One lookup of the file out.path: read() when the file exists (a hit), else, or when read() throws
   * FormatError (the file is then deleted and never trusted again), build() and store the result with
   * write(tmp). Fills out.source, out.problem and out.ms (from start).
   * \throws whatever build() throws.
   */
  void lookUp(CacheOutcome& out, std::chrono::steady_clock::time_point start, const std::function<void()>& read,
              const std::function<void()>& build, const std::function<void(const std::string& tmp)>& write);

 private:
  std::string directory_;
  std::atomic<std::uint64_t> hits_{0}, rejected_{0};
};

/**
 * \brief A disk cache of CLOD levels, one file per (mesh content hash, clustering distance, format
 * version); the grids of the Grid fast level go in the same directory (CellGridCache, grid_cache.h). A restart finds
 * the files and does not rebuild; a stale or corrupt file is detected, deleted and rebuilt, never trusted. Files are
 * written to a temporary name and renamed, so a crash or a concurrent writer never leaves a half-written file under the
 * final name.
 *
 * Thread-safe: getOrBuild may run concurrently (two threads asking for the same level may both
 * build it; the last rename wins and both results are valid).
 */
class SphereSetCache : public DiskCache {
 public:
  /** \brief A cache in directory (created on the first store); empty means defaultSphereCacheDirectory(). */
  explicit SphereSetCache(std::string directory = "");

  /** \brief The file that holds the level (hash, d). */
  std::string pathFor(std::uint64_t meshHash, double distance) const;

  /**
   * \brief The level (mesh, d) from the cache, or from build() when there is no valid file, which
   * is then stored. build is called at most once and only on a miss, so a caller can construct its
   * ClodBuilder (the expensive ray casts) inside it and skip it entirely on a hit. A failure to
   * store is reported in outcome->problem and is not an error.
   * \throws InvalidParameter for a negative or non-finite d; whatever build() throws.
   */
  std::shared_ptr<const ClodSphereSet> getOrBuild(const TriangleMesh& mesh, std::uint64_t meshHash, double distance,
                                                  const std::function<ClodSphereSet()>& build,
                                                  CacheOutcome* outcome = nullptr);

  /** \brief Levels built because no file existed. */
  std::uint64_t misses() const { return misses_.load(); }

 private:
  std::atomic<std::uint64_t> misses_{0};
};

}  // namespace clod_haptics
