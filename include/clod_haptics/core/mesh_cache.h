#pragma once

#include <atomic>
#include <cstdint>
#include <string>

#include "clod_haptics/core/mesh.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/sphere_cache.h"

namespace clod_haptics {

/**
 * \brief Version of the binary mesh cache format; part of every key and file header. 2: vertices read in
 * double by the strict readers; 3: vertices relative to the mesh's local origin, which is stored; 4: the
 * adjacency and the vertex corners are stored (rebuilding them was 85% of a read); 5: the box tree over the
 * triangles too (MeshBoxTree), which the grid detectors and swept queries of the mesh then share; 6: the checksum
 * is cacheChecksum (four lanes) instead of fnv1a64.
 */
constexpr std::uint32_t kMeshCacheFormatVersion = 6;

/**
 * \brief The key of a loaded mesh: a hash of the source file's bytes and of the load options (scale,
 * normalise, orientation) and the format version. Editing the file changes the key, so a cached mesh
 * of an older file is never used.
 * \throws MeshLoadError when the file cannot be read.
 */
std::uint64_t meshSourceKey(const std::string& path, const MeshLoadOptions& options);

/**
 * \brief Writes a loaded mesh (vertices, triangles, normals, adjacency and vertex corners, its box tree (mesh.boxTree
 * when it fits, else one built here), scale, offset, orientation flag, name) in a binary format with a header and a
 * checksum.
 * \throws FormatError when the file cannot be written.
 */
void writeMeshBinary(const TriangleMesh& mesh, std::uint64_t sourceKey, const std::string& path);

/**
 * \brief Reads what writeMeshBinary wrote and checks it: magic, version, key, sizes, checksum, every
 * index in range (vertices, neighbours, corners' triangles), corner offsets ascending over the corners, and
 * every coordinate and angle finite, and the box tree serving the mesh (meshBoxTreeProblem); the mesh read
 * carries that tree in boxTree.
 * \throws FormatError naming the first check that failed.
 */
TriangleMesh readMeshBinary(const std::string& path, std::uint64_t sourceKey);

/**
 * \brief A disk cache of loaded meshes, so a restart skips the parser (assimp): one file per source
 * key. Like SphereSetCache: a bad file is deleted and the mesh loaded again, files appear atomically.
 * Thread-safe.
 */
class MeshCache : public DiskCache {
 public:
  /** \brief A cache in directory; empty means defaultSphereCacheDirectory(). */
  explicit MeshCache(std::string directory = "");

  /**
   * \brief The mesh at path loaded with options: from the cache when a valid file exists, else with
   * loadMesh() (then stored). Either way the mesh carries its box tree (boxTree), which its grid detectors and swept
   * queries share instead of building one each. outcome reports which, and any problem.
   * \throws MeshLoadError, InvalidParameter as loadMesh.
   */
  TriangleMesh load(const std::string& path, const MeshLoadOptions& options = {}, CacheOutcome* outcome = nullptr);

  /** \brief The file that holds a mesh of this key. */
  std::string pathFor(std::uint64_t sourceKey) const;
  /** \brief Meshes parsed because no (valid) file existed. */
  std::uint64_t parsed() const { return parsed_.load(); }

 private:
  std::atomic<std::uint64_t> parsed_{0};
};

}  // namespace clod_haptics
