// ClodBuilder / ClodSphereSet: the coverage invariant on every shared mesh, monotone sphere counts,
// the fitted centres, and parameter checks.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "clod_haptics/core/clustering.h"
#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/sphere_set.h"
#include "clod_haptics/core/triangle_pieces.h"
#include "test_helpers.h"

namespace {

using namespace clod_haptics;
using clod_test::coverageProblems;

TEST(ClodSphereSet, CoverageOnEverySharedMeshAtPaperDistances) {
  const auto meshes = clod_test::sharedMeshes();
  ASSERT_GE(meshes.size(), 6u) << "expected the six shared meshes in " << CLOD_SHARED_MESH_DIR;
  for (const auto& path : meshes) {
    const auto mesh = clod_test::loadNormalized(path);
    const ClodBuilder builder(mesh);
    for (double d : {0.0, 0.02, 0.08}) {
      SCOPED_TRACE(clod_test::baseName(path) + " d=" + std::to_string(d));
      const ClodSphereSet set = builder.build(d);
      const auto problems = coverageProblems(*mesh, set);
      EXPECT_TRUE(problems.empty()) << clod_test::join(problems);
      EXPECT_EQ(set.distance, d);
      EXPECT_EQ(set.meshName, mesh->name);
      EXPECT_EQ(set.stats.spheres, set.size());
      EXPECT_EQ(set.stats.centres, builder.placed().size());
      EXPECT_EQ(set.stats.triangles, mesh->size());
      if (d == 0.0) {
        EXPECT_EQ(set.size(), builder.placed().size()) << "d = 0 keeps every centre";
      }
    }
  }
}

TEST(ClodSphereSet, SphereCountNonIncreasingInDistance) {
  const auto meshes = clod_test::sharedMeshes();
  ASSERT_FALSE(meshes.empty());
  for (const auto& path : meshes) {
    const auto mesh = clod_test::loadNormalized(path);
    const ClodBuilder builder(mesh);
    std::size_t previous = std::numeric_limits<std::size_t>::max();
    for (double d : {0.0, 0.001, 0.005, 0.01, 0.02, 0.03, 0.04, 0.05, 0.06, 0.07, 0.08, 0.2, 2.0}) {
      const std::size_t n = builder.build(d).size();
      EXPECT_LE(n, previous) << clod_test::baseName(path) << " d=" << d;
      previous = n;
    }
    EXPECT_EQ(previous, 1u) << "d beyond the model size leaves one sphere (a connected mesh): "
                            << clod_test::baseName(path);
  }
}

// The single-link merge distances of points, ascending: the edge lengths of their Euclidean minimum spanning tree
// (Prim, O(n^2)). Centres closer than d merge, so build(d) has n - #(edges < d) spheres.
std::vector<double> mergeDistances(const std::vector<Vec3>& points) {
  const std::size_t n = points.size();
  std::vector<double> best(n, std::numeric_limits<double>::infinity()), edges;
  std::vector<char> in(n, 0);
  std::size_t next = 0;
  for (std::size_t step = 0; step < n; ++step) {
    const std::size_t u = next;
    in[u] = 1;
    if (step > 0) edges.push_back(best[u]);
    double nearest = std::numeric_limits<double>::infinity();
    for (std::size_t v = 0; v < n; ++v) {
      if (in[v]) continue;
      best[v] = std::min(best[v], (points[u] - points[v]).norm());
      if (best[v] < nearest) {
        nearest = best[v];
        next = v;
      }
    }
  }
  std::sort(edges.begin(), edges.end());
  return edges;
}

TEST(ClodSphereSet, BuildAtMostIsTheLeastDistanceWithThatManySpheres) {
  const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh("head.off"));
  const ClodBuilder builder(mesh);
  std::vector<Vec3> centres;
  for (const PlacedSphere& p : builder.placed()) centres.push_back(p.centre);
  const std::vector<double> merges = mergeDistances(centres);
  const std::size_t n = centres.size();
  const double tolerance = 1e-6 * mesh->diagonal();
  for (std::size_t target : {std::size_t{1}, std::size_t{7}, std::size_t{100}, std::size_t{845}, n / 2, n - 1, n, n + 5}) {
    SCOPED_TRACE("at most " + std::to_string(target));
    const ClodSphereSet set = builder.buildAtMost(target);
    EXPECT_LE(set.size(), target);
    EXPECT_EQ(set.size(), builder.build(set.distance).size());
    if (target >= n) {
      EXPECT_EQ(set.distance, 0.0);
      continue;
    }
    // The least d with at most target spheres lies just above the (n - target)-th merge distance.
    const double least = merges[n - target - 1];
    EXPECT_GT(set.distance, least);
    EXPECT_LE(set.distance, least + 2.0 * tolerance);
  }
  EXPECT_THROW(builder.buildAtMost(0), InvalidParameter);
  EXPECT_THROW(builder.buildAtMost(10, 0.0), InvalidParameter);
}

TEST(ClodSphereSet, ListsAreSortedUniqueAndCoverEveryTriangle) {
  const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh("mannequin-devil.off"));
  const ClodBuilder builder(mesh);
  for (double d : {0.0, 0.03}) {
    const ClodSphereSet set = builder.build(d);
    std::vector<int> listed(mesh->size(), 0);
    for (std::size_t i = 0; i < set.size(); ++i) {
      ASSERT_LT(set.offsets[i], set.offsets[i + 1]) << "sphere " << i << " lists no triangle";
      for (const std::uint32_t* t = set.begin(i); t + 1 < set.end(i); ++t) ASSERT_LT(t[0], t[1]);
      for (const std::uint32_t* t = set.begin(i); t != set.end(i); ++t) ++listed[*t];
    }
    for (std::size_t t = 0; t < mesh->size(); ++t) EXPECT_GE(listed[t], 1) << "triangle " << t;
    std::size_t maxList = 0;
    for (std::size_t i = 0; i < set.size(); ++i) maxList = std::max<std::size_t>(maxList, set.end(i) - set.begin(i));
    EXPECT_EQ(set.stats.maxTrianglesPerSphere, maxList);
    EXPECT_NEAR(set.stats.meanTrianglesPerSphere, double(set.triangles.size()) / set.size(), 1e-12);
  }
}

TEST(ClodSphereSet, CentreIsMeanOfMembersAndRadiusIsTight) {
  // Recomputes clusters with the same single-link rule and checks each fitted sphere.
  const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh("head.off"));
  const ClodBuilder builder(mesh);
  const double d = 0.04;
  const ClodSphereSet set = builder.build(d);
  std::vector<Vec3> centres;
  for (const auto& s : builder.placed()) centres.push_back(s.centre);
  std::vector<std::uint32_t> labels;
  const std::uint32_t k = SingleLinkClustering().cluster(centres, d, labels);
  ASSERT_EQ(k, set.size());
  std::vector<Vec3> sum(k, Vec3::Zero());
  std::vector<int> count(k, 0);
  for (std::size_t i = 0; i < centres.size(); ++i) {
    sum[labels[i]] += centres[i];
    ++count[labels[i]];
  }
  for (std::uint32_t c = 0; c < k; ++c) {
    EXPECT_LE((sum[c] / count[c] - set.centres[c]).norm(), 1e-12) << "cluster " << c;
    // Tight: some listed vertex lies on the sphere.
    double far = 0;
    for (const std::uint32_t* t = set.begin(c); t != set.end(c); ++t)
      for (int v = 0; v < 3; ++v) far = std::max(far, (mesh->vertex(*t, v) - set.centres[c]).norm());
    EXPECT_NEAR(set.radii[c], far, 1e-12) << "cluster " << c;
  }
}

TEST(ClodSphereSet, LargeBuildEqualsItsDefinitionWrittenOut) {
  // mannequin-devil's ~50k centres take the builder's multi-threaded passes (on hardware with two or more
  // threads). Written out here from the placed spheres and the clustering's labels: each list is the
  // sorted unique triangles of the members, each centre the members' sum in point order over their
  // count, each radius the farthest listed vertex; the builder must give exactly these values.
  const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh("mannequin-devil.off"));
  const ClodBuilder builder(mesh);
  const auto placed = builder.placed();
  ASSERT_GT(placed.size(), 40000u);
  std::vector<Vec3> centres;
  for (const auto& s : placed) centres.push_back(s.centre);
  for (double d : {0.0, 0.03}) {
    SCOPED_TRACE("d=" + std::to_string(d));
    const ClodSphereSet set = builder.build(d);
    std::vector<std::uint32_t> labels;
    const std::uint32_t k = SingleLinkClustering(1).cluster(centres, d, labels);
    ASSERT_EQ(k, set.size());
    std::vector<Vec3> sum(k, Vec3::Zero());
    std::vector<int> count(k, 0);
    std::vector<std::vector<std::uint32_t>> lists(k);
    for (std::size_t i = 0; i < centres.size(); ++i) {
      sum[labels[i]] += centres[i];
      ++count[labels[i]];
      lists[labels[i]].push_back(placed[i].triangle);
    }
    for (std::uint32_t c = 0; c < k; ++c) {
      std::sort(lists[c].begin(), lists[c].end());
      lists[c].erase(std::unique(lists[c].begin(), lists[c].end()), lists[c].end());
      ASSERT_EQ(std::vector<std::uint32_t>(set.begin(c), set.end(c)), lists[c]) << "cluster " << c;
      const Vec3 mean = sum[c] / count[c];
      ASSERT_EQ(set.centres[c], mean) << "cluster " << c;
      double far2 = 0;
      for (const std::uint32_t t : lists[c])
        for (int v = 0; v < 3; ++v) far2 = std::max(far2, (mesh->vertex(t, v) - mean).squaredNorm());
      ASSERT_EQ(set.radii[c], std::sqrt(far2)) << "cluster " << c;
    }
  }
}

TEST(ClodSphereSet, BadDistanceThrowsInvalidParameter) {
  const auto mesh = clod_test::loadNormalized(clod_test::testData("cube.obj"));
  const ClodBuilder builder(mesh);
  for (double d : {-0.01, -std::numeric_limits<double>::min(), std::numeric_limits<double>::quiet_NaN(),
                   std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()})
    EXPECT_THROW(builder.build(d), InvalidParameter) << "d = " << d;
  EXPECT_NO_THROW(builder.build(0.0));
  EXPECT_THROW(requireNonNegative(std::nan(""), "x"), InvalidParameter);
}

TEST(ClodSphereSet, BuilderRejectsMissingMesh) {
  EXPECT_THROW(ClodBuilder(nullptr), InvalidParameter);
}

TEST(ClodSphereSet, ConcurrentBuildsAgree) {
  const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh("elephant.off"));
  const ClodBuilder builder(mesh);
  std::vector<ClodSphereSet> sets(4);
  clod_test::parallelFor(4, 4, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) sets[i] = builder.build(0.03);
  });
  for (std::size_t i = 1; i < sets.size(); ++i) {
    EXPECT_EQ(sets[i].centres, sets[0].centres);
    EXPECT_EQ(sets[i].radii, sets[0].radii);
    EXPECT_EQ(sets[i].triangles, sets[0].triangles);
  }
}

// fitProblem and a triangle split over several spheres: one long triangle listed by one sphere per piece, each
// holding its piece only. The union covers the triangle, so the set fits; shrinking any one sphere, or dropping
// one from the lists, leaves a piece uncovered, and fitProblem says which triangle sticks out.
TEST(ClodSphereSet, FitProblemAcceptsATriangleSplitOverSpheresAndNothingLess) {
  // An isosceles right triangle: its halves are isosceles right triangles, each held by the ball on its longest
  // edge (the smallest ball holding it).
  const auto mesh = std::make_shared<const TriangleMesh>(
      makeMesh({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)}, {Triangle{{0, 1, 2}}}, "right"));
  ClodSphereSet set;
  set.meshName = mesh->name;
  std::vector<Vec3> centroids;  // of the pieces
  const double maxEdge = 0.3;
  forEachPiece({mesh->vertex(0, 0), mesh->vertex(0, 1), mesh->vertex(0, 2)}, maxEdge, kMaxPieceDepth,
               [&](const TrianglePiece& piece) {
                 int k = 0;  // the longest edge, from corner k to k + 1
                 for (int e = 1; e < 3; ++e)
                   if ((piece[(e + 1) % 3] - piece[e]).norm() > (piece[(k + 1) % 3] - piece[k]).norm()) k = e;
                 const Vec3 centre = 0.5 * (piece[k] + piece[(k + 1) % 3]);
                 double r = 0.0;
                 for (const Vec3& v : piece) r = std::max(r, (v - centre).norm());
                 centroids.push_back((piece[0] + piece[1] + piece[2]) / 3.0);
                 set.centres.push_back(centre);
                 set.radii.push_back(r);
                 set.triangles.push_back(0);
                 set.offsets.push_back(static_cast<std::uint32_t>(set.triangles.size()));
               });
  ASSERT_GE(set.size(), 8u);
  for (std::size_t i = 0; i < set.size(); ++i) EXPECT_LT(set.radii[i], 0.5) << "no sphere holds the triangle";
  EXPECT_EQ(fitProblem(*mesh, set), "");
  EXPECT_TRUE(clod_test::coverageProblems(*mesh, set).empty());
  // Balls around neighbouring pieces overlap: a sphere shrunk or dropped may leave its piece covered by the
  // others. Where it leaves a point of the triangle (the piece's centroid) in no ball, the set must not fit.
  std::size_t uncovering = 0;
  for (std::size_t i = 0; i < set.size(); ++i) {
    ClodSphereSet shrunk = set;
    shrunk.radii[i] *= 0.3;
    bool held = false;
    for (std::size_t j = 0; j < set.size(); ++j)
      held = held || (centroids[i] - shrunk.centres[j]).norm() <= shrunk.radii[j] * (1 + 1e-9);
    if (held) continue;  // the piece's centroid is still in some ball
    ++uncovering;
    EXPECT_NE(fitProblem(*mesh, shrunk).find("triangle 0 sticks out"), std::string::npos) << "sphere " << i;
    EXPECT_FALSE(clod_test::coverageProblems(*mesh, shrunk).empty()) << "sphere " << i;
    ClodSphereSet dropped = set;  // sphere i no longer lists the triangle
    dropped.triangles.erase(dropped.triangles.begin() + static_cast<std::ptrdiff_t>(i));
    for (std::size_t j = i + 1; j < dropped.offsets.size(); ++j) --dropped.offsets[j];
    EXPECT_NE(fitProblem(*mesh, dropped).find("sticks out"), std::string::npos) << "sphere " << i;
  }
  EXPECT_GE(uncovering, set.size() / 4);  // 8 of the 32 pieces here
  // A sphere holding the whole triangle settles it, whatever the others hold.
  ClodSphereSet big = set;
  big.radii[0] = 2.0;
  big.radii[1] = 0.0;
  EXPECT_EQ(fitProblem(*mesh, big), "");
}

}  // namespace
