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
