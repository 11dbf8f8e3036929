// The trees over a level's spheres (sphere_trees.h): built trees pass the check that a tree read from the disk cache
// must pass, on every shared mesh at several clustering distances; each defect of a tree (a box that misses a ball,
// a tight box or a centre, a sphere twice, a layout the walks cannot follow, a gap radius too small) and trees of
// another level are refused with a reason.

#include <gtest/gtest.h>

#include <limits>
#include <memory>
#include <string>

#include "clod_haptics/core/mesh_box_tree.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/sphere_set.h"
#include "clod_haptics/core/sphere_trees.h"
#include "test_helpers.h"

namespace {

using namespace clod_haptics;

const std::string kTorus = CLOD_PACKAGE_DATA_DIR "/meshes/torus.obj";

TEST(SphereTrees, BuiltTreesServeTheirSet) {
  std::vector<std::string> paths = clod_test::sharedMeshes();
  paths.push_back(kTorus);
  for (const std::string& path : paths) {
    const auto mesh = clod_test::loadNormalized(path);
    const double pad = meshBoxTreePad(*mesh);
    for (double d : {0.003, 0.02, 0.1}) {
      const ClodSphereSet set = ClodBuilder(mesh).build(d);
      const SphereTrees trees = buildSphereTrees(*mesh, set, pad);
      EXPECT_EQ(sphereTreesProblem(trees, *mesh, set, pad), "") << clod_test::baseName(path) << " d " << d;
      EXPECT_EQ(trees.ballOrder.size(), set.size());
      EXPECT_EQ(trees.gapRadius.size(), trees.gapNodes.size());
    }
  }
}

std::size_t firstLeaf(const std::vector<BoxNode>& nodes) {
  for (std::size_t i = 0; i < nodes.size(); ++i)
    if (nodes[i].count > 0) return i;
  return 0;
}

// Each edit of valid trees is found, with the tree and the reason that name it.
TEST(SphereTrees, EveryDefectIsFound) {
  const auto mesh = clod_test::loadNormalized(kTorus);
  const double pad = meshBoxTreePad(*mesh);
  const ClodSphereSet set = ClodBuilder(mesh).build(0.005);
  ASSERT_GT(set.size(), 64u);
  const SphereTrees good = buildSphereTrees(*mesh, set, pad);
  ASSERT_EQ(sphereTreesProblem(good, *mesh, set, pad), "");
  struct Edit {
    const char* reason;
    void (*edit)(SphereTrees&);
  };
  const Edit edits[] = {
      {"ball tree: a leaf's box misses a sphere",
       [](SphereTrees& t) {
         BoxNode& leaf = t.ballNodes[firstLeaf(t.ballNodes)];
         leaf.hi[0] = leaf.lo[0];
       }},
      {"ball tree: a sphere is out of range or in two leaves", [](SphereTrees& t) { t.ballOrder[1] = t.ballOrder[0]; }},
      {"ball tree: a node's box misses a child's",
       [](SphereTrees& t) { t.ballNodes[0].lo[1] = t.ballNodes[1].lo[1] + 1e-3f; }},
      {"tight tree: a leaf's box misses a sphere",
       [](SphereTrees& t) {
         BoxNode& leaf = t.tightNodes[firstLeaf(t.tightNodes)];
         leaf.lo[2] = leaf.hi[2];
       }},
      {"tight tree: an inner node's children are out of place", [](SphereTrees& t) { t.tightNodes[0].first = 1; }},
      {"tight tree: the tree does not order every sphere once", [](SphereTrees& t) { t.tightOrder.pop_back(); }},
      {"gap tree: a leaf's box misses a sphere",
       [](SphereTrees& t) {
         BoxNode& leaf = t.gapNodes[firstLeaf(t.gapNodes)];
         leaf.lo[1] = leaf.hi[1];
       }},
      {"gap tree: a node's box is empty or not finite",
       [](SphereTrees& t) { t.gapNodes[0].lo[0] = std::numeric_limits<float>::quiet_NaN(); }},
      {"gap tree: a node's radius is below a sphere's", [](SphereTrees& t) { t.gapRadius[0] *= 0.5f; }},
      {"gap tree: one radius per node", [](SphereTrees& t) { t.gapRadius.pop_back(); }},
  };
  for (const Edit& e : edits) {
    SphereTrees bad = good;
    e.edit(bad);
    const std::string problem = sphereTreesProblem(bad, *mesh, set, pad);
    EXPECT_NE(problem.find(e.reason), std::string::npos) << "expected '" << e.reason << "', got '" << problem << "'";
  }
}

// Trees built for one level do not serve another level of the same mesh.
TEST(SphereTrees, TreesOfAnotherLevelAreRefused) {
  const auto mesh = clod_test::loadNormalized(kTorus);
  const double pad = meshBoxTreePad(*mesh);
  const ClodSphereSet coarse = ClodBuilder(mesh).build(0.05);
  const ClodSphereSet fine = ClodBuilder(mesh).build(0.01);
  ASSERT_NE(coarse.size(), fine.size());
  EXPECT_NE(sphereTreesProblem(buildSphereTrees(*mesh, coarse, pad), *mesh, fine, pad), "");
  EXPECT_NE(sphereTreesProblem(buildSphereTrees(*mesh, fine, pad), *mesh, coarse, pad), "");
}

}  // namespace
