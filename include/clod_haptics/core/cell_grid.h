#pragma once

#include <cstdint>
#include <vector>

#include "clod_haptics/core/mesh.h"
#include "clod_haptics/core/sphere_set.h"

namespace clod_haptics {

/**
 * \brief The fast level precomputed per cell of a hashed uniform grid: for every pointer of radius
 * up to radius() inside a cell, the triangles (and the spheres listing them) that the two-level
 * detection could report. A query is one hash lookup and a few exact triangle tests, O(1) in the
 * mesh size; an empty cell means no contact and no precise work at all.
 *
 * A cell of side h keeps every triangle whose distance to the cell's centre is at most
 * radius + h sqrt(3) / 2 (an exact test, so no candidate is missed), sorted by that distance, so a
 * query stops at the first candidate whose lower bound (distance to the centre minus the pointer's
 * offset from the centre) exceeds the best distance so far. Immutable after construction.
 */
class CellGrid {
 public:
  /** \brief One candidate of a cell. */
  struct Entry {
    std::uint32_t triangle;
    float centreDistance;  ///< distance dc from the cell centre to the triangle, rounded down
    /**
     * Unit direction u from the triangle's closest point q to the cell centre (zero when the centre
     * is on the triangle). The triangle lies in the half-space (x - q) . u <= 0, so for a pointer at p
     * distance(p, T) >= dc + (p - centre) . u, a bound three multiplications cheap.
     */
    float direction[3];
  };
  /** \brief A cell: its run of entries and the number of distinct spheres they come from. */
  struct Cell {
    std::uint64_t key;
    std::uint32_t first;
    std::uint32_t count;
    std::uint32_t spheres;
  };

  CellGrid() = default;
  /**
   * \brief Builds the grid for pointers of radius up to radius (> 0). Cell side is 2 radius, grown
   * when the grid would exceed 2^21 cells per axis or its memory budget: entriesPerTriangle
   * candidates per triangle on average (20 bytes each), so memory stays linear in the mesh.
   */
  CellGrid(const TriangleMesh& mesh, const ClodSphereSet& set, double radius, double entriesPerTriangle = 24.0);

  /** \brief The largest pointer radius the grid answers for; larger pointers need another descent. */
  double radius() const { return radius_; }
  /** \brief Slack to subtract from an Entry's bound for float rounding (relative to the cell). */
  double slack() const { return slack_; }
  /** \brief Side of a cell. */
  double cellSize() const { return cell_; }
  /** \brief Whether the grid was built. */
  bool empty() const { return slots_.empty(); }
  /** \brief Number of stored cells and candidates (for statistics). */
  std::size_t cells() const { return cellCount_; }
  std::size_t entries() const { return entries_.size(); }

  /** \brief Cell key of p, or kOutside when p is outside the grid (then no triangle is within radius()). */
  std::uint64_t keyOf(const Vec3& p) const noexcept;
  /** \brief The cell of a key, or null when no triangle is near it. */
  const Cell* find(std::uint64_t key) const noexcept;
  /** \brief Centre of the cell of a key. */
  Vec3 centreOf(std::uint64_t key) const noexcept;
  /** \brief First entry of a cell. */
  const Entry* entries(const Cell& c) const noexcept { return entries_.data() + c.first; }

  static constexpr std::uint64_t kOutside = ~0ull;

 private:
  double radius_ = 0.0;
  double cell_ = 0.0;
  double inv_ = 0.0;
  double slack_ = 0.0;
  Vec3 origin_ = Vec3::Zero();
  std::int64_t dims_[3] = {0, 0, 0};
  std::vector<Cell> slots_;  // open addressing, key kOutside marks a free slot
  std::uint64_t mask_ = 0;
  std::size_t cellCount_ = 0;
  std::vector<Entry> entries_;
};

}  // namespace clod_haptics
