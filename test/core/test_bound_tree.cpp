// BoundTree: the spheres it lists for a ball hold every sphere the ball reaches (brute force over all of them),
// after building and after spheres move, change radius or grow, or are switched off (NaN centre); far from them it
// lists none; a list longer than the caller's array reports its length.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "clod_haptics/core/bound_tree.h"

namespace {

using namespace clod_haptics;

struct Spheres {
  std::vector<double> x, y, z, radius, grow;
  bool reaches(std::size_t i, const Vec3& p, double r, bool grown) const {
    const double reach = radius[i] + r + (grown ? grow[i] : 0.0);
    return (p - Vec3(x[i], y[i], z[i])).squaredNorm() <= reach * reach;  // NaN: false
  }
};

Spheres randomSpheres(std::size_t n, double spread, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0), size(0.01, 0.2);
  Spheres s;
  for (std::size_t i = 0; i < n; ++i) {
    s.x.push_back(spread * u(rng));
    s.y.push_back(spread * u(rng));
    s.z.push_back(0.2 * spread * u(rng));
    s.radius.push_back(size(rng));
    s.grow.push_back(i % 3 == 0 ? 0.5 * size(rng) : 0.0);
  }
  return s;
}

// Every sphere a ball reaches is listed, each once; returns how many were listed in all.
std::size_t expectListsEveryReached(const BoundTree& tree, const Spheres& s, const Vec3& p, double r, bool grown) {
  std::vector<std::uint32_t> out(s.x.size() + 1);
  const std::size_t n = tree.candidates(p, r, grown, out.data(), out.size());
  EXPECT_LE(n, s.x.size());
  std::vector<std::uint32_t> listed(out.begin(), out.begin() + static_cast<std::ptrdiff_t>(n));
  std::sort(listed.begin(), listed.end());
  EXPECT_EQ(std::adjacent_find(listed.begin(), listed.end()), listed.end()) << "a sphere listed twice";
  for (std::size_t i = 0; i < s.x.size(); ++i)
    if (s.reaches(i, p, r, grown))
      EXPECT_TRUE(std::binary_search(listed.begin(), listed.end(), i)) << "sphere " << i << " reached, not listed";
  return n;
}

TEST(BoundTree, ListsEverySphereABallReachesAsTheyMove) {
  std::mt19937_64 rng(3);
  for (std::size_t count : {1u, 3u, 4u, 5u, 17u, 50u, 300u}) {
    Spheres s = randomSpheres(count, 2.0, rng);
    BoundTree tree;
    tree.build(s.x.data(), s.y.data(), s.z.data(), s.radius.data(), s.grow.data(), count);
    ASSERT_EQ(tree.size(), count);
    std::uniform_real_distribution<double> u(-2.5, 2.5), r(0.0, 0.1);
    std::size_t listed = 0;
    for (int round = 0; round < 6; ++round) {
      for (int k = 0; k < 300; ++k) {
        const Vec3 p(u(rng), u(rng), 0.3 * u(rng));
        const double radius = r(rng);
        for (bool grown : {false, true}) {
          const std::size_t n = expectListsEveryReached(tree, s, p, radius, grown);
          if (round == 0) listed += n;  // the layout the build chose: moved spheres only slow it down
        }
        if (HasFailure()) return;
      }
      // Move a third of the spheres far (another layout than the build's), resize some, switch one off and one on.
      std::uniform_real_distribution<double> pick(0.0, 1.0);
      for (std::uint32_t i = 0; i < count; ++i) {
        if (pick(rng) < 0.33) {
          s.x[i] = 2.0 * u(rng);
          s.y[i] = 2.0 * u(rng);
          s.radius[i] *= 0.5 + pick(rng);
          s.grow[i] = pick(rng) < 0.3 ? 0.1 * pick(rng) : 0.0;
        }
        if (i == static_cast<std::uint32_t>(round) % count)
          s.x[i] = std::isnan(s.x[i]) ? 0.0 : std::numeric_limits<double>::quiet_NaN();
        tree.update(i, s.x.data(), s.y.data(), s.z.data(), s.radius.data(), s.grow.data());
      }
    }
    // Where the spheres still lie as built, a query lists a few leaves' worth, not all of them (600 queries).
    if (count >= 50) EXPECT_LT(listed, 600 * count / 8) << count << " spheres: the tree must prune";
  }
}

TEST(BoundTree, FarPointsListNothingAndALongListReportsItsLength) {
  std::mt19937_64 rng(5);
  Spheres s = randomSpheres(100, 1.0, rng);
  BoundTree tree;
  tree.build(s.x.data(), s.y.data(), s.z.data(), s.radius.data(), s.grow.data(), 100);
  std::uint32_t out[8];
  EXPECT_EQ(tree.candidates(Vec3(50, 50, 50), 0.1, true, out, 8), 0u);
  // A ball holding everything: all 100 reached, 8 written, 100 reported.
  std::size_t all = 0;
  for (std::size_t i = 0; i < 100; ++i) all += s.reaches(i, Vec3::Zero(), 10.0, false);
  ASSERT_EQ(all, 100u);
  EXPECT_EQ(tree.candidates(Vec3::Zero(), 10.0, false, out, 8), 100u);
  // An empty tree lists nothing.
  BoundTree empty;
  empty.build(nullptr, nullptr, nullptr, nullptr, nullptr, 0);
  EXPECT_EQ(empty.candidates(Vec3::Zero(), 1.0, true, out, 8), 0u);
}

}  // namespace
