// buildBoxTree: the float bounds of every node contain, in double precision, every box below it (the
// float path's bound: outward rounding, so a test against a node never rejects what its items accept),
// every item appears exactly once, and leaves respect the leaf size.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "clod_haptics/core/box_tree.h"

namespace {

using Box = Eigen::AlignedBox3d;
using V = Eigen::Vector3d;

struct Walk {
  const std::vector<clod_haptics::BoxNode>& nodes;
  const std::vector<std::uint32_t>& order;
  const std::vector<Box>& boxes;
  std::uint32_t base;
  std::vector<int> seen;
  int leafSize;
  int depth = 0;

  // Returns the double box of everything below node n, checking containment on the way.
  Box visit(std::uint32_t n, int d) {
    depth = std::max(depth, d);
    const clod_haptics::BoxNode& node = nodes[n];
    Box below;
    below.setEmpty();
    if (node.count > 0) {
      EXPECT_LE(node.count, std::uint32_t(leafSize));
      for (std::uint32_t i = node.first; i < node.first + node.count; ++i) {
        const std::uint32_t item = order[i];
        EXPECT_LT(item, boxes.size());
        ++seen[item];
        below.extend(boxes[item]);
      }
    } else {
      EXPECT_GT(node.first, n + 1) << "right child after the left subtree";
      below.extend(visit(n + 1, d + 1));
      below.extend(visit(node.first, d + 1));
    }
    for (int k = 0; k < 3; ++k) {
      EXPECT_LE(double(node.lo[k]), below.min()[k]) << "node " << n << " axis " << k;
      EXPECT_GE(double(node.hi[k]), below.max()[k]) << "node " << n << " axis " << k;
    }
    return below;
  }
};

void checkTree(const std::vector<Box>& boxes, int leafSize, double pad) {
  std::vector<clod_haptics::BoxNode> nodes;
  std::vector<std::uint32_t> order{7, 7, 7};  // the tree appends after what is already there
  const std::uint32_t root = clod_haptics::buildBoxTree(boxes, leafSize, pad, nodes, order);
  ASSERT_EQ(order.size(), 3 + boxes.size());
  Walk w{nodes, order, boxes, 3, std::vector<int>(boxes.size(), 0), leafSize};
  w.visit(root, 0);
  for (std::size_t i = 0; i < boxes.size(); ++i) EXPECT_EQ(w.seen[i], 1) << "item " << i;
  EXPECT_LE(w.depth, 2 * int(std::log2(double(boxes.size()) + 1)) + 2) << "median splits keep it balanced";
  // squaredDistanceToNode never exceeds the distance to any box below (checked at the root).
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u(-3, 3);
  for (int i = 0; i < 2000; ++i) {
    const V p(u(rng), u(rng), u(rng));
    double nearest = std::numeric_limits<double>::infinity();
    for (const Box& b : boxes) nearest = std::min(nearest, b.squaredExteriorDistance(p));
    ASSERT_LE(clod_haptics::squaredDistanceToNode(nodes[root], p.x(), p.y(), p.z()), nearest);
  }
}

std::vector<Box> randomBoxes(std::mt19937_64& rng, std::size_t n, double scale, const V& offset) {
  std::uniform_real_distribution<double> u(-1, 1), s(0, 0.1);
  std::vector<Box> boxes;
  for (std::size_t i = 0; i < n; ++i) {
    const V c = offset + scale * V(u(rng), u(rng), u(rng));
    const V e = scale * V(s(rng), s(rng), s(rng));
    boxes.emplace_back(c - e, c + e);
  }
  return boxes;
}

TEST(BoxTree, FloatBoundsContainDoubleBoxes) {
  std::mt19937_64 rng(42);
  for (int leaf : {1, 4, 8}) checkTree(randomBoxes(rng, 1000, 1.0, V::Zero()), leaf, 0.0);
  // Coordinates that are not floats, far from the origin, tiny and huge.
  checkTree(randomBoxes(rng, 500, 1e-3, V(1e6 + 0.1, -1e6 - 0.3, 12345.678901)), 4, 0.0);
  checkTree(randomBoxes(rng, 500, 1e-9, V(0.1, 0.2, 0.3)), 4, 0.0);
  checkTree(randomBoxes(rng, 500, 1e20, V::Zero()), 4, 0.0);
  checkTree(randomBoxes(rng, 300, 1.0, V::Zero()), 4, 1e-3);
  // Degenerate boxes (points) and duplicates.
  std::vector<Box> points;
  for (int i = 0; i < 100; ++i) points.emplace_back(V(0.1 * i, 0.3, 0.7), V(0.1 * i, 0.3, 0.7));
  points.insert(points.end(), points.begin(), points.begin() + 50);
  checkTree(points, 4, 0.0);
}

// A large tree's root subtrees are built on two threads: the same tree, node for node and in the same order, as
// one thread builds, appended after what the arrays held (the right subtree's child indices shifted), and it keeps
// the contract checkTree checks.
TEST(BoxTree, TwoThreadsBuildTheSameTree) {
  std::mt19937_64 rng(7);
  for (int leaf : {1, 4}) {
    SCOPED_TRACE(leaf);
    const std::vector<Box> boxes = randomBoxes(rng, 40000, 1.0, V::Zero());
    std::vector<clod_haptics::BoxNode> one(5, clod_haptics::BoxNode{}), two(5, clod_haptics::BoxNode{});
    std::vector<std::uint32_t> orderOne{1, 2}, orderTwo{1, 2};
    const std::uint32_t rootOne = clod_haptics::buildBoxTree(boxes, leaf, 0.0, one, orderOne, 1);
    const std::uint32_t rootTwo = clod_haptics::buildBoxTree(boxes, leaf, 0.0, two, orderTwo, 2);
    EXPECT_EQ(rootOne, 5u);
    EXPECT_EQ(rootOne, rootTwo);
    ASSERT_EQ(one.size(), two.size());
    for (std::size_t n = 0; n < one.size(); ++n) {
      ASSERT_EQ(one[n].first, two[n].first) << "node " << n;
      ASSERT_EQ(one[n].count, two[n].count) << "node " << n;
      for (int k = 0; k < 3; ++k) {
        ASSERT_EQ(one[n].lo[k], two[n].lo[k]) << "node " << n;
        ASSERT_EQ(one[n].hi[k], two[n].hi[k]) << "node " << n;
      }
    }
    EXPECT_EQ(orderOne, orderTwo);
    checkTree(boxes, leaf, 0.0);
  }
}

// boxTreeNodeCount counts, from the item count alone, the nodes buildBoxTree makes (what a caller sizing memory
// before the build relies on).
TEST(BoxTree, NodeCountIsKnownBeforeTheBuild) {
  std::mt19937_64 rng(11);
  for (int leaf : {1, 2, 4, 7}) {
    for (std::size_t n : {0, 1, 2, 3, 4, 5, 7, 8, 9, 15, 16, 17, 100, 1000, 1023, 1025, 4097, 20000}) {
      const std::vector<Box> boxes = randomBoxes(rng, n, 1.0, V::Zero());
      std::vector<clod_haptics::BoxNode> nodes;
      std::vector<std::uint32_t> order;
      clod_haptics::buildBoxTree(boxes, leaf, 0.0, nodes, order);
      EXPECT_EQ(clod_haptics::boxTreeNodeCount(n, leaf), nodes.size()) << n << " items, leaves of " << leaf;
    }
  }
}

TEST(BoxTree, EmptyInputHasNoRoot) {
  std::vector<clod_haptics::BoxNode> nodes;
  std::vector<std::uint32_t> order;
  EXPECT_EQ(clod_haptics::buildBoxTree({}, 4, 0.0, nodes, order), std::numeric_limits<std::uint32_t>::max());
  EXPECT_TRUE(nodes.empty());
}

}  // namespace
