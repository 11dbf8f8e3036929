#include "wide_box_tree.h"

#include <utility>

namespace clod_haptics {

void smallSubtrees(const MeshBoxTree& tree, std::uint32_t limit, std::vector<std::uint8_t>& small,
                   std::vector<std::uint32_t>& first) {
  // Bottom up (a child's index is larger than its parent's): a node's triangles are its children's, the left ones
  // first in the order array when they follow on.
  const std::vector<BoxNode>& nodes = tree.nodes;
  limit = std::min<std::uint32_t>(limit, 255);
  small.assign(nodes.size(), 0);
  first.assign(nodes.size(), 0);
  for (std::size_t i = nodes.size(); i-- > 0;) {
    const BoxNode& n = nodes[i];
    if (n.count > 0) {
      first[i] = n.first;
      small[i] = n.count <= limit ? static_cast<std::uint8_t>(n.count) : 0;
      continue;
    }
    const std::size_t left = i + 1, right = n.first;
    if (right >= nodes.size() || right <= i) continue;  // not a tree meshBoxTreeOf builds: no shortcut
    first[i] = first[left];
    const std::uint32_t count = static_cast<std::uint32_t>(small[left]) + small[right];
    if (small[left] > 0 && small[right] > 0 && first[left] + small[left] == first[right] && count <= limit)
      small[i] = static_cast<std::uint8_t>(count);
  }
}

std::shared_ptr<const WideBoxTree> WideBoxTree::build(const MeshBoxTree& tree, std::uint32_t limit) {
  std::vector<std::uint8_t> small;
  std::vector<std::uint32_t> first;
  smallSubtrees(tree, limit, small, first);
  return build(tree, small, first);
}

std::shared_ptr<const WideBoxTree> WideBoxTree::build(const MeshBoxTree& tree, const std::vector<std::uint8_t>& small,
                                                      const std::vector<std::uint32_t>& first) {
  const std::vector<BoxNode>& bn = tree.nodes;
  if (bn.empty() || tree.slabs.size() != bn.size() || small.size() != bn.size() || first.size() != bn.size())
    return nullptr;
  auto terminal = [&](std::uint32_t b) { return small[b] > 0 || bn[b].count > 0; };
  auto wellFormed = [&](std::uint32_t b) { return bn[b].first > b && bn[b].first < bn.size() && b + 1 < bn.size(); };
  auto wide = std::make_shared<WideBoxTree>();
  wide->nodes.reserve(bn.size() / 6 + 1);
  wide->nodes.emplace_back();
  std::vector<std::pair<std::uint32_t, std::uint32_t>> todo{{0u, 0u}};  // (node here, node of tree)
  while (!todo.empty()) {
    const auto [w, b] = todo.back();
    todo.pop_back();
    std::uint32_t lane[4];
    std::uint32_t n = 0;
    if (terminal(b)) {
      lane[n++] = b;
    } else {
      if (!wellFormed(b)) return nullptr;
      for (const std::uint32_t c : {b + 1, bn[b].first}) {
        if (terminal(c)) {
          lane[n++] = c;
        } else {
          if (!wellFormed(c)) return nullptr;
          lane[n++] = c + 1;
          lane[n++] = bn[c].first;
        }
      }
    }
    Node node{};
    node.count = n;
    for (std::uint32_t k = 0; k < n; ++k) {
      const std::uint32_t g = lane[k];
      const BoxNode& box = bn[g];
      const NodeSlab& slab = tree.slabs[g];
      for (int j = 0; j < 3; ++j) {
        node.lanes.lo[j][k] = box.lo[j];
        node.lanes.hi[j][k] = box.hi[j];
        node.lanes.centre[j][k] = slab.centre[j];
        node.lanes.normal[j][k] = slab.normal[j];
      }
      node.lanes.thick[k] = slab.thick;
      node.lanes.radius[k] = slab.radius;
      if (terminal(g)) {
        node.child[k] = first[g];
        node.few[k] = small[g] > 0 ? small[g] : box.count;
      } else {
        node.child[k] = static_cast<std::uint32_t>(wide->nodes.size());
        wide->nodes.emplace_back();
        todo.emplace_back(node.child[k], g);
      }
    }
    wide->nodes[w] = node;
  }
  wide->nodes.shrink_to_fit();  // the reserve is a guess: keep no more than the nodes
  return wide;
}

}  // namespace clod_haptics
