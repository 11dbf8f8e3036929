#include "clod_haptics/core/tight_clustering.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include <Eigen/Eigenvalues>

#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/geometry.h"

namespace clod_haptics {
namespace {

constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();

void requireDistance(double d) {
  if (!std::isfinite(d) || d < 0.0)
    throw InvalidParameter("clustering distance must be finite and >= 0, got " + std::to_string(d));
}

// Splits items[begin, end) in two at the mean of their keys along the keys' principal axis; returns
// the first index of the second half, always strictly inside (begin, end) for end - begin >= 2.
// Depends only on the items and their keys, never on d: the tree is the same for every d.
std::uint32_t splitAtMean(std::vector<std::uint32_t>& items, std::uint32_t begin, std::uint32_t end,
                          const std::vector<Vec3>& key) {
  Vec3 mean = Vec3::Zero();
  for (std::uint32_t i = begin; i < end; ++i) mean += key[items[i]];
  mean /= static_cast<double>(end - begin);
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (std::uint32_t i = begin; i < end; ++i) {
    const Vec3 v = key[items[i]] - mean;
    cov.noalias() += v * v.transpose();
  }
  std::uint32_t mid = begin;
  if (cov.allFinite() && cov.trace() > 0.0) {
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(cov);
    const Vec3 axis = eigen.eigenvectors().col(2);  // largest eigenvalue last
    const double cut = axis.dot(mean);
    mid = static_cast<std::uint32_t>(
        std::partition(items.begin() + begin, items.begin() + end, [&](std::uint32_t t) { return axis.dot(key[t]) < cut; }) -
        items.begin());
  }
  // Coincident keys (or rounding) put everything on one side: halve by position instead.
  if (mid == begin || mid == end) mid = begin + (end - begin) / 2;
  return mid;
}

// Labels of the points from the cluster of each item, renumbered in the order of each cluster's
// first point (the Clustering contract).
std::uint32_t labelPoints(const std::vector<std::uint32_t>& clusterOfItem, const std::vector<std::uint32_t>& itemOfPoint,
                          std::uint32_t clusters, std::vector<std::uint32_t>& labels, std::vector<std::uint32_t>* firstOrder) {
  std::vector<std::uint32_t> renumber(clusters, kNone);
  std::uint32_t count = 0;
  for (std::size_t i = 0; i < itemOfPoint.size(); ++i) {
    const std::uint32_t c = clusterOfItem[itemOfPoint[i]];
    if (renumber[c] == kNone) {
      renumber[c] = count++;
      if (firstOrder) firstOrder->push_back(c);
    }
    labels[i] = renumber[c];
  }
  return count;
}

}  // namespace

SurfaceDistance::SurfaceDistance(const TriangleMesh& mesh) : mesh_(mesh) {
  std::vector<Eigen::AlignedBox3d> boxes(mesh.size());
  for (std::size_t t = 0; t < mesh.size(); ++t) {
    boxes[t].setEmpty();
    for (int k = 0; k < 3; ++k) boxes[t].extend(mesh.vertex(t, k));
  }
  buildBoxTree(boxes, 4, 0.0, nodes_, order_);
}

double SurfaceDistance::signedDistance(const Vec3& p, double bound) const {
  if (nodes_.empty()) return std::numeric_limits<double>::infinity();
  // Pruned at the bound (a little beyond it, against rounding); nothing within it: +bound.
  double best = std::isfinite(bound) ? bound * bound * (1.0 + 1e-9) + 1e-300 : std::numeric_limits<double>::infinity();
  std::uint32_t bestTriangle = kNone;
  Vec3 bestPoint = p;
  std::uint32_t stack[128];  // the median-split tree is balanced: depth ~ log2(n / 4)
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const std::uint32_t index = stack[--top];
    const BoxNode& node = nodes_[index];
    if (squaredDistanceToNode(node, p.x(), p.y(), p.z()) >= best) continue;
    if (node.count > 0) {
      for (std::uint32_t i = node.first; i < node.first + node.count; ++i) {
        const std::uint32_t t = order_[i];
        const Vec3 q = closestPointOnTriangle(p, mesh_.vertex(t, 0), mesh_.vertex(t, 1), mesh_.vertex(t, 2));
        const double d2 = (q - p).squaredNorm();
        if (d2 < best) {
          best = d2;
          bestTriangle = t;
          bestPoint = q;
        }
      }
      continue;
    }
    const std::uint32_t left = index + 1, right = node.first;
    const double dl = squaredDistanceToNode(nodes_[left], p.x(), p.y(), p.z());
    const double dr = squaredDistanceToNode(nodes_[right], p.x(), p.y(), p.z());
    if (top + 2 > 128) continue;  // unreachable for a balanced tree; never overflow
    if (dl <= dr) {  // nearer child on top
      stack[top++] = right;
      stack[top++] = left;
    } else {
      stack[top++] = left;
      stack[top++] = right;
    }
  }
  if (bestTriangle == kNone) return bound;
  const double distance = std::sqrt(best);
  return (p - bestPoint).dot(mesh_.normals[bestTriangle]) > 0.0 ? -distance : distance;
}

std::uint32_t TightClustering::cluster(const std::vector<Vec3>& points, double d,
                                       std::vector<std::uint32_t>& labels) const {
  requireDistance(d);
  const std::size_t n = points.size();
  labels.assign(n, 0);
  if (n == 0) return 0;
  if (n >= kNone) throw InvalidParameter("TightClustering: too many points");
  std::vector<std::uint32_t> items(n);
  for (std::uint32_t i = 0; i < n; ++i) items[i] = i;
  std::vector<std::uint32_t> clusterOf(n, 0);
  std::uint32_t clusters = 0;
  const double r2 = 0.25 * d * d;
  struct Range {
    std::uint32_t begin, end;
  };
  std::vector<Range> stack{{0, static_cast<std::uint32_t>(n)}};
  while (!stack.empty()) {
    const Range r = stack.back();
    stack.pop_back();
    Vec3 mean = Vec3::Zero();
    for (std::uint32_t i = r.begin; i < r.end; ++i) mean += points[items[i]];
    mean /= static_cast<double>(r.end - r.begin);
    double spread = 0.0;
    for (std::uint32_t i = r.begin; i < r.end; ++i) spread = std::max(spread, (points[items[i]] - mean).squaredNorm());
    if (r.end - r.begin == 1 || spread <= r2) {
      for (std::uint32_t i = r.begin; i < r.end; ++i) clusterOf[items[i]] = clusters;
      ++clusters;
      continue;
    }
    const std::uint32_t mid = splitAtMean(items, r.begin, r.end, points);
    stack.push_back({mid, r.end});
    stack.push_back({r.begin, mid});
  }
  std::vector<std::uint32_t> identity(n);
  for (std::uint32_t i = 0; i < n; ++i) identity[i] = i;
  return labelPoints(clusterOf, identity, clusters, labels, nullptr);
}

std::uint32_t TightClustering::clusterMesh(const TriangleMesh& mesh, const std::vector<Vec3>& points,
                                           const std::vector<std::uint32_t>& wrapped, double d,
                                           std::vector<std::uint32_t>& labels, std::vector<Vec3>& centres) const {
  requireDistance(d);
  centres.clear();
  const std::size_t n = points.size();
  labels.assign(n, 0);
  if (n == 0) return 0;
  if (wrapped.size() != n) throw InvalidParameter("TightClustering: one wrapped triangle per point is needed");
  for (const std::uint32_t t : wrapped)
    if (t >= mesh.size()) throw InvalidParameter("TightClustering: wrapped triangle out of range");

  // The items are the wrapped triangles (each once); the depth hint of a triangle is the mean of its
  // points' distances below it.
  const std::size_t triangles = mesh.size();
  std::vector<std::uint32_t> slot(triangles, kNone), itemOfPoint(n);
  std::vector<std::uint32_t> itemTriangle;
  std::vector<double> depthSum;
  std::vector<std::uint32_t> depthCount;
  std::vector<Vec3> pointSum;
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t t = wrapped[i];
    if (slot[t] == kNone) {
      slot[t] = static_cast<std::uint32_t>(itemTriangle.size());
      itemTriangle.push_back(t);
      depthSum.push_back(0.0);
      depthCount.push_back(0);
      pointSum.push_back(Vec3::Zero());
    }
    const std::uint32_t item = slot[t];
    itemOfPoint[i] = item;
    const double depth = (mesh.centroid(t) - points[i]).norm();
    if (std::isfinite(depth)) {
      depthSum[item] += depth;
      ++depthCount[item];
      pointSum[item] += points[i];
    }
  }
  const std::size_t m = itemTriangle.size();
  std::vector<Vec3> centroid(m);
  for (std::size_t k = 0; k < m; ++k) centroid[k] = mesh.centroid(itemTriangle[k]);

  const SurfaceDistance surface(mesh);
  std::vector<std::uint32_t> items(m);
  for (std::uint32_t k = 0; k < m; ++k) items[k] = k;
  const double d3 = d * d * d;
  // Excess of a sphere: the volume of its cap beyond the tangent plane at the surface point nearest to
  // its centre, over 4/3 pi (so that it compares with d^3): with rho the signed distance of the centre
  // and h = R - rho the cap's height, h^2 (3R - h) / 4; a centre outside counts as h = 2R (the whole ball).
  // The excess grows with h, and rho is at most the distance to the nearest vertex of the node's own
  // triangles, so R minus that distance bounds h from below: when that bound already exceeds the
  // threshold, the bound is returned and the distance query (the costly part) is skipped; the decision
  // and the best centre below are the same as with exact values.
  auto capVolume = [](double r, double h) { return 0.25 * h * h * (3.0 * r - h); };
  auto excess = [&](const Vec3& c, std::uint32_t begin, std::uint32_t end, double threshold) {
    double far2 = 0.0, near2 = std::numeric_limits<double>::infinity();
    for (std::uint32_t i = begin; i < end; ++i) {
      const std::uint32_t t = itemTriangle[items[i]];
      for (int v = 0; v < 3; ++v) {
        const double d2 = (mesh.vertex(t, v) - c).squaredNorm();
        far2 = std::max(far2, d2);
        near2 = std::min(near2, d2);
      }
    }
    const double r = std::sqrt(far2);
    const double lower = capVolume(r, std::clamp(r - std::sqrt(near2), 0.0, 2.0 * r));
    if (!std::isfinite(lower)) return std::numeric_limits<double>::infinity();
    if (lower > threshold) return lower;
    const double e = capVolume(r, std::clamp(r - surface.signedDistance(c, r), 0.0, 2.0 * r));
    return std::isfinite(e) ? e : std::numeric_limits<double>::infinity();
  };

  std::vector<std::uint32_t> clusterOf(m, 0);
  std::vector<Vec3> clusterCentre;
  struct Range {
    std::uint32_t begin, end;
  };
  std::vector<Range> stack{{0, static_cast<std::uint32_t>(m)}};
  while (!stack.empty()) {
    const Range r = stack.back();
    stack.pop_back();
    const double size = static_cast<double>(r.end - r.begin);
    Vec3 meanCentroid = Vec3::Zero(), meanNormal = Vec3::Zero(), meanPoint = Vec3::Zero();
    double depth = 0.0, weights = 0.0;
    for (std::uint32_t i = r.begin; i < r.end; ++i) {
      const std::uint32_t k = items[i];
      meanCentroid += centroid[k];
      meanNormal += mesh.normals[itemTriangle[k]];
      if (depthCount[k] > 0) {
        depth += depthSum[k] / depthCount[k];
        meanPoint += pointSum[k];
        weights += depthCount[k];
      }
    }
    meanCentroid /= size;
    depth /= size;
    Vec3 best = meanCentroid;  // the fallback (a patch on the surface): every other candidate beats it
    double bestExcess = std::numeric_limits<double>::infinity();
    // A single triangle is kept whatever d is: its centre is chosen on exact values.
    const double threshold = r.end - r.begin == 1 ? std::numeric_limits<double>::infinity() : d3;
    auto consider = [&](const Vec3& c) {
      if (!c.allFinite()) return;
      const double e = excess(c, r.begin, r.end, threshold);
      if (e < bestExcess) {
        bestExcess = e;
        best = c;
      }
    };
    if (weights > 0.0) consider(meanPoint / weights);
    const double normalLength = meanNormal.norm();
    if (normalLength > 1e-9 * size) {
      const Vec3 inward = -meanNormal / normalLength;
      if (depth > 0.0)
        for (const double f : {1.0, 0.75, 0.5, 0.25, 0.125}) consider(meanCentroid + f * depth * inward);
    }
    if (!std::isfinite(bestExcess)) bestExcess = excess(best, r.begin, r.end, threshold);  // no candidate: the patch itself
    if (r.end - r.begin == 1 || bestExcess <= d3) {
      for (std::uint32_t i = r.begin; i < r.end; ++i) clusterOf[items[i]] = static_cast<std::uint32_t>(clusterCentre.size());
      clusterCentre.push_back(best);
      continue;
    }
    const std::uint32_t mid = splitAtMean(items, r.begin, r.end, centroid);
    stack.push_back({mid, r.end});
    stack.push_back({r.begin, mid});
  }
  std::vector<std::uint32_t> order;
  const std::uint32_t count =
      labelPoints(clusterOf, itemOfPoint, static_cast<std::uint32_t>(clusterCentre.size()), labels, &order);
  centres.reserve(count);
  for (const std::uint32_t c : order) centres.push_back(clusterCentre[c]);
  return count;
}

}  // namespace clod_haptics
