#include "clod_haptics/core/probes.h"

#include <algorithm>
#include <random>

#include "clod_haptics/core/morton.h"

namespace clod_haptics {

std::vector<Vec3> nearSurfaceProbes(const TriangleMesh& mesh, std::size_t count, double maxOffset, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<double> cumulative(mesh.size());
  double total = 0.0;
  for (std::size_t t = 0; t < mesh.size(); ++t) {
    total += 0.5 * (mesh.vertex(t, 1) - mesh.vertex(t, 0)).cross(mesh.vertex(t, 2) - mesh.vertex(t, 0)).norm();
    cumulative[t] = total;
  }
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::uniform_real_distribution<double> offset(-maxOffset, maxOffset);
  std::uniform_int_distribution<std::size_t> anyTriangle(0, mesh.size() - 1);
  std::vector<Vec3> probes;
  probes.reserve(count);
  for (std::size_t i = 0; i < count; ++i) {
    std::size_t t;
    if (total > 0.0) {
      t = std::lower_bound(cumulative.begin(), cumulative.end(), unit(rng) * total) - cumulative.begin();
      t = std::min(t, mesh.size() - 1);
    } else {
      t = anyTriangle(rng);
    }
    double u = unit(rng), v = unit(rng);
    if (u + v > 1.0) {
      u = 1.0 - u;
      v = 1.0 - v;
    }
    const Vec3 point = mesh.vertex(t, 0) + u * (mesh.vertex(t, 1) - mesh.vertex(t, 0)) +
                       v * (mesh.vertex(t, 2) - mesh.vertex(t, 0));
    probes.push_back(mesh.toModel(point + offset(rng) * mesh.normals[t]));
  }
  return probes;
}

std::vector<Vec3> uniformProbes(const TriangleMesh& mesh, std::size_t count, double margin, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  const Eigen::AlignedBox3d box = mesh.modelBounds();
  const Vec3 lo = box.min() - Vec3::Constant(margin), size = box.sizes() + Vec3::Constant(2 * margin);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<Vec3> probes;
  probes.reserve(count);
  for (std::size_t i = 0; i < count; ++i) {
    const double x = unit(rng), y = unit(rng), z = unit(rng);
    probes.push_back(lo + Vec3(x * size.x(), y * size.y(), z * size.z()));
  }
  return probes;
}

void sortMorton(std::vector<Vec3>& points) {
  if (points.empty()) return;
  Eigen::AlignedBox3d box;
  for (const Vec3& p : points) box.extend(p);
  const double extent = std::max(box.sizes().maxCoeff(), 1e-300);
  std::vector<std::pair<std::uint64_t, Vec3>> keyed;
  keyed.reserve(points.size());
  for (const Vec3& p : points) {
    const Vec3 q = (p - box.min()) / extent * kMortonMax;
    keyed.emplace_back(mortonCode(q), p);
  }
  std::stable_sort(keyed.begin(), keyed.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  for (std::size_t i = 0; i < points.size(); ++i) points[i] = keyed[i].second;
}

}  // namespace clod_haptics
