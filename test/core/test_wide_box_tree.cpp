// WideBoxTree (src/core/wide_box_tree.*) and its AVX2 node tests (src/core/simd/node_filter_avx2.*): the wide tree
// against the mesh it bounds (every triangle once, every lane's box and slab holding its triangles' corners), and the
// two kernels against the geometry itself (distances sampled with closestPointOnTriangle), not against the scalar
// tests they stand in for.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "clod_haptics/core/geometry.h"
#include "clod_haptics/core/mesh_box_tree.h"
#include "simd/node_filter_avx2.h"
#include "test_helpers.h"
#include "wide_box_tree.h"

using namespace clod_haptics;
using clod_test::randomPoint;
using clod_test::randomUnit;

namespace {

/**
 * Lane k of lanes: one to four random triangles of size about scale around `around` (box rounded out to float,
 * slab and ball around their corners as a tree has them, or none when slab is false). Returns their corners, three a
 * triangle.
 */
std::vector<Vec3> randomNode(std::mt19937_64& rng, const Vec3& around, double scale, bool slab, unsigned k,
                             detail::NodeLanes& lanes) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Vec3> corners;
  for (int t = 0, n = 1 + static_cast<int>(u(rng) * 4); t < n; ++t) {
    const Vec3 centre = around + randomUnit(rng) * scale * 0.3 * u(rng);
    for (int j = 0; j < 3; ++j) corners.push_back(centre + randomUnit(rng) * scale * 0.4 * u(rng));
  }
  Vec3 lo = corners[0], hi = corners[0], c = Vec3::Zero(), normal = Vec3::Zero();
  for (const Vec3& v : corners) {
    lo = lo.cwiseMin(v);
    hi = hi.cwiseMax(v);
    c += v / static_cast<double>(corners.size());
  }
  for (std::size_t t = 0; t < corners.size(); t += 3)
    normal += (corners[t + 1] - corners[t]).cross(corners[t + 2] - corners[t]);
  normal = normal.norm() > 0.0 ? Vec3(normal.normalized()) : randomUnit(rng);
  double thick = 0.0, radius = 0.0;
  for (const Vec3& v : corners) {
    thick = std::max(thick, std::abs(normal.dot(v - c)));
    radius = std::max(radius, (v - c).norm());
  }
  for (int j = 0; j < 3; ++j) {
    lanes.lo[j][k] = std::nextafter(static_cast<float>(lo[j]), -HUGE_VALF);
    lanes.hi[j][k] = std::nextafter(static_cast<float>(hi[j]), HUGE_VALF);
    lanes.centre[j][k] = slab ? c[j] : 0.0;
    lanes.normal[j][k] = slab ? normal[j] : 0.0;
  }
  lanes.thick[k] = slab ? thick * (1.0 + 1e-9) + 1e-12 * radius : std::numeric_limits<double>::infinity();
  lanes.radius[k] = slab ? radius * (1.0 + 1e-9) : std::numeric_limits<double>::infinity();
  return corners;
}

double nearestTo(const Vec3& p, const std::vector<Vec3>& corners) {
  double nearest = std::numeric_limits<double>::infinity();
  for (std::size_t j = 0; j < corners.size(); j += 3)
    nearest = std::min(nearest, (closestPointOnTriangle(p, corners[j], corners[j + 1], corners[j + 2]) - p).norm());
  return nearest;
}

}  // namespace

// Every shared mesh's tree, four-wide at two cuts: each triangle in exactly one lane's run, each lane's box and slab
// holding the corners of the triangles below it, and every node reached once from the root.
TEST(WideBoxTree, ListsEveryTriangleOnceUnderBoxesAndSlabsThatHoldIt) {
  for (const std::string& path : clod_test::sharedMeshes()) {
    SCOPED_TRACE(path);
    const auto mesh = clod_test::loadNormalized(path);
    const auto tree = meshBoxTreeOf(*mesh);
    for (std::uint32_t cut : {4u, 8u}) {
      const auto wide = WideBoxTree::build(*tree, cut);
      ASSERT_NE(wide, nullptr);
      std::vector<int> seen(mesh->size(), 0), reached(wide->nodes.size(), 0);
      std::size_t bad = 0;
      std::vector<std::uint32_t> todo{0};
      reached[0] = 1;
      while (!todo.empty()) {
        const WideBoxTree::Node& node = wide->nodes[todo.back()];
        todo.pop_back();
        ASSERT_GE(node.count, 1u);
        ASSERT_LE(node.count, 4u);
        for (std::uint32_t k = 0; k < node.count; ++k) {
          if (node.few[k] == 0) {
            ASSERT_LT(node.child[k], wide->nodes.size());
            ++reached[node.child[k]];
            todo.push_back(node.child[k]);
            continue;
          }
          EXPECT_LE(node.few[k], std::max(cut, static_cast<std::uint32_t>(kMeshBoxTreeLeafSize)));
          for (std::uint32_t i = node.child[k]; i < node.child[k] + node.few[k]; ++i) {
            const std::uint32_t t = tree->order[i];
            ++seen[t];
            for (int v = 0; v < 3; ++v) {
              const Vec3& x = mesh->vertex(t, v);
              for (int j = 0; j < 3; ++j) bad += !(node.lanes.lo[j][k] <= x[j] && x[j] <= node.lanes.hi[j][k]);
              if (node.lanes.radius[k] < std::numeric_limits<double>::infinity()) {
                const Vec3 c(node.lanes.centre[0][k], node.lanes.centre[1][k], node.lanes.centre[2][k]);
                const Vec3 n(node.lanes.normal[0][k], node.lanes.normal[1][k], node.lanes.normal[2][k]);
                bad += !(std::abs(n.dot(x - c)) <= node.lanes.thick[k] && (x - c).norm() <= node.lanes.radius[k]);
              }
            }
          }
        }
      }
      EXPECT_EQ(bad, 0u);
      EXPECT_EQ(std::count(seen.begin(), seen.end(), 1), static_cast<long>(mesh->size()));
      EXPECT_EQ(std::count(reached.begin(), reached.end(), 1), static_cast<long>(wide->nodes.size()));
    }
  }
}

#if defined(CLOD_PACKET_AVX2)
// The swept query's four-node test (SweptSphereQuery::sweepWide): four random nodes, sweeps at every angle, the reach
// set at the least distance sampled along the sweep up to the best time so far, nudged a few ulps either way, and a
// plane under the start now and then (the hint's: a height difference bounds the distance). A node with a triangle
// that some sampled centre comes within the reach of must be kept, entered no later than that centre; most of the
// others should be dropped.
TEST(NodeFilterAvx2, KeepsEveryNodeASweepComesWithinReachOf) {
  if (!__builtin_cpu_supports("avx2")) GTEST_SKIP() << "no AVX2 on this CPU";
  std::mt19937_64 rng(31);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  clod_test::FilterTally tally;
  std::size_t late = 0;
  for (int round = 0; round < 4000; ++round) {
    double scale;
    const Vec3 a = randomPoint(rng, round, scale);
    Vec3 d = round % 7 == 0 ? Vec3(Vec3::Zero()) : Vec3(randomUnit(rng) * scale * std::pow(10.0, -3.0 + 3.5 * u(rng)));
    if (round % 11 == 0) d[round % 3] = 0.0;  // parallel to a face of every box
    const double tMax = round % 3 == 0 ? u(rng) : std::numeric_limits<double>::infinity();
    const unsigned count = 1 + static_cast<unsigned>(round % 4);
    detail::NodeLanes lanes{};
    double nearest[4], nearestAt[4];
    for (unsigned k = 0; k < count; ++k) {
      const Vec3 around = a + d * u(rng) + randomUnit(rng) * scale * (0.2 + 1.5 * u(rng));
      const std::vector<Vec3> corners = randomNode(rng, around, scale, round % 5 != 0, k, lanes);
      nearest[k] = nearestAt[k] = std::numeric_limits<double>::infinity();
      for (int i = 0; i <= 400; ++i) {
        const double t = std::min(1.0, tMax) * i / 400.0;
        const double dist = nearestTo(a + t * d, corners);
        if (dist < nearest[k]) {
          nearest[k] = dist;
          nearestAt[k] = t;
        }
      }
    }
    const double reach = nearest[round % count] * (1.0 + 1e-15 * (round % 5 - 2)) + 1e-300;
    detail::NodeFilterSweep s{};
    for (int j = 0; j < 3; ++j) {
      s.a[j] = a[j];
      s.d[j] = d[j];
      s.inv[j] = d[j] != 0.0 ? 1.0 / d[j] : 0.0;
    }
    s.grow = s.reach = reach;
    s.tMax = tMax;
    s.plane = round % 4 == 1;
    if (s.plane) {  // a plane the sweep starts above, as the hint's (Best::makePlane, clearance)
      const Vec3 n = randomUnit(rng);
      const double startHeight = scale * u(rng), climb = n.dot(d);
      for (int j = 0; j < 3; ++j) s.n[j] = n[j];
      s.offset = n.dot(a) - startHeight;
      s.clearance = startHeight + std::min(0.0, std::min(1.0, tMax) * climb) - reach;
    }
    double enter[4];
    const unsigned mask = detail::nodeFilterAvx2(lanes, count, s, enter);
    EXPECT_EQ(mask >> count, 0u);
    for (unsigned k = 0; k < count; ++k) {
      const bool reached = nearest[k] <= reach, got = (mask >> k) & 1u;
      tally.count(reached, got);
      late += reached && got && !(enter[k] <= nearestAt[k]);
    }
  }
  tally.expectConservative(2000, "nodes");
  EXPECT_EQ(late, 0u) << "nodes entered after a centre within reach";
}

// The point query's four-node test (ClodDetector's walk over the mesh): four random nodes around a point, the squared
// distance bound set at one node's distance nudged a few ulps either way. A node with a triangle within it must be
// kept, with a lower bound no larger than its distance; most of the others should be dropped.
TEST(NodeNearAvx2, KeepsEveryNodeWithinTheDistanceAndBoundsItFromBelow) {
  if (!__builtin_cpu_supports("avx2")) GTEST_SKIP() << "no AVX2 on this CPU";
  std::mt19937_64 rng(37);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  clod_test::FilterTally tally;
  std::size_t above = 0;
  for (int round = 0; round < 20000; ++round) {
    double scale;
    const Vec3 p = randomPoint(rng, round, scale);
    const unsigned count = 1 + static_cast<unsigned>(round % 4);
    detail::NodeLanes lanes{};
    double nearest[4];
    for (unsigned k = 0; k < count; ++k) {
      const Vec3 around = p + randomUnit(rng) * scale * (0.2 + 1.5 * u(rng));
      nearest[k] = nearestTo(p, randomNode(rng, around, scale, round % 5 != 0, k, lanes));
    }
    const double bound = nearest[round % count] * nearest[round % count] * (1.0 + 1e-15 * (round % 5 - 2));
    const double q[3] = {p.x(), p.y(), p.z()};
    double near[4];
    const unsigned mask = detail::nodeNearAvx2(lanes, count, q, bound, near);
    EXPECT_EQ(mask >> count, 0u);
    for (unsigned k = 0; k < count; ++k) {
      const double d2 = nearest[k] * nearest[k];
      tally.count(d2 <= bound, (mask >> k) & 1u);
      above += !(near[k] <= d2 * (1.0 + 1e-12));
    }
  }
  tally.expectConservative(5000, "nodes");
  EXPECT_EQ(above, 0u) << "lower bounds above a node's distance";
}
#endif
