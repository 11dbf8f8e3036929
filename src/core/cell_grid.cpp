#include "clod_haptics/core/cell_grid.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <utility>
#include <vector>

#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/geometry.h"
#include "float_rounding.h"
#include "grid_entry_codes.h"
#include "parallel.h"
#include "simd/closest_point_avx2.h"
#include "simd/dispatch.h"
#include "simd/grid_entry_avx2.h"

namespace clod_haptics {
namespace {

using detail::distanceCode;
using detail::finerCode;
using detail::quantiseDirection;
using detail::ReallocArray;
using detail::roundDown;
using Entry = CellGrid::Entry;

constexpr double kCellFactor = 2.0;  // cell side in pointer radii, unless coarser cells pay (cellFactor)
constexpr std::int64_t kMaxDim = (1 << CellGrid::kBits) - 1;
constexpr double kSqrt3 = 1.7320508075688772;
constexpr double kHalfDiagonal = 0.8660254037844386;  // half the diagonal of a unit cube
// Rounding of a stored direction: each component within 0.5 / 127 of u, so |u - stored| <= sqrt(3) / 254
// and the bound errs by at most that times |p - centre| <= h sqrt(3) / 2.
constexpr double kDirectionError = kSqrt3 / 254.0;

std::uint64_t mix(std::uint64_t k) {
  k ^= k >> 33;
  k *= 0xff51afd7ed558ccdull;
  k ^= k >> 33;
  k *= 0xc4ceb9fe1a85ec53ull;
  return k ^ (k >> 33);
}

/** Number of cells of the grid's box (in double: it may exceed what the dense index can hold). */
double cellsOfBox(const std::int64_t dims[3]) {
  return static_cast<double>(dims[0]) * static_cast<double>(dims[1]) * static_cast<double>(dims[2]);
}

// ---- Cell size and placement ----

/** The mesh's figures the cells are sized by. */
struct MeshFigures {
  Eigen::AlignedBox3d bounds;
  double magnitude;  // largest coordinate magnitude of the bounds
  double pad;        // rounding slack relative to the coordinates
  double area;       // total area
  double perimeter;  // total perimeter (the sum of every triangle's three edges)
};

MeshFigures measure(const TriangleMesh& mesh) {
  MeshFigures f;
  f.bounds = mesh.bounds();
  f.magnitude = std::max(f.bounds.min().cwiseAbs().maxCoeff(), f.bounds.max().cwiseAbs().maxCoeff());
  f.pad = 1e-12 * std::max(f.magnitude, f.bounds.diagonal().norm());
  f.area = 0.0;
  f.perimeter = 0.0;
  for (std::size_t t = 0; t < mesh.size(); ++t) {  // one pass over the corners for both
    const Vec3 &a = mesh.vertex(t, 0), &b = mesh.vertex(t, 1), &c = mesh.vertex(t, 2);
    f.area += 0.5 * (b - a).cross(c - a).norm();
    f.perimeter += (b - a).norm();
    f.perimeter += (c - b).norm();
    f.perimeter += (a - c).norm();
  }
  return f;
}

/**
 * Expected candidates of cells of side h keeping the triangles within reach of their centres: a cell lists a
 * triangle when its centre lies in the triangle grown by reach, whose volume is 2 reach A + (pi / 2) reach^2 P +
 * (4 pi / 3) reach^3 for a flat triangle of area A and perimeter P (Steiner's formula), so on average over the
 * grid's placement that volume over h^3, summed over the triangles. It holds for every shape: small triangles
 * (the ball term), large ones (the area term) and long thin ones (the perimeter term: a sliver spans a tube of
 * cells along its length, not the cube of its bounding box).
 */
double estimatedCandidates(const MeshFigures& f, std::size_t triangles, double reach, double h) {
  constexpr double kPi = 3.141592653589793;
  const double n = static_cast<double>(triangles);
  const double volume =
      2.0 * reach * f.area + 0.5 * kPi * reach * reach * f.perimeter + (4.0 / 3.0) * kPi * reach * reach * reach * n;
  return volume / (h * h * h);
}

/**
 * Cell side in pointer radii. Larger cells mean a smaller index (the part every query reads, kept in cache) but
 * more candidates per cell. About pi reach^2 n / area triangles lie within reach of a surface cell's centre; up to
 * about 13 of them the larger cells answer faster, beyond that slower, so the side is 3 r or 2.5 r when that
 * estimate stays under 13, else 2 r.
 */
double cellFactor(const MeshFigures& f, std::size_t triangles, double radius) {
  for (double factor : {3.0, 2.5}) {
    const double r = radius * (1.0 + kHalfDiagonal * factor);
    if (3.141592653589793 * r * r * static_cast<double>(triangles) <= 13.0 * f.area) return factor;
  }
  return kCellFactor;
}

/**
 * Expected non-empty cells of side h: those whose centres lie within reach of the surface, about the shell
 * 2 reach A (plus a ball's volume, for a mesh small against reach), at most one per candidate.
 */
double estimatedCells(const MeshFigures& f, double candidates, double reach, double h) {
  constexpr double kPi = 3.141592653589793;
  return std::min(candidates, (2.0 * reach * f.area + (4.0 / 3.0) * kPi * reach * reach * reach) / (h * h * h));
}

/**
 * Expected bytes of a grid of side h: 8 per candidate; per non-empty cell its header entry (8), its slab (8) and its
 * header's index (4); and the dense index's bit words (16 bytes per 64 cells of the box).
 */
double estimatedBytes(const MeshFigures& f, std::size_t triangles, double radius, double h) {
  const double reach = radius + kHalfDiagonal * h;
  const double candidates = estimatedCandidates(f, triangles, reach, h);
  const Vec3 box = (f.bounds.sizes() + Vec3::Constant(2.0 * (reach + h))) / h;
  return 8.0 * candidates + 20.0 * estimatedCells(f, candidates, reach, h) + 0.25 * box.prod();
}

/** Expected candidates of a non-empty cell of side h (what a query scans). */
double estimatedPerCell(const MeshFigures& f, std::size_t triangles, double radius, double h) {
  const double reach = radius + kHalfDiagonal * h;
  const double candidates = estimatedCandidates(f, triangles, reach, h);
  return candidates / std::max(1.0, estimatedCells(f, candidates, reach, h));
}

/**
 * The cell side: grown until the grid has at most kMaxDim - 4 cells per axis and about maxEntries candidates (the hard
 * limit on memory); then, while the grid would take more than bytesPerTriangle per triangle, grown further as long as
 * a cell keeps at most kCheapCell candidates, up to kCoarsest times the side the queries chose. A mesh of large
 * triangles (a few per cell) is answered as fast by coarser cells and takes a fraction of the memory and build time;
 * a mesh whose cells are already crowded (small or long thin triangles) keeps the side its queries need; and beyond
 * a few times the chosen side the cells' bounds and slabs (their slack grows with the side) let through triangles
 * that finer cells drop: on an ellipsoid of 20 r triangles, cells of 2.4 times the side answered free and in-contact
 * probes as fast as before, cells of 3.8 times 12% slower free and 25% slower on coherent paths (bench/README.md).
 */
double cellSide(const MeshFigures& f, std::size_t triangles, double radius, double maxEntries,
                double bytesPerTriangle) {
  constexpr double kCheapCell = 16.0, kCoarsest = 2.5;
  double h = cellFactor(f, triangles, radius) * radius;
  const double extent = f.bounds.sizes().maxCoeff() + 2.0 * (radius + 2.0 * h);
  h = std::max(h, extent / static_cast<double>(kMaxDim - 4));
  for (int guard = 0; guard < 64; ++guard) {
    if (estimatedCandidates(f, triangles, radius + kHalfDiagonal * h, h) <= maxEntries) break;
    h *= 1.25;
  }
  const double maxBytes = bytesPerTriangle * static_cast<double>(triangles);
  const double cap = kCoarsest * h;
  for (int guard = 0; guard < 64 && 1.25 * h <= cap; ++guard) {
    if (estimatedBytes(f, triangles, radius, h) <= maxBytes ||
        estimatedPerCell(f, triangles, radius, 1.25 * h) > kCheapCell)
      break;
    h *= 1.25;
  }
  return h;
}

/** Where the cells lie, and how far from a cell's centre its candidates reach. */
struct Layout {
  double h;      // cell side
  double inv;    // 1 / h
  double reach;  // radius + half diagonal + pad: the candidates of a cell are within it of the centre
  Vec3 origin;   // lower corner of cell (0, 0, 0)
  std::int64_t dims[3];

  Vec3 centre(std::int64_t x, std::int64_t y, std::int64_t z) const {
    return origin +
           (Vec3(static_cast<double>(x), static_cast<double>(y), static_cast<double>(z)) + Vec3::Constant(0.5)) * h;
  }
};

/** The cells of side h around the mesh, with a margin of reach + h on every side. */
Layout placeCells(const MeshFigures& f, double radius, double h) {
  Layout g;
  g.h = h;
  g.inv = 1.0 / h;
  g.reach = radius + kHalfDiagonal * h + f.pad;
  g.origin = f.bounds.min() - Vec3::Constant(g.reach + h);
  for (int k = 0; k < 3; ++k)
    g.dims[k] = std::min<std::int64_t>(
        kMaxDim, static_cast<std::int64_t>(std::ceil((f.bounds.sizes()[k] + 2 * (g.reach + h)) * g.inv)) + 1);
  return g;
}

/**
 * The cells a grid of these parameters takes: the constructor's choice, which CellGrid::forLevel compares with another
 * grid's (the memory budget: about entriesPerTriangle candidates a triangle at most, bytesPerTriangle where coarser
 * cells cost no speed, cellSide).
 */
Layout chooseCells(const MeshFigures& f, std::size_t triangles, double radius, double entriesPerTriangle,
                   double bytesPerTriangle) {
  const double maxEntries = std::max(1e6, entriesPerTriangle * static_cast<double>(triangles));
  return placeCells(f, radius, cellSide(f, triangles, radius, maxEntries, bytesPerTriangle));
}

/** The cells (unclamped: the floors of the coordinates) that triangle t's box grown by reach spans. */
void spannedCells(const TriangleMesh& mesh, const Layout& g, std::size_t t, std::int64_t l[3], std::int64_t u[3]) {
  const Vec3 &a = mesh.vertex(t, 0), &b = mesh.vertex(t, 1), &c = mesh.vertex(t, 2);
  const Vec3 lo = a.cwiseMin(b).cwiseMin(c) - Vec3::Constant(g.reach);
  const Vec3 hi = a.cwiseMax(b).cwiseMax(c) + Vec3::Constant(g.reach);
  for (int k = 0; k < 3; ++k) {
    l[k] = static_cast<std::int64_t>(std::floor((lo[k] - g.origin[k]) * g.inv));
    u[k] = static_cast<std::int64_t>(std::floor((hi[k] - g.origin[k]) * g.inv));
  }
}

// ---- Candidates ----

/** A triangle listed by a cell, before packing (20 bytes: the key in two halves, so nothing is padded). */
struct Candidate {
  std::uint32_t keyLow, keyHigh;
  std::uint32_t triangle;
  std::uint8_t distance;  // distanceCode: what the entry keeps, and all the query's early exit reads
  std::uint8_t finer;     // the distance within its code, in 256ths of the unit: the order within a code
  std::int8_t direction[3];

  std::uint64_t key() const { return std::uint64_t{keyHigh} << 32 | keyLow; }
};

/**
 * Sorts candidates collected in ascending triangle order into the entries' order (by cell, then by distance: its
 * code, then the finer byte, then by triangle) with one stable radix sort
 * (through scratch): a pass over the finer byte, one over the 8-bit distance code, then the keys cut down to the
 * bits their x, y and z ranges use (which keeps their order), 11 bits a pass. Stable, so candidates equal in all
 * three keep the triangles' order. A slice's
 * candidates are millions: this is linear in them, where sorting each cell's run took a sixth of the grid's build
 * on meshes whose triangles are far smaller than a cell (hundreds of candidates a cell).
 */
void sortCandidates(ReallocArray<Candidate>& c, ReallocArray<Candidate>& scratch) {
  const std::size_t n = c.size();
  if (n < 2) return;
  constexpr std::uint64_t kAxis = (1ull << CellGrid::kBits) - 1;
  std::uint64_t lo[3] = {kAxis, kAxis, kAxis}, hi[3] = {0, 0, 0};
  for (std::size_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) {
      const std::uint64_t v = (c[i].key() >> (k * CellGrid::kBits)) & kAxis;
      lo[k] = std::min(lo[k], v);
      hi[k] = std::max(hi[k], v);
    }
  int shift[3], total = 0;
  for (int k = 0; k < 3; ++k) {
    shift[k] = total;
    total += hi[k] > lo[k] ? 64 - __builtin_clzll(hi[k] - lo[k]) : 0;
  }
  auto compact = [&](std::uint64_t key) {
    std::uint64_t out = 0;
    for (int k = 0; k < 3; ++k) out |= (((key >> (k * CellGrid::kBits)) & kAxis) - lo[k]) << shift[k];
    return out;
  };
  constexpr int kDigit = 11;
  constexpr std::size_t kBuckets = std::size_t{1} << kDigit;
  scratch.resize(n);
  Candidate* from = c.data();
  Candidate* to = scratch.data();
  std::vector<std::size_t> count(kBuckets);
  auto pass = [&](auto&& digit) {
    std::fill(count.begin(), count.end(), 0);
    for (std::size_t i = 0; i < n; ++i) ++count[digit(from[i])];
    std::size_t sum = 0;
    for (std::size_t& b : count) sum += std::exchange(b, sum);
    for (std::size_t i = 0; i < n; ++i) to[count[digit(from[i])]++] = from[i];
    std::swap(from, to);
  };
  pass([](const Candidate& x) { return std::size_t{x.finer}; });
  pass([](const Candidate& x) { return std::size_t{x.distance}; });
  for (int at = 0; at < total; at += kDigit)
    pass([&](const Candidate& x) { return static_cast<std::size_t>((compact(x.key()) >> at) & (kBuckets - 1)); });
  if (from != c.data()) std::copy(from, from + n, c.data());
}

std::uint64_t cellKey(std::int64_t x, std::int64_t y, std::int64_t z) {
  return static_cast<std::uint64_t>(x) | static_cast<std::uint64_t>(y) << CellGrid::kBits |
         static_cast<std::uint64_t>(z) << (2 * CellGrid::kBits);
}

/** Lists, for triangles, the cells whose centre is within reach of them (an exact test: no candidate is missed). */
class CandidateCollector {
 public:
  CandidateCollector(const TriangleMesh& mesh, const Layout& g, const MeshFigures& f, double distanceUnit)
      : mesh_(mesh),
        g_(g),
        unit_(distanceUnit),
        finerScale_(256.0 / distanceUnit),
        planeLimit_(g.reach + 1e-9 * g.h + f.pad),  // slack for the rounding of the plane distance
        tiny_(std::max(1e-9 * g.h, 4e-9 * f.magnitude)),
        avx2_(detail::packetAvx2()) {}

  /** Appends the candidates of the triangles [begin, end) in the cells of z in [zBegin, zEnd). */
  void collect(const std::uint32_t* begin, const std::uint32_t* end, std::int64_t zBegin, std::int64_t zEnd,
               ReallocArray<Candidate>& out) const {
    for (const std::uint32_t* it = begin; it != end; ++it) collectTriangle(*it, zBegin, zEnd, out);
  }

 private:
  void collectTriangle(std::size_t t, std::int64_t zBegin, std::int64_t zEnd, ReallocArray<Candidate>& out) const {
    const Vec3 &a = mesh_.vertex(t, 0), &b = mesh_.vertex(t, 1), &c = mesh_.vertex(t, 2);
    const Vec3& n = mesh_.normals[t];
    const bool planar = !n.isZero(0.0);
    // The triangle's ball (centroid, farthest corner): a centre farther than reach from it is farther from the
    // triangle, which drops the corners of the triangle's box before the closest-point computation.
    const Vec3 mid = (a + b + c) * (1.0 / 3.0);
    const double ball =
        std::sqrt(std::max({(a - mid).squaredNorm(), (b - mid).squaredNorm(), (c - mid).squaredNorm()})) + planeLimit_;
    const double ball2 = ball * ball;
    std::int64_t l[3], u[3];
    spannedCells(mesh_, g_, t, l, u);
    for (int k = 0; k < 3; ++k) {
      l[k] = std::max<std::int64_t>(0, l[k]);
      u[k] = std::min<std::int64_t>(g_.dims[k] - 1, u[k]);
    }
    l[2] = std::max(l[2], zBegin);
    u[2] = std::min(u[2], zEnd - 1);
    if (l[2] > u[2]) return;
    // The cells that pass both bounds, four at a time: their closest points in one AVX2 pass where the CPU has it
    // (bit for bit the scalar function's; a small triangle's cells around it fall in different regions, whose
    // branches would mispredict).
    Vec3 centres[4];
    std::uint64_t keys[4];
    unsigned pending = 0;
    auto flush = [&] {
      unsigned computed = 0, encoded = 0;
      detail::ClosestPoints4 q;
      detail::GridEntries4 e;
#if defined(CLOD_PACKET_AVX2)
      if (avx2_ && pending > 1) {
        const Vec3* at[4];
        for (unsigned k = 0; k < 4; ++k) at[k] = &centres[std::min(k, pending - 1)];
        computed = detail::closestPointsAvx2(at, a, b, c, q);
        // Their entries' bytes too (the distance's square root and codes, the direction's division and rounding).
        if (computed != 0) encoded = computed & detail::gridEntriesAvx2(at, q, unit_, finerScale_, tiny_, e);
      }
#endif
      for (unsigned k = 0; k < pending; ++k) {
        if (encoded & (1u << k)) {
          if (e.distance[k] <= g_.reach)
            out.push_back(entry(keys[k], static_cast<std::uint32_t>(t), e.code[k], e.finer[k], e.direction[k]));
          continue;
        }
        const Vec3 closest =
            computed & (1u << k) ? Vec3(q.q[0][k], q.q[1][k], q.q[2][k]) : closestPointOnTriangle(centres[k], a, b, c);
        const Vec3 toCentre = centres[k] - closest;
        const double d = toCentre.norm();
        if (d <= g_.reach) out.push_back(candidate(keys[k], static_cast<std::uint32_t>(t), toCentre, d));
      }
      pending = 0;
    };
    auto add = [&](const Vec3& centre, std::int64_t x, std::int64_t y, std::int64_t z) {
      centres[pending] = centre;
      keys[pending] = cellKey(x, y, z);
      if (++pending == 4) flush();
    };
#if defined(CLOD_PACKET_AVX2)
    // Four cells of a column at a time through both bounds (most cells of the box fail one, in no pattern a branch
    // predicts); the same bounds on the same centres as below.
    if (avx2_ && u[2] - l[2] >= 3) {
      const detail::TriangleBounds bounds{planar, n, a, planeLimit_, mid, ball2};
      for (std::int64_t x = l[0]; x <= u[0]; ++x)
        for (std::int64_t y = l[1]; y <= u[1]; ++y) {
          const Vec3 column = g_.centre(x, y, 0);
          for (std::int64_t z = l[2]; z <= u[2]; z += 4) {
            const std::int64_t count = std::min<std::int64_t>(4, u[2] - z + 1);
            for (unsigned m = detail::columnCellsAvx2(column.x(), column.y(), g_.origin.z(), g_.h, z, bounds) &
                              ((1u << count) - 1u);
                 m != 0; m &= m - 1) {
              const std::int64_t at = z + __builtin_ctz(m);
              add(g_.centre(x, y, at), x, y, at);
            }
          }
        }
      flush();
      return;
    }
#endif
    for (std::int64_t x = l[0]; x <= u[0]; ++x)
      for (std::int64_t y = l[1]; y <= u[1]; ++y)
        for (std::int64_t z = l[2]; z <= u[2]; ++z) {
          const Vec3 centre = g_.centre(x, y, z);
          // The distance to the plane is a lower bound of the distance to the triangle: most cells of
          // the box are rejected by it before the closest-point computation.
          if (planar && std::abs(n.dot(centre - a)) > planeLimit_) continue;
          if ((centre - mid).squaredNorm() > ball2) continue;
          add(centre, x, y, z);
        }
    flush();
  }

  /**
   * The supporting-plane bound needs the true direction to the centre. The closest point carries an error
   * of a few ulps of the coordinates, so its direction is trusted only when d is far above it (the bound
   * then errs by < 1e-7 |p - q|, inside the slack); otherwise the entry keeps the trivial bound
   * 0 <= distance (dc = 0, u = 0): never skipped, never wrong.
   */
  Candidate candidate(std::uint64_t key, std::uint32_t t, const Vec3& toCentre, double d) const {
    const std::int8_t none[3] = {0, 0, 0};
    if (!(d > tiny_)) return entry(key, t, 0, 0, none);
    const Vec3 dir = toCentre / d;
    const float rounded = roundDown(d);
    const std::uint8_t code = distanceCode(rounded, unit_);
    const std::int8_t direction[3] = {quantiseDirection(dir.x()), quantiseDirection(dir.y()),
                                      quantiseDirection(dir.z())};
    return entry(key, t, code, finerCode(rounded, code, unit_, finerScale_), direction);
  }
  static Candidate entry(std::uint64_t key, std::uint32_t t, std::uint8_t code, std::uint8_t finer,
                         const std::int8_t direction[3]) {
    const auto low = static_cast<std::uint32_t>(key), high = static_cast<std::uint32_t>(key >> 32);
    return {low, high, t, code, finer, {direction[0], direction[1], direction[2]}};
  }

  const TriangleMesh& mesh_;
  const Layout& g_;
  double unit_;        // of the distance codes
  double finerScale_;  // 256 / unit_: the finer byte's steps
  double planeLimit_;
  double tiny_;
  bool avx2_;  // the closest points four at a time
};

// ---- Slices of z ----

/** The z range of cells that triangle t's box grown by reach spans, and how many columns of x and y. */
void zSpan(const TriangleMesh& mesh, const Layout& g, std::size_t t, std::int64_t& l2, std::int64_t& u2,
           double& columns) {
  std::int64_t l[3], u[3];
  spannedCells(mesh, g, t, l, u);
  for (int k = 0; k < 3; ++k) {
    l[k] = std::clamp<std::int64_t>(l[k], 0, g.dims[k] - 1);
    u[k] = std::clamp<std::int64_t>(u[k], 0, g.dims[k] - 1);
  }
  l2 = l[2];
  u2 = u[2];
  columns = static_cast<double>((u[0] - l[0] + 1) * (u[1] - l[1] + 1));
}

/**
 * The first layer of each of about `slices` slices of z holding equal shares of the candidates (estimated per
 * layer of cells from the triangles' grown boxes), then dims[2].
 */
std::vector<std::int64_t> sliceStarts(const TriangleMesh& mesh, const Layout& g, std::int64_t slices) {
  std::vector<std::int64_t> starts{0};
  if (slices > 1) {
    std::vector<double> layer(static_cast<std::size_t>(g.dims[2]) + 1, 0.0);
    for (std::size_t t = 0; t < mesh.size(); ++t) {
      std::int64_t l2, u2;
      double w;
      zSpan(mesh, g, t, l2, u2, w);
      layer[static_cast<std::size_t>(l2)] += w;
      layer[static_cast<std::size_t>(u2) + 1] -= w;
    }
    double running = 0.0, sum = 0.0;
    for (std::int64_t z = 0; z < g.dims[2]; ++z) sum += (running += layer[static_cast<std::size_t>(z)]);
    running = 0.0;
    double cumulative = 0.0;
    for (std::int64_t z = 0; z < g.dims[2]; ++z) {
      cumulative += (running += layer[static_cast<std::size_t>(z)]);
      if (cumulative >= sum * static_cast<double>(starts.size()) / static_cast<double>(slices) && z + 1 < g.dims[2])
        starts.push_back(z + 1);
    }
  }
  starts.push_back(g.dims[2]);
  return starts;
}

/** Per slice, the triangles whose z range meets it (most meet one slice): slice s lists [first[s], first[s + 1]). */
struct SliceTriangles {
  std::vector<std::uint32_t> first;
  std::vector<std::uint32_t> triangles;
};

SliceTriangles trianglesPerSlice(const TriangleMesh& mesh, const Layout& g, const std::vector<std::int64_t>& starts) {
  const std::size_t count = starts.size() - 1;
  SliceTriangles s;
  s.first.assign(count + 1, 0);
  if (count == 1) {
    s.triangles.resize(mesh.size());
    for (std::size_t t = 0; t < mesh.size(); ++t) s.triangles[t] = static_cast<std::uint32_t>(t);
    s.first[1] = static_cast<std::uint32_t>(mesh.size());
    return s;
  }
  // Each triangle's first and last slice, found once; counted and listed by two threads over the two halves of the
  // triangles, the first half's before the second's in every slice: each slice lists its triangles in ascending order,
  // as one thread would.
  const std::size_t n = mesh.size(), half = n / 2;
  std::vector<std::uint32_t> span(2 * n);
  std::vector<std::uint32_t> counts[2] = {std::vector<std::uint32_t>(count, 0), std::vector<std::uint32_t>(count, 0)};
  detail::runParallel(2, [&](unsigned part) {
    std::vector<std::uint32_t>& counted = counts[part];
    for (std::size_t t = part ? half : 0; t < (part ? n : half); ++t) {
      std::int64_t l2, u2;
      double w;
      zSpan(mesh, g, t, l2, u2, w);
      const auto sa =
          static_cast<std::uint32_t>(std::upper_bound(starts.begin(), starts.end(), l2) - starts.begin()) - 1;
      const auto sb =
          static_cast<std::uint32_t>(std::upper_bound(starts.begin(), starts.end(), u2) - starts.begin()) - 1;
      span[2 * t] = sa;
      span[2 * t + 1] = sb;
      for (std::uint32_t q = sa; q <= sb; ++q) ++counted[q];
    }
  });
  for (std::size_t q = 0; q < count; ++q) s.first[q + 1] = s.first[q] + counts[0][q] + counts[1][q];
  s.triangles.resize(s.first[count]);
  detail::runParallel(2, [&](unsigned part) {
    std::vector<std::uint32_t> fill(count);
    for (std::size_t q = 0; q < count; ++q) fill[q] = s.first[q] + (part ? counts[0][q] : 0);
    for (std::size_t t = part ? half : 0; t < (part ? n : half); ++t)
      for (std::uint32_t q = span[2 * t]; q <= span[2 * t + 1]; ++q)
        s.triangles[fill[q]++] = static_cast<std::uint32_t>(t);
  });
  return s;
}

/** One slice's candidates, sorted (by one thread), and how many cells they fill. */
struct SliceCandidates {
  ReallocArray<Candidate> list, scratch;  // scratch: the sort's buffer
  std::size_t cells = 0;

  void collect(const CandidateCollector& collector, const std::uint32_t* triangles, std::size_t count,
               std::int64_t zBegin, std::int64_t zEnd) {
    list.clear();
    collector.collect(triangles, triangles + count, zBegin, zEnd, list);
    sortCandidates(list, scratch);
    cells = 0;
    std::uint64_t last = CellGrid::kOutside;
    for (const Candidate& c : list) {
      cells += c.key() != last;
      last = c.key();
    }
  }
  /** Entries the slice's cells take: a header per cell and its candidates. */
  std::size_t entries() const { return list.size() + cells; }
};

// ---- Packing the entries ----

/** The key and the header position (in the entries) of every cell, in key order. */
struct CellTables {
  std::vector<std::uint64_t> keys;
  std::vector<std::uint64_t> headers;

  void append(const CellTables& more) {
    keys.insert(keys.end(), more.keys.begin(), more.keys.end());
    headers.insert(headers.end(), more.headers.begin(), more.headers.end());
  }
};

/**
 * Counts the distinct spheres listing one cell's candidates at a time (each triangle's first sphere), for the cell's
 * header: open() a cell, add() its candidates, count().
 */
class SphereCounter {
 public:
  SphereCounter(const std::vector<std::uint32_t>& sphereOf, std::size_t spheres)
      : sphereOf_(sphereOf), cellOfSphere_(spheres + 1, kNoCell) {}
  void open() {
    spheres_ = 0;
    ++cell_;
  }
  void add(std::uint32_t triangle) {
    // A triangle no sphere lists (kept by a caller's set that breaks the coverage invariant) counts as one more.
    std::uint32_t& seen = cellOfSphere_[std::min<std::size_t>(sphereOf_[triangle], cellOfSphere_.size() - 1)];
    spheres_ += seen != cell_;
    seen = cell_;
  }
  std::uint32_t count() const { return spheres_; }

 private:
  static constexpr std::uint32_t kNoCell = 0;   // no cell yet: cells are numbered from 1
  const std::vector<std::uint32_t>& sphereOf_;  // the first sphere listing each triangle
  std::vector<std::uint32_t> cellOfSphere_;     // per sphere (and one for none), the last cell listing it
  std::uint32_t cell_ = kNoCell;                // the open cell's number
  std::uint32_t spheres_ = 0;                   // distinct spheres of the open cell so far
};

/** Writes a cell's header: its candidate count, then in the next 4 bytes the number of distinct spheres. */
void writeHeader(CellGrid::Entry& e, std::uint32_t count, std::uint32_t spheres) {
  e = CellGrid::Entry{count, 0, {0, 0, 0}};
  std::memcpy(reinterpret_cast<unsigned char*>(&e) + 4, &spheres, sizeof spheres);
}

/**
 * Writes the cells of sorted candidates into the entries: per cell a header (writeHeader) followed by its
 * candidates. One packer per thread.
 */
class CellPacker {
 public:
  CellPacker(const std::vector<std::uint32_t>& sphereOf, std::size_t spheres) : counter_(sphereOf, spheres) {}

  /** Writes the slice's cells at entries[at, at + slice.entries()); their keys and headers go to tables. */
  void pack(const SliceCandidates& slice, CellGrid::Entry* entries, std::size_t at, CellTables& tables) {
    tables.keys.clear();
    tables.headers.clear();
    std::uint64_t last = CellGrid::kOutside;
    std::size_t header = at;
    auto close = [&] {
      if (last != CellGrid::kOutside)
        writeHeader(entries[header], static_cast<std::uint32_t>(at - header - 1), counter_.count());
    };
    for (const Candidate& c : slice.list) {
      if (c.key() != last) {
        close();
        counter_.open();
        header = at++;
        tables.headers.push_back(header);
        tables.keys.push_back(c.key());
        last = c.key();
      }
      entries[at++] = Entry{c.triangle, c.distance, {c.direction[0], c.direction[1], c.direction[2]}};
      counter_.add(c.triangle);
    }
    close();
  }

 private:
  SphereCounter counter_;
};

/**
 * Collects, sorts and packs the candidates of every cell into entries. Candidates are collected in slices of z
 * (keys sort by z first, so slices come in key order), two slices at a time, one per thread: each thread collects
 * and sorts its slice, then both write their cells straight onto the end of the entries, side by side. Only two
 * slices' 20-byte candidates are held beside the 8-byte entries, and the entries grow by realloc (pages moved, not
 * copied).
 */
CellTables packCells(const TriangleMesh& mesh, const ClodSphereSet& set, const MeshFigures& f, const Layout& g,
                     double sliceCandidates, double distanceUnit, ReallocArray<Entry>& entries) {
  const double expected = estimatedCandidates(f, mesh.size(), g.reach, g.h);
  const std::int64_t slices =
      std::clamp<std::int64_t>(2 * (static_cast<std::int64_t>(expected / std::max(1.0, sliceCandidates)) + 1), 1,
                               std::min<std::int64_t>(512, g.dims[2]));
  // Every triangle is listed by a sphere: the coverage invariant.
  const std::vector<std::uint32_t> sphereOf = firstSphereOfTriangles(set, mesh.size());
  const std::vector<std::int64_t> starts = sliceStarts(mesh, g, slices);
  const SliceTriangles lists = trianglesPerSlice(mesh, g, starts);
  const CandidateCollector collector(mesh, g, f, distanceUnit);
  SliceCandidates work[2];
  CellPacker packers[2] = {CellPacker(sphereOf, set.size()), CellPacker(sphereOf, set.size())};
  CellTables sliceTables[2], tables;
  const std::size_t count = starts.size() - 1;
  for (std::size_t first = 0; first < count; first += 2) {
    const unsigned pair = first + 1 < count ? 2u : 1u;
    detail::runParallel(pair, [&](unsigned part) {
      const std::size_t slice = first + part;
      work[part].collect(collector, lists.triangles.data() + lists.first[slice],
                         lists.first[slice + 1] - lists.first[slice], starts[slice], starts[slice + 1]);
    });
    std::size_t at[2];
    at[0] = entries.size();
    at[1] = at[0] + work[0].entries();
    entries.resize(at[1] + (pair > 1 ? work[1].entries() : 0));
    detail::runParallel(
        pair, [&](unsigned part) { packers[part].pack(work[part], entries.data(), at[part], sliceTables[part]); });
    for (unsigned part = 0; part < pair; ++part) tables.append(sliceTables[part]);
  }
  return tables;
}

// ---- Proofs of no contact ----

/** A convex polygon of up to 3 + 14 corners: a triangle clipped by the 14 planes of a cell's region. */
struct Polygon {
  Vec3 corner[24];
  int count = 0;
};

/**
 * The part of triangle (a, b, c) (relative to a cell's centre) inside the region |x|_inf <= half, |x|_1 <= diamond
 * (Sutherland-Hodgman against those 6 + 8 planes), in out; false when nothing of the triangle is inside.
 */
bool clipToRegion(const Vec3& a, const Vec3& b, const Vec3& c, double half, double diamond, Polygon& out) {
  // Most candidates of a fine mesh lie wholly inside the region (no clipping) or wholly outside one
  // of its planes (nothing inside).
  auto inside = [&](const Vec3& v) { return v.cwiseAbs().maxCoeff() <= half && v.lpNorm<1>() <= diamond; };
  out.corner[0] = a;
  out.corner[1] = b;
  out.corner[2] = c;
  out.count = 3;
  if (inside(a) && inside(b) && inside(c)) return true;
  for (int k = 0; k < 3; ++k)
    if ((a[k] > half && b[k] > half && c[k] > half) || (a[k] < -half && b[k] < -half && c[k] < -half)) return false;
  Polygon other;
  Polygon* in = &out;
  Polygon* to = &other;
  // Keeps the part where along(corner) <= limit; each corner's value is computed once. The planes' normals have
  // components 0 and +-1, so along() is the dot product with the normal exactly (the zero terms add nothing).
  double value[24];
  auto clip = [&](auto&& along, double limit) {
    const int count = in->count;
    bool cut = false;
    for (int i = 0; i < count; ++i) {
      value[i] = along(in->corner[i]) - limit;
      cut |= value[i] > 0.0;
    }
    if (!cut) return true;  // every corner kept: the polygon as it is
    int m = 0;
    for (int i = 0; i < count; ++i) {
      const int j = i + 1 == count ? 0 : i + 1;
      const Vec3& P = in->corner[i];
      const double dp = value[i], dq = value[j];
      if (dp <= 0.0) to->corner[m++] = P;
      if ((dp < 0.0 && dq > 0.0) || (dp > 0.0 && dq < 0.0))
        to->corner[m++] = P + (dp / (dp - dq)) * (in->corner[j] - P);
    }
    to->count = m;
    std::swap(in, to);
    return m > 0;
  };
  for (int k = 0; k < 3; ++k) {
    if (!clip([k](const Vec3& v) { return v[k]; }, half)) return false;
    if (!clip([k](const Vec3& v) { return -v[k]; }, half)) return false;
  }
  for (int q = 0; q < 8; ++q) {
    const double sx = q & 1 ? -1.0 : 1.0, sy = q & 2 ? -1.0 : 1.0, sz = q & 4 ? -1.0 : 1.0;
    if (!clip([&](const Vec3& v) { return sx * v.x() + sy * v.y() + sz * v.z(); }, diamond)) return false;
  }
  if (in != &out) out = *in;  // a plane that cut nothing left the polygon where it was
  return true;
}

/**
 * Builds each cell's slab. A triangle point within radius R of a point of the cell is within h / 2 + R of the
 * centre along each axis and within 3 h / 2 + sqrt(3) R in the L1 norm (the cell grown by a ball of radius R
 * lies in that box and that octahedron): the candidates clipped to both span the slab.
 */
class SlabBuilder {
 public:
  SlabBuilder(const TriangleMesh& mesh, double h, double radius, double pad, double unit)
      : mesh_(mesh),
        half_((0.5 * h + radius) * (1.0 + 1e-9) + pad),
        diamond_((1.5 * h + kSqrt3 * radius) * (1.0 + 1e-9) + 2.0 * pad),
        unit_(unit) {}

  /**
   * The slab of the cell at centre, exactly as the query uses it (8-bit normal): the narrower of two, along the
   * normal of the first candidate and along the mean normal of the candidates nearest the centre (within 1/16 of
   * the reach of the first: on a curved surface their mean is closer to the surface's normal over the cell). Both
   * ranges come from one pass, each candidate clipped at most once.
   */
  CellGrid::CellRef slab(const Vec3& centre, const Entry* candidates, std::uint32_t count) const {
    Vec3 sum = Vec3::Zero();
    for (std::uint32_t i = 0; i < count && candidates[i].distance <= candidates[0].distance + 16; ++i)
      sum += mesh_.normals[candidates[i].triangle];
    Range along[2] = {Range(mesh_.normals[candidates[0].triangle]),
                      Range(sum.norm() > 0.5 ? Vec3(sum.normalized()) : Vec3::Zero())};
    Polygon part;
    for (std::uint32_t i = 0; i < count; ++i) {
      const std::size_t t = candidates[i].triangle;
      const Vec3 a = mesh_.vertex(t, 0) - centre, b = mesh_.vertex(t, 1) - centre, c = mesh_.vertex(t, 2) - centre;
      // The clipped part's range lies within the corners' range: when that adds nothing, neither can the clip
      // (the same slab, without clipping the many small triangles of a crowded cell).
      if (along[0].holds(a, b, c) && along[1].holds(a, b, c)) continue;
      if (!clipToRegion(a, b, c, half_, diamond_, part)) continue;
      for (Range& r : along)
        for (int k = 0; k < part.count; ++k) r.add(part.corner[k]);
    }
    const CellGrid::CellRef first = along[0].slab(unit_), mean = along[1].slab(unit_);
    return mean.halfWidth < first.halfWidth ? mean : first;
  }

 private:
  /** The range of the candidates along an 8-bit normal (none for a zero one). */
  struct Range {
    explicit Range(const Vec3& n) : m8{quantiseDirection(n.x()), quantiseDirection(n.y()), quantiseDirection(n.z())} {
      m = n.isZero(0.0) ? Vec3::Zero() : Vec3(m8[0] / 127.0, m8[1] / 127.0, m8[2] / 127.0);
    }
    bool holds(const Vec3& a, const Vec3& b, const Vec3& c) const {
      if (m.isZero(0.0)) return true;
      const double x = m.dot(a), y = m.dot(b), z = m.dot(c);
      return std::min({x, y, z}) >= lo && std::max({x, y, z}) <= hi;
    }
    void add(const Vec3& v) {
      const double x = m.dot(v);
      lo = std::min(lo, x);
      hi = std::max(hi, x);
    }
    /** The slab (none for a zero normal, no candidate in the region, or one too wide for the 16-bit fields). */
    CellGrid::CellRef slab(double unit) const {
      CellGrid::CellRef ref{};
      ref.offset = 0;
      ref.halfWidth = 0xffff;  // no slab
      if (m.isZero(0.0) || !(lo <= hi)) return ref;
      const double mid = std::round(0.5 * (lo + hi) / unit);
      const double width = std::ceil(std::max(hi - mid * unit, mid * unit - lo) / unit) + 1.0;
      if (std::abs(mid) <= 32767.0 && width <= 65535.0) {
        for (int j = 0; j < 3; ++j) ref.normal[j] = m8[j];
        ref.offset = static_cast<std::int16_t>(mid);
        ref.halfWidth = static_cast<std::uint16_t>(width);
      }
      return ref;
    }
    std::int8_t m8[3];
    Vec3 m;
    double lo = std::numeric_limits<double>::infinity(), hi = -std::numeric_limits<double>::infinity();
  };

  const TriangleMesh& mesh_;
  const double half_, diamond_, unit_;
};

}  // namespace

CellGrid::CellGrid(const TriangleMesh& mesh, const ClodSphereSet& set, double radius, double entriesPerTriangle,
                   Index index, double sliceCandidates, double bytesPerTriangle) {
  if (!(radius > 0.0) || !std::isfinite(radius))
    throw InvalidParameter("cell grid radius must be finite and > 0, got " + std::to_string(radius));
  const MeshFigures figures = measure(mesh);
  const Layout layout = chooseCells(figures, mesh.size(), radius, entriesPerTriangle, bytesPerTriangle);
  const double h = layout.h;
  radius_ = radius;
  cell_ = h;
  inv_ = layout.inv;
  origin_ = layout.origin;
  std::copy(layout.dims, layout.dims + 3, dims_);
  // The 8-bit direction times |p - centre| <= h sqrt(3) / 2, plus float rounding (< 1e-6 h).
  slack_ = (kDirectionError * kHalfDiagonal + 1e-6) * h + figures.pad;
  unit_ = h / 8192.0;
  // Rounding of the slab test's products and of the clipped points: relative 1e-9 of the cell, plus pad.
  slabPad_ = 1e-9 * h + 4.0 * figures.pad;
  distanceUnit_ = layout.reach / 255.0;

  const CellTables tables = packCells(mesh, set, figures, layout, sliceCandidates, distanceUnit_, entries_);
  entries_.shrink();
  cellCount_ = tables.keys.size();
  for (const std::uint64_t header : tables.headers) largest_ = std::max(largest_, entries_[header].triangle);
  std::vector<CellRef> refs(cellCount_);
  const SlabBuilder slabs(mesh, h, radius, figures.pad, unit_);
  auto fill = [&](std::size_t begin, std::size_t end) {
    for (std::size_t k = begin; k < end; ++k) {
      const Entry* header = entries_.data() + tables.headers[k];
      refs[k] = slabs.slab(centreOf(tables.keys[k]), header + 1, header->triangle);
    }
  };
  detail::runParallel(2, [&](unsigned part) { part ? fill(cellCount_ / 2, cellCount_) : fill(0, cellCount_ / 2); });

  if (useDenseIndex(index, mesh.size()))
    buildDenseIndex(tables.keys, tables.headers, refs);
  else
    buildHashedIndex(tables.keys, tables.headers, refs);
}

CellGrid CellGrid::forLevel(const CellGrid& sameMesh, const TriangleMesh& mesh, const ClodSphereSet& set, double radius,
                            double entriesPerTriangle, Index index, double sliceCandidates, double bytesPerTriangle,
                            bool* reused) {
  if (reused) *reused = false;
  if (!sameMesh.empty() && sameMesh.radius_ == radius) {
    // The cells this level's build would choose: the same as the other grid's, then the same candidates.
    const Layout layout = chooseCells(measure(mesh), mesh.size(), radius, entriesPerTriangle, bytesPerTriangle);
    const bool sameCells = layout.h == sameMesh.cell_ && layout.origin == sameMesh.origin_ &&
                           std::equal(layout.dims, layout.dims + 3, sameMesh.dims_) &&
                           sameMesh.dense() == sameMesh.useDenseIndex(index, mesh.size());
    if (sameCells) {
      CellGrid grid = sameMesh;
      if (grid.recountSpheres(set, mesh.size())) {
        if (reused) *reused = true;
        return grid;
      }
    }
  }
  return CellGrid(mesh, set, radius, entriesPerTriangle, index, sliceCandidates, bytesPerTriangle);
}

bool CellGrid::recountSpheres(const ClodSphereSet& set, std::size_t triangles) {
  const std::vector<std::uint32_t> sphereOf = firstSphereOfTriangles(set, triangles);
  SphereCounter counter(sphereOf, set.size());
  for (std::size_t at = 0; at < entries_.size();) {
    const std::uint32_t count = entries_[at].triangle;
    if (count > entries_.size() - at - 1) return false;
    counter.open();
    for (std::size_t k = at + 1; k <= at + count; ++k) {
      if (entries_[k].triangle >= triangles) return false;  // not a grid of this mesh
      counter.add(entries_[k].triangle);
    }
    writeHeader(entries_[at], count, counter.count());
    at += 1 + count;
  }
  return true;
}

bool CellGrid::useDenseIndex(Index index, std::size_t triangles) const {
  const double total = cellsOfBox(dims_);
  const double denseBytes = total / 64.0 * sizeof(Word) + 12.0 * static_cast<double>(cellCount_);
  // The dense index is faster (a rank instead of a probe sequence): it is taken when it is no larger than the hashed
  // one (24-byte slots, at most half full) or within 16 bytes per triangle.
  double slots = 16.0;
  while (slots < 2.0 * static_cast<double>(cellCount_)) slots *= 2.0;
  const double budget = std::max(24.0 * slots, 16.0 * static_cast<double>(triangles));
  const bool fits = entries_.size() < (1ull << 32) && total < 17179869184.0;  // 2^34 cells
  return fits && (index == Index::Dense || (index == Index::Auto && denseBytes <= budget));
}

void CellGrid::buildDenseIndex(const std::vector<std::uint64_t>& keys, const std::vector<std::uint64_t>& headers,
                               std::vector<CellRef>& refs) {
  const auto total = static_cast<std::uint64_t>(cellsOfBox(dims_));
  words_.assign(static_cast<std::size_t>((total + 63) / 64), Word{0, 0, 0});
  // Keys sort by z, then y, then x: the same order as the linear index, so ranks follow key order.
  for (const std::uint64_t key : keys) {
    const std::uint64_t linear = linearOf(key);
    words_[linear >> 6].bits |= 1ull << (linear & 63);
  }
  std::uint32_t rank = 0;
  for (Word& w : words_) {
    w.rank = rank;
    rank += static_cast<std::uint32_t>(__builtin_popcountll(w.bits));
  }
  refs_ = std::move(refs);
  headers_.resize(headers.size());
  for (std::size_t k = 0; k < headers.size(); ++k) headers_[k] = static_cast<std::uint32_t>(headers[k]);
}

void CellGrid::buildHashedIndex(const std::vector<std::uint64_t>& keys, const std::vector<std::uint64_t>& headers,
                                const std::vector<CellRef>& refs) {
  std::size_t cap = 16;
  while (cap < 2 * keys.size()) cap <<= 1;
  slots_.assign(cap, Slot{kOutside, 0, CellRef{}});
  mask_ = cap - 1;
  for (std::size_t k = 0; k < keys.size(); ++k) {
    std::uint64_t slot = mix(keys[k]) & mask_;
    while (slots_[slot].key != kOutside) slot = (slot + 1) & mask_;
    slots_[slot] = {keys[k], headers[k], refs[k]};
  }
}

std::size_t CellGrid::bytes() const {
  return entries_.capacity() * sizeof(Entry) + words_.capacity() * sizeof(Word) + refs_.capacity() * sizeof(CellRef) +
         headers_.capacity() * sizeof(std::uint32_t) + slots_.capacity() * sizeof(Slot);
}

const CellGrid::CellRef* CellGrid::findHashed(std::uint64_t key) const noexcept {
  if (key == kOutside || slots_.empty()) return nullptr;
  std::uint64_t slot = mix(key) & mask_;
  for (;;) {
    const Slot& c = slots_[slot];
    if (c.key == key) return &c.ref;
    if (c.key == kOutside) return nullptr;
    slot = (slot + 1) & mask_;
  }
}

}  // namespace clod_haptics
