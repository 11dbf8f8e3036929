#pragma once
// Sphere tightness (the paper's Figs. 17 to 19): an octree sphere set of a given count, point in
// any sphere, and point inside a closed mesh, for Monte Carlo volumes and surface coverage.

#include <memory>
#include <vector>

#include "clod_haptics/core/mesh.h"
#include "clod_haptics/core/triangle_bvh.h"

namespace clod_bench {

using clod_haptics::TriangleMesh;
using clod_haptics::Vec3;

/** \brief Plain spheres. */
struct SphereList {
  std::vector<Vec3> centres;
  std::vector<double> radii;
};

/**
 * \brief Octree sphere set (as in Bradshaw's toolkit): the cube around the mesh is split into eight,
 * keeping the cells a triangle overlaps (exact triangle-box test), largest cells first, until at
 * least `target` cells; each cell gives its circumscribed sphere, so the surface is covered.
 */
SphereList octreeSpheres(const TriangleMesh& mesh, std::size_t target, int& maxDepth);

/** \brief Triangle-box overlap by the separating axis theorem (Akenine-Moller), touching counts. */
bool triangleBoxOverlap(const Vec3& centre, double half, const Vec3& a, const Vec3& b, const Vec3& c);

/** \brief A uniform grid over spheres answering "is p inside any sphere" (boundary included). */
class SphereGrid {
 public:
  explicit SphereGrid(const SphereList& spheres);
  bool contains(const Vec3& p) const;
  /** \brief Number of spheres containing p. */
  std::size_t count(const Vec3& p) const;
  /** \brief Bounds of the union of the spheres. */
  Eigen::AlignedBox3d bounds() const { return box_; }

 private:
  std::size_t visit(const Vec3& p, bool firstOnly) const;
  const SphereList& s_;
  Eigen::AlignedBox3d box_;
  double inv_ = 1.0;
  int n_[3] = {1, 1, 1};
  std::vector<std::uint32_t> start_, items_;
};

/**
 * \brief Inside test for a closed (or nearly closed) mesh: the winding number along a ray (signed
 * crossings), non-zero inside, majority over three fixed directions.
 */
class InsideTest {
 public:
  explicit InsideTest(const TriangleMesh& mesh) : mesh_(mesh), bvh_(mesh) {}
  bool inside(const Vec3& p) const;

 private:
  const TriangleMesh& mesh_;
  clod_haptics::TriangleBvh bvh_;
};

}  // namespace clod_bench
