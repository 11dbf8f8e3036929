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

  // Triangle lists, ascending and unique per cluster, in O(n) without sorting: the points are visited in
  // ascending order of the triangle they wrap (a counting sort over the triangles), so appending each
  // to its cluster keeps every list ascending, and a duplicate is always the list's last entry. One
  // pass counts, one fills the exactly sized array.
  const std::size_t points = centres_.size();
  std::vector<std::uint32_t> byTriangle(points);
  {
    std::vector<std::uint32_t> next(mesh.size() + 1, 0);
    for (std::size_t i = 0; i < points; ++i) ++next[wrapped_[i] + 1];
    for (std::size_t t = 0; t < mesh.size(); ++t) next[t + 1] += next[t];
    for (std::size_t i = 0; i < points; ++i) byTriangle[next[wrapped_[i]]++] = static_cast<std::uint32_t>(i);
  }
  constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
  std::vector<std::uint32_t> last(k, kNone);  // the last triangle appended to each cluster
  for (const std::uint32_t i : byTriangle) {
    const std::uint32_t c = labels[i], t = wrapped_[i];
    if (last[c] == t) continue;
    last[c] = t;
    ++set.offsets[c + 1];
  }
  for (std::uint32_t c = 0; c < k; ++c) set.offsets[c + 1] += set.offsets[c];
  set.triangles.resize(set.offsets[k]);
  {
    std::vector<std::uint32_t> fill(set.offsets.begin(), set.offsets.end() - 1);
    std::fill(last.begin(), last.end(), kNone);
    for (const std::uint32_t i : byTriangle) {
      const std::uint32_t c = labels[i], t = wrapped_[i];
      if (last[c] == t) continue;
      last[c] = t;
      set.triangles[fill[c]++] = t;
    }
  }

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
