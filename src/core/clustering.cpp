#include "clod_haptics/core/clustering.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <numeric>
#include <string>

#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/tight_clustering.h"
#include "parallel.h"

namespace clod_haptics {
namespace {

// Union-find that several threads may unite in at once, lock-free: a root is linked by compare-and-swap,
// always the larger root under the smaller one, and find halves paths with plain stores (every pointer
// goes to a smaller index of the same tree, so a stale store is still a valid one). A component's root
// is therefore its smallest index whatever the order of the unions, which keeps the labelling (and so
// the whole result) independent of the number of threads.
class UnionFind {
 public:
  // The entries start unset: the caller sets every one (set) before any find.
  explicit UnionFind(std::size_t n) : parent_(new std::atomic<std::uint32_t>[n]) {}
  void set(std::uint32_t x, std::uint32_t parent) { parent_[x].store(parent, std::memory_order_relaxed); }
  std::uint32_t find(std::uint32_t x) {
    for (;;) {
      const std::uint32_t p = parent_[x].load(std::memory_order_relaxed);
      if (p == x) return x;
      const std::uint32_t g = parent_[p].load(std::memory_order_relaxed);
      if (g == p) return p;
      parent_[x].store(g, std::memory_order_relaxed);  // path halving
      x = g;
    }
  }
  void unite(std::uint32_t a, std::uint32_t b) {
    for (;;) {
      a = find(a);
      b = find(b);
      if (a == b) return;
      if (a < b) std::swap(a, b);
      std::uint32_t expected = a;  // a is still a root, or another thread linked it first: retry
      if (parent_[a].compare_exchange_weak(expected, b, std::memory_order_relaxed)) return;
    }
  }

 private:
  std::unique_ptr<std::atomic<std::uint32_t>[]> parent_;
};

struct CellKey {
  std::int64_t x, y, z;
  bool operator==(const CellKey& o) const { return x == o.x && y == o.y && z == o.z; }
};

std::uint64_t hashKey(const CellKey& k) {
  std::uint64_t h = static_cast<std::uint64_t>(k.x) * 0x9E3779B97F4A7C15ull;
  h ^= static_cast<std::uint64_t>(k.y) * 0xC2B2AE3D27D4EB4Full + (h << 6) + (h >> 2);
  h ^= static_cast<std::uint64_t>(k.z) * 0x165667B19E3779F9ull + (h << 6) + (h >> 2);
  return h ^ (h >> 29);
}

// Open-addressing table that numbers cells in the order they are first inserted. The slots hold only
// the cell number (4 bytes) and the keys live once in a dense array, so the table costs a few bytes per
// cell, not per point: the old table of (key, run, flag) slots sized for every point was the largest
// allocation of a build (up to 320 bytes per triangle, most of it page clearing).
class CellTable {
 public:
  static constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();

  explicit CellTable(std::size_t expectedCells) {
    std::size_t cap = 64;
    while (cap < 2 * expectedCells) cap <<= 1;
    slots_.assign(cap, kNone);
    mask_ = cap - 1;
    keys_.reserve(expectedCells);
  }
  // The number of key's cell, numbering it when new.
  std::uint32_t insert(const CellKey& key) {
    if (2 * (keys_.size() + 1) > slots_.size()) grow();
    std::size_t i = hashKey(key) & mask_;
    for (; slots_[i] != kNone; i = (i + 1) & mask_)
      if (keys_[slots_[i]] == key) return slots_[i];
    slots_[i] = static_cast<std::uint32_t>(keys_.size());
    keys_.push_back(key);
    return slots_[i];
  }
  // The number of key's cell, or kNone.
  std::uint32_t find(const CellKey& key) const {
    for (std::size_t i = hashKey(key) & mask_; slots_[i] != kNone; i = (i + 1) & mask_)
      if (keys_[slots_[i]] == key) return slots_[i];
    return kNone;
  }
  std::size_t size() const { return keys_.size(); }
  const CellKey& key(std::uint32_t cell) const { return keys_[cell]; }

 private:
  void grow() {
    std::vector<std::uint32_t> slots(2 * slots_.size(), kNone);
    const std::size_t mask = slots.size() - 1;
    for (std::uint32_t c = 0; c < keys_.size(); ++c) {
      std::size_t i = hashKey(keys_[c]) & mask;
      while (slots[i] != kNone) i = (i + 1) & mask;
      slots[i] = c;
    }
    slots_.swap(slots);
    mask_ = mask;
  }
  std::vector<std::uint32_t> slots_;
  std::vector<CellKey> keys_;
  std::size_t mask_ = 0;
};

// The domain check both strategies share; sizes labels and returns the number of points.
std::size_t prepare(const std::vector<Vec3>& points, double d, std::vector<std::uint32_t>& labels) {
  requireNonNegative(d, "clustering distance");
  labels.assign(points.size(), 0);
  return points.size();
}

// Integer cell of p for cells of side cell anchored at origin.
CellKey cellOf(const Vec3& p, const Vec3& origin, double cell) {
  const Vec3 q = (p - origin) / cell;
  return {static_cast<std::int64_t>(std::floor(q.x())), static_cast<std::int64_t>(std::floor(q.y())),
          static_cast<std::int64_t>(std::floor(q.z()))};
}

// Unites every pair of points closer than d (Euclidean, strict), touching each pair of cells once.
// Cells have side d / sqrt(3) (shrunk a little against rounding), so points of one cell are
// normally all closer than d: each is linked to the cell's first point after an exact check, and
// a point that fails it ("loose", only possible through rounding) is checked against every
// neighbour point itself. Two neighbouring cells already in one cluster are not tested; otherwise
// their extreme points are tried first, then the points of one cell near the other's bounds against
// those of the other near the first's bounds, until one link joins the two cells.
// Every union is backed by an exact distance test, so the result equals naive single-link, and as
// a partition it does not depend on the order of the tests: the passes split over `threads`
// threads (points in ranges, cells in chunks) and give the same result as one thread.
void linkCloserThan(const std::vector<Vec3>& points, double d, unsigned threads, UnionFind& uf) {
  const std::size_t n = points.size();
  std::vector<std::size_t> cut(threads + 1);  // thread t's points: [cut[t], cut[t + 1])
  for (unsigned t = 0; t <= threads; ++t) cut[t] = n * t / threads;
  std::vector<Eigen::AlignedBox3d> parts(threads);
  detail::runParallel(threads, [&](unsigned t) {
    Eigen::AlignedBox3d part;  // a local: the compiler keeps it in registers
    for (std::size_t i = cut[t]; i < cut[t + 1]; ++i) part.extend(points[i]);
    parts[t] = part;
  });
  Eigen::AlignedBox3d box = parts[0];
  for (unsigned t = 1; t < threads; ++t) box.extend(parts[t]);
  const double extent =
      std::max({box.sizes().maxCoeff(), box.min().cwiseAbs().maxCoeff(), box.max().cwiseAbs().maxCoeff()});
  // Never finer than 1e-12 of the extent: keeps cell coordinates far from integer overflow.
  const double cell = std::max(d / std::sqrt(3.0) * (1.0 - 1e-6), extent * 1e-12);
  const int reach = static_cast<int>(std::ceil(d / cell));  // 2 for the usual cell size, never more
  const Vec3 origin = box.min();

  // Find the cells (expected O(n)): each thread numbers the cells of its points in a table of its own
  // and counts them; the tables are merged into the first.
  std::vector<std::uint32_t> sorted(n);  // first the thread-local cell of each point, then the points by cell
  std::vector<CellTable> tables;
  tables.reserve(threads);
  for (unsigned t = 0; t < threads; ++t) tables.emplace_back(std::min<std::size_t>(cut[t + 1] - cut[t], 1024));
  std::vector<std::vector<std::uint32_t>> counts(threads);  // per thread and local cell: points, then fill start
  detail::runParallel(threads, [&](unsigned t) {
    CellTable& table = tables[t];
    std::vector<std::uint32_t>& count = counts[t];
    // The placement emits two centres per triangle in triangle order (one near it, one towards its
    // opposite), so a centre is usually in the cell of the centre two places back: tried before the table.
    CellKey recent[2] = {{-1, -1, -1}, {-1, -1, -1}};
    std::uint32_t recentCell[2] = {0, 0};
    for (std::size_t i = cut[t]; i < cut[t + 1]; ++i) {
      const CellKey key = cellOf(points[i], origin, cell);
      const int slot = static_cast<int>(i & 1);
      std::uint32_t c;
      if (key == recent[slot]) {
        c = recentCell[slot];
      } else {
        c = table.insert(key);
        recent[slot] = key;
        recentCell[slot] = c;
      }
      if (c == count.size()) count.push_back(0);
      ++count[c];
      sorted[i] = c;
    }
  });
  CellTable& table = tables[0];
  std::vector<std::vector<std::uint32_t>> global(threads);  // thread t's local cell -> merged cell (t >= 1)
  for (unsigned t = 1; t < threads; ++t) {
    global[t].resize(tables[t].size());
    for (std::uint32_t c = 0; c < tables[t].size(); ++c) global[t][c] = table.insert(tables[t].key(c));
    tables[t] = CellTable(0);  // merged: free it
  }
  const std::size_t cells = table.size();

  // Number the cells in the order of their packed coordinates when each coordinate (>= 0: the origin is
  // the bounds' corner) fits in kBits bits: a sweep over that order then finds the neighbours without
  // hashing, and the data of neighbouring cells lie close in every per-cell array. Otherwise (a
  // distance below ~1e-6 of the extent) the table's order, and neighbours by hashing.
  constexpr int kBits = 21;
  constexpr std::int64_t kLimit = std::int64_t{1} << kBits;
  auto pack = [](std::int64_t x, std::int64_t y, std::int64_t z) {
    return static_cast<std::uint64_t>(x) << (2 * kBits) | static_cast<std::uint64_t>(y) << kBits |
           static_cast<std::uint64_t>(z);
  };
  bool packable = true;
  for (std::size_t c = 0; c < cells && packable; ++c) {
    const CellKey& k = table.key(static_cast<std::uint32_t>(c));
    packable = k.x < kLimit && k.y < kLimit && k.z < kLimit;
  }
  std::vector<std::uint32_t> number(cells);  // table's cell -> the cell's number below (while bucketing)
  std::vector<std::uint64_t> packed;         // by number, when packable
  if (packable) {
    std::vector<std::pair<std::uint64_t, std::uint32_t>> order(cells);  // (packed coordinates, table's cell)
    for (std::size_t c = 0; c < cells; ++c) {
      const CellKey& k = table.key(static_cast<std::uint32_t>(c));
      order[c] = {pack(k.x, k.y, k.z), static_cast<std::uint32_t>(c)};
    }
    if (threads > 1) {
      const auto middle = order.begin() + static_cast<std::ptrdiff_t>(cells / 2);
      detail::runParallel(2, [&](unsigned t) { std::sort(t ? middle : order.begin(), t ? order.end() : middle); });
      std::inplace_merge(order.begin(), middle, order.end());
    } else {
      std::sort(order.begin(), order.end());
    }
    packed.resize(cells);
    for (std::size_t s = 0; s < cells; ++s) {
      packed[s] = order[s].first;
      number[order[s].second] = static_cast<std::uint32_t>(s);
    }
  } else {
    std::iota(number.begin(), number.end(), 0u);
  }

  // Bucket the points by cell: prefix sums give each thread where its points of a cell go, and the
  // threads fill in parallel. Each run keeps ascending point order (thread t's points precede thread
  // t+1's), so a run starts with its cell's smallest point index.
  auto numberOf = [&](unsigned t, std::uint32_t c) { return number[t == 0 ? c : global[t][c]]; };
  std::vector<std::uint32_t> runStart(cells + 1, 0);
  for (unsigned t = 0; t < threads; ++t)
    for (std::uint32_t c = 0; c < counts[t].size(); ++c) runStart[numberOf(t, c) + 1] += counts[t][c];
  for (std::size_t c = 0; c < cells; ++c) runStart[c + 1] += runStart[c];
  {
    std::vector<std::uint32_t> next(runStart.begin(), runStart.end() - 1);
    for (unsigned t = 0; t < threads; ++t)
      for (std::uint32_t c = 0; c < counts[t].size(); ++c) {
        const std::uint32_t g = numberOf(t, c), count = counts[t][c];
        counts[t][c] = next[g];
        next[g] += count;
      }
  }
  {
    std::vector<std::uint32_t> localCell;
    localCell.swap(sorted);
    sorted.resize(n);
    detail::runParallel(threads, [&](unsigned t) {
      std::vector<std::uint32_t>& fill = counts[t];
      for (std::size_t i = cut[t]; i < cut[t + 1]; ++i) sorted[fill[localCell[i]]++] = static_cast<std::uint32_t>(i);
    });
  }
  counts.clear();
  global.clear();
  std::vector<std::uint32_t>().swap(number);
  // With the sorted coordinates, cells are found by binary search: the table's memory is not needed.
  if (packable) table = CellTable(0);
  auto findCell = [&](std::int64_t x, std::int64_t y, std::int64_t z) {
    if (!packable) return table.find({x, y, z});  // numbers are the table's
    if (x < 0 || y < 0 || z < 0 || x >= kLimit || y >= kLimit || z >= kLimit) return CellTable::kNone;
    const std::uint64_t key = pack(x, y, z);
    const auto it = std::lower_bound(packed.begin(), packed.end(), key);
    return it != packed.end() && *it == key ? static_cast<std::uint32_t>(it - packed.begin()) : CellTable::kNone;
  };

  const double d2 = d * d;
  // d * d underflows for d below ~1e-154 (and overflows above ~1e154): compare overflow-safe norms there.
  const bool extreme = !(d2 > 0.0) || !std::isfinite(d2) || d < 1e-140 || d > 1e140;
  auto close = [&](const Vec3& a, const Vec3& b) {
    return extreme ? (a - b).stableNorm() < d : (a - b).squaredNorm() < d2;
  };
  // Cells split among the threads at point boundaries: about n / threads points each.
  std::vector<std::size_t> cellCut(threads + 1, cells);
  for (unsigned t = 0; t < threads; ++t)
    cellCut[t] =
        static_cast<std::size_t>(std::lower_bound(runStart.begin(), runStart.end() - 1, cut[t]) - runStart.begin());

  // Within each cell: link to the first point (this sets every point's union-find entry); collect the
  // loose ones, the bounds of each cell's points and its non-loose points with the least and greatest
  // x, y and z, where a neighbour's points most likely come closer than d (so tried first).
  std::vector<unsigned char> loose(n, 0);
  std::vector<std::vector<std::uint32_t>> looseLists(threads);
  std::vector<Eigen::AlignedBox3d> cellBox(cells);
  // (Only with several points per cell on average: with one or two, a full scan costs no more.)
  const bool useExtremes = cells * 8 <= n;
  std::vector<std::array<std::uint32_t, 6>> extremes(useExtremes ? cells : 0);
  constexpr std::size_t kAhead = 16;
  detail::runParallel(threads, [&](unsigned t) {
    for (std::size_t c = cellCut[t]; c < cellCut[t + 1]; ++c) {
      const std::uint32_t first = sorted[runStart[c]];
      const Vec3& p = points[first];
      Eigen::AlignedBox3d bounds(p, p);
      std::array<std::uint32_t, 6> extreme;
      extreme.fill(first);
      Vec3 lo = p, hi = p;
      uf.set(first, first);
      for (std::size_t j = runStart[c] + 1; j < runStart[c + 1]; ++j) {
        const std::uint32_t i = sorted[j];
        if (j + kAhead < n) __builtin_prefetch(&points[sorted[j + kAhead]]);  // the loads are scattered
        const Vec3& q = points[i];
        bounds.extend(q);
        if (close(p, q)) {
          uf.set(i, first);
          for (int axis = 0; axis < 3; ++axis) {
            if (q[axis] < lo[axis]) lo[axis] = q[axis], extreme[2 * axis] = i;
            if (q[axis] > hi[axis]) hi[axis] = q[axis], extreme[2 * axis + 1] = i;
          }
        } else {
          uf.set(i, i);
          loose[i] = 1;
          looseLists[t].push_back(i);
        }
      }
      cellBox[c] = bounds;
      if (useExtremes) extremes[c] = extreme;
    }
  });

  // Between cells. The links join cells in a union-find of their own (a few bytes per cell, in cache,
  // unlike the points' entries): a cell stands for its non-loose points.
  UnionFind cellUf(cells);
  for (std::size_t c = 0; c < cells; ++c) cellUf.set(static_cast<std::uint32_t>(c), static_cast<std::uint32_t>(c));
  // Squared gap between a point or a box and a box (0 when they overlap).
  auto gap2 = [](const Vec3& lo, const Vec3& hi, const Eigen::AlignedBox3d& b) {
    return (b.min() - hi).cwiseMax(lo - b.max()).cwiseMax(0.0).squaredNorm();
  };
  const double farGap2 = d2 * (1.0 + 1e-12);  // slack: the pair tests round on their own
  // Tests one pair of neighbouring cells, joining them on the first link found.
  auto linkCells = [&](std::uint32_t c, std::uint32_t c2, std::vector<Vec3>& nearB) {
    const Eigen::AlignedBox3d& boxA = cellBox[c];
    const Eigen::AlignedBox3d& boxB = cellBox[c2];
    // Two cells whose bounds are d or more apart hold no close pair (no squared test when extreme).
    if (!extreme && gap2(boxA.min(), boxA.max(), boxB) >= farGap2) return;
    if (cellUf.find(c) == cellUf.find(c2)) return;
    if (useExtremes)
      for (const std::uint32_t i : extremes[c])
        for (const std::uint32_t j : extremes[c2])
          if (close(points[i], points[j])) {
            cellUf.unite(c, c2);
            return;
          }
    // A point d or more away from the other cell's bounds has no partner there.
    nearB.clear();
    for (std::size_t b = runStart[c2]; b < runStart[c2 + 1]; ++b) {
      const std::uint32_t j = sorted[b];
      if (loose[j] || (!extreme && gap2(points[j], points[j], boxA) >= farGap2)) continue;
      nearB.push_back(points[j]);
    }
    if (nearB.empty()) return;
    for (std::size_t a = runStart[c]; a < runStart[c + 1]; ++a) {
      const std::uint32_t i = sorted[a];
      const Vec3& pa = points[i];
      if (loose[i] || (!extreme && gap2(pa, pa, boxB) >= farGap2)) continue;
      for (const Vec3& pb : nearB)
        if (close(pa, pb)) {
          cellUf.unite(c, c2);
          return;
        }
    }
  };
  // Each unordered pair of neighbouring cells once (the lexicographically forward half), cells taken in
  // chunks by whichever thread is free.
  constexpr std::size_t kChunk = 256;
  std::atomic<std::size_t> nextChunk{0};
  if (packable) {
    constexpr std::uint64_t kMask = kLimit - 1;
    // The forward rows (dx, dy) beside the cell's own: dx > 0, or dx == 0 and dy > 0.
    std::vector<std::array<int, 2>> rows;
    for (int dx = 0; dx <= reach; ++dx)
      for (int dy = (dx == 0 ? 1 : -reach); dy <= reach; ++dy) rows.push_back({dx, dy});
    // Two sweeps: first the pairs of adjacent cells (offsets of at most 1 along every axis), which
    // usually link at once, then the pairs 2 apart, most of which those links have joined already.
    for (int ring = 1; ring <= reach; ++ring) {
      nextChunk = 0;
      detail::runParallel(threads, [&](unsigned) {
        std::vector<Vec3> nearB;  // the points of the other cell that may be closer than d to this cell
        std::vector<std::size_t> at(rows.size());  // per row: the first cell not yet passed
        for (std::size_t begin; (begin = nextChunk.fetch_add(kChunk, std::memory_order_relaxed)) < cells;) {
          const std::size_t end = std::min(cells, begin + kChunk);
          for (std::size_t c = begin; c < end; ++c) {
            const std::int64_t kx = static_cast<std::int64_t>(packed[c] >> (2 * kBits));
            const std::int64_t ky = static_cast<std::int64_t>((packed[c] >> kBits) & kMask);
            const std::int64_t kz = static_cast<std::int64_t>(packed[c] & kMask);
            auto dz = [&](std::size_t c2) { return std::abs(static_cast<std::int64_t>(packed[c2] & kMask) - kz); };
            // The same row: the next cells up to ring ahead in z.
            for (std::size_t c2 = c + 1; c2 < cells && packed[c2] <= pack(kx, ky, kz + ring); ++c2)
              if (ring == 1 || dz(c2) == ring)
                linkCells(static_cast<std::uint32_t>(c), static_cast<std::uint32_t>(c2), nearB);
            for (std::size_t r = 0; r < rows.size(); ++r) {
              const int ox = std::abs(rows[r][0]), oy = std::abs(rows[r][1]);
              const std::int64_t x = kx + rows[r][0], y = ky + rows[r][1];
              if (std::max(ox, oy) > ring || y < 0 || y >= kLimit || x >= kLimit) continue;
              const bool inner = std::max(ox, oy) < ring;  // then only the cells ring apart in z are new
              const std::uint64_t lo = pack(x, y, std::max<std::int64_t>(kz - ring, 0));
              const std::uint64_t hi = pack(x, y, std::min<std::int64_t>(kz + ring, kLimit - 1));
              std::size_t& i = at[r];
              if (c == begin)  // a new chunk: find the row's place, then only step forward
                i = static_cast<std::size_t>(std::lower_bound(packed.begin(), packed.end(), lo) - packed.begin());
              else
                while (i < cells && packed[i] < lo) ++i;
              for (std::size_t c2 = i; c2 < cells && packed[c2] <= hi; ++c2)
                if (!inner || dz(c2) == ring)
                  linkCells(static_cast<std::uint32_t>(c), static_cast<std::uint32_t>(c2), nearB);
            }
          }
        }
      });
    }
  } else {
    detail::runParallel(threads, [&](unsigned) {
      std::vector<Vec3> nearB;
      for (std::size_t begin; (begin = nextChunk.fetch_add(kChunk, std::memory_order_relaxed)) < cells;) {
        for (std::size_t c = begin; c < std::min(cells, begin + kChunk); ++c) {
          const CellKey k = table.key(static_cast<std::uint32_t>(c));  // numbers are the table's here
          for (int dx = 0; dx <= reach; ++dx)
            for (int dy = (dx == 0 ? 0 : -reach); dy <= reach; ++dy)
              for (int dz = (dx == 0 && dy == 0 ? 1 : -reach); dz <= reach; ++dz) {
                const std::uint32_t c2 = findCell(k.x + dx, k.y + dy, k.z + dz);
                if (c2 != CellTable::kNone) linkCells(static_cast<std::uint32_t>(c), c2, nearB);
              }
        }
      }
    });
  }
  // Each cell's first point joins the smallest first point of its cells' cluster (still a root at the
  // points' level), which is then the cluster's root there too.
  std::vector<std::uint32_t> low(cells, std::numeric_limits<std::uint32_t>::max());  // by cell root
  for (std::size_t c = 0; c < cells; ++c) {
    std::uint32_t& l = low[cellUf.find(static_cast<std::uint32_t>(c))];
    l = std::min(l, sorted[runStart[c]]);
  }
  for (std::size_t c = 0; c < cells; ++c) {
    const std::uint32_t first = sorted[runStart[c]], root = low[cellUf.find(static_cast<std::uint32_t>(c))];
    if (root != first) uf.set(first, root);
  }
  // Loose points: test against every point around them, in both directions.
  for (const auto& looseList : looseLists)
    for (const std::uint32_t i : looseList) {
      const CellKey k = cellOf(points[i], origin, cell);
      for (int dx = -reach; dx <= reach; ++dx)
        for (int dy = -reach; dy <= reach; ++dy)
          for (int dz = -reach; dz <= reach; ++dz) {
            const std::uint32_t c2 = findCell(k.x + dx, k.y + dy, k.z + dz);
            if (c2 == CellTable::kNone) continue;
            for (std::size_t b = runStart[c2]; b < runStart[c2 + 1]; ++b)
              if (sorted[b] != i && close(points[i], points[sorted[b]])) uf.unite(i, sorted[b]);
          }
    }
}

}  // namespace

void requireNonNegative(double value, const char* what) {
  if (!std::isfinite(value) || value < 0.0)
    throw InvalidParameter(std::string(what) + " must be finite and >= 0, got " + std::to_string(value));
}

std::uint32_t SingleLinkClustering::cluster(const std::vector<Vec3>& points, double d,
                                            std::vector<std::uint32_t>& labels) const {
  const std::size_t n = prepare(points, d, labels);
  if (n == 0) return 0;
  if (d == 0.0) {  // every centre apart, even duplicates
    std::iota(labels.begin(), labels.end(), 0u);
    return static_cast<std::uint32_t>(n);
  }
  const unsigned threads = detail::threadsFor(n, threads_, kMinPointsPerThread);
  UnionFind uf(n);
  linkCloserThan(points, d, threads, uf);
  // Label clusters in the order of their first point. The root of a cluster is its smallest index
  // (unite keeps the smaller root), i.e. its first point, so it is labelled before any other member:
  // the roots are found in parallel, the numbering is one ordered pass.
  std::vector<std::size_t> cut(threads + 1);
  for (unsigned t = 0; t <= threads; ++t) cut[t] = n * t / threads;
  detail::runParallel(threads, [&](unsigned t) {
    for (std::size_t i = cut[t]; i < cut[t + 1]; ++i) labels[i] = uf.find(static_cast<std::uint32_t>(i));
  });
  std::uint32_t count = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t root = labels[i];
    labels[i] = root == i ? count++ : labels[root];
  }
  return count;
}

std::uint32_t CubeClustering::cluster(const std::vector<Vec3>& points, double d,
                                      std::vector<std::uint32_t>& labels) const {
  const std::size_t n = prepare(points, d, labels);
  if (n == 0) return 0;
  if (d == 0.0) {
    for (std::size_t i = 0; i < n; ++i) labels[i] = static_cast<std::uint32_t>(i);
    return static_cast<std::uint32_t>(n);
  }
  Eigen::AlignedBox3d box;
  for (const Vec3& p : points) box.extend(p);
  const double extent =
      std::max({box.sizes().maxCoeff(), box.min().cwiseAbs().maxCoeff(), box.max().cwiseAbs().maxCoeff()});
  const double cell = std::max(d, extent * 1e-12);
  CellTable table(std::min<std::size_t>(n, 1024));  // numbers the cubes in the order of their first point
  for (std::size_t i = 0; i < n; ++i) labels[i] = table.insert(cellOf(points[i], box.min(), cell));
  return static_cast<std::uint32_t>(table.size());
}

std::shared_ptr<const Clustering> makeClustering(const std::string& name) {
  if (name == "single-link") return std::make_shared<SingleLinkClustering>();
  if (name == "cube") return std::make_shared<CubeClustering>();
  if (name == "tight") return std::make_shared<TightClustering>();
  return nullptr;
}

std::shared_ptr<const Clustering> requireClustering(const std::string& name, const std::string& what) {
  auto strategy = makeClustering(name);
  if (!strategy) throw InvalidParameter(what + " must be single-link, cube or tight, not '" + name + "'");
  return strategy;
}

}  // namespace clod_haptics
