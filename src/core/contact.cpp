#include "clod_haptics/core/contact.h"

#include <cmath>
#include <cstring>

#include "enum_names.h"

namespace clod_haptics {

namespace {
const detail::EnumNames<DetectionMode, 3> kModeNames = {
    {DetectionMode::Exact, "exact"}, {DetectionMode::Paper, "paper"}, {DetectionMode::Spheres, "spheres"}};
}  // namespace

bool parseDetectionMode(const char* text, DetectionMode& mode) { return detail::parseName(text, kModeNames, mode); }

const char* toString(DetectionMode mode) { return detail::nameOf(mode, kModeNames); }

Vec3 pseudoNormal(const TriangleMesh& mesh, std::uint32_t t, const TriangleRegion& region) noexcept {
  const Vec3& n = mesh.normals[t];
  const Triangle& tri = mesh.triangles[t];
  if (region.feature == TriangleFeature::Edge) {
    if (mesh.neighbours.size() != mesh.size()) return n;
    const std::uint32_t a = tri[region.index % 3], b = tri[(region.index + 1) % 3];
    for (const std::int32_t o : mesh.neighbours[t]) {
      if (o < 0) continue;
      const Triangle& u = mesh.triangles[static_cast<std::size_t>(o)];
      const bool hasA = u[0] == a || u[1] == a || u[2] == a, hasB = u[0] == b || u[1] == b || u[2] == b;
      if (hasA && hasB) return n + mesh.normals[static_cast<std::size_t>(o)];
    }
    return n;  // boundary or non-manifold edge: the face's side
  }
  if (region.feature == TriangleFeature::Vertex) {
    const std::uint32_t v = tri[region.index % 3];
    if (mesh.cornerOffsets.size() != mesh.vertices.size() + 1) return n;
    Vec3 sum = Vec3::Zero();
    for (std::uint32_t c = mesh.cornerOffsets[v]; c < mesh.cornerOffsets[v + 1]; ++c)
      sum += static_cast<double>(mesh.cornerAngles[c]) * mesh.normals[mesh.cornerTriangles[c]];
    return sum;
  }
  return n;
}

namespace {

// The pseudo-normal of a feature of triangle t, or the face normal where it is zero.
Vec3 featureNormal(const TriangleMesh& mesh, std::uint32_t t, const TriangleRegion& region) noexcept {
  const Vec3 pn = pseudoNormal(mesh, t, region);
  return pn.allFinite() && !pn.isZero(0.0) ? pn : mesh.normals[t];
}

// The feature of triangle t that p's closest point lies on.
TriangleRegion regionOf(const TriangleMesh& mesh, const Vec3& p, std::uint32_t t) noexcept {
  TriangleRegion region;
  closestPointOnTriangle(p, mesh.vertex(t, 0), mesh.vertex(t, 1), mesh.vertex(t, 2), &region);
  return region;
}

}  // namespace

bool pointBehindSurface(const TriangleMesh& mesh, const Vec3& p, std::uint32_t t, const Vec3& q) noexcept {
  return (p - q).dot(featureNormal(mesh, t, regionOf(mesh, p, t))) < 0.0;
}

void finishContact(const TriangleMesh& mesh, const Vec3& p, double r, ContactResult& out) noexcept {
  finishContact(mesh, p, r, regionOf(mesh, p, static_cast<std::uint32_t>(out.triangle)), out);
}

void finishContact(const TriangleMesh& mesh, const Vec3& p, double r, const TriangleRegion& region,
                   ContactResult& out) noexcept {
  const Vec3 pn = featureNormal(mesh, static_cast<std::uint32_t>(out.triangle), region);
  const Vec3 v = p - out.point;
  out.inside = v.dot(pn) < 0.0;
  out.depth = out.inside ? r + out.distance : r - out.distance;
  const double len = v.norm();
  if (len > 0.0 && std::isfinite(len)) {
    const Vec3 dir = v / len;
    if (dir.allFinite()) {
      out.normal = out.inside ? Vec3(-dir) : dir;
      return;
    }
  }
  const double n = pn.norm();
  if (n > 0.0 && std::isfinite(n)) {
    out.normal = pn / n;
  } else {
    out.normal = Vec3::UnitZ();  // on a zero-area triangle with no better direction
  }
}

Vec3 penaltyForce(const Vec3& penetration, double stiffness, double maxForce) noexcept {
  if (!(stiffness > 0.0)) return Vec3::Zero();
  Vec3 f = stiffness * penetration;
  if (!f.allFinite()) return Vec3::Zero();
  if (maxForce > 0.0) {
    const double n = f.norm();
    if (n > maxForce) f *= maxForce / n;
  }
  return f;
}

Vec3 penaltyForce(const ContactResult& result, double stiffness, double maxForce) noexcept {
  if (!result.contact || !(result.depth > 0.0)) return Vec3::Zero();
  return penaltyForce(Vec3(result.depth * result.normal), stiffness, maxForce);
}

}  // namespace clod_haptics
