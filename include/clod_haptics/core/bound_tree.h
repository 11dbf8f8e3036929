#pragma once

#include <cstdint>
#include <limits>
#include <vector>

#include "clod_haptics/core/geometry.h"

namespace clod_haptics {

/**
 * \brief A box tree over spheres that move: the scene's object bounds (SceneDetector). Built over the spheres'
 * centres as they are (median splits, leaves of up to kLeaf), then refitted along one leaf's path to the root when a
 * sphere moves or changes (O(depth), nothing allocated): the layout stays what the build chose, the boxes always
 * hold their spheres, so a query stays exact however far the spheres wander, and only slower.
 *
 * A sphere is a centre, a radius and a grow (how much farther it reaches in some queries: the scene's spheres
 * mode); a NaN centre (an inactive object) is in no box. The boxes are doubles, each side widened by 1e-12 of the
 * magnitudes it was computed from, so a box test never rejects a point the caller's own sphere test (in double, with
 * the same centre and reach) keeps.
 *
 * candidates() is const and allocation-free; build and update must not run concurrently with it.
 */
class BoundTree {
 public:
  static constexpr std::uint32_t kLeaf = 4;

  /** \brief Builds over n spheres: centre (x[i], y[i], z[i]), radius[i], grow[i] (grow null: none). Allocates. */
  void build(const double* x, const double* y, const double* z, const double* radius, const double* grow,
             std::size_t n);
  /** \brief Sphere i (of the arrays build saw, at the same addresses or copies) changed: refits its path. */
  void update(std::uint32_t i, const double* x, const double* y, const double* z, const double* radius,
              const double* grow);

  /**
   * \brief Writes to out (up to capacity) the spheres whose box comes within r of p (with their grow when grown):
   * every sphere that can reach p is among them, in no particular order. Returns how many there are in all, which
   * may exceed capacity (then out holds capacity of them and the caller needs another way).
   */
  std::size_t candidates(const Vec3& p, double r, bool grown, std::uint32_t* out, std::size_t capacity) const noexcept;

  /** \brief Spheres built over. */
  std::size_t size() const { return leafOf_.size(); }

 private:
  struct Node {
    double lo[3], hi[3];  ///< box of the spheres below (empty when none is active)
    double grow;          ///< the largest grow below
    std::uint32_t first;  ///< leaf: first entry in order_; inner: the right child (the left is the next node)
    std::uint32_t count;  ///< leaf: spheres (> 0); inner: 0
    std::uint32_t parent;
  };
  std::uint32_t split(std::uint32_t begin, std::uint32_t end, std::uint32_t parent, const double* x, const double* y,
                      const double* z);
  void fitLeaf(std::uint32_t node, const double* x, const double* y, const double* z, const double* radius,
               const double* grow);
  void fitInner(std::uint32_t node);

  std::vector<Node> nodes_;
  std::vector<std::uint32_t> order_;   // sphere indices in leaf order
  std::vector<std::uint32_t> leafOf_;  // per sphere, its leaf
};

}  // namespace clod_haptics
