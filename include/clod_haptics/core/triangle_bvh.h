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
 * \brief A packet in float for the float form of the packet walk's child test: origins, inverse directions
 * and PacketCull's arrays, rounded so that its test keeps every node the double test keeps (why: see
 * src/core/simd/packet_float.cpp).
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
 * \brief A packet kernel's triangle test: rayTriangle of the triangle (vertices a, b, c) against the active
 * rays of a packet (o and d: [3][kRays] row-major origins and directions); returns the rays that hit, with
 * their distances in t (32-byte aligned).
 */
using PacketTriangleTest = unsigned (*)(const double* a, const double* b, const double* c, const double* o,
                                        const double* d, unsigned active, double* t);

struct PacketKernels;
class PacketWalk;
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

  friend class detail::PacketWalk;

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
      // first, and a caller's keep() can then prune the origin's own neighbourhood.
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

namespace detail {
/**
 * \brief The traversal behind TriangleBvh::forEachPacketHit: the packet's rays laid out for the packet
 * kernels (chosen once for the CPU, see src/core/simd) and the stack of pending nodes. Its steps are
 * compiled in the core library; the template only reports the hits between them.
 */
class PacketWalk {
 public:
  static constexpr int kRays = PacketCull::kRays;

  /** \brief Starts a walk of count rays (1 to kRays) down bvh, which must have nodes. */
  PacketWalk(const TriangleBvh& bvh, const Vec3* origins, const Vec3* dirs, int count, const PacketCull& cull);
  PacketWalk(const PacketWalk&) = delete;
  PacketWalk& operator=(const PacketWalk&) = delete;

  /** \brief The next leaf that some ray reaches and whose cull lets it in, or nullptr when the walk is over. */
  const TriangleBvh::Node* nextLeaf();

  /**
   * \brief The rays of the current leaf that hit the triangle at entry i of order(), with their distances
   * in t (32-byte aligned): rayTriangle's decisions and distances, bit for bit.
   */
  unsigned hits(std::uint32_t i, double* t) const {
    const Triangle& v = bvh_.corners_[i];
    const std::vector<Vec3>& p = bvh_.mesh_.vertices;
    return triangle_(p[v[0]].data(), p[v[1]].data(), p[v[2]].data(), &o_[0][0], &dir_[0][0], leafMask_, t);
  }

  /** \brief Notes that a hit of ray r was reported: the caller may have changed ray r's cull entries. */
  void reported(int r) {
    ++hits_;
    if (inFloat_) float_.setCull(cull_, r);
  }

 private:
  struct Item {
    std::uint32_t node;
    unsigned mask;       // the rays that met the node's box and passed the cull when it was pushed
    std::uint64_t hits;  // hits reported before it was pushed: if none since, the cull is unchanged
    double t[kRays];     // where each ray of mask enters the node's box
  };

  // Steps of the constructor and nextLeaf, defined in triangle_bvh.cpp (their only caller); inline, so that
  // they are inlined there although the library is position independent.
  inline void setRays(const Vec3* origins, const Vec3* dirs, int count);
  inline void pushRoot(int count);
  inline void pushChildren(std::uint32_t index, const TriangleBvh::Node& node, unsigned mask);

  const TriangleBvh& bvh_;
  const PacketCull& cull_;
  const PacketKernels& kernels_;
  PacketTriangleTest triangle_;
  bool inFloat_ = false;  // the child test runs in float (float_), which keeps every node the double one keeps
  unsigned leafMask_ = 0;
  std::uint64_t hits_ = 0;
  int top_ = 0;
  // Per axis and ray (rays past count copy the first and stay masked out); a zero direction component
  // becomes a tiny one of the same sign in inv_, as in forEachRayHit.
  alignas(32) double o_[3][kRays];
  alignas(32) double inv_[3][kRays];
  alignas(32) double dir_[3][kRays];
  PacketFloat float_;
  Item stack_[128];  // at most one pending entry per level, as in forEachRayHit
};
}  // namespace detail

template <class Hit>
void TriangleBvh::forEachPacketHit(const Vec3* origins, const Vec3* dirs, int count, const PacketCull& cull,
                                   Hit&& hit) const {
  if (nodes_.empty() || count <= 0) return;
  detail::PacketWalk walk(*this, origins, dirs, std::min(count, kPacket), cull);
  alignas(32) double t[kPacket];
  while (const Node* leaf = walk.nextLeaf()) {
    for (std::uint32_t i = leaf->first; i < leaf->first + leaf->count; ++i) {
      for (unsigned got = walk.hits(i, t); got; got &= got - 1) {
        const int r = __builtin_ctz(got);
        hit(r, order_[i], t[r]);
        walk.reported(r);
      }
    }
  }
}

}  // namespace clod_haptics
