#include "clod_haptics/core/triangle_bvh.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>

#if defined(__x86_64__)
#include <immintrin.h>
#endif

#include "float_rounding.h"
#include "parallel.h"

namespace clod_haptics {
namespace {

// Surface area heuristic over kBins bins of the centroids along one axis: the split that minimises
// area(left) * count(left) + area(right) * count(right), the expected cost of a ray through the node.
constexpr int kBins = 16;
// Deeper than this the median split is used, which halves every range: the depth stays below
// kMaxSahDepth + 32, within the traversal's stack (one pending entry per level).
constexpr int kMaxSahDepth = 64;

using detail::roundDown;
using detail::roundUp;

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

// Four floats of which the build uses three; the same values with SSE or without.
#if defined(__SSE2__)
using F4 = __m128;
F4 loadLo(const Prim& p) { return _mm_load_ps(p.lo); }
F4 loadHi(const Prim& p) {  // the index's bits cleared
  return _mm_and_ps(_mm_load_ps(p.hi), _mm_castsi128_ps(_mm_set_epi32(0, -1, -1, -1)));
}
F4 splat4(float f) { return _mm_set1_ps(f); }
F4 min4(F4 a, F4 b) { return _mm_min_ps(a, b); }
F4 max4(F4 a, F4 b) { return _mm_max_ps(a, b); }
F4 centre4(F4 lo, F4 hi) { return _mm_add_ps(_mm_mul_ps(_mm_set1_ps(0.5f), lo), _mm_mul_ps(_mm_set1_ps(0.5f), hi)); }
void store4(float* out, F4 a) { _mm_storeu_ps(out, a); }
#else
struct F4 {
  float v[4];
};
F4 loadLo(const Prim& p) { return {{p.lo[0], p.lo[1], p.lo[2], 0.0f}}; }
F4 loadHi(const Prim& p) { return {{p.hi[0], p.hi[1], p.hi[2], 0.0f}}; }
F4 splat4(float f) { return {{f, f, f, f}}; }
F4 min4(F4 a, F4 b) { return {{a.v[0] < b.v[0] ? a.v[0] : b.v[0], a.v[1] < b.v[1] ? a.v[1] : b.v[1], a.v[2] < b.v[2] ? a.v[2] : b.v[2], 0.0f}}; }
F4 max4(F4 a, F4 b) { return {{a.v[0] > b.v[0] ? a.v[0] : b.v[0], a.v[1] > b.v[1] ? a.v[1] : b.v[1], a.v[2] > b.v[2] ? a.v[2] : b.v[2], 0.0f}}; }
F4 centre4(F4 lo, F4 hi) {
  F4 c;
  for (int k = 0; k < 4; ++k) c.v[k] = 0.5f * lo.v[k] + 0.5f * hi.v[k];
  return c;
}
void store4(float* out, F4 a) { std::memcpy(out, a.v, sizeof a.v); }
#endif

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
    const double lo = cbox.lo[axis], extent = double(cbox.hi[axis]) - cbox.lo[axis];
    auto median = [&]() {
      const std::uint32_t mid = begin + (end - begin) / 2;
      std::nth_element(prims.begin() + begin, prims.begin() + mid, prims.begin() + end,
                       [&](const Prim& a, const Prim& b) { return centreOf(a, axis) < centreOf(b, axis); });
      child[0] = centreBox(begin, mid);
      child[1] = centreBox(mid, end);
      return mid;
    };
    if (!(extent > 0.0) || !std::isfinite(extent) || end - begin < 16 || depth >= kMaxSahDepth) return median();
    const double scale = kBins / extent;
    auto binOf = [&](const Prim& p) { return std::min(kBins - 1, static_cast<int>((centreOf(p, axis) - lo) * scale)); };
    Bin bins[kBins];
    for (std::uint32_t i = begin; i < end; ++i) {
      const Prim& p = prims[i];
      Bin& bin = bins[binOf(p)];
      const F4 pl = loadLo(p), ph = loadHi(p), c = centre4(pl, ph);
      bin.lo = min4(bin.lo, pl);
      bin.hi = max4(bin.hi, ph);
      bin.clo = min4(bin.clo, c);
      bin.chi = max4(bin.chi, c);
      ++bin.count;
    }
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
    if (bestSplit < 0) return median();
    const auto mid = std::partition(prims.begin() + begin, prims.begin() + end,
                                    [&](const Prim& p) { return binOf(p) < bestSplit; });
    for (int side = 0; side < 2; ++side) {
      child[side] = Box();
      for (int i = side ? bestSplit : 0; i < (side ? kBins : bestSplit); ++i)
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

// Builds the nodes over prims (permuting them into leaf order).
void buildNodes(const TriangleMesh& mesh, PrimArray& prims, int leafSize, bool parallel,
                TriangleBvh::NodeArray& nodes) {
  using Node = TriangleBvh::Node;
  const std::size_t n = prims.size();
  const Build b{mesh, prims, std::max(1, leafSize)};
  const std::uint32_t count = static_cast<std::uint32_t>(n);
  if (!parallel) {
    // At most 2n - 1 nodes: reserving that never reallocates, and untouched capacity is never resident.
    nodes.reserve(2 * n);
    b.build(nodes, 0, count, b.centreBox(0, count), 0);
    return;
  }
  // The two top levels' splits first (the second level's two on two threads), then the up to four
  // subtrees below them built into arrays of their own by two threads, each taking the largest one
  // left, then appended in the serial build's depth-first order with their node indices shifted: the
  // same tree as the serial build, node for node, with the work balanced however uneven the splits.
  struct Task {
    std::uint32_t begin, end;
    Box cbox;
    int depth;
    TriangleBvh::NodeArray nodes;
  };
  const std::uint32_t leaf = static_cast<std::uint32_t>(b.leafSize);
  Box half[2];  // centre bounds of each half
  const std::uint32_t mid = b.split(0, count, b.centreBox(0, count), 0, half);
  const std::uint32_t halves[3] = {0, mid, count};
  std::uint32_t quarter[2];  // each half's split, or its end when the half is a leaf
  Box quarters[2][2];
  auto splitHalf = [&](int h) {
    const std::uint32_t begin = halves[h], end = halves[h + 1];
    quarter[h] = end - begin > leaf ? b.split(begin, end, half[h], 1, quarters[h]) : end;
  };
  detail::runParallel(2, [&](unsigned h) { splitHalf(static_cast<int>(h)); });
  std::vector<Task> tasks;
  tasks.reserve(4);
  for (int h = 0; h < 2; ++h) {
    if (quarter[h] == halves[h + 1]) {
      tasks.push_back({halves[h], halves[h + 1], half[h], 1, {}});
    } else {
      tasks.push_back({halves[h], quarter[h], quarters[h][0], 2, {}});
      tasks.push_back({quarter[h], halves[h + 1], quarters[h][1], 2, {}});
    }
  }
  std::vector<std::size_t> bySize(tasks.size());
  for (std::size_t i = 0; i < bySize.size(); ++i) bySize[i] = i;
  std::sort(bySize.begin(), bySize.end(), [&](std::size_t x, std::size_t y) {
    return tasks[x].end - tasks[x].begin > tasks[y].end - tasks[y].begin;
  });
  std::atomic<std::size_t> next{0};
  auto work = [&]() {
    for (std::size_t i; (i = next.fetch_add(1)) < bySize.size();) {
      Task& task = tasks[bySize[i]];
      task.nodes.reserve(2 * std::size_t(task.end - task.begin));
      b.build(task.nodes, task.begin, task.end, task.cbox, task.depth);
    }
  };
  detail::runParallel(2, [&](unsigned) { work(); });
  // The subtrees' places in the serial build's depth-first order: the root, then per half its own node
  // (when it was split) and its subtrees. They are copied there, their node indices shifted, in parallel.
  std::vector<std::uint32_t> base(tasks.size());
  std::uint32_t halfNode[2];
  std::uint32_t size = 1;  // the root
  std::size_t t = 0;
  for (int h = 0; h < 2; ++h) {
    halfNode[h] = size;
    if (quarter[h] != halves[h + 1]) ++size;  // the half's own node
    for (const std::size_t end = t + (quarter[h] == halves[h + 1] ? 1 : 2); t < end; ++t) {
      base[t] = size;
      size += static_cast<std::uint32_t>(tasks[t].nodes.size());
    }
  }
  nodes.resize(size);
  std::atomic<std::size_t> nextCopy{0};
  detail::runParallel(2, [&](unsigned) {
    for (std::size_t i; (i = nextCopy.fetch_add(1)) < bySize.size();) {
      Task& task = tasks[bySize[i]];
      const std::uint32_t shift = base[bySize[i]];
      Node* out = nodes.data() + shift;
      for (const Node& node : task.nodes) {
        *out = node;
        if (node.count == 0) out->first += shift;
        ++out;
      }
      TriangleBvh::NodeArray().swap(task.nodes);
    }
  });
  t = 0;
  for (int h = 0; h < 2; ++h) {
    if (quarter[h] == halves[h + 1]) {
      ++t;
      continue;
    }
    Build::join(nodes[halfNode[h]], nodes[base[t]], nodes[base[t + 1]], base[t + 1]);
    t += 2;
  }
  Build::join(nodes[0], nodes[halfNode[0]], nodes[halfNode[1]], halfNode[1]);
}

}  // namespace

TriangleBvh::TriangleBvh(const TriangleMesh& mesh, int leafSize, unsigned threads) : mesh_(mesh) {
  const std::size_t n = mesh.size();
  if (n == 0) return;
  // Every vertex rounded outward once (a vertex is shared by about six triangles), then each
  // triangle's box from its three corners. The boxes are widened by 2^-32 of the largest coordinate
  // first: the slab tests (in double) and rayTriangle round, so without it a ray through a box's face,
  // edge or corner -- a ray aimed at a vertex, a coordinate that is a float already -- could miss the box
  // of a triangle that rayTriangle says it hits.
  const std::size_t nv = mesh.vertices.size();
  double bound = 0.0;
  for (const Vec3& v : mesh.vertices) bound = std::max(bound, v.cwiseAbs().maxCoeff());
  const double margin = std::ldexp(bound, -32);
  std::vector<float, detail::DefaultInitAllocator<float>> rounded(6 * nv);  // per vertex: down x y z, up x y z
  PrimArray prims(n);
  auto roundVertices = [&](std::size_t begin, std::size_t end) {
    for (std::size_t v = begin; v < end; ++v)
      for (int k = 0; k < 3; ++k) {
        rounded[6 * v + k] = roundDown(mesh.vertices[v][k] - margin);
        rounded[6 * v + 3 + k] = roundUp(mesh.vertices[v][k] + margin);
      }
  };
  auto fill = [&](std::size_t begin, std::size_t end) {
    for (std::size_t t = begin; t < end; ++t) {
      Prim& p = prims[t];
      Box box;
      for (int v = 0; v < 3; ++v) {
        const float* r = &rounded[6 * std::size_t(mesh.triangles[t][v])];
        for (int k = 0; k < 3; ++k) {
          box.lo[k] = std::min(box.lo[k], r[k]);
          box.hi[k] = std::max(box.hi[k], r[3 + k]);
        }
      }
      for (int k = 0; k < 3; ++k) {
        p.lo[k] = box.lo[k];
        p.hi[k] = box.hi[k];
      }
      p.zero = 0.0f;
      p.index = static_cast<std::uint32_t>(t);
    }
  };
  const bool parallel = threads >= 2 && n >= 4096;
  if (parallel) {
    detail::runParallel(2, [&](unsigned h) { h ? roundVertices(nv / 2, nv) : roundVertices(0, nv / 2); });
    detail::runParallel(2, [&](unsigned h) { h ? fill(n / 2, n) : fill(0, n / 2); });
  } else {
    roundVertices(0, nv);
    fill(0, n);
  }
  decltype(rounded)().swap(rounded);
  buildNodes(mesh, prims, leafSize, parallel, nodes_);
  if (!nodes_.empty())
    for (int k = 0; k < 3; ++k)
      sceneBound_ = std::max({sceneBound_, std::fabs(double(nodes_[0].lo[k])), std::fabs(double(nodes_[0].hi[k]))});
  order_.resize(n);
  corners_.resize(n);
  auto leafOrder = [&](std::size_t begin, std::size_t end) {
    for (std::size_t i = begin; i < end; ++i) {
      order_[i] = prims[i].index;
      corners_[i] = mesh.triangles[prims[i].index];
    }
  };
  if (parallel)
    detail::runParallel(2, [&](unsigned h) { h ? leafOrder(n / 2, n) : leafOrder(0, n / 2); });
  else
    leafOrder(0, n);
}

namespace detail {

namespace {
std::atomic<bool> avx2Off{false};

}  // namespace

// Why the float test keeps every node the double one keeps. With B = sceneBound + the largest origin
// coordinate (both under 2^30) and every box widened by w = 2^-18 B on each side, a slab's numerator
// (lo - w) - o in float is below lo - o by at least w/4 after the roundings of o, lo - w and the
// difference (each at most 2^-24 B), and its product with the inverse direction (rounded once more, an
// inverse between 2^-30 and 2^30) stays on the far side of the double product: the relative error
// 2^-23 |lo - o| is under w/4. So every near distance in float is at most the double one and every far
// distance at least it, entry <= exit holds whenever it holds in double, and the entry is a lower
// bound. A direction component under 2^-30 (or zero, which the double test makes 1e-300) gets the
// inverse +-2^120: the ray is then inside that slab in float whenever the double test can enter the
// slab before the ray leaves the box along its largest component (at least 1/4, so the exit is within
// 4 B) -- the double entry through that slab is at least 2^30 times the gap, the float gap is below
// zero for any gap under w/4 -- and an exit through it is beyond every other exit. The normals' lower
// bound in float differs from the double sum by at most 2^-22 (|m0| + |m1| + |m2|) (components of
// normals at most 1): slack is twice that plus PacketCull::kSlack, and the thresholds round up.
void PacketFloat::setCull(const PacketCull& cull, int r) {
  double sum = 0.0;
  for (int k = 0; k < 3; ++k) {
    axis[k][r] = static_cast<float>(cull.axis[k][r]);
    sum += std::fabs(cull.axis[k][r]);
  }
  slack[r] = roundUp(sum * 0x1p-21 + 2.0 * PacketCull::kSlack);
  cap[r] = roundUp(cull.cap[r]);
  below[r] = roundUp(cull.below[r]);
  nearBelow[r] = roundUp(cull.nearBelow[r]);
  within[r] = roundUp(cull.within[r]);
}

bool PacketFloat::set(const double* origins, const double* dirs, const double* inverse, int count,
                      double sceneBound, const PacketCull& cull) {
  constexpr int W = PacketCull::kRays;
  constexpr double kLimit = 1073741824.0;  // 2^30
  double bound = sceneBound;
  for (int r = 0; r < W; ++r) {
    double largest = 0.0;
    for (int k = 0; k < 3; ++k) {
      bound = std::max(bound, std::fabs(origins[k * W + r]));
      largest = std::max(largest, std::fabs(dirs[k * W + r]));
    }
    // NaN fails every test here
    if (!(largest >= 0.25 && largest <= kLimit)) return false;
  }
  if (!(bound >= 1e-18 && bound <= kLimit)) return false;  // the widening stays a normal float
  const double w = std::ldexp(bound, -18);
  widen = roundUp(w);
  for (int k = 0; k < 3; ++k)
    for (int r = 0; r < W; ++r) {
      o[k][r] = static_cast<float>(origins[k * W + r]);
      const double d = dirs[k * W + r];
      inv[k][r] = std::fabs(d) >= 1.0 / kLimit ? static_cast<float>(inverse[k * W + r])
                                                : std::copysign(0x1p120f, float(inverse[k * W + r]));
    }
  for (int r = 0; r < W; ++r) setCull(cull, r < count ? r : 0);
  return true;
}

void usePacketAvx2(bool on) { avx2Off = !on; }

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
bool packetAvx2() {
  static const bool has = __builtin_cpu_supports("avx2");
  return has && !avx2Off.load(std::memory_order_relaxed);
}

namespace {
// The lanes that meet the box (entry t0 <= exit t1) and pass PacketCull::keeps (lower: the normals' lower
// bound less the slack), four doubles or eight floats at a time: the rule once for both precisions.
#define CLOD_AVX2 __attribute__((target("avx2"))) inline
CLOD_AVX2 __m256d lessThan(__m256d a, __m256d b) { return _mm256_cmp_pd(a, b, _CMP_LT_OQ); }
CLOD_AVX2 __m256 lessThan(__m256 a, __m256 b) { return _mm256_cmp_ps(a, b, _CMP_LT_OQ); }
CLOD_AVX2 __m256d lessEqual(__m256d a, __m256d b) { return _mm256_cmp_pd(a, b, _CMP_LE_OQ); }
CLOD_AVX2 __m256 lessEqual(__m256 a, __m256 b) { return _mm256_cmp_ps(a, b, _CMP_LE_OQ); }
CLOD_AVX2 __m256d both(__m256d a, __m256d b) { return _mm256_and_pd(a, b); }
CLOD_AVX2 __m256 both(__m256 a, __m256 b) { return _mm256_and_ps(a, b); }
CLOD_AVX2 __m256d either(__m256d a, __m256d b) { return _mm256_or_pd(a, b); }
CLOD_AVX2 __m256 either(__m256 a, __m256 b) { return _mm256_or_ps(a, b); }
CLOD_AVX2 unsigned bits(__m256d a) { return static_cast<unsigned>(_mm256_movemask_pd(a)); }
CLOD_AVX2 unsigned bits(__m256 a) { return static_cast<unsigned>(_mm256_movemask_ps(a)); }
template <class V>
CLOD_AVX2 unsigned keptBits(V lower, V t0, V t1, V cap, V below, V nearBelow, V within) {
  const V near = both(lessThan(lower, nearBelow), lessEqual(t0, within));
  return bits(both(lessEqual(t0, t1), both(lessThan(lower, cap), either(lessThan(lower, below), near))));
}
#undef CLOD_AVX2
}  // namespace

__attribute__((target("avx2"))) void packetChildrenAvx2(const float* const lo[2], const float* const hi[2],
                                                       const float* const nlo[2], const float* const nhi[2],
                                                       const double* o, const double* inv, const PacketCull& cull,
                                                       unsigned active, double* const entry[2], unsigned mask[2]) {
  constexpr int W = TriangleBvh::kPacket;
  static_assert(W == 16, "four registers of four rays");
  for (int c = 0; c < 2; ++c) {
    unsigned m = 0;
    for (int h = 0; h < W; h += 4) {
      if (!((active >> h) & 0xFu)) continue;  // the active rays of a packet are mostly neighbours
      // The box test as forEachRayHit's; the normals' lower bound as TriangleBvh::minDot's sum, in its
      // order (std::min(x, y) is min_pd(y, x)), less the slack; then PacketCull::keeps.
      __m256d t0 = _mm256_setzero_pd(), t1 = _mm256_set1_pd(std::numeric_limits<double>::infinity());
      __m256d lower = _mm256_setzero_pd();
      for (int k = 0; k < 3; ++k) {
        const __m256d ok = _mm256_loadu_pd(o + k * W + h), ik = _mm256_loadu_pd(inv + k * W + h);
        const __m256d a = _mm256_mul_pd(_mm256_sub_pd(_mm256_set1_pd(lo[c][k]), ok), ik);
        const __m256d b = _mm256_mul_pd(_mm256_sub_pd(_mm256_set1_pd(hi[c][k]), ok), ik);
        t0 = _mm256_max_pd(_mm256_min_pd(a, b), t0);
        t1 = _mm256_min_pd(_mm256_max_pd(a, b), t1);
        const __m256d mk = _mm256_load_pd(cull.axis[k] + h);
        const __m256d x = _mm256_mul_pd(mk, _mm256_set1_pd(nlo[c][k]));
        const __m256d y = _mm256_mul_pd(mk, _mm256_set1_pd(nhi[c][k]));
        lower = _mm256_add_pd(lower, _mm256_min_pd(y, x));
      }
      lower = _mm256_sub_pd(lower, _mm256_set1_pd(PacketCull::kSlack));
      _mm256_storeu_pd(entry[c] + h, t0);
      m |= keptBits(lower, t0, t1, _mm256_load_pd(cull.cap + h), _mm256_load_pd(cull.below + h),
                    _mm256_load_pd(cull.nearBelow + h), _mm256_load_pd(cull.within + h))
           << h;
    }
    mask[c] = m & active;
  }
}

__attribute__((target("avx2"))) void packetChildrenAvx2f(const float* const lo[2], const float* const hi[2],
                                                        const float* const nlo[2], const float* const nhi[2],
                                                        const PacketFloat& f, unsigned active,
                                                        double* const entry[2], unsigned mask[2]) {
  constexpr int W = TriangleBvh::kPacket;
  static_assert(W == 16, "two registers of eight rays");
  for (int c = 0; c < 2; ++c) {
    float wlo[3], whi[3];
    for (int k = 0; k < 3; ++k) {
      wlo[k] = lo[c][k] - f.widen;
      whi[k] = hi[c][k] + f.widen;
    }
    unsigned m = 0;
    for (int h = 0; h < W; h += 8) {
      if (!((active >> h) & 0xFFu)) continue;
      __m256 t0 = _mm256_setzero_ps(), t1 = _mm256_set1_ps(std::numeric_limits<float>::infinity());
      __m256 lower = _mm256_setzero_ps();
      for (int k = 0; k < 3; ++k) {
        const __m256 ok = _mm256_load_ps(f.o[k] + h), ik = _mm256_load_ps(f.inv[k] + h);
        const __m256 a = _mm256_mul_ps(_mm256_sub_ps(_mm256_set1_ps(wlo[k]), ok), ik);
        const __m256 b = _mm256_mul_ps(_mm256_sub_ps(_mm256_set1_ps(whi[k]), ok), ik);
        t0 = _mm256_max_ps(_mm256_min_ps(a, b), t0);
        t1 = _mm256_min_ps(_mm256_max_ps(a, b), t1);
        const __m256 mk = _mm256_load_ps(f.axis[k] + h);
        lower = _mm256_add_ps(lower, _mm256_min_ps(_mm256_mul_ps(mk, _mm256_set1_ps(nhi[c][k])),
                                                   _mm256_mul_ps(mk, _mm256_set1_ps(nlo[c][k]))));
      }
      lower = _mm256_sub_ps(lower, _mm256_load_ps(f.slack + h));
      _mm256_storeu_pd(entry[c] + h, _mm256_cvtps_pd(_mm256_castps256_ps128(t0)));
      _mm256_storeu_pd(entry[c] + h + 4, _mm256_cvtps_pd(_mm256_extractf128_ps(t0, 1)));
      m |= keptBits(lower, t0, t1, _mm256_load_ps(f.cap + h), _mm256_load_ps(f.below + h),
                    _mm256_load_ps(f.nearBelow + h), _mm256_load_ps(f.within + h))
           << h;
    }
    mask[c] = m & active;
  }
}

namespace {
// (x0 y0 + x1 y1) + x2 y2, Eigen's order for a 3-vector dot product.
__attribute__((target("avx2"))) inline __m256d dot3(__m256d x0, __m256d y0, __m256d x1, __m256d y1, __m256d x2,
                                                     __m256d y2) {
  return _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(x0, y0), _mm256_mul_pd(x1, y1)), _mm256_mul_pd(x2, y2));
}
}  // namespace

__attribute__((target("avx2"))) unsigned packetTriangleAvx2(const double* a, const double* b, const double* c,
                                                           const double* o, const double* d, unsigned active,
                                                           double* t) {
  constexpr int W = TriangleBvh::kPacket;
  static_assert(W == 16, "four registers of four rays");
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
    ok = _mm256_and_pd(ok, _mm256_and_pd(_mm256_cmp_pd(v, zero, _CMP_NLT_UQ),
                                         _mm256_cmp_pd(_mm256_add_pd(u, v), one, _CMP_NGT_UQ)));
    const __m256d tt = _mm256_mul_pd(dot3(e2x, qvx, e2y, qvy, e2z, qvz), inv);
    ok = _mm256_and_pd(ok, _mm256_cmp_pd(tt, zero, _CMP_GT_OQ));
    _mm256_store_pd(t + h, tt);
    m |= static_cast<unsigned>(_mm256_movemask_pd(ok)) << h;
  }
  return m & active;
}
#else
bool packetAvx2() { return false; }
void packetChildrenAvx2f(const float* const*, const float* const*, const float* const*, const float* const*,
                         const PacketFloat&, unsigned, double* const*, unsigned*) {}
unsigned packetTriangleAvx2(const double*, const double*, const double*, const double*, const double*, unsigned,
                            double*) {
  return 0;
}
void packetChildrenAvx2(const float* const*, const float* const*, const float* const*, const float* const*,
                        const double*, const double*, const PacketCull&, unsigned, double* const*, unsigned*) {}
#endif

}  // namespace detail
}  // namespace clod_haptics
