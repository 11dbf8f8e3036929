#pragma once
// Internal to the core (not API): a MeshBoxTree four children to a node, for the walks that test four nodes in one
// AVX2 call (src/core/simd/node_filter_avx2.h): the swept query's (SweptSphereQuery::sweepWide) and the point query's
// over the whole mesh (ClodDetector::preciseMeshTree).

#include <cstdint>
#include <memory>
#include <vector>

#include "clod_haptics/core/mesh_box_tree.h"
#include "simd/node_filter_avx2.h"

namespace clod_haptics {

/**
 * \brief Per node of tree, the number of triangles below it when it is a leaf or a subtree of at most limit (at most
 * 255) triangles lying together in the order array, else 0; first: each node's first triangle there (its leftmost
 * leaf's). What the walks test at once, without walking further.
 */
void smallSubtrees(const MeshBoxTree& tree, std::uint32_t limit, std::vector<std::uint8_t>& small,
                   std::vector<std::uint32_t>& first);

/**
 * \brief The box tree four children to a node. Each node of the binary tree that a walk enters (its root, and every
 * inner node that is not a small subtree) is a node here whose lanes are its children, or for a child that is itself
 * such a node, that child's two children: a walk tests up to four nodes of the binary tree in one call where the
 * binary walk tests two, and skips the level between. A lane that is a leaf or a small subtree holds its run of the
 * order array. Built in O(nodes); 512 bytes a node, as many nodes as a sixteenth of the triangles (ending at
 * subtrees of 8 on a tree with leaves of 4) to a quarter (ending at the leaves).
 */
struct WideBoxTree {
  struct alignas(64) Node {
    detail::NodeLanes lanes;  ///< the children's boxes and slabs
    std::uint32_t child[4];   ///< few > 0: its first triangle in the order array; else its node here
    std::uint32_t few[4];     ///< its triangles when a leaf or small subtree, else 0
    std::uint32_t count;      ///< lanes used
  };
  std::vector<Node> nodes;  ///< root at 0 (its lanes: the binary root's children or grandchildren, or the root itself)

  /**
   * \brief The wide tree over tree with small subtrees of at most limit triangles as its lanes' ends (smallSubtrees);
   * null when tree is not one meshBoxTreeOf builds (a slab for every node, children after their parent).
   */
  static std::shared_ptr<const WideBoxTree> build(const MeshBoxTree& tree, std::uint32_t limit);
  /** \brief The same from smallSubtrees' answer for tree (a caller that keeps it too). */
  static std::shared_ptr<const WideBoxTree> build(const MeshBoxTree& tree, const std::vector<std::uint8_t>& small,
                                                  const std::vector<std::uint32_t>& first);
  std::size_t bytes() const noexcept { return sizeof(*this) + nodes.capacity() * sizeof(Node); }

  /**
   * \brief A walk from the root, nearest first. test(node, key) answers the lanes of a node to enter (bits) and writes
   * each one's key (a lower bound of what it can give, in the walk's order); run(first, few) takes a leaf's or small
   * subtree's triangles, order[first, first + few); bound() is the key beyond which nothing can win, read again as
   * the walk narrows it. Pushes the entered lanes farthest first and requests their nodes' lines, so the stack takes
   * the nearest next. Allocates nothing.
   */
  template <class Bound, class Test, class Run>
  void walk(const Bound& bound, const Test& test, const Run& run) const {
    struct Item {
      std::uint32_t child, few;
      double key;
    };
    Item stack[3 * kMaxBoxTreeDepth + 8];  // a node pops one item and pushes at most four
    int top = 0;
    stack[top++] = {0, 0, 0.0};
    while (top > 0) {
      const Item item = stack[--top];
      if (item.key > bound()) continue;
      if (item.few > 0) {
        run(item.child, item.few);
        continue;
      }
      const Node& node = nodes[item.child];
      double key[4];
      int lane[4], n = 0;
      for (unsigned keep = test(node, key); keep != 0; keep &= keep - 1) {
        const int k = __builtin_ctz(keep);
        int j = n++;
        for (; j > 0 && key[lane[j - 1]] < key[k]; --j) lane[j] = lane[j - 1];
        lane[j] = k;
        if (node.few[k] == 0) {
          const char* line = reinterpret_cast<const char*>(&nodes[node.child[k]]);
          for (std::size_t b = 0; b < sizeof(Node); b += 64) __builtin_prefetch(line + b);
        }
      }
      for (int j = 0; j < n; ++j) stack[top++] = {node.child[lane[j]], node.few[lane[j]], key[lane[j]]};
    }
  }
};

}  // namespace clod_haptics
