#include "clod_haptics/core/box_tree.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "float_rounding.h"
#include "parallel.h"

namespace clod_haptics {
namespace {

using detail::roundDown;
using detail::roundUp;

// One item as the build moves it: its centre beside its index, 32 bytes, so that the median split and the
// centres' box of a range read consecutive memory (through an index array, each level of a large tree missed the
// cache on every item). The items' own boxes are read once, by the leaves; an inner node's box is the union of its
// children's (rounding outward is monotonic, so the union is the box of its items rounded). The comparisons, hence
// the tree, are those of a split over the index array.
struct Item {
  double c[3];
  std::uint32_t index;
};

struct Builder {
  Item* items;
  const std::vector<Eigen::AlignedBox3d>& boxes;
  std::vector<BoxNode>& nodes;
  std::uint32_t base;  // position of the tree's first item in the caller's order array
  int leafSize;
  double pad;

  /**
   * Builds items[begin, end) as build() does, the root's two subtrees on two threads: the left one into nodes
   * after the root, the right one into an array of its own, appended after the left one with its inner nodes'
   * child indices shifted (leaves index the items, which both share): the same tree, node for node.
   */
  std::uint32_t buildOnTwoThreads(std::uint32_t begin, std::uint32_t end) {
    std::uint32_t mid = 0;
    const std::uint32_t self = open(begin, end, mid);
    if (mid == 0) return self;
    std::vector<BoxNode> right;
    right.reserve(4 * std::size_t(end - mid) / static_cast<std::size_t>(leafSize) + 1);  // leaves hold >= leafSize / 2
    Builder other{items, boxes, right, base, leafSize, pad};
    detail::runParallel(2, [&](unsigned part) { part ? other.build(mid, end) : build(begin, mid); });
    const auto shift = static_cast<std::uint32_t>(nodes.size());
    for (BoxNode& node : right)
      if (node.count == 0) node.first += shift;
    nodes.insert(nodes.end(), right.begin(), right.end());
    close(self, shift);
    return self;
  }

  std::uint32_t build(std::uint32_t begin, std::uint32_t end) {
    std::uint32_t mid = 0;
    const std::uint32_t self = open(begin, end, mid);
    if (mid == 0) return self;
    build(begin, mid);
    close(self, build(mid, end));
    return self;
  }

  /** Makes nodes[self] the inner node of its left child (right after it) and right: child index and box. */
  void close(std::uint32_t self, std::uint32_t right) {
    BoxNode& node = nodes[self];
    const BoxNode& a = nodes[self + 1];
    const BoxNode& b = nodes[right];
    for (int k = 0; k < 3; ++k) {
      node.lo[k] = std::min(a.lo[k], b.lo[k]);
      node.hi[k] = std::max(a.hi[k], b.hi[k]);
    }
    node.first = right;
    node.count = 0;
  }

  /**
   * Appends the node of items[begin, end): a leaf with its box (mid stays 0), or an inner node whose items are
   * split at mid (the median along the longest axis of their centres), its box and child index left for close().
   */
  std::uint32_t open(std::uint32_t begin, std::uint32_t end, std::uint32_t& mid) {
    constexpr double kBig = std::numeric_limits<double>::max();
    const std::uint32_t self = static_cast<std::uint32_t>(nodes.size());
    BoxNode node{};
    if (end - begin <= static_cast<std::uint32_t>(leafSize)) {
      double lo[3] = {kBig, kBig, kBig}, hi[3] = {-kBig, -kBig, -kBig};
      for (std::uint32_t i = begin; i < end; ++i) {
        const Eigen::AlignedBox3d& box = boxes[items[i].index];
        for (int k = 0; k < 3; ++k) {
          lo[k] = std::min(lo[k], box.min()[k]);
          hi[k] = std::max(hi[k], box.max()[k]);
        }
      }
      for (int k = 0; k < 3; ++k) {
        node.lo[k] = roundDown(lo[k] - pad);
        node.hi[k] = roundUp(hi[k] + pad);
      }
      node.first = base + begin;
      node.count = end - begin;
      nodes.push_back(node);
      return self;
    }
    nodes.push_back(node);
    double clo[3] = {kBig, kBig, kBig}, chi[3] = {-kBig, -kBig, -kBig};
    for (std::uint32_t i = begin; i < end; ++i) {
      const Item& it = items[i];
      for (int k = 0; k < 3; ++k) {
        clo[k] = std::min(clo[k], it.c[k]);
        chi[k] = std::max(chi[k], it.c[k]);
      }
    }
    // The longest axis of the centres' box, the first on ties.
    int axis = 0;
    for (int k = 1; k < 3; ++k)
      if (chi[k] - clo[k] > chi[axis] - clo[axis]) axis = k;
    mid = begin + (end - begin) / 2;
    std::nth_element(items + begin, items + mid, items + end,
                     [axis](const Item& a, const Item& b) { return a.c[axis] < b.c[axis]; });
    return self;
  }
};

// Below this many items a tree builds in well under a millisecond: a thread would cost more than it saves.
constexpr std::uint32_t kTwoThreadsFrom = 16384;

}  // namespace

std::size_t boxTreeNodeCount(std::size_t items, int leafSize) {
  if (items == 0) return 0;
  // Every depth holds runs of at most two sizes, m and m + 1 (halving keeps them adjacent): count those.
  const std::size_t leaf = static_cast<std::size_t>(std::max(1, leafSize));
  std::size_t nodes = 0, m = items, small = 1, large = 0;  // runs of size m and of size m + 1
  while (small + large > 0) {
    nodes += small + large;
    std::size_t nextSmall = 0, nextLarge = 0;
    const std::size_t half = m / 2;  // the next depth's smaller size
    auto split = [&](std::size_t size, std::size_t runs) {
      if (runs == 0 || size <= leaf) return;                   // leaves
      const std::size_t left = size / 2, right = size - left;  // right is left or left + 1
      for (const std::size_t part : {left, right}) (part == half ? nextSmall : nextLarge) += runs;
    };
    split(m, small);
    split(m + 1, large);
    m = half;
    small = nextSmall;
    large = nextLarge;
  }
  return nodes;
}

std::uint32_t buildBoxTree(const std::vector<Eigen::AlignedBox3d>& boxes, int leafSize, double pad,
                           std::vector<BoxNode>& nodes, std::vector<std::uint32_t>& order, unsigned threads) {
  if (boxes.empty()) return std::numeric_limits<std::uint32_t>::max();
  const std::uint32_t base = static_cast<std::uint32_t>(order.size());
  std::vector<Item> items(boxes.size());
  for (std::uint32_t i = 0; i < boxes.size(); ++i) {
    const Eigen::Vector3d c = boxes[i].center();
    for (int k = 0; k < 3; ++k) items[i].c[k] = c[k];
    items[i].index = i;
  }
  Builder builder{items.data(), boxes, nodes, base, std::max(1, leafSize), pad};
  const auto count = static_cast<std::uint32_t>(boxes.size());
  const std::uint32_t root =
      threads > 1 && count >= kTwoThreadsFrom ? builder.buildOnTwoThreads(0, count) : builder.build(0, count);
  order.resize(order.size() + boxes.size());
  for (std::uint32_t i = 0; i < boxes.size(); ++i) order[base + i] = items[i].index;
  return root;
}

std::string boxTreeProblem(const std::vector<BoxNode>& nodes, const std::vector<std::uint32_t>& order,
                           std::size_t items, const std::function<bool(const BoxNode&, std::uint32_t)>& holds,
                           const std::string& item) {
  const std::size_t size = nodes.size();
  if (order.size() != items) return "the tree does not order every " + item + " once";
  if (items == 0) return size == 0 ? "" : "nodes without a " + item;
  if (size == 0 || size > 2 * items) return "node count out of range";
  std::vector<std::uint8_t> seen(items, 0);
  std::vector<std::uint32_t> depth(size, 0);
  std::uint32_t next = 0;      // nodes must appear in depth-first order: each visited node is the next index
  std::uint32_t nextItem = 0;  // and leaves take consecutive runs of the order array
  std::uint32_t stack[kMaxBoxTreeDepth + 2];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const std::uint32_t i = stack[--top];
    if (i != next++) return "the nodes are not in depth-first order";
    const BoxNode& node = nodes[i];
    for (int k = 0; k < 3; ++k)
      if (!(node.lo[k] <= node.hi[k])) return "a node's box is empty or not finite";
    if (node.count > 0) {
      if (node.first != nextItem || node.count > items - nextItem) return "a leaf's run is out of place";
      nextItem += node.count;
      for (std::uint32_t j = node.first; j < node.first + node.count; ++j) {
        const std::uint32_t at = order[j];
        if (at >= items || seen[at]) return "a " + item + " is out of range or in two leaves";
        seen[at] = 1;
        if (!holds(node, at)) return "a leaf's box misses a " + item;
      }
      continue;
    }
    const std::uint32_t left = i + 1, right = node.first;
    if (!(right > left && right < size)) return "an inner node's children are out of place";
    if (depth[i] >= kMaxBoxTreeDepth) return "the tree is too deep";
    for (const std::uint32_t c : {left, right}) {
      const BoxNode& child = nodes[c];
      for (int k = 0; k < 3; ++k)
        if (!(node.lo[k] <= child.lo[k] && node.hi[k] >= child.hi[k])) return "a node's box misses a child's";
      depth[c] = depth[i] + 1;
    }
    stack[top++] = right;
    stack[top++] = left;
  }
  if (next != size) return "nodes unreachable from the root";
  if (nextItem != items) return "the leaves do not cover the order";
  return "";
}

}  // namespace clod_haptics
