// The disk cache of grids (the Grid fast level): a grid read back from its file makes a detector that answers
// bit for bit as one with a freshly built grid and as the brute force; SceneAssets reads the grid of a restart
// from the cache; truncated, flipped, stale and structurally corrupt files (with a valid checksum) are typed
// errors, rebuilt by the cache, never a crash.

#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <limits>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "cache_file_helpers.h"
#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/detector.h"
#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/grid_cache.h"
#include "clod_haptics/core/probes.h"
#include "clod_haptics/core/scene_assets.h"
#include "test_helpers.h"

namespace {

using namespace clod_haptics;
namespace fs = std::filesystem;

std::shared_ptr<const TriangleMesh> torus() {
  static const auto mesh =
      std::make_shared<const TriangleMesh>(loadMesh(std::string(CLOD_PACKAGE_DATA_DIR) + "/meshes/torus.obj"));
  return mesh;
}

using clod_test::fixChecksum;
using clod_test::readBytes;
using clod_test::TempDir;
using clod_test::writeBytes;

double ms(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - since).count();
}

/** A level (mesh, its set at d) and a grid radius, with the key of its grid file. */
struct Level {
  std::shared_ptr<const TriangleMesh> mesh;
  std::shared_ptr<const ClodSphereSet> set;
  GridCacheKey key;
};

Level makeLevel(std::shared_ptr<const TriangleMesh> mesh, double distanceFraction, double radiusFraction) {
  Level l;
  l.mesh = std::move(mesh);
  const double diagonal = l.mesh->bounds().diagonal().norm();
  l.set = std::make_shared<const ClodSphereSet>(ClodBuilder(l.mesh).build(distanceFraction * diagonal));
  l.key.meshHash = meshContentHash(*l.mesh);
  l.key.distance = l.set->distance;
  l.key.setHash = sphereSetHash(*l.set);
  l.key.radius = radiusFraction * diagonal;
  return l;
}

/** A Grid detector's parts with a grid of key's options: what the cache stores. */
ClodDetector::GridParts partsOf(const Level& l, const GridCacheKey& key, double radius) {
  return {CellGrid(*l.mesh, *l.set, radius, key.entriesPerTriangle, key.index),
          buildSphereTrees(*l.mesh, *l.set, meshBoxTreePad(*l.mesh))};
}

/**
 * Two detectors answer bit for bit alike, and like the brute force, on near-surface probes at the grid radius
 * and half of it (the grid's answers) and twice it (the hierarchy beyond the grid).
 */
void expectSameAnswers(const Level& l, const ClodDetector& built, const ClodDetector& cached) {
  const double r = l.key.radius;
  std::size_t contacts = 0;
  for (double radius : {r, 0.5 * r, 2.0 * r}) {
    const std::vector<Vec3> probes = nearSurfaceProbes(*l.mesh, 700, 1.5 * radius, 11);
    for (const Vec3& p : probes) {
      ContactResult a, b;
      built.query(p, radius, DetectionMode::Exact, a);
      cached.query(p, radius, DetectionMode::Exact, b);
      const ContactResult want = bruteForceQuery(*l.mesh, p, radius);
      ASSERT_EQ(b.contact, want.contact) << "r " << radius << " probe " << p.transpose();
      ASSERT_EQ(a.contact, b.contact);
      EXPECT_EQ(built.fastLevelHits(p, radius), cached.fastLevelHits(p, radius)) << "probe " << p.transpose();
      if (!want.contact) continue;
      ++contacts;
      EXPECT_EQ(b.distance, want.distance) << "probe " << p.transpose();
      EXPECT_EQ(a.distance, b.distance);
      EXPECT_EQ(a.triangle, b.triangle);
      EXPECT_EQ(a.sphere, b.sphere);
      EXPECT_EQ(a.point, b.point);
      EXPECT_EQ(a.normal, b.normal);
      EXPECT_EQ(a.depth, b.depth);
      EXPECT_EQ(a.inside, b.inside);
      EXPECT_EQ(a.spheresHit, b.spheresHit);
      EXPECT_EQ(a.trianglesTested, b.trianglesTested);
    }
    // Spheres mode reads the trees over the spheres (the gap tree) that the cache keeps beside the grid.
    for (const Vec3& p : probes) {
      ContactResult a, b;
      built.query(p, radius, DetectionMode::Spheres, a);
      cached.query(p, radius, DetectionMode::Spheres, b);
      ASSERT_EQ(a.contact, b.contact) << "spheres mode, probe " << p.transpose();
      EXPECT_EQ(a.sphere, b.sphere);
      EXPECT_EQ(a.distance, b.distance);
    }
  }
  EXPECT_GT(contacts, 300u);
}

bool sameNodes(const std::vector<BoxNode>& a, const std::vector<BoxNode>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(BoxNode)) == 0;
}

void roundTrip(const Level& l, const std::string& label) {
  SCOPED_TRACE(label);
  TempDir dir;
  const std::string path = dir.file("grid.clodgrid");
  for (CellGrid::Index index : {CellGrid::Index::Auto, CellGrid::Index::Dense, CellGrid::Index::Hashed}) {
    GridCacheKey key = l.key;
    key.index = index;
    auto start = std::chrono::steady_clock::now();
    const ClodDetector::GridParts parts = partsOf(l, key, key.radius);
    const CellGrid& grid = parts.grid;
    const double buildMs = ms(start);
    writeCellGridBinary(parts, key, l.mesh->size(), path);
    start = std::chrono::steady_clock::now();
    const ClodDetector::GridParts readParts = readCellGridBinary(path, key, *l.mesh, *l.set);
    const CellGrid& read = readParts.grid;
    const double readMs = ms(start);
    std::cout << "[ info     ] " << label << " " << l.mesh->size() << " triangles, index "
              << (grid.dense() ? "dense" : "hashed") << ": grid build " << buildMs << " ms, read " << readMs << " ms\n";
    EXPECT_EQ(read.dense(), grid.dense());
    EXPECT_EQ(read.cells(), grid.cells());
    EXPECT_EQ(read.entries(), grid.entries());
    EXPECT_EQ(read.largestCell(), grid.largestCell());
    const SphereTrees &a = parts.trees, &b = readParts.trees;
    EXPECT_TRUE(sameNodes(a.ballNodes, b.ballNodes) && a.ballOrder == b.ballOrder);
    EXPECT_TRUE(sameNodes(a.tightNodes, b.tightNodes) && a.tightOrder == b.tightOrder);
    EXPECT_TRUE(sameNodes(a.gapNodes, b.gapNodes) && a.gapOrder == b.gapOrder && a.gapRadius == b.gapRadius);
    const ClodDetector built(l.mesh, l.set, FastLevel::Grid, key.radius,
                             [&](double radius) { return partsOf(l, key, radius); });
    int sourced = 0;
    const ClodDetector cached(l.mesh, l.set, FastLevel::Grid, key.radius, [&](double radius) {
      ++sourced;
      EXPECT_EQ(radius, key.radius);
      return readCellGridBinary(path, key, *l.mesh, *l.set);
    });
    EXPECT_EQ(sourced, 1);
    expectSameAnswers(l, built, cached);
  }
}

TEST(GridCache, RoundTripAnswersAsTheBuiltGridAndTheBruteForce) {
  roundTrip(makeLevel(torus(), 0.01, 0.01), "torus");  // 697 spheres: trees of several levels
  roundTrip(makeLevel(clod_test::loadNormalized(clod_test::sharedMesh("elephant.off")), 0.02, 0.01), "elephant");
}

TEST(GridCache, DetectorRefusesAGridOfAnotherRadius) {
  const Level l = makeLevel(torus(), 0.02, 0.01);
  EXPECT_THROW(ClodDetector(l.mesh, l.set, FastLevel::Grid, l.key.radius,
                            [&](double radius) { return partsOf(l, l.key, 2.0 * radius); }),
               InvalidParameter);
}

// Trees over another level's spheres from a grid source are refused, typed, before any walk reads them.
TEST(GridCache, DetectorRefusesTreesOfAnotherLevel) {
  const Level l = makeLevel(torus(), 0.01, 0.01);
  const Level other = makeLevel(torus(), 0.005, 0.01);
  ASSERT_NE(l.set->size(), other.set->size());
  EXPECT_THROW(ClodDetector(l.mesh, l.set, FastLevel::Grid, l.key.radius,
                            [&](double radius) {
                              ClodDetector::GridParts parts = partsOf(l, l.key, radius);
                              parts.trees = partsOf(other, other.key, radius).trees;
                              return parts;
                            }),
               InvalidParameter);
}

// ---- SceneAssets: a restart reads the grid ----

TEST(GridCache, SceneAssetsRestartReadsTheGridFromTheCache) {
  TempDir dir;
  const double d = 0.003, radius = 0.004;
  SceneAssets::LevelInfo info;
  std::shared_ptr<const ClodDetector> first;
  {
    SceneAssets assets(std::make_shared<SphereSetCache>(dir.str()), FastLevel::Grid, radius);
    first = assets.level(torus(), d, &info);
    EXPECT_TRUE(assets.gridCached(torus(), d));
    EXPECT_FALSE(assets.gridCached(torus(), 0.005)) << "no grid for another distance yet";
    EXPECT_EQ(info.cache.source, CacheSource::Built);
    EXPECT_EQ(info.grid.source, CacheSource::Built);
    EXPECT_FALSE(info.gridFromCache());
    ASSERT_FALSE(info.grid.path.empty());
    EXPECT_TRUE(fs::exists(info.grid.path)) << info.grid.problem;
    EXPECT_EQ(fs::path(info.grid.path).parent_path(), fs::path(dir.str())) << "beside the sphere sets";
    // Shared in memory: no grid file looked up.
    assets.level(torus(), d, &info);
    EXPECT_TRUE(info.shared);
    EXPECT_TRUE(info.grid.path.empty());
    // Other fast levels have no grid.
    assets.level(torus(), d, FastLevel::Hierarchy, &info);
    EXPECT_TRUE(info.grid.path.empty());
  }
  // A restart: fresh assets over the same directory read both the set and the grid.
  SceneAssets restarted(std::make_shared<SphereSetCache>(dir.str()), FastLevel::Grid, radius);
  EXPECT_TRUE(restarted.gridCached(torus(), d)) << "what a node asks before it skips the quick hierarchy";
  const auto second = restarted.level(torus(), d, &info);
  EXPECT_EQ(info.cache.source, CacheSource::Hit);
  EXPECT_EQ(info.grid.source, CacheSource::Hit) << info.grid.problem;
  EXPECT_TRUE(info.gridFromCache());
  EXPECT_EQ(restarted.placements(), 0u) << "nothing built";
  EXPECT_EQ(second->gridRadius(), radius);
  Level l;
  l.mesh = torus();
  l.set = second->spheres();
  l.key.radius = radius;
  expectSameAnswers(l, *first, *second);

  // Another radius is another file, built then read.
  restarted.setGridRadius(0.006);
  EXPECT_FALSE(restarted.gridCached(torus(), d)) << "no grid of the new radius yet";
  restarted.level(torus(), d, &info);
  EXPECT_TRUE(restarted.gridCached(torus(), d));
  EXPECT_EQ(info.grid.source, CacheSource::Built);
  SceneAssets third(std::make_shared<SphereSetCache>(dir.str()), FastLevel::Grid, 0.006);
  third.level(torus(), d, &info);
  EXPECT_TRUE(info.gridFromCache());

  // Without a disk cache, no grid file.
  SceneAssets noCache(nullptr, FastLevel::Grid, radius);
  EXPECT_FALSE(noCache.gridCached(torus(), d));
  noCache.level(torus(), d, &info);
  EXPECT_TRUE(info.grid.path.empty());
  EXPECT_FALSE(info.gridFromCache());
  // Nor for a hierarchy-level store, whose detectors have no grid.
  EXPECT_FALSE(
      SceneAssets(std::make_shared<SphereSetCache>(dir.str()), FastLevel::Hierarchy, radius).gridCached(torus(), d));
}

// ---- Corrupt and stale files ----

class GridCacheFiles : public ::testing::Test {
 protected:
  // d = 1% of the diagonal: 697 spheres, so the trees over them have inner nodes to corrupt.
  static void SetUpTestSuite() { level_ = new Level(makeLevel(torus(), 0.01, 0.01)); }
  static void TearDownTestSuite() {
    delete level_;
    level_ = nullptr;
  }

  /** The grid of key through cache, counting builds. */
  ClodDetector::GridParts get(CellGridCache& cache, const GridCacheKey& key, CacheOutcome& outcome) {
    return cache.getOrBuild(
        *level_->mesh, *level_->set, key,
        [&] {
          ++builds_;
          return partsOf(*level_, key, key.radius);
        },
        &outcome);
  }

  /**
   * Stores the grid of key, edits its file with mutate, and checks that a fresh cache rejects it with a problem
   * containing why, rebuilds a grid that answers right, and stores a good file again.
   */
  void expectRejected(const std::function<void(std::vector<char>&)>& mutate, const std::string& why,
                      CellGrid::Index index = CellGrid::Index::Auto) {
    TempDir dir;
    GridCacheKey key = level_->key;
    key.index = index;
    CacheOutcome outcome;
    {
      CellGridCache cache(dir.str());
      get(cache, key, outcome);
      ASSERT_EQ(outcome.source, CacheSource::Built);
      ASSERT_TRUE(outcome.problem.empty()) << outcome.problem;
    }
    std::vector<char> bytes = readBytes(outcome.path);
    mutate(bytes);
    writeBytes(outcome.path, bytes);
    // The reader alone: a typed error naming why.
    try {
      readCellGridBinary(outcome.path, key, *level_->mesh, *level_->set);
      ADD_FAILURE() << "the edited file was accepted (expected: " << why << ")";
    } catch (const FormatError& e) {
      EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
    }
    // The cache: rejected, rebuilt, stored again.
    CellGridCache restarted(dir.str());
    const int before = builds_;
    ClodDetector::GridParts grid = get(restarted, key, outcome);
    EXPECT_EQ(outcome.source, CacheSource::Rebuilt);
    EXPECT_NE(outcome.problem.find(why), std::string::npos) << outcome.problem;
    EXPECT_EQ(builds_, before + 1);
    EXPECT_EQ(restarted.rejected(), 1u);
    ClodDetector detector(level_->mesh, level_->set, FastLevel::Grid, key.radius,
                          [&](double) { return std::move(grid); });
    const ClodDetector fresh(level_->mesh, level_->set, FastLevel::Grid, key.radius);
    expectSameAnswers(*level_, fresh, detector);
    CellGridCache third(dir.str());
    get(third, key, outcome);
    EXPECT_EQ(outcome.source, CacheSource::Hit) << outcome.problem;
  }

  // Offsets in a grid file: magic 8, version 4, byte order 4, mesh hash 8, distance 8, set hash 8, radius 8,
  // entries per triangle 8, index 1, triangles 8; then the grid's 10 doubles, 3 dimensions, the cell count, the
  // 5 array sizes, and the arrays.
  static constexpr std::size_t kMeshHash = 16, kRadius = 40, kTriangles = 57, kGrid = 65;
  static constexpr std::size_t kCellSize = kGrid + 8, kCells = kGrid + 104, kSizes = kGrid + 112, kArrays = kGrid + 152;
  static std::uint64_t u64(const std::vector<char>& b, std::size_t at) {
    std::uint64_t v;
    std::memcpy(&v, b.data() + at, 8);
    return v;
  }
  template <class T>
  static void set(std::vector<char>& b, std::size_t at, T v) {
    std::memcpy(b.data() + at, &v, sizeof v);
  }
  /** Offset of array k (0 entries, 1 words, 2 refs, 3 headers, 4 slots). */
  static std::size_t arrayAt(const std::vector<char>& b, int k) {
    const std::size_t sizes[5] = {8, 16, 8, 4, 24};
    std::size_t at = kArrays;
    for (int i = 0; i < k; ++i) at += u64(b, kSizes + 8 * i) * sizes[i];
    return at;
  }
  /** Offset of the trees' 7 sizes (after the grid's arrays), then of tree array k (0 ball nodes, 1 ball order, 2
   * tight nodes, 3 tight order, 4 gap nodes, 5 gap order, 6 gap radii). */
  static std::size_t treeSizesAt(const std::vector<char>& b) { return arrayAt(b, 5); }
  static std::size_t treeArrayAt(const std::vector<char>& b, int k) {
    const std::size_t sizes[7] = {32, 4, 32, 4, 32, 4, 4};
    std::size_t at = treeSizesAt(b) + 56;
    for (int i = 0; i < k; ++i) at += u64(b, treeSizesAt(b) + 8 * i) * sizes[i];
    return at;
  }

  static Level* level_;
  int builds_ = 0;
};
Level* GridCacheFiles::level_ = nullptr;

TEST_F(GridCacheFiles, TruncatedFileIsRebuilt) {
  expectRejected([](std::vector<char>& b) { b.resize(b.size() - 100); }, "checksum");
  expectRejected([](std::vector<char>& b) { b.resize(b.size() / 2); }, "checksum");
  expectRejected([](std::vector<char>& b) { b.resize(5); }, "too short");
  expectRejected([](std::vector<char>& b) { b.clear(); }, "too short");
}

TEST_F(GridCacheFiles, FlippedByteIsRebuilt) {
  expectRejected([](std::vector<char>& b) { b[b.size() / 2] ^= 0x10; }, "checksum");
  expectRejected([](std::vector<char>& b) { b[kGrid + 3] ^= 0x01; }, "checksum");
}

TEST_F(GridCacheFiles, StaleFilesAreRebuilt) {
  expectRejected(
      [](std::vector<char>& b) {
        set<std::uint32_t>(b, 8, kGridCacheFormatVersion + 1);
        fixChecksum(b);
      },
      "format version");
  expectRejected(
      [](std::vector<char>& b) {
        b[kMeshHash] ^= 1;
        fixChecksum(b);
      },
      "another mesh");
  expectRejected(
      [](std::vector<char>& b) {
        set<double>(b, kRadius, 0.5);
        fixChecksum(b);
      },
      "grid radius");
  expectRejected(
      [](std::vector<char>& b) {
        b[0] = 'X';
        fixChecksum(b);
      },
      "not a clod_haptics grid cache file");
}

TEST_F(GridCacheFiles, FileOfAnotherMeshOrSetIsRefused) {
  TempDir dir;
  const std::string path = dir.file("g.clodgrid");
  writeCellGridBinary(partsOf(*level_, level_->key, level_->key.radius), level_->key, level_->mesh->size(), path);
  GridCacheKey other = level_->key;
  other.setHash ^= 1;
  EXPECT_THROW(readCellGridBinary(path, other, *level_->mesh, *level_->set), FormatError);
  other = level_->key;
  other.entriesPerTriangle = 12.0;
  EXPECT_THROW(readCellGridBinary(path, other, *level_->mesh, *level_->set), FormatError);
  const auto head = clod_test::loadNormalized(clod_test::sharedMesh("head.off"));
  EXPECT_THROW(readCellGridBinary(path, level_->key, *head, *level_->set), FormatError)
      << "another mesh's triangle count";
  EXPECT_THROW(readCellGridBinary(dir.file("missing.clodgrid"), level_->key, *level_->mesh, *level_->set), FormatError);
}

// Edits behind a valid checksum: the range checks alone stand between the file and an out-of-bounds read.
TEST_F(GridCacheFiles, StructuralCorruptionIsATypedError) {
  const auto triangles = static_cast<std::uint32_t>(level_->mesh->size());
  auto edit = [](std::function<void(std::vector<char>&)> change) {
    return [change](std::vector<char>& b) {
      change(b);
      fixChecksum(b);
    };
  };
  expectRejected(edit([](std::vector<char>& b) { set<double>(b, kCellSize, std::nan("")); }), "not finite");
  expectRejected(edit([](std::vector<char>& b) { set<std::int64_t>(b, kGrid + 80, 0); }), "dimensions");
  // One more entry than written: the grid's arrays shift into the trees' section (or past the file's end).
  expectRejected(edit([](std::vector<char>& b) { set<std::uint64_t>(b, kSizes, u64(b, kSizes) + 1); }),
                 "does not match");
  expectRejected(edit([](std::vector<char>& b) { set<std::uint64_t>(b, kSizes, u64(b, kSizes) + 1000000); }),
                 "array sizes");
  expectRejected(edit([](std::vector<char>& b) { set<std::uint64_t>(b, kCells, u64(b, kCells) + 1); }), "cell count");
  // A candidate's triangle past the mesh; a header whose count runs past the entries.
  expectRejected(edit([&](std::vector<char>& b) { set<std::uint32_t>(b, arrayAt(b, 0) + 8, triangles); }),
                 "out of range");
  expectRejected(edit([](std::vector<char>& b) { set<std::uint32_t>(b, arrayAt(b, 0), 0xfffffff0u); }),
                 "header out of range");
  // The dense index: a rank, a header position.
  expectRejected(edit([](std::vector<char>& b) { set<std::uint32_t>(b, arrayAt(b, 1) + 16 * 3 + 8, 7u); }), "ranks",
                 CellGrid::Index::Dense);
  expectRejected(edit([](std::vector<char>& b) { set<std::uint32_t>(b, arrayAt(b, 3) + 4, 1u); }), "index header",
                 CellGrid::Index::Dense);
  // The hash table: a header pointing at a candidate, a key moved off its probe chain, a full table.
  auto firstOccupied = [](const std::vector<char>& b) {
    std::size_t at = arrayAt(b, 4);
    while (u64(b, at) == CellGrid::kOutside) at += 24;
    return at;
  };
  expectRejected(edit([&](std::vector<char>& b) { set<std::uint64_t>(b, firstOccupied(b) + 8, 1u); }), "not a cell's",
                 CellGrid::Index::Hashed);
  expectRejected(edit([&](std::vector<char>& b) {
                   // Swap the first occupied slot with the free slot just before its chain start cannot be
                   // described portably; flipping a key's low bit sends it to another chain.
                   const std::size_t at = firstOccupied(b);
                   set<std::uint64_t>(b, at, u64(b, at) ^ 1u);
                 }),
                 "hash table", CellGrid::Index::Hashed);
  expectRejected(edit([](std::vector<char>& b) {
                   const std::size_t slots = u64(b, kSizes + 32), at = arrayAt(b, 4);
                   for (std::size_t s = 0; s < slots; ++s)
                     if (u64(b, at + 24 * s) == CellGrid::kOutside) set<std::uint64_t>(b, at + 24 * s, 5u);
                 }),
                 "hash table", CellGrid::Index::Hashed);
  // The trees over the spheres: a ball leaf's box shrunk, an order entry out of range, the tight tree's root made a
  // leaf over everything but its children left, a gap radius cut, the radii's count off.
  auto firstLeaf = [](const std::vector<char>& b, std::size_t nodes) {
    std::size_t at = nodes;
    while (u64(b, at + 24) >> 32 == 0) at += 32;  // count (the second half of the last 8 bytes) 0: inner
    return at;
  };
  expectRejected(edit([&](std::vector<char>& b) {
                   const std::size_t leaf = firstLeaf(b, treeArrayAt(b, 0));
                   float lo;
                   std::memcpy(&lo, b.data() + leaf, 4);
                   set<float>(b, leaf, lo + 1.0f);
                 }),
                 "ball tree");
  expectRejected(edit([&](std::vector<char>& b) { set<std::uint32_t>(b, treeArrayAt(b, 1), 0x7fffffffu); }),
                 "ball tree");
  expectRejected(edit([&](std::vector<char>& b) {
                   const std::size_t root = treeArrayAt(b, 2);
                   set<std::uint32_t>(b, root + 24, 0u);
                   set<std::uint32_t>(b, root + 28, static_cast<std::uint32_t>(u64(b, treeSizesAt(b) + 24)));
                 }),
                 "tight tree");
  expectRejected(edit([&](std::vector<char>& b) { set<float>(b, treeArrayAt(b, 6), 0.0f); }), "gap tree");
  expectRejected(edit([&](std::vector<char>& b) { set<std::uint64_t>(b, treeSizesAt(b) + 48, 1u); }), "array sizes");
}

// The grid files stay within the cache's byte budget: the least recently used go first, a hit makes a file
// recent, the file just stored always stays, and the sphere sets beside them are never touched.
TEST_F(GridCacheFiles, GridFilesStayWithinTheByteBudget) {
  TempDir dir;
  CacheOutcome outcome;
  GridCacheKey key = level_->key;
  std::uint64_t oneFile = 0;
  {
    CellGridCache probe(dir.str());
    get(probe, key, outcome);
    oneFile = std::filesystem::file_size(outcome.path);
  }
  const std::string sphereFile = dir.file("mesh-beside.clodsph");
  writeBytes(sphereFile, std::vector<char>(3 * oneFile, 'x'));  // not a grid file: never counted nor deleted
  // A budget of two and a half grids: the third store drops the least recently used one.
  CellGridCache cache(dir.str(), oneFile * 5 / 2);
  std::vector<std::string> paths;
  for (double scale : {1.0, 1.25, 1.5}) {
    key.radius = level_->key.radius * scale;
    get(cache, key, outcome);
    paths.push_back(outcome.path);
    if (scale == 1.25) {  // a hit on the first file makes it the most recent one
      key.radius = level_->key.radius;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));  // file times are coarse on some file systems
      get(cache, key, outcome);
      EXPECT_EQ(outcome.source, CacheSource::Hit);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_TRUE(std::filesystem::exists(paths[0])) << "the recently read grid was deleted";
  EXPECT_FALSE(std::filesystem::exists(paths[1])) << "the least recently used grid stayed beyond the budget";
  EXPECT_TRUE(std::filesystem::exists(paths[2])) << "the grid just stored was deleted";
  EXPECT_TRUE(std::filesystem::exists(sphereFile));
  // A budget smaller than one grid keeps the one just stored.
  CellGridCache tiny(dir.str(), 1);
  key.radius = level_->key.radius * 2.0;
  get(tiny, key, outcome);
  EXPECT_TRUE(std::filesystem::exists(outcome.path));
  std::size_t grids = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir.str())) grids += e.path().extension() == ".clodgrid";
  EXPECT_EQ(grids, 1u);
}
// Not a timed test: prints build and read times on the shared meshes (run with --gtest_also_run_disabled_tests).
TEST(GridCache, DISABLED_Timing) {
  for (const char* name : {"refined_elephant.off", "mannequin-devil.off"}) {
    const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh(name));
    const double d = 0.003, radius = 0.005;
    TempDir dir;
    double cold = 0.0, warm = 0.0, coldGrid = 0.0, warmGrid = 0.0;
    for (int pass = 0; pass < 2; ++pass) {
      SceneAssets assets(std::make_shared<SphereSetCache>(dir.str()), FastLevel::Grid, radius);
      SceneAssets::LevelInfo info;
      const auto start = std::chrono::steady_clock::now();
      assets.level(mesh, d, &info);
      (pass == 0 ? cold : warm) = ms(start);
      (pass == 0 ? coldGrid : warmGrid) = info.grid.ms;
      std::cout << "[ timing   ] " << name << (pass == 0 ? " cold" : " warm") << ": sphere set " << info.cache.ms
                << " ms, detector " << info.detectorMs << " ms (grid " << info.grid.ms << " ms)\n";
      EXPECT_EQ(info.gridFromCache(), pass == 1);
    }
    {  // What the warm detector spends beside the grid: the hierarchy's trees (the fallback beyond the grid radius).
      SceneAssets assets(std::make_shared<SphereSetCache>(dir.str()), FastLevel::Grid, radius);
      const auto set = assets.spheres(mesh, d);
      auto start = std::chrono::steady_clock::now();
      const std::uint64_t h = sphereSetHash(*set);
      const double hashMs = ms(start);
      start = std::chrono::steady_clock::now();
      const ClodDetector hierarchy(mesh, set, FastLevel::Hierarchy);
      std::cout << "[ timing   ] " << name << ": hierarchy detector " << ms(start) << " ms, set hash " << hashMs
                << " ms (" << (h != 0) << ")\n";
    }
    std::cout << "[ timing   ] " << name << " (" << mesh->size() << " triangles): grid build " << coldGrid
              << " ms, read " << warmGrid << " ms (" << coldGrid / warmGrid << "x); level() cold " << cold
              << " ms, warm " << warm << " ms (" << cold / warm << "x)\n";
  }
}

}  // namespace
