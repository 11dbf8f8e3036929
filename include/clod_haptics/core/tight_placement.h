#pragma once

#include <vector>

#include "clod_haptics/core/sphere_placement.h"

namespace clod_haptics {

/**
 * \brief One sphere per triangle, centred half way along the inward normal ray from the triangle's
 * centroid to the first surface it meets (any orientation): the middle of the local thickness, near
 * the medial axis. Its radius reaches the triangle's farthest vertex. A triangle whose ray meets
 * nothing (open mesh, outward winding) or that has zero area gets its sphere at its centroid (counted
 * as unpaired or degenerate). Simpler than PaperPlacement (first hit only, n spheres instead of 2n),
 * a medial-axis estimate for any clustering; with TightClustering the paper's placement measured as
 * tight or tighter. Ray casts on all hardware threads by default.
 */
class TightPlacement : public SpherePlacement {
 public:
  /** \brief threads = 0 uses std::thread::hardware_concurrency(). */
  explicit TightPlacement(unsigned threads = 0) : threads_(threads) {}
  std::vector<PlacedSphere> place(const TriangleMesh& mesh, PlacementStats* stats) const override;

 private:
  unsigned threads_;
};

}  // namespace clod_haptics
