// The disk cache of CLOD levels: content hash, binary round trip, a restart that reuses the files
// without building, and stale or corrupt files that are detected, deleted and rebuilt.

#include <gtest/gtest.h>

#include <atomic>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <unistd.h>

#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/detector.h"
#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/mesh_cache.h"
#include "clod_haptics/core/probes.h"
#include "clod_haptics/core/scene_assets.h"
#include "clod_haptics/core/sphere_cache.h"
#include "cache_file_helpers.h"
#include "test_helpers.h"

namespace {

using namespace clod_haptics;
namespace fs = std::filesystem;

std::string torusPath() { return std::string(CLOD_PACKAGE_DATA_DIR) + "/meshes/torus.obj"; }

using clod_test::TempDir;
using clod_test::readBytes;
using clod_test::writeBytes;
using clod_test::fixChecksum;

void expectSameSet(const ClodSphereSet& a, const ClodSphereSet& b) {
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(a.meshName, b.meshName);
  EXPECT_EQ(a.distance, b.distance);
  EXPECT_EQ(a.scale, b.scale);
  EXPECT_EQ(a.offsets, b.offsets);
  EXPECT_EQ(a.triangles, b.triangles);
  EXPECT_EQ(a.radii, b.radii);
  for (std::size_t i = 0; i < a.size(); ++i) ASSERT_EQ(a.centres[i], b.centres[i]) << "sphere " << i;
  EXPECT_EQ(a.stats.centres, b.stats.centres);
  EXPECT_EQ(a.stats.spheres, b.stats.spheres);
  EXPECT_EQ(a.stats.triangles, b.stats.triangles);
}

class SphereCacheTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    mesh_ = std::make_shared<const TriangleMesh>(loadMesh(torusPath()));
    builder_ = std::make_shared<const ClodBuilder>(mesh_);
  }
  static void TearDownTestSuite() {
    builder_.reset();
    mesh_.reset();
  }
  /** A build function that counts its calls. */
  std::function<ClodSphereSet()> counted(double d) {
    return [this, d] {
      ++builds_;
      return builder_->build(d);
    };
  }
  static std::shared_ptr<const TriangleMesh> mesh_;
  static std::shared_ptr<const ClodBuilder> builder_;
  int builds_ = 0;
  const double d_ = 0.003;
};
std::shared_ptr<const TriangleMesh> SphereCacheTest::mesh_;
std::shared_ptr<const ClodBuilder> SphereCacheTest::builder_;

TEST_F(SphereCacheTest, ContentHashFollowsGeometryNotName) {
  const std::uint64_t h = meshContentHash(*mesh_);
  TriangleMesh renamed = *mesh_;
  renamed.name = "another name";
  EXPECT_EQ(h, meshContentHash(renamed));
  EXPECT_EQ(h, meshContentHash(loadMesh(torusPath())));  // loading is deterministic

  TriangleMesh moved = *mesh_;
  moved.vertices[17].x() = std::nextafter(moved.vertices[17].x(), 1.0);  // one ulp of one coordinate
  EXPECT_NE(h, meshContentHash(moved));
  TriangleMesh rewound = *mesh_;
  std::swap(rewound.triangles[3][1], rewound.triangles[3][2]);
  EXPECT_NE(h, meshContentHash(rewound));
  MeshLoadOptions scaled;
  scaled.scale = 2.0;
  EXPECT_NE(h, meshContentHash(loadMesh(torusPath(), scaled)));
}

TEST_F(SphereCacheTest, BinaryRoundTripIsExact) {
  TempDir dir;
  const ClodSphereSet set = builder_->build(d_);
  const std::string path = dir.str() + "/set.clodsph";
  const std::uint64_t h = meshContentHash(*mesh_);
  writeSphereSetBinary(set, h, path);
  expectSameSet(set, readSphereSetBinary(path, h, d_, *mesh_));
}

TEST_F(SphereCacheTest, RestartReusesTheCacheWithoutBuilding) {
  TempDir dir;
  const std::uint64_t h = meshContentHash(*mesh_);
  std::shared_ptr<const ClodSphereSet> first;
  {
    SphereSetCache cache(dir.str());
    CacheOutcome outcome;
    first = cache.getOrBuild(*mesh_, h, d_, counted(d_), &outcome);
    EXPECT_EQ(outcome.source, CacheSource::Built);
    EXPECT_TRUE(outcome.problem.empty()) << outcome.problem;
    EXPECT_EQ(builds_, 1);
    EXPECT_TRUE(fs::is_regular_file(outcome.path));
    // Another level of the same mesh is another file.
    cache.getOrBuild(*mesh_, h, 0.02, counted(0.02), &outcome);
    EXPECT_EQ(builds_, 2);
  }
  // "Restart": a new cache object on the same directory finds both files and builds nothing.
  SphereSetCache restarted(dir.str());
  CacheOutcome outcome;
  auto again = restarted.getOrBuild(*mesh_, h, d_, counted(d_), &outcome);
  EXPECT_EQ(outcome.source, CacheSource::Hit);
  EXPECT_EQ(builds_, 2);
  EXPECT_EQ(restarted.hits(), 1u);
  expectSameSet(*first, *again);
  restarted.getOrBuild(*mesh_, h, 0.02, counted(0.02), &outcome);
  EXPECT_EQ(outcome.source, CacheSource::Hit);
  EXPECT_EQ(builds_, 2);

  // The cached level answers exactly as the built one, which matches the reference.
  ClodDetector fromCache(mesh_, again, FastLevel::Grid, 0.002);
  ClodDetector fromBuild(mesh_, first, FastLevel::Grid, 0.002);
  for (const Vec3& p : nearSurfaceProbes(*mesh_, 3000, 0.004, 7)) {
    ContactResult a, b;
    fromCache.query(p, 0.002, DetectionMode::Exact, a);
    fromBuild.query(p, 0.002, DetectionMode::Exact, b);
    const ContactResult ref = bruteForceQuery(*mesh_, p, 0.002);
    ASSERT_EQ(a.contact, b.contact);
    ASSERT_EQ(a.distance, b.distance);
    if (std::abs(ref.distance - 0.002) > 1e-12) {
      ASSERT_EQ(a.contact, ref.contact) << p.transpose();
    }
    if (a.contact) {
      ASSERT_NEAR(a.distance, ref.distance, 1e-12);
    }
  }
}

/** Writes a valid cache file, damages it with edit, and checks getOrBuild rejects, deletes and rebuilds it. */
void expectRejected(SphereCacheTest& t, const std::function<void(std::vector<char>&)>& edit, const std::string& why,
                    const std::shared_ptr<const TriangleMesh>& mesh, double d, int& builds,
                    const std::function<ClodSphereSet()>& build) {
  TempDir dir;
  const std::uint64_t h = meshContentHash(*mesh);
  SphereSetCache cache(dir.str());
  CacheOutcome outcome;
  auto good = cache.getOrBuild(*mesh, h, d, build, &outcome);
  ASSERT_EQ(outcome.source, CacheSource::Built);
  std::vector<char> bytes = readBytes(outcome.path);
  edit(bytes);
  writeBytes(outcome.path, bytes);
  EXPECT_THROW(readSphereSetBinary(outcome.path, h, d, *mesh), FormatError);

  const int before = builds;
  SphereSetCache restarted(dir.str());
  auto rebuilt = restarted.getOrBuild(*mesh, h, d, build, &outcome);
  EXPECT_EQ(outcome.source, CacheSource::Rebuilt);
  EXPECT_NE(outcome.problem.find(why), std::string::npos) << "problem: " << outcome.problem;
  EXPECT_EQ(builds, before + 1) << "a rejected file must be rebuilt";
  EXPECT_EQ(restarted.rejected(), 1u);
  expectSameSet(*good, *rebuilt);
  // The rebuilt file replaced the bad one: the next start hits.
  SphereSetCache third(dir.str());
  third.getOrBuild(*mesh, h, d, build, &outcome);
  EXPECT_EQ(outcome.source, CacheSource::Hit);
  EXPECT_EQ(builds, before + 1);
  (void)t;
}

TEST_F(SphereCacheTest, FlippedByteIsDetectedAndRebuilt) {
  expectRejected(*this, [](std::vector<char>& b) { b[b.size() / 2] ^= 0x10; }, "checksum", mesh_, d_, builds_,
                 counted(d_));
}

TEST_F(SphereCacheTest, TruncatedFileIsDetectedAndRebuilt) {
  expectRejected(*this, [](std::vector<char>& b) { b.resize(b.size() - 100); }, "checksum", mesh_, d_, builds_,
                 counted(d_));
  expectRejected(*this, [](std::vector<char>& b) { b.resize(5); }, "too short", mesh_, d_, builds_, counted(d_));
}

TEST_F(SphereCacheTest, OtherFormatVersionIsStale) {
  expectRejected(*this,
                 [](std::vector<char>& b) {
                   const std::uint32_t old = kSphereCacheFormatVersion + 1;
                   std::memcpy(b.data() + 8, &old, 4);
                   fixChecksum(b);
                 },
                 "format version", mesh_, d_, builds_, counted(d_));
}

TEST_F(SphereCacheTest, OtherMeshHashIsStale) {
  expectRejected(*this,
                 [](std::vector<char>& b) {
                   b[16] ^= 1;  // the mesh hash follows magic (8), version (4) and byte order (4)
                   fixChecksum(b);
                 },
                 "another mesh", mesh_, d_, builds_, counted(d_));
}

TEST_F(SphereCacheTest, SetThatDoesNotCoverTheMeshIsRejected) {
  // A consistent file (checksum right) whose first radius was shrunk: it would miss contacts.
  expectRejected(*this,
                 [this](std::vector<char>& b) {
                   const ClodSphereSet set = builder_->build(d_);
                   const std::size_t header = 8 + 4 + 4 + 8 + 8 + 8 + 8 + 8 + 8 + 8 + 5 * 8 + 3 * 8;
                   const std::size_t radius0 = header + set.size() * sizeof(Vec3);
                   double r;
                   std::memcpy(&r, b.data() + radius0, 8);
                   ASSERT_EQ(r, set.radii[0]);
                   r *= 0.5;
                   std::memcpy(b.data() + radius0, &r, 8);
                   fixChecksum(b);
                 },
                 "sticks out of sphere", mesh_, d_, builds_, counted(d_));
}

TEST_F(SphereCacheTest, FileOfAnotherDistanceUnderThisNameIsStale) {
  TempDir dir;
  const std::uint64_t h = meshContentHash(*mesh_);
  SphereSetCache cache(dir.str());
  CacheOutcome outcome;
  cache.getOrBuild(*mesh_, h, 0.02, counted(0.02), &outcome);
  fs::copy_file(outcome.path, cache.pathFor(h, d_));
  auto set = cache.getOrBuild(*mesh_, h, d_, counted(d_), &outcome);
  EXPECT_EQ(outcome.source, CacheSource::Rebuilt);
  EXPECT_NE(outcome.problem.find("clustering distance"), std::string::npos) << outcome.problem;
  EXPECT_EQ(set->distance, d_);
  EXPECT_EQ(builds_, 2);
}

TEST_F(SphereCacheTest, BadDistanceThrowsWithoutBuilding) {
  TempDir dir;
  SphereSetCache cache(dir.str());
  EXPECT_THROW(cache.getOrBuild(*mesh_, 1, -0.1, counted(-0.1)), InvalidParameter);
  EXPECT_THROW(cache.getOrBuild(*mesh_, 1, std::nan(""), counted(0)), InvalidParameter);
  EXPECT_EQ(builds_, 0);
}

TEST_F(SphereCacheTest, UnwritableDirectoryStillAnswers) {
  TempDir dir;
  const std::string file = dir.str() + "/not_a_directory";
  writeBytes(file, {'x'});
  SphereSetCache cache(file + "/sub");  // cannot be created: a file is in the way
  CacheOutcome outcome;
  auto set = cache.getOrBuild(*mesh_, meshContentHash(*mesh_), d_, counted(d_), &outcome);
  ASSERT_TRUE(set);
  EXPECT_EQ(set->distance, d_);
  EXPECT_NE(outcome.problem.find("not stored"), std::string::npos);
}

TEST(SceneAssets, SharesMeshesAndLevelsAndRestartsFromTheCache) {
  TempDir dir;
  std::shared_ptr<const ClodDetector> first;
  {
    SceneAssets assets(std::make_shared<SphereSetCache>(dir.str()), FastLevel::Grid, 0.002);
    auto a = assets.mesh(torusPath());
    auto b = assets.mesh(torusPath());
    EXPECT_EQ(a.get(), b.get());  // same file, same options: loaded once
    MeshLoadOptions scaled;
    scaled.scale = 0.5;
    auto c = assets.mesh(torusPath(), scaled);
    EXPECT_NE(a.get(), c.get());
    SceneAssets::LevelInfo info;
    first = assets.level(a, 0.003, &info);
    EXPECT_EQ(info.cache.source, CacheSource::Built);
    auto again = assets.level(b, 0.003, &info);
    EXPECT_TRUE(info.shared);
    EXPECT_EQ(first.get(), again.get());
    assets.level(a, 0.01, &info);  // another level of the same mesh: the builder is reused
    assets.level(c, 0.003, &info);
    EXPECT_EQ(assets.placements(), 2u);  // one ray-cast placement per distinct mesh
    // Another fast level of a known level: the same sphere set, no disk access, a new detector.
    const auto hitsBefore = assets.cache()->hits() + assets.cache()->misses();
    auto hierarchy = assets.level(a, 0.003, FastLevel::Hierarchy, &info);
    EXPECT_TRUE(info.shared);
    EXPECT_EQ(hierarchy->fastLevel(), FastLevel::Hierarchy);
    EXPECT_EQ(first->fastLevel(), FastLevel::Grid);
    EXPECT_EQ(hierarchy->spheres().get(), first->spheres().get());
    EXPECT_EQ(assets.cache()->hits() + assets.cache()->misses(), hitsBefore);
    EXPECT_THROW(assets.level(a, -1.0), InvalidParameter);
    EXPECT_THROW(assets.mesh("/nonexistent/mesh.obj"), MeshLoadError);
  }
  SceneAssets restarted(std::make_shared<SphereSetCache>(dir.str()), FastLevel::Grid, 0.002);
  auto mesh = restarted.mesh(torusPath());
  SceneAssets::LevelInfo info;
  auto set = restarted.spheres(mesh, 0.003, &info);  // what a restarted node reads first
  EXPECT_EQ(info.cache.source, CacheSource::Hit);
  EXPECT_FALSE(info.shared);
  auto level = restarted.level(mesh, 0.003, &info);
  EXPECT_TRUE(info.shared);
  EXPECT_EQ(level->spheres().get(), set.get());
  EXPECT_EQ(restarted.placements(), 0u) << "a restart must not run the placement again";
  expectSameSet(*first->spheres(), *level->spheres());
}

void expectSameMesh(const TriangleMesh& a, const TriangleMesh& b) {
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.scale, b.scale);
  EXPECT_EQ(a.offset, b.offset);
  EXPECT_EQ(a.flipped, b.flipped);
  ASSERT_EQ(a.vertices.size(), b.vertices.size());
  ASSERT_EQ(a.triangles, b.triangles);
  ASSERT_EQ(a.normals.size(), b.normals.size());
  for (std::size_t i = 0; i < a.vertices.size(); ++i) ASSERT_EQ(a.vertices[i], b.vertices[i]);
  for (std::size_t i = 0; i < a.normals.size(); ++i) ASSERT_EQ(a.normals[i], b.normals[i]);
}

TEST(MeshCache, RestartReadsTheLoadedMeshBack) {
  TempDir dir;
  MeshLoadOptions options;
  options.scale = 0.5;
  const TriangleMesh parsed = loadMesh(torusPath(), options);
  {
    MeshCache cache(dir.str());
    CacheOutcome outcome;
    expectSameMesh(parsed, cache.load(torusPath(), options, &outcome));
    EXPECT_EQ(outcome.source, CacheSource::Built);
    EXPECT_TRUE(outcome.problem.empty()) << outcome.problem;
    EXPECT_EQ(cache.parsed(), 1u);
  }
  MeshCache restarted(dir.str());
  CacheOutcome outcome;
  const TriangleMesh cached = restarted.load(torusPath(), options, &outcome);
  EXPECT_EQ(outcome.source, CacheSource::Hit);
  EXPECT_EQ(restarted.parsed(), 0u) << "a restart must not parse the file again";
  expectSameMesh(parsed, cached);
  EXPECT_EQ(meshContentHash(parsed), meshContentHash(cached));  // so the sphere cache hits as well
  // Other load options are another entry.
  restarted.load(torusPath(), MeshLoadOptions{}, &outcome);
  EXPECT_EQ(outcome.source, CacheSource::Built);
}

TEST(MeshCache, EditedSourceFileIsNeverServedFromTheOldEntry) {
  TempDir dir;
  const std::string copy = dir.str() + "/model.obj";
  fs::copy_file(torusPath(), copy);
  MeshCache cache(dir.str() + "/cache");
  CacheOutcome outcome;
  cache.load(copy, {}, &outcome);
  EXPECT_EQ(outcome.source, CacheSource::Built);
  // Move one vertex in the file: the key changes, the new geometry is parsed.
  std::ifstream in(copy);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  in.close();
  const std::size_t at = text.find("\nv ");
  ASSERT_NE(at, std::string::npos);
  text.replace(at, 3, "\nv 1");  // the first vertex's x, 0.082, becomes 10.082
  std::ofstream(copy, std::ios::trunc) << text;
  const TriangleMesh edited = cache.load(copy, {}, &outcome);
  EXPECT_EQ(outcome.source, CacheSource::Built);
  expectSameMesh(loadMesh(copy), edited);
}

TEST(MeshCache, CorruptFileIsRebuiltAndMissingFileThrows) {
  TempDir dir;
  MeshCache cache(dir.str());
  CacheOutcome outcome;
  const TriangleMesh first = cache.load(torusPath(), {}, &outcome);
  std::vector<char> bytes = readBytes(outcome.path);
  bytes[bytes.size() / 3] ^= 0x40;
  writeBytes(outcome.path, bytes);
  EXPECT_THROW(readMeshBinary(outcome.path, meshSourceKey(torusPath(), {})), FormatError);
  const TriangleMesh again = cache.load(torusPath(), {}, &outcome);
  EXPECT_EQ(outcome.source, CacheSource::Rebuilt);
  EXPECT_NE(outcome.problem.find("checksum"), std::string::npos) << outcome.problem;
  EXPECT_EQ(cache.rejected(), 1u);
  expectSameMesh(first, again);
  EXPECT_THROW(cache.load(dir.str() + "/no_such_mesh.obj"), MeshLoadError);
}

}  // namespace

namespace {

// The levels of each clustering strategy go to a directory of their own (file names do not name the strategy):
// single-link's is the cache directory itself, the others' a subdirectory; an empty directory is the default one.
TEST(SphereCacheDirectory, EachStrategyHasItsOwnDirectory) {
  using clod_haptics::defaultSphereCacheDirectory;
  using clod_haptics::sphereCacheDirectoryFor;
  EXPECT_EQ(sphereCacheDirectoryFor("/tmp/c", "single-link"), "/tmp/c");
  EXPECT_EQ(sphereCacheDirectoryFor("/tmp/c", "tight"), "/tmp/c/tight");
  EXPECT_EQ(sphereCacheDirectoryFor("/tmp/c", "cube"), "/tmp/c/cube");
  EXPECT_EQ(sphereCacheDirectoryFor("", "single-link"), defaultSphereCacheDirectory());
  EXPECT_EQ(sphereCacheDirectoryFor("", "tight"), defaultSphereCacheDirectory() + "/tight");
}

}  // namespace
