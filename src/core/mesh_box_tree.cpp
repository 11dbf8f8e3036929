#include "clod_haptics/core/mesh_box_tree.h"

#include <algorithm>
#include <cmath>

#include "parallel.h"

namespace clod_haptics {

namespace {
constexpr int kLeafSize = 4;
constexpr int kMaxDepth = 60;  // the walks' stacks hold 64 (detector) and 128 (swept query) entries
}  // namespace

double meshBoxTreePad(const TriangleMesh& mesh) {
  const Eigen::AlignedBox3d bounds = mesh.bounds();
  const double magnitude = std::max(bounds.min().cwiseAbs().maxCoeff(), bounds.max().cwiseAbs().maxCoeff());
  return 1e-12 * std::max(magnitude, bounds.diagonal().norm());
}

std::shared_ptr<const MeshBoxTree> buildMeshBoxTree(const TriangleMesh& mesh) {
  auto tree = std::make_shared<MeshBoxTree>();
  std::vector<Eigen::AlignedBox3d> boxes(mesh.size());
  for (std::size_t t = 0; t < mesh.size(); ++t) {
    boxes[t].setEmpty();
    for (int v = 0; v < 3; ++v) boxes[t].extend(mesh.vertex(t, v));
  }
  buildBoxTree(boxes, kLeafSize, meshBoxTreePad(mesh), tree->nodes, tree->order);
  return tree;
}

std::string meshBoxTreeProblem(const MeshBoxTree& tree, const TriangleMesh& mesh) {
  const std::size_t n = mesh.size(), size = tree.nodes.size();
  if (tree.order.size() != n) return "the tree does not order every triangle once";
  if (n == 0) return size == 0 ? "" : "nodes without triangles";
  if (size == 0 || size > 2 * n) return "node count out of range";
  const double pad = meshBoxTreePad(mesh);
  std::vector<std::uint8_t> seen(n, 0);
  std::vector<std::uint32_t> depth(size, 0);
  std::uint32_t next = 0;      // nodes must appear in depth-first order: each visited node is the next index
  std::uint32_t nextItem = 0;  // and leaves take consecutive runs of the order array
  std::uint32_t stack[kMaxDepth + 2];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const std::uint32_t i = stack[--top];
    if (i != next++) return "the nodes are not in depth-first order";
    const BoxNode& node = tree.nodes[i];
    for (int k = 0; k < 3; ++k)
      if (!(node.lo[k] <= node.hi[k])) return "a node's box is empty or not finite";
    if (node.count > 0) {
      if (node.first != nextItem || node.count > n - nextItem) return "a leaf's run is out of place";
      nextItem += node.count;
      for (std::uint32_t j = node.first; j < node.first + node.count; ++j) {
        const std::uint32_t t = tree.order[j];
        if (t >= n || seen[t]) return "a triangle is out of range or in two leaves";
        seen[t] = 1;
        for (int v = 0; v < 3; ++v) {
          const Vec3& p = mesh.vertex(t, v);
          for (int k = 0; k < 3; ++k)
            if (!(node.lo[k] <= p[k] - pad && node.hi[k] >= p[k] + pad)) return "a leaf's box misses a triangle";
        }
      }
      continue;
    }
    const std::uint32_t left = i + 1, right = node.first;
    if (!(right > left && right < size)) return "an inner node's children are out of place";
    if (depth[i] >= kMaxDepth) return "the tree is too deep";
    for (const std::uint32_t c : {left, right}) {
      const BoxNode& child = tree.nodes[c];
      for (int k = 0; k < 3; ++k)
        if (!(node.lo[k] <= child.lo[k] && node.hi[k] >= child.hi[k])) return "a node's box misses a child's";
      depth[c] = depth[i] + 1;
    }
    stack[top++] = right;
    stack[top++] = left;
  }
  if (next != size) return "nodes unreachable from the root";
  if (nextItem != n) return "the leaves do not cover the order";
  return "";
}

std::shared_ptr<const MeshBoxTree> meshBoxTreeOf(const TriangleMesh& mesh) {
  if (mesh.boxTree && meshBoxTreeProblem(*mesh.boxTree, mesh).empty()) return mesh.boxTree;
  return buildMeshBoxTree(mesh);
}

std::vector<NodeSlab> meshTreeSlabs(const MeshBoxTree& tree, const TriangleMesh& mesh) {
  const std::vector<BoxNode>& nodes = tree.nodes;
  std::vector<NodeSlab> slabs(nodes.size());
  // The run of the order array below each node: children come after their parent (the left one next), and the
  // leaves below a node take consecutive runs (meshBoxTreeProblem), so one pass from the last node up gives them.
  std::vector<std::uint32_t> begin(nodes.size()), end(nodes.size());
  for (std::size_t i = nodes.size(); i-- > 0;) {
    const BoxNode& n = nodes[i];
    if (n.count > 0) {
      begin[i] = n.first;
      end[i] = n.first + n.count;
    } else {
      begin[i] = std::min(begin[i + 1], begin[n.first]);
      end[i] = std::max(end[i + 1], end[n.first]);
    }
  }
  const double pad = meshBoxTreePad(mesh);
  auto fill = [&](std::size_t i) {
    if (end[i] - begin[i] > kSlabTriangles) return;
    const BoxNode& n = nodes[i];
    NodeSlab& s = slabs[i];
    s.centre = 0.5 * (Vec3(n.lo[0], n.lo[1], n.lo[2]) + Vec3(n.hi[0], n.hi[1], n.hi[2]));
    Vec3 sum = Vec3::Zero();  // area-weighted, so slivers and fan centres barely turn it
    for (std::uint32_t k = begin[i]; k < end[i]; ++k) {
      const std::size_t t = tree.order[k];
      sum += (mesh.vertex(t, 1) - mesh.vertex(t, 0)).cross(mesh.vertex(t, 2) - mesh.vertex(t, 0));
    }
    const double length = sum.norm();
    s.normal = length > 0.0 ? Vec3(sum / length) : Vec3::Zero();
    double thick = 0.0, radius = 0.0;
    for (std::uint32_t k = begin[i]; k < end[i]; ++k)
      for (int v = 0; v < 3; ++v) {
        const Vec3 m = mesh.vertex(tree.order[k], v) - s.centre;
        thick = std::max(thick, std::abs(s.normal.dot(m)));
        radius = std::max(radius, m.norm());
      }
    // Rounded up for the rounding of these sums and of the bound's own evaluation (relative to the node and to the
    // coordinates).
    s.thick = thick * (1.0 + 1e-9) + 1e-12 * radius + pad;
    s.radius = radius * (1.0 + 1e-9) + pad;
  };
  // Two threads, each half of the nodes (depth first: about half of the tree each).
  const std::size_t half = nodes.size() / 2;
  detail::runParallel(2, [&](unsigned part) {
    for (std::size_t i = part ? half : 0; i < (part ? nodes.size() : half); ++i) fill(i);
  });
  return slabs;
}

}  // namespace clod_haptics
