#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "clod_haptics/core/box_tree.h"
#include "clod_haptics/core/contact.h"
#include "clod_haptics/core/mesh.h"
#include "clod_haptics/core/sphere_set.h"

namespace clod_haptics {

/** \brief How the fast level finds the spheres the pointer overlaps, and how a hit sphere is searched. */
enum class FastLevel : std::uint8_t {
  Flat,       ///< the paper: the pointer against every sphere, then every triangle a hit sphere lists
  Hierarchy,  ///< a box tree over the spheres, then a box tree over each sphere's triangles; O(log n)
};

/** \brief Parses "flat" or "hierarchy"; returns false for anything else. */
bool parseFastLevel(const char* text, FastLevel& level);

/**
 * \brief Two-level collision detection of a pointer sphere against one CLOD level (paper 3.3).
 *
 * Immutable after construction: query() is const, allocates nothing, never throws and may be called
 * from any number of threads at once. Swap levels by building a new detector and exchanging a
 * shared_ptr.
 */
class ClodDetector {
 public:
  /** \brief Prepares the flat arrays and trees; the mesh and set are kept alive by the pointers. */
  ClodDetector(std::shared_ptr<const TriangleMesh> mesh, std::shared_ptr<const ClodSphereSet> spheres,
               FastLevel fastLevel = FastLevel::Hierarchy);

  /**
   * \brief Answers whether the pointer (centre p, radius r) touches the mesh, and where.
   * A non-finite p or r, or a negative r, answers no contact.
   */
  void query(const Vec3& p, double r, DetectionMode mode, ContactResult& out) const noexcept;

  /** \brief Indices of the spheres the pointer overlaps (for display; allocates into out). */
  void hitSpheres(const Vec3& p, double r, std::vector<std::uint32_t>& out) const;

  /** \brief The mesh. */
  const std::shared_ptr<const TriangleMesh>& mesh() const { return mesh_; }
  /** \brief The sphere set. */
  const std::shared_ptr<const ClodSphereSet>& spheres() const { return spheres_; }
  /** \brief The fast-level strategy in use. */
  FastLevel fastLevel() const { return fastLevel_; }

 private:
  struct Best;
  template <class Visit>
  void forEachHitSphere(double px, double py, double pz, const double& reach, Visit&& visit) const;
  void preciseFlat(std::uint32_t sphere, const Vec3& p, DetectionMode mode, Best& best) const;
  void preciseTree(std::uint32_t sphere, const Vec3& p, DetectionMode mode, Best& best) const;
  void testTriangle(std::uint32_t tri, std::uint32_t sphere, const Vec3& p, DetectionMode mode, Best& best) const;

  std::shared_ptr<const TriangleMesh> mesh_;
  std::shared_ptr<const ClodSphereSet> spheres_;
  FastLevel fastLevel_;
  double pad_ = 0.0;  // conservative padding relative to the model's coordinates

  // Flat copies for the cache: triangle corners (9 doubles each) and padded spheres (x, y, z, radius).
  std::vector<double> corners_;
  std::vector<double> sphereData_;
  // Hierarchy: tree over spheres, and one tree per sphere over its triangles.
  std::vector<BoxNode> sphereNodes_;
  std::vector<std::uint32_t> sphereOrder_;
  std::vector<BoxNode> triangleNodes_;
  std::vector<std::uint32_t> triangleOrder_;  // triangle indices in per-sphere leaf order
  std::vector<std::uint32_t> triangleRoot_;   // per sphere: root in triangleNodes_
};

}  // namespace clod_haptics
