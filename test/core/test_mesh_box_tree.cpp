// The box tree over a mesh's triangles, shared through TriangleMesh::boxTree: the check that decides whether a
// tree may serve a mesh finds every defect (a box that misses, a triangle twice, a layout the walks cannot follow,
// a tree too deep for their stacks, a stale tree), and detectors over a mesh read from the cache share its tree
// and answer as a brute force over every triangle.

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <functional>
#include <limits>
#include <memory>
#include <random>
#include <string>

#include "cache_file_helpers.h"
#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/detector.h"
#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/geometry.h"
#include "clod_haptics/core/mesh_box_tree.h"
#include "clod_haptics/core/mesh_cache.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/probes.h"
#include "clod_haptics/core/sphere_set.h"
#include "clod_haptics/core/swept_query.h"
#include "test_helpers.h"

namespace {

using namespace clod_haptics;

const std::string kTorus = CLOD_PACKAGE_DATA_DIR "/meshes/torus.obj";

TEST(MeshBoxTree, BuiltTreeServesItsMesh) {
  std::vector<std::string> paths = clod_test::sharedMeshes();
  paths.push_back(kTorus);
  for (const std::string& path : paths) {
    const TriangleMesh mesh = loadMesh(path);
    const auto tree = buildMeshBoxTree(mesh);
    EXPECT_EQ(meshBoxTreeProblem(*tree, mesh), "") << path;
    EXPECT_EQ(tree->order.size(), mesh.size()) << path;
  }
}

// Each edit of a valid tree is found, with the reason that names it.
TEST(MeshBoxTree, EveryDefectIsFound) {
  const TriangleMesh mesh = loadMesh(kTorus);
  const MeshBoxTree good = *buildMeshBoxTree(mesh);
  auto leafIndex = [&](const MeshBoxTree& t) {
    for (std::size_t i = 0; i < t.nodes.size(); ++i)
      if (t.nodes[i].count > 0) return i;
    return std::size_t{0};
  };
  struct Edit {
    const char* reason;
    void (*edit)(MeshBoxTree&, std::size_t leaf);
  };
  const Edit edits[] = {
      {"misses a triangle", [](MeshBoxTree& t, std::size_t leaf) { t.nodes[leaf].hi[0] = t.nodes[leaf].lo[0]; }},
      {"misses a child", [](MeshBoxTree& t, std::size_t) { t.nodes[0].lo[1] = t.nodes[1].lo[1] + 1e-3f; }},
      {"two leaves", [](MeshBoxTree& t, std::size_t) { t.order[1] = t.order[0]; }},
      {"out of range", [](MeshBoxTree& t, std::size_t) { t.order[2] = 1u << 30; }},
      {"children are out of place", [](MeshBoxTree& t, std::size_t) { t.nodes[0].first = 1; }},
      {"not finite", [](MeshBoxTree& t, std::size_t) { t.nodes[0].lo[2] = std::numeric_limits<float>::quiet_NaN(); }},
      {"every triangle once", [](MeshBoxTree& t, std::size_t) { t.order.pop_back(); }},
      {"run is out of place", [](MeshBoxTree& t, std::size_t leaf) { t.nodes[leaf].first += 1; }},
  };
  ASSERT_EQ(meshBoxTreeProblem(good, mesh), "");
  for (const Edit& e : edits) {
    MeshBoxTree bad = good;
    e.edit(bad, leafIndex(bad));
    const std::string problem = meshBoxTreeProblem(bad, mesh);
    EXPECT_NE(problem.find(e.reason), std::string::npos) << "expected '" << e.reason << "', got '" << problem << "'";
  }
}

// A valid chain-shaped tree of a given depth: inner node i (0 <= i < depth) has inner node i + 1 (or the first leaf)
// on its left; right children are leaves, each over one triangle, the root's over the rest. Every box is the mesh's.
MeshBoxTree chain(const TriangleMesh& mesh, std::uint32_t depth) {
  MeshBoxTree t;
  const Eigen::AlignedBox3d b = mesh.bounds();
  BoxNode all{};
  for (int k = 0; k < 3; ++k) {
    all.lo[k] = static_cast<float>(b.min()[k]) - 1.0f;
    all.hi[k] = static_cast<float>(b.max()[k]) + 1.0f;
  }
  const std::uint32_t n = static_cast<std::uint32_t>(mesh.size());
  t.nodes.assign(2 * depth + 1, all);
  for (std::uint32_t i = 0; i < depth; ++i) {  // inner i's right child comes after the whole left chain
    t.nodes[i].count = 0;
    t.nodes[i].first = 2 * depth - i;
  }
  t.nodes[depth].first = 0;  // the deepest (left-most) leaf: triangle 0
  t.nodes[depth].count = 1;
  for (std::uint32_t i = depth; i-- > 0;) {  // right leaves in depth-first order: the deepest parent's first
    BoxNode& leaf = t.nodes[2 * depth - i];
    leaf.first = depth - i;
    leaf.count = i == 0 ? n - depth : 1;
  }
  for (std::uint32_t k = 0; k < n; ++k) t.order.push_back(k);
  return t;
}

// The walks keep a stack of 64 entries: a tree deeper than 60 levels is refused, a shallower one of the same shape
// is fine.
TEST(MeshBoxTree, TooDeepForTheWalksIsRefused) {
  const TriangleMesh mesh = loadMesh(kTorus);
  EXPECT_EQ(meshBoxTreeProblem(chain(mesh, 50), mesh), "");
  EXPECT_NE(meshBoxTreeProblem(chain(mesh, 61), mesh).find("too deep"), std::string::npos);
}

// A mesh whose vertices moved after its tree was built keeps a tree that no longer bounds it: it is not used, and
// the detector over that mesh answers as a brute force over every triangle.
TEST(MeshBoxTree, StaleTreeIsNotUsed) {
  TriangleMesh original = loadMesh(kTorus);
  original.boxTree = buildMeshBoxTree(original);
  TriangleMesh moved = original;
  for (Vec3& v : moved.vertices) v *= 1.25;
  ASSERT_EQ(moved.boxTree, original.boxTree);
  EXPECT_NE(meshBoxTreeProblem(*moved.boxTree, moved), "");
  EXPECT_NE(meshBoxTreeOf(moved), moved.boxTree);
  EXPECT_EQ(meshBoxTreeOf(original), original.boxTree);
  auto mesh = std::make_shared<const TriangleMesh>(makeMesh(moved.vertices, moved.triangles, "moved"));
  auto withStale = std::make_shared<TriangleMesh>(*mesh);
  withStale->boxTree = original.boxTree;
  std::shared_ptr<const TriangleMesh> m = withStale;
  auto set = std::make_shared<const ClodSphereSet>(ClodBuilder(m).build(0.02));
  const double r = 0.2 * mesh->bounds().diagonal().norm();  // beyond the grid's radius: the mesh tree answers
  ClodDetector detector(m, set, FastLevel::Grid, 0.01 * mesh->bounds().diagonal().norm());
  EXPECT_NE(detector.meshTree(), original.boxTree);
  for (const Vec3& p : nearSurfaceProbes(*mesh, 300, 0.3 * r, 5)) {
    ContactResult got;
    detector.query(p, r, DetectionMode::Exact, got);
    const ContactResult want = bruteForceQuery(*mesh, p, r);
    ASSERT_EQ(got.contact, want.contact) << p.transpose();
    if (want.contact) {
      EXPECT_NEAR(got.distance, want.distance, 1e-12) << p.transpose();
    }
  }
}

// A tree remembers the fingerprint of the mesh it was built for or checked against: a mesh with that fingerprint is
// served without the O(triangles) check, any change to a vertex or a triangle changes the fingerprint and brings
// the check back, and a tree with no fingerprint is always checked.
TEST(MeshBoxTree, FingerprintStandsForTheCheckOnlyForTheSameMesh) {
  TriangleMesh mesh = loadMesh(kTorus);
  mesh.boxTree = buildMeshBoxTree(mesh);
  ASSERT_EQ(mesh.boxTree->servesFingerprint, meshFingerprint(mesh));
  EXPECT_EQ(meshBoxTreeOf(mesh), mesh.boxTree);
  TriangleMesh nudged = mesh;  // one coordinate of one vertex, by one unit in the last place
  nudged.vertices[7].x() = std::nextafter(nudged.vertices[7].x(), 1e9);
  EXPECT_NE(meshFingerprint(nudged), meshFingerprint(mesh));
  TriangleMesh flipped = mesh;  // the same vertices, one triangle turned
  std::swap(flipped.triangles[3][0], flipped.triangles[3][1]);
  EXPECT_NE(meshFingerprint(flipped), meshFingerprint(mesh));
  // The fingerprint is trusted: a wrong tree carrying the mesh's fingerprint is served (so only the builder and
  // the checked cache read set it); without it, the same wrong tree is checked and replaced.
  auto wrong = std::make_shared<MeshBoxTree>(*mesh.boxTree);
  wrong->nodes[0].hi[0] = wrong->nodes[0].lo[0];
  TriangleMesh carrying = mesh;
  carrying.boxTree = wrong;
  EXPECT_EQ(meshBoxTreeOf(carrying), wrong);
  wrong->servesFingerprint = 0;
  EXPECT_NE(meshBoxTreeOf(carrying), wrong);
}

// Read from the cache, a mesh brings its tree; the grid detector and the swept query share it, and answer as a
// brute force (the deep search and pointers beyond the grid's radius walk it).
TEST(MeshBoxTree, CachedMeshSharesItsTree) {
  clod_test::TempDir dir;
  MeshCache cache(dir.str());
  cache.load(kTorus, {});
  const auto mesh = std::make_shared<const TriangleMesh>(cache.load(kTorus, {}));
  ASSERT_TRUE(mesh->boxTree);
  EXPECT_EQ(mesh->boxTree->servesFingerprint, meshFingerprint(*mesh)) << "checked at the read, not again";
  ASSERT_TRUE(mesh->boxTree);
  EXPECT_EQ(meshBoxTreeProblem(*mesh->boxTree, *mesh), "");
  auto set = std::make_shared<const ClodSphereSet>(ClodBuilder(mesh).build(0.02));
  const double diagonal = mesh->bounds().diagonal().norm();
  auto detector = std::make_shared<const ClodDetector>(mesh, set, FastLevel::Grid, 0.01 * diagonal);
  EXPECT_EQ(detector->meshTree(), mesh->boxTree);
  const SweptSphereQuery swept(mesh, detector);
  const double r = 0.1 * diagonal;
  for (const Vec3& p : nearSurfaceProbes(*mesh, 300, 0.5 * r, 9)) {
    ContactResult got;
    detector->query(p, r, DetectionMode::Exact, got);
    const ContactResult want = bruteForceQuery(*mesh, p, r);
    ASSERT_EQ(got.contact, want.contact) << p.transpose();
    if (want.contact) {
      EXPECT_NEAR(got.distance, want.distance, 1e-12) << p.transpose();
    }
    SweptContact s;
    swept.sweep(p, p + Vec3(0.3 * r, -0.2 * r, 0.1 * r), r, s);
    const SweptContact ref = bruteForceSweep(*mesh, p, p + Vec3(0.3 * r, -0.2 * r, 0.1 * r), r);
    ASSERT_EQ(s.hit, ref.hit) << p.transpose();
    if (ref.hit) {
      EXPECT_EQ(s.toi, ref.toi) << p.transpose();
    }
  }
}

// A cache file whose stored tree is damaged (with a valid checksum) is refused with a FormatError that says so.
TEST(MeshBoxTree, DamagedTreeInTheCacheFileIsRefused) {
  clod_test::TempDir dir;
  const TriangleMesh mesh = loadMesh(kTorus);
  const std::uint64_t key = meshSourceKey(kTorus, {});
  const std::string path = dir.file("torus.clodmesh");
  writeMeshBinary(mesh, key, path);
  ASSERT_TRUE(readMeshBinary(path, key).boxTree);
  const std::vector<char> good = clod_test::readBytes(path);
  // The file ends with the tree's order (4 bytes per triangle), its slabs (64 bytes per node), the name, then the
  // checksum.
  const std::size_t nodes = buildMeshBoxTree(mesh)->nodes.size();
  const std::size_t slabsAt = good.size() - 8 - mesh.name.size() - 64 * nodes;
  const std::size_t orderAt = slabsAt - 4 * mesh.size();
  auto expectRefused = [&](const std::function<void(std::vector<char>&)>& edit, const char* what) {
    std::vector<char> bytes = good;
    edit(bytes);
    clod_test::fixChecksum(bytes);
    clod_test::writeBytes(path, bytes);
    try {
      readMeshBinary(path, key);
      ADD_FAILURE() << "read a mesh whose tree " << what;
    } catch (const FormatError& e) {
      EXPECT_NE(std::string(e.what()).find("box tree"), std::string::npos) << e.what();
    }
  };
  expectRefused(
      [&](std::vector<char>& b) {
        const std::uint32_t duplicate = 0;
        std::memcpy(b.data() + orderAt + 4, &duplicate, 4);
        std::memcpy(b.data() + orderAt, &duplicate, 4);
      },
      "lists a triangle twice");
  // The last node is a leaf: it has a slab. A normal that is not a unit vector, a NaN thickness.
  const std::size_t lastSlab = slabsAt + 64 * (nodes - 1);
  expectRefused(
      [&](std::vector<char>& b) {
        const double two = 2.0;
        std::memcpy(b.data() + lastSlab + 24, &two, 8);
      },
      "has a slab whose normal is not a unit vector");
  expectRefused(
      [&](std::vector<char>& b) {
        const double nan = std::nan("");
        std::memcpy(b.data() + lastSlab + 48, &nan, 8);
      },
      "has a slab of NaN thickness");
}

// The slabs: every vertex below a node within its thick of the plane and its radius of the centre, and the slab's
// bound never above the distance to a triangle below (brute force over the node's triangles), from points near
// and far, on every shared mesh and a finely tessellated sheet far from the origin. Nodes above kSlabTriangles
// have none (infinite, never pruning).
TEST(MeshBoxTree, SlabsBoundWhatLiesBelowThem) {
  std::vector<std::shared_ptr<const TriangleMesh>> meshes;
  for (const std::string& path : clod_test::sharedMeshes()) meshes.push_back(clod_test::loadNormalized(path));
  meshes.push_back(std::make_shared<const TriangleMesh>(clod_test::heightField(
      60, [](double x, double y) { return 0.06 * std::sin(9.0 * x) * std::cos(6.0 * y); }, Eigen::Matrix3d::Identity(),
      Vec3(3e3, -2e3, 0.0))));
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (const auto& mesh : meshes) {
    const auto tree = buildMeshBoxTree(*mesh);
    const std::vector<NodeSlab> slabs = meshTreeSlabs(*tree, *mesh);
    ASSERT_EQ(slabs.size(), tree->nodes.size()) << mesh->name;
    // The triangles below each node: its leaves' runs, collected depth first.
    std::size_t withSlab = 0, checked = 0, tight = 0;
    for (std::size_t i = 0; i < tree->nodes.size(); ++i) {
      std::vector<std::uint32_t> below, stack{static_cast<std::uint32_t>(i)};
      while (!stack.empty()) {
        const BoxNode& node = tree->nodes[stack.back()];
        const std::uint32_t at = stack.back();
        stack.pop_back();
        if (node.count > 0) {
          for (std::uint32_t k = node.first; k < node.first + node.count; ++k) below.push_back(tree->order[k]);
        } else {
          stack.push_back(at + 1);
          stack.push_back(node.first);
        }
      }
      const NodeSlab& s = slabs[i];
      if (below.size() > kSlabTriangles) {
        EXPECT_TRUE(std::isinf(s.thick) && std::isinf(s.radius)) << mesh->name << " node " << i;
        continue;
      }
      ++withSlab;
      for (std::uint32_t t : below)
        for (int k = 0; k < 3; ++k) {
          const Vec3 m = mesh->vertex(t, k) - s.centre;
          ASSERT_LE(std::abs(s.normal.dot(m)), s.thick) << mesh->name << " node " << i;
          ASSERT_LE(m.norm(), s.radius) << mesh->name << " node " << i;
        }
      if (i % 7 != 0) continue;  // the bound on a sample of the nodes
      for (int q = 0; q < 20; ++q) {
        const double scale = q < 10 ? s.radius : 5.0 * s.radius;
        Vec3 p = s.centre + scale * Vec3(u(rng), u(rng), u(rng));
        if (q % 4 == 0) p = s.centre + s.normal * (s.thick * (1.0 + 1e-6)) + 0.5 * s.radius * Vec3(u(rng), u(rng), 0.0);
        double nearest = std::numeric_limits<double>::infinity();
        for (std::uint32_t t : below)
          nearest = std::min(nearest,
                             (p - closestPointOnTriangle(p, mesh->vertex(t, 0), mesh->vertex(t, 1), mesh->vertex(t, 2)))
                                 .squaredNorm());
        const double bound = slabSquaredDistance(s, p);
        ASSERT_LE(bound, nearest) << mesh->name << " node " << i << " point " << p.transpose();
        ++checked;
        tight += bound > 0.25 * nearest;
      }
    }
    EXPECT_GT(withSlab, tree->nodes.size() / 2) << mesh->name;
    EXPECT_GT(tight, checked / 4) << mesh->name << ": the bound must mean something";
  }
}

}  // namespace
