#include "cell_scan_avx2.h"

#include <cstring>

#if defined(CLOD_PACKET_AVX2)
#include <immintrin.h>
#endif

namespace clod_haptics {
namespace detail {

CellScanBounds cellScanBounds(const Vec3& r0, const Vec3& r1, double off0, double off1, double unit, double limit,
                              double reach) {
  CellScanBounds b;
  for (int k = 0; k < 3; ++k) {
    b.r0[k] = static_cast<float>(r0[k] * (1.0 / 127.0));
    b.r1[k] = static_cast<float>(r1[k] * (1.0 / 127.0));
  }
  b.off0 = static_cast<float>(off0);
  b.off1 = static_cast<float>(off1);
  b.unit = static_cast<float>(unit);
  // Every term is at most reach (the ends' distance from the centre with their slack, or the largest stored
  // distance) in size; float rounds each of the dozen operations by 6e-8 of that at most.
  b.limit = static_cast<float>(limit + 1e-5 * (reach + limit + 255.0 * unit));
  return b;
}

#if defined(CLOD_PACKET_AVX2)

namespace {

// r . u + off for the eight entries (r: the piece's end over 127).
__attribute__((target("avx2"))) inline __m256 along(__m256 ux, __m256 uy, __m256 uz, const float* r, float off) {
  const __m256 x = _mm256_add_ps(_mm256_mul_ps(ux, _mm256_set1_ps(r[0])), _mm256_set1_ps(off));
  return _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(uy, _mm256_set1_ps(r[1])), _mm256_mul_ps(uz, _mm256_set1_ps(r[2]))),
                       x);
}

}  // namespace

__attribute__((target("avx2"))) unsigned cellScanBlockAvx2(const CellGrid::Entry* e, const CellScanBounds& b) {
  static_assert(sizeof(CellGrid::Entry) == 8, "eight-byte entries: a triangle, then distance and direction bytes");
  // The high half of each entry (distance, then the three direction bytes), entries 0..7 in order.
  const __m256 lo = _mm256_loadu_ps(reinterpret_cast<const float*>(e));
  const __m256 hi = _mm256_loadu_ps(reinterpret_cast<const float*>(e + 4));
  const __m256 odd = _mm256_shuffle_ps(lo, hi, 0xDD);  // e0 e1 e4 e5 | e2 e3 e6 e7
  const __m256i h = _mm256_castpd_si256(_mm256_permute4x64_pd(_mm256_castps_pd(odd), 0xD8));
  const __m256 dc =
      _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_and_si256(h, _mm256_set1_epi32(0xFF))), _mm256_set1_ps(b.unit));
  const __m256 ux = _mm256_cvtepi32_ps(_mm256_srai_epi32(_mm256_slli_epi32(h, 16), 24));
  const __m256 uy = _mm256_cvtepi32_ps(_mm256_srai_epi32(_mm256_slli_epi32(h, 8), 24));
  const __m256 uz = _mm256_cvtepi32_ps(_mm256_srai_epi32(h, 24));
  const __m256 bound =
      _mm256_add_ps(_mm256_min_ps(along(ux, uy, uz, b.r0, b.off0), along(ux, uy, uz, b.r1, b.off1)), dc);
  return static_cast<unsigned>(_mm256_movemask_ps(_mm256_cmp_ps(bound, _mm256_set1_ps(b.limit), _CMP_LE_OQ)));
}

#endif

}  // namespace detail
}  // namespace clod_haptics
