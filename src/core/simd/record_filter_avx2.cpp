#include "record_filter_avx2.h"

#if defined(CLOD_PACKET_AVX2)
#include <immintrin.h>

#include "avx2_ops.h"
#endif

namespace clod_haptics {
namespace detail {

#if defined(CLOD_PACKET_AVX2)

namespace {

// Rows r0..r3 (one per triangle) to columns: out[j] holds field j of the four.
__attribute__((target("avx2"))) inline void transpose(__m256d r0, __m256d r1, __m256d r2, __m256d r3, __m256d out[4]) {
  const __m256d t0 = _mm256_unpacklo_pd(r0, r1), t1 = _mm256_unpackhi_pd(r0, r1);
  const __m256d t2 = _mm256_unpacklo_pd(r2, r3), t3 = _mm256_unpackhi_pd(r2, r3);
  out[0] = _mm256_permute2f128_pd(t0, t2, 0x20);
  out[1] = _mm256_permute2f128_pd(t1, t3, 0x20);
  out[2] = _mm256_permute2f128_pd(t0, t2, 0x31);
  out[3] = _mm256_permute2f128_pd(t1, t3, 0x31);
}

}  // namespace

__attribute__((target("avx2"))) unsigned recordFilterAvx2(const double* const record[4], const RecordFilterSweep& s) {
  __m256d ball[4], plane[4];  // centre x, y, z, radius; normal x, y, z, thickness
  transpose(_mm256_loadu_pd(record[0]), _mm256_loadu_pd(record[1]), _mm256_loadu_pd(record[2]),
            _mm256_loadu_pd(record[3]), ball);
  transpose(_mm256_loadu_pd(record[0] + 4), _mm256_loadu_pd(record[1] + 4), _mm256_loadu_pd(record[2] + 4),
            _mm256_loadu_pd(record[3] + 4), plane);
  const __m256d mx = _mm256_sub_pd(_mm256_set1_pd(s.a[0]), ball[0]);
  const __m256d my = _mm256_sub_pd(_mm256_set1_pd(s.a[1]), ball[1]);
  const __m256d mz = _mm256_sub_pd(_mm256_set1_pd(s.a[2]), ball[2]);
  const __m256d dx = _mm256_set1_pd(s.d[0]), dy = _mm256_set1_pd(s.d[1]), dz = _mm256_set1_pd(s.d[2]);
  const __m256d sign = _mm256_set1_pd(-0.0), loose = _mm256_set1_pd(1.0 + 1e-9);
  // The ball: the sweep's nearest point to its centre farther than (radius + R) (1 + 1e-12), loosened.
  const __m256d md = avx2::dot3(mx, dx, my, dy, mz, dz);
  const __m256d t =
      _mm256_min_pd(_mm256_max_pd(_mm256_mul_pd(_mm256_xor_pd(md, sign), _mm256_set1_pd(s.invdd)), _mm256_setzero_pd()),
                    _mm256_set1_pd(s.end));
  const __m256d qx = _mm256_add_pd(mx, _mm256_mul_pd(t, dx)), qy = _mm256_add_pd(my, _mm256_mul_pd(t, dy)),
                qz = _mm256_add_pd(mz, _mm256_mul_pd(t, dz));
  const __m256d q2 = avx2::dot3(qx, qx, qy, qy, qz, qz);
  const __m256d reach =
      _mm256_mul_pd(_mm256_add_pd(ball[3], _mm256_set1_pd(s.R)), _mm256_set1_pd((1.0 + 1e-12) * (1.0 + 1e-9)));
  const __m256d farBall = _mm256_cmp_pd(q2, _mm256_mul_pd(reach, reach), _CMP_GT_OQ);
  // Across the plane: both ends on one side, farther than across (less the thickness), loosened.
  const __m256d s0 = avx2::dot3(plane[0], mx, plane[1], my, plane[2], mz);
  const __m256d sd = avx2::dot3(plane[0], dx, plane[1], dy, plane[2], dz);
  const __m256d s1 = _mm256_add_pd(s0, _mm256_mul_pd(_mm256_set1_pd(s.end), sd));
  const __m256d nearer = _mm256_min_pd(_mm256_andnot_pd(sign, s0), _mm256_andnot_pd(sign, s1));
  const __m256d gap = _mm256_sub_pd(nearer, _mm256_mul_pd(plane[3], loose));
  const __m256d oneSide = _mm256_cmp_pd(_mm256_mul_pd(s0, s1), _mm256_setzero_pd(), _CMP_GT_OQ);
  const __m256d acrossGap = _mm256_div_pd(gap, loose);
  const __m256d farAcross = _mm256_and_pd(oneSide, _mm256_cmp_pd(acrossGap, _mm256_set1_pd(s.across), _CMP_GT_OQ));
  // Across and along together (planeBoundMisses): the centre's motion projected on the plane passes no nearer to the
  // record's centre than along + rho, so the triangle is at least sqrt(across^2 + along^2) away; both lowered and the
  // reach raised by 1e-9 (the scalar bound's own rounding is far below), so this never drops what the scalar keeps.
  const __m256d acrossLow = _mm256_and_pd(oneSide, _mm256_max_pd(acrossGap, _mm256_setzero_pd()));
  const __m256d mpx = _mm256_sub_pd(mx, _mm256_mul_pd(s0, plane[0])),
                mpy = _mm256_sub_pd(my, _mm256_mul_pd(s0, plane[1])),
                mpz = _mm256_sub_pd(mz, _mm256_mul_pd(s0, plane[2]));
  const __m256d dpx = _mm256_sub_pd(dx, _mm256_mul_pd(sd, plane[0])),
                dpy = _mm256_sub_pd(dy, _mm256_mul_pd(sd, plane[1])),
                dpz = _mm256_sub_pd(dz, _mm256_mul_pd(sd, plane[2]));
  const __m256d dpp = avx2::dot3(dpx, dpx, dpy, dpy, dpz, dpz);
  const __m256d mpdp = avx2::dot3(mpx, dpx, mpy, dpy, mpz, dpz);
  const __m256d moving = _mm256_cmp_pd(dpp, _mm256_setzero_pd(), _CMP_GT_OQ);
  const __m256d tp = _mm256_and_pd(
      moving,
      _mm256_min_pd(_mm256_max_pd(_mm256_div_pd(_mm256_xor_pd(mpdp, sign), _mm256_max_pd(dpp, _mm256_set1_pd(1e-300))),
                                  _mm256_setzero_pd()),
                    _mm256_set1_pd(s.end)));
  const __m256d vx = _mm256_add_pd(mpx, _mm256_mul_pd(tp, dpx)), vy = _mm256_add_pd(mpy, _mm256_mul_pd(tp, dpy)),
                vz = _mm256_add_pd(mpz, _mm256_mul_pd(tp, dpz));
  const __m256d vn = _mm256_sqrt_pd(avx2::dot3(vx, vx, vy, vy, vz, vz));
  const __m256d alongLow =
      _mm256_max_pd(_mm256_sub_pd(_mm256_div_pd(vn, loose), _mm256_mul_pd(ball[3], loose)), _mm256_setzero_pd());
  const __m256d reachHigh = _mm256_mul_pd(_mm256_set1_pd(s.across), loose);
  const __m256d farBoth =
      _mm256_cmp_pd(_mm256_add_pd(_mm256_mul_pd(acrossLow, acrossLow), _mm256_mul_pd(alongLow, alongLow)),
                    _mm256_mul_pd(reachHigh, reachHigh), _CMP_GT_OQ);
  return ~static_cast<unsigned>(_mm256_movemask_pd(_mm256_or_pd(_mm256_or_pd(farBall, farAcross), farBoth))) & 0xFu;
}

#endif

}  // namespace detail
}  // namespace clod_haptics
