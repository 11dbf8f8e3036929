#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

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
inline Vec3 closestPointOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c,
                                   TriangleFeature* feature = nullptr);

/**
 * \brief Which feature of a triangle a closest point lies on, and which one: the region the
 * inside/outside test needs (the pseudo-normal of that feature).
 */
struct TriangleRegion {
  TriangleFeature feature = TriangleFeature::Face;
  std::uint8_t index = 0;  ///< Edge: edge (index, index + 1 mod 3); Vertex: vertex index; Face: 0
};

/**
 * \brief The closest point of closestPointOnTriangle (the same arithmetic, the same point) and its region.
 * A point computed on an edge that lands on an end (parameter 0 or 1) is reported as that vertex.
 * Not inline: the detector's hot loop calls the inline version; this one runs once per answer.
 */
Vec3 closestPointAndRegion(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, TriangleRegion& region);

/** \brief Closest point on segment [a, b] to p; a zero-length segment gives a. */
inline Vec3 closestPointOnSegment(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 ab = b - a;
  const double len2 = ab.squaredNorm();
  if (!(len2 > 0.0)) return a;
  const double t = std::clamp((p - a).dot(ab) / len2, 0.0, 1.0);
  return a + t * ab;
}

/**
 * \brief The paper's Algorithm 2: project p onto the triangle's plane and accept the projection when
 * the cross products (b-a)x(q-a), (c-b)x(q-b), (a-c)x(q-c) all point along the normal n.
 * \return true and the projection in q when it lies inside (boundary included); false for a
 * projection outside the triangle or a zero normal.
 */
bool projectInsideTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& n, Vec3& q);

/**
 * \brief Ray against triangle (Moller-Trumbore, both faces). Inline: the placement's ray casts call it
 * for every triangle of every leaf they reach.
 * \return true with the ray parameter in t when the ray hits the closed triangle at t > 0.
 */
inline bool rayTriangle(const Vec3& origin, const Vec3& dir, const Vec3& a, const Vec3& b, const Vec3& c, double& t) {
  const Vec3 e1 = b - a, e2 = c - a;
  const Vec3 pv = dir.cross(e2);
  const double det = e1.dot(pv);
  if (det == 0.0 || !std::isfinite(det)) return false;
  const double inv = 1.0 / det;
  const Vec3 tv = origin - a;
  const double u = tv.dot(pv) * inv;
  if (u < 0.0 || u > 1.0) return false;
  const Vec3 qv = tv.cross(e1);
  const double v = dir.dot(qv) * inv;
  if (v < 0.0 || u + v > 1.0) return false;
  t = e2.dot(qv) * inv;
  return t > 0.0;
}

/** \brief Squared distance from p to the box (zero inside). */
inline double squaredDistanceToBox(const Vec3& p, const Vec3& lo, const Vec3& hi) {
  const Vec3 d = (lo - p).cwiseMax(p - hi).cwiseMax(0.0);
  return d.squaredNorm();
}

namespace detail {

// A zero-area triangle is a segment (or a point): its closest point is on one of its edges.
inline Vec3 closestOnEdges(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, TriangleFeature* feature) {
  const Vec3 q0 = closestPointOnSegment(p, a, b);
  const Vec3 q1 = closestPointOnSegment(p, b, c);
  const Vec3 q2 = closestPointOnSegment(p, c, a);
  const double d0 = (p - q0).squaredNorm(), d1 = (p - q1).squaredNorm(), d2 = (p - q2).squaredNorm();
  if (feature) *feature = TriangleFeature::Edge;
  if (d0 <= d1 && d0 <= d2) return q0;
  return d1 <= d2 ? q1 : q2;
}

}  // namespace detail

// Ericson, Real-Time Collision Detection, 5.1.5: Voronoi regions of vertices, edges, then the face.
inline Vec3 closestPointOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, TriangleFeature* feature) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) {
    if (feature) *feature = TriangleFeature::Vertex;
    return a;
  }
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) {
    if (feature) *feature = TriangleFeature::Vertex;
    return b;
  }
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
    const double den = d1 - d3;
    if (!(den > 0.0)) return detail::closestOnEdges(p, a, b, c, feature);
    if (feature) *feature = TriangleFeature::Edge;
    return a + (d1 / den) * ab;
  }
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) {
    if (feature) *feature = TriangleFeature::Vertex;
    return c;
  }
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
    const double den = d2 - d6;
    if (!(den > 0.0)) return detail::closestOnEdges(p, a, b, c, feature);
    if (feature) *feature = TriangleFeature::Edge;
    return a + (d2 / den) * ac;
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
    const double den = (d4 - d3) + (d5 - d6);
    if (!(den > 0.0)) return detail::closestOnEdges(p, a, b, c, feature);
    if (feature) *feature = TriangleFeature::Edge;
    return b + ((d4 - d3) / den) * (c - b);
  }
  const double sum = va + vb + vc;
  // sum is twice the squared area times a positive factor; a tiny one means a sliver whose face
  // coordinates would be noise, so the edges answer instead.
  const double scale = ab.squaredNorm() * ac.squaredNorm();
  if (!(sum > 1e-14 * scale) || !std::isfinite(sum)) return detail::closestOnEdges(p, a, b, c, feature);
  const double denom = 1.0 / sum;
  if (feature) *feature = TriangleFeature::Face;
  return a + ab * (vb * denom) + ac * (vc * denom);
}

}  // namespace clod_haptics
