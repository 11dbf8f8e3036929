#include "medial_reference.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <unordered_map>

namespace clod_bench {
namespace {

/** Nearest sample to a point through a uniform grid (rings of cells until the ring is beyond the best). */
class PointGrid {
 public:
  PointGrid(const std::vector<Vec3>& points, double cell) : points_(points), cell_(cell) {
    for (std::uint32_t i = 0; i < points.size(); ++i) cells_[key(cellOf(points[i]))].push_back(i);
    for (const Vec3& p : points) box_.extend(p);
  }
  // The nearest sample to c other than skip within reach (skip when none; dist then +inf): rings of cells, only
  // each ring's shell, until the ring lies beyond the best or the reach.
  std::uint32_t nearest(const Vec3& c, std::uint32_t skip, double reach, double& dist) const {
    const Eigen::Vector3i k = cellOf(c);
    double best2 = reach * reach;
    std::uint32_t best = skip;
    const int maxRing = static_cast<int>(std::ceil(reach / cell_)) + 1;
    for (int ring = 0; ring <= maxRing; ++ring) {
      if ((ring - 1) * cell_ > std::sqrt(best2)) break;
      for (int x = -ring; x <= ring; ++x)
        for (int y = -ring; y <= ring; ++y) {
          const bool side = std::abs(x) == ring || std::abs(y) == ring;
          for (int z = -ring; z <= ring; z += side || ring == 0 ? 1 : 2 * ring) {
            const auto it = cells_.find(key(k + Eigen::Vector3i(x, y, z)));
            if (it == cells_.end()) continue;
            for (std::uint32_t i : it->second) {
              if (i == skip) continue;
              const double d2 = (points_[i] - c).squaredNorm();
              if (d2 < best2) best2 = d2, best = i;
            }
          }
        }
    }
    dist = best == skip ? std::numeric_limits<double>::infinity() : std::sqrt(best2);
    return best;
  }

 private:
  Eigen::Vector3i cellOf(const Vec3& p) const {
    return Eigen::Vector3i(static_cast<int>(std::floor(p.x() / cell_)), static_cast<int>(std::floor(p.y() / cell_)),
                           static_cast<int>(std::floor(p.z() / cell_)));
  }
  static std::int64_t key(const Eigen::Vector3i& k) {
    return (static_cast<std::int64_t>(k.x()) & 0x1fffff) | (static_cast<std::int64_t>(k.y()) & 0x1fffff) << 21 |
           (static_cast<std::int64_t>(k.z()) & 0x1fffff) << 42;
  }
  const std::vector<Vec3>& points_;
  double cell_;
  Eigen::AlignedBox3d box_;
  std::unordered_map<std::int64_t, std::vector<std::uint32_t>> cells_;
};

}  // namespace

void surfaceSamples(const TriangleMesh& mesh, std::size_t count, std::uint64_t seed, std::vector<Vec3>& points,
                    std::vector<Vec3>* normals) {
  std::vector<double> cumulative(mesh.size());
  double total = 0.0;
  for (std::size_t t = 0; t < mesh.size(); ++t) {
    total += 0.5 * (mesh.vertex(t, 1) - mesh.vertex(t, 0)).cross(mesh.vertex(t, 2) - mesh.vertex(t, 0)).norm();
    cumulative[t] = total;
  }
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  points.resize(count);
  if (normals) normals->resize(count);
  for (std::size_t i = 0; i < count; ++i) {
    const std::size_t t = std::min<std::size_t>(
        mesh.size() - 1, std::lower_bound(cumulative.begin(), cumulative.end(), unit(rng) * total) - cumulative.begin());
    double u = unit(rng), v = unit(rng);
    if (u + v > 1.0) u = 1.0 - u, v = 1.0 - v;
    points[i] = mesh.vertex(t, 0) + u * (mesh.vertex(t, 1) - mesh.vertex(t, 0)) + v * (mesh.vertex(t, 2) - mesh.vertex(t, 0));
    if (normals) (*normals)[i] = mesh.normals[t];
  }
}

SphereList medialSpheres(const TriangleMesh& mesh, std::size_t target, std::size_t samples, std::uint64_t seed) {
  std::vector<Vec3> points, normals;
  surfaceSamples(mesh, samples, seed, points, &normals);
  const double diagonal = mesh.diagonal();
  const PointGrid grid(points, diagonal / 64.0);
  // Shrinking ball: the largest ball tangent at p (centre along the inward normal) holding no other sample.
  std::vector<Vec3> centre(points.size());
  std::vector<double> radius(points.size());
  std::vector<char> valid(points.size(), 0);
  const InsideTest inside(mesh);
  for (std::uint32_t i = 0; i < points.size(); ++i) {
    const Vec3 m = -normals[i];
    double r = 0.25 * diagonal;
    for (int iteration = 0; iteration < 40; ++iteration) {
      const Vec3 c = points[i] + r * m;
      double dist;
      const std::uint32_t q = grid.nearest(c, i, r, dist);
      if (q == i || dist >= r * (1.0 - 1e-9)) break;
      const double along = m.dot(points[q] - points[i]);
      if (!(along > 0.0)) break;
      const double next = (points[q] - points[i]).squaredNorm() / (2.0 * along);
      if (!(next < r)) break;
      r = next;
    }
    centre[i] = points[i] + r * m;
    radius[i] = r;
    // A ball that never shrank, or whose centre is outside (a sample too sparse to stop it), is no medial ball.
    valid[i] = r < 0.25 * diagonal && inside.inside(centre[i]);
  }
  // Farthest-point sampling of the medial centres.
  std::vector<std::uint32_t> chosen;
  std::vector<double> far(points.size(), std::numeric_limits<double>::infinity());
  for (std::uint32_t i = 0; i < points.size(); ++i)
    if (!valid[i]) far[i] = -1.0;  // never chosen
  std::uint32_t next = static_cast<std::uint32_t>(std::find(valid.begin(), valid.end(), 1) - valid.begin());
  if (next == points.size()) return {};
  while (chosen.size() < std::min(target, points.size())) {
    const std::uint32_t current = next;
    chosen.push_back(current);
    double best = -1.0;
    for (std::uint32_t i = 0; i < points.size(); ++i) {
      if (valid[i]) far[i] = std::min(far[i], (centre[i] - centre[current]).norm());
      if (far[i] > best) best = far[i], next = i;
    }
    if (best <= 0.0) break;
  }
  // Each sample to the chosen ball whose surface is nearest; each sphere grows to reach its samples.
  SphereList out;
  out.centres.resize(chosen.size());
  out.radii.assign(chosen.size(), 0.0);
  for (std::size_t k = 0; k < chosen.size(); ++k) out.centres[k] = centre[chosen[k]];
  for (std::uint32_t i = 0; i < points.size(); ++i) {
    std::size_t best = 0;
    double bestGap = std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k < chosen.size(); ++k) {
      const double gap = (points[i] - out.centres[k]).norm() - radius[chosen[k]];
      if (gap < bestGap) bestGap = gap, best = k;
    }
    out.radii[best] = std::max(out.radii[best], (points[i] - out.centres[best]).norm());
  }
  // Spheres that got no sample are dropped.
  SphereList kept;
  for (std::size_t k = 0; k < chosen.size(); ++k)
    if (out.radii[k] > 0.0) kept.centres.push_back(out.centres[k]), kept.radii.push_back(out.radii[k]);
  return kept;
}

SphereList grownToCover(SphereList spheres, const TriangleMesh& mesh, std::size_t samples, std::uint64_t seed) {
  std::vector<Vec3> points;
  surfaceSamples(mesh, samples, seed, points, nullptr);
  for (const Vec3& p : points) {
    double least = std::numeric_limits<double>::infinity();
    std::size_t grow = 0;
    for (std::size_t i = 0; i < spheres.radii.size(); ++i) {
      const double need = (p - spheres.centres[i]).norm() - spheres.radii[i];
      if (need < least) least = need, grow = i;
    }
    if (least > 0.0) spheres.radii[grow] += least;
  }
  return spheres;
}

}  // namespace clod_bench
