#include "clod_haptics/core/tight_placement.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>

#include "clod_haptics/core/triangle_bvh.h"
#include "parallel.h"

namespace clod_haptics {

std::vector<PlacedSphere> TightPlacement::place(const TriangleMesh& mesh, PlacementStats* stats) const {
  const auto start = std::chrono::steady_clock::now();
  const std::size_t n = mesh.size();
  const TriangleBvh bvh(mesh);
  const double minT = 1e-12 * mesh.diagonal();  // ignore hits at the origin itself (coplanar duplicates)
  // Distance along the inward normal to the first other triangle, or +inf.
  std::vector<double> depth(n, std::numeric_limits<double>::infinity());
  std::atomic<std::size_t> next{0};
  auto worker = [&]() {
    constexpr std::size_t kChunk = 256;
    for (;;) {
      const std::size_t begin = next.fetch_add(kChunk);
      if (begin >= n) return;
      const std::size_t end = std::min(n, begin + kChunk);
      for (std::size_t t = begin; t < end; ++t) {
        const Vec3& normal = mesh.normals[t];
        if (normal.isZero(0.0)) continue;
        double tMax = std::numeric_limits<double>::infinity();
        bvh.forEachRayHit(mesh.centroid(t), -normal, tMax, [&](std::uint32_t tri, double dist) {
          if (tri != t && dist > minT && dist < tMax) tMax = dist;  // lowering tMax prunes farther nodes
        });
        depth[t] = tMax;
      }
    }
  };
  // Ray casts are compute-bound: every hardware thread, at least 1024 rays each.
  detail::runParallel(detail::threadsFor(n, threads_, 1024, std::numeric_limits<unsigned>::max()),
                      [&](unsigned) { worker(); });

  PlacementStats s;
  s.triangles = n;
  std::vector<PlacedSphere> spheres;
  spheres.reserve(n);
  for (std::size_t t = 0; t < n; ++t) {
    Vec3 centre = mesh.centroid(t);
    if (mesh.normals[t].isZero(0.0)) {
      ++s.degenerate;
    } else if (!std::isfinite(depth[t])) {
      ++s.unpaired;
    } else {
      ++s.paired;
      centre -= 0.5 * depth[t] * mesh.normals[t];
    }
    double r2 = 0.0;
    for (int k = 0; k < 3; ++k) r2 = std::max(r2, (mesh.vertex(t, k) - centre).squaredNorm());
    spheres.push_back({centre, std::sqrt(r2), static_cast<std::uint32_t>(t)});
  }
  s.milliseconds = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  if (stats) *stats = s;
  return spheres;
}

}  // namespace clod_haptics
