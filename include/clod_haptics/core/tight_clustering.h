#pragma once

#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "clod_haptics/core/clustering.h"
#include "clod_haptics/core/mesh.h"

namespace clod_haptics {

/**
 * \brief Tight sphere sets ("tight" in makeClustering): the surface is split top-down into patches,
 * each wrapped by a sphere centred deep inside the mesh, so that only a thin cap of it lies outside.
 *
 * Every triangle goes to exactly one cluster (the points that wrap it follow it), except a long one split into
 * pieces or one in a thin patch (below), which goes to every cluster holding one of its pieces. The clusters are the
 * leaves of a binary tree that does not depend on d: a node's triangles are split in two at the mean of
 * their centroids along the one of the centroids' three principal axes that leaves the two children most compact
 * (the least largest distance of a centroid from its child's mean), so that a thin cylinder is cut into rings
 * rather than across them; but along the principal axis alone when the mean of the centroids lies outside the mesh
 * (a ring of a hollow tube or of a shell's rim, whose sphere would be centred in the empty space it encloses, and
 * whose halves that measure judges less compact than the ring), so that a hollow part is cut into patches of its
 * wall. A node becomes a sphere when its
 * excess is at most d^3: with R reaching every vertex of its triangles, rho the signed distance from
 * its centre to the mesh (SurfaceDistance) and h = R - rho the height of its cap beyond the tangent
 * plane at the nearest surface point, the excess h^2 (3R - h) / 4 is that cap's volume over 4/3 pi;
 * so d is the radius of a ball holding as much volume as the cap may. A larger d gives fewer, larger
 * spheres (the cut moves up the same tree: the count never grows with d); d = 0 gives one sphere per
 * triangle. Nothing chains: thin parts get small spheres, thick parts few large ones.
 *
 * The cap sees one side of the surface only; a ball in a thin plate sticks out on both sides, one in a
 * leg all the way round. So a node whose cap passes is also scored on every side: from its centre, along
 * 32 directions spread over the sphere, the part of the radius beyond the first surface crossing, s, gives
 * (R^3 - min(s, R)^3) averaged over the directions, the ball's volume beyond the surface over 4/3 pi as
 * seen from the centre (an upper estimate: a region behind a second crossing counts as outside). The
 * excess is the larger of the two.
 *
 * A node's centre is the candidate with the least excess among the mean of the placement's points
 * on its triangles and the mean of the triangles' centroids pushed inward along their mean normal by
 * 2, 3/2, 1, 3/4, 1/2, 1/4 and 1/8 of the mean depth of those points below their triangles (twice the depth
 * is the middle of a thin part for PaperPlacement, a quarter of the way across), and for a node whose items face
 * every way (their unit normals sum to less than a fifth of their count: a ring of a leg or a branch) the middle of
 * its corners' box too, on the ring's axis, where the ball is smallest. Any placement
 * works (the default is PaperPlacement: points a quarter of the way to the opposite triangle).
 * Handing over (when the builder asks for lists): the centres stay, and each triangle (or piece) goes to the
 * sphere it lies deepest in among those that hold it whole and passed the bound (its own, or a neighbour's), for up
 * to 8 rounds; each radius then shrinks to its triangles' farthest corner. No sphere grows, a sphere left with
 * nothing is dropped, and a smaller radius about the same centre only lowers the cap and the volume outside, so
 * every bound above still holds. A triangle at the edge of a large patch that a neighbour already holds stops
 * setting the large sphere's radius: on the shared meshes at 150 and 500 spheres this lowers the outside volume
 * by 10 to 50% (bench/results/thin_tightness.md).
 *
 * Thin patches (when the builder asks for lists): a sphere whose centre lies less than half its radius below the
 * surface, whose corners lie near a plane (within 0.4 of the radius, rms) and whose triangles face both ways
 * (both faces of a plate, not a flat face of a thick part) is a patch of a thin part, its ball sticking out on both
 * sides; its volume outside grows as R^3 while what it covers grows as R^2, so equal,
 * compact patches (hexagons) hold the most for their volume, and the tree's halvings leave rectangles. Such patches
 * are settled before the handing over: their items are halved further (continuing their triangle's halving),
 * Lloyd's rounds on the surface move them between thin patches towards compact, alike patches (out of the tree's
 * grid by a jitter fixed by each patch's index), each centre goes to its patch's smallest enclosing ball, the
 * pieces at a patch's rim are halved once more, and k-centre rounds (each piece to the patch its farthest corner is
 * nearest to, each centre to its patch's smallest enclosing ball) lower the largest radii; the handing over can
 * then give the rim's pieces to a neighbour. On plates
 * this takes 28 to 32% off the spheres' volume at the same count; a triangle in a thin patch may then be listed by
 * several spheres (one per piece at most), like a long one. Deterministic, independent of the threads. A settled
 * sphere is not judged again: the excess bound d^3 above is the judge's for the patches as cut, not a promise for a
 * settled one (CapOfEverySphereHoldsAtMostABallOfRadiusD still holds on head and elephant, whose ears settle).
 *
 * Every radius reaches every corner of every triangle or piece its sphere holds, so coverage holds whatever the
 * centres are: every point of every triangle lies in a sphere listing it (the invariant the detector relies on,
 * see ClodSphereSet).
 *
 * Long triangles: a triangle wholly in one sphere makes that sphere's radius at least half the triangle's longest
 * edge, so a model of long thin triangles would keep large spheres at every d. When some wrapped triangle has an
 * edge longer than pieceEdge times the mesh's diagonal (and the builder asks for lists), the items of the tree are
 * pieces instead: each such triangle halved across its longest edge until no edge is longer (forEachPiece, at
 * most kMaxPieceDepth halvings), the others whole. A piece keeps its triangle's depth hint and normal. The strategy
 * then fits the spheres itself (ClusterLists): each lists the triangles of its pieces, once, and its radius reaches
 * its pieces' corners. A split triangle is listed by every sphere holding one of its pieces; the pieces tile it,
 * so every point of it lies in a sphere listing it (the invariant; fitProblem checks it by the same halving). The
 * tree, and so the count's monotonicity in d, does not depend on d: the pieces depend on the mesh alone. d = 0
 * gives one sphere per piece.
 *
 * Without the mesh (the plain cluster() call) the same split runs on the points alone and a node is
 * kept when all its points lie within d / 2 of their mean. Expected O(n log n).
 */
class TightClustering : public Clustering {
 public:
  /** \brief The default longest edge of a piece, relative to the mesh's diagonal. */
  static constexpr double kDefaultPieceEdge = 1.0 / 64.0;

  /**
   * \brief pieceEdge: a triangle with an edge longer than pieceEdge times the mesh's diagonal is split into pieces
   * (see above); 0 splits none.
   * \throws InvalidParameter for a negative or non-finite pieceEdge.
   */
  explicit TightClustering(double pieceEdge = kDefaultPieceEdge);

  std::uint32_t cluster(const std::vector<Vec3>& points, double d, std::vector<std::uint32_t>& labels) const override;
  std::uint32_t clusterMesh(const TriangleMesh& mesh, const std::vector<Vec3>& points,
                            const std::vector<std::uint32_t>& wrapped, double d, std::vector<std::uint32_t>& labels,
                            std::vector<Vec3>& centres, ClusterLists* lists) const override;

  /** \brief The longest edge of a piece, relative to the mesh's diagonal (0: no triangle is split). */
  double pieceEdge() const { return pieceEdge_; }

 private:
  double pieceEdge_;
};

/**
 * \brief Signed distance from p to the mesh: the distance to the nearest point, negative when p is
 * on the outer side of the face normal of the nearest triangle. A bounding-box tree over the triangles
 * in Morton order, built by one sort.
 */
class SurfaceDistance {
 public:
  /** \brief The mesh must outlive this. */
  explicit SurfaceDistance(const TriangleMesh& mesh);
  /**
   * \brief Signed distance (positive inside); +inf for a mesh without triangles. With a finite bound,
   * a point farther than bound from every triangle gets +bound (the search is pruned there).
   */
  double signedDistance(const Vec3& p, double bound = std::numeric_limits<double>::infinity()) const;

 private:
  static constexpr std::size_t kLeaf = 4;  ///< triangles per leaf
  struct Box {
    double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL};
    double hi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
  };
  const TriangleMesh& mesh_;
  std::vector<Box> boxes_;            ///< complete binary tree in heap layout, leaves last
  std::vector<std::uint32_t> order_;  ///< triangles in Morton order, kLeaf per leaf
  std::vector<double> corners_;       ///< their corners in that order, 9 per triangle (a leaf reads one run)
  std::vector<double> planes_;        ///< their planes in that order, 5 per triangle (normal, offset, thickness)
  std::size_t leaves_ = 0;            ///< leaves in the tree (a power of two)
};

}  // namespace clod_haptics
