#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "clod_haptics/core/mesh.h"

namespace clod_haptics {

/** \brief One sphere before clustering: a centre, a radius and the one triangle it wraps. */
struct PlacedSphere {
  Vec3 centre;
  double radius;
  std::uint32_t triangle;
};

/** \brief What the placement did, for the build statistics. */
struct PlacementStats {
  std::size_t triangles = 0;       ///< triangles in the mesh
  std::size_t paired = 0;          ///< triangles whose inward ray found an opposite triangle
  std::size_t unpaired = 0;        ///< no opposite triangle (open mesh, outward ray): own sphere at the centroid
  std::size_t degenerate = 0;      ///< zero-area triangles (no normal): own sphere at the centroid
  std::size_t relaxations = 0;     ///< sum over paired triangles of the 0.01 steps the threshold was relaxed
  double milliseconds = 0.0;       ///< wall time of the placement
};

/**
 * \brief Placed spheres as flat arrays, what ClodBuilder keeps: centre i wraps triangle wrapped[i]
 * (its radius, the distance to that triangle's farthest vertex, is not stored).
 */
struct PlacedCentres {
  std::vector<Vec3> centres;
  std::vector<std::uint32_t> wrapped;
};

/**
 * \brief Strategy that turns a mesh into unclustered spheres (paper section 3.2.1 or another rule).
 * Every triangle must end up inside at least one returned sphere that names it.
 */
class SpherePlacement {
 public:
  virtual ~SpherePlacement() = default;
  /** \brief Places the spheres; stats may be null. */
  virtual std::vector<PlacedSphere> place(const TriangleMesh& mesh, PlacementStats* stats) const = 0;
  /**
   * \brief The same spheres, in the same order, as flat arrays. The default converts place(); a
   * placement may fill the arrays directly and save the array of structs (ClodBuilder calls this).
   */
  virtual PlacedCentres placeCentres(const TriangleMesh& mesh, PlacementStats* stats) const;
};

/**
 * \brief The paper's rule, section 3.2.1. For each triangle, a ray is cast from its centroid along
 * the negative normal; among the triangles it meets, the threshold tau starts at -0.99 and grows by
 * 0.01 until some hit has normal . n < tau, and the nearest such hit is the opposite triangle. Two
 * centres follow at 1/4 and 3/4 of the centroid-to-centroid segment: the first wraps this triangle,
 * the second the opposite one (each radius reaches the farthest vertex of the triangle nearest that
 * centre). So every triangle places two spheres and d = 0 keeps 2n centres.
 *
 * When the ray meets nothing (an open mesh, or a triangle wound against the rest) or the triangle
 * has zero area, there is no opposite triangle: the triangle gets one sphere at its centroid whose
 * radius reaches its farthest vertex, so it is still covered, and it is counted as unpaired.
 * The ray casts use a TriangleBvh and run on all hardware threads.
 */
class PaperPlacement : public SpherePlacement {
 public:
  /**
   * \brief threads = 0 uses std::thread::hardware_concurrency(); progress, if set, is called from the
   * calling thread with the fraction of triangles done.
   */
  explicit PaperPlacement(unsigned threads = 0, std::function<void(double)> progress = {})
      : threads_(threads), progress_(std::move(progress)) {}
  std::vector<PlacedSphere> place(const TriangleMesh& mesh, PlacementStats* stats) const override;
  /** \brief The same spheres as place(), written straight into exactly sized flat arrays. */
  PlacedCentres placeCentres(const TriangleMesh& mesh, PlacementStats* stats) const override;

 private:
  struct Opposites;
  Opposites castRays(const TriangleMesh& mesh) const;

  unsigned threads_;
  std::function<void(double)> progress_;
};

}  // namespace clod_haptics
