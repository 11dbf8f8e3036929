#include "clod_haptics/core/geometry.h"

#include <algorithm>
#include <cmath>

namespace clod_haptics {

bool projectInsideTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& n, Vec3& q) {
  if (n.isZero(0.0)) return false;
  q = p - (p - a).dot(n) * n;
  const double s0 = (b - a).cross(q - a).dot(n);
  const double s1 = (c - b).cross(q - b).dot(n);
  const double s2 = (a - c).cross(q - c).dot(n);
  return s0 >= 0.0 && s1 >= 0.0 && s2 >= 0.0;
}

namespace {

// Region of the point at parameter t on edge `edge`, t running from vertex `from` (0) to vertex `to` (1):
// an end is the vertex there.
TriangleRegion edgeRegion(double t, std::uint8_t from, std::uint8_t to, std::uint8_t edge) {
  if (t <= 0.0) return {TriangleFeature::Vertex, from};
  if (t >= 1.0) return {TriangleFeature::Vertex, to};
  return {TriangleFeature::Edge, edge};
}

// closestPointOnSegment with its parameter.
Vec3 onSegment(const Vec3& p, const Vec3& a, const Vec3& b, double& t) {
  const Vec3 ab = b - a;
  const double len2 = ab.squaredNorm();
  if (!(len2 > 0.0)) {
    t = 0.0;
    return a;
  }
  t = std::clamp((p - a).dot(ab) / len2, 0.0, 1.0);
  return a + t * ab;
}

// detail::closestOnEdges with the region.
Vec3 edgesWithRegion(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, TriangleRegion& region) {
  double t0, t1, t2;
  const Vec3 q0 = onSegment(p, a, b, t0);
  const Vec3 q1 = onSegment(p, b, c, t1);
  const Vec3 q2 = onSegment(p, c, a, t2);
  const double d0 = (p - q0).squaredNorm(), d1 = (p - q1).squaredNorm(), d2 = (p - q2).squaredNorm();
  if (d0 <= d1 && d0 <= d2) {
    region = edgeRegion(t0, 0, 1, 0);
    return q0;
  }
  if (d1 <= d2) {
    region = edgeRegion(t1, 1, 2, 1);
    return q1;
  }
  region = edgeRegion(t2, 2, 0, 2);
  return q2;
}

}  // namespace

// The arithmetic of the inline closestPointOnTriangle, step for step, so both give the same point.
Vec3 closestPointAndRegion(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, TriangleRegion& region) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) {
    region = {TriangleFeature::Vertex, 0};
    return a;
  }
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) {
    region = {TriangleFeature::Vertex, 1};
    return b;
  }
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
    const double den = d1 - d3;
    if (!(den > 0.0)) return edgesWithRegion(p, a, b, c, region);
    const double t = d1 / den;
    region = edgeRegion(t, 0, 1, 0);
    return a + t * ab;
  }
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) {
    region = {TriangleFeature::Vertex, 2};
    return c;
  }
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
    const double den = d2 - d6;
    if (!(den > 0.0)) return edgesWithRegion(p, a, b, c, region);
    const double t = d2 / den;
    region = edgeRegion(t, 0, 2, 2);  // edge 2 runs from c to a; t is measured from a
    return a + t * ac;
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
    const double den = (d4 - d3) + (d5 - d6);
    if (!(den > 0.0)) return edgesWithRegion(p, a, b, c, region);
    const double t = (d4 - d3) / den;
    region = edgeRegion(t, 1, 2, 1);
    return b + t * (c - b);
  }
  const double sum = va + vb + vc;
  const double scale = ab.squaredNorm() * ac.squaredNorm();
  if (!(sum > 1e-14 * scale) || !std::isfinite(sum)) return edgesWithRegion(p, a, b, c, region);
  const double denom = 1.0 / sum;
  region = {TriangleFeature::Face, 0};
  return a + ab * (vb * denom) + ac * (vc * denom);
}

}  // namespace clod_haptics
