#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "clod_haptics/core/eigen_abi.h"  // a program built with other vector flags fails to link, not at run time

namespace clod_haptics {

using Vec3 = Eigen::Vector3d;
/** \brief Vertex indices of one triangle. */
using Triangle = std::array<std::uint32_t, 3>;

struct MeshBoxTree;

/**
 * \brief An indexed triangle mesh in double precision, the geometry every other piece reads.
 *
 * Built only through makeMesh() or loadMesh(), which validate it: every index is in range, every
 * coordinate finite. Zero-area triangles are kept (they must still be covered by a sphere) and get
 * a zero normal rather than NaN.
 */
struct TriangleMesh {
  std::string name;                 ///< file name or a caller-given label
  /**
   * Positions relative to `origin`, after scaling or normalising: the model frame's vertex i is
   * vertices[i] + origin. Every structure built from the mesh (spheres, grids, trees) is in this local
   * frame; every point a caller passes in or gets back (queries, contacts, probes, markers) is in the model
   * frame. See chooseLocalOrigin().
   */
  std::vector<Vec3> vertices;
  /// Where the local frame's zero lies in the model frame: zero for a mesh near the model frame's origin,
  /// the bounds' centre on each axis where the mesh lies far from it (see chooseLocalOrigin()).
  Vec3 origin = Vec3::Zero();
  std::vector<Triangle> triangles;  ///< counter-clockwise seen from outside when the source is consistent
  std::vector<Vec3> normals;        ///< unit face normal per triangle, or zero for a zero-area triangle
  /**
   * Adjacency for the inside/outside test (pointBehindSurface in contact.h), filled by computeAdjacency().
   * Per triangle, the triangles across its three edges: the other triangle of a manifold edge (exactly two
   * triangles, wound in opposite directions), -1 for a boundary, non-manifold or inconsistently wound edge.
   * Unordered: a neighbour is found by the edge's two vertex ids, so the entry stays valid when a triangle's
   * winding is reversed in place (as the loader does for an inside-out mesh).
   */
  std::vector<std::array<std::int32_t, 3>> neighbours;
  /// Per vertex v, its corners are [cornerOffsets[v], cornerOffsets[v + 1]) in the two arrays below.
  std::vector<std::uint32_t> cornerOffsets;
  std::vector<std::uint32_t> cornerTriangles;  ///< the triangle of each corner, ascending per vertex
  std::vector<float> cornerAngles;             ///< the triangle's angle at that corner (radians)
  double scale = 1.0;               ///< factor applied to the source coordinates
  Vec3 offset = Vec3::Zero();       ///< translation applied after scaling (normalising only)
  bool flipped = false;             ///< windings were reversed at load to make normals point outward
  /// The box tree over the triangles (mesh_box_tree.h) when the mesh came with one (MeshCache stores it): shared by
  /// every detector and swept query of the mesh, each of which checks it against the vertices before use and builds
  /// its own otherwise. Null after makeMesh or loadMesh.
  std::shared_ptr<const MeshBoxTree> boxTree;

  /** \brief Number of triangles. */
  std::size_t size() const { return triangles.size(); }
  /** \brief Vertex k (0..2) of triangle t. */
  const Vec3& vertex(std::size_t t, int k) const { return vertices[triangles[t][k]]; }
  /** \brief Centroid of triangle t. */
  Vec3 centroid(std::size_t t) const { return (vertex(t, 0) + vertex(t, 1) + vertex(t, 2)) / 3.0; }
  /** \brief Axis-aligned bounds of all vertices referenced by triangles. */
  Eigen::AlignedBox3d bounds() const;
  /** \brief bounds() in the model frame (translated by origin). */
  Eigen::AlignedBox3d modelBounds() const { return bounds().translated(origin); }
  /** \brief A point of the model frame in the local frame of vertices. */
  Vec3 toLocal(const Vec3& model) const { return model - origin; }
  /** \brief A point of the local frame of vertices in the model frame. */
  Vec3 toModel(const Vec3& local) const { return local + origin; }
  /** \brief Length of the bounds' diagonal: the model size every relative tolerance refers to. */
  double diagonal() const { return bounds().diagonal().norm(); }
};

/**
 * \brief The local origin for vertices whose bounds are `box` (model frame): on each axis, the box's centre
 * when the box lies farther than 4 times its largest side from zero on that axis, else zero.
 *
 * Why: a mesh 1 unit wide at x = 1e6 has a double spacing of 1.2e-10 there, so distances computed from its
 * coordinates carry errors of about 1e-10 (2e-8 of a 5 mm pointer). Relative to its centre the same mesh
 * has the precision of a mesh at the origin. The subtraction is exact: every coordinate v on such an axis
 * lies within a factor 2 of the centre c (|c| > 4 * side >= 8 * |v - c|), where Sterbenz's lemma makes
 * v - c a double. So local + origin gives back the model coordinate bit for bit, and no precision is lost
 * anywhere. Near zero the coordinates are already as small as the mesh, and a zero origin keeps them as given.
 */
Vec3 chooseLocalOrigin(const Eigen::AlignedBox3d& box);

/**
 * \brief Builds a validated mesh from raw arrays (model frame) and computes the face normals and the adjacency.
 * The vertices are stored relative to chooseLocalOrigin() of their bounds (mesh.origin).
 * \throws InvalidParameter when an index is out of range, a coordinate is not finite or there is no triangle.
 */
TriangleMesh makeMesh(std::vector<Vec3> vertices, std::vector<Triangle> triangles, std::string name = "mesh");

/**
 * \brief As makeMesh, for vertices already relative to a given local origin (mesh.origin = origin, nothing
 * subtracted): a part of a mesh cut out with that mesh's vertices and origin computes bit for bit as the whole.
 * \throws InvalidParameter as makeMesh, and for a non-finite origin.
 */
TriangleMesh makeLocalMesh(std::vector<Vec3> localVertices, std::vector<Triangle> triangles, std::string name,
                           const Vec3& origin);

/**
 * \brief Fills the mesh's adjacency (neighbours, corners and their angles) from its triangles and vertices:
 * what the pseudo-normals of edges and vertices are assembled from. makeMesh() and readMeshBinary() call it.
 * The data depends only on the connectivity and the angles, so scaling, translating or reversing every
 * winding afterwards (the loader's transformMesh and orientation) leaves it valid. 12 bytes per triangle for
 * the neighbours, 24 per triangle for the corners, 4 per vertex for the offsets.
 */
void computeAdjacency(TriangleMesh& mesh);

/** \brief Unit normal of the triangle (a, b, c), or zero when its area is zero relative to its size. */
Vec3 faceNormal(const Vec3& a, const Vec3& b, const Vec3& c);

}  // namespace clod_haptics
