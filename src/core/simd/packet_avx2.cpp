#include "packet_avx2.h"

#if defined(CLOD_PACKET_AVX2)

#include <immintrin.h>

#include <limits>

#include "avx2_ops.h"

namespace clod_haptics {
namespace detail {

namespace {
using namespace avx2;
constexpr int W = PacketCull::kRays;
static_assert(W == 16, "four registers of four doubles, or two of eight floats");

#define CLOD_AVX2 __attribute__((target("avx2"))) inline

// The lanes that meet the box (entry t0 <= exit t1) and pass PacketCull::keeps (lower: the normals' lower
// bound less the slack), four doubles or eight floats at a time: the rule once for both precisions.
template <class V>
CLOD_AVX2 unsigned keptBits(V lower, V t0, V t1, V cap, V below, V nearBelow, V within) {
  const V near = both(lessThan(lower, nearBelow), lessEqual(t0, within));
  return bits(both(lessEqual(t0, t1), both(lessThan(lower, cap), either(lessThan(lower, below), near))));
}

// One axis of forEachRayHit's box test: the distances (lo - o) inv and (hi - o) inv to the box's planes,
// the smaller one the near one (there is no NaN), narrow [t0, t1] to the slab between them.
template <class V>
CLOD_AVX2 void slab(V lo, V hi, V o, V inv, V& t0, V& t1) {
  const V a = times(minus(lo, o), inv), b = times(minus(hi, o), inv);
  t0 = larger(smaller(a, b), t0);
  t1 = smaller(larger(a, b), t1);
}

// One axis's term of TriangleBvh::minDot's sum, std::min(m nlo, m nhi) (which is smaller(m nhi, m nlo)).
template <class V>
CLOD_AVX2 V minDotTerm(V m, V nlo, V nhi) {
  return smaller(times(m, nhi), times(m, nlo));
}

// The four rays from h of the double test on node: the box test; the normals' lower bound as
// TriangleBvh::minDot's sum, in its order, less the slack; then PacketCull::keeps. Stores the entries at
// entry + h.
CLOD_AVX2 unsigned childLanes(const TriangleBvh::Node& node, const double* o, const double* inv, const PacketCull& cull,
                              int h, double* entry) {
  __m256d t0 = _mm256_setzero_pd(), t1 = _mm256_set1_pd(std::numeric_limits<double>::infinity());
  __m256d lower = _mm256_setzero_pd();
  for (int k = 0; k < 3; ++k) {
    slab(_mm256_set1_pd(node.lo[k]), _mm256_set1_pd(node.hi[k]), _mm256_loadu_pd(o + k * W + h),
         _mm256_loadu_pd(inv + k * W + h), t0, t1);
    lower = plus(lower, minDotTerm(_mm256_load_pd(cull.axis[k] + h), _mm256_set1_pd(node.normalLo[k]),
                                   _mm256_set1_pd(node.normalHi[k])));
  }
  lower = minus(lower, _mm256_set1_pd(PacketCull::kSlack));
  _mm256_storeu_pd(entry + h, t0);
  return keptBits(lower, t0, t1, _mm256_load_pd(cull.cap + h), _mm256_load_pd(cull.below + h),
                  _mm256_load_pd(cull.nearBelow + h), _mm256_load_pd(cull.within + h));
}

// The eight rays from h of the float test on node, its box widened to wlo, whi.
CLOD_AVX2 unsigned childLanesFloat(const TriangleBvh::Node& node, const float* wlo, const float* whi,
                                   const PacketFloat& f, int h, double* entry) {
  __m256 t0 = _mm256_setzero_ps(), t1 = _mm256_set1_ps(std::numeric_limits<float>::infinity());
  __m256 lower = _mm256_setzero_ps();
  for (int k = 0; k < 3; ++k) {
    slab(_mm256_set1_ps(wlo[k]), _mm256_set1_ps(whi[k]), _mm256_load_ps(f.o[k] + h), _mm256_load_ps(f.inv[k] + h), t0,
         t1);
    lower = plus(lower, minDotTerm(_mm256_load_ps(f.axis[k] + h), _mm256_set1_ps(node.normalLo[k]),
                                   _mm256_set1_ps(node.normalHi[k])));
  }
  lower = minus(lower, _mm256_load_ps(f.slack + h));
  _mm256_storeu_pd(entry + h, _mm256_cvtps_pd(_mm256_castps256_ps128(t0)));
  _mm256_storeu_pd(entry + h + 4, _mm256_cvtps_pd(_mm256_extractf128_ps(t0, 1)));
  return keptBits(lower, t0, t1, _mm256_load_ps(f.cap + h), _mm256_load_ps(f.below + h),
                  _mm256_load_ps(f.nearBelow + h), _mm256_load_ps(f.within + h));
}

#undef CLOD_AVX2
}  // namespace

__attribute__((target("avx2"))) void packetChildrenAvx2(const TriangleBvh::Node* const child[2], const double* o,
                                                        const double* inv, const PacketCull& cull, unsigned active,
                                                        double* const entry[2], unsigned mask[2]) {
  for (int c = 0; c < 2; ++c) {
    unsigned m = 0;
    for (int h = 0; h < W; h += 4)  // the active rays of a packet are mostly neighbours
      if ((active >> h) & 0xFu) m |= childLanes(*child[c], o, inv, cull, h, entry[c]) << h;
    mask[c] = m & active;
  }
}

__attribute__((target("avx2"))) void packetChildrenAvx2f(const TriangleBvh::Node* const child[2], const PacketFloat& f,
                                                         unsigned active, double* const entry[2], unsigned mask[2]) {
  for (int c = 0; c < 2; ++c) {
    float wlo[3], whi[3];
    for (int k = 0; k < 3; ++k) {
      wlo[k] = child[c]->lo[k] - f.widen;
      whi[k] = child[c]->hi[k] + f.widen;
    }
    unsigned m = 0;
    for (int h = 0; h < W; h += 8)
      if ((active >> h) & 0xFFu) m |= childLanesFloat(*child[c], wlo, whi, f, h, entry[c]) << h;
    mask[c] = m & active;
  }
}

__attribute__((target("avx2"))) unsigned packetTriangleAvx2(const double* a, const double* b, const double* c,
                                                            const double* o, const double* d, unsigned active,
                                                            double* t) {
  // rayTriangle's steps (Eigen's cross products by component, its dot products as (x + y) + z, no fused
  // multiply-add), every lane computed and the early returns turned into masks.
  double e1[3], e2[3];
  for (int k = 0; k < 3; ++k) {
    e1[k] = b[k] - a[k];
    e2[k] = c[k] - a[k];
  }
  const __m256d e1x = _mm256_set1_pd(e1[0]), e1y = _mm256_set1_pd(e1[1]), e1z = _mm256_set1_pd(e1[2]);
  const __m256d e2x = _mm256_set1_pd(e2[0]), e2y = _mm256_set1_pd(e2[1]), e2z = _mm256_set1_pd(e2[2]);
  const __m256d zero = _mm256_setzero_pd(), one = _mm256_set1_pd(1.0);
  const __m256d inf = _mm256_set1_pd(std::numeric_limits<double>::infinity());
  const __m256d sign = _mm256_set1_pd(-0.0);
  unsigned m = 0;
  for (int h = 0; h < W; h += 4) {
    if (!((active >> h) & 0xFu)) continue;
    const __m256d dx = _mm256_loadu_pd(d + h), dy = _mm256_loadu_pd(d + W + h), dz = _mm256_loadu_pd(d + 2 * W + h);
    const __m256d pvx = _mm256_sub_pd(_mm256_mul_pd(dy, e2z), _mm256_mul_pd(dz, e2y));
    const __m256d pvy = _mm256_sub_pd(_mm256_mul_pd(dz, e2x), _mm256_mul_pd(dx, e2z));
    const __m256d pvz = _mm256_sub_pd(_mm256_mul_pd(dx, e2y), _mm256_mul_pd(dy, e2x));
    const __m256d det = dot3(e1x, pvx, e1y, pvy, e1z, pvz);
    // det != 0 and finite
    __m256d ok = _mm256_and_pd(_mm256_cmp_pd(det, zero, _CMP_NEQ_OQ),
                               _mm256_cmp_pd(_mm256_andnot_pd(sign, det), inf, _CMP_LT_OQ));
    const __m256d inv = _mm256_div_pd(one, det);
    const __m256d tvx = _mm256_sub_pd(_mm256_loadu_pd(o + h), _mm256_set1_pd(a[0]));
    const __m256d tvy = _mm256_sub_pd(_mm256_loadu_pd(o + W + h), _mm256_set1_pd(a[1]));
    const __m256d tvz = _mm256_sub_pd(_mm256_loadu_pd(o + 2 * W + h), _mm256_set1_pd(a[2]));
    const __m256d u = _mm256_mul_pd(dot3(tvx, pvx, tvy, pvy, tvz, pvz), inv);
    // not (u < 0 or u > 1): a NaN passes, as in rayTriangle
    ok = _mm256_and_pd(ok, _mm256_and_pd(_mm256_cmp_pd(u, zero, _CMP_NLT_UQ), _mm256_cmp_pd(u, one, _CMP_NGT_UQ)));
    const __m256d qvx = _mm256_sub_pd(_mm256_mul_pd(tvy, e1z), _mm256_mul_pd(tvz, e1y));
    const __m256d qvy = _mm256_sub_pd(_mm256_mul_pd(tvz, e1x), _mm256_mul_pd(tvx, e1z));
    const __m256d qvz = _mm256_sub_pd(_mm256_mul_pd(tvx, e1y), _mm256_mul_pd(tvy, e1x));
    const __m256d v = _mm256_mul_pd(dot3(dx, qvx, dy, qvy, dz, qvz), inv);
    ok = _mm256_and_pd(
        ok, _mm256_and_pd(_mm256_cmp_pd(v, zero, _CMP_NLT_UQ), _mm256_cmp_pd(_mm256_add_pd(u, v), one, _CMP_NGT_UQ)));
    const __m256d tt = _mm256_mul_pd(dot3(e2x, qvx, e2y, qvy, e2z, qvz), inv);
    ok = _mm256_and_pd(ok, _mm256_cmp_pd(tt, zero, _CMP_GT_OQ));
    _mm256_store_pd(t + h, tt);
    m |= static_cast<unsigned>(_mm256_movemask_pd(ok)) << h;
  }
  return m & active;
}

}  // namespace detail
}  // namespace clod_haptics

#endif
