#pragma once

#include "clod_haptics/core/mesh.h"

namespace clod_haptics {

/** \brief Where on a triangle a closest point lies; the paper's precise test sees only Face. */
enum class TriangleFeature : std::uint8_t { Face, Edge, Vertex };

/**
 * \brief Closest point on triangle (a, b, c) to p, exact in double precision for every point,
 * including those whose closest point is on an edge or a vertex. Zero-area triangles are handled
 * as their longest edge (never NaN).
 * \param feature if not null, receives the feature the closest point lies on.
 */
Vec3 closestPointOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c,
                            TriangleFeature* feature = nullptr);

/** \brief Closest point on segment [a, b] to p; a zero-length segment gives a. */
Vec3 closestPointOnSegment(const Vec3& p, const Vec3& a, const Vec3& b);

/**
 * \brief The paper's Algorithm 2: project p onto the triangle's plane and accept the projection when
 * the cross products (b-a)x(q-a), (c-b)x(q-b), (a-c)x(q-c) all point along the normal n.
 * \return true and the projection in q when it lies inside (boundary included); false for a
 * projection outside the triangle or a zero normal.
 */
bool projectInsideTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& n, Vec3& q);

/**
 * \brief Ray against triangle (Moller-Trumbore, both faces).
 * \return true with the ray parameter in t when the ray hits the closed triangle at t > 0.
 */
bool rayTriangle(const Vec3& origin, const Vec3& dir, const Vec3& a, const Vec3& b, const Vec3& c, double& t);

/** \brief Squared distance from p to the box (zero inside). */
inline double squaredDistanceToBox(const Vec3& p, const Vec3& lo, const Vec3& hi) {
  const Vec3 d = (lo - p).cwiseMax(p - hi).cwiseMax(0.0);
  return d.squaredNorm();
}

}  // namespace clod_haptics
