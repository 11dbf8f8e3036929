// The binary mesh cache keeps the file layout and rebuilds the adjacency on reading: a mesh read back
// answers the inside/outside test as the loaded one.

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
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

// A mesh far from zero comes back from the cache with its local origin: the same model coordinates, bit for bit.
TEST(MeshCacheOrigin, FarMeshReadsBackWithItsOrigin) {
  const std::string dir = (std::filesystem::temp_directory_path() / ("clod_mesh_cache_origin_" + std::to_string(::getpid())))
                              .string();
  std::filesystem::create_directories(dir);
  const std::string source = dir + "/far.off";
  {
    std::ofstream out(source);
    out.precision(17);
    out << "OFF\n4 4 0\n";
    for (const char* v : {"1000000.1 2e5 3", "1000001.3 2e5 3", "1000000.1 200001.7 3", "1000000.1 2e5 4.1"}) out << v << "\n";
    out << "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";
  }
  const TriangleMesh loaded = loadMesh(source);
  ASSERT_NE(loaded.origin.x(), 0.0);
  const std::uint64_t key = meshSourceKey(source, MeshLoadOptions());
  writeMeshBinary(loaded, key, dir + "/far.bin");
  const TriangleMesh read = readMeshBinary(dir + "/far.bin", key);
  std::filesystem::remove_all(dir);
  EXPECT_EQ(read.origin, loaded.origin);
  ASSERT_EQ(read.vertices.size(), loaded.vertices.size());
  for (std::size_t v = 0; v < read.vertices.size(); ++v) EXPECT_EQ(read.toModel(read.vertices[v]), loaded.toModel(loaded.vertices[v]));
  EXPECT_EQ(loaded.toModel(loaded.vertices[0]), Vec3(1000000.1, 2e5, 3));
}

}  // namespace
