#include "clod_haptics/core/triangle_bvh.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>

#include "float_rounding.h"
#include "parallel.h"
#include "simd/dispatch.h"
#include "simd/float4.h"
#include "simd/packet_baseline.h"

namespace clod_haptics {
namespace {

// Surface area heuristic over kBins bins of the centroids along one axis: the split that minimises
// area(left) * count(left) + area(right) * count(right), the expected cost of a ray through the node.
constexpr int kBins = 16;
// Deeper than this the median split is used, which halves every range: the depth stays below
// kMaxSahDepth + 32, within the traversal's stack (one pending entry per level).
constexpr int kMaxSahDepth = 64;

using detail::centre4;
using detail::F4;
using detail::loadMasked4;
using detail::loadPadded4;
using detail::max4;
using detail::min4;
using detail::roundDown;
using detail::roundUp;
using detail::splat4;
using detail::store4;

// A float box; the triangles' boxes are rounded outward, so unions of them stay conservative.
struct Box {
  float lo[3] = {std::numeric_limits<float>::infinity(), std::numeric_limits<float>::infinity(),
                 std::numeric_limits<float>::infinity()};
  float hi[3] = {-std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity(),
                 -std::numeric_limits<float>::infinity()};
  void extend(const Box& b) {
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], b.lo[k]);
      hi[k] = std::max(hi[k], b.hi[k]);
    }
  }
  void extend(const float* p) {
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], p[k]);
      hi[k] = std::max(hi[k], p[k]);
    }
  }
  bool empty() const { return lo[0] > hi[0]; }
  double halfArea() const {
    if (empty()) return 0.0;
    const double x = double(hi[0]) - lo[0], y = double(hi[1]) - lo[1], z = double(hi[2]) - lo[2];
    return x * y + y * z + z * x;
  }
};

// What the build keeps per triangle: its box and its index, 32 bytes, each corner in a 16-byte row so a
// pass loads it with one instruction (the row's fourth float: 0 after lo, the index's bits after hi,
// masked off before any arithmetic). The build partitions these records themselves, so every pass
// over a node's range reads memory in order instead of gathering through an index array.
struct alignas(16) Prim {
  float lo[3];
  float zero;
  float hi[3];
  std::uint32_t index;
};

using PrimArray = std::vector<Prim, detail::DefaultInitAllocator<Prim>>;

// A box centre coordinate, the binning key.
float centreOf(const Prim& p, int axis) { return 0.5f * p.lo[axis] + 0.5f * p.hi[axis]; }

// A bin of the surface area heuristic: the boxes of its triangles and the bounds of their centres.
struct Bin {
  F4 lo = splat4(std::numeric_limits<float>::infinity()), hi = splat4(-std::numeric_limits<float>::infinity());
  F4 clo = lo, chi = hi;
  std::uint32_t count = 0;
};
Box boxOf(F4 lo, F4 hi) {
  float l[4], h[4];
  store4(l, lo);
  store4(h, hi);
  Box b;
  for (int k = 0; k < 3; ++k) {
    b.lo[k] = l[k];
    b.hi[k] = h[k];
  }
  return b;
}

// Where a centre falls among the bins along the axis of a split.
struct Binning {
  int axis;
  double lo, scale;  // the centres' lower bound along axis, bins per unit length
  int binOf(const Prim& p) const { return std::min(kBins - 1, static_cast<int>((centreOf(p, axis) - lo) * scale)); }
};

struct Build {
  const TriangleMesh& mesh;
  PrimArray& prims;
  int leafSize;

  // Partitions prims[begin, end) (centre bounds cbox) and returns the split point, with the centre
  // bounds of both sides in child (from the bins: no pass of their own); falls back to the median when
  // the centres coincide along the axis or the heuristic leaves one side empty.
  std::uint32_t split(std::uint32_t begin, std::uint32_t end, const Box& cbox, int depth, Box child[2]) const {
    int axis = 0;
    for (int k = 1; k < 3; ++k)
      if (double(cbox.hi[k]) - cbox.lo[k] > double(cbox.hi[axis]) - cbox.lo[axis]) axis = k;
    const double extent = double(cbox.hi[axis]) - cbox.lo[axis];
    if (!(extent > 0.0) || !std::isfinite(extent) || end - begin < 16 || depth >= kMaxSahDepth)
      return median(begin, end, axis, child);
    const Binning binning{axis, cbox.lo[axis], kBins / extent};
    Bin bins[kBins];
    fillBins(begin, end, binning, bins);
    const int best = cheapestSplit(bins);
    if (best < 0) return median(begin, end, axis, child);
    return partition(begin, end, binning, bins, best, child);
  }

  // Splits prims[begin, end) at the median centre along axis.
  std::uint32_t median(std::uint32_t begin, std::uint32_t end, int axis, Box child[2]) const {
    const std::uint32_t mid = begin + (end - begin) / 2;
    std::nth_element(prims.begin() + begin, prims.begin() + mid, prims.begin() + end,
                     [&](const Prim& a, const Prim& b) { return centreOf(a, axis) < centreOf(b, axis); });
    child[0] = centreBox(begin, mid);
    child[1] = centreBox(mid, end);
    return mid;
  }

  void fillBins(std::uint32_t begin, std::uint32_t end, const Binning& binning, Bin bins[kBins]) const {
    for (std::uint32_t i = begin; i < end; ++i) {
      const Prim& p = prims[i];
      Bin& bin = bins[binning.binOf(p)];
      const F4 pl = loadPadded4(p.lo), ph = loadMasked4(p.hi), c = centre4(pl, ph);
      bin.lo = min4(bin.lo, pl);
      bin.hi = max4(bin.hi, ph);
      bin.clo = min4(bin.clo, c);
      bin.chi = max4(bin.chi, c);
      ++bin.count;
    }
  }

  // The bin boundary i (bins below i go left) of the least cost, or -1 when every boundary leaves a side
  // empty.
  static int cheapestSplit(const Bin bins[kBins]) {
    double rightArea[kBins];
    std::uint32_t rightCount[kBins];
    Box acc;
    std::uint32_t n = 0;
    for (int i = kBins - 1; i > 0; --i) {
      acc.extend(boxOf(bins[i].lo, bins[i].hi));
      n += bins[i].count;
      rightArea[i] = acc.halfArea();
      rightCount[i] = n;
    }
    acc = Box();
    n = 0;
    double bestCost = std::numeric_limits<double>::infinity();
    int bestSplit = -1;
    for (int i = 1; i < kBins; ++i) {
      acc.extend(boxOf(bins[i - 1].lo, bins[i - 1].hi));
      n += bins[i - 1].count;
      if (n == 0 || rightCount[i] == 0) continue;
      const double cost = acc.halfArea() * n + rightArea[i] * rightCount[i];
      if (cost < bestCost) {
        bestCost = cost;
        bestSplit = i;
      }
    }
    return bestSplit;
  }

  // Moves the triangles of the bins below split in front of the others; the sides' centre bounds from
  // the bins.
  std::uint32_t partition(std::uint32_t begin, std::uint32_t end, const Binning& binning, const Bin bins[kBins],
                          int split, Box child[2]) const {
    const auto mid = std::partition(prims.begin() + begin, prims.begin() + end,
                                    [&](const Prim& p) { return binning.binOf(p) < split; });
    for (int side = 0; side < 2; ++side) {
      child[side] = Box();
      for (int i = side ? split : 0; i < (side ? kBins : split); ++i)
        if (bins[i].count) child[side].extend(boxOf(bins[i].clo, bins[i].chi));
    }
    return static_cast<std::uint32_t>(mid - prims.begin());
  }

  Box centreBox(std::uint32_t begin, std::uint32_t end) const {
    Box c;
    for (std::uint32_t i = begin; i < end; ++i) {
      const float centre[3] = {centreOf(prims[i], 0), centreOf(prims[i], 1), centreOf(prims[i], 2)};
      c.extend(centre);
    }
    return c;
  }

  // Builds order[begin, end) into nodes (indices local to nodes, left child next to its parent) and
  // returns the node's index; bounds are filled bottom up from the leaves.
  std::uint32_t build(TriangleBvh::NodeArray& nodes, std::uint32_t begin, std::uint32_t end, const Box& cbox,
                      int depth) const {
    const std::uint32_t self = static_cast<std::uint32_t>(nodes.size());
    nodes.emplace_back();
    if (end - begin <= static_cast<std::uint32_t>(leafSize)) {
      leaf(nodes[self], begin, end);
      return self;
    }
    Box child[2];
    const std::uint32_t mid = split(begin, end, cbox, depth, child);
    const std::uint32_t left = build(nodes, begin, mid, child[0], depth + 1);
    const std::uint32_t right = build(nodes, mid, end, child[1], depth + 1);
    join(nodes[self], nodes[left], nodes[right], right);
    return self;
  }

  void leaf(TriangleBvh::Node& node, std::uint32_t begin, std::uint32_t end) const {
    Box box;
    double nlo[3] = {2, 2, 2}, nhi[3] = {-2, -2, -2};
    for (std::uint32_t i = begin; i < end; ++i) {
      box.extend(prims[i].lo);
      box.extend(prims[i].hi);
      const Vec3& n = mesh.normals[prims[i].index];
      for (int k = 0; k < 3; ++k) {
        nlo[k] = std::min(nlo[k], n[k]);
        nhi[k] = std::max(nhi[k], n[k]);
      }
    }
    for (int k = 0; k < 3; ++k) {
      node.lo[k] = box.lo[k];
      node.hi[k] = box.hi[k];
      // Outward by more than float rounding: bounds stay bounds after the cast.
      node.normalLo[k] = static_cast<float>(nlo[k] - 1e-6);
      node.normalHi[k] = static_cast<float>(nhi[k] + 1e-6);
    }
    node.first = begin;
    node.count = end - begin;
  }

  static void join(TriangleBvh::Node& node, const TriangleBvh::Node& a, const TriangleBvh::Node& b,
                   std::uint32_t right) {
    for (int k = 0; k < 3; ++k) {
      node.lo[k] = std::min(a.lo[k], b.lo[k]);
      node.hi[k] = std::max(a.hi[k], b.hi[k]);
      node.normalLo[k] = std::min(a.normalLo[k], b.normalLo[k]);
      node.normalHi[k] = std::max(a.normalHi[k], b.normalHi[k]);
    }
    node.first = right;
    node.count = 0;
  }
};

// The build on two threads: the two top levels' splits first (the second level's two on two threads),
// then the up to four subtrees below them built into arrays of their own by two threads, each taking the
// largest one left, then appended in the serial build's depth-first order with their node indices
// shifted: the same tree as the serial build, node for node, with the work balanced however uneven the
// splits.
class TwoThreadBuild {
 public:
  explicit TwoThreadBuild(const Build& build) : b_(build), count_(static_cast<std::uint32_t>(build.prims.size())) {}

  void run(TriangleBvh::NodeArray& nodes) {
    splitTopLevels();
    forEachLargestFirst([&](Subtree& s) {
      s.nodes.reserve(2 * std::size_t(s.end - s.begin));
      b_.build(s.nodes, s.begin, s.end, s.cbox, s.depth);
    });
    std::uint32_t halfNode[2];
    nodes.resize(placeSubtrees(halfNode));
    forEachLargestFirst([&](Subtree& s) { copyShifted(s, nodes); });
    joinTopLevels(nodes, halfNode);
  }

 private:
  struct Subtree {
    std::uint32_t begin, end;
    Box cbox;
    int depth;
    TriangleBvh::NodeArray nodes;
    std::uint32_t base;  // the index of its root in the whole tree
  };

  // Whether half h (of the root's split) was split again, or is a subtree of its own.
  bool halfSplit(int h) const { return quarter_[h] != halves_[h + 1]; }

  // The root's split, its halves' splits on two threads, and the subtrees below them, largest first.
  void splitTopLevels() {
    Box half[2];  // centre bounds of each half
    const std::uint32_t mid = b_.split(0, count_, b_.centreBox(0, count_), 0, half);
    halves_[1] = mid;
    halves_[2] = count_;
    Box quarters[2][2];
    const std::uint32_t leaf = static_cast<std::uint32_t>(b_.leafSize);
    detail::runParallel(2, [&](unsigned h) {
      const std::uint32_t begin = halves_[h], end = halves_[h + 1];
      quarter_[h] = end - begin > leaf ? b_.split(begin, end, half[h], 1, quarters[h]) : end;
    });
    subtrees_.reserve(4);
    for (int h = 0; h < 2; ++h) {
      if (!halfSplit(h)) {
        subtrees_.push_back({halves_[h], halves_[h + 1], half[h], 1, {}, 0});
      } else {
        subtrees_.push_back({halves_[h], quarter_[h], quarters[h][0], 2, {}, 0});
        subtrees_.push_back({quarter_[h], halves_[h + 1], quarters[h][1], 2, {}, 0});
      }
    }
    bySize_.resize(subtrees_.size());
    for (std::size_t i = 0; i < bySize_.size(); ++i) bySize_[i] = i;
    std::sort(bySize_.begin(), bySize_.end(), [&](std::size_t x, std::size_t y) {
      return subtrees_[x].end - subtrees_[x].begin > subtrees_[y].end - subtrees_[y].begin;
    });
  }

  // Runs work(subtree) for every subtree on two threads, each taking the largest one left.
  template <class Work>
  void forEachLargestFirst(Work&& work) {
    std::atomic<std::size_t> next{0};
    detail::runParallel(2, [&](unsigned) {
      for (std::size_t i; (i = next.fetch_add(1)) < bySize_.size();) work(subtrees_[bySize_[i]]);
    });
  }

  // The subtrees' places in the serial build's depth-first order: the root, then per half its own node
  // (when it was split) and its subtrees. Returns the number of nodes.
  std::uint32_t placeSubtrees(std::uint32_t halfNode[2]) {
    std::uint32_t size = 1;  // the root
    std::size_t t = 0;
    for (int h = 0; h < 2; ++h) {
      halfNode[h] = size;
      if (halfSplit(h)) ++size;  // the half's own node
      for (const std::size_t end = t + (halfSplit(h) ? 2 : 1); t < end; ++t) {
        subtrees_[t].base = size;
        size += static_cast<std::uint32_t>(subtrees_[t].nodes.size());
      }
    }
    return size;
  }

  // Copies a subtree to its place, its inner nodes' child indices shifted, and frees its array.
  static void copyShifted(Subtree& s, TriangleBvh::NodeArray& nodes) {
    TriangleBvh::Node* out = nodes.data() + s.base;
    for (const TriangleBvh::Node& node : s.nodes) {
      *out = node;
      if (node.count == 0) out->first += s.base;
      ++out;
    }
    TriangleBvh::NodeArray().swap(s.nodes);
  }

  // The nodes above the subtrees: the halves that were split, then the root.
  void joinTopLevels(TriangleBvh::NodeArray& nodes, const std::uint32_t halfNode[2]) const {
    std::size_t t = 0;
    for (int h = 0; h < 2; ++h) {
      if (!halfSplit(h)) {
        ++t;
        continue;
      }
      const std::uint32_t left = subtrees_[t].base, right = subtrees_[t + 1].base;
      Build::join(nodes[halfNode[h]], nodes[left], nodes[right], right);
      t += 2;
    }
    Build::join(nodes[0], nodes[halfNode[0]], nodes[halfNode[1]], halfNode[1]);
  }

  const Build& b_;
  const std::uint32_t count_;
  std::uint32_t halves_[3] = {0, 0, 0};  // the root's range and split
  std::uint32_t quarter_[2] = {0, 0};    // each half's split, or its end when the half is a leaf
  std::vector<Subtree> subtrees_;
  std::vector<std::size_t> bySize_;  // subtrees_'s indices, largest first
};

// Builds the nodes over prims (permuting them into leaf order).
void buildNodes(const TriangleMesh& mesh, PrimArray& prims, int leafSize, bool parallel,
                TriangleBvh::NodeArray& nodes) {
  const Build b{mesh, prims, std::max(1, leafSize)};
  if (parallel) {
    TwoThreadBuild(b).run(nodes);
    return;
  }
  // At most 2n - 1 nodes: reserving that never reallocates, and untouched capacity is never resident.
  const std::uint32_t count = static_cast<std::uint32_t>(prims.size());
  nodes.reserve(2 * std::size_t(count));
  b.build(nodes, 0, count, b.centreBox(0, count), 0);
}

// Runs part(begin, end) over [0, n): in two halves on two threads when parallel.
template <class Part>
void inHalves(bool parallel, std::size_t n, Part&& part) {
  if (parallel)
    detail::runParallel(2, [&](unsigned h) { h ? part(n / 2, n) : part(0, n / 2); });
  else
    part(0, n);
}

// Every vertex rounded outward once (a vertex is shared by about six triangles), per vertex: down x y z,
// up x y z. The boxes are widened by 2^-32 of the largest coordinate first: the slab tests (in double) and
// rayTriangle round, so without it a ray through a box's face, edge or corner -- a ray aimed at a vertex,
// a coordinate that is a float already -- could miss the box of a triangle that rayTriangle says it hits.
std::vector<float, detail::DefaultInitAllocator<float>> roundedVertices(const TriangleMesh& mesh, bool parallel) {
  double bound = 0.0;
  for (const Vec3& v : mesh.vertices) bound = std::max(bound, v.cwiseAbs().maxCoeff());
  const double margin = std::ldexp(bound, -32);
  std::vector<float, detail::DefaultInitAllocator<float>> rounded(6 * mesh.vertices.size());
  inHalves(parallel, mesh.vertices.size(), [&](std::size_t begin, std::size_t end) {
    for (std::size_t v = begin; v < end; ++v)
      for (int k = 0; k < 3; ++k) {
        rounded[6 * v + k] = roundDown(mesh.vertices[v][k] - margin);
        rounded[6 * v + 3 + k] = roundUp(mesh.vertices[v][k] + margin);
      }
  });
  return rounded;
}

// The build's record of one triangle: the box of its corners' rounded coordinates (see roundedVertices).
Prim primOf(const float* rounded, const Triangle& corners, std::uint32_t index) {
  Box box;
  for (int v = 0; v < 3; ++v) {
    const float* r = rounded + 6 * std::size_t(corners[v]);
    for (int k = 0; k < 3; ++k) {
      box.lo[k] = std::min(box.lo[k], r[k]);
      box.hi[k] = std::max(box.hi[k], r[3 + k]);
    }
  }
  Prim p;
  for (int k = 0; k < 3; ++k) {
    p.lo[k] = box.lo[k];
    p.hi[k] = box.hi[k];
  }
  p.zero = 0.0f;
  p.index = index;
  return p;
}

// The build's records of every triangle, in the mesh's order.
PrimArray primsOf(const TriangleMesh& mesh, bool parallel) {
  const auto rounded = roundedVertices(mesh, parallel);
  PrimArray prims(mesh.size());
  inHalves(parallel, prims.size(), [&](std::size_t begin, std::size_t end) {
    for (std::size_t t = begin; t < end; ++t)
      prims[t] = primOf(rounded.data(), mesh.triangles[t], static_cast<std::uint32_t>(t));
  });
  return prims;
}

}  // namespace

TriangleBvh::TriangleBvh(const TriangleMesh& mesh, int leafSize, unsigned threads) : mesh_(mesh) {
  const std::size_t n = mesh.size();
  if (n == 0) return;
  const bool parallel = threads >= 2 && n >= 4096;
  PrimArray prims = primsOf(mesh, parallel);
  buildNodes(mesh, prims, leafSize, parallel, nodes_);
  for (int k = 0; k < 3; ++k)
    sceneBound_ = std::max({sceneBound_, std::fabs(double(nodes_[0].lo[k])), std::fabs(double(nodes_[0].hi[k]))});
  order_.resize(n);
  corners_.resize(n);
  inHalves(parallel, n, [&](std::size_t begin, std::size_t end) {
    for (std::size_t i = begin; i < end; ++i) {
      order_[i] = prims[i].index;
      corners_[i] = mesh.triangles[prims[i].index];
    }
  });
}

namespace detail {

PacketWalk::PacketWalk(const TriangleBvh& bvh, const Vec3* origins, const Vec3* dirs, int count, const PacketCull& cull)
    : bvh_(bvh), cull_(cull), kernels_(packetKernels()), triangle_(kernels_.triangle) {
  setRays(origins, dirs, count);
  inFloat_ = kernels_.childrenFloat != nullptr &&
             float_.set(&o_[0][0], &dir_[0][0], &inv_[0][0], count, bvh.sceneBound_, cull);
  pushRoot(count);
}

inline void PacketWalk::setRays(const Vec3* origins, const Vec3* dirs, int count) {
  for (int r = 0; r < kRays; ++r)
    for (int k = 0; k < 3; ++k) {
      const int s = r < count ? r : 0;
      const double d = dirs[s][k] != 0.0 ? dirs[s][k] : std::copysign(1e-300, dirs[s][k]);
      inv_[k][r] = 1.0 / d;
      o_[k][r] = origins[s][k];
      dir_[k][r] = dirs[s][k];
    }
}

// The root holds the rays that meet its box; its hits mark matches no count, so the cull is applied when
// it is popped, with every entry at 0.
inline void PacketWalk::pushRoot(int count) {
  Item& root = stack_[0];
  root.node = 0;
  root.mask = packetBoxBaseline(bvh_.nodes_[0], &o_[0][0], &inv_[0][0], root.t) & ((1u << count) - 1);
  root.hits = ~std::uint64_t{0};
  std::fill(root.t, root.t + kRays, 0.0);
  top_ = root.mask ? 1 : 0;
}

const TriangleBvh::Node* PacketWalk::nextLeaf() {
  while (top_ > 0) {
    const Item item = stack_[--top_];  // a copy: reading the slot in place while pushing is slower
    const TriangleBvh::Node& node = bvh_.nodes_[item.node];
    const unsigned mask = item.hits == hits_ ? item.mask : packetKept(cull_, node, item.t, item.mask);
    if (mask == 0) continue;
    if (node.count > 0) {
      leafMask_ = mask;
      return &node;
    }
    pushChildren(item.node, node, mask);
  }
  return nullptr;
}

// Tests both children of the inner node at index against the rays of mask in one kernel call and pushes
// those some ray enters.
inline void PacketWalk::pushChildren(std::uint32_t index, const TriangleBvh::Node& node, unsigned mask) {
  Item l, r;
  l.node = index + 1;
  r.node = node.first;
  l.hits = r.hits = hits_;
  const TriangleBvh::Node* const child[2] = {&bvh_.nodes_[l.node], &bvh_.nodes_[r.node]};
  double* const entry[2] = {l.t, r.t};
  unsigned masks[2];
  if (inFloat_)
    kernels_.childrenFloat(child, float_, mask, entry, masks);
  else
    kernels_.children(child, &o_[0][0], &inv_[0][0], cull_, mask, entry, masks);
  l.mask = masks[0];
  r.mask = masks[1];
  // The order forEachRayHit takes for the first ray that meets both children (nearer first, a child
  // containing the origin last); the other rays follow it.
  const unsigned both = l.mask & r.mask;
  const bool left = both == 0 || TriangleBvh::leftFirst(l.t[__builtin_ctz(both)], r.t[__builtin_ctz(both)]);
  const Item& first = left ? l : r;
  const Item& second = left ? r : l;
  if (second.mask) stack_[top_++] = second;
  if (first.mask) stack_[top_++] = first;
}

}  // namespace detail
}  // namespace clod_haptics
