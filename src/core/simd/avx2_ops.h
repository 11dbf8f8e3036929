#pragma once
// Internal to the core (not API): the one-line AVX2 operations the kernels share, on four doubles or eight floats
// a register, each carrying the target attribute (so the rest of the core still runs on any x86-64). Include only
// from a kernel's .cpp, under CLOD_PACKET_AVX2, and call only where packetAvx2() (dispatch.h) is true.

#include <immintrin.h>

namespace clod_haptics {
namespace detail {
namespace avx2 {

#define CLOD_AVX2_OP __attribute__((target("avx2"))) inline

// Comparisons (ordered: false for NaN, as the scalar comparisons) and their masks.
CLOD_AVX2_OP __m256d lessThan(__m256d a, __m256d b) { return _mm256_cmp_pd(a, b, _CMP_LT_OQ); }
CLOD_AVX2_OP __m256 lessThan(__m256 a, __m256 b) { return _mm256_cmp_ps(a, b, _CMP_LT_OQ); }
CLOD_AVX2_OP __m256d lessEqual(__m256d a, __m256d b) { return _mm256_cmp_pd(a, b, _CMP_LE_OQ); }
CLOD_AVX2_OP __m256 lessEqual(__m256 a, __m256 b) { return _mm256_cmp_ps(a, b, _CMP_LE_OQ); }
CLOD_AVX2_OP __m256d greaterThan(__m256d a, __m256d b) { return _mm256_cmp_pd(a, b, _CMP_GT_OQ); }
CLOD_AVX2_OP __m256d greaterEqual(__m256d a, __m256d b) { return _mm256_cmp_pd(a, b, _CMP_GE_OQ); }
CLOD_AVX2_OP __m256d both(__m256d a, __m256d b) { return _mm256_and_pd(a, b); }
CLOD_AVX2_OP __m256 both(__m256 a, __m256 b) { return _mm256_and_ps(a, b); }
CLOD_AVX2_OP __m256d either(__m256d a, __m256d b) { return _mm256_or_pd(a, b); }
CLOD_AVX2_OP __m256 either(__m256 a, __m256 b) { return _mm256_or_ps(a, b); }
CLOD_AVX2_OP __m256d butNot(__m256d a, __m256d notThis) { return _mm256_andnot_pd(notThis, a); }
// mask ? b : a, lane by lane.
CLOD_AVX2_OP __m256d pick(__m256d a, __m256d b, __m256d mask) { return _mm256_blendv_pd(a, b, mask); }
CLOD_AVX2_OP unsigned bits(__m256d a) { return static_cast<unsigned>(_mm256_movemask_pd(a)); }
CLOD_AVX2_OP unsigned bits(__m256 a) { return static_cast<unsigned>(_mm256_movemask_ps(a)); }

// Lane-wise arithmetic.
CLOD_AVX2_OP __m256d plus(__m256d a, __m256d b) { return _mm256_add_pd(a, b); }
CLOD_AVX2_OP __m256 plus(__m256 a, __m256 b) { return _mm256_add_ps(a, b); }
CLOD_AVX2_OP __m256d minus(__m256d a, __m256d b) { return _mm256_sub_pd(a, b); }
CLOD_AVX2_OP __m256 minus(__m256 a, __m256 b) { return _mm256_sub_ps(a, b); }
CLOD_AVX2_OP __m256d times(__m256d a, __m256d b) { return _mm256_mul_pd(a, b); }
CLOD_AVX2_OP __m256 times(__m256 a, __m256 b) { return _mm256_mul_ps(a, b); }
CLOD_AVX2_OP __m256d smaller(__m256d a, __m256d b) { return _mm256_min_pd(a, b); }
CLOD_AVX2_OP __m256 smaller(__m256 a, __m256 b) { return _mm256_min_ps(a, b); }
CLOD_AVX2_OP __m256d larger(__m256d a, __m256d b) { return _mm256_max_pd(a, b); }
CLOD_AVX2_OP __m256 larger(__m256 a, __m256 b) { return _mm256_max_ps(a, b); }

// (x0 y0 + x1 y1) + x2 y2, Eigen's order for a 3-vector dot product (no fused multiply-add).
CLOD_AVX2_OP __m256d dot3(__m256d x0, __m256d y0, __m256d x1, __m256d y1, __m256d x2, __m256d y2) {
  return _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(x0, y0), _mm256_mul_pd(x1, y1)), _mm256_mul_pd(x2, y2));
}

#undef CLOD_AVX2_OP

}  // namespace avx2
}  // namespace detail
}  // namespace clod_haptics
