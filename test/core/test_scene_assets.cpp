// SceneAssets: the grid radius of the detectors it builds follows setGridRadius (the pointer radius a node
// is reconfigured to), without touching detectors already handed out; every answer equals the brute force.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>

#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/probes.h"
#include "clod_haptics/core/scene_assets.h"
#include "test_helpers.h"

namespace {

using namespace clod_haptics;

std::shared_ptr<const TriangleMesh> torus() {
  static const auto mesh =
      std::make_shared<const TriangleMesh>(loadMesh(std::string(CLOD_PACKAGE_DATA_DIR) + "/meshes/torus.obj"));
  return mesh;
}

void expectBruteForceAnswers(const ClodDetector& detector, double r) {
  std::size_t contacts = 0;
  for (const Vec3& p : nearSurfaceProbes(*torus(), 600, 2.0 * r, 3)) {
    ContactResult got;
    detector.query(p, r, DetectionMode::Exact, got);
    const ContactResult want = bruteForceQuery(*torus(), p, r);
    ASSERT_EQ(got.contact, want.contact) << "r " << r << " probe " << p.transpose();
    if (!want.contact) continue;
    ++contacts;
    EXPECT_EQ(got.distance, want.distance);
  }
  EXPECT_GT(contacts, 100u);
}

TEST(SceneAssets, GridFollowsTheRadiusSetAndOldDetectorsKeepTheirs) {
  SceneAssets assets(nullptr, FastLevel::Grid, 0.002);
  auto small = assets.level(torus(), 0.003);
  EXPECT_EQ(small->gridRadius(), 0.002);
  EXPECT_EQ(assets.level(torus(), 0.003), small) << "the same radius shares the detector";

  assets.setGridRadius(0.005);
  EXPECT_EQ(assets.gridRadius(), 0.005);
  const auto large = assets.level(torus(), 0.003);
  EXPECT_NE(large, small);
  EXPECT_EQ(large->gridRadius(), 0.005);
  EXPECT_EQ(small->gridRadius(), 0.002) << "a detector handed out keeps its grid";
  EXPECT_EQ(large->spheres(), small->spheres()) << "a radius change reuses the sphere set";
  // Both answer every radius exactly: the one above its grid's radius through the hierarchy.
  expectBruteForceAnswers(*small, 0.005);
  expectBruteForceAnswers(*large, 0.005);
  expectBruteForceAnswers(*large, 0.002);

  // A grid nobody holds any more is dropped when the next radius is built.
  const std::weak_ptr<const ClodDetector> smallWeak = small;
  const std::weak_ptr<const ClodDetector> largeWeak = large;
  small.reset();
  assets.setGridRadius(0.008);
  const auto larger = assets.level(torus(), 0.003);
  EXPECT_EQ(larger->gridRadius(), 0.008);
  EXPECT_TRUE(smallWeak.expired()) << "the unused 2 mm grid stayed in memory";
  EXPECT_FALSE(largeWeak.expired()) << "a grid still held must stay";
  // The hierarchy level ignores the grid radius.
  EXPECT_EQ(assets.level(torus(), 0.003, FastLevel::Hierarchy)->gridRadius(), 0.0);
}

// A change of d while the current level is held (a node answers with it until the new one is ready): the new level's
// grid is made from the held level's (its cells, the new sphere counts), and answers as the brute force; with nothing
// held the grid is built.
TEST(SceneAssets, ANewLevelMakesItsGridFromAHeldLevelOfTheMesh) {
  SceneAssets assets(nullptr, FastLevel::Grid, 0.002);
  SceneAssets::LevelInfo info;
  const auto first = assets.level(torus(), 0.003, FastLevel::Grid, &info);
  EXPECT_FALSE(info.gridFromLevel);
  const auto second = assets.level(torus(), 0.006, FastLevel::Grid, &info);
  EXPECT_TRUE(info.gridFromLevel);
  EXPECT_NE(second->spheres(), first->spheres());
  EXPECT_EQ(second->grid().cells(), first->grid().cells());
  expectBruteForceAnswers(*second, 0.002);
  // Its sphere counts are its own level's: a detector built alone gives every probe the same fast-level hits.
  const ClodDetector alone(torus(), second->spheres(), FastLevel::Grid, 0.002);
  for (const Vec3& p : nearSurfaceProbes(*torus(), 300, 0.004, 9))
    ASSERT_EQ(second->fastLevelHits(p, 0.002), alone.fastLevelHits(p, 0.002)) << p.transpose();
  // Another radius: built.
  assets.setGridRadius(0.004);
  assets.level(torus(), 0.009, FastLevel::Grid, &info);
  EXPECT_FALSE(info.gridFromLevel);
}

TEST(SceneAssets, BadGridRadiusIsRefused) {
  SceneAssets assets(nullptr, FastLevel::Grid, 0.002);
  EXPECT_THROW(assets.setGridRadius(-1e-3), InvalidParameter);
  EXPECT_THROW(assets.setGridRadius(std::numeric_limits<double>::quiet_NaN()), InvalidParameter);
  EXPECT_THROW(assets.setGridRadius(std::numeric_limits<double>::infinity()), InvalidParameter);
  EXPECT_EQ(assets.gridRadius(), 0.002);
}

}  // namespace
