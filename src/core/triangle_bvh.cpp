#include "clod_haptics/core/triangle_bvh.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>

#if defined(__x86_64__)
#include <immintrin.h>
#endif

#include "parallel.h"

namespace clod_haptics {
namespace {

// Surface area heuristic over kBins bins of the centroids along one axis: the split that minimises
// area(left) * count(left) + area(right) * count(right), the expected cost of a ray through the node.
constexpr int kBins = 16;
// Deeper than this the median split is used, which halves every range: the depth stays below
// kMaxSahDepth + 32, within the traversal's stack (one pending entry per level).
constexpr int kMaxSahDepth = 64;

// The next float below / above f (f not NaN), by its bit pattern: nextafterf is a library call, and
// this runs six times per triangle.
float below(float f) {
  if (f == 0.0f) return -std::numeric_limits<float>::denorm_min();
  std::uint32_t bits;
  std::memcpy(&bits, &f, sizeof bits);
  bits = f > 0.0f ? bits - 1 : bits + 1;
  std::memcpy(&f, &bits, sizeof f);
  return f;
}
float above(float f) { return -below(-f); }
// x rounded to float downward / upward.
float down(double x) {
  const float f = static_cast<float>(x);
  return static_cast<double>(f) > x ? below(f) : f;
}
float up(double x) {
  const float f = static_cast<float>(x);
  return static_cast<double>(f) < x ? above(f) : f;
}

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

// What the build keeps per triangle: its box, its box centre (the binning key) and its index, 40 bytes.
// The build partitions these records themselves, so every pass over a node's range reads memory in
// order instead of gathering through the index array.
struct Prim {
  Box box;
  float centre[3];
  std::uint32_t index;
};

struct Build {
  const TriangleMesh& mesh;
  std::vector<Prim>& prims;
  int leafSize;

  // Partitions order[begin, end) and returns the split point; falls back to the median when the
  // centres coincide along the axis or the heuristic leaves one side empty.
  std::uint32_t split(std::uint32_t begin, std::uint32_t end, const Box& cbox, int depth) const {
    int axis = 0;
    for (int k = 1; k < 3; ++k)
      if (double(cbox.hi[k]) - cbox.lo[k] > double(cbox.hi[axis]) - cbox.lo[axis]) axis = k;
    const double lo = cbox.lo[axis], extent = double(cbox.hi[axis]) - cbox.lo[axis];
    auto median = [&]() {
      const std::uint32_t mid = begin + (end - begin) / 2;
      std::nth_element(prims.begin() + begin, prims.begin() + mid, prims.begin() + end,
                       [&](const Prim& a, const Prim& b) { return a.centre[axis] < b.centre[axis]; });
      return mid;
    };
    if (!(extent > 0.0) || !std::isfinite(extent) || end - begin < 16 || depth >= kMaxSahDepth) return median();
    const double scale = kBins / extent;
    auto binOf = [&](const Prim& p) { return std::min(kBins - 1, static_cast<int>((p.centre[axis] - lo) * scale)); };
    Box bins[kBins];
    std::uint32_t counts[kBins] = {};
    for (std::uint32_t i = begin; i < end; ++i) {
      const int b = binOf(prims[i]);
      bins[b].extend(prims[i].box);
      ++counts[b];
    }
    double rightArea[kBins];
    std::uint32_t rightCount[kBins];
    Box acc;
    std::uint32_t n = 0;
    for (int i = kBins - 1; i > 0; --i) {
      acc.extend(bins[i]);
      n += counts[i];
      rightArea[i] = acc.halfArea();
      rightCount[i] = n;
    }
    acc = Box();
    n = 0;
    double bestCost = std::numeric_limits<double>::infinity();
    int bestSplit = -1;
    for (int i = 1; i < kBins; ++i) {
      acc.extend(bins[i - 1]);
      n += counts[i - 1];
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
    return static_cast<std::uint32_t>(mid - prims.begin());
  }

  Box centreBox(std::uint32_t begin, std::uint32_t end) const {
    Box c;
    for (std::uint32_t i = begin; i < end; ++i) c.extend(prims[i].centre);
    return c;
  }

  // Builds order[begin, end) into nodes (indices local to nodes, left child next to its parent) and
  // returns the node's index; bounds are filled bottom up from the leaves.
  std::uint32_t build(std::vector<TriangleBvh::Node>& nodes, std::uint32_t begin, std::uint32_t end, int depth) const {
    const std::uint32_t self = static_cast<std::uint32_t>(nodes.size());
    nodes.emplace_back();
    if (end - begin <= static_cast<std::uint32_t>(leafSize)) {
      leaf(nodes[self], begin, end);
      return self;
    }
    const std::uint32_t mid = split(begin, end, centreBox(begin, end), depth);
    const std::uint32_t left = build(nodes, begin, mid, depth + 1);
    const std::uint32_t right = build(nodes, mid, end, depth + 1);
    join(nodes[self], nodes[left], nodes[right], right);
    return self;
  }

  void leaf(TriangleBvh::Node& node, std::uint32_t begin, std::uint32_t end) const {
    Box box;
    double nlo[3] = {2, 2, 2}, nhi[3] = {-2, -2, -2};
    for (std::uint32_t i = begin; i < end; ++i) {
      box.extend(prims[i].box);
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
void buildNodes(const TriangleMesh& mesh, std::vector<Prim>& prims, int leafSize, bool parallel,
                std::vector<TriangleBvh::Node>& nodes) {
  using Node = TriangleBvh::Node;
  const std::size_t n = prims.size();
  const Build b{mesh, prims, std::max(1, leafSize)};
  const std::uint32_t count = static_cast<std::uint32_t>(n);
  if (!parallel) {
    // At most 2n - 1 nodes: reserving that never reallocates, and untouched capacity is never resident.
    nodes.reserve(2 * n);
    b.build(nodes, 0, count, 0);
    return;
  }
  // The two top levels' splits first (the second level's two on two threads), then the up to four
  // subtrees below them built into arrays of their own by two threads, each taking the largest one
  // left, then appended in the serial build's depth-first order with their node indices shifted: the
  // same tree as the serial build, node for node, with the work balanced however uneven the splits.
  struct Task {
    std::uint32_t begin, end;
    int depth;
    std::vector<Node> nodes;
  };
  const std::uint32_t leaf = static_cast<std::uint32_t>(b.leafSize);
  const std::uint32_t mid = b.split(0, count, b.centreBox(0, count), 0);
  const std::uint32_t halves[3] = {0, mid, count};
  std::uint32_t quarter[2];  // each half's split, or its end when the half is a leaf
  auto splitHalf = [&](int h) {
    const std::uint32_t begin = halves[h], end = halves[h + 1];
    quarter[h] = end - begin > leaf ? b.split(begin, end, b.centreBox(begin, end), 1) : end;
  };
  detail::runParallel(2, [&](unsigned h) { splitHalf(static_cast<int>(h)); });
  std::vector<Task> tasks;
  tasks.reserve(4);
  for (int h = 0; h < 2; ++h) {
    if (quarter[h] == halves[h + 1]) {
      tasks.push_back({halves[h], halves[h + 1], 1, {}});
    } else {
      tasks.push_back({halves[h], quarter[h], 2, {}});
      tasks.push_back({quarter[h], halves[h + 1], 2, {}});
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
      b.build(task.nodes, task.begin, task.end, task.depth);
    }
  };
  detail::runParallel(2, [&](unsigned) { work(); });
  // The subtrees' places in the serial build's depth-first order: the root, then per half its own node
  // (when it was split) and its subtrees. They are copied there, their node indices shifted, in parallel.
  std::vector<std::uint32_t> base(tasks.size());
  std::uint32_t half[2];
  std::uint32_t size = 1;  // the root
  std::size_t t = 0;
  for (int h = 0; h < 2; ++h) {
    half[h] = size;
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
      std::vector<Node>().swap(task.nodes);
    }
  });
  t = 0;
  for (int h = 0; h < 2; ++h) {
    if (quarter[h] == halves[h + 1]) {
      ++t;
      continue;
    }
    Build::join(nodes[half[h]], nodes[base[t]], nodes[base[t + 1]], base[t + 1]);
    t += 2;
  }
  Build::join(nodes[0], nodes[half[0]], nodes[half[1]], half[1]);
}

}  // namespace

TriangleBvh::TriangleBvh(const TriangleMesh& mesh, int leafSize, unsigned threads) : mesh_(mesh) {
  const std::size_t n = mesh.size();
  if (n == 0) return;
  // Every vertex rounded outward once (a vertex is shared by about six triangles), then each
  // triangle's box from its three corners.
  const std::size_t nv = mesh.vertices.size();
  std::vector<float> rounded(6 * nv);  // per vertex: down x y z, up x y z
  std::vector<Prim> prims(n);
  auto roundVertices = [&](std::size_t begin, std::size_t end) {
    for (std::size_t v = begin; v < end; ++v)
      for (int k = 0; k < 3; ++k) {
        rounded[6 * v + k] = down(mesh.vertices[v][k]);
        rounded[6 * v + 3 + k] = up(mesh.vertices[v][k]);
      }
  };
  auto fill = [&](std::size_t begin, std::size_t end) {
    for (std::size_t t = begin; t < end; ++t) {
      Prim& p = prims[t];
      for (int v = 0; v < 3; ++v) {
        const float* r = &rounded[6 * std::size_t(mesh.triangles[t][v])];
        for (int k = 0; k < 3; ++k) {
          p.box.lo[k] = std::min(p.box.lo[k], r[k]);
          p.box.hi[k] = std::max(p.box.hi[k], r[3 + k]);
        }
      }
      for (int k = 0; k < 3; ++k) p.centre[k] = 0.5f * p.box.lo[k] + 0.5f * p.box.hi[k];
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
  std::vector<float>().swap(rounded);
  buildNodes(mesh, prims, leafSize, parallel, nodes_);
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

void usePacketAvx2(bool on) { avx2Off = !on; }

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
bool packetAvx2() {
  static const bool has = __builtin_cpu_supports("avx2");
  return has && !avx2Off.load(std::memory_order_relaxed);
}

__attribute__((target("avx2"))) void packetEnterAvx2(const float* const lo[2], const float* const hi[2],
                                                    const double* o, const double* inv, double* const entry[2],
                                                    unsigned mask[2]) {
  constexpr int W = TriangleBvh::kPacket;
  static_assert(W == 16, "four registers of four rays");
  for (int c = 0; c < 2; ++c) {
    unsigned m = 0;
    for (int h = 0; h < W; h += 4) {
      __m256d t0 = _mm256_setzero_pd(), t1 = _mm256_set1_pd(std::numeric_limits<double>::infinity());
      for (int k = 0; k < 3; ++k) {
        const __m256d ok = _mm256_loadu_pd(o + k * W + h), ik = _mm256_loadu_pd(inv + k * W + h);
        const __m256d a = _mm256_mul_pd(_mm256_sub_pd(_mm256_set1_pd(lo[c][k]), ok), ik);
        const __m256d b = _mm256_mul_pd(_mm256_sub_pd(_mm256_set1_pd(hi[c][k]), ok), ik);
        t0 = _mm256_max_pd(_mm256_min_pd(a, b), t0);
        t1 = _mm256_min_pd(_mm256_max_pd(a, b), t1);
      }
      _mm256_storeu_pd(entry[c] + h, t0);
      m |= static_cast<unsigned>(_mm256_movemask_pd(_mm256_cmp_pd(t0, t1, _CMP_LE_OQ))) << h;
    }
    mask[c] = m;
  }
}
#else
bool packetAvx2() { return false; }
void packetEnterAvx2(const float* const*, const float* const*, const double*, const double*, double* const*, unsigned*) {}
#endif

}  // namespace detail
}  // namespace clod_haptics
