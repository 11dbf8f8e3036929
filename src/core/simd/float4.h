#pragma once
// Internal to the core (not API): four floats of which the hierarchy's build uses three (a box corner),
// in an SSE register where the compiler targets SSE2 and in plain C++ otherwise, the same values either way.

#if defined(__SSE2__)
#include <emmintrin.h>
#else
#include <cstring>
#endif

namespace clod_haptics {
namespace detail {

#if defined(__SSE2__)
using F4 = __m128;
/** \brief The three floats at p (16-byte aligned), whose fourth float is 0. */
inline F4 loadPadded4(const float* p) { return _mm_load_ps(p); }
/** \brief The three floats at p (16-byte aligned), the fourth float's bits cleared. */
inline F4 loadMasked4(const float* p) {
  return _mm_and_ps(_mm_load_ps(p), _mm_castsi128_ps(_mm_set_epi32(0, -1, -1, -1)));
}
inline F4 splat4(float f) { return _mm_set1_ps(f); }
inline F4 min4(F4 a, F4 b) { return _mm_min_ps(a, b); }
inline F4 max4(F4 a, F4 b) { return _mm_max_ps(a, b); }
/** \brief 0.5 lo + 0.5 hi, a box centre. */
inline F4 centre4(F4 lo, F4 hi) {
  return _mm_add_ps(_mm_mul_ps(_mm_set1_ps(0.5f), lo), _mm_mul_ps(_mm_set1_ps(0.5f), hi));
}
inline void store4(float* out, F4 a) { _mm_storeu_ps(out, a); }
#else
struct F4 {
  float v[4];
};
inline F4 loadPadded4(const float* p) { return {{p[0], p[1], p[2], 0.0f}}; }
inline F4 loadMasked4(const float* p) { return loadPadded4(p); }
inline F4 splat4(float f) { return {{f, f, f, f}}; }
inline F4 min4(F4 a, F4 b) {
  return {
      {a.v[0] < b.v[0] ? a.v[0] : b.v[0], a.v[1] < b.v[1] ? a.v[1] : b.v[1], a.v[2] < b.v[2] ? a.v[2] : b.v[2], 0.0f}};
}
inline F4 max4(F4 a, F4 b) {
  return {
      {a.v[0] > b.v[0] ? a.v[0] : b.v[0], a.v[1] > b.v[1] ? a.v[1] : b.v[1], a.v[2] > b.v[2] ? a.v[2] : b.v[2], 0.0f}};
}
inline F4 centre4(F4 lo, F4 hi) {
  F4 c;
  for (int k = 0; k < 4; ++k) c.v[k] = 0.5f * lo.v[k] + 0.5f * hi.v[k];
  return c;
}
inline void store4(float* out, F4 a) { std::memcpy(out, a.v, sizeof a.v); }
#endif

}  // namespace detail
}  // namespace clod_haptics
