#include "clod_haptics/core/mesh_box_tree.h"

#include <algorithm>
#include <cmath>

#include "clod_haptics/core/checksum.h"
#include "parallel.h"

namespace clod_haptics {

std::uint64_t meshFingerprint(const TriangleMesh& mesh) {
  const std::uint64_t sums[2] = {cacheChecksum(mesh.vertices.data(), mesh.vertices.size() * sizeof(Vec3)),
                                 cacheChecksum(mesh.triangles.data(), mesh.triangles.size() * sizeof(Triangle))};
  return cacheChecksum(sums, sizeof sums);
}

double meshBoxTreePad(const TriangleMesh& mesh) { return meshBoxTreePad(mesh.bounds()); }

double meshBoxTreePad(const Eigen::AlignedBox3d& bounds) {
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
  const double pad = meshBoxTreePad(mesh);
  buildBoxTree(boxes, kMeshBoxTreeLeafSize, pad, tree->nodes, tree->order);
  tree->slabs = meshTreeSlabs(*tree, mesh, pad);
  tree->servesFingerprint = meshFingerprint(mesh);
  return tree;
}

std::string meshBoxTreeProblem(const MeshBoxTree& tree, const TriangleMesh& mesh) {
  return meshBoxTreeProblem(tree, mesh, meshBoxTreePad(mesh));
}

std::string meshBoxTreeProblem(const MeshBoxTree& tree, const TriangleMesh& mesh, double pad) {
  const std::size_t n = mesh.size(), size = tree.nodes.size();
  if (tree.order.size() != n) return "the tree does not order every triangle once";
  if (n == 0) return size == 0 ? "" : "nodes without triangles";
  if (size == 0 || size > 2 * n) return "node count out of range";
  return boxTreeProblem(
      tree.nodes, tree.order, n,
      [&](const BoxNode& node, std::uint32_t t) {
        for (int v = 0; v < 3; ++v)
          if (!nodeHoldsPadded(node, Eigen::AlignedBox3d(mesh.vertex(t, v), mesh.vertex(t, v)), pad)) return false;
        return true;
      },
      "triangle");
}

std::shared_ptr<const MeshBoxTree> meshBoxTreeOf(const TriangleMesh& mesh) {
  return meshBoxTreeOf(mesh, meshBoxTreePad(mesh));
}

std::shared_ptr<const MeshBoxTree> meshBoxTreeOf(const TriangleMesh& mesh, double pad) {
  if (mesh.boxTree) {
    const MeshBoxTree& tree = *mesh.boxTree;
    const std::uint64_t fingerprint = meshFingerprint(mesh);
    if (tree.servesFingerprint != 0 && tree.servesFingerprint == fingerprint && tree.slabs.size() == tree.nodes.size())
      return mesh.boxTree;
    if (meshBoxTreeProblem(tree, mesh, pad).empty()) {
      auto checked = std::make_shared<MeshBoxTree>();
      checked->nodes = tree.nodes;
      checked->order = tree.order;
      checked->slabs = meshTreeSlabs(tree, mesh, pad);
      checked->servesFingerprint = fingerprint;
      return checked;
    }
  }
  return buildMeshBoxTree(mesh);
}

std::vector<NodeSlab> meshTreeSlabs(const MeshBoxTree& tree, const TriangleMesh& mesh) {
  return meshTreeSlabs(tree, mesh, meshBoxTreePad(mesh));
}

std::vector<NodeSlab> meshTreeSlabs(const MeshBoxTree& tree, const TriangleMesh& mesh, double pad) {
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
  // Each triangle's doubled area vector, in leaf order, once: a node sums those of its run.
  std::vector<Vec3> areas(tree.order.size());
  detail::runParallel(2, [&](unsigned part) {
    const std::size_t half = areas.size() / 2;
    for (std::size_t k = part ? half : 0; k < (part ? areas.size() : half); ++k) {
      const std::size_t t = tree.order[k];
      areas[k] = (mesh.vertex(t, 1) - mesh.vertex(t, 0)).cross(mesh.vertex(t, 2) - mesh.vertex(t, 0));
    }
  });
  auto fill = [&](std::size_t i) {
    if (end[i] - begin[i] > kSlabTriangles) return;
    const BoxNode& n = nodes[i];
    NodeSlab& s = slabs[i];
    s.centre = 0.5 * (Vec3(n.lo[0], n.lo[1], n.lo[2]) + Vec3(n.hi[0], n.hi[1], n.hi[2]));
    Vec3 sum = Vec3::Zero();  // area-weighted, so slivers and fan centres barely turn it
    for (std::uint32_t k = begin[i]; k < end[i]; ++k) sum += areas[k];
    const double length = sum.norm();
    s.normal = length > 0.0 ? Vec3(sum / length) : Vec3::Zero();
    double thick = 0.0, radius2 = 0.0;
    for (std::uint32_t k = begin[i]; k < end[i]; ++k)
      for (int v = 0; v < 3; ++v) {
        const Vec3 m = mesh.vertex(tree.order[k], v) - s.centre;
        thick = std::max(thick, std::abs(s.normal.dot(m)));
        radius2 = std::max(radius2, m.squaredNorm());
      }
    const double radius = std::sqrt(radius2);  // the largest norm: sqrt is monotonic and correctly rounded
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
