#include "clod_haptics/core/cell_grid.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/geometry.h"
#include "float_rounding.h"
#include "parallel.h"

namespace clod_haptics {
namespace {

#ifndef CLOD_CELL_FACTOR
#define CLOD_CELL_FACTOR 2.0
#endif
constexpr double kCellFactor = CLOD_CELL_FACTOR;  // cell side in pointer radii
constexpr std::int64_t kMaxDim = (1 << CellGrid::kBits) - 1;

std::uint64_t mix(std::uint64_t k) {
  k ^= k >> 33;
  k *= 0xff51afd7ed558ccdull;
  k ^= k >> 33;
  k *= 0xc4ceb9fe1a85ec53ull;
  return k ^ (k >> 33);
}

using detail::roundDown;

struct Candidate {
  std::uint64_t key;
  float distance;
  std::uint32_t triangle;
  std::int8_t direction[3];
};

std::int8_t quantise(double u) { return static_cast<std::int8_t>(std::lround(std::clamp(u, -1.0, 1.0) * 127.0)); }

// Rounding of a stored direction: each component within 0.5 / 127 of u, so |u - stored| <= sqrt(3) / 254
// and the bound errs by at most that times |p - centre| <= h sqrt(3) / 2.
constexpr double kDirectionError = 1.7320508075688772 / 254.0;
constexpr double kHalfDiagonal = 0.8660254037844386;

// Range of n . x over the part of triangle (a, b, c) (relative to a cell's centre) inside the region
// |x|_inf <= half, |x|_1 <= diamond (Sutherland-Hodgman against those 6 + 8 planes); false when nothing
// of the triangle is inside.
bool clippedRange(const Vec3& a, const Vec3& b, const Vec3& c, double half, double diamond, const Vec3& n, double& lo,
                  double& hi) {
  // Most candidates of a fine mesh lie wholly inside the region (no clipping) or wholly outside one
  // of its planes (nothing inside).
  auto inside = [&](const Vec3& v) { return v.cwiseAbs().maxCoeff() <= half && v.lpNorm<1>() <= diamond; };
  if (inside(a) && inside(b) && inside(c)) {
    const double x = n.dot(a), y = n.dot(b), z = n.dot(c);
    lo = std::min({x, y, z});
    hi = std::max({x, y, z});
    return true;
  }
  for (int k = 0; k < 3; ++k)
    if ((a[k] > half && b[k] > half && c[k] > half) || (a[k] < -half && b[k] < -half && c[k] < -half)) return false;
  Vec3 poly[2][24];
  int count = 3;
  poly[0][0] = a;
  poly[0][1] = b;
  poly[0][2] = c;
  int cur = 0;
  auto clip = [&](const Vec3& normal, double limit) {
    const Vec3* in = poly[cur];
    Vec3* out = poly[1 - cur];
    int m = 0;
    for (int i = 0; i < count; ++i) {
      const Vec3& P = in[i];
      const Vec3& Q = in[(i + 1) % count];
      const double dp = normal.dot(P) - limit, dq = normal.dot(Q) - limit;
      if (dp <= 0.0) out[m++] = P;
      if ((dp < 0.0 && dq > 0.0) || (dp > 0.0 && dq < 0.0)) out[m++] = P + (dp / (dp - dq)) * (Q - P);
    }
    count = m;
    cur = 1 - cur;
    return count > 0;
  };
  for (int k = 0; k < 3; ++k)
    for (double side : {1.0, -1.0})
      if (!clip(side * Vec3::Unit(k), half)) return false;
  for (int q = 0; q < 8; ++q)
    if (!clip(Vec3(q & 1 ? -1.0 : 1.0, q & 2 ? -1.0 : 1.0, q & 4 ? -1.0 : 1.0), diamond)) return false;
  lo = std::numeric_limits<double>::infinity();
  hi = -lo;
  for (int i = 0; i < count; ++i) {
    const double v = n.dot(poly[cur][i]);
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  return true;
}

}  // namespace

CellGrid::CellGrid(const TriangleMesh& mesh, const ClodSphereSet& set, double radius, double entriesPerTriangle,
                   Index index, double sliceCandidates) {
  const double maxEntries = std::max(1e6, entriesPerTriangle * static_cast<double>(mesh.size()));
  if (!(radius > 0.0) || !std::isfinite(radius))
    throw InvalidParameter("cell grid radius must be finite and > 0, got " + std::to_string(radius));
  radius_ = radius;
  const Eigen::AlignedBox3d bounds = mesh.bounds();
  const double magnitude = std::max(bounds.min().cwiseAbs().maxCoeff(), bounds.max().cwiseAbs().maxCoeff());
  const double pad = 1e-12 * std::max(magnitude, bounds.diagonal().norm());

  // Total area decides how many candidates a cell side gives; grow the side until it fits.
  double area = 0.0;
  for (std::size_t t = 0; t < mesh.size(); ++t)
    area += 0.5 * (mesh.vertex(t, 1) - mesh.vertex(t, 0)).cross(mesh.vertex(t, 2) - mesh.vertex(t, 0)).norm();
  // Cell side: larger cells mean a smaller index (the part every query reads, kept in cache) but more
  // candidates per cell. About pi reach^2 n / area triangles lie within reach of a surface cell's
  // centre; up to ~13 of them the larger cells measured faster (mannequin-devil, 26k triangles: median
  // 95 -> 62 ns at 3 r), beyond that slower (refined_elephant, 89k: 94 -> 165 ns), so the side is 3 r
  // or 2.5 r when that estimate stays under 13, else 2 r.
  double factor = kCellFactor;
  for (double f : {3.0, 2.5}) {
    const double r = radius * (1.0 + 0.8660254037844386 * f);
    if (f > factor && 3.141592653589793 * r * r * static_cast<double>(mesh.size()) <= 13.0 * area) {
      factor = f;
      break;
    }
  }
  double h = factor * radius;
  const double extent = bounds.sizes().maxCoeff() + 2.0 * (radius + 2.0 * h);
  h = std::max(h, extent / static_cast<double>(kMaxDim - 4));
  // Mean edge length: a triangle spans about (edge + 2 reach) / h cells along each axis.
  double edges = 0.0;
  for (std::size_t t = 0; t < mesh.size(); ++t)
    for (int k = 0; k < 3; ++k) edges += (mesh.vertex(t, (k + 1) % 3) - mesh.vertex(t, k)).norm();
  const double edge = edges / (3.0 * static_cast<double>(mesh.size()));
  for (int guard = 0; guard < 64; ++guard) {
    // Each triangle lands in the cells within radius + half diagonal: a slab around its area, or for
    // triangles smaller than a cell, the ball of that reach around it (about half its bounding cube).
    const double reach = radius + 0.8660254037844386 * h;
    const double slab = (2.0 * reach * area) / (h * h * h);
    const double span = (edge + 2.0 * reach) / h;
    const double estimate = std::max(slab, 0.6 * span * span * span * static_cast<double>(mesh.size()));
    if (estimate <= maxEntries) break;
    h *= 1.25;
  }
  cell_ = h;
  inv_ = 1.0 / h;
  // The 8-bit direction times |p - centre| <= h sqrt(3) / 2, plus float rounding (< 1e-6 h).
  slack_ = (kDirectionError * kHalfDiagonal + 1e-6) * h + pad;
  unit_ = h / 8192.0;
  // Rounding of the slab test's products and of the clipped points: relative 1e-9 of the cell, plus pad.
  slabPad_ = 1e-9 * h + 4.0 * pad;
  const double reach = radius + 0.8660254037844386 * h + pad;
  distanceUnit_ = reach / 255.0;
  origin_ = bounds.min() - Vec3::Constant(reach + h);
  for (int k = 0; k < 3; ++k)
    dims_[k] = std::min<std::int64_t>(kMaxDim, static_cast<std::int64_t>(std::ceil((bounds.sizes()[k] + 2 * (reach + h)) * inv_)) + 1);

  const double tiny = std::max(1e-9 * h, 4e-9 * magnitude);
  // Candidates of a range of triangles; two threads each fill their own list.
  auto collect = [&](const std::uint32_t* begin, const std::uint32_t* end, std::int64_t zBegin, std::int64_t zEnd,
                     detail::ReallocArray<Candidate>& candidates) {
    for (const std::uint32_t* it = begin; it != end; ++it) {
      const std::size_t t = *it;
      const Vec3 &a = mesh.vertex(t, 0), &b = mesh.vertex(t, 1), &c = mesh.vertex(t, 2);
      const Vec3& n = mesh.normals[t];
      const bool planar = !n.isZero(0.0);
      const double planeLimit = reach + 1e-9 * h + pad;  // slack for the rounding of the plane distance
      const Vec3 lo = a.cwiseMin(b).cwiseMin(c) - Vec3::Constant(reach);
      const Vec3 hi = a.cwiseMax(b).cwiseMax(c) + Vec3::Constant(reach);
      std::int64_t l[3], u[3];
      for (int k = 0; k < 3; ++k) {
        l[k] = std::max<std::int64_t>(0, static_cast<std::int64_t>(std::floor((lo[k] - origin_[k]) * inv_)));
        u[k] = std::min<std::int64_t>(dims_[k] - 1, static_cast<std::int64_t>(std::floor((hi[k] - origin_[k]) * inv_)));
      }
      l[2] = std::max(l[2], zBegin);
      u[2] = std::min(u[2], zEnd - 1);
      if (l[2] > u[2]) continue;
      for (std::int64_t x = l[0]; x <= u[0]; ++x)
        for (std::int64_t y = l[1]; y <= u[1]; ++y)
          for (std::int64_t z = l[2]; z <= u[2]; ++z) {
            const Vec3 centre = origin_ + (Vec3(static_cast<double>(x), static_cast<double>(y), static_cast<double>(z)) +
                                           Vec3::Constant(0.5)) * h;
            // The distance to the plane is a lower bound of the distance to the triangle: most cells of
            // the box are rejected by it before the closest-point computation.
            if (planar && std::abs(n.dot(centre - a)) > planeLimit) continue;
            const Vec3 toCentre = centre - closestPointOnTriangle(centre, a, b, c);
            const double d = toCentre.norm();
            if (d <= reach) {
              const std::uint64_t key = static_cast<std::uint64_t>(x) | static_cast<std::uint64_t>(y) << kBits |
                                        static_cast<std::uint64_t>(z) << (2 * kBits);
              // The supporting-plane bound needs the true direction to the centre. The closest point
              // carries an error of a few ulps of the coordinates, so its direction is trusted only when
              // d is far above it (the bound then errs by < 1e-7 |p - q|, inside the slack); otherwise the
              // entry keeps the trivial bound 0 <= distance (dc = 0, u = 0): never skipped, never wrong.
              if (d > tiny) {
                const Vec3 dir = toCentre / d;
                candidates.push_back({key, roundDown(d), static_cast<std::uint32_t>(t),
                                      {quantise(dir.x()), quantise(dir.y()), quantise(dir.z())}});
              } else {
                candidates.push_back({key, 0.0f, static_cast<std::uint32_t>(t), {0, 0, 0}});
              }
            }
          }
    }
  };
  auto order = [](const Candidate& p, const Candidate& q) {
    if (p.key != q.key) return p.key < q.key;
    if (p.distance != q.distance) return p.distance < q.distance;
    return p.triangle < q.triangle;
  };
  // The first sphere listing each triangle (every triangle is listed: the coverage invariant).
  const std::vector<std::uint32_t> sphereOf = firstSphereOfTriangles(set, mesh.size());

  // Candidates are collected in slices of z (keys sort by z first, so slices come in key order), each
  // slice's two halves (two threads) sorted and merged straight onto the end of the entries: only one
  // slice's 24-byte candidates are held beside the 8-byte entries, and both arrays grow by realloc
  // (pages moved, not copied). Slices hold about equal shares of the candidates, estimated per layer
  // of cells from the triangles' boxes grown by reach.
  double expected = 0.0;
  {
    const double slab = (2.0 * reach * area) / (h * h * h);
    const double span = (edge + 2.0 * reach) / h;
    expected = std::max(slab, 0.6 * span * span * span * static_cast<double>(mesh.size()));
  }
  const std::int64_t slices = std::clamp<std::int64_t>(
      static_cast<std::int64_t>(expected / std::max(1.0, sliceCandidates)) + 1, 1, std::min<std::int64_t>(256, dims_[2]));
  // The z range of cells each triangle's box (grown by reach) spans.
  auto zRange = [&](std::size_t t, std::int64_t& l2, std::int64_t& u2, double& columns) {
    const Vec3 &a = mesh.vertex(t, 0), &b = mesh.vertex(t, 1), &c = mesh.vertex(t, 2);
    const Vec3 lo = a.cwiseMin(b).cwiseMin(c) - Vec3::Constant(reach);
    const Vec3 hi = a.cwiseMax(b).cwiseMax(c) + Vec3::Constant(reach);
    std::int64_t l[3], u[3];
    for (int k = 0; k < 3; ++k) {
      l[k] = std::clamp<std::int64_t>(static_cast<std::int64_t>(std::floor((lo[k] - origin_[k]) * inv_)), 0, dims_[k] - 1);
      u[k] = std::clamp<std::int64_t>(static_cast<std::int64_t>(std::floor((hi[k] - origin_[k]) * inv_)), 0, dims_[k] - 1);
    }
    l2 = l[2];
    u2 = u[2];
    columns = static_cast<double>((u[0] - l[0] + 1) * (u[1] - l[1] + 1));
  };
  std::vector<std::int64_t> sliceStart{0};
  if (slices > 1) {
    std::vector<double> layer(static_cast<std::size_t>(dims_[2]) + 1, 0.0);
    for (std::size_t t = 0; t < mesh.size(); ++t) {
      std::int64_t l2, u2;
      double w;
      zRange(t, l2, u2, w);
      layer[static_cast<std::size_t>(l2)] += w;
      layer[static_cast<std::size_t>(u2) + 1] -= w;
    }
    double running = 0.0, sum = 0.0;
    for (std::int64_t z = 0; z < dims_[2]; ++z) sum += (running += layer[static_cast<std::size_t>(z)]);
    running = 0.0;
    double cumulative = 0.0;
    for (std::int64_t z = 0; z < dims_[2]; ++z) {
      cumulative += (running += layer[static_cast<std::size_t>(z)]);
      if (cumulative >= sum * static_cast<double>(sliceStart.size()) / static_cast<double>(slices) && z + 1 < dims_[2])
        sliceStart.push_back(z + 1);
    }
  }
  sliceStart.push_back(dims_[2]);
  // Per slice, the triangles whose z range meets it (most triangles meet one slice).
  const std::size_t sliceCount = sliceStart.size() - 1;
  std::vector<std::uint32_t> sliceFirst(sliceCount + 1, 0), sliceTriangles;
  {
    auto slicesOf = [&](std::size_t t, std::size_t& sa, std::size_t& sb) {
      std::int64_t l2, u2;
      double w;
      zRange(t, l2, u2, w);
      sa = static_cast<std::size_t>(std::upper_bound(sliceStart.begin(), sliceStart.end(), l2) - sliceStart.begin()) - 1;
      sb = static_cast<std::size_t>(std::upper_bound(sliceStart.begin(), sliceStart.end(), u2) - sliceStart.begin()) - 1;
    };
    std::size_t sa, sb;
    if (sliceCount == 1) {
      sliceTriangles.resize(mesh.size());
      for (std::size_t t = 0; t < mesh.size(); ++t) sliceTriangles[t] = static_cast<std::uint32_t>(t);
      sliceFirst[1] = static_cast<std::uint32_t>(mesh.size());
    } else {
      for (std::size_t t = 0; t < mesh.size(); ++t) {
        slicesOf(t, sa, sb);
        for (std::size_t q = sa; q <= sb; ++q) ++sliceFirst[q + 1];
      }
      for (std::size_t q = 0; q < sliceCount; ++q) sliceFirst[q + 1] += sliceFirst[q];
      sliceTriangles.resize(sliceFirst[sliceCount]);
      std::vector<std::uint32_t> fill(sliceFirst.begin(), sliceFirst.end() - 1);
      for (std::size_t t = 0; t < mesh.size(); ++t) {
        slicesOf(t, sa, sb);
        for (std::size_t q = sa; q <= sb; ++q) sliceTriangles[fill[q]++] = static_cast<std::uint32_t>(t);
      }
    }
  }
  std::vector<std::uint64_t> headers;  // per cell: its header's position in the entries
  std::vector<std::uint64_t> keys;
  std::size_t cells = 0;
  detail::ReallocArray<Candidate> first, second;
  std::vector<std::uint32_t> seen;
  for (std::size_t slice = 0; slice < sliceCount; ++slice) {
    const std::int64_t zBegin = sliceStart[slice], zEnd = sliceStart[slice + 1];
    if (zBegin >= zEnd) continue;
    first.clear();
    second.clear();
    const std::uint32_t* list = sliceTriangles.data() + sliceFirst[slice];
    const std::size_t count = sliceFirst[slice + 1] - sliceFirst[slice], half = count / 2;
    detail::runParallel(2, [&](unsigned part) {
      auto& out = part ? second : first;
      collect(part ? list + half : list, part ? list + count : list + half, zBegin, zEnd, out);
      std::sort(out.begin(), out.end(), order);
    });
    // Visits the candidates of both halves in merged order.
    auto merged = [&](auto&& visit) {
      std::size_t i = 0, j = 0;
      while (i < first.size() || j < second.size()) {
        if (j == second.size() || (i < first.size() && order(first[i], second[j])))
          visit(first[i++]);
        else
          visit(second[j++]);
      }
    };
    std::size_t sliceCells = 0;
    {
      std::uint64_t last = kOutside;
      merged([&](const Candidate& c) {
        sliceCells += c.key != last;
        last = c.key;
      });
    }
    // Entries: per cell a header, then its candidates.
    std::size_t at = entries_.size(), header = 0;
    entries_.resize(at + first.size() + second.size() + sliceCells);
    std::uint64_t last = kOutside;
    auto close = [&]() {
      if (last == kOutside) return;
      std::sort(seen.begin(), seen.end());
      const auto spheres = static_cast<std::uint32_t>(std::unique(seen.begin(), seen.end()) - seen.begin());
      Entry& e = entries_[header];
      e = Entry{static_cast<std::uint32_t>(at - header - 1), 0, {0, 0, 0}};
      std::memcpy(reinterpret_cast<unsigned char*>(&e) + 4, &spheres, sizeof spheres);
    };
    merged([&](const Candidate& c) {
      if (c.key != last) {
        close();
        seen.clear();
        header = at++;
        headers.push_back(header);
        keys.push_back(c.key);
        last = c.key;
      }
      // The distance in 8 bits, rounded down (q * unit <= d, exactly as the query computes it).
      double q = std::min(255.0, std::floor(static_cast<double>(c.distance) / distanceUnit_));
      while (q > 0.0 && q * distanceUnit_ > static_cast<double>(c.distance)) q -= 1.0;
      entries_[at++] = Entry{c.triangle, static_cast<std::uint8_t>(q), {c.direction[0], c.direction[1], c.direction[2]}};
      seen.push_back(sphereOf[c.triangle]);
    });
    close();
    cells += sliceCells;
  }
  first = detail::ReallocArray<Candidate>();
  second = detail::ReallocArray<Candidate>();
  std::vector<std::uint32_t>().swap(sliceTriangles);
  entries_.shrink();
  cellCount_ = cells;

  // Per cell, the index entry: the slab. A triangle point within radius R of a point of the cell is
  // within h / 2 + R of the centre along each axis and within 3 h / 2 + sqrt(3) R in the L1 norm (the
  // cell grown by a ball of radius R lies in that box and that octahedron): the candidates clipped to
  // both span the slab.
  std::vector<CellRef> refs(cells);
  {
    const double half = (0.5 * h + radius) * (1.0 + 1e-9) + pad;
    const double diamond = (1.5 * h + 1.7320508075688772 * radius) * (1.0 + 1e-9) + 2.0 * pad;
    auto fill = [&](std::size_t begin, std::size_t end) {
      for (std::size_t k = begin; k < end; ++k) {
        const Vec3 centre = centreOf(keys[k]);
        CellRef ref{};
        const Entry* head = entries_.data() + headers[k];
        const Cell c{head + 1, head->triangle, 0};
        // The slab along the first candidate's normal, exactly as the query will use it (the 8-bit m).
        ref.offset = 0;
        ref.halfWidth = 0xffff;
        const Vec3& n = mesh.normals[c.entries[0].triangle];
        if (!n.isZero(0.0)) {
          const std::int8_t m8[3] = {quantise(n.x()), quantise(n.y()), quantise(n.z())};
          const Vec3 m(m8[0] / 127.0, m8[1] / 127.0, m8[2] / 127.0);
          double lo = std::numeric_limits<double>::infinity(), hi = -lo;
          for (std::uint32_t i = 0; i < c.count; ++i) {
            const std::size_t t = c.entries[i].triangle;
            double l, u;
            if (clippedRange(mesh.vertex(t, 0) - centre, mesh.vertex(t, 1) - centre, mesh.vertex(t, 2) - centre, half,
                             diamond, m, l, u)) {
              lo = std::min(lo, l);
              hi = std::max(hi, u);
            }
          }
          if (lo <= hi) {
            const double mid = std::round(0.5 * (lo + hi) / unit_);
            const double width = std::ceil(std::max(hi - mid * unit_, mid * unit_ - lo) / unit_) + 1.0;
            if (std::abs(mid) <= 32767.0 && width <= 65535.0) {
              for (int j = 0; j < 3; ++j) ref.normal[j] = m8[j];
              ref.offset = static_cast<std::int16_t>(mid);
              ref.halfWidth = static_cast<std::uint16_t>(width);
            }
          }
        }
        refs[k] = ref;
      }
    };
    detail::runParallel(2, [&](unsigned part) { part ? fill(cells / 2, cells) : fill(0, cells / 2); });
  }

  // Dense index when its bits are small (or forced), else a hash table.
  const double total = static_cast<double>(dims_[0]) * static_cast<double>(dims_[1]) * static_cast<double>(dims_[2]);
  const double denseBytes = total / 64.0 * sizeof(Word) + 12.0 * static_cast<double>(cells);
  const double budget = std::max(4.0 * 1024 * 1024, 16.0 * static_cast<double>(mesh.size()));
  const bool fits = entries_.size() < (1ull << 32) && total < 17179869184.0;  // 2^34 cells
  const bool dense = fits && (index == Index::Dense || (index == Index::Auto && denseBytes <= budget));
  const std::uint64_t m = (1ull << kBits) - 1;
  if (dense) {
    const auto nx = static_cast<std::uint64_t>(dims_[0]), ny = static_cast<std::uint64_t>(dims_[1]);
    words_.assign(static_cast<std::size_t>((static_cast<std::uint64_t>(total) + 63) / 64), Word{0, 0, 0});
    // Keys sort by z, then y, then x: the same order as the linear index, so ranks follow key order.
    for (std::size_t k = 0; k < keys.size(); ++k) {
      const std::uint64_t key = keys[k];
      const std::uint64_t linear = (key & m) + nx * (((key >> kBits) & m) + ny * ((key >> (2 * kBits)) & m));
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
  } else {
    std::size_t cap = 16;
    while (cap < 2 * cells) cap <<= 1;
    slots_.assign(cap, Slot{kOutside, 0, CellRef{}});
    mask_ = cap - 1;
    for (std::size_t k = 0; k < keys.size(); ++k) {
      std::uint64_t slot = mix(keys[k]) & mask_;
      while (slots_[slot].key != kOutside) slot = (slot + 1) & mask_;
      slots_[slot] = {keys[k], headers[k], refs[k]};
    }
  }
}

std::size_t CellGrid::bytes() const {
  return entries_.capacity() * sizeof(Entry) + words_.capacity() * sizeof(Word) +
         refs_.capacity() * sizeof(CellRef) + headers_.capacity() * sizeof(std::uint32_t) +
         slots_.capacity() * sizeof(Slot);
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
