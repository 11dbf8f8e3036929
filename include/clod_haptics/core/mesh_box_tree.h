#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "clod_haptics/core/box_tree.h"
#include "clod_haptics/core/mesh.h"

namespace clod_haptics {

/**
 * \brief One box tree over all the triangles of a mesh (leaves of 4, boxes padded by meshBoxTreePad), in the
 * mesh's local frame: what the grid level walks beyond its radius and for the deep search, and what the swept
 * query walks for radii its grid does not serve. Built once per mesh and shared (TriangleMesh::boxTree), so a mesh
 * read from the disk cache brings its tree and no detector of it builds one.
 */
struct MeshBoxTree {
  std::vector<BoxNode> nodes;        ///< depth first, root at 0 (BoxNode)
  std::vector<std::uint32_t> order;  ///< every triangle once, in leaf order
};

/** \brief The padding of the tree's boxes: 1e-12 of the mesh's coordinates' magnitude or diagonal, whichever is larger.
 */
double meshBoxTreePad(const TriangleMesh& mesh);

/** \brief Builds the tree over the mesh's triangles (empty for a mesh without triangles). */
std::shared_ptr<const MeshBoxTree> buildMeshBoxTree(const TriangleMesh& mesh);

/**
 * \brief Why tree cannot serve mesh, or "" when it can: a depth-first layout the walks can follow (every inner
 * node's children after it and inside the array, at most 60 levels deep), every triangle in exactly one leaf, and
 * every box holding what lies below it (a leaf's box each vertex of its triangles, padded by meshBoxTreePad; an
 * inner node's box its children's). A tree that passes gives exact answers, however it was split. O(nodes +
 * triangles); a stale tree (the mesh's vertices moved since) fails it.
 */
std::string meshBoxTreeProblem(const MeshBoxTree& tree, const TriangleMesh& mesh);

/** \brief mesh.boxTree when it serves the mesh (meshBoxTreeProblem), else a tree built for it. */
std::shared_ptr<const MeshBoxTree> meshBoxTreeOf(const TriangleMesh& mesh);

}  // namespace clod_haptics
