#include "clod_haptics/core/sphere_set.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>

#include "clod_haptics/core/errors.h"
#include "parallel.h"

namespace clod_haptics {
namespace {

constexpr std::size_t kMinPointsPerThread = 8192;  // below this per thread, build's passes stay on one

}  // namespace

std::vector<std::uint32_t> firstSphereOfTriangles(const ClodSphereSet& set, std::size_t triangles) {
  std::vector<std::uint32_t> first(triangles, std::numeric_limits<std::uint32_t>::max());
  for (std::size_t s = set.size(); s-- > 0;)  // backwards, so the lowest sphere index stays
    for (const std::uint32_t* t = set.begin(s); t != set.end(s); ++t) first[*t] = static_cast<std::uint32_t>(s);
  return first;
}

ClodBuilder::ClodBuilder(std::shared_ptr<const TriangleMesh> mesh, std::shared_ptr<const SpherePlacement> placement,
                         std::shared_ptr<const Clustering> clustering)
    : mesh_(std::move(mesh)), clustering_(std::move(clustering)) {
  if (!mesh_ || mesh_->size() == 0) throw InvalidParameter("ClodBuilder needs a mesh with triangles");
  // Flat arrays straight from the placement (no array of structs and copy): a low peak per triangle.
  PlacedCentres placed = placement->placeCentres(*mesh_, &placementStats_);
  centres_ = std::move(placed.centres);
  wrapped_ = std::move(placed.wrapped);
}

std::vector<PlacedSphere> ClodBuilder::placed() const {
  std::vector<PlacedSphere> out;
  out.reserve(centres_.size());
  for (std::size_t i = 0; i < centres_.size(); ++i) {
    double r2 = 0.0;
    for (int v = 0; v < 3; ++v) r2 = std::max(r2, (mesh_->vertex(wrapped_[i], v) - centres_[i]).squaredNorm());
    out.push_back({centres_[i], std::sqrt(r2), wrapped_[i]});
  }
  return out;
}

ClodSphereSet ClodBuilder::build(double d) const {
  requireNonNegative(d, "clustering distance");
  const auto start = std::chrono::steady_clock::now();
  const TriangleMesh& mesh = *mesh_;
  std::vector<std::uint32_t> labels;
  std::vector<Vec3> chosen;  // centres the strategy chose, if it did
  const std::uint32_t k = clustering_->clusterMesh(mesh, centres_, wrapped_, d, labels, chosen);

  ClodSphereSet set;
  set.meshName = mesh.name;
  set.scale = mesh.scale;
  set.distance = d;
  set.centres.assign(k, Vec3::Zero());
  set.radii.assign(k, 0.0);
  set.offsets.assign(k + 1, 0);

  const std::size_t points = centres_.size();
  // Large inputs split their passes over two or more threads (one pass is one core's worth of memory
  // traffic); every value is computed as on one thread, in the same order where the order matters.
  const unsigned threads = detail::threadsFor(points, 0, kMinPointsPerThread);

  constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
  if (k == points) {
    // Every cluster has one member (d = 0, or no two centres closer than d): its list is the member's
    // triangle and its centre the member's, computed as the general mean below computes it.
    const bool chose = chosen.size() == k;
    if (chose) set.centres = std::move(chosen);
    std::iota(set.offsets.begin(), set.offsets.end(), 0u);
    set.triangles.resize(k);
    detail::runParallel(threads, [&](unsigned j) {
      for (std::size_t i = points * j / threads; i < points * (j + 1) / threads; ++i) {
        const std::uint32_t c = labels[i];
        set.triangles[c] = wrapped_[i];
        if (!chose) set.centres[c] = (Vec3::Zero() + centres_[i]) / 1.0;
      }
    });
  } else {
    // Mean of the member centres (summed in point order, as one thread would: one thread does all of it),
    // beside the sort of the points by the triangle they wrap.
    auto means = [&] {
      if (chosen.size() == k) {
        set.centres = std::move(chosen);
        return;
      }
      std::vector<std::uint32_t> members(k, 0);
      for (std::size_t i = 0; i < points; ++i) {
        set.centres[labels[i]] += centres_[i];
        ++members[labels[i]];
      }
      for (std::uint32_t c = 0; c < k; ++c) set.centres[c] /= static_cast<double>(members[c]);
    };

    // Triangle lists, ascending and unique per cluster, in O(n) without sorting: the points are visited in
    // ascending order of the triangle they wrap (a counting sort over the triangles), so appending each
    // to its cluster keeps every list ascending, and a duplicate is always the list's last entry. One
    // pass counts, one fills the exactly sized array.
    const std::size_t triangles = mesh.size();
    std::vector<std::uint32_t> byTriangle(points);
    std::vector<std::uint32_t> ends(triangles + 1, 0);  // ends[t]: one past triangle t's points in byTriangle
    auto sortByTriangle = [&] {
      for (std::size_t i = 0; i < points; ++i) ++ends[wrapped_[i] + 1];
      for (std::size_t t = 0; t < triangles; ++t) ends[t + 1] += ends[t];
      for (std::size_t i = 0; i < points; ++i) byTriangle[ends[wrapped_[i]]++] = static_cast<std::uint32_t>(i);
    };
    auto begins = [&](std::size_t t) { return t == 0 ? std::uint32_t{0} : ends[t - 1]; };
    if (threads > 1) {
      detail::runParallel(2, [&](unsigned t) { t ? sortByTriangle() : means(); });
    } else {
      means();
      sortByTriangle();
    }

    // The lists: the triangles split among the threads (so a duplicate stays within one part); each part
    // counts and fills its clusters' entries after those of the parts before. Per thread two arrays of
    // one entry per cluster: only when there are few clusters per point.
    const unsigned parts = k <= points / 8 ? threads : 1;
    std::vector<std::vector<std::uint32_t>> last(parts), count(parts);  // per part and cluster
    // Calls add(cluster, triangle) for the points of part j's triangles in ascending triangle order.
    auto forEachPoint = [&](unsigned j, auto&& add) {
      for (std::size_t t = triangles * j / parts; t < triangles * (j + 1) / parts; ++t)
        for (std::uint32_t p = begins(t); p < ends[t]; ++p) add(labels[byTriangle[p]], static_cast<std::uint32_t>(t));
    };
    detail::runParallel(parts, [&](unsigned j) {
      last[j].assign(k, kNone);  // the last triangle appended to each cluster
      count[j].assign(k, 0);
      forEachPoint(j, [&](std::uint32_t c, std::uint32_t t) {
        if (last[j][c] == t) return;
        last[j][c] = t;
        ++count[j][c];
      });
    });
    for (std::uint32_t c = 0; c < k; ++c) {
      std::uint32_t start = set.offsets[c];
      for (unsigned j = 0; j < parts; ++j) {
        const std::uint32_t entries = count[j][c];
        count[j][c] = start;  // now where part j's entries of cluster c go
        start += entries;
      }
      set.offsets[c + 1] = start;
    }
    set.triangles.resize(set.offsets[k]);
    detail::runParallel(parts, [&](unsigned j) {
      std::vector<std::uint32_t>& fill = count[j];
      std::fill(last[j].begin(), last[j].end(), kNone);
      forEachPoint(j, [&](std::uint32_t c, std::uint32_t t) {
        if (last[j][c] == t) return;
        last[j][c] = t;
        set.triangles[fill[c]++] = t;
      });
    });
    last.clear();
    count.clear();
    std::vector<std::uint32_t>().swap(byTriangle);
    std::vector<std::uint32_t>().swap(ends);
  }

  // Radius: reach every vertex of every wrapped triangle (the coverage invariant). The list entries are
  // split among the threads; a cluster's squared radius is the largest over its parts (exact, so the same).
  const std::size_t entries = set.triangles.size();
  constexpr std::size_t kAhead = 16;
  std::vector<std::pair<std::uint32_t, double>> shared(threads, {kNone, 0.0});  // a cluster begun in an earlier part
  detail::runParallel(threads, [&](unsigned j) {
    const std::size_t lo = entries * j / threads, hi = entries * (j + 1) / threads;
    if (lo == hi) return;
    std::uint32_t c = static_cast<std::uint32_t>(std::upper_bound(set.offsets.begin(), set.offsets.end(), lo) -
                                                 set.offsets.begin() - 1);
    for (; c < k && set.offsets[c] < hi; ++c) {
      double r2 = 0.0;
      const std::size_t end = std::min<std::size_t>(hi, set.offsets[c + 1]);
      for (std::size_t e = std::max<std::size_t>(lo, set.offsets[c]); e < end; ++e) {
        // The triangles are scattered loads, their vertices more so: start both early.
        if (e + 2 * kAhead < entries) __builtin_prefetch(&mesh.triangles[set.triangles[e + 2 * kAhead]]);
        if (e + kAhead < entries)
          for (int v = 0; v < 3; ++v) __builtin_prefetch(&mesh.vertex(set.triangles[e + kAhead], v));
        for (int v = 0; v < 3; ++v)
          r2 = std::max(r2, (mesh.vertex(set.triangles[e], v) - set.centres[c]).squaredNorm());
      }
      if (set.offsets[c] < lo)
        shared[j] = {c, r2};
      else
        set.radii[c] = r2;
    }
  });
  for (const auto& [c, r2] : shared)
    if (c != kNone) set.radii[c] = std::max(set.radii[c], r2);
  for (double& r : set.radii) r = std::sqrt(r);

  BuildStats& st = set.stats;
  st.triangles = mesh.size();
  st.centres = centres_.size();
  st.spheres = k;
  st.unpaired = placementStats_.unpaired;
  st.degenerate = placementStats_.degenerate;
  for (std::uint32_t c = 0; c < k; ++c)
    st.maxTrianglesPerSphere = std::max<std::size_t>(st.maxTrianglesPerSphere, set.offsets[c + 1] - set.offsets[c]);
  st.meanTrianglesPerSphere = k ? static_cast<double>(set.triangles.size()) / k : 0.0;
  st.placementMs = placementStats_.milliseconds;
  st.clusteringMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return set;
}

std::string fitProblem(const TriangleMesh& mesh, const ClodSphereSet& set, double relativeTolerance) {
  const std::size_t n = set.centres.size();
  if (set.radii.size() != n || set.offsets.size() != n + 1) return "inconsistent array sizes";
  if (set.offsets.front() != 0 || set.offsets.back() != set.triangles.size()) {
    return "offsets do not span the triangle list";
  }
  const double tolerance = relativeTolerance * std::max(mesh.diagonal(), 1e-300);
  std::vector<char> covered(mesh.size(), 0);
  for (std::size_t i = 0; i < n; ++i) {
    if (set.offsets[i] > set.offsets[i + 1]) return "offsets decrease at sphere " + std::to_string(i);
    const Vec3& c = set.centres[i];
    const double radius = set.radii[i];
    if (!c.allFinite() || !std::isfinite(radius) || radius < 0.0) return "sphere " + std::to_string(i) + " is not finite";
    const double reach = radius * (1.0 + 1e-9) + tolerance;
    for (std::uint32_t k = set.offsets[i]; k < set.offsets[i + 1]; ++k) {
      const std::uint32_t t = set.triangles[k];
      if (t >= mesh.size()) {
        return "sphere " + std::to_string(i) + " lists triangle " + std::to_string(t) + " but the mesh has " +
               std::to_string(mesh.size());
      }
      for (int v = 0; v < 3; ++v) {
        if (!((mesh.vertex(t, v) - c).norm() <= reach)) {
          return "triangle " + std::to_string(t) + " sticks out of sphere " + std::to_string(i) +
                 " (is it the same mesh and scale?)";
        }
      }
      covered[t] = 1;
    }
  }
  for (std::size_t t = 0; t < covered.size(); ++t) {
    if (!covered[t]) return "triangle " + std::to_string(t) + " is in no sphere";
  }
  return {};
}

}  // namespace clod_haptics
