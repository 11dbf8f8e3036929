#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "clod_haptics/core/geometry.h"
#include "clod_haptics/core/mesh.h"

namespace clod_haptics {

namespace detail {
/**
 * \brief std::allocator whose value-less construct default-initialises: resizing a vector of plain
 * records leaves them unwritten (and their fresh pages untouched) until the code that fills them runs,
 * on as many threads as it uses, instead of zeroing them first on one.
 */
template <class T>
struct DefaultInitAllocator : std::allocator<T> {
  template <class U>
  struct rebind {
    using other = DefaultInitAllocator<U>;
  };
  DefaultInitAllocator() = default;
  template <class U>
  DefaultInitAllocator(const DefaultInitAllocator<U>&) noexcept {}
  template <class U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible<U>::value) {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

/** \brief Whether forEachPacketHit uses AVX2: the CPU runs it (checked once) and it is not turned off. */
bool packetAvx2();
/** \brief Turns the AVX2 form off (or back on where the CPU has it), so tests cover both forms. */
void usePacketAvx2(bool on);
}  // namespace detail

/**
 * \brief What a packet walk (TriangleBvh::forEachPacketHit) may skip, per ray r of the packet: it visits
 * a subtree only when the subtree may hold a triangle with unit normal n such that n . m < cap[r] and
 * either n . m < below[r], or n . m < nearBelow[r] with the ray entering the subtree's box no farther
 * than within[r] (m = axis[.][r]; "may" by the subtree's bounds of its normals, less kSlack against
 * rounding). cap = below = +inf visits everything the ray meets; cap = +inf, below = -inf and
 * nearBelow = +inf make within a plain distance limit. The walk reads ray r's entries afresh after
 * every hit it reports for ray r, so the hit callback may change them (and only them).
 */
struct PacketCull {
  static constexpr int kRays = 16;
  static constexpr double kSlack = 1e-9;
  alignas(32) double axis[3][kRays];
  alignas(32) double cap[kRays];
  alignas(32) double below[kRays];
  alignas(32) double nearBelow[kRays];
  alignas(32) double within[kRays];
  /** \brief Whether ray r visits a subtree whose normals' lower bound (less kSlack) is lower, entered at entry. */
  bool keeps(int r, double lower, double entry) const {
    return lower < cap[r] && (lower < below[r] || (lower < nearBelow[r] && entry <= within[r]));
  }
};

namespace detail {
/**
 * \brief forEachPacketHit's test of a node's two children with AVX2 (four rays per register, groups of
 * four without an active ray skipped), the same values as the SSE2 and plain forms: the box test (o and
 * inv are [3][16] row-major) and the cull. entry[c] gets the entry distances into child c (of the groups
 * tested) and mask[c] the active rays that meet its box and pass the cull. The caller checks packetAvx2().
 */
void packetChildrenAvx2(const float* const lo[2], const float* const hi[2], const float* const nlo[2],
                        const float* const nhi[2], const double* o, const double* inv, const PacketCull& cull,
                        unsigned active, double* const entry[2], unsigned mask[2]);

/**
 * \brief A packet in float for packetChildrenAvx2f: origins, inverse directions and PacketCull's arrays,
 * rounded so that its test keeps every node the double test keeps (see forEachPacketHit).
 */
struct PacketFloat {
  alignas(32) float o[3][PacketCull::kRays];
  alignas(32) float inv[3][PacketCull::kRays];
  alignas(32) float axis[3][PacketCull::kRays];
  alignas(32) float slack[PacketCull::kRays];  ///< bounds the float rounding of the normals' lower bound
  alignas(32) float cap[PacketCull::kRays];    ///< cap, below, nearBelow, within rounded up
  alignas(32) float below[PacketCull::kRays];
  alignas(32) float nearBelow[PacketCull::kRays];
  alignas(32) float within[PacketCull::kRays];
  float widen;  ///< every box is widened by this much on each side
  /** \brief Copies ray r's cull entries, rounded (thresholds up, slack from the axis). */
  void setCull(const PacketCull& cull, int r);
  /**
   * \brief Fills the packet from count rays, or returns false when a ray is outside what the float test
   * covers (coordinates or scene beyond 2^30, a direction longer than 2^30 or whose largest component is
   * under 1/4): the caller then uses the double test. sceneBound: the largest coordinate of the scene.
   */
  bool set(const double* o, const double* dirs, const double* inv, int count, double sceneBound, const PacketCull& cull);
};

/**
 * \brief packetChildrenAvx2's test in float, eight rays per register: a node kept by the double test is
 * kept here (boxes widened, thresholds rounded up, see PacketFloat), entry[c] gets lower bounds of the
 * entry distances. The caller checks packetAvx2().
 */
void packetChildrenAvx2f(const float* const lo[2], const float* const hi[2], const float* const nlo[2],
                         const float* const nhi[2], const PacketFloat& f, unsigned active, double* const entry[2],
                         unsigned mask[2]);

/**
 * \brief rayTriangle of one triangle (vertices a, b, c) against the active rays of a packet with AVX2, four
 * rays per register (groups of four without an active ray skipped): the same operations in the same
 * order, so the same decisions and distances bit for bit. o and d are [3][16] row-major origins and
 * directions; returns the active rays that hit, with their distances in t. The caller checks packetAvx2().
 */
unsigned packetTriangleAvx2(const double* a, const double* b, const double* c, const double* o, const double* d,
                            unsigned active, double* t);
}  // namespace detail

/**
 * \brief A bounding-volume hierarchy over a mesh's triangles in flat arrays, for the ray casts of
 * sphere placement (every hit along a ray, not only the first).
 *
 * Nodes are stored depth first (the left child follows its parent); a leaf holds a contiguous run of
 * the permuted triangle order. Bounds are floats rounded outward, so a node's box contains its
 * triangles exactly while a node takes 56 bytes instead of 80; the ray-box test runs in double.
 */
class TriangleBvh {
 public:
  /** \brief One node: bounds, and either the second child (inner) or a triangle run (leaf). */
  struct Node {
    float lo[3];          ///< box of the triangles below, rounded outward
    float hi[3];
    float normalLo[3];    ///< component-wise bounds of the unit face normals below (rounded outward)
    float normalHi[3];
    std::uint32_t first;  ///< leaf: first entry in order(); inner: index of the right child
    std::uint32_t count;  ///< leaf: number of triangles; inner: 0
  };
  /** \brief The nodes' array (filled by the build's threads without zeroing first). */
  using NodeArray = std::vector<Node, detail::DefaultInitAllocator<Node>>;

  /**
   * \brief Builds the hierarchy (binned surface area heuristic); the mesh must outlive it. threads > 1
   * builds the root's two subtrees concurrently (same tree as one thread).
   */
  explicit TriangleBvh(const TriangleMesh& mesh, int leafSize = 4, unsigned threads = 1);

  /**
   * \brief Calls hit(triangle, t) for every triangle the ray origin + t dir meets at 0 < t < tMax.
   * The callback may lower tMax (it is read again after each hit), which prunes farther nodes;
   * nearer children are visited first, except that a child containing the origin waits for its
   * sibling. Allocates nothing.
   */
  template <class Hit>
  void forEachRayHit(const Vec3& origin, const Vec3& dir, double& tMax, Hit&& hit) const {
    forEachRayHit(origin, dir, tMax, hit, [](const Node&, double) { return true; });
  }

  /**
   * \brief The same, visiting a node only when keep(node, tEntry) is true (tEntry: where the ray
   * enters its box), so a caller can skip subtrees that cannot change its answer.
   */
  template <class Hit, class Keep>
  void forEachRayHit(const Vec3& origin, const Vec3& dir, double& tMax, Hit&& hit, Keep&& keep) const;

  /** \brief The most rays forEachPacketHit takes at once. */
  static constexpr int kPacket = PacketCull::kRays;

  /**
   * \brief Every hit of up to kPacket rays at once, without a distance limit, in the subtrees cull lets
   * each ray into: one walk down the hierarchy for all of them, each node's two children tested against
   * every ray still in it, box and cull together. Meant for rays that start close together and point
   * alike (the placement's neighbouring rays share most of their nodes). Calls hit(r, triangle, t)
   * with r the ray's index; hit may change ray r's entries of cull, and nodes pushed before the change
   * are tested again.
   * Each ray gets every hit forEachRayHit gives it alone with keep = cull.keeps, in an order that may
   * differ. Allocates nothing.
   */
  template <class Hit>
  void forEachPacketHit(const Vec3* origins, const Vec3* dirs, int count, const PacketCull& cull, Hit&& hit) const;

  /** \brief cull.keeps for ray r at node entered at entry (the form forEachRayHit's keep takes). */
  static bool keeps(const PacketCull& cull, int r, const Node& node, double entry) {
    const Vec3 m(cull.axis[0][r], cull.axis[1][r], cull.axis[2][r]);
    return cull.keeps(r, minDot(node, m) - PacketCull::kSlack, entry);
  }

  /** \brief Lower bound of n . m over the unit normals n of a node's triangles. */
  static double minDot(const Node& node, const Vec3& m) {
    double s = 0.0;
    for (int k = 0; k < 3; ++k) s += std::min(m[k] * node.normalLo[k], m[k] * node.normalHi[k]);
    return s;
  }

  /** \brief The nodes, root first. */
  const NodeArray& nodes() const { return nodes_; }
  /** \brief Triangle indices in leaf order. */
  const std::vector<std::uint32_t>& order() const { return order_; }

 private:
  // Whether a walk visits the left child first, given where the ray enters each: the nearer first,
  // except that a child containing the origin (entered at 0) waits for a sibling the ray reaches
  // further on.
  static bool leftFirst(double tl, double tr) { return (tl == 0.0) == (tr == 0.0) ? tl <= tr : tr == 0.0; }

  const TriangleMesh& mesh_;
  NodeArray nodes_;
  std::vector<std::uint32_t> order_;
  // Each leaf entry's vertex indices, in leaf order: a leaf's triangles are read from one run of memory
  // instead of through the mesh's triangle array at scattered places (the walks' most frequent miss).
  std::vector<Triangle, detail::DefaultInitAllocator<Triangle>> corners_;
  double sceneBound_ = 0.0;  // the largest coordinate of the root's box (for detail::PacketFloat)
};

template <class Hit, class Keep>
void TriangleBvh::forEachRayHit(const Vec3& origin, const Vec3& dir, double& tMax, Hit&& hit, Keep&& keep) const {
  if (nodes_.empty()) return;
  // A zero direction component becomes a tiny one of the same sign: the slab products stay finite or
  // +-inf, never 0 * inf = NaN, so the test needs no special cases.
  double inv[3];
  bool negative[3];
  for (int k = 0; k < 3; ++k) {
    const double d = dir[k] != 0.0 ? dir[k] : std::copysign(1e-300, dir[k]);
    inv[k] = 1.0 / d;
    negative[k] = inv[k] < 0.0;
  }
  // Entry distance of the ray into a node's box, or 1e308 when it misses within (0, tMax).
  const double o[3] = {origin[0], origin[1], origin[2]};
  auto enter = [&](const Node& node) {
    double t0 = 0.0, t1 = tMax;
    for (int k = 0; k < 3; ++k) {
      const double lo = node.lo[k], hi = node.hi[k];
      const double near = ((negative[k] ? hi : lo) - o[k]) * inv[k];
      const double far = ((negative[k] ? lo : hi) - o[k]) * inv[k];
      t0 = near > t0 ? near : t0;
      t1 = far < t1 ? far : t1;
    }
    return t0 <= t1 ? t0 : 1e308;
  };
  struct Item {
    std::uint32_t node;
    double t;
  };
  Item stack[128];  // at most one pending entry per level, and the build keeps the depth under 96
  int top = 0;
  if (enter(nodes_[0]) < 1e308) stack[top++] = {0, 0.0};
  while (top > 0) {
    const Item item = stack[--top];
    if (item.t > tMax) continue;
    const Node& node = nodes_[item.node];
    if (!keep(node, item.t)) continue;
    if (node.count > 0) {
      for (std::uint32_t i = node.first; i < node.first + node.count; ++i) {
        const Triangle& v = corners_[i];
        double t;
        if (rayTriangle(origin, dir, mesh_.vertices[v[0]], mesh_.vertices[v[1]], mesh_.vertices[v[2]], t) && t < tMax)
          hit(order_[i], t);
      }
    } else {
      const std::uint32_t left = item.node + 1, right = node.first;
      const double tl = enter(nodes_[left]), tr = enter(nodes_[right]);
      // Nearer child first, except that a child containing the origin (entered at 0) waits for a
      // sibling the ray reaches further on: a ray cast from a surface point finds the opposite surface
      // first, and a caller's keep() can then prune the origin's own neighbourhood (the placement's
      // rays: about a third fewer nodes and half the triangle tests).
      if (leftFirst(tl, tr)) {
        if (tr < 1e308) stack[top++] = {right, tr};
        if (tl < 1e308) stack[top++] = {left, tl};
      } else {
        if (tl < 1e308) stack[top++] = {left, tl};
        if (tr < 1e308) stack[top++] = {right, tr};
      }
    }
  }
}

template <class Hit>
void TriangleBvh::forEachPacketHit(const Vec3* origins, const Vec3* dirs, int count, const PacketCull& cull,
                                   Hit&& hit) const {
  constexpr int W = kPacket;
  static_assert(W % 2 == 0 && W < 32, "rays go two per register, and a mask bit each");
  if (nodes_.empty() || count <= 0) return;
  count = std::min(count, W);
  // Per axis and ray (rays past count copy the first and stay masked out); a zero direction
  // component becomes a tiny one of the same sign, as in forEachRayHit.
  alignas(32) double o[3][W], inv[3][W], dv[3][W];
  for (int r = 0; r < W; ++r)
    for (int k = 0; k < 3; ++k) {
      const int s = r < count ? r : 0;
      const double d = dirs[s][k] != 0.0 ? dirs[s][k] : std::copysign(1e-300, dirs[s][k]);
      inv[k][r] = 1.0 / d;
      o[k][r] = origins[s][k];
      dv[k][r] = dirs[s][k];
    }
  // Entry distance of every ray into a node's box and the mask of the rays that meet it: the same
  // values as forEachRayHit's test (the near slab is the smaller product, there being no NaN), two
  // rays per SSE2 register. Every lane is computed: skipping the lanes of rays that left the node
  // costs more in branches than it saves.
#if defined(__SSE2__)
  __m128d oV[3][W / 2], invV[3][W / 2];
  for (int k = 0; k < 3; ++k)
    for (int h = 0; h < W / 2; ++h) {
      oV[k][h] = _mm_set_pd(o[k][2 * h + 1], o[k][2 * h]);
      invV[k][h] = _mm_set_pd(inv[k][2 * h + 1], inv[k][2 * h]);
    }
#endif
  auto enter = [&](const Node& node, double* entry) {
    unsigned mask = 0;
#if defined(__SSE2__)
    for (int h = 0; h < W / 2; ++h) {
      __m128d t0 = _mm_setzero_pd(), t1 = _mm_set1_pd(std::numeric_limits<double>::infinity());
      for (int k = 0; k < 3; ++k) {
        const __m128d a = _mm_mul_pd(_mm_sub_pd(_mm_set1_pd(node.lo[k]), oV[k][h]), invV[k][h]);
        const __m128d b = _mm_mul_pd(_mm_sub_pd(_mm_set1_pd(node.hi[k]), oV[k][h]), invV[k][h]);
        t0 = _mm_max_pd(_mm_min_pd(a, b), t0);
        t1 = _mm_min_pd(_mm_max_pd(a, b), t1);
      }
      _mm_storeu_pd(entry + 2 * h, t0);
      mask |= static_cast<unsigned>(_mm_movemask_pd(_mm_cmple_pd(t0, t1))) << (2 * h);
    }
#else
    for (int r = 0; r < W; ++r) {
      double t0 = 0.0, t1 = std::numeric_limits<double>::infinity();
      for (int k = 0; k < 3; ++k) {
        const double a = (node.lo[k] - o[k][r]) * inv[k][r], b = (node.hi[k] - o[k][r]) * inv[k][r];
        t0 = std::max(std::min(a, b), t0);
        t1 = std::min(std::max(a, b), t1);
      }
      entry[r] = t0;
      mask |= static_cast<unsigned>(t0 <= t1) << r;
    }
#endif
    return mask;
  };
  // The rays of active that pass the cull at node (entered at entry[r]).
  auto culled = [&](const Node& node, const double* entry, unsigned active) {
    unsigned mask = 0;
    for (unsigned m = active; m; m &= m - 1) {
      const int r = __builtin_ctz(m);
      if (keeps(cull, r, node, entry[r])) mask |= 1u << r;
    }
    return mask;
  };
  // Where the CPU runs AVX2 both children are tested by one out-of-line call, four rays per register,
  // or eight in float when the packet's values allow a float test that keeps every node this one keeps.
  const bool avx2 = W == 16 && detail::packetAvx2();
  detail::PacketFloat packetFloat;
  const bool inFloat = avx2 && packetFloat.set(&o[0][0], &dv[0][0], &inv[0][0], count, sceneBound_, cull);
  struct Item {
    std::uint32_t node;
    unsigned mask;     // the rays that met the node's box and passed the cull when it was pushed
    std::uint64_t hits;  // hits reported before it was pushed: if none since, the cull is unchanged
    double t[W];
  };
  std::uint64_t hits = 0;
  Item stack[128];  // at most one pending entry per level, as in forEachRayHit
  int top = 0;
  stack[0].node = 0;
  stack[0].mask = enter(nodes_[0], stack[0].t) & ((1u << count) - 1);
  stack[0].hits = ~std::uint64_t{0};  // not culled yet
  std::fill(stack[0].t, stack[0].t + W, 0.0);
  if (stack[0].mask) top = 1;
  while (top > 0) {
    const Item item = stack[--top];  // a copy: reading the slot in place while pushing is slower
    const Node& node = nodes_[item.node];
    const unsigned mask = item.hits == hits ? item.mask : culled(node, item.t, item.mask);
    if (mask == 0) continue;
    if (node.count > 0) {
      for (std::uint32_t i = node.first; i < node.first + node.count; ++i) {
        const std::uint32_t tri = order_[i];
        const Triangle& v = corners_[i];
        const Vec3 &a = mesh_.vertices[v[0]], &b = mesh_.vertices[v[1]], &c = mesh_.vertices[v[2]];
        if (avx2) {  // the same tests, four rays at a time, hits reported in the same order
          alignas(32) double t[W];
          const unsigned got = detail::packetTriangleAvx2(a.data(), b.data(), c.data(), &o[0][0], &dv[0][0], mask, t);
          for (unsigned m = got; m; m &= m - 1) {
            const int r = __builtin_ctz(m);
            ++hits;
            hit(r, tri, t[r]);
            if (inFloat) packetFloat.setCull(cull, r);
          }
          continue;
        }
        for (unsigned m = mask; m; m &= m - 1) {
          const int r = __builtin_ctz(m);
          double t;
          if (rayTriangle(origins[r], dirs[r], a, b, c, t)) {
            ++hits;
            hit(r, tri, t);
          }
        }
      }
      continue;
    }
    Item l, r;
    l.node = item.node + 1;
    r.node = node.first;
    l.hits = r.hits = hits;
    const Node &ln = nodes_[l.node], &rn = nodes_[r.node];
    if (avx2) {
      const float* const lo[2] = {ln.lo, rn.lo};
      const float* const hi[2] = {ln.hi, rn.hi};
      const float* const nlo[2] = {ln.normalLo, rn.normalLo};
      const float* const nhi[2] = {ln.normalHi, rn.normalHi};
      double* const entry[2] = {l.t, r.t};
      unsigned masks[2];
      if (inFloat)
        detail::packetChildrenAvx2f(lo, hi, nlo, nhi, packetFloat, mask, entry, masks);
      else
        detail::packetChildrenAvx2(lo, hi, nlo, nhi, &o[0][0], &inv[0][0], cull, mask, entry, masks);
      l.mask = masks[0];
      r.mask = masks[1];
    } else {
      l.mask = culled(ln, l.t, enter(ln, l.t) & mask);
      r.mask = culled(rn, r.t, enter(rn, r.t) & mask);
    }
    // The order forEachRayHit takes for the first ray that meets both children (nearer first, a child
    // containing the origin last); the other rays follow it.
    const unsigned both = l.mask & r.mask;
    const bool left = both == 0 || leftFirst(l.t[__builtin_ctz(both)], r.t[__builtin_ctz(both)]);
    const Item& first = left ? l : r;
    const Item& second = left ? r : l;
    if (second.mask) stack[top++] = second;
    if (first.mask) stack[top++] = first;
  }
}

}  // namespace clod_haptics
