#include "clod_haptics/core/box_tree.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "float_rounding.h"

namespace clod_haptics {
namespace {

using detail::roundDown;
using detail::roundUp;

struct Builder {
  const std::vector<Eigen::AlignedBox3d>& boxes;
  std::vector<Eigen::Vector3d> centres;
  std::vector<BoxNode>& nodes;
  std::uint32_t* order;  // this tree's run inside the caller's order array
  std::uint32_t base;    // position of order[0] in the caller's array
  int leafSize;
  double pad;

  std::uint32_t build(std::uint32_t begin, std::uint32_t end) {
    Eigen::AlignedBox3d box, centreBox;
    for (std::uint32_t i = begin; i < end; ++i) {
      box.extend(boxes[order[i]]);
      centreBox.extend(centres[order[i]]);
    }
    const std::uint32_t self = static_cast<std::uint32_t>(nodes.size());
    BoxNode node{};
    for (int k = 0; k < 3; ++k) {
      node.lo[k] = roundDown(box.min()[k] - pad);
      node.hi[k] = roundUp(box.max()[k] + pad);
    }
    nodes.push_back(node);
    if (end - begin <= static_cast<std::uint32_t>(leafSize)) {
      nodes[self].first = base + begin;
      nodes[self].count = end - begin;
      return self;
    }
    int axis;
    centreBox.sizes().maxCoeff(&axis);
    const std::uint32_t mid = begin + (end - begin) / 2;
    std::nth_element(order + begin, order + mid, order + end,
                     [&](std::uint32_t a, std::uint32_t b) { return centres[a][axis] < centres[b][axis]; });
    build(begin, mid);
    const std::uint32_t right = build(mid, end);
    nodes[self].first = right;
    nodes[self].count = 0;
    return self;
  }
};

}  // namespace

std::uint32_t buildBoxTree(const std::vector<Eigen::AlignedBox3d>& boxes, int leafSize, double pad,
                           std::vector<BoxNode>& nodes, std::vector<std::uint32_t>& order) {
  if (boxes.empty()) return std::numeric_limits<std::uint32_t>::max();
  const std::uint32_t base = static_cast<std::uint32_t>(order.size());
  order.resize(order.size() + boxes.size());
  for (std::uint32_t i = 0; i < boxes.size(); ++i) order[base + i] = i;
  Builder builder{boxes, {}, nodes, order.data() + base, base, std::max(1, leafSize), pad};
  builder.centres.reserve(boxes.size());
  for (const auto& b : boxes) builder.centres.push_back(b.center());
  return builder.build(0, static_cast<std::uint32_t>(boxes.size()));
}

}  // namespace clod_haptics
