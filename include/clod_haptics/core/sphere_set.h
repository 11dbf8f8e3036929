#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "clod_haptics/core/clustering.h"
#include "clod_haptics/core/mesh.h"
#include "clod_haptics/core/sphere_placement.h"

namespace clod_haptics {

/** \brief Figures of one build, the columns of the paper's Table 2 that do not need queries. */
struct BuildStats {
  std::size_t triangles = 0;          ///< triangles in the mesh
  std::size_t centres = 0;            ///< sphere centres before clustering
  std::size_t spheres = 0;            ///< spheres after clustering
  std::size_t unpaired = 0;           ///< triangles without an opposite triangle (see PaperPlacement)
  std::size_t degenerate = 0;         ///< zero-area triangles
  std::size_t maxTrianglesPerSphere = 0;
  double meanTrianglesPerSphere = 0.0;
  double placementMs = 0.0;           ///< ray casts and sphere placement (shared by every level)
  double clusteringMs = 0.0;          ///< clustering and fitting of this level
};

/**
 * \brief One contact level of detail: the clustered spheres of a mesh for a clustering distance.
 *
 * Flat arrays: sphere i has centres[i], radii[i] and wraps the triangles
 * triangles[offsets[i] .. offsets[i+1]). Invariant: every point of every triangle of the mesh lies inside
 * some sphere that lists that triangle. Usually one sphere holds the whole triangle (its radius reaches every
 * vertex of every triangle it lists); a long triangle may instead be split: listed by several spheres, each holding
 * some of its pieces (triangle_pieces.h), which together tile it. The detector relies on that invariant alone: a
 * contact at a point q of triangle t lies in a sphere listing t, which the pointer then overlaps, so t is tested.
 */
struct ClodSphereSet {
  std::string meshName;
  double scale = 1.0;       ///< the mesh's scale, for the file format
  double distance = 0.0;    ///< clustering distance d
  /// The mesh's local origin (TriangleMesh::origin): centres are relative to it, as the mesh's vertices are;
  /// centres[i] + origin is sphere i's centre in the model frame.
  Vec3 origin = Vec3::Zero();
  std::vector<Vec3> centres;
  std::vector<double> radii;
  std::vector<std::uint32_t> offsets{0};
  std::vector<std::uint32_t> triangles;
  BuildStats stats;

  /** \brief Number of spheres. */
  std::size_t size() const { return centres.size(); }
  /** \brief First listed triangle of sphere i. */
  const std::uint32_t* begin(std::size_t i) const { return triangles.data() + offsets[i]; }
  /** \brief One past the last listed triangle of sphere i. */
  const std::uint32_t* end(std::size_t i) const { return triangles.data() + offsets[i + 1]; }
};

/**
 * \brief Builds CLOD sphere sets of one mesh. The placement (the ray casts) runs once, in the
 * constructor; each build(d) only clusters, so a sweep over d or a reconfigure is cheap.
 * Thread-safe: build() is const and may run concurrently.
 */
class ClodBuilder {
 public:
  /** \brief Runs the placement; defaults to the paper's rule and single-link clustering. */
  explicit ClodBuilder(std::shared_ptr<const TriangleMesh> mesh,
                       std::shared_ptr<const SpherePlacement> placement = std::make_shared<PaperPlacement>(),
                       std::shared_ptr<const Clustering> clustering = std::make_shared<SingleLinkClustering>());

  /**
   * \brief Clusters the placed spheres with distance d and fits one sphere per cluster: its centre is
   * the mean of the member centres (on the central axis for a thin part), or the one the clustering
   * chose (Clustering::clusterMesh), and its radius reaches every vertex of every triangle the members wrap;
   * or the spheres the strategy fitted itself (ClusterLists), a long triangle split over several of them.
   * \throws InvalidParameter for a negative or non-finite d.
   */
  ClodSphereSet build(double d) const;

  /**
   * \brief The level with at most maxSpheres spheres: build(d) at the least d, to within tolerance times the
   * mesh's diagonal, whose set has at most maxSpheres spheres, found by bisection over d between 0 and the
   * diagonal (doubled while the count is still above maxSpheres, at most 40 times). The count falls as d grows
   * for single-link clustering (clusters only merge), so the answer is the least such d; for a strategy whose
   * count is not monotone in d it is a d where the count drops to maxSpheres or below, the set always within it.
   * \throws InvalidParameter when maxSpheres is 0, tolerance is not in (0, 1), or no d reaches maxSpheres.
   */
  ClodSphereSet buildAtMost(std::size_t maxSpheres, double tolerance = 1e-6) const;

  /** \brief The mesh. */
  const std::shared_ptr<const TriangleMesh>& mesh() const { return mesh_; }
  /** \brief The spheres before clustering (assembled on demand: the builder keeps only flat arrays). */
  std::vector<PlacedSphere> placed() const;
  /** \brief Number of sphere centres before clustering. */
  std::size_t centres() const { return centres_.size(); }
  /** \brief Statistics of the placement. */
  const PlacementStats& placementStats() const { return placementStats_; }

 private:
  std::shared_ptr<const TriangleMesh> mesh_;
  std::shared_ptr<const Clustering> clustering_;
  std::vector<Vec3> centres_;                // placed centres, the points the clustering sees
  std::vector<std::uint32_t> wrapped_;       // the triangle each placed sphere wraps
  PlacementStats placementStats_;
};

/**
 * \brief For each of the mesh's triangles, the first sphere of the set that lists it (UINT32_MAX for
 * a triangle no sphere lists, which the coverage invariant rules out for a built set).
 */
std::vector<std::uint32_t> firstSphereOfTriangles(const ClodSphereSet& set, std::size_t triangles);

/**
 * \brief Why the set does not fit the mesh, or "" when it does. It fits when its arrays are consistent (offsets from
 * 0, never decreasing, up to the list's end), every sphere is finite, every listed index is a triangle of the mesh,
 * and every triangle is covered by the spheres listing it: its three vertices lie in one of them (within radius *
 * (1 + 1e-9) + relativeTolerance * the mesh's diagonal), or else each of its pieces, halved as forEachPiece halves
 * it up to kMaxPieceDepth times, lies in one of them (a split triangle). The coverage invariant the detector relies
 * on to miss no contact, and what keeps its lists inside the mesh's arrays. O(list entries) for sets without split
 * triangles; the one check of the detector's constructor, the sphere cache and the ROS service client.
 */
std::string fitProblem(const TriangleMesh& mesh, const ClodSphereSet& set, double relativeTolerance = 1e-12);

}  // namespace clod_haptics
