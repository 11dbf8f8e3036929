// Probe generators: deterministic for a seed, near-surface probes within maxOffset of the surface,
// uniform probes inside the grown bounding box, and sortMorton a permutation.

#include <gtest/gtest.h>

#include <algorithm>

#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/probes.h"
#include "test_helpers.h"

namespace {

using namespace clod_haptics;

bool lessVec(const Vec3& a, const Vec3& b) {
  return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
}

TEST(Probes, NearSurfaceWithinOffsetAndDeterministic) {
  const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh("head.off"));
  const double offset = 0.01;
  const auto a = nearSurfaceProbes(*mesh, 3000, offset, 17);
  const auto b = nearSurfaceProbes(*mesh, 3000, offset, 17);
  const auto c = nearSurfaceProbes(*mesh, 3000, offset, 18);
  ASSERT_EQ(a.size(), 3000u);
  EXPECT_EQ(a, b) << "same seed, same probes";
  EXPECT_NE(a, c);
  std::size_t onBothSides = 0;
  for (const Vec3& p : a) {
    const ContactResult r = bruteForceQuery(*mesh, p, offset * (1 + 1e-9));
    ASSERT_TRUE(r.contact) << "probe " << p.transpose() << " farther than maxOffset from the surface";
    onBothSides += (p - r.point).dot(r.normal) > 0;
  }
  EXPECT_GT(onBothSides, 1000u);
  EXPECT_LT(onBothSides, 2000u) << "offsets on both sides of the surface";
}

TEST(Probes, NearSurfaceOnZeroAreaMesh) {
  const auto mesh = std::make_shared<const TriangleMesh>(
      makeMesh({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(2, 0, 0)}, {{0, 1, 2}}, "segment"));
  const auto p = nearSurfaceProbes(*mesh, 100, 0.1, 1);
  ASSERT_EQ(p.size(), 100u);
  for (const Vec3& x : p) {
    ASSERT_TRUE(x.allFinite());
    EXPECT_TRUE(bruteForceQuery(*mesh, x, 1e-12).contact) << "zero normal: probes stay on the segment";
  }
}

TEST(Probes, UniformInsideGrownBox) {
  const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh("elephant.off"));
  const double margin = 0.05;
  const auto p = uniformProbes(*mesh, 5000, margin, 3);
  EXPECT_EQ(p, uniformProbes(*mesh, 5000, margin, 3));
  Eigen::AlignedBox3d grown = mesh->bounds();
  grown.extend(grown.min() - Vec3::Constant(margin)).extend(grown.max() + Vec3::Constant(margin));
  Eigen::AlignedBox3d seen;
  for (const Vec3& x : p) {
    ASSERT_TRUE(grown.contains(x)) << x.transpose();
    seen.extend(x);
  }
  EXPECT_GT(seen.volume(), 0.9 * grown.volume()) << "the probes fill the box";
}

TEST(Probes, SortMortonIsAPermutationAndCoherent) {
  const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh("head.off"));
  auto p = uniformProbes(*mesh, 4000, 0.0, 9);
  auto sorted = p;
  sortMorton(sorted);
  auto a = p, b = sorted;
  std::sort(a.begin(), a.end(), lessVec);
  std::sort(b.begin(), b.end(), lessVec);
  EXPECT_EQ(a, b);
  double jumpRandom = 0, jumpSorted = 0;
  for (std::size_t i = 1; i < p.size(); ++i) {
    jumpRandom += (p[i] - p[i - 1]).norm();
    jumpSorted += (sorted[i] - sorted[i - 1]).norm();
  }
  EXPECT_LT(jumpSorted, 0.3 * jumpRandom) << "a Z-order stream moves little between probes";
  std::vector<Vec3> empty;
  sortMorton(empty);
  std::vector<Vec3> same(10, Vec3(1, 2, 3));
  sortMorton(same);
  EXPECT_EQ(same, std::vector<Vec3>(10, Vec3(1, 2, 3)));
}

}  // namespace
