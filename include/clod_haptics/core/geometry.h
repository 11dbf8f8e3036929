#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "clod_haptics/core/mesh.h"

namespace clod_haptics {

/** \brief Where on a triangle a closest point lies; the paper's precise test sees only Face. */
enum class TriangleFeature : std::uint8_t { Face, Edge, Vertex };

/**
 * \brief Which feature of a triangle a closest point lies on, and which one: the region the
 * inside/outside test needs (the pseudo-normal of that feature).
 */
struct TriangleRegion {
  TriangleFeature feature = TriangleFeature::Face;
  std::uint8_t index = 0;  ///< Edge: edge (index, index + 1 mod 3); Vertex: vertex index; Face: 0
};

/**
 * \brief Closest point on triangle (a, b, c) to p, exact in double precision for every point,
 * including those whose closest point is on an edge or a vertex. Zero-area triangles are handled
 * as their closest edge (never NaN). Inline: the detector's hot loop calls it with region null, and
 * the region's bookkeeping then compiles away.
 * \param region if not null, receives the feature the closest point lies on; a point computed on an
 * edge that lands on an end (parameter 0 or 1) is reported as that vertex.
 */
inline Vec3 closestPointOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c,
                                   TriangleRegion* region = nullptr);

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

// The region of the point at parameter t on edge `edge`, t running from vertex `from` (0) to `to` (1).
inline void setEdgeRegion(TriangleRegion* region, double t, std::uint8_t from, std::uint8_t to, std::uint8_t edge) {
  if (!region) return;
  if (t <= 0.0) {
    *region = {TriangleFeature::Vertex, from};
  } else if (t >= 1.0) {
    *region = {TriangleFeature::Vertex, to};
  } else {
    *region = {TriangleFeature::Edge, edge};
  }
}

inline void setVertexRegion(TriangleRegion* region, std::uint8_t vertex) {
  if (region) *region = {TriangleFeature::Vertex, vertex};
}

// closestPointOnSegment with its parameter t.
inline Vec3 onSegment(const Vec3& p, const Vec3& a, const Vec3& b, double& t) {
  const Vec3 ab = b - a;
  const double len2 = ab.squaredNorm();
  t = len2 > 0.0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return len2 > 0.0 ? Vec3(a + t * ab) : a;
}

// A zero-area triangle is a segment (or a point): its closest point is on one of its edges.
inline Vec3 closestOnEdges(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, TriangleRegion* region) {
  double t0, t1, t2;
  const Vec3 q0 = onSegment(p, a, b, t0);
  const Vec3 q1 = onSegment(p, b, c, t1);
  const Vec3 q2 = onSegment(p, c, a, t2);
  const double d0 = (p - q0).squaredNorm(), d1 = (p - q1).squaredNorm(), d2 = (p - q2).squaredNorm();
  if (d0 <= d1 && d0 <= d2) {
    setEdgeRegion(region, t0, 0, 1, 0);
    return q0;
  }
  if (d1 <= d2) {
    setEdgeRegion(region, t1, 1, 2, 1);
    return q1;
  }
  setEdgeRegion(region, t2, 2, 0, 2);
  return q2;
}

}  // namespace detail

// Ericson, Real-Time Collision Detection, 5.1.5: Voronoi regions of vertices, edges, then the face.
inline Vec3 closestPointOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, TriangleRegion* region) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) {
    detail::setVertexRegion(region, 0);
    return a;
  }
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) {
    detail::setVertexRegion(region, 1);
    return b;
  }
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
    const double den = d1 - d3;
    if (!(den > 0.0)) return detail::closestOnEdges(p, a, b, c, region);
    const double t = d1 / den;
    detail::setEdgeRegion(region, t, 0, 1, 0);
    return a + t * ab;
  }
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) {
    detail::setVertexRegion(region, 2);
    return c;
  }
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
    const double den = d2 - d6;
    if (!(den > 0.0)) return detail::closestOnEdges(p, a, b, c, region);
    const double t = d2 / den;
    detail::setEdgeRegion(region, t, 0, 2, 2);  // edge 2 runs from c to a; t is measured from a
    return a + t * ac;
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
    const double den = (d4 - d3) + (d5 - d6);
    if (!(den > 0.0)) return detail::closestOnEdges(p, a, b, c, region);
    const double t = (d4 - d3) / den;
    detail::setEdgeRegion(region, t, 1, 2, 1);
    return b + t * (c - b);
  }
  const double sum = va + vb + vc;
  // sum is twice the squared area times a positive factor; a tiny one means a sliver whose face
  // coordinates would be noise, so the edges answer instead.
  const double scale = ab.squaredNorm() * ac.squaredNorm();
  if (!(sum > 1e-14 * scale) || !std::isfinite(sum)) return detail::closestOnEdges(p, a, b, c, region);
  const double denom = 1.0 / sum;
  if (region) *region = {TriangleFeature::Face, 0};
  return a + ab * (vb * denom) + ac * (vc * denom);
}

}  // namespace clod_haptics
