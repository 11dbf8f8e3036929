#include "clod_haptics/core/triangle_bvh.h"

#include <algorithm>
#include <cmath>

#include "../float_rounding.h"

namespace clod_haptics {
namespace detail {

// Why the float test keeps every node the double one keeps. With B = sceneBound + the largest origin
// coordinate (both under 2^30) and every box widened by w = 2^-18 B on each side, a slab's numerator
// (lo - w) - o in float is below lo - o by at least w/4 after the roundings of o, lo - w and the
// difference (each at most 2^-24 B), and its product with the inverse direction (rounded once more, an
// inverse between 2^-30 and 2^30) stays on the far side of the double product: the relative error
// 2^-23 |lo - o| is under w/4. So every near distance in float is at most the double one and every far
// distance at least it, entry <= exit holds whenever it holds in double, and the entry is a lower
// bound. A direction component under 2^-30 (or zero, which the double test makes 1e-300) gets the
// inverse +-2^120: the ray is then inside that slab in float whenever the double test can enter the
// slab before the ray leaves the box along its largest component (at least 1/4, so the exit is within
// 4 B) -- the double entry through that slab is at least 2^30 times the gap, the float gap is below
// zero for any gap under w/4 -- and an exit through it is beyond every other exit. The normals' lower
// bound in float differs from the double sum by at most 2^-22 (|m0| + |m1| + |m2|) (components of
// normals at most 1): slack is twice that plus PacketCull::kSlack, and the thresholds round up.
void PacketFloat::setCull(const PacketCull& cull, int r) {
  double sum = 0.0;
  for (int k = 0; k < 3; ++k) {
    axis[k][r] = static_cast<float>(cull.axis[k][r]);
    sum += std::fabs(cull.axis[k][r]);
  }
  slack[r] = roundUp(sum * 0x1p-21 + 2.0 * PacketCull::kSlack);
  cap[r] = roundUp(cull.cap[r]);
  below[r] = roundUp(cull.below[r]);
  nearBelow[r] = roundUp(cull.nearBelow[r]);
  within[r] = roundUp(cull.within[r]);
}

bool PacketFloat::set(const double* origins, const double* dirs, const double* inverse, int count, double sceneBound,
                      const PacketCull& cull) {
  constexpr int W = PacketCull::kRays;
  constexpr double kLimit = 1073741824.0;  // 2^30
  double bound = sceneBound;
  for (int r = 0; r < W; ++r) {
    double largest = 0.0;
    for (int k = 0; k < 3; ++k) {
      bound = std::max(bound, std::fabs(origins[k * W + r]));
      largest = std::max(largest, std::fabs(dirs[k * W + r]));
    }
    // NaN fails every test here
    if (!(largest >= 0.25 && largest <= kLimit)) return false;
  }
  if (!(bound >= 1e-18 && bound <= kLimit)) return false;  // the widening stays a normal float
  const double w = std::ldexp(bound, -18);
  widen = roundUp(w);
  for (int k = 0; k < 3; ++k)
    for (int r = 0; r < W; ++r) {
      o[k][r] = static_cast<float>(origins[k * W + r]);
      const double d = dirs[k * W + r];
      inv[k][r] = std::fabs(d) >= 1.0 / kLimit ? static_cast<float>(inverse[k * W + r])
                                               : std::copysign(0x1p120f, float(inverse[k * W + r]));
    }
  for (int r = 0; r < W; ++r) setCull(cull, r < count ? r : 0);
  return true;
}

}  // namespace detail
}  // namespace clod_haptics
