#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "clod_haptics/core/mesh.h"

namespace clod_haptics {

/**
 * \brief Throws InvalidParameter unless value is finite and not negative; what names the parameter. The one
 * check of a clustering distance (every Clustering, ClodBuilder::build) and of other distances taken from users.
 */
void requireNonNegative(double value, const char* what);

/**
 * \brief Spheres a strategy fits itself (see Clustering::clusterMesh): sphere c lists the triangles
 * triangles[offsets[c] .. offsets[c+1]), ascending and unique, and radii[c] reaches the part of each of them it
 * covers: the whole triangle, or some pieces of a split one (triangle_pieces.h) whose other pieces other spheres
 * cover. Empty (no offsets) when the builder is to fit the spheres from the labels.
 */
struct ClusterLists {
  std::vector<std::uint32_t> offsets;
  std::vector<std::uint32_t> triangles;
  std::vector<double> radii;
};

/**
 * \brief Strategy that groups sphere centres into clusters for a clustering distance d.
 * Labels are 0..k-1, numbered in the order of each cluster's first point.
 */
class Clustering {
 public:
  virtual ~Clustering() = default;
  /**
   * \brief Fills labels (one per point) and returns the number of clusters.
   * \throws InvalidParameter for a negative or non-finite d.
   */
  virtual std::uint32_t cluster(const std::vector<Vec3>& points, double d, std::vector<std::uint32_t>& labels) const = 0;
  /**
   * \brief The same, for a strategy that reads the mesh: wrapped[i] is the triangle point i wraps. It
   * may also choose each cluster's sphere centre (centres[c]); left empty, the builder uses the mean of
   * the members. With lists not null, a strategy may also fit the spheres itself (lists, then centres are
   * set too), to split a long triangle over several spheres; it leaves lists empty otherwise, and so does a
   * strategy given null. The builder calls this one; the default ignores the mesh and calls cluster().
   */
  virtual std::uint32_t clusterMesh(const TriangleMesh& mesh, const std::vector<Vec3>& points,
                                    const std::vector<std::uint32_t>& wrapped, double d,
                                    std::vector<std::uint32_t>& labels, std::vector<Vec3>& centres,
                                    ClusterLists* lists) const {
    (void)mesh;
    (void)wrapped;
    centres.clear();
    if (lists) *lists = ClusterLists{};
    return cluster(points, d, labels);
  }
};

/**
 * \brief Single-link clustering (paper 3.2.2): two centres whose Euclidean distance is strictly
 * less than d are in one cluster, and clusters are closed under that relation (chains merge).
 * Euclidean rather than the cube's Chebyshev distance, so the result does not depend on how the
 * model is rotated. d = 0 keeps every centre apart. Expected O(n): a grid of cells of side d / sqrt(3)
 * (never finer than 1e-12 of the point cloud's extent) and union-find over neighbouring cells, on several
 * threads for a large input (the same result as on one).
 */
class SingleLinkClustering : public Clustering {
 public:
  /**
   * \brief threads: how many threads a large clustering uses (0 = the hardware's concurrency, at most 4);
   * inputs under kMinPointsPerThread points per thread use fewer. The result does not depend on it.
   */
  explicit SingleLinkClustering(unsigned threads = 0) : threads_(threads) {}
  std::uint32_t cluster(const std::vector<Vec3>& points, double d, std::vector<std::uint32_t>& labels) const override;

  /** \brief Points per thread below which a thread is not worth starting. */
  static constexpr std::size_t kMinPointsPerThread = 8192;

 private:
  unsigned threads_;
};

/**
 * \brief The clustering cube read literally: space is cut into cubes of side d (aligned with the
 * points' bounding box) and the centres in one cube form a cluster. No chaining, so no cluster
 * grows beyond a cube; d = 0 keeps every centre apart. O(n). An alternative to single-link for
 * comparison (tighter spheres, more of them); the default stays single-link, as the paper states.
 */
class CubeClustering : public Clustering {
 public:
  std::uint32_t cluster(const std::vector<Vec3>& points, double d, std::vector<std::uint32_t>& labels) const override;
};

/** \brief A clustering strategy by name: "single-link", "cube" or "tight" (TightClustering); null for anything else. */
std::shared_ptr<const Clustering> makeClustering(const std::string& name);

/**
 * \brief makeClustering(name), or InvalidParameter naming what (e.g. "~clustering") and the known names, for
 * the places that take the strategy from a user (command line, ROS parameter).
 */
std::shared_ptr<const Clustering> requireClustering(const std::string& name, const std::string& what);

}  // namespace clod_haptics
