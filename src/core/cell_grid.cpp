#include "clod_haptics/core/cell_grid.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <thread>

#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/geometry.h"

namespace clod_haptics {
namespace {

constexpr int kBits = 21;
#ifndef CLOD_CELL_FACTOR
#define CLOD_CELL_FACTOR 2.0
#endif
constexpr double kCellFactor = CLOD_CELL_FACTOR;  // cell side in pointer radii
constexpr std::int64_t kMaxDim = (1 << kBits) - 1;

std::uint64_t mix(std::uint64_t k) {
  k ^= k >> 33;
  k *= 0xff51afd7ed558ccdull;
  k ^= k >> 33;
  k *= 0xc4ceb9fe1a85ec53ull;
  return k ^ (k >> 33);
}

float roundDown(double x) {
  float f = static_cast<float>(x);
  return static_cast<double>(f) > x ? std::nextafter(f, -std::numeric_limits<float>::infinity()) : f;
}

struct Candidate {
  std::uint64_t key;
  float distance;
  std::uint32_t triangle;
  float direction[3];
};

}  // namespace

CellGrid::CellGrid(const TriangleMesh& mesh, const ClodSphereSet& set, double radius, double entriesPerTriangle) {
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
  double h = kCellFactor * radius;
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
  // Float rounding of u (relative 2^-24 per component) times |p - centre| <= h: bounded by 1e-6 h.
  slack_ = 1e-6 * h + pad;
  const double reach = radius + 0.8660254037844386 * h + pad;
  origin_ = bounds.min() - Vec3::Constant(reach + h);
  for (int k = 0; k < 3; ++k)
    dims_[k] = std::min<std::int64_t>(kMaxDim, static_cast<std::int64_t>(std::ceil((bounds.sizes()[k] + 2 * (reach + h)) * inv_)) + 1);

  const double tiny = std::max(1e-9 * h, 4e-9 * magnitude);
  // Candidates of a range of triangles; two threads each fill their own list.
  auto collect = [&](std::size_t begin, std::size_t end, std::vector<Candidate>& candidates) {
    for (std::size_t t = begin; t < end; ++t) {
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
                candidates.push_back(
                    {key, roundDown(d), static_cast<std::uint32_t>(t),
                     {static_cast<float>(dir.x()), static_cast<float>(dir.y()), static_cast<float>(dir.z())}});
              } else {
                candidates.push_back({key, 0.0f, static_cast<std::uint32_t>(t), {0.0f, 0.0f, 0.0f}});
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
  std::vector<Candidate> candidates;
  {
    const std::size_t half = mesh.size() / 2;
    std::vector<Candidate> second;
    std::thread helper([&] {
      collect(half, mesh.size(), second);
      std::sort(second.begin(), second.end(), order);
    });
    collect(0, half, candidates);
    std::sort(candidates.begin(), candidates.end(), order);
    helper.join();
    const std::size_t middle = candidates.size();
    candidates.insert(candidates.end(), second.begin(), second.end());
    std::inplace_merge(candidates.begin(), candidates.begin() + static_cast<std::ptrdiff_t>(middle), candidates.end(),
                       order);
  }

  // The first sphere listing each triangle (every triangle is listed: the coverage invariant).
  const std::vector<std::uint32_t> sphereOf = firstSphereOfTriangles(set, mesh.size());

  std::size_t cells = 0;
  for (std::size_t i = 0; i < candidates.size(); ++i) cells += (i == 0 || candidates[i].key != candidates[i - 1].key);
  std::size_t cap = 16;
  while (cap < 2 * cells) cap <<= 1;
  slots_.assign(cap, Cell{kOutside, 0, 0, 0});
  mask_ = cap - 1;
  cellCount_ = cells;
  entries_.resize(candidates.size());
  std::vector<std::uint32_t> seen;
  for (std::size_t i = 0; i < candidates.size();) {
    std::size_t j = i;
    seen.clear();
    while (j < candidates.size() && candidates[j].key == candidates[i].key) {
      const Candidate& c = candidates[j];
      entries_[j] = {c.triangle, c.distance, {c.direction[0], c.direction[1], c.direction[2]}};
      seen.push_back(sphereOf[candidates[j].triangle]);
      ++j;
    }
    std::sort(seen.begin(), seen.end());
    const auto spheres = static_cast<std::uint32_t>(std::unique(seen.begin(), seen.end()) - seen.begin());
    std::uint64_t slot = mix(candidates[i].key) & mask_;
    while (slots_[slot].key != kOutside) slot = (slot + 1) & mask_;
    slots_[slot] = {candidates[i].key, static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(j - i), spheres};
    i = j;
  }
}

std::uint64_t CellGrid::keyOf(const Vec3& p) const noexcept {
  std::uint64_t key = 0;
  for (int k = 0; k < 3; ++k) {
    const double q = std::floor((p[k] - origin_[k]) * inv_);
    if (!(q >= 0.0) || q >= static_cast<double>(dims_[k])) return kOutside;
    key |= static_cast<std::uint64_t>(q) << (k * kBits);
  }
  return key;
}

const CellGrid::Cell* CellGrid::find(std::uint64_t key) const noexcept {
  if (key == kOutside || slots_.empty()) return nullptr;
  std::uint64_t slot = mix(key) & mask_;
  for (;;) {
    const Cell& c = slots_[slot];
    if (c.key == key) return &c;
    if (c.key == kOutside) return nullptr;
    slot = (slot + 1) & mask_;
  }
}

Vec3 CellGrid::centreOf(std::uint64_t key) const noexcept {
  const std::uint64_t m = (1ull << kBits) - 1;
  return origin_ + (Vec3(static_cast<double>(key & m), static_cast<double>((key >> kBits) & m),
                         static_cast<double>((key >> (2 * kBits)) & m)) +
                    Vec3::Constant(0.5)) *
                       cell_;
}

}  // namespace clod_haptics
