#include "clod_haptics/core/clustering.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>

#include "clod_haptics/core/errors.h"

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

// Open-addressing table from a cell to its run of points (points sorted by cell).
class CellTable {
 public:
  explicit CellTable(std::size_t cells) {
    std::size_t cap = 16;
    while (cap < 2 * cells) cap <<= 1;
    slots_.assign(cap, Slot{});
    mask_ = cap - 1;
  }
  // Returns the slot of key, inserting it when absent.
  std::size_t insert(const CellKey& key) {
    std::size_t i = hashKey(key) & mask_;
    while (slots_[i].used && !(slots_[i].key == key)) i = (i + 1) & mask_;
    if (!slots_[i].used) {
      slots_[i].used = true;
      slots_[i].key = key;
    }
    return i;
  }
  const std::size_t* find(const CellKey& key) const {
    std::size_t i = hashKey(key) & mask_;
    while (slots_[i].used) {
      if (slots_[i].key == key) return &slots_[i].run;
      i = (i + 1) & mask_;
    }
    return nullptr;
  }
  std::size_t& run(std::size_t slot) { return slots_[slot].run; }

 private:
  struct Slot {
    CellKey key{0, 0, 0};
    std::size_t run = 0;
    bool used = false;
  };
  std::vector<Slot> slots_;
  std::size_t mask_ = 0;
};

}  // namespace

std::uint32_t SingleLinkClustering::cluster(const std::vector<Vec3>& points, double d,
                                            std::vector<std::uint32_t>& labels) const {
  if (!std::isfinite(d) || d < 0.0)
    throw InvalidParameter("clustering distance must be finite and >= 0, got " + std::to_string(d));
  const std::size_t n = points.size();
  labels.assign(n, 0);
  if (n == 0) return 0;
  UnionFind uf(n);
  if (d > 0.0) {
    Eigen::AlignedBox3d box;
    for (const Vec3& p : points) box.extend(p);
    const double extent =
        std::max({box.sizes().maxCoeff(), box.min().cwiseAbs().maxCoeff(), box.max().cwiseAbs().maxCoeff()});
    // A cell never smaller than d keeps every pair closer than d within neighbouring cells; the floor
    // keeps cell coordinates far from integer overflow for a tiny d.
    const double cell = std::max(d, extent * 1e-12);
    std::vector<CellKey> keys(n);
    for (std::size_t i = 0; i < n; ++i) {
      const Vec3 q = (points[i] - box.min()) / cell;
      keys[i] = {static_cast<std::int64_t>(std::floor(q.x())), static_cast<std::int64_t>(std::floor(q.y())),
                 static_cast<std::int64_t>(std::floor(q.z()))};
    }
    // Bucket the points by cell: count, prefix sum, fill (expected O(n)).
    CellTable table(n);
    std::vector<std::size_t> slotOf(n);
    for (std::size_t i = 0; i < n; ++i) {
      const std::size_t s = table.insert(keys[i]);
      slotOf[i] = s;
    }
    // Number the cells and lay out their runs.
    std::vector<std::size_t> runStart, runCount;
    {
      for (std::size_t i = 0; i < n; ++i) {
        std::size_t& r = table.run(slotOf[i]);
        if (r == 0) {
          runCount.push_back(0);
          r = runCount.size();  // 1-based so 0 means unnumbered
        }
        ++runCount[r - 1];
      }
      runStart.assign(runCount.size() + 1, 0);
      for (std::size_t c = 0; c < runCount.size(); ++c) runStart[c + 1] = runStart[c] + runCount[c];
    }
    std::vector<std::uint32_t> sorted(n);
    {
      std::vector<std::size_t> fill(runStart.begin(), runStart.end() - 1);
      for (std::size_t i = 0; i < n; ++i) sorted[fill[table.run(slotOf[i]) - 1]++] = static_cast<std::uint32_t>(i);
    }
    const double d2 = d * d;
    for (std::size_t i = 0; i < n; ++i) {
      const CellKey& k = keys[i];
      const Vec3& p = points[i];
      for (int dx = -1; dx <= 1; ++dx)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dz = -1; dz <= 1; ++dz) {
            const std::size_t* run = table.find({k.x + dx, k.y + dy, k.z + dz});
            if (run == nullptr) continue;
            const std::size_t c = *run - 1;
            for (std::size_t j = runStart[c]; j < runStart[c + 1]; ++j) {
              const std::uint32_t q = sorted[j];
              if (q <= i) continue;  // each pair once
              if ((points[q] - p).squaredNorm() < d2) uf.unite(static_cast<std::uint32_t>(i), q);
            }
          }
    }
  }
  // Label clusters in the order of their first point.
  std::vector<std::uint32_t> id(n, std::numeric_limits<std::uint32_t>::max());
  std::uint32_t count = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t root = uf.find(static_cast<std::uint32_t>(i));
    if (id[root] == std::numeric_limits<std::uint32_t>::max()) id[root] = count++;
    labels[i] = id[root];
  }
  return count;
}

}  // namespace clod_haptics
