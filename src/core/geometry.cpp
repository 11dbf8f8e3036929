#include "clod_haptics/core/geometry.h"

#include <algorithm>
#include <cmath>

namespace clod_haptics {

Vec3 closestPointOnSegment(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 ab = b - a;
  const double len2 = ab.squaredNorm();
  if (!(len2 > 0.0)) return a;
  const double t = std::clamp((p - a).dot(ab) / len2, 0.0, 1.0);
  return a + t * ab;
}

namespace {

// A zero-area triangle is a segment (or a point): its closest point is on one of its edges.
Vec3 closestOnEdges(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, TriangleFeature* feature) {
  const Vec3 q0 = closestPointOnSegment(p, a, b);
  const Vec3 q1 = closestPointOnSegment(p, b, c);
  const Vec3 q2 = closestPointOnSegment(p, c, a);
  const double d0 = (p - q0).squaredNorm(), d1 = (p - q1).squaredNorm(), d2 = (p - q2).squaredNorm();
  if (feature) *feature = TriangleFeature::Edge;
  if (d0 <= d1 && d0 <= d2) return q0;
  return d1 <= d2 ? q1 : q2;
}

}  // namespace

// Ericson, Real-Time Collision Detection, 5.1.5: Voronoi regions of vertices, edges, then the face.
Vec3 closestPointOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, TriangleFeature* feature) {
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
    if (!(den > 0.0)) return closestOnEdges(p, a, b, c, feature);
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
    if (!(den > 0.0)) return closestOnEdges(p, a, b, c, feature);
    if (feature) *feature = TriangleFeature::Edge;
    return a + (d2 / den) * ac;
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
    const double den = (d4 - d3) + (d5 - d6);
    if (!(den > 0.0)) return closestOnEdges(p, a, b, c, feature);
    if (feature) *feature = TriangleFeature::Edge;
    return b + ((d4 - d3) / den) * (c - b);
  }
  const double sum = va + vb + vc;
  // sum is twice the squared area times a positive factor; a tiny one means a sliver whose face
  // coordinates would be noise, so the edges answer instead.
  const double scale = ab.squaredNorm() * ac.squaredNorm();
  if (!(sum > 1e-14 * scale) || !std::isfinite(sum)) return closestOnEdges(p, a, b, c, feature);
  const double denom = 1.0 / sum;
  if (feature) *feature = TriangleFeature::Face;
  return a + ab * (vb * denom) + ac * (vc * denom);
}

bool projectInsideTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& n, Vec3& q) {
  if (n.isZero(0.0)) return false;
  q = p - (p - a).dot(n) * n;
  const double s0 = (b - a).cross(q - a).dot(n);
  const double s1 = (c - b).cross(q - b).dot(n);
  const double s2 = (a - c).cross(q - c).dot(n);
  return s0 >= 0.0 && s1 >= 0.0 && s2 >= 0.0;
}

bool rayTriangle(const Vec3& origin, const Vec3& dir, const Vec3& a, const Vec3& b, const Vec3& c, double& t) {
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

}  // namespace clod_haptics
