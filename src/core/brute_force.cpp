#include "clod_haptics/core/brute_force.h"

#include <cmath>
#include <limits>

#include "clod_haptics/core/geometry.h"

namespace clod_haptics {

ContactResult bruteForceQuery(const TriangleMesh& mesh, const Vec3& p, double r) {
  ContactResult out;
  if (!validPointer(p, r)) return out;
  double best = std::numeric_limits<double>::infinity();
  std::size_t bestTri = 0;
  Vec3 bestPoint = Vec3::Zero();
  for (std::size_t t = 0; t < mesh.size(); ++t) {
    const Vec3 q = closestPointOnTriangle(p, mesh.vertex(t, 0), mesh.vertex(t, 1), mesh.vertex(t, 2));
    const double d2 = (p - q).squaredNorm();
    if (d2 < best) {  // strict: ties keep the lowest index
      best = d2;
      bestTri = t;
      bestPoint = q;
    }
  }
  out.trianglesTested = static_cast<std::uint32_t>(mesh.size());
  if (!(best <= r * r)) return out;
  out.contact = true;
  out.point = bestPoint;
  out.distance = std::sqrt(best);
  out.depth = r - out.distance;
  out.triangle = static_cast<std::int32_t>(bestTri);
  out.normal = contactNormal(p, bestPoint, mesh.normals[bestTri]);
  return out;
}

}  // namespace clod_haptics
