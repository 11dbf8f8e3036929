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
// cell, not per point.
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

// Thread t's share of n items: [cut[t], cut[t + 1]).
std::vector<std::size_t> evenCuts(std::size_t n, unsigned threads) {
  std::vector<std::size_t> cut(threads + 1);
  for (unsigned t = 0; t <= threads; ++t) cut[t] = n * t / threads;
  return cut;
}

// The largest of the box's sizes and of its corners' coordinates: what the finest cell is measured against.
double extentOf(const Eigen::AlignedBox3d& box) {
  return std::max({box.sizes().maxCoeff(), box.min().cwiseAbs().maxCoeff(), box.max().cwiseAbs().maxCoeff()});
}

// Integer cell of p for cells of side cell anchored at origin.
CellKey cellOf(const Vec3& p, const Vec3& origin, double cell) {
  const Vec3 q = (p - origin) / cell;
  return {static_cast<std::int64_t>(std::floor(q.x())), static_cast<std::int64_t>(std::floor(q.y())),
          static_cast<std::int64_t>(std::floor(q.z()))};
}

// Whether two points are closer than d (Euclidean, strict). d * d underflows for d below ~1e-154 (and
// overflows above ~1e154): overflow-safe norms are compared there.
struct CloserThan {
  explicit CloserThan(double distance)
      : d(distance), d2(d * d), extreme(!(d2 > 0.0) || !std::isfinite(d2) || d < 1e-140 || d > 1e140) {}
  bool operator()(const Vec3& a, const Vec3& b) const {
    return extreme ? (a - b).stableNorm() < d : (a - b).squaredNorm() < d2;
  }
  double d, d2;
  bool extreme;  // no squared distance can be trusted
};

// Squared gap between a point or a box [lo, hi] and a box (0 when they overlap).
inline double gap2(const Vec3& lo, const Vec3& hi, const Eigen::AlignedBox3d& b) {
  return (b.min() - hi).cwiseMax(lo - b.max()).cwiseMax(0.0).squaredNorm();
}

// The cells of single-link: side d / sqrt(3) (shrunk a little against rounding), so that points of one
// cell are normally all closer than d, anchored at the points' lower corner.
struct Grid {
  Vec3 origin;
  double cell;
  int reach;  // a point closer than d is at most this many cells away along each axis: 2, never more
  CellKey keyOf(const Vec3& p) const { return cellOf(p, origin, cell); }
};

Grid gridFor(const std::vector<Vec3>& points, double d, const std::vector<std::size_t>& cut) {
  const auto threads = static_cast<unsigned>(cut.size() - 1);
  std::vector<Eigen::AlignedBox3d> parts(threads);
  detail::runParallel(threads, [&](unsigned t) {
    Eigen::AlignedBox3d part;  // a local: the compiler keeps it in registers
    for (std::size_t i = cut[t]; i < cut[t + 1]; ++i) part.extend(points[i]);
    parts[t] = part;
  });
  Eigen::AlignedBox3d box = parts[0];
  for (unsigned t = 1; t < threads; ++t) box.extend(parts[t]);
  // Never finer than 1e-12 of the extent: keeps cell coordinates far from integer overflow.
  const double cell = std::max(d / std::sqrt(3.0) * (1.0 - 1e-6), extentOf(box) * 1e-12);
  return {box.min(), cell, static_cast<int>(std::ceil(d / cell))};
}

// Cell coordinates in [0, kLimit) packed in one integer, kBits bits each, x highest.
constexpr int kBits = 21;
constexpr std::int64_t kLimit = std::int64_t{1} << kBits;
constexpr std::uint64_t kMask = kLimit - 1;

inline std::uint64_t pack(std::int64_t x, std::int64_t y, std::int64_t z) {
  return static_cast<std::uint64_t>(x) << (2 * kBits) | static_cast<std::uint64_t>(y) << kBits |
         static_cast<std::uint64_t>(z);
}

// The points bucketed by cell. The cells are numbered in the order of their packed coordinates when each
// coordinate (>= 0: the origin is the bounds' corner) fits in kBits bits: a sweep over that order then
// finds the neighbours without hashing, and the data of neighbouring cells lie close in every per-cell
// array. Otherwise (a distance below ~1e-6 of the extent) in the table's order, and neighbours by hashing.
struct CellIndex {
  std::size_t cells = 0;
  bool packable = true;
  std::vector<std::uint64_t> packed;    // by number, when packable
  CellTable table{0};                   // the cells when not packable (numbers are the table's)
  std::vector<std::uint32_t> runStart;  // cell c's points: sorted[runStart[c], runStart[c + 1])
  std::vector<std::uint32_t> sorted;    // the points by cell, ascending within a cell

  std::uint32_t first(std::size_t c) const { return sorted[runStart[c]]; }
  // The number of cell (x, y, z), or CellTable::kNone. With the sorted coordinates, by binary search.
  std::uint32_t find(std::int64_t x, std::int64_t y, std::int64_t z) const {
    if (!packable) return table.find({x, y, z});
    if (x < 0 || y < 0 || z < 0 || x >= kLimit || y >= kLimit || z >= kLimit) return CellTable::kNone;
    const std::uint64_t key = pack(x, y, z);
    const auto it = std::lower_bound(packed.begin(), packed.end(), key);
    return it != packed.end() && *it == key ? static_cast<std::uint32_t>(it - packed.begin()) : CellTable::kNone;
  }
};

// Builds a CellIndex (expected O(n)) on the threads of cut: each thread numbers the cells of its points in
// a table of its own and counts them, the tables are merged into the first, the cells numbered, and the
// points bucketed in parallel.
class CellBucketing {
 public:
  CellBucketing(const std::vector<Vec3>& points, const Grid& grid, const std::vector<std::size_t>& cut)
      : points_(points), grid_(grid), cut_(cut), threads_(static_cast<unsigned>(cut.size() - 1)) {}

  CellIndex run() {
    CellIndex index;
    index.sorted.resize(points_.size());  // first the thread-local cell of each point, then the points by cell
    findLocalCells(index.sorted);
    mergeTables();
    index.cells = tables_[0].size();
    numberCells(index);
    fillRuns(index);
    if (!index.packable) index.table = std::move(tables_[0]);
    return index;
  }

 private:
  void findLocalCells(std::vector<std::uint32_t>& localCell) {
    tables_.reserve(threads_);
    for (unsigned t = 0; t < threads_; ++t) tables_.emplace_back(std::min<std::size_t>(cut_[t + 1] - cut_[t], 1024));
    counts_.resize(threads_);
    detail::runParallel(threads_, [&](unsigned t) { findLocalCells(t, localCell); });
  }

  // Thread t's cells in tables_[t], their point counts in counts_[t], and localCell[i] for its points.
  void findLocalCells(unsigned t, std::vector<std::uint32_t>& localCell) {
    CellTable& table = tables_[t];
    std::vector<std::uint32_t>& count = counts_[t];
    // The placement emits two centres per triangle in triangle order (one near it, one towards its
    // opposite), so a centre is usually in the cell of the centre two places back: tried before the table.
    CellKey recent[2] = {{-1, -1, -1}, {-1, -1, -1}};
    std::uint32_t recentCell[2] = {0, 0};
    for (std::size_t i = cut_[t]; i < cut_[t + 1]; ++i) {
      const CellKey key = grid_.keyOf(points_[i]);
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
      localCell[i] = c;
    }
  }

  // The other threads' tables merged into the first: global_[t][c] is thread t's cell c there (t >= 1).
  void mergeTables() {
    CellTable& table = tables_[0];
    global_.resize(threads_);
    for (unsigned t = 1; t < threads_; ++t) {
      global_[t].resize(tables_[t].size());
      for (std::uint32_t c = 0; c < tables_[t].size(); ++c) global_[t][c] = table.insert(tables_[t].key(c));
      tables_[t] = CellTable(0);  // merged: free it
    }
  }

  // number_[c]: the number of the merged table's cell c; index.packable and index.packed.
  void numberCells(CellIndex& index) {
    const CellTable& table = tables_[0];
    const std::size_t cells = index.cells;
    for (std::size_t c = 0; c < cells && index.packable; ++c) {
      const CellKey& k = table.key(static_cast<std::uint32_t>(c));
      index.packable = k.x < kLimit && k.y < kLimit && k.z < kLimit;
    }
    number_.resize(cells);
    if (!index.packable) {
      std::iota(number_.begin(), number_.end(), 0u);
      return;
    }
    std::vector<std::pair<std::uint64_t, std::uint32_t>> order(cells);  // (packed coordinates, table's cell)
    for (std::size_t c = 0; c < cells; ++c) {
      const CellKey& k = table.key(static_cast<std::uint32_t>(c));
      order[c] = {pack(k.x, k.y, k.z), static_cast<std::uint32_t>(c)};
    }
    if (threads_ > 1) {
      const auto middle = order.begin() + static_cast<std::ptrdiff_t>(cells / 2);
      detail::runParallel(2, [&](unsigned t) { std::sort(t ? middle : order.begin(), t ? order.end() : middle); });
      std::inplace_merge(order.begin(), middle, order.end());
    } else {
      std::sort(order.begin(), order.end());
    }
    index.packed.resize(cells);
    for (std::size_t s = 0; s < cells; ++s) {
      index.packed[s] = order[s].first;
      number_[order[s].second] = static_cast<std::uint32_t>(s);
    }
  }

  std::uint32_t numberOf(unsigned t, std::uint32_t c) const { return number_[t == 0 ? c : global_[t][c]]; }

  // Buckets the points by cell: prefix sums give each thread where its points of a cell go (counts_ then
  // holds those places), and the threads fill in parallel. Each run keeps ascending point order (thread
  // t's points precede thread t+1's), so a run starts with its cell's smallest point index.
  void fillRuns(CellIndex& index) {
    std::vector<std::uint32_t>& runStart = index.runStart;
    runStart.assign(index.cells + 1, 0);
    for (unsigned t = 0; t < threads_; ++t)
      for (std::uint32_t c = 0; c < counts_[t].size(); ++c) runStart[numberOf(t, c) + 1] += counts_[t][c];
    for (std::size_t c = 0; c < index.cells; ++c) runStart[c + 1] += runStart[c];
    std::vector<std::uint32_t> next(runStart.begin(), runStart.end() - 1);
    for (unsigned t = 0; t < threads_; ++t)
      for (std::uint32_t c = 0; c < counts_[t].size(); ++c) {
        const std::uint32_t g = numberOf(t, c), count = counts_[t][c];
        counts_[t][c] = next[g];
        next[g] += count;
      }
    std::vector<std::uint32_t>().swap(next);
    std::vector<std::uint32_t> localCell;
    localCell.swap(index.sorted);
    index.sorted.resize(points_.size());
    detail::runParallel(threads_, [&](unsigned t) {
      std::vector<std::uint32_t>& fill = counts_[t];
      for (std::size_t i = cut_[t]; i < cut_[t + 1]; ++i)
        index.sorted[fill[localCell[i]]++] = static_cast<std::uint32_t>(i);
    });
  }

  const std::vector<Vec3>& points_;
  const Grid& grid_;
  const std::vector<std::size_t>& cut_;
  unsigned threads_;
  std::vector<CellTable> tables_;                   // per thread; after merging, the first holds every cell
  std::vector<std::vector<std::uint32_t>> counts_;  // per thread and local cell: points, then fill start
  std::vector<std::vector<std::uint32_t>> global_;  // per thread t >= 1: local cell -> merged table's cell
  std::vector<std::uint32_t> number_;               // merged table's cell -> the cell's number
};

CellIndex bucketPoints(const std::vector<Vec3>& points, const Grid& grid, const std::vector<std::size_t>& cut) {
  return CellBucketing(points, grid, cut).run();
}

// Calls visit(begin, end) for chunks of [0, count), each taken by whichever thread asks first.
template <class Visit>
void forEachChunk(std::atomic<std::size_t>& next, std::size_t count, Visit&& visit) {
  constexpr std::size_t kChunk = 256;
  for (std::size_t begin; (begin = next.fetch_add(kChunk, std::memory_order_relaxed)) < count;)
    visit(begin, std::min(count, begin + kChunk));
}

// The links of single-link over a CellIndex, in three passes: within each cell, between neighbouring
// cells, and for the loose points (see linkCloserThan).
class CellLinker {
 public:
  CellLinker(const std::vector<Vec3>& points, const Grid& grid, const CellIndex& index, double d, UnionFind& uf)
      : points_(points),
        grid_(grid),
        index_(index),
        close_(d),
        farGap2_(close_.d2 * (1.0 + 1e-12)),  // slack: the pair tests round on their own
        uf_(uf),
        cellUf_(index.cells) {}

  // Within each cell, the cells split among the threads at point boundaries (about n / threads points
  // each): link to the first point (this sets every point's union-find entry); collect the loose ones,
  // the bounds of each cell's points and its non-loose points with the least and greatest x, y and z,
  // where a neighbour's points most likely come closer than d (so tried first).
  void linkWithinCells(const std::vector<std::size_t>& cut) {
    const auto threads = static_cast<unsigned>(cut.size() - 1);
    const std::size_t n = points_.size(), cells = index_.cells;
    std::vector<std::size_t> cellCut(threads + 1, cells);
    for (unsigned t = 0; t < threads; ++t)
      cellCut[t] = static_cast<std::size_t>(
          std::lower_bound(index_.runStart.begin(), index_.runStart.end() - 1, cut[t]) - index_.runStart.begin());
    loose_.assign(n, 0);
    looseLists_.resize(threads);
    cellBox_.resize(cells);
    // (Only with several points per cell on average: with one or two, a full scan costs no more.)
    useExtremes_ = cells * 8 <= n;
    extremes_.resize(useExtremes_ ? cells : 0);
    detail::runParallel(threads, [&](unsigned t) {
      for (std::size_t c = cellCut[t]; c < cellCut[t + 1]; ++c) linkWithinCell(c, looseLists_[t]);
    });
  }

  // Between cells. The links join cells in a union-find of their own (a few bytes per cell, in cache,
  // unlike the points' entries): a cell stands for its non-loose points. Each unordered pair of
  // neighbouring cells is tested once (the lexicographically forward half).
  void linkBetweenCells(unsigned threads) {
    for (std::size_t c = 0; c < index_.cells; ++c)
      cellUf_.set(static_cast<std::uint32_t>(c), static_cast<std::uint32_t>(c));
    if (index_.packable)
      linkPackedNeighbours(threads);
    else
      linkHashedNeighbours(threads);
    joinCellRoots();
  }

  // Loose points: test against every point around them, in both directions.
  void linkLoosePoints() {
    const int reach = grid_.reach;
    for (const auto& looseList : looseLists_)
      for (const std::uint32_t i : looseList) {
        const CellKey k = grid_.keyOf(points_[i]);
        for (int dx = -reach; dx <= reach; ++dx)
          for (int dy = -reach; dy <= reach; ++dy)
            for (int dz = -reach; dz <= reach; ++dz) {
              const std::uint32_t c2 = index_.find(k.x + dx, k.y + dy, k.z + dz);
              if (c2 == CellTable::kNone) continue;
              for (std::size_t b = index_.runStart[c2]; b < index_.runStart[c2 + 1]; ++b)
                if (index_.sorted[b] != i && close_(points_[i], points_[index_.sorted[b]]))
                  uf_.unite(i, index_.sorted[b]);
            }
      }
  }

 private:
  void linkWithinCell(std::size_t c, std::vector<std::uint32_t>& looseList) {
    constexpr std::size_t kAhead = 16;
    const std::vector<Vec3>& points = points_;
    const std::vector<std::uint32_t>& sorted = index_.sorted;
    const std::size_t n = points.size();
    const std::uint32_t first = index_.first(c);
    const Vec3& p = points[first];
    Eigen::AlignedBox3d bounds(p, p);
    std::array<std::uint32_t, 6> extreme;
    extreme.fill(first);
    Vec3 lo = p, hi = p;
    uf_.set(first, first);
    for (std::size_t j = index_.runStart[c] + 1; j < index_.runStart[c + 1]; ++j) {
      const std::uint32_t i = sorted[j];
      if (j + kAhead < n) __builtin_prefetch(&points[sorted[j + kAhead]]);  // the loads are scattered
      const Vec3& q = points[i];
      bounds.extend(q);
      if (close_(p, q)) {
        uf_.set(i, first);
        for (int axis = 0; axis < 3; ++axis) {
          if (q[axis] < lo[axis]) lo[axis] = q[axis], extreme[2 * axis] = i;
          if (q[axis] > hi[axis]) hi[axis] = q[axis], extreme[2 * axis + 1] = i;
        }
      } else {
        uf_.set(i, i);
        loose_[i] = 1;
        looseList.push_back(i);
      }
    }
    cellBox_[c] = bounds;
    if (useExtremes_) extremes_[c] = extreme;
  }

  // Tests one pair of neighbouring cells, joining them on the first link found: the extreme points
  // first, then the points of one cell near the other's bounds against those of the other near the
  // first's bounds. nearB is scratch space.
  void linkCells(std::uint32_t c, std::uint32_t c2, std::vector<Vec3>& nearB) {
    const Eigen::AlignedBox3d& boxA = cellBox_[c];
    const Eigen::AlignedBox3d& boxB = cellBox_[c2];
    const bool extreme = close_.extreme;
    // Two cells whose bounds are d or more apart hold no close pair (no squared test when extreme).
    if (!extreme && gap2(boxA.min(), boxA.max(), boxB) >= farGap2_) return;
    if (cellUf_.find(c) == cellUf_.find(c2)) return;
    if (useExtremes_)
      for (const std::uint32_t i : extremes_[c])
        for (const std::uint32_t j : extremes_[c2])
          if (close_(points_[i], points_[j])) {
            cellUf_.unite(c, c2);
            return;
          }
    // A point d or more away from the other cell's bounds has no partner there.
    nearB.clear();
    for (std::size_t b = index_.runStart[c2]; b < index_.runStart[c2 + 1]; ++b) {
      const std::uint32_t j = index_.sorted[b];
      if (loose_[j] || (!extreme && gap2(points_[j], points_[j], boxA) >= farGap2_)) continue;
      nearB.push_back(points_[j]);
    }
    if (nearB.empty()) return;
    for (std::size_t a = index_.runStart[c]; a < index_.runStart[c + 1]; ++a) {
      const std::uint32_t i = index_.sorted[a];
      const Vec3& pa = points_[i];
      if (loose_[i] || (!extreme && gap2(pa, pa, boxB) >= farGap2_)) continue;
      for (const Vec3& pb : nearB)
        if (close_(pa, pb)) {
          cellUf_.unite(c, c2);
          return;
        }
    }
  }

  // Two sweeps over the cells in packed order: first the pairs of adjacent cells (offsets of at most 1
  // along every axis), which usually link at once, then the pairs 2 apart, most of which those links
  // have joined already.
  void linkPackedNeighbours(unsigned threads) {
    const int reach = grid_.reach;
    // The forward rows (dx, dy) beside the cell's own: dx > 0, or dx == 0 and dy > 0.
    std::vector<std::array<int, 2>> rows;
    for (int dx = 0; dx <= reach; ++dx)
      for (int dy = (dx == 0 ? 1 : -reach); dy <= reach; ++dy) rows.push_back({dx, dy});
    for (int ring = 1; ring <= reach; ++ring) {
      std::atomic<std::size_t> nextChunk{0};
      detail::runParallel(threads, [&](unsigned) {
        std::vector<Vec3> nearB;                   // the points of the other cell that may be closer than d
        std::vector<std::size_t> at(rows.size());  // per row: the first cell not yet passed
        forEachChunk(nextChunk, index_.cells, [&](std::size_t begin, std::size_t end) {
          for (std::size_t c = begin; c < end; ++c) linkRing(c, ring, rows, c == begin, at, nearB);
        });
      });
    }
  }

  // Links cell c to its forward neighbours ring apart (up to ring apart for ring 1): the next cells of its
  // own row, then those of the forward rows. at[r]: row r's place, found anew at a chunk's first cell,
  // then only stepped forward.
  void linkRing(std::size_t c, int ring, const std::vector<std::array<int, 2>>& rows, bool chunkStart,
                std::vector<std::size_t>& at, std::vector<Vec3>& nearB) {
    const std::vector<std::uint64_t>& packed = index_.packed;
    const std::size_t cells = index_.cells;
    const std::int64_t kx = static_cast<std::int64_t>(packed[c] >> (2 * kBits));
    const std::int64_t ky = static_cast<std::int64_t>((packed[c] >> kBits) & kMask);
    const std::int64_t kz = static_cast<std::int64_t>(packed[c] & kMask);
    auto dz = [&](std::size_t c2) { return std::abs(static_cast<std::int64_t>(packed[c2] & kMask) - kz); };
    // The same row: the next cells up to ring ahead in z.
    for (std::size_t c2 = c + 1; c2 < cells && packed[c2] <= pack(kx, ky, kz + ring); ++c2)
      if (ring == 1 || dz(c2) == ring) linkCells(static_cast<std::uint32_t>(c), static_cast<std::uint32_t>(c2), nearB);
    for (std::size_t r = 0; r < rows.size(); ++r) {
      const int ox = std::abs(rows[r][0]), oy = std::abs(rows[r][1]);
      const std::int64_t x = kx + rows[r][0], y = ky + rows[r][1];
      if (std::max(ox, oy) > ring || y < 0 || y >= kLimit || x >= kLimit) continue;
      const bool inner = std::max(ox, oy) < ring;  // then only the cells ring apart in z are new
      const std::uint64_t lo = pack(x, y, std::max<std::int64_t>(kz - ring, 0));
      const std::uint64_t hi = pack(x, y, std::min<std::int64_t>(kz + ring, kLimit - 1));
      std::size_t& i = at[r];
      if (chunkStart)
        i = static_cast<std::size_t>(std::lower_bound(packed.begin(), packed.end(), lo) - packed.begin());
      else
        while (i < cells && packed[i] < lo) ++i;
      for (std::size_t c2 = i; c2 < cells && packed[c2] <= hi; ++c2)
        if (!inner || dz(c2) == ring) linkCells(static_cast<std::uint32_t>(c), static_cast<std::uint32_t>(c2), nearB);
    }
  }

  // The neighbours by hashing, when the cells are not in packed order.
  void linkHashedNeighbours(unsigned threads) {
    const int reach = grid_.reach;
    std::atomic<std::size_t> nextChunk{0};
    detail::runParallel(threads, [&](unsigned) {
      std::vector<Vec3> nearB;
      forEachChunk(nextChunk, index_.cells, [&](std::size_t begin, std::size_t end) {
        for (std::size_t c = begin; c < end; ++c) {
          const CellKey k = index_.table.key(static_cast<std::uint32_t>(c));  // numbers are the table's here
          for (int dx = 0; dx <= reach; ++dx)
            for (int dy = (dx == 0 ? 0 : -reach); dy <= reach; ++dy)
              for (int dz = (dx == 0 && dy == 0 ? 1 : -reach); dz <= reach; ++dz) {
                const std::uint32_t c2 = index_.find(k.x + dx, k.y + dy, k.z + dz);
                if (c2 != CellTable::kNone) linkCells(static_cast<std::uint32_t>(c), c2, nearB);
              }
        }
      });
    });
  }

  // Each cell's first point joins the smallest first point of its cells' cluster (still a root at the
  // points' level), which is then the cluster's root there too.
  void joinCellRoots() {
    const std::size_t cells = index_.cells;
    std::vector<std::uint32_t> low(cells, std::numeric_limits<std::uint32_t>::max());  // by cell root
    for (std::size_t c = 0; c < cells; ++c) {
      std::uint32_t& l = low[cellUf_.find(static_cast<std::uint32_t>(c))];
      l = std::min(l, index_.first(c));
    }
    for (std::size_t c = 0; c < cells; ++c) {
      const std::uint32_t first = index_.first(c), root = low[cellUf_.find(static_cast<std::uint32_t>(c))];
      if (root != first) uf_.set(first, root);
    }
  }

  const std::vector<Vec3>& points_;
  const Grid& grid_;
  const CellIndex& index_;
  const CloserThan close_;
  const double farGap2_;
  UnionFind& uf_;
  UnionFind cellUf_;
  std::vector<unsigned char> loose_;                    // by point: not closer than d to its cell's first
  std::vector<std::vector<std::uint32_t>> looseLists_;  // per thread: its loose points
  std::vector<Eigen::AlignedBox3d> cellBox_;            // by cell: bounds of its points
  bool useExtremes_ = false;
  std::vector<std::array<std::uint32_t, 6>> extremes_;  // by cell, when useExtremes_
};

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
  const std::vector<std::size_t> cut = evenCuts(points.size(), threads);
  const Grid grid = gridFor(points, d, cut);
  const CellIndex index = bucketPoints(points, grid, cut);
  CellLinker linker(points, grid, index, d, uf);
  linker.linkWithinCells(cut);
  linker.linkBetweenCells(threads);
  linker.linkLoosePoints();
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
  const std::vector<std::size_t> cut = evenCuts(n, threads);
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
  const double cell = std::max(d, extentOf(box) * 1e-12);
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
