#include "closest_point_avx2.h"

#if defined(CLOD_PACKET_AVX2)

#include <immintrin.h>

#include "avx2_ops.h"

namespace clod_haptics {
namespace detail {

namespace {

using namespace avx2;

#define CLOD_AVX2 __attribute__((target("avx2"))) inline

/** Three coordinates of four points, one register each. */
struct V3 {
  __m256d x, y, z;
};
CLOD_AVX2 V3 load(const Vec3* const v[4]) {
  return {_mm256_set_pd(v[3]->x(), v[2]->x(), v[1]->x(), v[0]->x()),
          _mm256_set_pd(v[3]->y(), v[2]->y(), v[1]->y(), v[0]->y()),
          _mm256_set_pd(v[3]->z(), v[2]->z(), v[1]->z(), v[0]->z())};
}
CLOD_AVX2 V3 difference(const V3& u, const V3& v) { return {minus(u.x, v.x), minus(u.y, v.y), minus(u.z, v.z)}; }
CLOD_AVX2 __m256d dot(const V3& u, const V3& v) { return dot3(u.x, v.x, u.y, v.y, u.z, v.z); }
// mask ? v : u, lane by lane.
CLOD_AVX2 V3 choose(const V3& u, const V3& v, __m256d mask) {
  return {pick(u.x, v.x, mask), pick(u.y, v.y, mask), pick(u.z, v.z, mask)};
}

constexpr int kVertexA = ClosestPoints4::kVertexA, kVertexB = ClosestPoints4::kVertexB,
              kEdgeAB = ClosestPoints4::kEdgeAB, kVertexC = ClosestPoints4::kVertexC, kEdgeAC = ClosestPoints4::kEdgeAC,
              kEdgeBC = ClosestPoints4::kEdgeBC;

// The four lanes' closest points (any of P, A, B and C may hold one value in every lane), in out; the lanes computed.
CLOD_AVX2 unsigned closestPoints(const V3& P, const V3& A, const V3& B, const V3& C, ClosestPoints4& out) {
  const __m256d zero = _mm256_setzero_pd();
  const V3 ab = difference(B, A), ac = difference(C, A), ap = difference(P, A), bp = difference(P, B),
           cp = difference(P, C);
  const __m256d d1 = dot(ab, ap), d2 = dot(ac, ap), d3 = dot(ab, bp), d4 = dot(ac, bp), d5 = dot(ab, cp),
                d6 = dot(ac, cp);
  const __m256d vc = minus(times(d1, d4), times(d3, d2));
  const __m256d vb = minus(times(d5, d2), times(d1, d6));
  const __m256d va = minus(times(d3, d6), times(d5, d4));
  const __m256d d43 = minus(d4, d3), d56 = minus(d5, d6);
  // The scalar function's regions in its order: each lane takes the first whose test it passes.
  const __m256d tests[6] = {
      both(lessEqual(d1, zero), lessEqual(d2, zero)),                                     // vertex a
      both(greaterEqual(d3, zero), lessEqual(d4, d3)),                                    // vertex b
      both(both(lessEqual(vc, zero), greaterEqual(d1, zero)), lessEqual(d3, zero)),       // edge ab
      both(greaterEqual(d6, zero), lessEqual(d5, d6)),                                    // vertex c
      both(both(lessEqual(vb, zero), greaterEqual(d2, zero)), lessEqual(d6, zero)),       // edge ac
      both(both(lessEqual(va, zero), greaterEqual(d43, zero)), greaterEqual(d56, zero)),  // edge bc
  };
  __m256d taken = zero, in[6];
  for (int k = 0; k < 6; ++k) {
    in[k] = butNot(tests[k], taken);
    taken = either(taken, in[k]);
  }
  const __m256d face = butNot(_mm256_castsi256_pd(_mm256_set1_epi64x(-1)), taken);
  // One division for every lane: an edge's parameter num / den, the face's 1 / sum.
  const __m256d sum = plus(plus(va, vb), vc);
  const __m256d denAB = minus(d1, d3), denAC = minus(d2, d6), denBC = plus(d43, d56);
  __m256d num = pick(pick(_mm256_set1_pd(1.0), d43, in[kEdgeBC]), d2, in[kEdgeAC]);
  num = pick(num, d1, in[kEdgeAB]);
  __m256d den = pick(pick(sum, denBC, in[kEdgeBC]), denAC, in[kEdgeAC]);
  den = pick(den, denAB, in[kEdgeAB]);
  // The fallback to the edges (closestOnEdges): an edge whose denominator is not positive, a face whose sum is
  // not above 1e-14 |ab|^2 |ac|^2 or not finite (sum - sum is 0 only for a finite sum).
  const __m256d edge = either(either(in[kEdgeAB], in[kEdgeAC]), in[kEdgeBC]);
  const __m256d scale = times(dot(ab, ab), dot(ac, ac));
  const __m256d faceOk =
      both(greaterThan(sum, times(_mm256_set1_pd(1e-14), scale)), _mm256_cmp_pd(minus(sum, sum), zero, _CMP_EQ_OQ));
  const __m256d fallback = either(butNot(edge, greaterThan(den, zero)), butNot(face, faceOk));
  const __m256d ratio = _mm256_div_pd(num, pick(_mm256_set1_pd(1.0), den, either(edge, face)));
  // Edges: base + t dir (a + t ab, a + t ac, b + t (c - b)).
  const V3 base = choose(A, B, in[kEdgeBC]);
  const V3 dir = choose(choose(difference(C, B), ac, in[kEdgeAC]), ab, in[kEdgeAB]);
  const V3 onEdge{plus(base.x, times(ratio, dir.x)), plus(base.y, times(ratio, dir.y)),
                  plus(base.z, times(ratio, dir.z))};
  // Face: a + ab (vb / sum) + ac (vc / sum), as (a + ab s) + ac t.
  const __m256d s = times(vb, ratio), t = times(vc, ratio);
  const V3 onFace{plus(plus(A.x, times(ab.x, s)), times(ac.x, t)), plus(plus(A.y, times(ab.y, s)), times(ac.y, t)),
                  plus(plus(A.z, times(ab.z, s)), times(ac.z, t))};
  V3 q = choose(onFace, onEdge, edge);
  q = choose(q, A, in[kVertexA]);
  q = choose(q, B, in[kVertexB]);
  q = choose(q, C, in[kVertexC]);
  const V3 w = difference(P, q);
  _mm256_storeu_pd(out.q[0], q.x);
  _mm256_storeu_pd(out.q[1], q.y);
  _mm256_storeu_pd(out.q[2], q.z);
  _mm256_storeu_pd(out.d2, dot(w, w));
  _mm256_storeu_pd(out.param, ratio);
  __m256d kind = _mm256_set1_pd(ClosestPoints4::kFace);
  for (int k = 5; k >= 0; --k) kind = pick(kind, _mm256_set1_pd(k), in[k]);
  _mm256_storeu_pd(out.kind, kind);
  return 0xfu & ~static_cast<unsigned>(_mm256_movemask_pd(fallback));
}
CLOD_AVX2 V3 broadcast(const Vec3& v) { return {_mm256_set1_pd(v.x()), _mm256_set1_pd(v.y()), _mm256_set1_pd(v.z())}; }

#undef CLOD_AVX2
}  // namespace

__attribute__((target("avx2"))) unsigned closestPointsAvx2(const Vec3& p, const Vec3* const a[4],
                                                           const Vec3* const b[4], const Vec3* const c[4],
                                                           ClosestPoints4& out) {
  return closestPoints(broadcast(p), load(a), load(b), load(c), out);
}

__attribute__((target("avx2"))) unsigned closestPointsAvx2(const Vec3* const p[4], const Vec3& a, const Vec3& b,
                                                           const Vec3& c, ClosestPoints4& out) {
  return closestPoints(load(p), broadcast(a), broadcast(b), broadcast(c), out);
}

}  // namespace detail
}  // namespace clod_haptics

#endif
