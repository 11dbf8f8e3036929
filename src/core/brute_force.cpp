#include "clod_haptics/core/brute_force.h"

#include <cmath>
#include <limits>

#include "clod_haptics/core/geometry.h"

namespace clod_haptics {

namespace {

// The nearest triangle over all (ties: the lowest index), as point, distance and triangle in out.
// Returns the squared distance (infinity for a mesh without triangles).
double nearest(const TriangleMesh& mesh, const Vec3& p, ContactResult& out) {
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
  out.point = bestPoint;
  out.distance = std::sqrt(best);
  out.triangle = static_cast<std::int32_t>(bestTri);
  return best;
}

}  // namespace

namespace {

// Both references: the nearest triangle, finished by the shared sign rule; a contact within r, and with
// anyDepthInside also a centre behind the surface at any depth inside the mesh's bounds.
// p and the answer's point are in the model frame; the search runs in the mesh's local frame.
ContactResult reference(const TriangleMesh& mesh, const Vec3& model, double r, bool anyDepthInside) {
  ContactResult out;
  if (!validPointer(model, r)) return out;
  const Vec3 p = mesh.toLocal(model);
  ContactResult found;
  const double best = nearest(mesh, p, found);
  out.trianglesTested = found.trianglesTested;
  if (!std::isfinite(best)) return out;
  found.contact = true;
  finishContact(mesh, p, r, found);
  if (best <= r * r || (anyDepthInside && found.inside && mesh.bounds().contains(p))) {
    out = found;
    out.point = mesh.toModel(out.point);
  }
  return out;
}

}  // namespace

ContactResult bruteForceQuery(const TriangleMesh& mesh, const Vec3& p, double r) {
  return reference(mesh, p, r, false);
}

ContactResult bruteForceSignedQuery(const TriangleMesh& mesh, const Vec3& p, double r) {
  return reference(mesh, p, r, true);
}

}  // namespace clod_haptics
