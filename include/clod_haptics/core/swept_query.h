#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "clod_haptics/core/box_tree.h"
#include "clod_haptics/core/detector.h"
#include "clod_haptics/core/geometry.h"
#include "clod_haptics/core/mesh.h"
#include "clod_haptics/core/mesh_box_tree.h"

namespace clod_haptics {

struct WideBoxTree;  // internal to the core (src/core/wide_box_tree.h)

/**
 * \brief The first contact of a sphere of radius r whose centre moves along the segment a -> b (continuous
 * collision detection): what a haptic proxy needs so that it never jumps through a part thinner than its
 * motion in one tick. Fields other than hit, toi and trianglesTested are meaningful only when hit is true.
 *
 * Contact means distance(centre, triangle) <= r. The answer is the smallest time of impact over the
 * triangles, ties to the lowest triangle index (but see the hint of bruteForceSweep), with these rules (the same for
 * every triangle):
 * - Moving sphere: the first t in [0, 1] at which the sphere touches a triangle it did not touch at t = 0.
 * - Start in contact (the sphere touches a triangle at a): t = 0 when the motion brings the centre closer to
 *   that triangle (or the centre lies on it, within 1e-9 r); a motion that keeps or grows the distance (sliding along
 * the triangle, leaving it) is free of that triangle, which lets a sphere resting on a surface slide and lift. Distance
 * to a triangle is convex along a line, so such a motion never comes back to it.
 * - Zero-length sweep (a == b): a point query, t = 0 when the sphere touches a triangle.
 * Conservative: the test runs with the radius inflated by sweptRadiusMargin (1e-10 of the coordinates'
 * magnitude), so rounding can report a contact slightly early, never a blocked path as free.
 */
struct SweptContact {
  bool hit = false;
  double toi = 1.0;             ///< time of impact in [0, 1] (1 without a hit)
  Vec3 centre = Vec3::Zero();   ///< sphere centre at toi: a + toi (b - a), model frame
  Vec3 point = Vec3::Zero();    ///< closest point of the triangle to that centre, model frame
  Vec3 normal = Vec3::Zero();   ///< unit, from point towards the centre (the direction that pushes the sphere out)
  std::int32_t triangle = -1;   ///< triangle of the contact
  TriangleRegion region;        ///< feature of the triangle the point lies on (face, edge, vertex)
  bool startInContact = false;  ///< the sphere touched the triangle at a (toi = 0)
  std::uint32_t trianglesTested = 0;  ///< exact triangle tests run (statistics)
};

/**
 * \brief The radius the exact tests use for a sweep of radius r whose coordinates are at most magnitude
 * (absolute) in size: r plus 1e-10 (r + magnitude), so that double rounding never hides a contact.
 */
inline double sweptRadiusMargin(double r, double magnitude) { return r + 1e-10 * (r + magnitude); }

/**
 * \brief The exact test of one triangle (v0, v1, v2) against the sphere of radius R whose centre moves
 * from a by d (face plane, three edge capsules, three vertex spheres, in double), with SweptContact's rules.
 * tMax: only a contact at a time up to it is reported (the best so far of a search; the test is cheaper
 * the earlier it is); the time reported does not depend on it.
 * \return true with the time of impact in toi (in [0, min(1, tMax)]) and whether it is a start in contact.
 */
bool sweptSphereTriangle(const Vec3& a, const Vec3& d, double R, const Vec3& v0, const Vec3& v1, const Vec3& v2,
                         double& toi, bool& startInContact, double tMax = 1.0) noexcept;

/**
 * \brief The reference: every triangle of the mesh with sweptSphereTriangle, the smallest time of impact
 * (ties to the lowest index). a, b and the answer in the model frame. O(triangles); tests use it.
 * hint: a triangle that wins a tie at toi = 0 when it blocks the sweep at 0 (any triangle that blocks at 0 is a
 * first contact; a proxy resting on its last contact passes that one, and the search then ends at once). -1: none.
 */
SweptContact bruteForceSweep(const TriangleMesh& mesh, const Vec3& a, const Vec3& b, double r, std::int32_t hint = -1);

/**
 * \brief The accelerated swept-sphere query of one mesh: answers exactly what bruteForceSweep answers.
 *
 * For radii the detector's grid serves (ClodDetector::grid(), r up to gridRadius()), the sweep is cut into
 * pieces no longer than a cell, and the candidates of the cells each piece passes through are tested, piece
 * by piece until the first contact lies within the pieces seen, the piece cut back to the best time so far:
 * a short sweep costs a few point queries. The grid lists every triangle within its radius of a cell, so
 * every contact at radius r is found; a triangle that comes within the rounding margin beyond the grid's
 * radius but never within it may be passed over there (the answer then differs from bruteForceSweep's only
 * within that margin, and still reports no path free that is blocked at radius r).
 * Larger radii, a mesh without a grid, a sweep longer than 4096 cells, and a sweep that starts or ends in a cell
 * listing more than ClodDetector::kTreeAboveEntries triangles (triangles far smaller than r) walk the box tree over the
 * triangles (MeshBoxTree: the grid detector's, else the mesh's own when it fits, else built here) with the capsule,
 * nearest node first; a node is entered when the part of the sweep inside its box grown by r comes within r of the
 * box and of the node's slab (NodeSlab).
 *
 * Immutable after construction: sweep() is const, allocates nothing, never throws, and may run on many
 * threads at once.
 */
class SweptSphereQuery {
 public:
  /**
   * \brief Prepares the query for a mesh, using detector's grid when it has one (detector may be null).
   * \throws InvalidParameter when mesh is null or detector belongs to another mesh.
   */
  explicit SweptSphereQuery(std::shared_ptr<const TriangleMesh> mesh,
                            std::shared_ptr<const ClodDetector> detector = nullptr);

  /**
   * \brief The first contact of the sphere (radius r) moving a -> b (model frame), as bruteForceSweep.
   * Non-finite input or a radius outside [0, kMaxRadius] answers no hit. hint: a triangle likely to be the
   * first contact (a proxy's last contact), tested first so that its time prunes the rest; when it blocks the
   * sweep at toi = 0 it is the answer and nothing else is searched. The answer is bruteForceSweep's with the same
   * hint.
   */
  void sweep(const Vec3& a, const Vec3& b, double r, SweptContact& out, std::int32_t hint = -1) const noexcept;

  /**
   * \brief Whether one triangle blocks the sweep at toi = 0 (the sphere touches it at a, and the motion does not
   * keep away from it), with sweep's rules: then out is what sweep answers with that triangle as its hint, and true.
   * Otherwise out is left as it was. A proxy wedged against several triangles checks its last constraints this way
   * before it searches. Allocation-free, noexcept; false for a triangle out of range, non-finite input or a negative
   * or NaN within.
   * \param within also true when the sweep meets the triangle before the centre has moved this far (a proxy left a
   * hair above its constraints): out is then answered at toi = 0 all the same, the centre at a. Another triangle may
   * come first within that distance: a caller that stays at a enters neither.
   */
  bool blocksAtStart(std::int32_t triangle, const Vec3& a, const Vec3& b, double r, SweptContact& out,
                     double within = 0.0) const noexcept;

  /** \brief The mesh. */
  const std::shared_ptr<const TriangleMesh>& mesh() const { return mesh_; }
  /** \brief The detector whose grid is used (may be null). */
  const std::shared_ptr<const ClodDetector>& detector() const { return detector_; }

 private:
  struct Best;
  const double* recordOf(std::uint32_t t) const noexcept;
  void testTriangle(std::uint32_t t, const Vec3& a, const Vec3& d, double R, Best& best) const noexcept;
  void testRecord(std::uint32_t t, const Vec3& a, const Vec3& d, double R, Best& best) const noexcept;
  void sweepGrid(const Vec3& a, const Vec3& d, double R, Best& best) const noexcept;
  void sweepCell(const CellGrid::CellRef& ref, std::uint64_t key, const Vec3& p0, const Vec3& p1, const Vec3& a,
                 const Vec3& d, double R, double t0, double t1, Best& best) const noexcept;
  /** The triangles order[from, from + few) of tree_ (a leaf or small subtree), through the records' filter. */
  void testRun(std::uint32_t from, std::uint32_t few, const Vec3& a, const Vec3& d, double R,
               Best& best) const noexcept;
  void sweepTree(const Vec3& a, const Vec3& d, double R, Best& best) const noexcept;
  void sweepWide(const Vec3& a, const Vec3& d, double R, Best& best) const noexcept;
  /** Whether the grid's cell at a local point lists more than ClodDetector::kTreeAboveEntries triangles. */
  bool crowdedAt(const Vec3& local) const noexcept;

  std::shared_ptr<const TriangleMesh> mesh_;
  std::shared_ptr<const ClodDetector> detector_;
  const CellGrid* grid_ = nullptr;  // the detector's grid, null when it has none
  // Per triangle, what the filters read (ball: centre, radius; unit normal, thickness; local frame), one cache line
  // each: a record that straddles two lines costs the filter two loads. The exact test reads the mesh's corners.
  struct alignas(64) Record {
    double v[8];
  };
  std::vector<Record> records_;
  std::shared_ptr<const MeshBoxTree> tree_;  // box tree over the triangles and its slabs (local frame), shared
  /**
   * A subtree of at most this many triangles (two leaves) is not walked: its triangles go straight to the records'
   * filter, four at a time. On the 0.1 r ellipsoid (122k triangles, every sweep walking the tree) the proxy's ticks
   * at 2 m/s were 6 to 11% faster than with the leaves alone (two sets of alternating runs), on the 0.25 r one the
   * same; 16 and 32 were no better.
   */
  static constexpr std::uint32_t kSmallSubtree = 8;
  // Per node of tree_: the number of triangles below it when it is a leaf or a subtree of at most kSmallSubtree
  // triangles lying together in the order array (from its leftmost leaf's first), else 0.
  std::vector<std::uint8_t> small_;
  /**
   * The same tree four children to a node, ending at the small subtrees (WideBoxTree, internal to the core), tested
   * four at a time in AVX2 (sweepWide): where the CPU does not run AVX2, sweepTree walks tree_. Null without it.
   */
  std::shared_ptr<const WideBoxTree> wide_;
};

}  // namespace clod_haptics
