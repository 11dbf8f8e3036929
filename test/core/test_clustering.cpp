// SingleLinkClustering against a naive O(n^2) single-link written here: union-find over every pair
// closer than d (Euclidean, strict), partitions compared up to label renaming.

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "clod_haptics/core/clustering.h"
#include "clod_haptics/core/errors.h"

namespace {

using namespace clod_haptics;

// Naive single-link: label propagation by depth-first search over the "closer than d" graph.
std::vector<std::uint32_t> naiveSingleLink(const std::vector<Vec3>& points, double d) {
  const std::size_t n = points.size();
  std::vector<std::uint32_t> labels(n, std::numeric_limits<std::uint32_t>::max());
  std::uint32_t next = 0;
  std::vector<std::size_t> stack;
  for (std::size_t s = 0; s < n; ++s) {
    if (labels[s] != std::numeric_limits<std::uint32_t>::max()) continue;
    labels[s] = next;
    stack.assign(1, s);
    while (!stack.empty()) {
      const std::size_t i = stack.back();
      stack.pop_back();
      for (std::size_t j = 0; j < n; ++j)
        if (labels[j] == std::numeric_limits<std::uint32_t>::max() && (points[i] - points[j]).norm() < d) {
          labels[j] = next;
          stack.push_back(j);
        }
    }
    ++next;
  }
  return labels;  // numbered in the order of each cluster's first point
}

// Renumbers labels in the order of first appearance, so two partitions compare equal iff they are
// the same up to renaming.
std::vector<std::uint32_t> canonical(const std::vector<std::uint32_t>& labels) {
  std::vector<std::uint32_t> map(labels.size() + 1, std::numeric_limits<std::uint32_t>::max()), out(labels.size());
  std::uint32_t next = 0;
  for (std::size_t i = 0; i < labels.size(); ++i) {
    if (labels[i] >= map.size()) return {};  // a label out of range never matches
    if (map[labels[i]] == std::numeric_limits<std::uint32_t>::max()) map[labels[i]] = next++;
    out[i] = map[labels[i]];
  }
  return out;
}

std::vector<Vec3> uniformPoints(std::mt19937_64& rng, std::size_t n, double extent, const Vec3& origin) {
  std::uniform_real_distribution<double> u(0.0, extent);
  std::vector<Vec3> pts(n);
  for (auto& p : pts) p = origin + Vec3(u(rng), u(rng), u(rng));
  return pts;
}

std::vector<Vec3> clusteredPoints(std::mt19937_64& rng, std::size_t n, std::size_t blobs, double spread) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g(0.0, spread);
  std::vector<Vec3> centres(blobs);
  for (auto& c : centres) c = Vec3(u(rng), u(rng), u(rng));
  std::vector<Vec3> pts(n);
  for (auto& p : pts) p = centres[static_cast<std::size_t>(u(rng) * blobs) % blobs] + Vec3(g(rng), g(rng), g(rng));
  return pts;
}

void expectSameAsNaive(const std::vector<Vec3>& pts, double d, const std::string& what, unsigned threads = 0) {
  SingleLinkClustering clustering(threads);
  std::vector<std::uint32_t> labels;
  const std::uint32_t k = clustering.cluster(pts, d, labels);
  ASSERT_EQ(labels.size(), pts.size()) << what;
  const auto naive = naiveSingleLink(pts, d);
  const std::uint32_t naiveK = naive.empty() ? 0 : *std::max_element(naive.begin(), naive.end()) + 1;
  ASSERT_EQ(k, naiveK) << what << " d=" << d;
  ASSERT_EQ(canonical(labels), naive) << what << " d=" << d;
  // The documented numbering: in the order of each cluster's first point.
  EXPECT_EQ(labels, canonical(labels)) << what;
}

TEST(SingleLinkClustering, EqualsNaiveOnUniformPoints) {
  int cases = 0;
  for (std::uint64_t seed = 0; seed < 12; ++seed) {
    std::mt19937_64 rng(seed);
    const auto pts = uniformPoints(rng, 300 + 100 * seed, 1.0, Vec3::Zero());
    for (double d : {1e-4, 0.01, 0.03, 0.05, 0.08, 0.15, 0.4, 2.0}) {
      expectSameAsNaive(pts, d, "uniform seed " + std::to_string(seed));
      ++cases;
    }
  }
  EXPECT_EQ(cases, 96);
}

TEST(SingleLinkClustering, EqualsNaiveOnClusteredPoints) {
  for (std::uint64_t seed = 100; seed < 112; ++seed) {
    std::mt19937_64 rng(seed);
    const auto pts = clusteredPoints(rng, 1200, 3 + seed % 10, 0.01 + 0.005 * (seed % 4));
    for (double d : {0.001, 0.005, 0.01, 0.02, 0.04, 0.08}) expectSameAsNaive(pts, d, "blobs seed " + std::to_string(seed));
  }
}

TEST(SingleLinkClustering, EqualsNaiveFarFromOriginAndAtOtherScales) {
  for (std::uint64_t seed = 200; seed < 206; ++seed) {
    std::mt19937_64 rng(seed);
    for (double scale : {1e-6, 1e3, 1e6}) {
      const auto pts = uniformPoints(rng, 600, scale, Vec3::Constant(1e6 * (seed % 2 ? -1 : 1)));
      for (double d : {0.02, 0.05, 0.1}) expectSameAsNaive(pts, d * scale, "offset/scale seed " + std::to_string(seed));
    }
  }
}

TEST(SingleLinkClustering, StrictLessOnALattice) {
  // Integer lattice, spacing 1: at d = 1 nothing merges (strict), just above 1 everything does.
  std::vector<Vec3> pts;
  for (int x = 0; x < 6; ++x)
    for (int y = 0; y < 5; ++y)
      for (int z = 0; z < 4; ++z) pts.emplace_back(x, y, z);
  SingleLinkClustering clustering;
  std::vector<std::uint32_t> labels;
  EXPECT_EQ(clustering.cluster(pts, 1.0, labels), pts.size());
  EXPECT_EQ(clustering.cluster(pts, 1.0000001, labels), 1u);
  expectSameAsNaive(pts, 1.0, "lattice");
  expectSameAsNaive(pts, 1.0000001, "lattice");
  expectSameAsNaive(pts, std::sqrt(2.0) + 1e-9, "lattice diagonal");
}

TEST(SingleLinkClustering, ChainsMergeAcrossManyCells) {
  // A straight chain with spacing 2^-7 (exact in binary): one cluster for any d above the spacing,
  // even though its ends are far apart; none at d equal to the spacing (strict).
  const double spacing = 0.0078125;
  std::vector<Vec3> pts;
  for (int i = 0; i < 500; ++i) pts.emplace_back(spacing * i, 0.375, 0.75);
  SingleLinkClustering clustering;
  std::vector<std::uint32_t> labels;
  EXPECT_EQ(clustering.cluster(pts, 0.01, labels), 1u);
  EXPECT_EQ(clustering.cluster(pts, spacing * 1.0001, labels), 1u);
  EXPECT_EQ(clustering.cluster(pts, spacing, labels), 500u);
  expectSameAsNaive(pts, spacing, "chain");
  expectSameAsNaive(pts, 0.01, "chain");
}

TEST(SingleLinkClustering, ZeroDistanceKeepsEveryCentreEvenDuplicates) {
  std::mt19937_64 rng(7);
  auto pts = uniformPoints(rng, 1000, 1.0, Vec3::Zero());
  pts.insert(pts.end(), pts.begin(), pts.begin() + 100);  // exact duplicates
  SingleLinkClustering clustering;
  std::vector<std::uint32_t> labels;
  ASSERT_EQ(clustering.cluster(pts, 0.0, labels), pts.size());
  std::vector<std::uint32_t> expected(pts.size());
  std::iota(expected.begin(), expected.end(), 0u);
  EXPECT_EQ(labels, expected);
  // A small positive d merges exactly the duplicates.
  EXPECT_EQ(clustering.cluster(pts, 1e-9, labels), 1000u);
}

TEST(SingleLinkClustering, TinyPositiveDistanceMergesDuplicates) {
  // Duplicates are at distance 0 < d for every d > 0, however small: d * d must not underflow to 0.
  std::mt19937_64 rng(8);
  auto pts = uniformPoints(rng, 200, 1.0, Vec3::Zero());
  pts.insert(pts.end(), pts.begin(), pts.begin() + 50);
  SingleLinkClustering clustering;
  std::vector<std::uint32_t> labels;
  for (double d : {1e-200, 1e-300, std::numeric_limits<double>::denorm_min()})
    EXPECT_EQ(clustering.cluster(pts, d, labels), 200u) << "d = " << d;
}

TEST(SingleLinkClustering, EmptyAndSinglePoint) {
  SingleLinkClustering clustering;
  std::vector<std::uint32_t> labels{5, 6};
  EXPECT_EQ(clustering.cluster({}, 0.1, labels), 0u);
  EXPECT_TRUE(labels.empty());
  EXPECT_EQ(clustering.cluster({Vec3(1, 2, 3)}, 0.1, labels), 1u);
  EXPECT_EQ(labels, std::vector<std::uint32_t>{0});
}

TEST(SingleLinkClustering, BadDistanceThrowsInvalidParameter) {
  SingleLinkClustering clustering;
  std::vector<std::uint32_t> labels;
  const std::vector<Vec3> pts{Vec3(0, 0, 0), Vec3(1, 0, 0)};
  for (double d : {-1e-12, -1.0, std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity(),
                   -std::numeric_limits<double>::infinity()})
    EXPECT_THROW(clustering.cluster(pts, d, labels), InvalidParameter) << "d = " << d;
}

TEST(SingleLinkClustering, EqualsNaiveWithManyMoreCellsThanTheTableStartsWith) {
  // The cell table starts small and grows: thousands of occupied cells (most points alone in theirs),
  // with exact duplicates mixed in, still give the naive partition.
  std::mt19937_64 rng(300);
  auto pts = uniformPoints(rng, 5000, 1.0, Vec3::Constant(-0.5));
  pts.insert(pts.end(), pts.begin() + 1000, pts.begin() + 1400);
  for (double d : {1e-9, 2e-3, 0.02}) expectSameAsNaive(pts, d, "many cells");
}

TEST(SingleLinkClustering, EqualsNaiveOnTwoThreads) {
  // Enough points for two threads (kMinPointsPerThread each), asked for explicitly so that the split
  // passes and the shared union-find run whatever the hardware: blobs with exact duplicates across the
  // two halves of the points, at distances where neighbours are found by the sorted sweep (0.004,
  // 0.012) and by hashing (1e-9: too many cells per axis to pack), then far from the origin, where cells
  // cannot be finer than 1e-12 of the extent and nearly every point is loose (tested one by one).
  std::mt19937_64 rng(500);
  const std::size_t n = 2 * SingleLinkClustering::kMinPointsPerThread + 2500;
  auto blobs = clusteredPoints(rng, n, 40, 0.01);
  blobs.insert(blobs.end(), blobs.begin(), blobs.begin() + 800);
  for (double d : {1e-9, 0.004, 0.012}) expectSameAsNaive(blobs, d, "two threads, blobs", 2);
  const auto far = uniformPoints(rng, n, 1e-6, Vec3::Constant(1e6));
  expectSameAsNaive(far, 0.05e-6, "two threads, far from the origin", 2);
}

// The cube rule read literally, written here: the cube index of each point along each axis from the
// points' bounding box, clusters numbered in the order of their first point.
std::vector<std::uint32_t> naiveCubes(const std::vector<Vec3>& points, double d) {
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity());
  for (const Vec3& p : points) lo = lo.cwiseMin(p);
  std::vector<std::array<long long, 3>> seen;
  std::vector<std::uint32_t> labels;
  for (const Vec3& p : points) {
    std::array<long long, 3> key{};
    for (int k = 0; k < 3; ++k) key[k] = static_cast<long long>(std::floor((p[k] - lo[k]) / d));
    const auto it = std::find(seen.begin(), seen.end(), key);
    labels.push_back(static_cast<std::uint32_t>(it - seen.begin()));
    if (it == seen.end()) seen.push_back(key);
  }
  return labels;
}

TEST(CubeClustering, EqualsTheCubeRuleWrittenOut) {
  std::mt19937_64 rng(400);
  const auto pts = clusteredPoints(rng, 4000, 7, 0.05);
  CubeClustering clustering;
  std::vector<std::uint32_t> labels;
  for (double d : {0.003, 0.01, 0.02, 0.08, 0.5}) {
    const auto expected = naiveCubes(pts, d);
    const std::uint32_t k = clustering.cluster(pts, d, labels);
    EXPECT_EQ(k, *std::max_element(expected.begin(), expected.end()) + 1) << "d = " << d;
    EXPECT_EQ(labels, expected) << "d = " << d;
  }
  ASSERT_EQ(clustering.cluster(pts, 0.0, labels), pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) EXPECT_EQ(labels[i], i);
}

TEST(RequireClustering, KnownNamesGiveTheirStrategyUnknownOnesAnErrorNamingTheParameter) {
  EXPECT_NE(std::dynamic_pointer_cast<const SingleLinkClustering>(requireClustering("single-link", "~clustering")),
            nullptr);
  EXPECT_NE(std::dynamic_pointer_cast<const CubeClustering>(requireClustering("cube", "~clustering")), nullptr);
  EXPECT_NE(requireClustering("tight", "~clustering"), nullptr);
  for (const char* bad : {"", "single_link", "Cube", "tight "}) {
    try {
      requireClustering(bad, "/sphere_builder/clustering");
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const InvalidParameter& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("/sphere_builder/clustering"), std::string::npos) << what;
      EXPECT_NE(what.find("'" + std::string(bad) + "'"), std::string::npos) << what;
      EXPECT_NE(what.find("single-link"), std::string::npos) << what;
    }
  }
}

}  // namespace
