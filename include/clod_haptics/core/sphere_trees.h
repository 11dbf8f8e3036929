#pragma once
// The box trees a detector keeps over a level's spheres: built from the mesh and the set, or read from the disk
// cache beside the level's grid (grid_cache.h) and checked before use.

#include <cstdint>
#include <string>
#include <vector>

#include "clod_haptics/core/box_tree.h"
#include "clod_haptics/core/mesh.h"
#include "clod_haptics/core/sphere_set.h"

namespace clod_haptics {

/**
 * \brief Three box trees over a level's spheres, in the mesh's local frame, boxes padded by meshBoxTreePad. The ball
 * tree bounds each sphere's ball (spheres mode, display; leaves of 4); the tight tree bounds each sphere by the box
 * of the triangles it lists intersected with its ball, the region where a precise contact through it can lie
 * (leaves of 1); the gap tree is over the spheres' centres (leaves of 4) with each node's largest padded radius
 * rounded up to float, searched best first for the nearest sphere surface. Every tree orders sphere indices.
 */
struct SphereTrees {
  std::vector<BoxNode> ballNodes;
  std::vector<std::uint32_t> ballOrder;
  std::vector<BoxNode> tightNodes;
  std::vector<std::uint32_t> tightOrder;
  std::vector<BoxNode> gapNodes;
  std::vector<std::uint32_t> gapOrder;
  std::vector<float> gapRadius;  ///< per gap node

  /** \brief The bytes of the arrays. */
  std::size_t bytes() const;
};

/** \brief Builds the three trees of set (which fits mesh: fitProblem) with boxes padded by pad. */
SphereTrees buildSphereTrees(const TriangleMesh& mesh, const ClodSphereSet& set, double pad);

/**
 * \brief Why trees cannot serve set over mesh with boxes padded by pad, or "" when they can: each tree passes
 * boxTreeProblem over the set's spheres (a ball leaf's box holds each ball, a tight leaf's box each sphere's tight
 * box, a gap leaf's box each centre, all padded) and each gap node's radius is at least the largest padded radius
 * below it. Trees that pass answer exactly, however they were split. O(spheres + listed triangles).
 */
std::string sphereTreesProblem(const SphereTrees& trees, const TriangleMesh& mesh, const ClodSphereSet& set,
                               double pad);

}  // namespace clod_haptics
