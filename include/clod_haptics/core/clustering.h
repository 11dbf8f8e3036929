#pragma once

#include <cstdint>
#include <vector>

#include "clod_haptics/core/mesh.h"

namespace clod_haptics {

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
};

/**
 * \brief Single-link clustering (paper 3.2.2): two centres whose Euclidean distance is strictly
 * less than d are in one cluster, and clusters are closed under that relation (chains merge).
 * Euclidean rather than the cube's Chebyshev distance, so the result does not depend on how the
 * model is rotated. d = 0 keeps every centre apart. Expected O(n): a hash grid of cell size d
 * (never finer than 1e-12 of the point cloud's extent) and union-find over neighbouring cells.
 */
class SingleLinkClustering : public Clustering {
 public:
  std::uint32_t cluster(const std::vector<Vec3>& points, double d, std::vector<std::uint32_t>& labels) const override;
};

}  // namespace clod_haptics
