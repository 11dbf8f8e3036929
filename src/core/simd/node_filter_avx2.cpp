#include "node_filter_avx2.h"

#if defined(CLOD_PACKET_AVX2)
#include <immintrin.h>

#include "avx2_ops.h"
#endif

namespace clod_haptics {
namespace detail {

#if defined(CLOD_PACKET_AVX2)

__attribute__((target("avx2"))) unsigned nodeFilterAvx2(const NodeLanes& lanes, unsigned count,
                                                        const NodeFilterSweep& s, double enter[4]) {
  using namespace avx2;
  const __m256d zero = _mm256_setzero_pd(), one = _mm256_set1_pd(1.0), sign = _mm256_set1_pd(-0.0);
  const __m256d grow = _mm256_set1_pd(s.grow);
  // The box grown by grow: the times [t0, t1] the centre spends in it (clipToBox, lane by lane the same arithmetic).
  __m256d t0 = zero, t1 = one, keep = _mm256_castsi256_pd(_mm256_set1_epi64x(-1));
  __m256d lo[3], hi[3];
  for (int k = 0; k < 3; ++k) {
    lo[k] = _mm256_load_pd(lanes.lo[k]);
    hi[k] = _mm256_load_pd(lanes.hi[k]);
    const __m256d glo = minus(lo[k], grow), ghi = plus(hi[k], grow), a = _mm256_set1_pd(s.a[k]);
    if (s.d[k] == 0.0) {
      keep = both(keep, both(greaterEqual(a, glo), lessEqual(a, ghi)));
      continue;
    }
    const __m256d inv = _mm256_set1_pd(s.inv[k]);
    const __m256d e = times(minus(glo, a), inv), l = times(minus(ghi, a), inv);
    t0 = larger(t0, smaller(e, l));
    t1 = smaller(t1, larger(e, l));
  }
  keep = both(keep, lessEqual(t0, t1));
  // Entered after the best time: nothing inside can win (the scalar walk pushes it and skips it).
  t1 = smaller(t1, _mm256_set1_pd(s.tMax));
  keep = both(keep, lessEqual(t0, t1));
  // The part of the sweep inside the grown box, [p0, p1]: its bounding box's gap to the node's box.
  __m256d p0[3], p1[3], gap2 = zero;
  for (int k = 0; k < 3; ++k) {
    const __m256d a = _mm256_set1_pd(s.a[k]), d = _mm256_set1_pd(s.d[k]);
    p0[k] = plus(a, times(t0, d));
    p1[k] = plus(a, times(t1, d));
    const __m256d g = larger(larger(minus(lo[k], larger(p0[k], p1[k])), minus(smaller(p0[k], p1[k]), hi[k])), zero);
    gap2 = plus(gap2, times(g, g));
  }
  keep = both(keep, lessEqual(gap2, _mm256_set1_pd(s.grow * s.grow * (1.0 + 1e-9))));
  // The slab and ball (planeBoundMisses on [p0, p1]), loosened as the records' filter.
  const __m256d radius = _mm256_load_pd(lanes.radius), thick = _mm256_load_pd(lanes.thick);
  const __m256d hasSlab = lessThan(radius, _mm256_set1_pd(__builtin_inf()));
  const __m256d nx = _mm256_load_pd(lanes.normal[0]), ny = _mm256_load_pd(lanes.normal[1]),
                nz = _mm256_load_pd(lanes.normal[2]);
  const __m256d cx = _mm256_load_pd(lanes.centre[0]), cy = _mm256_load_pd(lanes.centre[1]),
                cz = _mm256_load_pd(lanes.centre[2]);
  const __m256d loose = _mm256_set1_pd(1.0 + 1e-9);
  const __m256d mx = minus(p0[0], cx), my = minus(p0[1], cy), mz = minus(p0[2], cz);
  const __m256d dx = minus(p1[0], p0[0]), dy = minus(p1[1], p0[1]), dz = minus(p1[2], p0[2]);
  const __m256d s0 = dot3(nx, mx, ny, my, nz, mz), sd = dot3(nx, dx, ny, dy, nz, dz), s1 = plus(s0, sd);
  const __m256d nearer = smaller(_mm256_andnot_pd(sign, s0), _mm256_andnot_pd(sign, s1));
  const __m256d oneSide = greaterThan(times(s0, s1), zero);
  const __m256d acrossGap = _mm256_div_pd(minus(nearer, times(thick, loose)), loose);
  const __m256d reach = _mm256_set1_pd(s.reach);
  const __m256d farAcross = both(oneSide, greaterThan(acrossGap, reach));
  const __m256d acrossLow = both(oneSide, larger(acrossGap, zero));
  const __m256d mpx = minus(mx, times(s0, nx)), mpy = minus(my, times(s0, ny)), mpz = minus(mz, times(s0, nz));
  const __m256d dpx = minus(dx, times(sd, nx)), dpy = minus(dy, times(sd, ny)), dpz = minus(dz, times(sd, nz));
  const __m256d dpp = dot3(dpx, dpx, dpy, dpy, dpz, dpz), mpdp = dot3(mpx, dpx, mpy, dpy, mpz, dpz);
  const __m256d tp =
      both(greaterThan(dpp, zero),
           smaller(larger(_mm256_div_pd(_mm256_xor_pd(mpdp, sign), larger(dpp, _mm256_set1_pd(1e-300))), zero), one));
  const __m256d vx = plus(mpx, times(tp, dpx)), vy = plus(mpy, times(tp, dpy)), vz = plus(mpz, times(tp, dpz));
  const __m256d vn = _mm256_sqrt_pd(dot3(vx, vx, vy, vy, vz, vz));
  const __m256d alongLow = larger(minus(_mm256_div_pd(vn, loose), times(radius, loose)), zero);
  const __m256d reachHigh = times(reach, loose);
  const __m256d farBoth =
      greaterThan(plus(times(acrossLow, acrossLow), times(alongLow, alongLow)), times(reachHigh, reachHigh));
  keep = butNot(keep, both(hasSlab, either(farAcross, farBoth)));
  // The hint's plane (Best::below on the slab): every point below lies farther than reach under every centre that
  // can still win. Its margins doubled for this order of the same operations.
  if (s.plane) {
    const __m256d hx = _mm256_set1_pd(s.n[0]), hy = _mm256_set1_pd(s.n[1]), hz = _mm256_set1_pd(s.n[2]);
    const __m256d along = dot3(hx, nx, hy, ny, hz, nz);
    const __m256d ax = minus(hx, times(along, nx)), ay = minus(hy, times(along, ny)), az = minus(hz, times(along, nz));
    const __m256d across2 = dot3(ax, ax, ay, ay, az, az);
    const __m256d absAlong = _mm256_andnot_pd(sign, along);
    const __m256d slanted =
        plus(times(absAlong, thick),
             _mm256_sqrt_pd(times(across2, larger(minus(times(radius, radius), times(thick, thick)), zero))));
    const __m256d rise = pick(slanted, radius, lessEqual(times(absAlong, radius), thick));
    const __m256d top = plus(
        plus(minus(dot3(hx, cx, hy, cy, hz, cz), _mm256_set1_pd(s.offset)), times(rise, _mm256_set1_pd(1.0 + 2e-9))),
        times(thick, _mm256_set1_pd(2e-9)));
    keep = butNot(keep, both(hasSlab, lessThan(top, _mm256_set1_pd(s.clearance))));
  }
  _mm256_storeu_pd(enter, t0);
  return bits(keep) & ((1u << count) - 1u);
}

__attribute__((target("avx2"))) unsigned nodeNearAvx2(const NodeLanes& lanes, unsigned count, const double p[3],
                                                      double d2, double near[4]) {
  using namespace avx2;
  const __m256d zero = _mm256_setzero_pd(), sign = _mm256_set1_pd(-0.0);
  // The box: per axis the larger of lo - p and p - hi, not below 0 (squaredDistanceToNode).
  __m256d box = zero, m[3];
  for (int k = 0; k < 3; ++k) {
    const __m256d q = _mm256_set1_pd(p[k]);
    const __m256d g =
        larger(larger(minus(_mm256_load_pd(lanes.lo[k]), q), minus(q, _mm256_load_pd(lanes.hi[k]))), zero);
    box = plus(box, times(g, g));
    m[k] = minus(q, _mm256_load_pd(lanes.centre[k]));
  }
  // The slab: across it beyond thick, along its plane beyond radius (slabSquaredDistance; a child without a slab has
  // a zero normal and infinite thick and radius: 0).
  const __m256d nx = _mm256_load_pd(lanes.normal[0]), ny = _mm256_load_pd(lanes.normal[1]),
                nz = _mm256_load_pd(lanes.normal[2]);
  const __m256d h = dot3(nx, m[0], ny, m[1], nz, m[2]);
  const __m256d across = larger(minus(_mm256_andnot_pd(sign, h), _mm256_load_pd(lanes.thick)), zero);
  const __m256d ax = minus(m[0], times(h, nx)), ay = minus(m[1], times(h, ny)), az = minus(m[2], times(h, nz));
  const __m256d along = larger(minus(_mm256_sqrt_pd(dot3(ax, ax, ay, ay, az, az)), _mm256_load_pd(lanes.radius)), zero);
  const __m256d slab = plus(times(across, across), times(along, along));
  const __m256d lower = times(larger(box, slab), _mm256_set1_pd(1.0 - 1e-9));
  _mm256_storeu_pd(near, lower);
  return bits(lessEqual(lower, _mm256_set1_pd(d2))) & ((1u << count) - 1u);
}

#endif

}  // namespace detail
}  // namespace clod_haptics
