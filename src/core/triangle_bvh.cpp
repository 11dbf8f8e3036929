#include "clod_haptics/core/triangle_bvh.h"

#include <algorithm>
#include <limits>

namespace clod_haptics {
namespace {

// Surface area heuristic over kBins bins of the centroids along one axis: the split that minimises
// area(left) * count(left) + area(right) * count(right), the expected cost of a ray through the node.
constexpr int kBins = 16;

double halfArea(const Eigen::AlignedBox3d& b) {
  if (b.isEmpty()) return 0.0;
  const Vec3 e = b.sizes();
  return e.x() * e.y() + e.y() * e.z() + e.z() * e.x();
}

struct Build {
  const TriangleMesh& mesh;
  std::vector<Vec3> centroids;
  std::vector<Eigen::AlignedBox3d> boxes;
  std::vector<TriangleBvh::Node>& nodes;
  std::vector<std::uint32_t>& order;
  int leafSize;

  // Partitions order[begin, end) and returns the split point; falls back to the median when the
  // centroids coincide along the axis or the heuristic leaves one side empty.
  std::uint32_t split(std::uint32_t begin, std::uint32_t end, int axis, const Eigen::AlignedBox3d& cbox) {
    const double lo = cbox.min()[axis], extent = cbox.sizes()[axis];
    auto median = [&]() {
      const std::uint32_t mid = begin + (end - begin) / 2;
      std::nth_element(order.begin() + begin, order.begin() + mid, order.begin() + end,
                       [&](std::uint32_t a, std::uint32_t b) { return centroids[a][axis] < centroids[b][axis]; });
      return mid;
    };
    if (!(extent > 0.0) || end - begin < 16) return median();
    const double scale = kBins / extent;
    auto binOf = [&](std::uint32_t t) {
      return std::min(kBins - 1, static_cast<int>((centroids[t][axis] - lo) * scale));
    };
    Eigen::AlignedBox3d bins[kBins];
    std::uint32_t counts[kBins] = {};
    for (int i = 0; i < kBins; ++i) bins[i].setEmpty();
    for (std::uint32_t i = begin; i < end; ++i) {
      const int b = binOf(order[i]);
      bins[b].extend(boxes[order[i]]);
      ++counts[b];
    }
    double rightArea[kBins];
    std::uint32_t rightCount[kBins];
    Eigen::AlignedBox3d acc;
    acc.setEmpty();
    std::uint32_t n = 0;
    for (int i = kBins - 1; i > 0; --i) {
      acc.extend(bins[i]);
      n += counts[i];
      rightArea[i] = halfArea(acc);
      rightCount[i] = n;
    }
    acc.setEmpty();
    n = 0;
    double bestCost = std::numeric_limits<double>::infinity();
    int bestSplit = -1;
    for (int i = 1; i < kBins; ++i) {
      acc.extend(bins[i - 1]);
      n += counts[i - 1];
      if (n == 0 || rightCount[i] == 0) continue;
      const double cost = halfArea(acc) * n + rightArea[i] * rightCount[i];
      if (cost < bestCost) {
        bestCost = cost;
        bestSplit = i;
      }
    }
    if (bestSplit < 0) return median();
    const auto mid = std::partition(order.begin() + begin, order.begin() + end,
                                    [&](std::uint32_t t) { return binOf(t) < bestSplit; });
    return static_cast<std::uint32_t>(mid - order.begin());
  }

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
    const std::uint32_t mid = split(begin, end, axis, cbox);
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
