#include "clod_haptics/core/sphere_set.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>

#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/triangle_pieces.h"
#include "parallel.h"

namespace clod_haptics {
namespace {

constexpr std::size_t kMinPointsPerThread = 8192;  // below this per thread, build's passes stay on one
constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();

// The placed points in ascending order of the triangle they wrap, by a counting sort over the triangles:
// after sort(), triangle t's points are byTriangle[begin(t), ends[t]).
struct PointsByTriangle {
  PointsByTriangle(std::size_t points, std::size_t triangles) : byTriangle(points), ends(triangles + 1, 0) {}
  void sort(const std::vector<std::uint32_t>& wrapped) {
    const std::size_t triangles = ends.size() - 1;
    for (const std::uint32_t t : wrapped) ++ends[t + 1];
    for (std::size_t t = 0; t < triangles; ++t) ends[t + 1] += ends[t];
    for (std::size_t i = 0; i < wrapped.size(); ++i) byTriangle[ends[wrapped[i]]++] = static_cast<std::uint32_t>(i);
  }
  std::uint32_t begin(std::size_t t) const { return t == 0 ? std::uint32_t{0} : ends[t - 1]; }

  std::vector<std::uint32_t> byTriangle;
  std::vector<std::uint32_t> ends;  // one past triangle t's points in byTriangle
};

// Triangle lists, ascending and unique per cluster, in O(n) without sorting: the points are visited in
// ascending order of the triangle they wrap, so appending each to its cluster keeps every list ascending,
// and a duplicate is always the list's last entry. One pass counts, one fills the exactly sized array.
// The triangles are split among the parts (so a duplicate stays within one part); each part counts and
// fills its clusters' entries after those of the parts before.
class TriangleLists {
 public:
  TriangleLists(const PointsByTriangle& sorted, const std::vector<std::uint32_t>& labels, std::uint32_t k,
                unsigned parts)
      : sorted_(sorted), labels_(labels), k_(k), parts_(parts), last_(parts), count_(parts) {}

  // Counts the entries of each part's clusters.
  void count() {
    detail::runParallel(parts_, [&](unsigned j) {
      count_[j].assign(k_, 0);
      forEachEntry(j, [&](std::uint32_t c, std::uint32_t) { ++count_[j][c]; });
    });
  }
  // Sets the offsets from the counts; each part's count becomes where its entries of the cluster start.
  void place(std::vector<std::uint32_t>& offsets) {
    for (std::uint32_t c = 0; c < k_; ++c) {
      std::uint32_t start = offsets[c];
      for (unsigned j = 0; j < parts_; ++j) {
        const std::uint32_t entries = count_[j][c];
        count_[j][c] = start;
        start += entries;
      }
      offsets[c + 1] = start;
    }
  }
  // Writes the entries to the places place() set.
  void fill(std::vector<std::uint32_t>& triangles) {
    detail::runParallel(parts_, [&](unsigned j) {
      std::vector<std::uint32_t>& next = count_[j];
      forEachEntry(j, [&](std::uint32_t c, std::uint32_t t) { triangles[next[c]++] = t; });
    });
  }

 private:
  // Calls add(cluster, triangle) once per entry of part j's triangles, in ascending triangle order.
  template <class Add>
  void forEachEntry(unsigned j, Add&& add) {
    std::vector<std::uint32_t>& last = last_[j];  // the last triangle appended to each cluster
    last.assign(k_, kNone);
    const std::size_t triangles = sorted_.ends.size() - 1;
    for (std::size_t t = triangles * j / parts_; t < triangles * (j + 1) / parts_; ++t)
      for (std::uint32_t p = sorted_.begin(t); p < sorted_.ends[t]; ++p) {
        const std::uint32_t c = labels_[sorted_.byTriangle[p]];
        if (last[c] == t) continue;
        last[c] = static_cast<std::uint32_t>(t);
        add(c, static_cast<std::uint32_t>(t));
      }
  }

  const PointsByTriangle& sorted_;
  const std::vector<std::uint32_t>& labels_;
  std::uint32_t k_;
  unsigned parts_;
  std::vector<std::vector<std::uint32_t>> last_, count_;  // per part and cluster
};

// Fits one sphere per cluster into a set: its centre, the triangles its members wrap, and a radius that
// reaches every vertex of them. Large inputs split the passes over two or more threads (one pass is one
// core's worth of memory traffic); every value is computed as on one thread, in the same order where the
// order matters.
class SphereFitter {
 public:
  SphereFitter(const TriangleMesh& mesh, const std::vector<Vec3>& centres, const std::vector<std::uint32_t>& wrapped,
               const std::vector<std::uint32_t>& labels, std::uint32_t k, ClodSphereSet& set)
      : mesh_(mesh),
        centres_(centres),
        wrapped_(wrapped),
        labels_(labels),
        k_(k),
        points_(centres.size()),
        threads_(detail::threadsFor(points_, 0, kMinPointsPerThread)),
        set_(set) {
    set.centres.assign(k, Vec3::Zero());
    set.radii.assign(k, 0.0);
    set.offsets.assign(k + 1, 0);
  }

  // Centres and lists when every cluster has one member (d = 0, or no two centres closer than d): its
  // list is the member's triangle and its centre the member's (or the one the strategy chose).
  void fitSingletons(std::vector<Vec3>& chosen) {
    const bool chose = chosen.size() == k_;
    if (chose) set_.centres = std::move(chosen);
    std::iota(set_.offsets.begin(), set_.offsets.end(), 0u);
    set_.triangles.resize(k_);
    detail::runParallel(threads_, [&](unsigned j) {
      for (std::size_t i = points_ * j / threads_; i < points_ * (j + 1) / threads_; ++i) {
        const std::uint32_t c = labels_[i];
        set_.triangles[c] = wrapped_[i];
        if (!chose) set_.centres[c] = centres_[i];
      }
    });
  }

  // Centres and lists in general: the means beside the sort of the points by triangle, then the lists
  // (several parts only with few clusters per point: each part holds two arrays of one entry per cluster).
  void fitClusters(std::vector<Vec3>& chosen) {
    PointsByTriangle sorted(points_, mesh_.size());
    if (threads_ > 1) {
      detail::runParallel(2, [&](unsigned t) { t ? sorted.sort(wrapped_) : meanCentres(chosen); });
    } else {
      meanCentres(chosen);
      sorted.sort(wrapped_);
    }
    TriangleLists lists(sorted, labels_, k_, k_ <= points_ / 8 ? threads_ : 1);
    lists.count();
    lists.place(set_.offsets);
    set_.triangles.resize(set_.offsets[k_]);
    lists.fill(set_.triangles);
  }

  // Radius: reach every vertex of every listed triangle (the coverage invariant). The list entries are
  // split among the threads; a cluster's squared radius is the largest over its parts (exact, so the same).
  void fitRadii() {
    const std::size_t entries = set_.triangles.size();
    std::vector<std::pair<std::uint32_t, double>> shared(threads_, {kNone, 0.0});  // a cluster begun in an earlier part
    detail::runParallel(threads_, [&](unsigned j) {
      const std::size_t lo = entries * j / threads_, hi = entries * (j + 1) / threads_;
      if (lo != hi) shared[j] = fitRadiiIn(lo, hi);
    });
    for (const auto& [c, r2] : shared)
      if (c != kNone) set_.radii[c] = std::max(set_.radii[c], r2);
    for (double& r : set_.radii) r = std::sqrt(r);
  }

 private:
  // Each cluster's centre: the one the strategy chose, or the mean of the member centres (summed in point
  // order, as one thread would: one thread does all of it).
  void meanCentres(std::vector<Vec3>& chosen) {
    if (chosen.size() == k_) {
      set_.centres = std::move(chosen);
      return;
    }
    std::vector<std::uint32_t> members(k_, 0);
    for (std::size_t i = 0; i < points_; ++i) {
      set_.centres[labels_[i]] += centres_[i];
      ++members[labels_[i]];
    }
    for (std::uint32_t c = 0; c < k_; ++c) set_.centres[c] /= static_cast<double>(members[c]);
  }

  // The squared radii over list entries [lo, hi): set for the clusters that start there, returned for
  // the one begun before lo (kNone when there is none).
  std::pair<std::uint32_t, double> fitRadiiIn(std::size_t lo, std::size_t hi) {
    const std::vector<std::uint32_t>& offsets = set_.offsets;
    std::pair<std::uint32_t, double> shared{kNone, 0.0};
    auto c = static_cast<std::uint32_t>(std::upper_bound(offsets.begin(), offsets.end(), lo) - offsets.begin() - 1);
    for (; c < k_ && offsets[c] < hi; ++c) {
      const double r2 =
          squaredReach(c, std::max<std::size_t>(lo, offsets[c]), std::min<std::size_t>(hi, offsets[c + 1]));
      if (offsets[c] < lo)
        shared = {c, r2};
      else
        set_.radii[c] = r2;
    }
    return shared;
  }

  // Squared distance from cluster c's centre to the farthest vertex of list entries [from, to).
  double squaredReach(std::uint32_t c, std::size_t from, std::size_t to) const {
    constexpr std::size_t kAhead = 16;
    const std::vector<std::uint32_t>& list = set_.triangles;
    double r2 = 0.0;
    for (std::size_t e = from; e < to; ++e) {
      // The triangles are scattered loads, their vertices more so: start both early.
      if (e + 2 * kAhead < list.size()) __builtin_prefetch(&mesh_.triangles[list[e + 2 * kAhead]]);
      if (e + kAhead < list.size())
        for (int v = 0; v < 3; ++v) __builtin_prefetch(&mesh_.vertex(list[e + kAhead], v));
      for (int v = 0; v < 3; ++v) r2 = std::max(r2, (mesh_.vertex(list[e], v) - set_.centres[c]).squaredNorm());
    }
    return r2;
  }

  const TriangleMesh& mesh_;
  const std::vector<Vec3>& centres_;
  const std::vector<std::uint32_t>& wrapped_;
  const std::vector<std::uint32_t>& labels_;
  std::uint32_t k_;
  std::size_t points_;
  unsigned threads_;
  ClodSphereSet& set_;
};

// The figures of a built set, but for the clustering time.
BuildStats statsOf(const ClodSphereSet& set, std::size_t triangles, std::size_t centres,
                   const PlacementStats& placement) {
  BuildStats st;
  const std::size_t k = set.size();
  st.triangles = triangles;
  st.centres = centres;
  st.spheres = k;
  st.unpaired = placement.unpaired;
  st.degenerate = placement.degenerate;
  for (std::size_t c = 0; c < k; ++c)
    st.maxTrianglesPerSphere = std::max<std::size_t>(st.maxTrianglesPerSphere, set.offsets[c + 1] - set.offsets[c]);
  st.meanTrianglesPerSphere = k ? static_cast<double>(set.triangles.size()) / k : 0.0;
  st.placementMs = placement.milliseconds;
  return st;
}

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
  ClusterLists lists;        // spheres the strategy fitted itself, if it did
  const std::uint32_t k = clustering_->clusterMesh(mesh, centres_, wrapped_, d, labels, chosen, &lists);

  ClodSphereSet set;
  set.meshName = mesh.name;
  set.scale = mesh.scale;
  set.origin = mesh.origin;
  set.distance = d;
  if (!lists.offsets.empty()) {
    if (lists.offsets.size() != std::size_t{k} + 1 || lists.radii.size() != k || chosen.size() != k)
      throw std::logic_error("ClodBuilder: the clustering's lists do not match its cluster count");
    set.centres = std::move(chosen);
    set.radii = std::move(lists.radii);
    set.offsets = std::move(lists.offsets);
    set.triangles = std::move(lists.triangles);
  } else {
    SphereFitter fitter(mesh, centres_, wrapped_, labels, k, set);
    if (k == centres_.size())
      fitter.fitSingletons(chosen);
    else
      fitter.fitClusters(chosen);
    fitter.fitRadii();
  }
  set.stats = statsOf(set, mesh.size(), centres_.size(), placementStats_);
  set.stats.clusteringMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return set;
}

ClodSphereSet ClodBuilder::buildAtMost(std::size_t maxSpheres, double tolerance) const {
  if (maxSpheres == 0) throw InvalidParameter("buildAtMost: the sphere count must be at least 1");
  if (!(tolerance > 0.0 && tolerance < 1.0))
    throw InvalidParameter("buildAtMost: the tolerance must lie in (0, 1), got " + std::to_string(tolerance));
  ClodSphereSet low = build(0.0);
  if (low.size() <= maxSpheres) return low;
  const double diagonal = std::max(mesh_->diagonal(), std::numeric_limits<double>::min());
  // An upper end whose set fits: the diagonal merges every single-link cluster; other strategies may need more.
  double lo = 0.0, hi = diagonal;
  ClodSphereSet high = build(hi);
  for (int grow = 0; high.size() > maxSpheres; ++grow) {
    if (grow == 40)
      throw InvalidParameter("buildAtMost: no clustering distance up to " + std::to_string(hi) + " gives at most " +
                             std::to_string(maxSpheres) + " spheres");
    lo = hi;
    hi *= 2.0;
    high = build(hi);
  }
  // Invariant: build(lo) has more than maxSpheres spheres, build(hi) at most.
  while (hi - lo > tolerance * diagonal) {
    const double mid = 0.5 * (lo + hi);
    ClodSphereSet set = build(mid);
    if (set.size() <= maxSpheres) {
      hi = mid;
      high = std::move(set);
    } else {
      lo = mid;
    }
  }
  return high;
}

std::string fitProblem(const TriangleMesh& mesh, const ClodSphereSet& set, double relativeTolerance) {
  const std::size_t n = set.centres.size();
  if (set.radii.size() != n || set.offsets.size() != n + 1) return "inconsistent array sizes";
  if (set.offsets.front() != 0 || set.offsets.back() != set.triangles.size()) {
    return "offsets do not span the triangle list";
  }
  if (set.origin != mesh.origin) return "built for a mesh with another local origin (is it the same mesh and scale?)";
  const double tolerance = relativeTolerance * std::max(mesh.diagonal(), 1e-300);
  auto holds = [&](std::size_t sphere, const Vec3& p) {
    return (p - set.centres[sphere]).norm() <= set.radii[sphere] * (1.0 + 1e-9) + tolerance;
  };
  auto holdsAll = [&](std::size_t sphere, const Vec3& a, const Vec3& b, const Vec3& c) {
    return holds(sphere, a) && holds(sphere, b) && holds(sphere, c);
  };
  // Per triangle: listed by no sphere, whole in a sphere listing it, or listed but whole in none (a split triangle,
  // with the sphere that first listed it).
  enum : char { kUnlisted, kWhole, kPartial };
  std::vector<char> state(mesh.size(), kUnlisted);
  std::vector<std::uint32_t> firstPartial;
  for (std::size_t i = 0; i < n; ++i) {
    if (set.offsets[i] > set.offsets[i + 1]) return "offsets decrease at sphere " + std::to_string(i);
    if (!set.centres[i].allFinite() || !std::isfinite(set.radii[i]) || set.radii[i] < 0.0)
      return "sphere " + std::to_string(i) + " is not finite";
    for (std::uint32_t k = set.offsets[i]; k < set.offsets[i + 1]; ++k) {
      const std::uint32_t t = set.triangles[k];
      if (t >= mesh.size()) {
        return "sphere " + std::to_string(i) + " lists triangle " + std::to_string(t) + " but the mesh has " +
               std::to_string(mesh.size());
      }
      if (state[t] == kWhole) continue;
      if (holdsAll(i, mesh.vertex(t, 0), mesh.vertex(t, 1), mesh.vertex(t, 2))) {
        state[t] = kWhole;
      } else if (state[t] == kUnlisted) {
        state[t] = kPartial;
        if (firstPartial.empty()) firstPartial.assign(mesh.size(), kNone);
        firstPartial[t] = static_cast<std::uint32_t>(i);
      }
    }
  }
  if (!firstPartial.empty()) {
    // A triangle whole in none of its spheres is covered when its pieces (triangle_pieces.h) each lie in one.
    std::vector<std::uint32_t> begin(mesh.size() + 1, 0), listing;
    for (std::uint32_t t : set.triangles) begin[t + 1] += state[t] == kPartial;
    for (std::size_t t = 0; t < mesh.size(); ++t) begin[t + 1] += begin[t];
    listing.resize(begin.back());
    std::vector<std::uint32_t> next(begin.begin(), begin.end() - 1);
    for (std::size_t i = 0; i < n; ++i)
      for (const std::uint32_t* t = set.begin(i); t != set.end(i); ++t)
        if (state[*t] == kPartial) listing[next[*t]++] = static_cast<std::uint32_t>(i);
    for (std::size_t t = 0; t < mesh.size(); ++t) {
      if (state[t] != kPartial) continue;
      const TrianglePiece whole{mesh.vertex(t, 0), mesh.vertex(t, 1), mesh.vertex(t, 2)};
      const bool covered = coveredByPieces(whole, kMaxPieceDepth, [&](const TrianglePiece& piece) {
        for (std::uint32_t j = begin[t]; j < begin[t + 1]; ++j)
          if (holdsAll(listing[j], piece[0], piece[1], piece[2])) return true;
        return false;
      });
      if (!covered) {
        return "triangle " + std::to_string(t) + " sticks out of sphere " + std::to_string(firstPartial[t]) +
               " and the other spheres listing it (is it the same mesh and scale?)";
      }
    }
  }
  for (std::size_t t = 0; t < state.size(); ++t) {
    if (state[t] == kUnlisted) return "triangle " + std::to_string(t) + " is in no sphere";
  }
  return {};
}

}  // namespace clod_haptics
