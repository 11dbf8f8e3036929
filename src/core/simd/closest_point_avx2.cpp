#include "closest_point_avx2.h"

#if defined(CLOD_PACKET_AVX2)

#include <immintrin.h>

namespace clod_haptics {
namespace detail {

namespace {

#define CLOD_AVX2 __attribute__((target("avx2"))) inline

CLOD_AVX2 __m256d add(__m256d x, __m256d y) { return _mm256_add_pd(x, y); }
CLOD_AVX2 __m256d sub(__m256d x, __m256d y) { return _mm256_sub_pd(x, y); }
CLOD_AVX2 __m256d mul(__m256d x, __m256d y) { return _mm256_mul_pd(x, y); }
CLOD_AVX2 __m256d le(__m256d x, __m256d y) { return _mm256_cmp_pd(x, y, _CMP_LE_OQ); }
CLOD_AVX2 __m256d ge(__m256d x, __m256d y) { return _mm256_cmp_pd(x, y, _CMP_GE_OQ); }
CLOD_AVX2 __m256d gt(__m256d x, __m256d y) { return _mm256_cmp_pd(x, y, _CMP_GT_OQ); }
CLOD_AVX2 __m256d both(__m256d x, __m256d y) { return _mm256_and_pd(x, y); }
CLOD_AVX2 __m256d either(__m256d x, __m256d y) { return _mm256_or_pd(x, y); }
CLOD_AVX2 __m256d butNot(__m256d x, __m256d notThis) { return _mm256_andnot_pd(notThis, x); }
// mask ? y : x
CLOD_AVX2 __m256d pick(__m256d x, __m256d y, __m256d mask) { return _mm256_blendv_pd(x, y, mask); }

/** Three coordinates of four points, one register each. */
struct V3 {
  __m256d x, y, z;
};
CLOD_AVX2 V3 load(const Vec3* const v[4]) {
  return {_mm256_set_pd(v[3]->x(), v[2]->x(), v[1]->x(), v[0]->x()),
          _mm256_set_pd(v[3]->y(), v[2]->y(), v[1]->y(), v[0]->y()),
          _mm256_set_pd(v[3]->z(), v[2]->z(), v[1]->z(), v[0]->z())};
}
CLOD_AVX2 V3 sub(const V3& u, const V3& v) { return {sub(u.x, v.x), sub(u.y, v.y), sub(u.z, v.z)}; }
// (x0 y0 + x1 y1) + x2 y2: Eigen's order for a 3-vector dot product.
CLOD_AVX2 __m256d dot(const V3& u, const V3& v) { return add(add(mul(u.x, v.x), mul(u.y, v.y)), mul(u.z, v.z)); }
CLOD_AVX2 V3 pick(const V3& u, const V3& v, __m256d mask) {
  return {pick(u.x, v.x, mask), pick(u.y, v.y, mask), pick(u.z, v.z, mask)};
}

constexpr int kVertexA = ClosestPoints4::kVertexA, kVertexB = ClosestPoints4::kVertexB,
              kEdgeAB = ClosestPoints4::kEdgeAB, kVertexC = ClosestPoints4::kVertexC, kEdgeAC = ClosestPoints4::kEdgeAC,
              kEdgeBC = ClosestPoints4::kEdgeBC;

}  // namespace

__attribute__((target("avx2"))) unsigned closestPointsAvx2(const Vec3& p, const Vec3* const a[4],
                                                           const Vec3* const b[4], const Vec3* const c[4],
                                                           ClosestPoints4& out) {
  const V3 A = load(a), B = load(b), C = load(c);
  const V3 P{_mm256_set1_pd(p.x()), _mm256_set1_pd(p.y()), _mm256_set1_pd(p.z())};
  const __m256d zero = _mm256_setzero_pd();
  const V3 ab = sub(B, A), ac = sub(C, A), ap = sub(P, A), bp = sub(P, B), cp = sub(P, C);
  const __m256d d1 = dot(ab, ap), d2 = dot(ac, ap), d3 = dot(ab, bp), d4 = dot(ac, bp), d5 = dot(ab, cp),
                d6 = dot(ac, cp);
  const __m256d vc = sub(mul(d1, d4), mul(d3, d2));
  const __m256d vb = sub(mul(d5, d2), mul(d1, d6));
  const __m256d va = sub(mul(d3, d6), mul(d5, d4));
  const __m256d d43 = sub(d4, d3), d56 = sub(d5, d6);
  // The scalar function's regions in its order: each lane takes the first whose test it passes.
  const __m256d tests[6] = {
      both(le(d1, zero), le(d2, zero)),                        // vertex a
      both(ge(d3, zero), le(d4, d3)),                          // vertex b
      both(both(le(vc, zero), ge(d1, zero)), le(d3, zero)),    // edge ab
      both(ge(d6, zero), le(d5, d6)),                          // vertex c
      both(both(le(vb, zero), ge(d2, zero)), le(d6, zero)),    // edge ac
      both(both(le(va, zero), ge(d43, zero)), ge(d56, zero)),  // edge bc
  };
  __m256d taken = zero, in[6];
  for (int k = 0; k < 6; ++k) {
    in[k] = butNot(tests[k], taken);
    taken = either(taken, in[k]);
  }
  const __m256d face = butNot(_mm256_castsi256_pd(_mm256_set1_epi64x(-1)), taken);
  // One division for every lane: an edge's parameter num / den, the face's 1 / sum.
  const __m256d sum = add(add(va, vb), vc);
  const __m256d denAB = sub(d1, d3), denAC = sub(d2, d6), denBC = add(d43, d56);
  __m256d num = pick(pick(_mm256_set1_pd(1.0), d43, in[kEdgeBC]), d2, in[kEdgeAC]);
  num = pick(num, d1, in[kEdgeAB]);
  __m256d den = pick(pick(sum, denBC, in[kEdgeBC]), denAC, in[kEdgeAC]);
  den = pick(den, denAB, in[kEdgeAB]);
  // The fallback to the edges (closestOnEdges): an edge whose denominator is not positive, a face whose sum is
  // not above 1e-14 |ab|^2 |ac|^2 or not finite (sum - sum is 0 only for a finite sum).
  const __m256d edge = either(either(in[kEdgeAB], in[kEdgeAC]), in[kEdgeBC]);
  const __m256d scale = mul(dot(ab, ab), dot(ac, ac));
  const __m256d faceOk =
      both(gt(sum, mul(_mm256_set1_pd(1e-14), scale)), _mm256_cmp_pd(sub(sum, sum), zero, _CMP_EQ_OQ));
  const __m256d fallback = either(butNot(edge, gt(den, zero)), butNot(face, faceOk));
  const __m256d ratio = _mm256_div_pd(num, pick(_mm256_set1_pd(1.0), den, either(edge, face)));
  // Edges: base + t dir (a + t ab, a + t ac, b + t (c - b)).
  const V3 base = pick(A, B, in[kEdgeBC]);
  const V3 dir = pick(pick(sub(C, B), ac, in[kEdgeAC]), ab, in[kEdgeAB]);
  const V3 onEdge{add(base.x, mul(ratio, dir.x)), add(base.y, mul(ratio, dir.y)), add(base.z, mul(ratio, dir.z))};
  // Face: a + ab (vb / sum) + ac (vc / sum), as (a + ab s) + ac t.
  const __m256d s = mul(vb, ratio), t = mul(vc, ratio);
  const V3 onFace{add(add(A.x, mul(ab.x, s)), mul(ac.x, t)), add(add(A.y, mul(ab.y, s)), mul(ac.y, t)),
                  add(add(A.z, mul(ab.z, s)), mul(ac.z, t))};
  V3 q = pick(onFace, onEdge, edge);
  q = pick(q, A, in[kVertexA]);
  q = pick(q, B, in[kVertexB]);
  q = pick(q, C, in[kVertexC]);
  const V3 w = sub(P, q);
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

}  // namespace detail
}  // namespace clod_haptics

#endif
