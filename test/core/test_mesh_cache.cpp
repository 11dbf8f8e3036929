// The binary mesh cache keeps the file layout and rebuilds the adjacency on reading: a mesh read back
// answers the inside/outside test as the loaded one.

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include <unistd.h>

#include "clod_haptics/core/mesh_cache.h"
#include "clod_haptics/core/mesh_loader.h"
#include "test_helpers.h"

namespace {

using namespace clod_haptics;

TEST(MeshCacheAdjacency, ReadBackEqualsTheLoadedMesh) {
  const std::string source = CLOD_PACKAGE_DATA_DIR "/meshes/torus.obj";
  MeshLoadOptions options;
  options.normalize = true;
  const TriangleMesh loaded = loadMesh(source, options);
  const std::uint64_t key = meshSourceKey(source, options);
  const std::string path =
      (std::filesystem::temp_directory_path() / ("clod_mesh_cache_adjacency_" + std::to_string(::getpid()) + ".bin"))
          .string();
  writeMeshBinary(loaded, key, path);
  const TriangleMesh read = readMeshBinary(path, key);
  std::filesystem::remove(path);
  ASSERT_EQ(read.triangles, loaded.triangles);
  EXPECT_EQ(read.neighbours, loaded.neighbours);
  EXPECT_EQ(read.cornerOffsets, loaded.cornerOffsets);
  EXPECT_EQ(read.cornerTriangles, loaded.cornerTriangles);
  EXPECT_EQ(read.cornerAngles, loaded.cornerAngles);
  EXPECT_FALSE(read.neighbours.empty());
}

}  // namespace
