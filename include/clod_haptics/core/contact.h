#pragma once

#include <cmath>
#include <cstdint>

#include "clod_haptics/core/geometry.h"
#include "clod_haptics/core/mesh.h"

namespace clod_haptics {

/**
 * \brief Largest pointer radius a query accepts: above it r * r overflows (or nearly), so squared
 * distances could compare inf <= inf. A larger radius is invalid input and answers no contact.
 */
constexpr double kMaxRadius = 1e150;

/** \brief Whether (p, r) is a pointer a query answers: finite centre, 0 <= r <= kMaxRadius. */
inline bool validPointer(const Vec3& p, double r) {
  return p.allFinite() && std::isfinite(r) && r >= 0.0 && r <= kMaxRadius;
}

/** \brief The precise level of the two-level detection (paper section 3.3). */
enum class DetectionMode : std::uint8_t {
  Exact,    ///< closest point on each candidate triangle, faces, edges and vertices: no contact missed
  Paper,    ///< Algorithm 2 as published: projection inside the triangle by cross-product signs
  Spheres,  ///< the fast level alone: contact with the clustered spheres, the coarsest answer
};

/** \brief Parses "exact", "paper" or "spheres"; returns false for anything else. */
bool parseDetectionMode(const char* text, DetectionMode& mode);
/** \brief The lower-case name of a mode. */
const char* toString(DetectionMode mode);

/** \brief What one query answers. Fields other than contact are meaningful only when contact is true. */
struct ContactResult {
  bool contact = false;
  Vec3 point = Vec3::Zero();   ///< closest surface point (spheres mode: closest point on the hit sphere)
  Vec3 normal = Vec3::Zero();  ///< unit outward surface normal at the contact, for the penalty force
  double distance = 0.0;       ///< distance from the pointer centre to point
  /**
   * Penetration depth, growing while the pointer pushes in: r - distance with the centre outside,
   * r + distance with it behind the surface (inside). Spheres mode: r - distance.
   */
  double depth = 0.0;
  bool inside = false;         ///< the pointer centre is behind the surface (pointBehindSurface)
  std::int32_t triangle = -1;  ///< triangle of the closest point (-1 in spheres mode)
  std::int32_t sphere = -1;    ///< clustered sphere through which it was found
  std::uint32_t spheresHit = 0;       ///< spheres the fast level reported
  std::uint32_t trianglesTested = 0;  ///< triangles the precise level tested
};

/**
 * \brief The angle-weighted pseudo-normal (Baerentzen & Aanaes 2005) of the feature of triangle t named by
 * region, not normalised: a face its normal; an edge the sum of its two triangles' normals; a vertex the
 * sum of its incident triangles' normals weighted by their angles there. An edge without a manifold
 * neighbour (boundary, non-manifold, inconsistent winding) gives the face normal. Built from mesh.normals
 * and the adjacency of computeAdjacency(); without that adjacency, the face normal. Allocates nothing.
 */
Vec3 pseudoNormal(const TriangleMesh& mesh, std::uint32_t t, const TriangleRegion& region) noexcept;

/**
 * \brief The shared sign rule: whether p lies behind the surface, q being its closest point on triangle t
 * (q on t, as a query found it). The sign of (p - q) . pseudo-normal of the feature of t that q lies on: exact
 * for a closed, consistently wound manifold mesh, whichever feature is closest. Falls back to the face
 * normal where the pseudo-normal is zero; p on the surface (q == p) is outside. On an open mesh or at a
 * non-manifold edge the answer is the side of the nearest face, which is all such a surface defines.
 * Allocates nothing.
 */
bool pointBehindSurface(const TriangleMesh& mesh, const Vec3& p, std::uint32_t t, const Vec3& q) noexcept;

/**
 * \brief Completes a contact whose point, distance and triangle are set, for pointer (p, r): inside
 * (pointBehindSurface), depth (r + distance inside, r - distance outside) and the unit outward normal
 * (from the point towards p outside, away from p inside; on the surface the pseudo-normal, else the face
 * normal, else +z). Never NaN; allocates nothing. The one rule brute force and the detector share.
 */
void finishContact(const TriangleMesh& mesh, const Vec3& p, double r, ContactResult& out) noexcept;

/**
 * \brief finishContact when the caller already has the feature of out.triangle that out.point lies on, as
 * closestPointOnTriangle(p, the triangle's vertices, &region) gives it (the same answer, without computing the
 * closest point again).
 */
void finishContact(const TriangleMesh& mesh, const Vec3& p, double r, const TriangleRegion& region,
                   ContactResult& out) noexcept;

/**
 * \brief The penalty spring force of a penetration vector (depth times the outward normal, summed over the
 * contacts of a scene): stiffness * penetration, clamped to maxForce when maxForce > 0; zero when the stiffness
 * is not positive or the result is not finite. depth is the signed penetration (ContactResult::depth), so the
 * force grows monotonically while the stylus pushes in, up to the clamp. Allocates nothing.
 */
Vec3 penaltyForce(const Vec3& penetration, double stiffness, double maxForce = 0.0) noexcept;

/** \brief The penalty force of one contact: penaltyForce(depth * normal, ...); zero without contact or depth. */
Vec3 penaltyForce(const ContactResult& result, double stiffness, double maxForce = 0.0) noexcept;

}  // namespace clod_haptics
