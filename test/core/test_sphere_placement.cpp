// PaperPlacement (paper section 3.2.1) against a brute-force re-implementation written here: every
// ray against every triangle, no BVH, the threshold relaxed step by step exactly as the paper says.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "clod_haptics/core/geometry.h"
#include "clod_haptics/core/sphere_placement.h"
#include "clod_haptics/core/sphere_set.h"
#include "test_helpers.h"

namespace {

using namespace clod_haptics;

constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();

struct Reference {
  std::vector<std::uint32_t> opposite;  // kNone when there is none
  std::vector<int> steps;
};

// The paper's loop, literally: tau = -0.99, then -0.98, ... until some hit has normal . n < tau;
// the nearest such hit wins (ties to the lowest index). Hits at the origin itself are ignored.
Reference bruteForcePaperRule(const TriangleMesh& mesh) {
  Reference ref;
  const std::size_t n = mesh.size();
  ref.opposite.assign(n, kNone);
  ref.steps.assign(n, 0);
  const double minT = 1e-12 * mesh.diagonal();
  struct Hit {
    std::uint32_t tri;
    double t, dot;
  };
  std::vector<Hit> hits;
  for (std::size_t t = 0; t < n; ++t) {
    const Vec3& normal = mesh.normals[t];
    if (normal.isZero(0.0)) continue;
    const Vec3 origin = mesh.centroid(t);
    hits.clear();
    for (std::size_t o = 0; o < n; ++o) {
      if (o == t) continue;
      double dist;
      if (rayTriangle(origin, -normal, mesh.vertex(o, 0), mesh.vertex(o, 1), mesh.vertex(o, 2), dist) && dist > minT)
        hits.push_back({static_cast<std::uint32_t>(o), dist, mesh.normals[o].dot(normal)});
    }
    if (hits.empty()) continue;
    for (int k = 0; k <= 201; ++k) {
      const double tau = -0.99 + 0.01 * k;
      double bestT = std::numeric_limits<double>::infinity();
      std::uint32_t best = kNone;
      for (const Hit& h : hits)
        if (h.dot < tau && (h.t < bestT || (h.t == bestT && h.tri < best))) {
          bestT = h.t;
          best = h.tri;
        }
      if (best != kNone) {
        ref.opposite[t] = best;
        ref.steps[t] = k;
        break;
      }
    }
  }
  return ref;
}

double farthest(const TriangleMesh& mesh, std::uint32_t t, const Vec3& c) {
  double r = 0;
  for (int k = 0; k < 3; ++k) r = std::max(r, (mesh.vertex(t, k) - c).norm());
  return r;
}

// Compares the placement with the reference sphere by sphere and returns the reference's counts.
void expectMatchesReference(const TriangleMesh& mesh, const std::vector<PlacedSphere>& placed,
                            const PlacementStats& stats, std::size_t& paired, std::size_t& unpaired) {
  const Reference ref = bruteForcePaperRule(mesh);
  paired = unpaired = 0;
  std::size_t degenerate = 0, relaxations = 0, next = 0, mismatches = 0;
  const double tol = 1e-12 * mesh.diagonal();
  for (std::size_t t = 0; t < mesh.size(); ++t) {
    const Vec3 c0 = mesh.centroid(t);
    const std::uint32_t o = ref.opposite[t];
    ASSERT_LT(next, placed.size());
    if (o == kNone) {
      (mesh.normals[t].isZero(0.0) ? degenerate : unpaired)++;
      const PlacedSphere& s = placed[next++];
      EXPECT_EQ(s.triangle, t);
      EXPECT_LE((s.centre - c0).norm(), tol) << "fallback sphere of triangle " << t << " is at the centroid";
      EXPECT_NEAR(s.radius, farthest(mesh, t, c0), tol);
      continue;
    }
    ++paired;
    relaxations += ref.steps[t];
    ASSERT_LT(next + 1, placed.size());
    const PlacedSphere& s1 = placed[next++];
    const PlacedSphere& s2 = placed[next++];
    const Vec3 c1 = mesh.centroid(o);
    const Vec3 quarter = c0 + 0.25 * (c1 - c0), threeQuarter = c0 + 0.75 * (c1 - c0);
    const bool same = s1.triangle == t && s2.triangle == o && (s1.centre - quarter).norm() <= tol &&
                      (s2.centre - threeQuarter).norm() <= tol &&
                      std::abs(s1.radius - farthest(mesh, t, quarter)) <= tol &&
                      std::abs(s2.radius - farthest(mesh, o, threeQuarter)) <= tol;
    if (!same && ++mismatches <= 10)
      ADD_FAILURE() << "triangle " << t << ": reference opposite " << o << " (step " << ref.steps[t]
                    << "), placement names " << s1.triangle << " and " << s2.triangle;
  }
  EXPECT_EQ(mismatches, 0u);
  EXPECT_EQ(next, placed.size()) << "every sphere is accounted for";
  EXPECT_EQ(stats.triangles, mesh.size());
  EXPECT_EQ(stats.paired, paired);
  EXPECT_EQ(stats.unpaired, unpaired);
  EXPECT_EQ(stats.degenerate, degenerate);
  EXPECT_EQ(stats.relaxations, relaxations);
  EXPECT_EQ(placed.size(), 2 * paired + unpaired + degenerate);
}

// Each placed sphere wraps the triangle it names.
void expectEachSphereCoversItsTriangle(const TriangleMesh& mesh, const std::vector<PlacedSphere>& placed) {
  std::vector<char> covered(mesh.size(), 0);
  for (const PlacedSphere& s : placed) {
    ASSERT_LT(s.triangle, mesh.size());
    ASSERT_TRUE(s.centre.allFinite());
    ASSERT_TRUE(std::isfinite(s.radius));
    for (int k = 0; k < 3; ++k)
      ASSERT_LE((mesh.vertex(s.triangle, k) - s.centre).norm(), s.radius * (1 + 1e-12) + 1e-15 * mesh.diagonal());
    covered[s.triangle] = 1;
  }
  for (std::size_t t = 0; t < mesh.size(); ++t) EXPECT_TRUE(covered[t]) << "triangle " << t << " has no sphere";
}

TEST(PaperPlacement, ClosedMeshMatchesBruteForceRule) {
  const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh("elephant.off"));
  PlacementStats stats;
  const auto placed = PaperPlacement(2).place(*mesh, &stats);
  std::size_t paired, unpaired;
  expectMatchesReference(*mesh, placed, stats, paired, unpaired);
  expectEachSphereCoversItsTriangle(*mesh, placed);
  std::printf("[ INFO     ] elephant.off: %zu triangles, %zu paired, %zu unpaired, %zu relaxation steps\n",
              mesh->size(), paired, unpaired, stats.relaxations);
  EXPECT_GT(paired, mesh->size() * 95 / 100) << "a closed mesh pairs nearly every triangle";
}

TEST(PaperPlacement, ClosedCubePairsEveryTriangleWithTheOppositeFace) {
  const TriangleMesh mesh = loadMesh(clod_test::testData("cube.obj"));
  PlacementStats stats;
  const auto placed = PaperPlacement(1).place(mesh, &stats);
  std::size_t paired, unpaired;
  expectMatchesReference(mesh, placed, stats, paired, unpaired);
  EXPECT_EQ(paired, 12u);
  EXPECT_EQ(unpaired, 0u);
  EXPECT_EQ(stats.relaxations, 0u) << "opposite faces have dot -1 < -0.99 at once";
  for (std::size_t i = 0; i < placed.size(); i += 2) {
    const std::uint32_t t = placed[i].triangle, o = placed[i + 1].triangle;
    EXPECT_DOUBLE_EQ(mesh.normals[t].dot(mesh.normals[o]), -1.0);
  }
}

TEST(PaperPlacement, OpenMeshFallsBackToOwnSphereAtCentroid) {
  const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh("mesh_with_border.off"));
  PlacementStats stats;
  const auto placed = PaperPlacement(2).place(*mesh, &stats);
  std::size_t paired, unpaired;
  expectMatchesReference(*mesh, placed, stats, paired, unpaired);
  expectEachSphereCoversItsTriangle(*mesh, placed);
  std::printf("[ INFO     ] mesh_with_border.off: %zu triangles, %zu paired, %zu unpaired (own sphere at centroid)\n",
              mesh->size(), paired, unpaired);
  EXPECT_GT(unpaired, 0u) << "an open mesh has triangles whose inward ray meets nothing";
}

TEST(PaperPlacement, ThreadCountDoesNotChangeTheResult) {
  const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh("head.off"));
  const auto one = PaperPlacement(1).place(*mesh, nullptr);
  const auto four = PaperPlacement(4).place(*mesh, nullptr);
  ASSERT_EQ(one.size(), four.size());
  for (std::size_t i = 0; i < one.size(); ++i) {
    EXPECT_EQ(one[i].triangle, four[i].triangle);
    EXPECT_EQ(one[i].centre, four[i].centre);
    EXPECT_EQ(one[i].radius, four[i].radius);
  }
}

TEST(PaperPlacement, ProgressIsReportedUpToOne) {
  const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh("head.off"));
  std::vector<double> seen;
  PaperPlacement(1, [&](double f) { seen.push_back(f); }).place(*mesh, nullptr);
  ASSERT_FALSE(seen.empty());
  EXPECT_DOUBLE_EQ(seen.back(), 1.0);
  for (std::size_t i = 1; i < seen.size(); ++i) EXPECT_LE(seen[i - 1], seen[i]);
}

TEST(PaperPlacement, BuilderUsesPlacementOnce) {
  const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh("head.off"));
  const ClodBuilder builder(mesh);
  const auto direct = PaperPlacement().place(*mesh, nullptr);
  ASSERT_EQ(builder.placed().size(), direct.size());
  EXPECT_EQ(builder.placementStats().paired + builder.placementStats().unpaired +
                builder.placementStats().degenerate,
            mesh->size());
}

TEST(PaperPlacement, FlatArraysEqualThePlacedSpheres) {
  // placeCentres (what ClodBuilder keeps) writes the same spheres as place(), in the same order.
  for (const char* name : {"elephant.off", "mesh_with_border.off"}) {
    const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh(name));
    PlacementStats a, b;
    const auto placed = PaperPlacement(2).place(*mesh, &a);
    const PlacedCentres flat = PaperPlacement(2).placeCentres(*mesh, &b);
    ASSERT_EQ(flat.centres.size(), placed.size()) << name;
    ASSERT_EQ(flat.wrapped.size(), placed.size()) << name;
    for (std::size_t i = 0; i < placed.size(); ++i) {
      ASSERT_EQ(flat.centres[i], placed[i].centre) << name << " sphere " << i;
      ASSERT_EQ(flat.wrapped[i], placed[i].triangle) << name << " sphere " << i;
    }
    EXPECT_EQ(a.paired, b.paired);
    EXPECT_EQ(a.unpaired, b.unpaired);
    EXPECT_EQ(a.degenerate, b.degenerate);
    EXPECT_EQ(a.relaxations, b.relaxations);
  }
}

// A placement that only implements place(): the base class converts it to flat arrays.
class OneSpherePerTriangle : public SpherePlacement {
 public:
  std::vector<PlacedSphere> place(const TriangleMesh& mesh, PlacementStats* stats) const override {
    std::vector<PlacedSphere> out;
    for (std::size_t t = 0; t < mesh.size(); ++t)
      out.push_back({mesh.centroid(t), farthest(mesh, std::uint32_t(t), mesh.centroid(t)), std::uint32_t(t)});
    if (stats) stats->triangles = mesh.size();
    return out;
  }
};

TEST(SpherePlacement, DefaultFlatArraysConvertPlace) {
  const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh("head.off"));
  PlacementStats stats;
  const PlacedCentres flat = OneSpherePerTriangle().placeCentres(*mesh, &stats);
  EXPECT_EQ(stats.triangles, mesh->size());
  ASSERT_EQ(flat.centres.size(), mesh->size());
  for (std::size_t t = 0; t < mesh->size(); ++t) {
    EXPECT_EQ(flat.centres[t], mesh->centroid(t));
    EXPECT_EQ(flat.wrapped[t], t);
  }
  // A builder over it keeps exactly those centres.
  const ClodBuilder builder(mesh, std::make_shared<OneSpherePerTriangle>());
  EXPECT_EQ(builder.centres(), mesh->size());
}

}  // namespace
