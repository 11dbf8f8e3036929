#include "clod_haptics/core/sphere_set.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>

#include "clod_haptics/core/errors.h"

namespace clod_haptics {

void requireNonNegative(double value, const char* what) {
  if (!std::isfinite(value) || value < 0.0)
    throw InvalidParameter(std::string(what) + " must be finite and >= 0, got " + std::to_string(value));
}

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

  if (chosen.size() == k) {
    set.centres = std::move(chosen);
  } else {  // Mean of the member centres.
    std::vector<std::uint32_t> members(k, 0);
    for (std::size_t i = 0; i < centres_.size(); ++i) {
      set.centres[labels[i]] += centres_[i];
      ++members[labels[i]];
    }
    for (std::uint32_t c = 0; c < k; ++c) set.centres[c] /= static_cast<double>(members[c]);
  }

  // Triangle lists, grouped by cluster (counting sort), then sorted and made unique per cluster.
  for (std::size_t i = 0; i < centres_.size(); ++i) ++set.offsets[labels[i] + 1];
  for (std::uint32_t c = 0; c < k; ++c) set.offsets[c + 1] += set.offsets[c];
  std::vector<std::uint32_t> fill(set.offsets.begin(), set.offsets.end() - 1);
  std::vector<std::uint32_t> lists(centres_.size());
  for (std::size_t i = 0; i < centres_.size(); ++i) lists[fill[labels[i]]++] = wrapped_[i];
  set.triangles.reserve(lists.size());
  std::vector<std::uint32_t> offsets(k + 1, 0);
  // Duplicates within a cluster are dropped with a stamp per triangle (the last cluster that took
  // it), O(n) in all; each list is then sorted, which is cheap on the short lists most clusters have.
  std::vector<std::uint32_t> stamp(mesh.size(), std::numeric_limits<std::uint32_t>::max());
  for (std::uint32_t c = 0; c < k; ++c) {
    const std::size_t start = set.triangles.size();
    for (std::uint32_t i = set.offsets[c]; i < set.offsets[c + 1]; ++i) {
      const std::uint32_t t = lists[i];
      if (stamp[t] == c) continue;
      stamp[t] = c;
      set.triangles.push_back(t);
    }
    std::sort(set.triangles.begin() + static_cast<std::ptrdiff_t>(start), set.triangles.end());
    offsets[c + 1] = static_cast<std::uint32_t>(set.triangles.size());
  }
  set.offsets = std::move(offsets);

  // Radius: reach every vertex of every wrapped triangle (the coverage invariant).
  for (std::uint32_t c = 0; c < k; ++c) {
    double r2 = 0.0;
    for (const std::uint32_t* t = set.begin(c); t != set.end(c); ++t)
      for (int v = 0; v < 3; ++v) r2 = std::max(r2, (mesh.vertex(*t, v) - set.centres[c]).squaredNorm());
    set.radii[c] = std::sqrt(r2);
  }

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

}  // namespace clod_haptics
