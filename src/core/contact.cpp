#include "clod_haptics/core/contact.h"

#include <cmath>
#include <cstring>

namespace clod_haptics {

bool parseDetectionMode(const char* text, DetectionMode& mode) {
  if (text == nullptr) return false;
  if (std::strcmp(text, "exact") == 0) {
    mode = DetectionMode::Exact;
  } else if (std::strcmp(text, "paper") == 0) {
    mode = DetectionMode::Paper;
  } else if (std::strcmp(text, "spheres") == 0) {
    mode = DetectionMode::Spheres;
  } else {
    return false;
  }
  return true;
}

const char* toString(DetectionMode mode) {
  switch (mode) {
    case DetectionMode::Exact:
      return "exact";
    case DetectionMode::Paper:
      return "paper";
    case DetectionMode::Spheres:
      return "spheres";
  }
  return "unknown";
}

Vec3 contactNormal(const Vec3& p, const Vec3& q, const Vec3& faceNormal) {
  const Vec3 v = p - q;
  const double len = v.norm();
  if (len > 0.0 && std::isfinite(len)) {
    Vec3 dir = v / len;
    if (dir.dot(faceNormal) < 0.0) dir = -dir;
    return dir;
  }
  if (!faceNormal.isZero(0.0)) return faceNormal;
  return Vec3::UnitZ();  // pointer centre exactly on a zero-area triangle: no direction is better than another
}

}  // namespace clod_haptics
