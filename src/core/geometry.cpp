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

}  // namespace clod_haptics
