#include "packet_baseline.h"

#include <algorithm>
#include <limits>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace clod_haptics {
namespace detail {

namespace {
constexpr int W = PacketCull::kRays;
static_assert(W % 2 == 0 && W < 32, "rays go two per register, and a mask bit each");

// The near slab is the smaller product, there being no NaN. Every lane is computed: skipping the lanes of
// rays that left the node costs more in branches than it saves. (Internal, so that the children's test
// inlines it: the library is position independent, and its exported functions could be interposed.)
inline unsigned boxLanes(const TriangleBvh::Node& node, const double* o, const double* inv, double* entry) {
  unsigned mask = 0;
#if defined(__SSE2__)
  const __m128d lo[3] = {_mm_set1_pd(node.lo[0]), _mm_set1_pd(node.lo[1]), _mm_set1_pd(node.lo[2])};
  const __m128d hi[3] = {_mm_set1_pd(node.hi[0]), _mm_set1_pd(node.hi[1]), _mm_set1_pd(node.hi[2])};
  for (int h = 0; h < W; h += 2) {
    __m128d t0 = _mm_setzero_pd(), t1 = _mm_set1_pd(std::numeric_limits<double>::infinity());
    for (int k = 0; k < 3; ++k) {
      const __m128d ok = _mm_load_pd(o + k * W + h), ik = _mm_load_pd(inv + k * W + h);
      const __m128d a = _mm_mul_pd(_mm_sub_pd(lo[k], ok), ik), b = _mm_mul_pd(_mm_sub_pd(hi[k], ok), ik);
      t0 = _mm_max_pd(_mm_min_pd(a, b), t0);
      t1 = _mm_min_pd(_mm_max_pd(a, b), t1);
    }
    _mm_storeu_pd(entry + h, t0);
    mask |= static_cast<unsigned>(_mm_movemask_pd(_mm_cmple_pd(t0, t1))) << h;
  }
#else
  for (int r = 0; r < W; ++r) {
    double t0 = 0.0, t1 = std::numeric_limits<double>::infinity();
    for (int k = 0; k < 3; ++k) {
      const double a = (node.lo[k] - o[k * W + r]) * inv[k * W + r], b = (node.hi[k] - o[k * W + r]) * inv[k * W + r];
      t0 = std::max(std::min(a, b), t0);
      t1 = std::min(std::max(a, b), t1);
    }
    entry[r] = t0;
    mask |= static_cast<unsigned>(t0 <= t1) << r;
  }
#endif
  return mask;
}

}  // namespace

unsigned packetBoxBaseline(const TriangleBvh::Node& node, const double* o, const double* inv, double* entry) {
  return boxLanes(node, o, inv, entry);
}

void packetChildrenBaseline(const TriangleBvh::Node* const child[2], const double* o, const double* inv,
                            const PacketCull& cull, unsigned active, double* const entry[2], unsigned mask[2]) {
  for (int c = 0; c < 2; ++c)
    mask[c] = packetKept(cull, *child[c], entry[c], boxLanes(*child[c], o, inv, entry[c]) & active);
}

unsigned packetTriangleBaseline(const double* a, const double* b, const double* c, const double* o, const double* d,
                                unsigned active, double* t) {
  const Vec3 va(a[0], a[1], a[2]), vb(b[0], b[1], b[2]), vc(c[0], c[1], c[2]);
  unsigned got = 0;
  for (unsigned m = active; m; m &= m - 1) {
    const int r = __builtin_ctz(m);
    if (rayTriangle(Vec3(o[r], o[W + r], o[2 * W + r]), Vec3(d[r], d[W + r], d[2 * W + r]), va, vb, vc, t[r]))
      got |= 1u << r;
  }
  return got;
}

}  // namespace detail
}  // namespace clod_haptics
