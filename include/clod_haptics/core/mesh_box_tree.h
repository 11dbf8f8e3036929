#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "clod_haptics/core/box_tree.h"
#include "clod_haptics/core/mesh.h"

namespace clod_haptics {

/**
 * \brief A slab and a ball around the triangles below one node of a MeshBoxTree: every vertex below lies within
 * `thick` of the plane through `centre` with unit `normal` and within `radius` of `centre` (rounded up). A node's
 * box keeps what lies within the pointer radius of its corners; on a finely tessellated surface turned against the
 * axes that is several times the triangles the slab and ball keep (a patch's box is as deep as it is wide).
 * A node without a bound has a zero normal and infinite thick and radius. ClodDetector's walk of the tree (crowded
 * cells, pointers beyond the grid's radius, the deep search) and the swept query's prune by them.
 */
struct NodeSlab {
  Vec3 centre = Vec3::Zero();
  Vec3 normal = Vec3::Zero();
  double thick = std::numeric_limits<double>::infinity();
  double radius = std::numeric_limits<double>::infinity();
};

/**
 * \brief What a walk down a box tree reads next at an inner node whose children are left (the node's successor) and
 * right: requested together (the right child's box lies elsewhere in the array, each slab is 64 bytes and may
 * straddle two lines), so that a walk into a region it has not touched lately waits for them at once rather than one
 * after another. slabs may be null (a tree without them).
 */
inline void prefetchChildren(const BoxNode* nodes, const NodeSlab* slabs, std::uint32_t left, std::uint32_t right) {
  __builtin_prefetch(&nodes[right]);
  if (slabs == nullptr) return;
  __builtin_prefetch(&slabs[left]);
  __builtin_prefetch(&slabs[right]);
  __builtin_prefetch(reinterpret_cast<const char*>(&slabs[left]) + 63);
  __builtin_prefetch(reinterpret_cast<const char*>(&slabs[right]) + 63);
}

/**
 * \brief One box tree over all the triangles of a mesh (leaves of 4, boxes padded by meshBoxTreePad), in the
 * mesh's local frame: what the grid level walks beyond its radius and for the deep search, and what the swept
 * query walks for radii its grid does not serve. Built once per mesh and shared (TriangleMesh::boxTree), so a mesh
 * read from the disk cache brings its tree and no detector of it builds one.
 */
struct MeshBoxTree {
  std::vector<BoxNode> nodes;        ///< depth first, root at 0 (BoxNode)
  std::vector<std::uint32_t> order;  ///< every triangle once, in leaf order
  /// Per node, what the walks prune by beside the boxes (meshTreeSlabs): filled by buildMeshBoxTree and meshBoxTreeOf,
  /// and stored in the mesh cache with the tree.
  std::vector<NodeSlab> slabs;
  /// meshFingerprint of the mesh the tree and its slabs were built for or checked against (meshBoxTreeProblem), 0 if
  /// none: a mesh with that fingerprint is served without the check (the mesh cache reads and checks the tree, then
  /// every detector and swept query of the mesh asks meshBoxTreeOf again).
  std::uint64_t servesFingerprint = 0;
};

/** \brief Triangles per leaf of the MeshBoxTree, at most. */
constexpr int kMeshBoxTreeLeafSize = 4;

/** \brief A checksum of the mesh's vertices and triangles (cacheChecksum): what a box tree over it depends on. */
std::uint64_t meshFingerprint(const TriangleMesh& mesh);

/** \brief The padding of the tree's boxes: 1e-12 of the mesh's coordinates' magnitude or diagonal, whichever is larger.
 */
double meshBoxTreePad(const TriangleMesh& mesh);
/** \brief The same from the mesh's bounds (TriangleMesh::bounds, a pass over every vertex) when the caller has them. */
double meshBoxTreePad(const Eigen::AlignedBox3d& bounds);

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
/** \brief The same with the mesh's pad given (meshBoxTreePad(mesh)). */
std::string meshBoxTreeProblem(const MeshBoxTree& tree, const TriangleMesh& mesh, double pad);

/**
 * \brief mesh.boxTree when it serves the mesh with its slabs (its servesFingerprint is the mesh's); a copy of it with
 * the slabs computed again when meshBoxTreeProblem finds nothing (the vertices may have moved within the boxes); else
 * a tree built for it. The tree returned always has its slabs.
 */
std::shared_ptr<const MeshBoxTree> meshBoxTreeOf(const TriangleMesh& mesh);
/** \brief The same with the mesh's pad given (meshBoxTreePad(mesh)). */
std::shared_ptr<const MeshBoxTree> meshBoxTreeOf(const TriangleMesh& mesh, double pad);

/** \brief Below this many triangles a node gets a slab (above, a curved surface makes the slab as thick as the box). */
constexpr std::uint32_t kSlabTriangles = 64;

/** \brief One slab per node of tree (which serves mesh): the nodes with at most kSlabTriangles below, else none. */
std::vector<NodeSlab> meshTreeSlabs(const MeshBoxTree& tree, const TriangleMesh& mesh);
/** \brief The same with the mesh's pad given (meshBoxTreePad(mesh)). */
std::vector<NodeSlab> meshTreeSlabs(const MeshBoxTree& tree, const TriangleMesh& mesh, double pad);

/**
 * \brief A lower bound of the squared distance from p to every point below the slab's node: the distance across the
 * slab and along its plane beyond the ball (each point below is at least that far on each, and they are orthogonal).
 */
inline double slabSquaredDistance(const NodeSlab& s, const Vec3& p) {
  const Vec3 m = p - s.centre;
  const double h = s.normal.dot(m);
  const double across = std::max(0.0, std::abs(h) - s.thick);
  const double along = std::max(0.0, (m - h * s.normal).norm() - s.radius);
  return across * across + along * along;
}

}  // namespace clod_haptics
