#pragma once
// Internal to the core (not API): the node tests of the four-wide box tree (WideBoxTree). The swept query's (a box tree
// node's grown box, the gap from the part of the sweep inside it, its slab and ball, and the hint's plane under the
// sweep) for the four children of a node of its four-wide tree at once, in AVX2, in double. The box clip is the scalar
// one's arithmetic lane by lane; the bounds after it are looser than the scalar ones by a relative 1e-9, so a node the
// scalar walk keeps is kept. Compiled for x86-64 with GCC or Clang (the function carries the target attribute); call it
// only where packetAvx2() (dispatch.h) is true.

#include "packet_avx2.h"

namespace clod_haptics {
namespace detail {

/**
 * \brief The four children of a wide node as the filter reads them: rows of four doubles, one lane per child.
 * Lanes at or beyond the count passed are unused (any finite values). A child without a slab has radius +infinity.
 */
struct alignas(64) NodeLanes {
  double lo[3][4], hi[3][4];  ///< its box (the tree's float box, exactly)
  /// Its slab (NodeSlab): every vertex below lies within thick of the plane through centre with unit normal, and
  /// within radius of centre.
  double centre[3][4], normal[3][4], thick[4], radius[4];
};

/** \brief One sweep as the node filter sees it (the mesh's local frame). */
struct NodeFilterSweep {
  double a[3], d[3];
  double inv[3];                   ///< 1 / d per axis, 0 where d is 0
  double grow;                     ///< the test radius with its rounding margin: the boxes are grown by it
  double reach;                    ///< the slab bound's reach (R with its rounding slack)
  double tMax;                     ///< the best time so far: nothing after it can win
  bool plane;                      ///< whether the hint's plane below is set
  double n[3], offset, clearance;  ///< the hint's plane (Best::below): a point below clearance is out of reach
};

#if defined(CLOD_PACKET_AVX2)
/**
 * \brief Bit k set: child k (k < count) may hold a triangle that the sweep meets before tMax; enter[k] is then the
 * time at which the sweep enters its grown box (the walk's order). Never clears a child that the scalar walk
 * (SweptSphereQuery::sweepTree's enterNode and Best::below) keeps.
 */
unsigned nodeFilterAvx2(const NodeLanes& lanes, unsigned count, const NodeFilterSweep& s, double enter[4]);

/**
 * \brief The point query's node test for four children: bit k set when child k (k < count) may hold a point within
 * sqrt(d2) of p, by its box's squared distance (squaredDistanceToNode) and its slab's (slabSquaredDistance), the same
 * arithmetic lane by lane; near[k] the larger of the two lowered by a relative 1e-9, a lower bound of the squared
 * distance from p to everything below (the walk's order, and its test when the child is popped). Never clears a
 * child that ClodDetector's binary walk keeps.
 */
unsigned nodeNearAvx2(const NodeLanes& lanes, unsigned count, const double p[3], double d2, double near[4]);
#endif

}  // namespace detail
}  // namespace clod_haptics
