#include "clod_haptics/core/sphere_set.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

#include "clod_haptics/core/errors.h"

namespace clod_haptics {

void requireNonNegative(double value, const char* what) {
  if (!std::isfinite(value) || value < 0.0)
    throw InvalidParameter(std::string(what) + " must be finite and >= 0, got " + std::to_string(value));
}

ClodBuilder::ClodBuilder(std::shared_ptr<const TriangleMesh> mesh, std::shared_ptr<const SpherePlacement> placement,
                         std::shared_ptr<const Clustering> clustering)
    : mesh_(std::move(mesh)), clustering_(std::move(clustering)) {
  if (!mesh_ || mesh_->size() == 0) throw InvalidParameter("ClodBuilder needs a mesh with triangles");
  placed_ = placement->place(*mesh_, &placementStats_);
  placedCentres_.reserve(placed_.size());
  for (const PlacedSphere& s : placed_) placedCentres_.push_back(s.centre);
}

ClodSphereSet ClodBuilder::build(double d) const {
  requireNonNegative(d, "clustering distance");
  const auto start = std::chrono::steady_clock::now();
  const TriangleMesh& mesh = *mesh_;
  std::vector<std::uint32_t> labels;
  const std::uint32_t k = clustering_->cluster(placedCentres_, d, labels);

  ClodSphereSet set;
  set.meshName = mesh.name;
  set.scale = mesh.scale;
  set.distance = d;
  set.centres.assign(k, Vec3::Zero());
  set.radii.assign(k, 0.0);
  set.offsets.assign(k + 1, 0);

  // Mean of the member centres.
  std::vector<std::uint32_t> members(k, 0);
  for (std::size_t i = 0; i < placed_.size(); ++i) {
    set.centres[labels[i]] += placed_[i].centre;
    ++members[labels[i]];
  }
  for (std::uint32_t c = 0; c < k; ++c) set.centres[c] /= static_cast<double>(members[c]);

  // Triangle lists, grouped by cluster (counting sort), then sorted and made unique per cluster.
  for (std::size_t i = 0; i < placed_.size(); ++i) ++set.offsets[labels[i] + 1];
  for (std::uint32_t c = 0; c < k; ++c) set.offsets[c + 1] += set.offsets[c];
  std::vector<std::uint32_t> fill(set.offsets.begin(), set.offsets.end() - 1);
  std::vector<std::uint32_t> lists(placed_.size());
  for (std::size_t i = 0; i < placed_.size(); ++i) lists[fill[labels[i]]++] = placed_[i].triangle;
  set.triangles.reserve(lists.size());
  std::vector<std::uint32_t> offsets(k + 1, 0);
  for (std::uint32_t c = 0; c < k; ++c) {
    auto first = lists.begin() + set.offsets[c], last = lists.begin() + set.offsets[c + 1];
    std::sort(first, last);
    last = std::unique(first, last);
    set.triangles.insert(set.triangles.end(), first, last);
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
  st.centres = placed_.size();
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
