#include "clod_haptics/core/triangle_bvh.h"

#include <algorithm>

namespace clod_haptics {
namespace {

struct Build {
  const TriangleMesh& mesh;
  std::vector<Vec3> centroids;
  std::vector<Eigen::AlignedBox3d> boxes;
  std::vector<TriangleBvh::Node>& nodes;
  std::vector<std::uint32_t>& order;
  int leafSize;

  std::uint32_t build(std::uint32_t begin, std::uint32_t end) {
    Eigen::AlignedBox3d box, cbox, nbox;
    for (std::uint32_t i = begin; i < end; ++i) {
      box.extend(boxes[order[i]]);
      cbox.extend(centroids[order[i]]);
      nbox.extend(mesh.normals[order[i]]);
    }
    const std::uint32_t self = static_cast<std::uint32_t>(nodes.size());
    TriangleBvh::Node node{};
    for (int k = 0; k < 3; ++k) {
      node.lo[k] = box.min()[k];
      node.hi[k] = box.max()[k];
      // Outward by more than float rounding: bounds stay bounds after the cast.
      node.normalLo[k] = static_cast<float>(nbox.min()[k] - 1e-6);
      node.normalHi[k] = static_cast<float>(nbox.max()[k] + 1e-6);
    }
    nodes.push_back(node);
    if (end - begin <= static_cast<std::uint32_t>(leafSize)) {
      nodes[self].first = begin;
      nodes[self].count = end - begin;
      return self;
    }
    int axis;
    cbox.sizes().maxCoeff(&axis);
    const std::uint32_t mid = begin + (end - begin) / 2;
    std::nth_element(order.begin() + begin, order.begin() + mid, order.begin() + end,
                     [&](std::uint32_t a, std::uint32_t b) { return centroids[a][axis] < centroids[b][axis]; });
    build(begin, mid);
    nodes[self].first = build(mid, end);
    nodes[self].count = 0;
    return self;
  }
};

}  // namespace

TriangleBvh::TriangleBvh(const TriangleMesh& mesh, int leafSize) : mesh_(mesh) {
  const std::size_t n = mesh.size();
  if (n == 0) return;
  Build b{mesh, {}, {}, nodes_, order_, std::max(1, leafSize)};
  b.centroids.resize(n);
  b.boxes.resize(n);
  order_.resize(n);
  for (std::size_t t = 0; t < n; ++t) {
    b.centroids[t] = mesh.centroid(t);
    b.boxes[t].setEmpty();
    for (int k = 0; k < 3; ++k) b.boxes[t].extend(mesh.vertex(t, k));
    order_[t] = static_cast<std::uint32_t>(t);
  }
  nodes_.reserve(2 * n / std::max(1, leafSize) + 2);
  b.build(0, static_cast<std::uint32_t>(n));
}

}  // namespace clod_haptics
