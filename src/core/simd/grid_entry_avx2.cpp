#include "grid_entry_avx2.h"

#if defined(CLOD_PACKET_AVX2)

#include <immintrin.h>

#include "avx2_ops.h"

namespace clod_haptics {
namespace detail {

namespace {

using namespace avx2;

// quantiseDirection, lane by lane: clamp to [-1, 1], times 127, toward zero, then half away from zero.
__attribute__((target("avx2"))) inline __m128i quantise(__m256d u) {
  const __m256d v = times(smaller(larger(u, _mm256_set1_pd(-1.0)), _mm256_set1_pd(1.0)), _mm256_set1_pd(127.0));
  const __m256d whole = _mm256_round_pd(v, _MM_FROUND_TO_ZERO | _MM_FROUND_NO_EXC);
  const __m256d part = minus(v, whole);  // exact
  const __m256d one = _mm256_set1_pd(1.0);
  const __m256d up = _mm256_and_pd(greaterEqual(part, _mm256_set1_pd(0.5)), one);
  const __m256d down = _mm256_and_pd(lessEqual(part, _mm256_set1_pd(-0.5)), one);
  return _mm256_cvttpd_epi32(minus(plus(whole, up), down));
}

}  // namespace

__attribute__((target("avx2"))) unsigned columnCellsAvx2(double x, double y, double originZ, double h, std::int64_t z,
                                                         const TriangleBounds& bounds) {
  // The centres' z as Grid's centre(): origin + (z + 0.5) h, per lane.
  const double base = static_cast<double>(z);
  const __m256d zs = plus(
      _mm256_set1_pd(originZ),
      times(plus(_mm256_set_pd(base + 3.0, base + 2.0, base + 1.0, base), _mm256_set1_pd(0.5)), _mm256_set1_pd(h)));
  // |n . (p - a)| > limit drops the lane: (n.x (x - a.x) + n.y (y - a.y)) + n.z (z - a.z), as Vec3::dot.
  const Vec3& n = bounds.normal;
  const Vec3& a = bounds.corner;
  unsigned keep = 0xFu;
  if (bounds.planar) {
    const double xy = n.x() * (x - a.x()) + n.y() * (y - a.y());
    const __m256d s = plus(_mm256_set1_pd(xy), times(_mm256_set1_pd(n.z()), minus(zs, _mm256_set1_pd(a.z()))));
    keep &= ~bits(greaterThan(_mm256_andnot_pd(_mm256_set1_pd(-0.0), s), _mm256_set1_pd(bounds.limit)));
  }
  // (p - mid)^2 > ball2 drops it: ((x - m.x)^2 + (y - m.y)^2) + (z - m.z)^2, as Vec3::squaredNorm.
  const Vec3& m = bounds.mid;
  const double xy = (x - m.x()) * (x - m.x()) + (y - m.y()) * (y - m.y());
  const __m256d dz = minus(zs, _mm256_set1_pd(m.z()));
  keep &= ~bits(greaterThan(plus(_mm256_set1_pd(xy), times(dz, dz)), _mm256_set1_pd(bounds.ball2)));
  return keep;
}

__attribute__((target("avx2"))) unsigned gridEntriesAvx2(const Vec3* const centre[4], const ClosestPoints4& closest,
                                                         double unit, double scale, double tiny, GridEntries4& out) {
  // centre - closest and its norm, as Vec3: (x^2 + y^2) + z^2, then the square root.
  const __m256d tx = minus(_mm256_set_pd(centre[3]->x(), centre[2]->x(), centre[1]->x(), centre[0]->x()),
                           _mm256_loadu_pd(closest.q[0]));
  const __m256d ty = minus(_mm256_set_pd(centre[3]->y(), centre[2]->y(), centre[1]->y(), centre[0]->y()),
                           _mm256_loadu_pd(closest.q[1]));
  const __m256d tz = minus(_mm256_set_pd(centre[3]->z(), centre[2]->z(), centre[1]->z(), centre[0]->z()),
                           _mm256_loadu_pd(closest.q[2]));
  const __m256d d = _mm256_sqrt_pd(plus(plus(times(tx, tx), times(ty, ty)), times(tz, tz)));
  _mm256_storeu_pd(out.distance, d);
  unsigned lanes = bits(greaterThan(d, _mm256_set1_pd(tiny)));
  // roundDown(d): the nearest float, one step toward zero when it lies above d (d > tiny > 0: the float is positive).
  const __m128 nearest = _mm256_cvtpd_ps(d);
  const unsigned above = bits(greaterThan(_mm256_cvtps_pd(nearest), d));
  const __m128i step = _mm_set_epi32(-static_cast<int>((above >> 3) & 1u), -static_cast<int>((above >> 2) & 1u),
                                     -static_cast<int>((above >> 1) & 1u), -static_cast<int>(above & 1u));
  const __m256d rounded = _mm256_cvtps_pd(_mm_castsi128_ps(_mm_add_epi32(_mm_castps_si128(nearest), step)));
  // distanceCode: min(255, floor(rounded / unit)), then down while q > 0 and q unit > rounded (at most twice here).
  const __m256d u = _mm256_set1_pd(unit), zero = _mm256_setzero_pd(), one = _mm256_set1_pd(1.0);
  __m256d q = smaller(_mm256_floor_pd(_mm256_div_pd(rounded, u)), _mm256_set1_pd(255.0));
  for (int k = 0; k < 2; ++k)
    q = minus(q, _mm256_and_pd(both(greaterThan(q, zero), greaterThan(times(q, u), rounded)), one));
  lanes &= ~bits(both(greaterThan(q, zero), greaterThan(times(q, u), rounded)));
  // finerCode: (rounded - q unit) scale, clamped to [0, 255], toward zero.
  const __m256d within =
      smaller(larger(times(minus(rounded, times(q, u)), _mm256_set1_pd(scale)), zero), _mm256_set1_pd(255.0));
  alignas(16) std::int32_t code[4], finer[4], x[4], y[4], z[4];
  _mm_store_si128(reinterpret_cast<__m128i*>(code), _mm256_cvttpd_epi32(q));
  _mm_store_si128(reinterpret_cast<__m128i*>(finer), _mm256_cvttpd_epi32(within));
  _mm_store_si128(reinterpret_cast<__m128i*>(x), quantise(_mm256_div_pd(tx, d)));
  _mm_store_si128(reinterpret_cast<__m128i*>(y), quantise(_mm256_div_pd(ty, d)));
  _mm_store_si128(reinterpret_cast<__m128i*>(z), quantise(_mm256_div_pd(tz, d)));
  for (int k = 0; k < 4; ++k) {
    out.code[k] = static_cast<std::uint8_t>(code[k]);
    out.finer[k] = static_cast<std::uint8_t>(finer[k]);
    out.direction[k][0] = static_cast<std::int8_t>(x[k]);
    out.direction[k][1] = static_cast<std::int8_t>(y[k]);
    out.direction[k][2] = static_cast<std::int8_t>(z[k]);
  }
  return lanes;
}

}  // namespace detail
}  // namespace clod_haptics

#endif
