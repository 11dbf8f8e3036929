#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace clod_haptics {

/**
 * \brief One node of a bounding-box tree kept in a flat array (depth first, left child next to its
 * parent). Bounds are float, rounded outward and padded, so a test against them never rejects what
 * the double-precision geometry inside would accept.
 */
struct BoxNode {
  float lo[3];
  float hi[3];
  std::uint32_t first;  ///< leaf: first entry of its run in the order array; inner: absolute index of the right child
  std::uint32_t count;  ///< leaf: number of items (> 0); inner: 0
};

/**
 * \brief Builds a tree over items given by their boxes (median split on the longest axis of the
 * box centres), appending its nodes to nodes and the item order to order.
 * \param pad absolute padding added around every box before rounding to float
 * \param threads 2 (the default) builds the root's two subtrees on two threads when there are many items; the
 * tree is the same node for node with 1
 * \return index of the root in nodes, or UINT32_MAX when there are no items
 */
std::uint32_t buildBoxTree(const std::vector<Eigen::AlignedBox3d>& boxes, int leafSize, double pad,
                           std::vector<BoxNode>& nodes, std::vector<std::uint32_t>& order, unsigned threads = 2);

/**
 * \brief How many nodes buildBoxTree makes for items items with leaves of leafSize (it splits every run at its
 * middle, so the count depends on nothing else): what a caller sizing memory ahead of the build can count on.
 */
std::size_t boxTreeNodeCount(std::size_t items, int leafSize);

/**
 * \brief Whether a node's box holds box padded by pad, compared in double (the build rounds the padded box outward
 * to float, so a built tree's leaf holds its items' boxes exactly by this test).
 */
inline bool nodeHoldsPadded(const BoxNode& node, const Eigen::AlignedBox3d& box, double pad) {
  for (int k = 0; k < 3; ++k)
    if (!(node.lo[k] <= box.min()[k] - pad && node.hi[k] >= box.max()[k] + pad)) return false;
  return true;
}

/** \brief The deepest tree the walks follow: their stacks hold 64 (detector) and 128 (swept query) entries. */
constexpr int kMaxBoxTreeDepth = 60;

/**
 * \brief Why nodes and order are not a tree over `items` items that the walks can follow, or "" when they are: a
 * depth-first layout from the root at 0 (every inner node's children after it and inside the array, at most
 * kMaxBoxTreeDepth levels), leaves taking consecutive runs of order, every item in exactly one leaf, every box
 * non-empty and holding its children's, and holds(leaf, item) for each item of each leaf. O(nodes + items). A tree
 * that passes bounds its items however it was split: what a tree read from a file must show before a walk uses it.
 * item names an item in the reasons ("triangle", "sphere").
 */
std::string boxTreeProblem(const std::vector<BoxNode>& nodes, const std::vector<std::uint32_t>& order,
                           std::size_t items, const std::function<bool(const BoxNode&, std::uint32_t)>& holds,
                           const std::string& item = "item");

/** \brief Squared distance from (px, py, pz) to a node's box, zero inside; computed in double. */
inline double squaredDistanceToNode(const BoxNode& n, double px, double py, double pz) {
  double dx = n.lo[0] - px, ex = px - n.hi[0];
  double dy = n.lo[1] - py, ey = py - n.hi[1];
  double dz = n.lo[2] - pz, ez = pz - n.hi[2];
  dx = dx > ex ? dx : ex;
  dy = dy > ey ? dy : ey;
  dz = dz > ez ? dz : ez;
  dx = dx > 0.0 ? dx : 0.0;
  dy = dy > 0.0 ? dy : 0.0;
  dz = dz > 0.0 ? dz : 0.0;
  return dx * dx + dy * dy + dz * dz;
}

}  // namespace clod_haptics
