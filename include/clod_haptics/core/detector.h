#pragma once

#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <vector>

#include "clod_haptics/core/box_tree.h"
#include "clod_haptics/core/cell_grid.h"
#include "clod_haptics/core/contact.h"
#include "clod_haptics/core/mesh.h"
#include "clod_haptics/core/mesh_box_tree.h"
#include "clod_haptics/core/sphere_set.h"
#include "clod_haptics/core/sphere_trees.h"

namespace clod_haptics {

struct WideBoxTree;  // internal to the core (src/core/wide_box_tree.h)

/** \brief How the fast level finds the spheres the pointer overlaps, and how a hit sphere is searched. */
enum class FastLevel : std::uint8_t {
  Flat,       ///< the paper: the pointer against every sphere, then every triangle a hit sphere lists
  Hierarchy,  ///< a box tree over the spheres, then a box tree over each sphere's triangles; O(log n)
  Grid,  ///< the fast level precomputed per grid cell (CellGrid), O(1); one box tree over the mesh beyond its radius
};

/**
 * \brief Per-stream state for temporal coherence: a haptic pointer moves little between two
 * queries, so the last cell and (after a step of at most the radius) the last contact triangle are tried first, and
 * a slow stream answers from the triangles it kept near its pointer (the neighbourhood below). Owned by the caller
 * (one per stylus stream, not shared between threads; about 700 bytes). Every contact within the pointer radius is
 * answered the same with or without it; the cache adds one thing, deep penetration: after an answer with the
 * centre inside, the stream keeps its contact when the centre goes deeper than the radius (see query()).
 */
struct QueryCache {
  /// The detector that filled it, by ClodDetector::id() (never by address: a freed detector's address is
  /// reused by the next allocation, its id never is). 0: empty. Another detector ignores the entry.
  std::uint64_t owner = 0;
  std::uint64_t key = ~0ull;       ///< last grid cell
  const void* cell = nullptr;      ///< that cell's index entry in the grid (null: empty cell)
  std::int32_t lastTriangle = -1;  ///< last contact triangle
  std::uint64_t hits = 0;          ///< queries that reused the cell (statistics)
  /// The last answer was a contact with the centre inside: the next query follows it beyond the radius.
  /// Kept across detectors (a level swap of the same part keeps the push); an invalid query leaves it.
  bool lastInside = false;
  /// The last contact's distance from its centre to the nearest triangle, and that centre (local frame): the nearest
  /// triangle of a later centre p is at least lastDistance - |p - lastDistanceAt| away, which tells a followed push
  /// where it need not look (ClodDetector's deep search). NaN when the last answer was no contact. A bound on the
  /// work only: after a swap to another mesh it may be wrong, and then costs a walk of the tree, never an answer.
  double lastDistance = std::numeric_limits<double>::quiet_NaN();
  Vec3 lastDistanceAt = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());

  /// The neighbourhood of a slow stream (exact mode on the grid): while the pointer moves less than a sixteenth of
  /// its radius a query, the query that scans a cell also keeps every triangle of that cell's list within the radius
  /// plus a margin of its centre (nearTriangle, nearest first, with that distance). The next queries in the same
  /// cell within the margin of that centre test only those, nearest first, and stop at the first one too far: a
  /// triangle within the radius of such a centre is within the radius plus the margin of the first. Same answers.
  static constexpr std::uint32_t kNear = 48;
  Vec3 lastPoint = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());  ///< last centre (local frame)
  Vec3 nearAnchor = Vec3::Zero();  ///< the centre the neighbourhood was filled at (local frame)
  std::uint64_t nearKey = ~0ull;   ///< that centre's grid cell, whose list the neighbourhood is drawn from
  double nearRadius = 0.0;         ///< the radius it serves
  double nearMargin = -1.0;        ///< how far from the anchor it holds (< 0: no neighbourhood)
  std::uint32_t nearSpheres = 0;   ///< the cell's sphere count (the answer's spheresHit)
  std::uint32_t nearCount = 0;
  std::uint32_t nearTriangle[kNear] = {};
  double nearDistance[kNear] = {};
  std::uint64_t nearHits = 0;  ///< queries answered from the neighbourhood (statistics)
};

/** \brief Parses "flat", "hierarchy" or "grid"; returns false for anything else. */
bool parseFastLevel(const char* text, FastLevel& level);

/** \brief The name parseFastLevel reads: "grid", "hierarchy" or "flat". */
const char* toString(FastLevel level);

/**
 * \brief Two-level collision detection of a pointer sphere against one CLOD level (paper 3.3).
 *
 * Immutable after construction: query() is const, allocates nothing, never throws and may be called
 * from any number of threads at once. Swap levels by building a new detector and exchanging a
 * shared_ptr.
 */
class ClodDetector {
 public:
  /**
   * \brief Prepares the flat arrays and trees; the mesh and set are kept alive by the pointers.
   * \param gridRadius for FastLevel::Grid, the largest pointer radius the grid serves (larger ones use
   * the hierarchy); 0 picks 1% of the model's diagonal.
   * \param gridSource for FastLevel::Grid, where the grid and the trees over the spheres come from instead of a
   * build (a disk cache, see CellGridCache): called once with the radius (after the 0 default is resolved), it
   * returns what buildGridParts(*mesh, *spheres, radius) would build, or builds it. Empty: both are built here.
   * \throws SphereSetMismatch when the set does not fit the mesh (fitProblem): built for another mesh or scale;
   * InvalidParameter when gridSource returns a grid of another radius or trees over another number of spheres
   * (a disk cache checks the trees themselves: sphereTreesProblem); whatever gridSource throws.
   */
  struct GridParts {
    CellGrid grid;
    SphereTrees trees;
  };
  using GridSource = std::function<GridParts(double radius)>;
  /**
   * \brief What a Grid detector of mesh and spheres builds beyond them for a grid radius (> 0): the grid and the
   * trees over the spheres (padded by meshBoxTreePad(mesh)). The set must fit the mesh (fitProblem).
   * sameMesh: the grid of another level's Grid detector of this mesh (or null): when its cells are those this build
   * would choose, the grid is made from it (CellGrid::forLevel, the same grid at a fraction of the cost; reused, when
   * given, says whether it was).
   */
  static GridParts buildGridParts(const TriangleMesh& mesh, const ClodSphereSet& spheres, double radius,
                                  const CellGrid* sameMesh = nullptr, bool* reused = nullptr);
  /**
   * \brief The bytes per triangle a Grid detector of mesh and spheres gives its grid (CellGrid's bytesPerTriangle):
   * kBytesPerTriangle less what it keeps beside the grid (trees, as given, the mesh's box tree, per-sphere and
   * per-triangle arrays), at least kMinGridBytesPerTriangle. A function of the mesh's and set's sizes and the trees'
   * only, so a grid built for a disk cache is the grid the detector builds.
   */
  static double gridBytesPerTriangle(const TriangleMesh& mesh, const ClodSphereSet& spheres, const SphereTrees& trees);
  /**
   * \brief A grid cell that lists more triangles than this is answered through the tree over the mesh instead of
   * its sorted scan. Such cells come from triangles far smaller than the grid radius (thousands within reach of
   * every point of the cell, most of them scanned); the tree then reads a few dozen. Measured on ellipsoids
   * tessellated at 0.1 to 0.35 of the radius, probes in random order (bench/README.md): the tree answers faster
   * from about 1,000 to 2,000 entries up; below, the scan. The answers are the same either way (both find every
   * triangle within the radius, ties to the lowest index).
   */
  static constexpr std::uint32_t kTreeAboveEntries = 2048;
  /**
   * \brief The memory a Grid detector aims at per triangle, everything it keeps counted (bytes()): its grid is given
   * what the trees and arrays leave (CellGrid's bytesPerTriangle, at least kMinGridBytesPerTriangle), and takes it
   * only where coarser cells cost its queries no speed; a mesh of small or long thin triangles keeps the cells its
   * queries need and may take more.
   */
  static constexpr double kBytesPerTriangle = 300.0;
  static constexpr double kMinGridBytesPerTriangle = 64.0;
  /** \brief The radius of the grid a Grid detector of mesh builds for gridRadius (0: 1% of the diagonal). */
  static double effectiveGridRadius(const TriangleMesh& mesh, double gridRadius);
  /** \brief The same from the mesh's bounds (TriangleMesh::bounds). */
  static double effectiveGridRadius(const Eigen::AlignedBox3d& bounds, double gridRadius);
  ClodDetector(std::shared_ptr<const TriangleMesh> mesh, std::shared_ptr<const ClodSphereSet> spheres,
               FastLevel fastLevel = FastLevel::Grid, double gridRadius = 0.0, const GridSource& gridSource = {});

  /**
   * \brief Answers whether the pointer (centre p, radius r) touches the mesh, and where. p and the contact
   * point are in the model frame (TriangleMesh::origin added back); the search runs in the mesh's local frame.
   * A non-finite p or r, a negative r or one above kMaxRadius answers no contact. cache (optional) carries temporal
   * coherence between the queries of one stream.
   *
   * Depth is the signed penetration (ContactResult::depth): r - distance outside, r + distance with the
   * centre behind the surface. Deep penetration, the centre more than r behind the surface, has no
   * triangle within r: with a cache whose last answer was inside (exact or paper mode), the search finds the
   * nearest triangle within the model's bounding-box diagonal, for a centre inside that box (the grid level: one
   * walk of its tree over the mesh; the others: radius doubling from 2r); inside by pointBehindSurface, the
   * answer is that contact (depth r + distance, as bruteForceSignedQuery), else no contact. Without a cache
   * (stateless queries) a deep centre answers no contact, as bruteForceQuery. The deep search costs more than a
   * bounded query (the flat level also scans the mesh's bounds) and still allocates nothing.
   *
   * Spheres mode answers the sphere of the level whose surface is nearest the pointer's centre among those the
   * pointer overlaps (|p - c| <= radius + r; least |p - c| - radius, the lower index on a tie). The grid and the
   * hierarchy find it through a tree over the sphere centres that keeps each node's largest radius, best first,
   * so a query reads a few spheres even where thousands overlap (d = 0); spheresHit then counts the overlapping
   * spheres it read. The flat level tests every sphere.
   */
  void query(const Vec3& p, double r, DetectionMode mode, ContactResult& out,
             QueryCache* cache = nullptr) const noexcept;

  /**
   * \brief The fast level alone, as the configured descent runs it for the precise modes: how many
   * spheres it reports for the pointer (grid: the spheres cached for p's cell, none when the cell's
   * index entry proves no contact; hierarchy: spheres
   * whose bound meets the pointer; flat: every sphere the pointer overlaps). For timing the two
   * levels apart; allocates nothing.
   */
  std::uint32_t fastLevelHits(const Vec3& p, double r) const noexcept;

  /** \brief Indices of the spheres the pointer overlaps (for display; allocates into out). */
  void hitSpheres(const Vec3& p, double r, std::vector<std::uint32_t>& out) const;

  /** \brief The mesh. */
  const std::shared_ptr<const TriangleMesh>& mesh() const { return mesh_; }
  /** \brief The grid level's box tree over the mesh (shared with the mesh and its swept queries); null otherwise. */
  const std::shared_ptr<const MeshBoxTree>& meshTree() const { return meshTree_; }
  /** \brief The sphere set. */
  const std::shared_ptr<const ClodSphereSet>& spheres() const { return spheres_; }
  /** \brief The fast-level strategy in use. */
  FastLevel fastLevel() const { return fastLevel_; }
  /**
   * \brief How far the level's spheres reach (in the mesh's local frame, measured once at construction, off the
   * haptic path): the largest |centre - c| + radius over the spheres, c the centre of the mesh's bounds, and the
   * largest distance from the bounds to a sphere's centre plus its radius. What spheres mode needs beyond the
   * mesh's own bounds (SceneDetector's rejection tests).
   */
  double spheresReachFromBoundsCentre() const noexcept { return reachFromCentre_; }
  double spheresReachBeyondBounds() const noexcept { return reachBeyondBox_; }
  /**
   * \brief Bytes of the arrays this detector keeps (its grid, trees, records and sphere data), without the mesh and
   * the sphere set it shares.
   */
  std::size_t bytes() const noexcept;
  /** \brief The largest pointer radius the grid serves (0 without a grid): larger radii take the tree over the mesh. */
  double gridRadius() const noexcept { return grid_.empty() ? 0.0 : grid_.radius(); }
  /** \brief The grid of FastLevel::Grid (empty otherwise), for queries that walk its cells (SweptSphereQuery). */
  const CellGrid& grid() const noexcept { return grid_; }
  /**
   * \brief A number unique to this detector within the process (a counter stamped at construction,
   * never reused, never 0): the identity a QueryCache keeps across level swaps.
   */
  std::uint64_t id() const { return id_; }

 private:
  struct Best;
  struct NearFill;
  template <class Visit>
  void forEachHitSphere(double px, double py, double pz, const double& reach, bool tight, Visit&& visit) const;
  void preciseFlat(std::uint32_t sphere, const Vec3& p, DetectionMode mode, Best& best) const;
  void preciseTree(std::uint32_t sphere, const Vec3& p, DetectionMode mode, Best& best) const;
  void testTriangle(std::uint32_t tri, std::uint32_t sphere, const Vec3& p, DetectionMode mode, Best& best) const;
  // fill: also hands every computed squared distance to a neighbourhood being filled (see QueryCache).
  void testGridTriangle(std::uint32_t tri, const Vec3& p, DetectionMode mode, Best& best,
                        NearFill* fill = nullptr) const;
  // testGridTriangle on count (1..batchSize(mode)) triangles: four at a time in AVX2 for the exact mode.
  void testGridBatch(const std::uint32_t* triangles, unsigned count, const Vec3& p, DetectionMode mode, Best& best,
                     NearFill* fill = nullptr) const;
  unsigned batchSize(DetectionMode mode) const;  // 4 for the exact mode where the CPU runs AVX2, else 1
  // The stream's last contact triangle when the cache is this detector's and holds one, else UINT32_MAX.
  std::uint32_t lastContact(const QueryCache* cache) const;
  void preciseGrid(const Vec3& p, DetectionMode mode, Best& best, QueryCache* cache) const;
  // The grid's scan of one cell for p (rel: p from the cell's centre). Fill is NearFill (every triangle within its
  // reach is handed to it as well) or std::nullptr_t (a plain query). skip: a triangle already tested for p, passed
  // over (UINT32_MAX: none).
  template <class Fill>
  void scanCell(const CellGrid::Cell& cell, const Vec3& rel, const Vec3& p, DetectionMode mode, Best& best, Fill* fill,
                std::uint32_t skip) const;
  // The answer for p from the stream's neighbourhood (QueryCache::nearTriangle), s = |p - anchor|.
  void preciseNear(const Vec3& p, double s, DetectionMode mode, Best& best, const QueryCache& cache) const;
  // The nearest triangle within best's reach through the tree over the mesh; skip: a triangle already tested for p,
  // passed over (UINT32_MAX: none).
  void preciseMeshTree(const Vec3& p, DetectionMode mode, Best& best, std::uint32_t skip) const;
  // The stages of query(): the spheres mode; the nearest triangle within radius; the growing search of a deep
  // centre; the answer from the search's result.
  void querySpheres(const Vec3& p, double r, ContactResult& out, QueryCache* cache) const;
  template <class Visit>
  void nearestSphereSurface(const Vec3& p, double r, const double& bestGap, Visit&& visit) const;
  void search(const Vec3& p, double radius, DetectionMode mode, Best& best, QueryCache* cache) const;
  void searchDeep(const Vec3& p, double r, DetectionMode mode, Best& best, QueryCache* cache) const;
  // searchDeep's shortcut: the nearest triangle from the grid cell of p, when the best so far (found) lies within what
  // the cell lists, or a scan bounded to that reach finds one; false (best as it was) otherwise. skip: a triangle
  // already tested for p.
  bool deepFromCell(const Vec3& p, DetectionMode mode, Best& best, const QueryCache* cache, std::uint32_t skip) const;
  void answer(const Vec3& p, double r, const Best& best, ContactResult& out, QueryCache* cache) const;

  std::shared_ptr<const TriangleMesh> mesh_;
  std::shared_ptr<const ClodSphereSet> spheres_;
  FastLevel fastLevel_;
  std::uint64_t id_;
  double pad_ = 0.0;  // conservative padding relative to the model's coordinates

  // The spheres, flat for the cache: x, y, z, radius + pad.
  std::vector<double> sphereData_;
  // Per triangle, one record of 13 doubles (two cache lines): a ball around it (centroid and padded
  // radius reaching its vertices) for a cheap reject, then its three corners. Empty for the grid level.
  std::vector<double> triangles_;
  // Hierarchy and grid: the trees over the spheres (ball, tight, gap; SphereTrees). Hierarchy only: one tree per
  // sphere over its triangles.
  SphereTrees trees_;
  std::vector<BoxNode> triangleNodes_;
  std::vector<std::uint32_t> triangleOrder_;  // triangle indices in per-sphere leaf order
  std::vector<std::uint32_t> triangleRoot_;   // per sphere: root in triangleNodes_
  // Grid: the fast level per cell, and the first sphere listing each triangle.
  CellGrid grid_;
  std::vector<std::uint32_t> sphereOfTriangle_;
  // Grid: one tree over all the triangles, for pointers beyond the grid's radius and the deep search (the mesh's
  // own when it brings one that fits, see meshBoxTreeOf).
  std::shared_ptr<const MeshBoxTree> meshTree_;
  // The same four children to a node (WideBoxTree, internal to the core), walked four nodes a test in AVX2 where the
  // CPU runs it; built only for a grid with a crowded cell (kTreeAboveEntries), null otherwise and without AVX2.
  std::shared_ptr<const WideBoxTree> meshWide_;
  const Triangle* triangleIndex_ = nullptr;  // the mesh's arrays (kept alive by mesh_)
  const Vec3* vertices_ = nullptr;
  const Vec3* normals_ = nullptr;
  Vec3 origin_ = Vec3::Zero();                           // the mesh's local origin: p - origin_ in, point + origin_ out
  double reachFromCentre_ = 0.0, reachBeyondBox_ = 0.0;  // see spheresReachFromBoundsCentre()
};

}  // namespace clod_haptics
