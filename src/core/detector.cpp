#include "clod_haptics/core/detector.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <new>
#include <string>
#include <type_traits>

#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/geometry.h"
#include "clod_haptics/core/mesh_box_tree.h"
#include "enum_names.h"
#include "float_rounding.h"
#include "simd/cell_scan_avx2.h"
#include "simd/closest_point_avx2.h"
#include "simd/dispatch.h"
#include "vector_bytes.h"
#include "wide_box_tree.h"

namespace clod_haptics {

namespace {
const detail::EnumNames<FastLevel, 3> kFastLevelNames = {
    {FastLevel::Grid, "grid"}, {FastLevel::Hierarchy, "hierarchy"}, {FastLevel::Flat, "flat"}};
}  // namespace

bool parseFastLevel(const char* text, FastLevel& level) { return detail::parseName(text, kFastLevelNames, level); }

const char* toString(FastLevel level) { return detail::nameOf(level, kFastLevelNames); }

// The search state of one query: the current search radius shrinks as closer triangles are found.
struct ClodDetector::Best {
  double d2;     // squared search radius: r^2 until a contact, then the best squared distance
  double reach;  // sqrt(d2), for sphere pruning
  bool found = false;
  bool deep = false;  // searched beyond r for a stream that was inside (searchDeep)
  std::uint32_t triangle = 0;
  std::uint32_t sphere = 0;
  Vec3 point = Vec3::Zero();
  TriangleRegion region;     // the feature of `triangle` that `point` lies on (exact mode)
  bool regionKnown = false;  // region holds closestPointOnTriangle's answer (not so in paper mode)
  std::uint32_t tested = 0;
  std::uint32_t hits = 0;

  /**
   * Keeps triangle tri (closest point q on feature `feature`, or null when unknown; squared distance d2, through
   * sphere) when it is nearer than the best so far, or as near with a lower index: the tie rule of
   * bruteForceQuery. Returns whether it did.
   */
  bool offer(double dist2, std::uint32_t tri, std::uint32_t viaSphere, const Vec3& q, const TriangleRegion* feature) {
    if (!(dist2 < d2 || (dist2 == d2 && (!found || tri < triangle)))) return false;
    d2 = dist2;
    reach = std::sqrt(dist2);
    found = true;
    triangle = tri;
    sphere = viaSphere;
    point = q;
    regionKnown = feature != nullptr;
    if (regionKnown) region = *feature;
    return true;
  }
};

/**
 * A stream's neighbourhood being filled (QueryCache::nearTriangle) at a centre a, for a margin m: every triangle that
 * can be the answer of a query within m of a, nearest first. Such an answer lies within r of the query, and (when a
 * has a nearest triangle at d0) within d0 + m of it, so within min(r + m, d0 + 2 m) of a: reach (plus slack, the
 * rounding), which shrinks while the scan finds nearer triangles, and to the farthest kept one once
 * QueryCache::kNear are kept (the margin then shrinks to what that reach covers). Every triangle left out lies
 * farther than reach.
 */
struct ClodDetector::NearFill {
  NearFill(QueryCache& into, double radius, double m, double roundSlack)
      : cache(into), r(radius), margin(m), slack(roundSlack), reach(radius + m + roundSlack) {}
  QueryCache& cache;
  double r, margin, slack;
  double reach;  // for the scan's bounds
  std::uint32_t count = 0;
  double d2[QueryCache::kNear];

  void follow(double bestDistance) {
    reach = std::min(reach, std::min(r + margin, bestDistance + 2.0 * margin) + slack);
  }
  void keep(std::uint32_t tri, double dist2) {
    if (!(dist2 <= reach * reach)) return;
    if (count == QueryCache::kNear && !(dist2 < d2[count - 1])) return;
    std::uint32_t i = count;
    while (i > 0 && d2[i - 1] > dist2) --i;
    // Met twice (the last contact, tested first, comes again in the scan): the same distance, just before.
    for (std::uint32_t j = i; j > 0 && d2[j - 1] == dist2; --j)
      if (cache.nearTriangle[j - 1] == tri) return;
    if (count == QueryCache::kNear) --count;  // the farthest kept makes room
    for (std::uint32_t j = count++; j > i; --j) {
      d2[j] = d2[j - 1];
      cache.nearTriangle[j] = cache.nearTriangle[j - 1];
    }
    d2[i] = dist2;
    cache.nearTriangle[i] = tri;
    if (count == QueryCache::kNear) reach = std::min(reach, std::sqrt(d2[count - 1]));
  }
  /** The margin the neighbourhood holds for, the nearest distance at its centre being d0 (infinite: none). */
  double held(double d0) const {
    const double covered = reach - 2.0 * slack;
    return std::min(margin, std::max(covered - r, 0.5 * (covered - d0)));
  }
};

namespace {
// The closest point of p on triangle (a, b, c) as the mode defines it, and its feature when the mode computes
// one (exact: closestPointOnTriangle; paper: the projection inside the triangle, or nothing). Returns false when
// the triangle has no such point.
inline bool closestFor(DetectionMode mode, const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c,
                       const Vec3& normal, Vec3& q, TriangleRegion*& region) {
  if (mode == DetectionMode::Exact) {
    q = closestPointOnTriangle(p, a, b, c, region);
    return true;
  }
  region = nullptr;
  return projectInsideTriangle(p, a, b, c, normal, q);
}
}  // namespace

namespace {
constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();

constexpr std::size_t kRecord = 13;  // doubles per triangle record: ball (4), corners (9)

// The four-wide tree's lanes end at subtrees of at most this many triangles (WideBoxTree): the binary walk's leaves.
constexpr std::uint32_t kWideTreeLeaves = kMeshBoxTreeLeafSize;

// Above this many triangles the grid scan tests its candidates a group behind, their lines prefetched (TriangleBatch):
// in-contact probes in random order, interleaved runs, median of 6: refined_elephant (88,928) mean -12 to -21%, p99
// -21 to -26%; mannequin-devil (25,888) -8% and -12%; head (2,918, in the caches) +16% and +12%, so not there.
constexpr std::size_t kLookaheadAbove = 16384;

// Gathers triangles for a batch test, capacity (1 to 4) at a time: flush(triangles, count), count in 1..capacity.
// After lookAhead(), a group is tested only once the next group is full (or at the end): each triangle's index entry
// is prefetched as it is added, and the next group's corners before a group is tested, so a query whose triangles are
// out of the caches waits for their lines together rather than group by group. Where they are in the caches (a small
// mesh) that only delays the narrowing of the scan's bounds: see kLookaheadAbove.
template <class Flush>
class TriangleBatch {
 public:
  TriangleBatch(unsigned capacity, Flush flush) : capacity_(capacity), flush_(flush) {}
  /** Tests a group behind, prefetching from the mesh's index and vertices (see above). */
  void lookAhead(const Triangle* index, const Vec3* vertices) {
    index_ = index;
    vertices_ = vertices;
  }
  void add(std::uint32_t triangle) {
    if (index_ != nullptr) __builtin_prefetch(index_ + triangle);
    held_[count_++] = triangle;
    if (count_ == (index_ != nullptr ? 2 * capacity_ : capacity_)) flushFirst();
  }
  void finish() {
    while (count_ > capacity_) flushFirst();
    if (count_ > 0) flush_(held_, count_);
    count_ = 0;
  }

 private:
  void flushFirst() {
    for (unsigned k = capacity_; k < count_; ++k) {  // the next group, held only when looking ahead
      const Triangle& t = index_[held_[k]];
      for (int j = 0; j < 3; ++j) __builtin_prefetch(vertices_ + t[j]);
    }
    const unsigned n = std::min(capacity_, count_);
    flush_(held_, n);
    for (unsigned k = n; k < count_; ++k) held_[k - n] = held_[k];
    count_ -= n;
  }
  unsigned capacity_;
  Flush flush_;
  const Triangle* index_ = nullptr;
  const Vec3* vertices_ = nullptr;
  std::uint32_t held_[8];
  unsigned count_ = 0;
};

// Detector ids: 64 bits counted from 1 do not wrap in the life of a process.
std::uint64_t nextDetectorId() {
  static std::atomic<std::uint64_t> counter{0};
  return counter.fetch_add(1, std::memory_order_relaxed) + 1;
}

/**
 * Nearest child first through a box tree from root, calling leaf(item) for every item of each leaf whose box lies
 * within sqrt(d2) of p (and its slab, when slabs are given per node); d2 may shrink during the walk (a closer
 * triangle found), which prunes the rest.
 */
template <class Leaf>
inline void walkBoxTree(const BoxNode* nodes, std::uint32_t root, const std::uint32_t* order, const Vec3& p,
                        const double& d2, Leaf&& leaf, const NodeSlab* slabs = nullptr) {
  std::uint32_t stack[64];
  int top = 0;
  stack[top++] = root;
  while (top > 0) {
    const std::uint32_t at = stack[--top];
    const BoxNode& node = nodes[at];
    if (squaredDistanceToNode(node, p.x(), p.y(), p.z()) > d2) continue;
    if (slabs != nullptr && slabSquaredDistance(slabs[at], p) > d2) continue;
    if (node.count > 0) {
      for (std::uint32_t i = node.first; i < node.first + node.count; ++i) leaf(order[i]);
      continue;
    }
    const std::uint32_t left = static_cast<std::uint32_t>(&node - nodes) + 1, right = node.first;
    prefetchChildren(nodes, slabs, left, right);  // each slab is read when its child is popped
    const double dl = squaredDistanceToNode(nodes[left], p.x(), p.y(), p.z());
    const double dr = squaredDistanceToNode(nodes[right], p.x(), p.y(), p.z());
    // Nearer child last on the stack, so it is searched first and shrinks the radius sooner.
    if (dl <= dr) {
      if (dr <= d2) stack[top++] = right;
      if (dl <= d2) stack[top++] = left;
    } else {
      if (dl <= d2) stack[top++] = left;
      if (dr <= d2) stack[top++] = right;
    }
  }
}

/** Per triangle, a ball around it (centroid, radius reaching its vertices plus pad), then its three corners. */
std::vector<double> triangleRecords(const TriangleMesh& m, double pad) {
  std::vector<double> records(kRecord * m.size());
  for (std::size_t t = 0; t < m.size(); ++t) {
    double* record = records.data() + kRecord * t;
    const Vec3 c = m.centroid(t);
    double r2 = 0.0;
    for (int v = 0; v < 3; ++v) r2 = std::max(r2, (m.vertex(t, v) - c).squaredNorm());
    for (int k = 0; k < 3; ++k) record[k] = c[k];
    record[3] = std::sqrt(r2) + pad;
    for (int v = 0; v < 3; ++v)
      for (int k = 0; k < 3; ++k) record[4 + 3 * v + k] = m.vertex(t, v)[k];
  }
  return records;
}

/** The spheres as (x, y, z, radius + pad). */
std::vector<double> paddedSpheres(const ClodSphereSet& s, double pad) {
  std::vector<double> data(4 * s.size());
  for (std::size_t i = 0; i < s.size(); ++i) {
    for (int k = 0; k < 3; ++k) data[4 * i + k] = s.centres[i][k];
    data[4 * i + 3] = s.radii[i] + pad;
  }
  return data;
}

/**
 * One box tree per sphere over the triangles it lists, all in nodes; order lists triangle ids in leaf order
 * and root[i] is sphere i's root (kNone for an empty list).
 */
void buildTriangleTrees(const TriangleMesh& m, const ClodSphereSet& s, double pad, std::vector<BoxNode>& nodes,
                        std::vector<std::uint32_t>& order, std::vector<std::uint32_t>& root) {
  root.assign(s.size(), kNone);
  order.reserve(s.triangles.size());
  std::vector<Eigen::AlignedBox3d> boxes;
  std::vector<std::uint32_t> localOrder;
  for (std::size_t i = 0; i < s.size(); ++i) {
    boxes.clear();
    for (const std::uint32_t* t = s.begin(i); t != s.end(i); ++t) {
      Eigen::AlignedBox3d b;
      b.setEmpty();
      for (int v = 0; v < 3; ++v) b.extend(m.vertex(*t, v));
      boxes.push_back(b);
    }
    localOrder.clear();
    root[i] = buildBoxTree(boxes, 4, pad, nodes, localOrder);
    // Leaves index localOrder from 0; shift them into order and map to triangle ids.
    const auto base = static_cast<std::uint32_t>(order.size());
    for (std::uint32_t local : localOrder) order.push_back(s.begin(i)[local]);
    if (root[i] == kNone) continue;
    for (std::size_t n = root[i]; n < nodes.size(); ++n)
      if (nodes[n].count > 0) nodes[n].first += base;
  }
}
}  // namespace

namespace {
// The grid of a Grid detector, built by the detector or for the disk cache (buildGridParts): one set of parameters.
// sameMesh: another level's grid of the mesh, reused when its cells are the ones this build would choose.
CellGrid detectorGrid(const TriangleMesh& mesh, const ClodSphereSet& spheres, double radius, const SphereTrees& trees,
                      const CellGrid* sameMesh = nullptr, bool* reused = nullptr) {
  const double bytes = ClodDetector::gridBytesPerTriangle(mesh, spheres, trees);
  if (sameMesh)
    return CellGrid::forLevel(*sameMesh, mesh, spheres, radius, 24.0, CellGrid::Index::Auto, 1e6, bytes, reused);
  return CellGrid(mesh, spheres, radius, 24.0, CellGrid::Index::Auto, 1e6, bytes);
}
}  // namespace

ClodDetector::ClodDetector(std::shared_ptr<const TriangleMesh> mesh, std::shared_ptr<const ClodSphereSet> spheres,
                           FastLevel fastLevel, double gridRadius, const GridSource& gridSource)
    : mesh_(std::move(mesh)), spheres_(std::move(spheres)), fastLevel_(fastLevel), id_(nextDetectorId()) {
  const TriangleMesh& m = *mesh_;
  const ClodSphereSet& s = *spheres_;
  // A level built for another mesh would send the lists past the mesh's arrays: refuse it, typed.
  const std::string misfit = fitProblem(m, s);
  if (!misfit.empty())
    throw SphereSetMismatch("ClodDetector: the sphere set does not fit mesh '" + m.name + "': " + misfit);
  const Eigen::AlignedBox3d bounds = m.bounds();
  // Padding relative to the coordinates' magnitude: covers rounding in every bound test. The mesh's box tree is
  // padded alike, so the tree shared with the mesh is the one this detector would build.
  pad_ = meshBoxTreePad(bounds);
  for (std::size_t i = 0; i < s.size(); ++i) {
    reachFromCentre_ = std::max(reachFromCentre_, (s.centres[i] - bounds.center()).norm() + s.radii[i]);
    reachBeyondBox_ = std::max(reachBeyondBox_, bounds.exteriorDistance(s.centres[i]) + s.radii[i]);
  }

  // Records for the hierarchy and the flat list; the grid reads the mesh's own arrays instead (compact, so they
  // stay in cache), also in its tree over the mesh.
  if (fastLevel_ != FastLevel::Grid) triangles_ = triangleRecords(m, pad_);
  sphereData_ = paddedSpheres(s, pad_);
  sphereOfTriangle_ = firstSphereOfTriangles(s, m.size());
  triangleIndex_ = m.triangles.data();
  vertices_ = m.vertices.data();
  origin_ = m.origin;
  normals_ = m.normals.data();

  // A Grid detector with a source takes its trees from the source with the grid (a disk cache keeps both).
  const double radius = fastLevel_ == FastLevel::Grid ? effectiveGridRadius(bounds, gridRadius) : 0.0;
  const bool fromSource = radius > 0.0 && gridSource;
  if (fastLevel_ != FastLevel::Flat) {
    if (!fromSource) trees_ = buildSphereTrees(m, s, pad_);
    // The hierarchy searches each hit sphere's own triangles; the grid, beyond its radius and for the deep search,
    // all the triangles at once.
    if (fastLevel_ == FastLevel::Hierarchy)
      buildTriangleTrees(m, s, pad_, triangleNodes_, triangleOrder_, triangleRoot_);
    else {
      meshTree_ = meshBoxTreeOf(m, pad_);  // with its slabs
    }
  }
  // The grid last: its construction peak then meets only the trees kept, not their build's temporaries.
  if (fastLevel_ == FastLevel::Grid) {
    if (radius > 0.0) {
      if (fromSource) {
        GridParts parts = gridSource(radius);
        grid_ = std::move(parts.grid);
        trees_ = std::move(parts.trees);
        // The walks index the set with what the trees order: trees of another level would read past its arrays.
        const std::size_t n = s.size();
        if (trees_.ballOrder.size() != n || trees_.tightOrder.size() != n || trees_.gapOrder.size() != n ||
            trees_.gapRadius.size() != trees_.gapNodes.size())
          throw InvalidParameter("ClodDetector: the grid source gave trees over " +
                                 std::to_string(trees_.ballOrder.size()) + " spheres, expected " + std::to_string(n));
      } else {
        grid_ = detectorGrid(m, s, radius, trees_);
      }
      if (grid_.radius() != radius)
        throw InvalidParameter("ClodDetector: the grid source gave a grid of radius " + std::to_string(grid_.radius()) +
                               ", expected " + std::to_string(radius));
    }
#if defined(CLOD_PACKET_AVX2)
    // The four-wide tree where crowded cells send every query in them through the tree (triangles far smaller than
    // the radius); elsewhere the walk is rare (pointers beyond the radius, the deep search) and its bytes not spent.
    if (meshTree_ && grid_.largestCell() > kTreeAboveEntries)
      meshWide_ = WideBoxTree::build(*meshTree_, kWideTreeLeaves);
#endif
  }
}

ClodDetector::GridParts ClodDetector::buildGridParts(const TriangleMesh& mesh, const ClodSphereSet& spheres,
                                                     double radius, const CellGrid* sameMesh, bool* reused) {
  GridParts parts;
  parts.trees = buildSphereTrees(mesh, spheres, meshBoxTreePad(mesh));
  parts.grid = detectorGrid(mesh, spheres, radius, parts.trees, sameMesh, reused);  // last: its peak meets the trees
  return parts;
}

double ClodDetector::gridBytesPerTriangle(const TriangleMesh& mesh, const ClodSphereSet& spheres,
                                          const SphereTrees& trees) {
  const double n = static_cast<double>(std::max<std::size_t>(1, mesh.size()));
  // By sizes, not capacities: what the trees hold, whatever their vectors reserved.
  auto nodes = [](std::size_t count) { return static_cast<double>(count * sizeof(BoxNode)); };
  const double treeBytes =
      nodes(trees.ballNodes.size()) + nodes(trees.tightNodes.size()) + nodes(trees.gapNodes.size()) +
      4.0 * static_cast<double>(trees.ballOrder.size()) + 4.0 * static_cast<double>(trees.tightOrder.size()) +
      4.0 * static_cast<double>(trees.gapOrder.size()) + 4.0 * static_cast<double>(trees.gapRadius.size());
  // The mesh's box tree (nodes, their slabs, the order) and the per-sphere (padded sphere) and per-triangle (first
  // sphere) arrays.
  const double meshTree = static_cast<double>(
      boxTreeNodeCount(mesh.size(), kMeshBoxTreeLeafSize) * (sizeof(BoxNode) + sizeof(NodeSlab)) + 4 * mesh.size());
  const double arrays = 32.0 * static_cast<double>(spheres.size()) + 4.0 * static_cast<double>(mesh.size());
  const double other = static_cast<double>(sizeof(ClodDetector)) + treeBytes + meshTree + arrays;
  // Aimed 5% under the target: the grid's size is estimated before its build, and the arrays' capacities may exceed
  // their sizes.
  return std::max(kMinGridBytesPerTriangle, 0.95 * kBytesPerTriangle - other / n);
}

double ClodDetector::effectiveGridRadius(const TriangleMesh& mesh, double gridRadius) {
  return gridRadius > 0.0 && std::isfinite(gridRadius) ? gridRadius : effectiveGridRadius(mesh.bounds(), gridRadius);
}

double ClodDetector::effectiveGridRadius(const Eigen::AlignedBox3d& bounds, double gridRadius) {
  return gridRadius > 0.0 && std::isfinite(gridRadius) ? gridRadius : 0.01 * bounds.diagonal().norm();
}

std::size_t ClodDetector::bytes() const noexcept {
  using detail::bytesOf;
  return sizeof(*this) + grid_.bytes() + bytesOf(sphereData_) + bytesOf(triangles_) + trees_.bytes() +
         bytesOf(triangleNodes_) + bytesOf(triangleOrder_) + bytesOf(triangleRoot_) + bytesOf(sphereOfTriangle_) +
         (meshTree_ ? bytesOf(meshTree_->nodes) + bytesOf(meshTree_->order) + bytesOf(meshTree_->slabs) : 0) +
         (meshWide_ ? meshWide_->bytes() : 0);
}

inline void ClodDetector::testTriangle(std::uint32_t tri, std::uint32_t sphere, const Vec3& p, DetectionMode mode,
                                       Best& best) const {
  ++best.tested;
  Vec3 a, b, cc;
  if (!triangles_.empty()) {
    // A ball around the triangle rejects it cheaply when it cannot beat the current best.
    const double* ball = triangles_.data() + kRecord * tri;
    const double bx = p.x() - ball[0], by = p.y() - ball[1], bz = p.z() - ball[2], reach = ball[3] + best.reach;
    if (bx * bx + by * by + bz * bz > reach * reach) return;
    const double* c = ball + 4;
    a = Vec3(c[0], c[1], c[2]);
    b = Vec3(c[3], c[4], c[5]);
    cc = Vec3(c[6], c[7], c[8]);
  } else {  // the grid level keeps no records
    const Triangle& t = triangleIndex_[tri];
    a = vertices_[t[0]];
    b = vertices_[t[1]];
    cc = vertices_[t[2]];
  }
  Vec3 q;
  TriangleRegion feature, *region = &feature;
  if (!closestFor(mode, p, a, b, cc, mesh_->normals[tri], q, region)) return;
  best.offer((p - q).squaredNorm(), tri, sphere, q, region);
}

void ClodDetector::preciseFlat(std::uint32_t sphere, const Vec3& p, DetectionMode mode, Best& best) const {
  const ClodSphereSet& s = *spheres_;
  for (const std::uint32_t* t = s.begin(sphere); t != s.end(sphere); ++t) testTriangle(*t, sphere, p, mode, best);
}

void ClodDetector::preciseTree(std::uint32_t sphere, const Vec3& p, DetectionMode mode, Best& best) const {
  const std::uint32_t root = triangleRoot_[sphere];
  if (root == kNone) return;
  walkBoxTree(triangleNodes_.data(), root, triangleOrder_.data(), p, best.d2,
              [&](std::uint32_t t) { testTriangle(t, sphere, p, mode, best); });
}

void ClodDetector::preciseMeshTree(const Vec3& p, DetectionMode mode, Best& best, std::uint32_t skip) const {
  TriangleBatch batch(batchSize(mode),
                      [&](const std::uint32_t* t, unsigned count) { testGridBatch(t, count, p, mode, best); });
#if defined(CLOD_PACKET_AVX2)
  if (meshWide_ && detail::packetAvx2()) {
    // walkBoxTree four nodes a test (nodeNearAvx2: the same box and slab distances, nearest first).
    const double q[3] = {p.x(), p.y(), p.z()};
    const std::uint32_t* order = meshTree_->order.data();
    meshWide_->walk([&] { return best.d2; },
                    [&](const WideBoxTree::Node& node, double* key) {
                      return detail::nodeNearAvx2(node.lanes, node.count, q, best.d2, key);
                    },
                    [&](std::uint32_t first, std::uint32_t few) {
                      for (std::uint32_t i = first; i < first + few; ++i)
                        if (order[i] != skip) batch.add(order[i]);
                    });
    batch.finish();
    return;
  }
#endif
  walkBoxTree(
      meshTree_->nodes.data(), 0, meshTree_->order.data(), p, best.d2,
      [&](std::uint32_t t) {
        if (t != skip) batch.add(t);
      },
      meshTree_->slabs.data());
  batch.finish();
}

// The grid's precise test reads the triangle from the mesh's own arrays (indices, vertices: compact,
// so they stay in cache) rather than from the per-triangle records the other fast levels use.
inline void ClodDetector::testGridTriangle(std::uint32_t tri, const Vec3& p, DetectionMode mode, Best& best,
                                           NearFill* fill) const {
  ++best.tested;
  const Triangle& t = triangleIndex_[tri];
  const Vec3* v = vertices_;
  Vec3 q;
  TriangleRegion feature, *region = &feature;
  if (!closestFor(mode, p, v[t[0]], v[t[1]], v[t[2]], normals_[tri], q, region)) return;
  const double d2 = (p - q).squaredNorm();
  if (fill != nullptr) fill->keep(tri, d2);
  if (best.offer(d2, tri, kNone, q, region)) {
    // The answer reads them last: start their loads while the scan goes on.
    __builtin_prefetch(normals_ + tri);
    __builtin_prefetch(sphereOfTriangle_.data() + tri);
  }
}

unsigned ClodDetector::batchSize(DetectionMode mode) const {
#if defined(CLOD_PACKET_AVX2)
  return mode == DetectionMode::Exact && detail::packetAvx2() ? 4 : 1;
#else
  (void)mode;
  return 1;
#endif
}

// Four exact tests at once, branch-free (the scalar test's seven regions mispredict on most candidates), with the
// same values bit for bit (closest_point_avx2.h); a lane that needs the zero-area fallback goes to the scalar test.
// A batch of one (the only kind where batchSize(mode) is 1: paper mode, or no AVX2) is tested by testGridTriangle.
void ClodDetector::testGridBatch(const std::uint32_t* triangles, unsigned count, const Vec3& p, DetectionMode mode,
                                 Best& best, NearFill* fill) const {
#if defined(CLOD_PACKET_AVX2)
  if (count > 1) {  // only where batchSize(mode) is 4: the exact mode with AVX2
    const Vec3 *a[4], *b[4], *c[4];
    for (unsigned k = 0; k < 4; ++k) {
      const Triangle& t = triangleIndex_[triangles[std::min(k, count - 1)]];
      a[k] = vertices_ + t[0];
      b[k] = vertices_ + t[1];
      c[k] = vertices_ + t[2];
    }
    detail::ClosestPoints4 q;
    const unsigned computed = detail::closestPointsAvx2(p, a, b, c, q);
    for (unsigned k = 0; k < count; ++k) {
      if (!(computed & (1u << k))) {
        testGridTriangle(triangles[k], p, mode, best, fill);
        continue;
      }
      ++best.tested;
      if (fill != nullptr) fill->keep(triangles[k], q.d2[k]);
      if (!(q.d2[k] <= best.d2)) continue;  // farther than the best: offer would refuse it
      const TriangleRegion region = q.region(k);
      if (best.offer(q.d2[k], triangles[k], kNone, Vec3(q.q[0][k], q.q[1][k], q.q[2][k]), &region)) {
        __builtin_prefetch(normals_ + triangles[k]);
        __builtin_prefetch(sphereOfTriangle_.data() + triangles[k]);
      }
    }
    return;
  }
#endif
  for (unsigned k = 0; k < count; ++k) testGridTriangle(triangles[k], p, mode, best, fill);
}

namespace {
/**
 * An optional T whose storage stays uninitialised until emplace: std::optional's default constructor
 * value-initialises its payload, which for the 440-byte NearFill was a memset on every scan of a cell.
 */
template <class T>
class Deferred {
  static_assert(std::is_trivially_destructible<T>::value, "nothing to destroy: the storage is simply dropped");

 public:
  Deferred() {}  // user-provided: the storage is left as it is
  Deferred(const Deferred&) = delete;
  Deferred& operator=(const Deferred&) = delete;
  template <class... Args>
  T& emplace(Args&&... args) {
    engaged_ = true;
    return *new (storage_) T(std::forward<Args>(args)...);
  }
  explicit operator bool() const { return engaged_; }
  T& operator*() { return *std::launder(reinterpret_cast<T*>(storage_)); }
  T* operator->() { return &**this; }

 private:
  alignas(T) unsigned char storage_[sizeof(T)];
  bool engaged_ = false;
};

// A stream slower than this (per query, in radii) fills a neighbourhood; the margin it is filled for is this many
// of its steps, between the two bounds (in radii): a neighbourhood then serves up to 16 queries at a steady pace.
// A larger margin (32 steps, up to r/2) made each fill dearer than the queries it served saved; 8 was no better.
constexpr double kNearStep = 1.0 / 16.0, kNearSteps = 16.0, kNearMarginMin = 1.0 / 32.0, kNearMarginMax = 0.25;

// The last contact is tested first only after a step of at most this many radii. Chosen on the bench's coherent paths
// (refined_elephant, elephant, mannequin-devil, head; offsets within 0.9 r, so no deep points; cached and stateless
// queries interleaved point by point): at 2 m/s (2.6 r a step) testing it made the cached query 6 to 15% slower than
// the stateless one, skipping it 0 to 2%; at 0.1 m/s (0.13 r) the cache stays 5 to 8% faster either way; at 0.5 m/s
// (0.67 r) a threshold of 0.5 or 1 r made no difference beyond the noise.
constexpr double kLastContactStep = 1.0;

// What the neighbourhood's bounds allow for the rounding of the distances it keeps and of |p - anchor|: far above
// either (relative 1e-16 of the radius and of the local coordinates), far below any margin.
inline double nearSlack(double r, const Vec3& p) { return 1e-9 * r + 1e-12 * p.cwiseAbs().maxCoeff(); }
}  // namespace

template <class Fill>
inline __attribute__((always_inline)) void ClodDetector::scanCell(const CellGrid::Cell& cell, const Vec3& rel,
                                                                  const Vec3& p, DetectionMode mode, Best& best,
                                                                  Fill* fill, std::uint32_t skip) const {
  const double offset = rel.norm() + pad_;
  const double slack = grid_.slack();
  const double unit = grid_.distanceUnit();
  // The reach the bounds are held to: the best so far, or what the neighbourhood being filled needs (no fill: the
  // scan of a plain query, whose bounds read best.reach as it narrows).
  constexpr bool filling = std::is_same<Fill, NearFill>::value;
  // The stored directions are scaled by 127; scaling rel instead saves a multiplication per entry.
  const double rx = rel.x() * (1.0 / 127.0), ry = rel.y() * (1.0 / 127.0), rz = rel.z() * (1.0 / 127.0);
  const CellGrid::Entry* e = cell.entries;
  // Exact mode with AVX2: the candidates that pass the bounds are tested four at a time (testGridBatch); the bounds
  // are judged against the best as it stood before the batch, so a batch may test a candidate the one-by-one scan
  // would have skipped, never the reverse.
  TriangleBatch batch(batchSize(mode), [&](const std::uint32_t* t, unsigned count) {
    if constexpr (filling) {
      testGridBatch(t, count, p, mode, best, fill);
      fill->follow(best.reach);
    } else {
      testGridBatch(t, count, p, mode, best);
    }
  });
  if (mesh_->size() > kLookaheadAbove) batch.lookAhead(triangleIndex_, vertices_);
  auto reachNow = [&]() -> double {  // as it stands: it narrows during the scan
    if constexpr (filling)
      return fill->reach;
    else
      return best.reach;
  };
  // Entry i's two bounds against the reach as it stands: false when the scan is over (sorted by dc, so the rest is
  // farther), else the entry handed to the batch when it passes.
  auto visit = [&](std::uint32_t i) {
    const double reach = reachNow();
    const double dc = e[i].distance * unit;
    // Triangle inequality: distance(p, T) >= dc - |p - centre|; entries are sorted by dc, so stop.
    if (dc - offset > reach) return false;
    // Supporting plane at the triangle's point nearest the centre: a tighter bound for this p.
    const double bound = dc + rx * e[i].direction[0] + ry * e[i].direction[1] + rz * e[i].direction[2];
    if (bound - slack > reach || e[i].triangle == skip) return true;
    batch.add(e[i].triangle);  // the sphere is looked up once, for the answer
    return true;
  };
  std::uint32_t i = 0;
#if defined(CLOD_PACKET_AVX2)
  // Eight entries at a time through the swept query's float filter (the point as a piece of zero length), which keeps
  // every entry whose plane bound the double test keeps at the reach it was given; the entries it keeps go through
  // visit, against the reach as it stands then.
  if (cell.count >= 8 && detail::packetAvx2()) {
    double boundsReach = -1.0;
    detail::CellScanBounds bounds{};
    for (; i + 8 <= cell.count; i += 8) {
      const double reach = reachNow();
      if (e[i].distance * unit - offset > reach) break;  // the block's nearest entry is out of reach: so is the rest
      if (reach != boundsReach) {
        boundsReach = reach;
        bounds = detail::cellScanBounds(rel, rel, 0.0, 0.0, unit, reach + slack, offset + reach);
      }
      bool more = true;
      for (unsigned m = detail::cellScanBlockAvx2(e + i, bounds); m != 0 && more; m &= m - 1)
        more = visit(i + static_cast<std::uint32_t>(__builtin_ctz(m)));
      if (!more) break;
    }
    if (i + 8 <= cell.count) {
      batch.finish();
      return;
    }
  }
#endif
  for (; i < cell.count && visit(i); ++i) {
  }
  batch.finish();
}

std::uint32_t ClodDetector::lastContact(const QueryCache* cache) const {
  if (cache == nullptr || cache->owner != id_ || cache->lastTriangle < 0 ||
      static_cast<std::size_t>(cache->lastTriangle) >= mesh_->size())
    return kNone;
  return static_cast<std::uint32_t>(cache->lastTriangle);
}

void ClodDetector::preciseGrid(const Vec3& p, DetectionMode mode, Best& best, QueryCache* cache) const {
  const std::uint64_t key = grid_.keyOf(p);
  const double r = best.reach;  // the search radius (search() sets it)
  // The stream's squared step since its last query (infinite for another detector's cache), for the neighbourhood.
  double step2 = std::numeric_limits<double>::infinity();
  if (cache != nullptr) {
    if (cache->owner == id_) step2 = (p - cache->lastPoint).squaredNorm();
    cache->lastPoint = p;
    // In the neighbourhood of the last fill: the triangles it lists are all this query needs.
    if (cache->owner == id_ && cache->nearKey == key && cache->nearMargin >= 0.0 && cache->nearRadius == r &&
        mode == DetectionMode::Exact && !best.deep) {
      const double s2 = (p - cache->nearAnchor).squaredNorm();
      if (s2 <= cache->nearMargin * cache->nearMargin) {
        ++cache->hits;
        ++cache->nearHits;
        preciseNear(p, std::sqrt(s2), mode, best, *cache);
        return;
      }
    }
  }
  const CellGrid::CellRef* ref;
  if (cache != nullptr && cache->owner == id_ && cache->key == key) {
    ref = static_cast<const CellGrid::CellRef*>(cache->cell);
    ++cache->hits;
  } else {
    ref = grid_.find(key);
  }
  if (cache != nullptr) {
    if (cache->owner != id_) {  // another detector's: its triangles and cells mean nothing here
      cache->lastTriangle = -1;
      cache->nearMargin = -1.0;
    }
    cache->owner = id_;
    cache->key = key;
    cache->cell = ref;
  }
  if (ref == nullptr) return;  // no triangle within the grid radius of this cell: no precise work
  const Vec3 centre = grid_.centreOf(key);
  const Vec3 rel = p - centre;
  // Near but not on the surface: proven from the index entry, the candidates stay unread.
  if (grid_.noContact(*ref, rel, best.reach)) return;
  const CellGrid::Cell cell = grid_.cell(*ref);
  best.hits = cell.spheres;
  const bool crowded = cell.count > kTreeAboveEntries && meshTree_;
  // A slow stream (exact mode, not a crowded cell): this scan also fills the neighbourhood the next queries use.
  Deferred<NearFill> fill;
  if (cache != nullptr && mode == DetectionMode::Exact && !best.deep && !crowded &&
      step2 <= kNearStep * kNearStep * r * r) {
    const double margin = std::clamp(kNearSteps * std::sqrt(step2), kNearMarginMin * r, kNearMarginMax * r);
    // Rounding of the distances and of |p - anchor| (relative to the radius and to the coordinates), kept on the
    // safe side: a triangle the neighbourhood leaves out is farther than it needs by more than it.
    fill.emplace(*cache, r, margin, nearSlack(r, p));
  }
  // Start from the last contact: a close triangle found first lets the sorted scan stop early (and narrows the reach
  // of a fill from the start). Only after a step of at most kLastContactStep radii: beyond it the last contact is
  // seldom within reach any more, and its test (a cold triangle) is all the cache adds to the query.
  // The plain scan then passes that triangle over: a second test would answer the same (in the bench's 0.1 m/s
  // streams it made the cached query 2 to 8% slower than the stateless one). A fill keeps it once either way.
  const std::uint32_t tested = step2 <= kLastContactStep * kLastContactStep * r * r ? lastContact(cache) : kNone;
  if (tested != kNone) {
    testGridTriangle(tested, p, mode, best, fill ? &*fill : nullptr);
    if (fill) fill->follow(best.reach);
  }
  if (fill) {
    scanCell(cell, rel, p, mode, best, &*fill, kNone);
    // What it holds for the answer found: the margin, or less where the reach had to shrink for room.
    fill->follow(best.reach);
    const double held = fill->held(best.found ? best.reach : std::numeric_limits<double>::infinity());
    std::uint32_t count = 0;
    while (count < fill->count && fill->d2[count] <= fill->reach * fill->reach) ++count;
    cache->nearMargin = held > 0.0 ? held : -1.0;
    cache->nearAnchor = p;
    cache->nearKey = key;
    cache->nearRadius = r;
    cache->nearSpheres = cell.spheres;
    cache->nearCount = count;
    for (std::uint32_t i = 0; i < count; ++i) cache->nearDistance[i] = std::sqrt(fill->d2[i]);
    return;
  }
  // A crowded cell (triangles far smaller than the radius): the tree reads fewer of them than the scan would.
  if (crowded) {
    preciseMeshTree(p, mode, best, tested);
    return;
  }
  scanCell(cell, rel, p, mode, best, static_cast<std::nullptr_t*>(nullptr), tested);
}

void ClodDetector::preciseNear(const Vec3& p, double s, DetectionMode mode, Best& best, const QueryCache& cache) const {
  best.hits = cache.nearSpheres;
  const double slack = nearSlack(best.reach, p);
  TriangleBatch batch(batchSize(mode),
                      [&](const std::uint32_t* t, unsigned count) { testGridBatch(t, count, p, mode, best); });
  for (std::uint32_t i = 0; i < cache.nearCount; ++i) {
    // distance(p, T) >= distance(anchor, T) - |p - anchor|: nearest first, so the rest is farther still.
    if (cache.nearDistance[i] - s - slack > best.reach) break;
    batch.add(cache.nearTriangle[i]);
  }
  batch.finish();
}

template <class Visit>
void ClodDetector::forEachHitSphere(double px, double py, double pz, const double& reach, bool tight,
                                    Visit&& visit) const {
  const double* sd = sphereData_.data();
  if (fastLevel_ == FastLevel::Flat || trees_.ballNodes.empty() || (tight && trees_.tightNodes.empty())) {
    const std::size_t n = spheres_->size();
    for (std::size_t i = 0; i < n; ++i) {
      const double dx = px - sd[4 * i], dy = py - sd[4 * i + 1], dz = pz - sd[4 * i + 2];
      const double rr = sd[4 * i + 3] + reach;
      if (dx * dx + dy * dy + dz * dz <= rr * rr) visit(static_cast<std::uint32_t>(i));
    }
    return;
  }
  std::uint32_t stack[64];
  int top = 0;
  stack[top++] = 0;
  const BoxNode* nodes = tight ? trees_.tightNodes.data() : trees_.ballNodes.data();
  const std::uint32_t* order = tight ? trees_.tightOrder.data() : trees_.ballOrder.data();
  while (top > 0) {
    const BoxNode& node = nodes[stack[--top]];
    if (squaredDistanceToNode(node, px, py, pz) > reach * reach) continue;
    if (node.count > 0) {
      for (std::uint32_t j = node.first; j < node.first + node.count; ++j) {
        const std::uint32_t i = order[j];
        const double dx = px - sd[4 * i], dy = py - sd[4 * i + 1], dz = pz - sd[4 * i + 2];
        const double rr = sd[4 * i + 3] + reach;
        if (dx * dx + dy * dy + dz * dz <= rr * rr) visit(i);
      }
      continue;
    }
    const std::uint32_t left = static_cast<std::uint32_t>(&node - nodes) + 1, right = node.first;
    const double dl = squaredDistanceToNode(nodes[left], px, py, pz);
    const double dr = squaredDistanceToNode(nodes[right], px, py, pz);
    if (dl <= dr) {
      stack[top++] = right;
      stack[top++] = left;
    } else {
      stack[top++] = left;
      stack[top++] = right;
    }
  }
}

// Best first through the gap tree: a node whose bound on |p - c| - radius exceeds both the pointer's radius and the
// best gap so far (beyond the padding) holds no sphere that could answer; the nearer child is searched first.
template <class Visit>
void ClodDetector::nearestSphereSurface(const Vec3& p, double r, const double& bestGap, Visit&& visit) const {
  const BoxNode* nodes = trees_.gapNodes.data();
  const float* maxRadius = trees_.gapRadius.data();
  const double slack = 4.0 * pad_;
  auto bound = [&](std::uint32_t n) {
    return std::sqrt(squaredDistanceToNode(nodes[n], p.x(), p.y(), p.z())) - static_cast<double>(maxRadius[n]);
  };
  std::uint32_t stack[64];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const std::uint32_t n = stack[--top];
    const double limit = std::min(r, bestGap) + slack;
    if (bound(n) > limit) continue;
    const BoxNode& node = nodes[n];
    if (node.count > 0) {
      for (std::uint32_t j = node.first; j < node.first + node.count; ++j) visit(trees_.gapOrder[j]);
      continue;
    }
    const std::uint32_t left = n + 1, right = node.first;
    const double bl = bound(left), br = bound(right);
    const bool leftFirst = bl <= br;  // the nearer child goes on the stack last, to be searched first
    if (std::max(bl, br) <= limit) stack[top++] = leftFirst ? right : left;
    if (std::min(bl, br) <= limit) stack[top++] = leftFirst ? left : right;
  }
}

inline void ClodDetector::querySpheres(const Vec3& p, double r, ContactResult& out, QueryCache* cache) const {
  const double* sd = sphereData_.data();
  double bestGap = std::numeric_limits<double>::infinity();
  std::uint32_t bestSphere = kNone, hits = 0;
  // A sphere the pointer overlaps (padded, as the hierarchy's test); the nearest surface, the lower index on a tie.
  auto visit = [&](std::uint32_t i) {
    const double dx = p.x() - sd[4 * i], dy = p.y() - sd[4 * i + 1], dz = p.z() - sd[4 * i + 2];
    const double rr = sd[4 * i + 3] + r, d2 = dx * dx + dy * dy + dz * dz;
    if (d2 > rr * rr) return;
    ++hits;
    const double gap = std::sqrt(d2) - spheres_->radii[i];
    if (gap < bestGap || (gap == bestGap && i < bestSphere)) {
      bestGap = gap;
      bestSphere = i;
    }
  };
  if (trees_.gapNodes.empty()) {  // the flat level: every sphere
    for (std::uint32_t i = 0; i < spheres_->size(); ++i) visit(i);
  } else {
    nearestSphereSurface(p, r, bestGap, visit);
  }
  out.spheresHit = hits;
  if (bestSphere == kNone) return;
  const Vec3& c = spheres_->centres[bestSphere];
  const Vec3 v = p - c;
  const double len = v.norm();
  out.contact = true;
  out.normal = len > 0.0 ? Vec3(v / len) : Vec3::UnitZ();
  out.point = c + spheres_->radii[bestSphere] * out.normal;
  out.distance = std::max(0.0, bestGap);
  out.depth = r - out.distance;
  out.sphere = static_cast<std::int32_t>(bestSphere);
  if (cache != nullptr) cache->lastInside = false;  // spheres never say inside
}

inline void ClodDetector::search(const Vec3& p, double radius, DetectionMode mode, Best& best,
                                 QueryCache* cache) const {
  best.d2 = radius * radius;
  best.reach = radius;
  best.found = false;
  if (!grid_.empty() && radius <= grid_.radius()) {
    preciseGrid(p, mode, best, cache);
    return;
  }
  // The grid level beyond its radius: every triangle within it, through one tree.
  if (meshTree_ && !meshTree_->nodes.empty()) {
    preciseMeshTree(p, mode, best, kNone);
    return;
  }
  const bool tree = fastLevel_ != FastLevel::Flat && !triangleRoot_.empty();
  // best.reach by reference: the sphere search narrows as closer triangles are found.
  forEachHitSphere(p.x(), p.y(), p.z(), best.reach, tree, [&](std::uint32_t i) {
    ++best.hits;
    if (tree)
      preciseTree(i, p, mode, best);
    else
      preciseFlat(i, p, mode, best);
  });
}

void ClodDetector::searchDeep(const Vec3& p, double r, DetectionMode mode, Best& best, QueryCache* cache) const {
  best.deep = true;
  Eigen::AlignedBox3d box;
  if (!trees_.tightNodes.empty()) {  // the root bounds every triangle (float, rounded outward)
    const BoxNode& root = trees_.tightNodes[0];
    box = Eigen::AlignedBox3d(Vec3(root.lo[0], root.lo[1], root.lo[2]), Vec3(root.hi[0], root.hi[1], root.hi[2]));
  } else {
    box = mesh_->bounds();  // the flat level keeps no tree: O(triangles), only while a push is followed
  }
  if (!box.contains(p)) return;
  const double diagonal = box.diagonal().norm();
  // One walk of the tree over the mesh finds the nearest within the diagonal. The last answer's triangle is tested
  // first: a push moves little between two queries, so it is near the nearest, and its distance prunes the walk
  // from the root on (from the diagonal alone the walk reads every node nearer than the first leaf it reaches).
  if (meshTree_ && !meshTree_->nodes.empty() && (grid_.empty() || diagonal > grid_.radius())) {
    best.d2 = diagonal * diagonal;
    best.reach = diagonal;
    best.found = false;
    const std::uint32_t tested = lastContact(cache);  // passed over by the walk (see preciseGrid)
    if (tested != kNone) testGridTriangle(tested, p, mode, best);
    // A push a little deeper than the grid radius (the usual one: a stylus pressed in) is answered by the cell of p,
    // which the search within r has just read, when the nearest lies within what the cell lists.
    if (best.found && deepFromCell(p, mode, best, cache, tested)) return;
    preciseMeshTree(p, mode, best, tested);
    return;
  }
  if (meshTree_ && !meshTree_->nodes.empty()) {
    search(p, diagonal, mode, best, cache);
    return;
  }
  // At most about 20 rounds from a tiny radius; 2r for a usual one.
  for (double radius = std::max(2.0 * r, diagonal * 0x1p-20);; radius *= 2.0) {
    const double reach = std::min(radius, diagonal);
    search(p, reach, mode, best, cache);
    if (best.found || !(reach < diagonal)) break;
  }
}

bool ClodDetector::deepFromCell(const Vec3& p, DetectionMode mode, Best& best, const QueryCache* cache,
                                std::uint32_t skip) const {
  if (grid_.empty()) return false;
  const std::uint64_t key = grid_.keyOf(p);
  const CellGrid::CellRef* ref = cache != nullptr && cache->owner == id_ && cache->key == key
                                     ? static_cast<const CellGrid::CellRef*>(cache->cell)
                                     : grid_.find(key);
  if (ref == nullptr) return false;
  const CellGrid::Cell cell = grid_.cell(*ref);
  if (cell.count > kTreeAboveEntries) return false;  // a crowded cell: the tree reads fewer
  const Vec3 rel = p - grid_.centreOf(key);
  // The nearest triangle is no farther than the best so far; when the cell lists everything within that distance of
  // p, one scan finds the nearest (ties to the lowest index, as the tree walk: the scan's bounds hold for any reach).
  const double listed = grid_.listedWithin(rel);
  if (best.reach <= listed) {
    scanCell(cell, rel, p, mode, best, static_cast<std::nullptr_t*>(nullptr), skip);
    return true;
  }
  // The best so far lies beyond what the cell lists (a fast push: the last answer's triangle is far behind). The
  // nearest may still lie within it: a scan bounded there finds it when it does (every triangle nearer than what it
  // finds is listed), and the tree, from the best so far, answers otherwise.
  // The scan is skipped where it would rarely find anything: p farther than that reach from the cell's slab, deep
  // behind the surface. A guess only (the slab holds the candidates' parts within radius() of the cell, not all within
  // that reach of p), so it decides no answer: the tree's is exact either way.
  if (!(listed > 0.0) || grid_.noContact(*ref, rel, listed)) return false;
  // Nor where the last answer shows the nearest lies beyond that reach (a slow push deep inside): distance is
  // 1-Lipschitz, so the nearest is at least the last distance less the step away (NaN when unknown: no skip).
  if (cache != nullptr && cache->owner == id_ && cache->lastDistance - (p - cache->lastDistanceAt).norm() > listed)
    return false;
  const Best far = best;
  best.d2 = listed * listed;
  best.reach = listed;
  best.found = false;
  scanCell(cell, rel, p, mode, best, static_cast<std::nullptr_t*>(nullptr), skip);
  if (best.found) return true;
  const std::uint32_t tested = best.tested;
  best = far;
  best.tested = tested;
  return false;
}

inline void ClodDetector::answer(const Vec3& p, double r, const Best& best, ContactResult& out,
                                 QueryCache* cache) const {
  out.spheresHit = best.hits;
  out.trianglesTested = best.tested;
  if (!best.found) {
    if (cache != nullptr) {
      cache->lastInside = false;
      cache->lastDistance = std::numeric_limits<double>::quiet_NaN();
    }
    return;
  }
  out.point = best.point;
  out.distance = std::sqrt(best.d2);
  out.triangle = static_cast<std::int32_t>(best.triangle);
  // Inside, signed depth, outward normal: the rule brute force shares (from the winner's feature when known).
  if (best.regionKnown)
    finishContact(*mesh_, p, r, best.region, out);
  else
    finishContact(*mesh_, p, r, out);
  if (best.deep && !out.inside) {
    // The nearest surface is beyond r and the centre is outside it: no contact.
    out = ContactResult{};
    out.spheresHit = best.hits;
    out.trianglesTested = best.tested;
    cache->lastInside = false;
    cache->lastDistance = std::numeric_limits<double>::quiet_NaN();
    return;
  }
  out.contact = true;
  // The grid defers the sphere to here: the first sphere listing the triangle.
  const std::uint32_t sphere = best.sphere != kNone ? best.sphere : sphereOfTriangle_[best.triangle];
  out.sphere = sphere != kNone ? static_cast<std::int32_t>(sphere) : -1;
  if (cache != nullptr) {
    cache->lastTriangle = out.triangle;
    cache->lastInside = out.inside;
    cache->lastDistance = out.distance;
    cache->lastDistanceAt = p;
  }
}

void ClodDetector::query(const Vec3& model, double r, DetectionMode mode, ContactResult& out,
                         QueryCache* cache) const noexcept {
  out = ContactResult{};
  if (!validPointer(model, r)) return;
  // Everything below runs in the mesh's local frame (exact for a mesh far from zero: chooseLocalOrigin).
  const Vec3 p = model - origin_;
  if (mode == DetectionMode::Spheres) {  // coarsest answer: the nearest sphere surface within r
    querySpheres(p, r, out, cache);
    if (out.contact) out.point += origin_;
    return;
  }
  // The nearest triangle within r (the tie rule of bruteForceQuery), through the configured levels: the grid
  // up to its radius, the hierarchy (or the flat list) beyond.
  Best best;
  search(p, r, mode, best, cache);
  // Deep penetration: the stream was inside and no triangle is within r. The nearest triangle is found
  // with a growing radius; only a centre inside the model's box can be inside a closed surface, and from
  // there every triangle is within the box's diagonal, where the search ends.
  if (!best.found && cache != nullptr && cache->lastInside) searchDeep(p, r, mode, best, cache);
  answer(p, r, best, out, cache);
  if (out.contact) out.point += origin_;
}

std::uint32_t ClodDetector::fastLevelHits(const Vec3& model, double r) const noexcept {
  if (!validPointer(model, r)) return 0;
  const Vec3 p = model - origin_;
  if (!grid_.empty() && r <= grid_.radius()) {
    const std::uint64_t key = grid_.keyOf(p);
    const CellGrid::CellRef* ref = grid_.find(key);
    if (ref == nullptr || grid_.noContact(*ref, p - grid_.centreOf(key), r)) return 0;
    return grid_.cell(*ref).spheres;
  }
  std::uint32_t hits = 0;
  const bool tree = fastLevel_ != FastLevel::Flat && !triangleRoot_.empty();
  forEachHitSphere(p.x(), p.y(), p.z(), r, tree, [&](std::uint32_t) { ++hits; });
  return hits;
}

void ClodDetector::hitSpheres(const Vec3& model, double r, std::vector<std::uint32_t>& out) const {
  out.clear();
  if (!validPointer(model, r)) return;
  const Vec3 p = model - origin_;
  forEachHitSphere(p.x(), p.y(), p.z(), r, false, [&](std::uint32_t i) { out.push_back(i); });
  std::sort(out.begin(), out.end());
}

}  // namespace clod_haptics
