#include "clod_haptics/core/clustering.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>

#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/tight_clustering.h"

namespace clod_haptics {
namespace {

struct UnionFind {
  std::vector<std::uint32_t> parent;
  explicit UnionFind(std::size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0u); }
  std::uint32_t find(std::uint32_t x) {
    while (parent[x] != x) {
      parent[x] = parent[parent[x]];
      x = parent[x];
    }
    return x;
  }
  void unite(std::uint32_t a, std::uint32_t b) {
    a = find(a);
    b = find(b);
    if (a == b) return;
    if (a < b) std::swap(a, b);
    parent[a] = b;  // the smaller index is the root: deterministic
  }
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
  if (!std::isfinite(d) || d < 0.0)
    throw InvalidParameter("clustering distance must be finite and >= 0, got " + std::to_string(d));
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
// neighbour point itself. Between two cells whose first points are already in one cluster nothing
// is tested; otherwise point pairs are tested until one link is found, which joins the two cells.
// Every union is backed by an exact distance test, so the result equals naive single-link.
void linkCloserThan(const std::vector<Vec3>& points, double d, UnionFind& uf) {
  const std::size_t n = points.size();
  Eigen::AlignedBox3d box;
  for (const Vec3& p : points) box.extend(p);
  const double extent =
      std::max({box.sizes().maxCoeff(), box.min().cwiseAbs().maxCoeff(), box.max().cwiseAbs().maxCoeff()});
  // Never finer than 1e-12 of the extent: keeps cell coordinates far from integer overflow.
  const double cell = std::max(d / std::sqrt(3.0) * (1.0 - 1e-6), extent * 1e-12);
  const int reach = static_cast<int>(std::ceil(d / cell));  // 2 for the usual cell size
  const Vec3 origin = box.min();
  // Bucket the points by cell (expected O(n)): number the cells, count, prefix sum, fill. Cells are
  // numbered in the order of their first point and each run keeps ascending point order.
  CellTable table(std::min<std::size_t>(n, 1024));
  std::vector<std::uint32_t> sorted(n);  // first the cell of each point, then the points by cell
  for (std::size_t i = 0; i < n; ++i) sorted[i] = table.insert(cellOf(points[i], origin, cell));
  const std::size_t cells = table.size();
  std::vector<std::uint32_t> runStart(cells + 1, 0);
  for (std::size_t i = 0; i < n; ++i) ++runStart[sorted[i] + 1];
  for (std::size_t c = 0; c < cells; ++c) runStart[c + 1] += runStart[c];
  {
    std::vector<std::uint32_t> cellOfPoint;
    cellOfPoint.swap(sorted);
    sorted.resize(n);
    // Fill through runStart shifted by one cell: afterwards runStart[c + 1] is the end of cell c again.
    std::vector<std::uint32_t>& fill = runStart;
    for (std::size_t c = cells; c > 0; --c) fill[c] = fill[c - 1];
    for (std::size_t i = 0; i < n; ++i) sorted[fill[cellOfPoint[i] + 1]++] = static_cast<std::uint32_t>(i);
  }
  const double d2 = d * d;
  // d * d underflows for d below ~1e-154 (and overflows above ~1e154): compare overflow-safe norms there.
  const bool extreme = !(d2 > 0.0) || !std::isfinite(d2) || d < 1e-140 || d > 1e140;
  auto close = [&](std::uint32_t a, std::uint32_t b) {
    return extreme ? (points[a] - points[b]).stableNorm() < d : (points[a] - points[b]).squaredNorm() < d2;
  };

  // Within each cell: link to the first point; collect the loose ones.
  std::vector<unsigned char> loose(n, 0);
  std::vector<std::uint32_t> looseList;
  for (std::size_t c = 0; c < cells; ++c) {
    const std::uint32_t first = sorted[runStart[c]];
    for (std::size_t j = runStart[c] + 1; j < runStart[c + 1]; ++j) {
      if (close(first, sorted[j])) {
        uf.unite(first, sorted[j]);
      } else {
        loose[sorted[j]] = 1;
        looseList.push_back(sorted[j]);
      }
    }
  }
  // Bounds of each cell's points: two cells whose bounds are d or more apart hold no close pair.
  std::vector<Eigen::AlignedBox3d> cellBox(cells);
  for (std::size_t c = 0; c < cells; ++c) {
    cellBox[c].setEmpty();
    for (std::size_t j = runStart[c]; j < runStart[c + 1]; ++j) cellBox[c].extend(points[sorted[j]]);
  }
  auto apart = [&](std::size_t a, std::size_t b) {
    if (extreme) return false;  // no squared test there; the point tests decide
    const Vec3 gap = (cellBox[a].min() - cellBox[b].max()).cwiseMax(cellBox[b].min() - cellBox[a].max()).cwiseMax(0.0);
    return gap.squaredNorm() >= d2 * (1.0 + 1e-12);  // slack: the pair tests round on their own
  };
  // Between cells: each unordered pair of neighbouring cells once (the lexicographically forward half).
  for (std::size_t c = 0; c < cells; ++c) {
    const CellKey k = table.key(static_cast<std::uint32_t>(c));
    const std::uint32_t repA = sorted[runStart[c]];
    for (int dx = 0; dx <= reach; ++dx)
      for (int dy = (dx == 0 ? 0 : -reach); dy <= reach; ++dy)
        for (int dz = (dx == 0 && dy == 0 ? 1 : -reach); dz <= reach; ++dz) {
          const std::uint32_t c2 = table.find({k.x + dx, k.y + dy, k.z + dz});
          if (c2 == CellTable::kNone) continue;
          const std::uint32_t repB = sorted[runStart[c2]];
          if (apart(c, c2) || uf.find(repA) == uf.find(repB)) continue;
          bool linked = false;
          for (std::size_t a = runStart[c]; a < runStart[c + 1] && !linked; ++a) {
            if (loose[sorted[a]]) continue;
            // A point d or more away from the other cell's bounds has no partner there.
            if (!extreme) {
              const Vec3& pa = points[sorted[a]];
              const Vec3 gap = (cellBox[c2].min() - pa).cwiseMax(pa - cellBox[c2].max()).cwiseMax(0.0);
              if (gap.squaredNorm() >= d2 * (1.0 + 1e-12)) continue;
            }
            for (std::size_t b = runStart[c2]; b < runStart[c2 + 1]; ++b) {
              if (loose[sorted[b]]) continue;
              if (close(sorted[a], sorted[b])) {
                uf.unite(sorted[a], sorted[b]);
                linked = true;
                break;
              }
            }
          }
        }
  }
  // Loose points: test against every point around them, in both directions.
  for (const std::uint32_t i : looseList) {
    const CellKey k = cellOf(points[i], origin, cell);
    for (int dx = -reach; dx <= reach; ++dx)
      for (int dy = -reach; dy <= reach; ++dy)
        for (int dz = -reach; dz <= reach; ++dz) {
          const std::uint32_t c2 = table.find({k.x + dx, k.y + dy, k.z + dz});
          if (c2 == CellTable::kNone) continue;
          for (std::size_t b = runStart[c2]; b < runStart[c2 + 1]; ++b)
            if (sorted[b] != i && close(i, sorted[b])) uf.unite(i, sorted[b]);
        }
  }
}

}  // namespace

std::uint32_t SingleLinkClustering::cluster(const std::vector<Vec3>& points, double d,
                                            std::vector<std::uint32_t>& labels) const {
  const std::size_t n = prepare(points, d, labels);
  if (n == 0) return 0;
  UnionFind uf(n);
  if (d > 0.0) linkCloserThan(points, d, uf);
  // Label clusters in the order of their first point. The root of a cluster is its smallest index
  // (unite keeps the smaller root), i.e. its first point, so it is labelled before any other member.
  std::uint32_t count = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t root = uf.find(static_cast<std::uint32_t>(i));
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
