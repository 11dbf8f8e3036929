#pragma once

#include <cmath>
#include <cstdint>

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
  double depth = 0.0;          ///< penetration depth: pointer radius - distance
  std::int32_t triangle = -1;  ///< triangle of the closest point (-1 in spheres mode)
  std::int32_t sphere = -1;    ///< clustered sphere through which it was found
  std::uint32_t spheresHit = 0;       ///< spheres the fast level reported
  std::uint32_t trianglesTested = 0;  ///< triangles the precise level tested
};

/**
 * \brief Fills the outward normal for a contact at q from pointer centre p on a triangle with face
 * normal n: the direction from q to p, flipped to n's side when p lies behind the face, or n itself
 * when p is on the surface. Never NaN.
 */
Vec3 contactNormal(const Vec3& p, const Vec3& q, const Vec3& faceNormal);

}  // namespace clod_haptics
