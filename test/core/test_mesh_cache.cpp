// The binary mesh cache keeps the file layout and the adjacency (stored, not rebuilt on reading): a mesh read
// back has the adjacency computeAdjacency gives the loaded one, and a stored adjacency that would index out of
// range is refused.

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <limits>
#include <string>

#include "clod_haptics/core/errors.h"
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

// Each adjacency array written out of range (or not finite, or not ascending), and a normal that is neither a unit
// vector nor zero, is refused on reading with a FormatError that names it; the unedited mesh reads back.
TEST(MeshCacheAdjacency, StoredAdjacencyOutOfRangeIsRefused) {
  const std::string source = CLOD_PACKAGE_DATA_DIR "/meshes/torus.obj";
  const TriangleMesh loaded = loadMesh(source);
  const std::uint64_t key = meshSourceKey(source, MeshLoadOptions());
  const std::string path =
      (std::filesystem::temp_directory_path() / ("clod_mesh_cache_range_" + std::to_string(::getpid()) + ".bin"))
          .string();
  const auto nt = static_cast<std::int32_t>(loaded.size());
  struct Edit {
    const char* what;
    void (*edit)(TriangleMesh&, std::int32_t);
  };
  const Edit edits[] = {
      {"neighbour", [](TriangleMesh& m, std::int32_t n) { m.neighbours[7][1] = n; }},
      {"neighbour", [](TriangleMesh& m, std::int32_t) { m.neighbours[0][0] = -2; }},
      {"corner's triangle",
       [](TriangleMesh& m, std::int32_t n) { m.cornerTriangles[5] = static_cast<std::uint32_t>(n); }},
      {"ascending", [](TriangleMesh& m, std::int32_t) { std::swap(m.cornerOffsets[3], m.cornerOffsets[4]); }},
      {"span", [](TriangleMesh& m, std::int32_t) { m.cornerOffsets.back() -= 1; }},
      {"angle", [](TriangleMesh& m, std::int32_t) { m.cornerAngles[2] = std::numeric_limits<float>::quiet_NaN(); }},
      // Found by fuzz_cache_read: a huge normal passed (finite) and overflowed an int in the placement's steps.
      {"normal", [](TriangleMesh& m, std::int32_t) { m.normals[4] *= 1e69; }},
      {"normal", [](TriangleMesh& m, std::int32_t) { m.normals[9] *= 0.5; }},
  };
  for (const Edit& e : edits) {
    TriangleMesh edited = loaded;
    e.edit(edited, nt);
    writeMeshBinary(edited, key, path);
    try {
      readMeshBinary(path, key);
      ADD_FAILURE() << "read back a mesh with a bad " << e.what;
    } catch (const FormatError& error) {
      EXPECT_NE(std::string(error.what()).find(e.what), std::string::npos) << error.what();
    }
  }
  writeMeshBinary(loaded, key, path);
  EXPECT_EQ(readMeshBinary(path, key).neighbours, loaded.neighbours);
  std::filesystem::remove(path);
}

// A mesh far from zero comes back from the cache with its local origin: the same model coordinates, bit for bit.
TEST(MeshCacheOrigin, FarMeshReadsBackWithItsOrigin) {
  const std::string dir =
      (std::filesystem::temp_directory_path() / ("clod_mesh_cache_origin_" + std::to_string(::getpid()))).string();
  std::filesystem::create_directories(dir);
  const std::string source = dir + "/far.off";
  {
    std::ofstream out(source);
    out.precision(17);
    out << "OFF\n4 4 0\n";
    for (const char* v : {"1000000.1 2e5 3", "1000001.3 2e5 3", "1000000.1 200001.7 3", "1000000.1 2e5 4.1"})
      out << v << "\n";
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
  for (std::size_t v = 0; v < read.vertices.size(); ++v)
    EXPECT_EQ(read.toModel(read.vertices[v]), loaded.toModel(loaded.vertices[v]));
  EXPECT_EQ(loaded.toModel(loaded.vertices[0]), Vec3(1000000.1, 2e5, 3));
}

}  // namespace
