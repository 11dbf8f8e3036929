#include "clod_haptics/core/tight_clustering.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>
#include <thread>

#include "clod_haptics/core/box_tree.h"
#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/geometry.h"
#include "clod_haptics/core/morton.h"
#include "clod_haptics/core/triangle_bvh.h"
#include "clod_haptics/core/triangle_pieces.h"
#include "parallel.h"

namespace clod_haptics {
namespace {

constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();

// A node of the tree: the items in [begin, end) of the order its splits leave.
struct Range {
  std::uint32_t begin, end;
};

// 0, 1, ..., n - 1.
std::vector<std::uint32_t> identity(std::size_t n) {
  std::vector<std::uint32_t> v(n);
  std::iota(v.begin(), v.end(), 0u);
  return v;
}

// A cut along another principal axis is taken only when it leaves the halves' spread below this share of the
// principal cut's. With any gain (1), the legs model's tree grew five times the nodes (331 -> 1,689 judged, build
// 28 -> 72 ms) for outside volumes within 10%; 0.85 keeps every cut the thin cylinders need (their tables are the
// same) and builds legs in 27 ms. Chosen on thin_bench's models (cylinder-0.05, legs): see its table.
constexpr double kCompactGain = 0.85;

// Of the three principal axes (eigenvectors of the keys' covariance, largest eigenvalue last), the one whose cut at
// the mean leaves the halves most compact: the least of the two halves' largest squared distance of a key from the
// half's mean, if it is below kCompactGain of the principal cut's, else the principal axis (the one of largest
// variance). A thin cylinder's ring is thus cut along the cylinder, where the principal axis alone turns across it
// once the ring is shorter than its girth. Not for a hollow node (PatchJudge::hollow): there a ring's halves, whose
// keys lie farther from their own mean than the ring's from its, seem less compact than thinner rings, and the tree
// would cut a hollow tube (or a shell's rim) into rings whose spheres sit in the empty space they enclose (on
// thin_bench's tube-shell-0.004, 19 balls of the tube's radius centred on its axis).
Vec3 compactAxis(const std::vector<std::uint32_t>& items, std::uint32_t begin, std::uint32_t end, const Vec3* key,
                 const Vec3& mean, const Eigen::Matrix3d& axes) {
  Vec3 best = axes.col(2);
  double bestSpread = std::numeric_limits<double>::infinity(), principal = bestSpread;
  for (int a = 2; a >= 0; --a) {  // largest eigenvalue first, so ties keep it
    const Vec3 axis = axes.col(a);
    const double cut = axis.dot(mean);
    Vec3 sum[2] = {Vec3::Zero(), Vec3::Zero()};
    std::uint32_t count[2] = {0, 0};
    for (std::uint32_t i = begin; i < end; ++i) {
      const int side = axis.dot(key[items[i]]) < cut ? 0 : 1;
      sum[side] += key[items[i]];
      ++count[side];
    }
    if (count[0] == 0 || count[1] == 0) continue;
    const Vec3 centre[2] = {sum[0] / count[0], sum[1] / count[1]};
    double spread = 0.0;
    for (std::uint32_t i = begin; i < end; ++i) {
      const int side = axis.dot(key[items[i]]) < cut ? 0 : 1;
      spread = std::max(spread, (key[items[i]] - centre[side]).squaredNorm());
    }
    if (a == 2) principal = spread;
    if (spread < bestSpread && (a == 2 || spread < kCompactGain * principal)) {
      bestSpread = spread;
      best = axis;
    }
  }
  return best;
}

// Splits items[begin, end) in two at the mean of their keys along the keys' principal axis, or with compact along
// compactAxis; returns the first index of the second half, always strictly inside (begin, end) for end - begin >= 2.
// Depends only on the items and their keys, never on d: the tree is the same for every d.
std::uint32_t splitAtMean(std::vector<std::uint32_t>& items, std::uint32_t begin, std::uint32_t end, const Vec3* key,
                          bool compact) {
  Vec3 mean = Vec3::Zero();
  for (std::uint32_t i = begin; i < end; ++i) mean += key[items[i]];
  mean /= static_cast<double>(end - begin);
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (std::uint32_t i = begin; i < end; ++i) {
    const Vec3 v = key[items[i]] - mean;
    cov.noalias() += v * v.transpose();
  }
  std::uint32_t mid = begin;
  if (cov.allFinite() && cov.trace() > 0.0) {
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(cov);
    const Vec3 axis = compact ? compactAxis(items, begin, end, key, mean, eigen.eigenvectors())
                              : Vec3(eigen.eigenvectors().col(2));  // largest eigenvalue last
    const double cut = axis.dot(mean);
    mid = static_cast<std::uint32_t>(std::partition(items.begin() + begin, items.begin() + end,
                                                    [&](std::uint32_t t) { return axis.dot(key[t]) < cut; }) -
                                     items.begin());
  }
  // Coincident keys (or rounding) put everything on one side: halve by position instead.
  if (mid == begin || mid == end) mid = begin + (end - begin) / 2;
  return mid;
}

// Labels of the points from the cluster of each item, renumbered in the order of each cluster's
// first point (the Clustering contract).
std::uint32_t labelPoints(const std::vector<std::uint32_t>& clusterOfItem,
                          const std::vector<std::uint32_t>& itemOfPoint, std::uint32_t clusters,
                          std::vector<std::uint32_t>& labels, std::vector<std::uint32_t>* firstOrder) {
  std::vector<std::uint32_t> renumber(clusters, kNone);
  std::uint32_t count = 0;
  for (std::size_t i = 0; i < itemOfPoint.size(); ++i) {
    const std::uint32_t c = clusterOfItem[itemOfPoint[i]];
    if (renumber[c] == kNone) {
      renumber[c] = count++;
      if (firstOrder) firstOrder->push_back(c);
    }
    labels[i] = renumber[c];
  }
  return count;
}

inline double boxDistance2(const Vec3& p, const double* lo, const double* hi) {
  double sum = 0.0;
  for (int k = 0; k < 3; ++k) {
    const double below = lo[k] - p[k], above = p[k] - hi[k];
    const double d = below > above ? below : above;
    sum += d > 0.0 ? d * d : 0.0;
  }
  return sum;  // an empty box (lo > hi) gives a positive value; its leaves hold no triangles anyway
}

// The largest squared distance of the points of node r from their mean.
double squaredSpread(const std::vector<Vec3>& points, const std::vector<std::uint32_t>& items, Range r) {
  Vec3 mean = Vec3::Zero();
  for (std::uint32_t i = r.begin; i < r.end; ++i) mean += points[items[i]];
  mean /= static_cast<double>(r.end - r.begin);
  double spread = 0.0;
  for (std::uint32_t i = r.begin; i < r.end; ++i) spread = std::max(spread, (points[items[i]] - mean).squaredNorm());
  return spread;
}

void requireWrapped(const TriangleMesh& mesh, std::size_t points, const std::vector<std::uint32_t>& wrapped) {
  if (wrapped.size() != points) throw InvalidParameter("TightClustering: one wrapped triangle per point is needed");
  for (const std::uint32_t t : wrapped)
    if (t >= mesh.size()) throw InvalidParameter("TightClustering: wrapped triangle out of range");
}

// The arrays by item are left uninitialised when sized (every element is written before it is read): a thin plate's
// pieces run to 17 MB, and zeroing them first cost as long as writing them.
template <class T>
using ItemArray = std::vector<T, detail::DefaultInitAllocator<T>>;

// The items of clusterMesh are the wrapped triangles (each once, in the order first wrapped), or their
// pieces (splitLongItems), with what the choice of a centre needs of each: its corners, its centroid and the
// depth hint, the mean of its triangle's points' distances below the triangle (from the sums of the points
// with a finite distance).
struct TriangleItems {
  std::vector<std::uint32_t> itemOfPoint;  // by point (a split triangle's first piece)
  ItemArray<std::uint32_t> triangle;       // by item, as are the arrays below
  ItemArray<double> depthSum;
  ItemArray<std::uint32_t> depthCount;
  ItemArray<Vec3> pointSum;
  ItemArray<Vec3> centroid;
  ItemArray<TrianglePiece> corners;
  ItemArray<std::uint8_t> halvings;  // how many halvings below its triangle (0: the triangle whole)
};

TriangleItems gatherItems(const TriangleMesh& mesh, const std::vector<Vec3>& points,
                          const std::vector<std::uint32_t>& wrapped) {
  TriangleItems items;
  std::vector<std::uint32_t> slot(mesh.size(), kNone);  // by triangle: its item
  items.itemOfPoint.resize(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const std::uint32_t t = wrapped[i];
    if (slot[t] == kNone) {
      slot[t] = static_cast<std::uint32_t>(items.triangle.size());
      items.triangle.push_back(t);
      items.depthSum.push_back(0.0);
      items.depthCount.push_back(0);
      items.pointSum.push_back(Vec3::Zero());
    }
    const std::uint32_t item = slot[t];
    items.itemOfPoint[i] = item;
    const double depth = (mesh.centroid(t) - points[i]).norm();
    if (std::isfinite(depth)) {
      items.depthSum[item] += depth;
      ++items.depthCount[item];
      items.pointSum[item] += points[i];
    }
  }
  items.centroid.resize(items.triangle.size());
  items.corners.resize(items.triangle.size());
  for (std::size_t k = 0; k < items.triangle.size(); ++k) {
    const std::uint32_t t = items.triangle[k];
    items.centroid[k] = mesh.centroid(t);
    items.corners[k] = {mesh.vertex(t, 0), mesh.vertex(t, 1), mesh.vertex(t, 2)};
  }
  items.halvings.assign(items.triangle.size(), 0);
  return items;
}

// Whether some item has an edge longer than maxEdge.
bool hasLongItem(const TriangleItems& items, double maxEdge) {
  if (!(maxEdge > 0.0)) return false;
  for (const TrianglePiece& t : items.corners)
    if (longestEdge2(t) > maxEdge * maxEdge) return true;
  return false;
}

// The items with each item k replaced by its pieces, a piece halved while split(k, piece) asks (halveWhile,
// continuing the item's own halvings, in order); cluster (by item; may be empty) follows.
// A piece keeps its triangle's depth hint; its mean point is its triangle's, moved by as much as its centroid is
// from the triangle's. Two passes, each thread over its own run of items: the pieces are counted, then written where
// they go (the same pieces in the same order whatever the threads; split is called from several threads at once
// and must only read).
template <class Split>
TriangleItems splitItems(const TriangleItems& whole, Split&& split, std::vector<std::uint32_t>& cluster) {
  const std::size_t n = whole.triangle.size();
  const unsigned threads = detail::threadsFor(n, 0, 2048);
  std::vector<std::uint32_t> firstPiece(n + 1, 0);
  auto halve = [&](std::size_t k, auto&& visit) {
    const int done = whole.halvings[k];
    halveWhile(
        whole.corners[k], kMaxPieceDepth - done, done, [&](const TrianglePiece& piece) { return split(k, piece); },
        visit);
  };
  detail::runParallel(threads, [&](unsigned t) {
    for (std::size_t k = n * t / threads; k < n * (t + 1) / threads; ++k)
      halve(k, [&](const TrianglePiece&, int) { ++firstPiece[k + 1]; });
  });
  for (std::size_t k = 0; k < n; ++k) firstPiece[k + 1] += firstPiece[k];
  const std::size_t total = firstPiece[n];
  TriangleItems items;
  items.triangle.resize(total);
  items.depthSum.resize(total);
  items.depthCount.resize(total);
  items.pointSum.resize(total);
  items.centroid.resize(total);
  items.corners.resize(total);
  items.halvings.resize(total);
  std::vector<std::uint32_t> pieceCluster(cluster.empty() ? 0 : total);
  detail::runParallel(threads, [&](unsigned t) {
    for (std::size_t k = n * t / threads; k < n * (t + 1) / threads; ++k) {
      std::size_t at = firstPiece[k];
      halve(k, [&](const TrianglePiece& piece, int depth) {
        const Vec3 centroid = (piece[0] + piece[1] + piece[2]) / 3.0;
        items.triangle[at] = whole.triangle[k];
        items.depthSum[at] = whole.depthSum[k];
        items.depthCount[at] = whole.depthCount[k];
        const double points = whole.depthCount[k];
        items.pointSum[at] = whole.pointSum[k] + points * (centroid - whole.centroid[k]);
        items.centroid[at] = centroid;
        items.corners[at] = piece;
        items.halvings[at] = static_cast<std::uint8_t>(depth);
        if (!cluster.empty()) pieceCluster[at] = cluster[k];
        ++at;
      });
    }
  });
  items.itemOfPoint.resize(whole.itemOfPoint.size());
  for (std::size_t i = 0; i < whole.itemOfPoint.size(); ++i) items.itemOfPoint[i] = firstPiece[whole.itemOfPoint[i]];
  cluster.swap(pieceCluster);
  return items;
}

// The items with each long triangle replaced by its pieces of edges up to maxEdge.
TriangleItems splitLongItems(const TriangleItems& whole, double maxEdge) {
  std::vector<std::uint32_t> none;
  return splitItems(
      whole, [maxEdge](std::size_t, const TrianglePiece& piece) { return longestEdge2(piece) > maxEdge * maxEdge; },
      none);
}

constexpr double kInfinity = std::numeric_limits<double>::infinity();
constexpr int kMaxCandidates = 9;  // the mean point, seven pushed centroids, the box's middle
// A node whose items' unit normals sum to less than this share of their count faces every way (a ring of a leg, a
// branch, a closed end, both sheets of a plate) and also gets the middle of its corners' box as a candidate. On
// thin_bench (2026-11-29): the cylinder of 12 long triangles 0.02 thick 1.06 -> 0.36 outside at 150 spheres and 0.76
// -> 0.36 at 500 (95 spheres: its pieces are as long as the rings then), the 0.05 cylinder at 500 0.149 -> 0.070 (316
// spheres); but legs at 500 0.084 -> 0.094, the held-out insect (six legs 0.02 thick on a body) 3 and 5% more, and
// branches at 150 2.89 -> 3.01, at 500 1.45 -> 1.51 (a level's d shares the spheres out between the parts otherwise);
// the shared meshes the same but elephant at 500 (4% less). With 0.5: the same cylinders, refined_elephant at 500
// 2.5% more.
constexpr double kFacingEveryWay = 0.2;
constexpr int kRays = 32;  // directions of the all-sides estimate

struct Candidate {
  Vec3 centre;
  double far2, near2, lower;  // squared distances to the farthest and nearest vertex; bound of the excess
};

inline double capVolume(double r, double h) { return 0.25 * h * h * (3.0 * r - h); }

// Unit directions spread over the sphere (a Fibonacci lattice).
std::vector<Vec3> rayDirections() {
  std::vector<Vec3> dirs(kRays);
  const double golden = M_PI * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < kRays; ++i) {
    const double z = 1.0 - (2.0 * i + 1.0) / kRays, ring = std::sqrt(1.0 - z * z);
    dirs[i] = Vec3(ring * std::cos(golden * i), ring * std::sin(golden * i), z);
  }
  return dirs;
}

// Whether a node becomes a sphere, and its centre. Excess of a sphere: the volume of its cap beyond the
// tangent plane at the surface point nearest to its centre, over 4/3 pi (so that it compares with d^3):
// with rho the signed distance of the centre and h = R - rho the cap's height, h^2 (3R - h) / 4; a centre
// outside counts as h = 2R (the whole ball). The excess grows with h, and rho is at most the distance to
// the nearest vertex of the node's own triangles, so R minus that distance bounds h from below: a
// candidate whose bound already exceeds d^3 or the best exact excess found gets no distance query (the
// costly part); the decision and the chosen centre are those of exact values.
class PatchJudge {
 public:
  PatchJudge(const TriangleMesh& mesh, const TriangleItems& items, const std::vector<std::uint32_t>& order, double d)
      : mesh_(mesh), items_(items), order_(order), surface_(mesh), bvh_(mesh), dirs_(rayDirections()), d3_(d * d * d) {}

  // Whether the mean of node r's item centroids lies outside the mesh: the node then encloses empty space (a ring
  // of a hollow tube, a shell's rim), and its split takes the principal axis (compactAxis). Depends on the node
  // alone, never on d, so the tree does not either.
  bool hollow(Range r) const {
    Vec3 mean = Vec3::Zero();
    for (std::uint32_t i = r.begin; i < r.end; ++i) mean += items_.centroid[order_[i]];
    mean /= static_cast<double>(r.end - r.begin);
    return surface_.signedDistance(mean, kInfinity) < 0.0;
  }

  // Whether node r becomes a sphere; its centre in best either way, in passed whether its excess is within
  // d^3 (a single item is kept even when it is not), and in depth the centre's signed distance below the surface
  // (+inf when it was not needed).
  bool evaluate(Range r, Vec3& best, bool& passed, double& depth) const {
    Candidate cand[kMaxCandidates];
    const int count = placeCandidates(r, cand);
    reach(cand, count, r);
    boundExcess(cand, count);
    // A single triangle is kept whatever d is: its centre is chosen on exact values.
    const bool single = r.end - r.begin == 1;
    const double bestExcess = pickCentre(cand, count, single ? kInfinity : d3_, best, depth);
    passed = bestExcess <= d3_;
    return single || passed;
  }

 private:
  // The mean of the placement's points on the node's triangles, and the mean of their centroids pushed
  // inward along their mean normal by fractions of their mean depth: those that are finite, or the mean
  // centroid alone when none is. Returns how many.
  int placeCandidates(Range r, Candidate* cand) const {
    const double size = static_cast<double>(r.end - r.begin);
    Vec3 meanCentroid = Vec3::Zero(), meanNormal = Vec3::Zero(), meanPoint = Vec3::Zero();
    double depth = 0.0, weights = 0.0;
    for (std::uint32_t i = r.begin; i < r.end; ++i) {
      const std::uint32_t k = order_[i];
      meanCentroid += items_.centroid[k];
      meanNormal += mesh_.normals[items_.triangle[k]];
      if (items_.depthCount[k] > 0) {
        depth += items_.depthSum[k] / items_.depthCount[k];
        meanPoint += items_.pointSum[k];
        weights += items_.depthCount[k];
      }
    }
    meanCentroid /= size;
    depth /= size;
    int count = 0;
    if (weights > 0.0) cand[count++].centre = meanPoint / weights;
    const double normalLength = meanNormal.norm();
    if (normalLength > 1e-9 * size && depth > 0.0) {
      const Vec3 inward = -meanNormal / normalLength;
      // Up to twice the depth: the middle of a thin part for a placement a quarter of the way across.
      for (const double f : {2.0, 1.5, 1.0, 0.75, 0.5, 0.25, 0.125})
        cand[count++].centre = meanCentroid + f * depth * inward;
    }
    // Items facing every way (a ring of a leg or a branch): the middle of their corners' box, on the ring's axis,
    // where the ball reaching every corner is smallest; the points above lean to the side where more items lie. The
    // corners are read for it only here: most nodes face one way.
    if (normalLength < kFacingEveryWay * size) {
      Eigen::AlignedBox3d box;
      for (std::uint32_t i = r.begin; i < r.end; ++i)
        for (const Vec3& v : items_.corners[order_[i]]) box.extend(v);
      cand[count++].centre = box.center();
    }
    int kept = 0;
    for (int j = 0; j < count; ++j)
      if (cand[j].centre.allFinite()) cand[kept++] = cand[j];
    if (kept == 0) cand[kept++].centre = meanCentroid;  // no depth to go by: the patch itself
    return kept;
  }

  // Fills far2 / near2 of every candidate in one pass over the corners of the node's items.
  void reach(Candidate* cand, int count, Range r) const {
    for (int j = 0; j < count; ++j) {
      cand[j].far2 = 0.0;
      cand[j].near2 = kInfinity;
    }
    for (std::uint32_t i = r.begin; i < r.end; ++i) {
      const TrianglePiece& corners = items_.corners[order_[i]];
      for (int v = 0; v < 3; ++v) {
        const Vec3& p = corners[v];
        for (int j = 0; j < count; ++j) {
          const double d2 = (p - cand[j].centre).squaredNorm();
          cand[j].far2 = std::max(cand[j].far2, d2);
          cand[j].near2 = std::min(cand[j].near2, d2);
        }
      }
    }
  }

  // Each candidate's lower bound of its excess, from its nearest vertex (+inf where not finite).
  static void boundExcess(Candidate* cand, int count) {
    for (int j = 0; j < count; ++j) {
      const double radius = std::sqrt(cand[j].far2);
      cand[j].lower = capVolume(radius, std::clamp(radius - std::sqrt(cand[j].near2), 0.0, 2.0 * radius));
      if (!std::isfinite(cand[j].lower)) cand[j].lower = kInfinity;
    }
  }

  // Exact excess (one distance query) only for candidates whose bound could still pass threshold and win;
  // the lowest bounds first, so that fewer are left to query (ties keep the candidates' order). Returns
  // the least exact excess (+inf when none was found), its centre in best (else the lowest bound's).
  double pickCentre(Candidate* cand, int count, double threshold, Vec3& best, double& depth) const {
    std::stable_sort(cand, cand + count, [](const Candidate& x, const Candidate& y) { return x.lower < y.lower; });
    best = cand[0].centre;
    depth = kInfinity;
    double bestExcess = kInfinity, bestRadius = 0.0;
    for (int j = 0; j < count; ++j) {
      if (cand[j].lower > threshold || cand[j].lower >= bestExcess) continue;
      const double radius = std::sqrt(cand[j].far2), rho = surface_.signedDistance(cand[j].centre, radius);
      const double e = capVolume(radius, std::clamp(radius - rho, 0.0, 2.0 * radius));
      if (std::isfinite(e) && e < bestExcess) {
        bestExcess = e;
        bestRadius = radius;
        best = cand[j].centre;
        depth = rho;
      }
    }
    // The cap sees one side; a ball in a thin part also sticks out on the far side (a plate) or all round (a leg).
    // Scored for the chosen centre, once its cap passes.
    if (bestExcess <= d3_) bestExcess = std::max(bestExcess, outsideAllRound(best, bestRadius, d3_));
    return bestExcess;
  }

  // The ball's volume beyond the surface on every side, over 4/3 pi, as seen from its centre: along each of kRays
  // directions the part of the radius beyond the first surface crossing, (R^3 - min(s, R)^3) averaged (a solid
  // angle's share of the ball). Counts a region behind a second crossing as outside: an upper estimate.
  // Stops once the estimate exceeds limit (the answer is then some value above limit, not the estimate).
  double outsideAllRound(const Vec3& centre, double radius, double limit) const {
    const double r3 = radius * radius * radius;
    double sum = 0.0;
    for (const Vec3& dir : dirs_) {
      double first = radius;
      bvh_.forEachRayHit(centre, dir, first, [&](std::uint32_t, double t) { first = std::min(first, t); });
      sum += r3 - first * first * first;
      if (sum > limit * kRays) return sum / kRays;  // the rest only adds (each term >= 0)
    }
    return sum / kRays;
  }

  const TriangleMesh& mesh_;
  const TriangleItems& items_;
  const std::vector<std::uint32_t>& order_;
  const SurfaceDistance surface_;
  const TriangleBvh bvh_;
  const std::vector<Vec3> dirs_;
  const double d3_;
};

// A node kept as a sphere, with its centre.
struct Leaf {
  Range range;
  Vec3 centre;
  bool passed;   // its excess is within d^3 (not so for a single item kept whatever d is)
  double depth;  // the centre's signed distance below the surface (+inf: not known)
};

// The tree over the items, cut where the judge keeps a node. Items of disjoint nodes are disjoint ranges
// of order(), so nodes run in parallel.
class PatchTree {
 public:
  PatchTree(const TriangleMesh& mesh, const TriangleItems& items, double d)
      : items_(items), order_(identity(items.triangle.size())), judge_(mesh, items, order_, d) {}
  PatchTree(const PatchTree&) = delete;
  PatchTree& operator=(const PatchTree&) = delete;

  // The leaves in groups: those found at the top of the tree, then those below each node the top left.
  // The tree and the leaves do not depend on the threads (only their grouping, which the labelling removes).
  std::vector<std::vector<Leaf>> leaves() {
    unsigned threads = std::max(1u, std::thread::hardware_concurrency());
    if (order_.size() < 4096) threads = 1;
    std::vector<std::vector<Leaf>> groups(1);
    std::vector<Range> tasks{{0, static_cast<std::uint32_t>(order_.size())}};
    std::atomic<std::size_t> nextTask{expandTop(threads, tasks, groups[0])};
    groups.resize(1 + tasks.size());
    detail::runParallel(threads, [&](unsigned) {
      for (std::size_t t; (t = nextTask.fetch_add(1)) < tasks.size();) descend(tasks[t], groups[1 + t]);
    });
    return groups;
  }

  // The items in the order of the tree: a leaf's items are order()[leaf.range].
  const std::vector<std::uint32_t>& order() const { return order_; }

 private:
  // Whether node r is a leaf (with its centre); if not, it is split and mid is where its second half starts.
  bool isLeaf(Range r, Vec3& centre, bool& passed, double& depth, std::uint32_t& mid) {
    if (judge_.evaluate(r, centre, passed, depth)) return true;
    mid = splitAtMean(order_, r.begin, r.end, items_.centroid.data(), !judge_.hollow(r));
    return false;
  }

  // The top of the tree breadth first on this thread until there are a few nodes per thread (nothing on
  // one thread): its leaves go to top, its nodes to tasks. Returns the first node it left to expand.
  std::size_t expandTop(unsigned threads, std::vector<Range>& tasks, std::vector<Leaf>& top) {
    std::size_t next = 0;
    while (threads > 1 && next < tasks.size() && tasks.size() - next < 4 * std::size_t(threads)) {
      const Range r = tasks[next++];
      Vec3 centre;
      bool passed;
      double depth;
      std::uint32_t mid;
      if (isLeaf(r, centre, passed, depth, mid)) {
        top.push_back({r, centre, passed, depth});
        continue;
      }
      tasks.push_back({r.begin, mid});
      tasks.push_back({mid, r.end});
    }
    return next;
  }

  // Depth first below one node.
  void descend(Range root, std::vector<Leaf>& leaves) {
    std::vector<Range> stack{root};
    while (!stack.empty()) {
      const Range r = stack.back();
      stack.pop_back();
      Vec3 centre;
      bool passed;
      double depth;
      std::uint32_t mid;
      if (isLeaf(r, centre, passed, depth, mid)) {
        leaves.push_back({r, centre, passed, depth});
        continue;
      }
      stack.push_back({mid, r.end});
      stack.push_back({r.begin, mid});
    }
  }

  const TriangleItems& items_;
  std::vector<std::uint32_t> order_;
  const PatchJudge judge_;
};

// Labels the points by the leaf holding their triangle, and the leaves' centres in label order.
std::uint32_t labelLeaves(const std::vector<std::vector<Leaf>>& groups, const std::vector<std::uint32_t>& order,
                          const TriangleItems& items, std::vector<std::uint32_t>& labels, std::vector<Vec3>& centres) {
  std::vector<std::uint32_t> clusterOf(order.size(), 0);
  std::vector<Vec3> clusterCentre;
  for (const std::vector<Leaf>& leaves : groups)
    for (const Leaf& leaf : leaves) {
      for (std::uint32_t i = leaf.range.begin; i < leaf.range.end; ++i)
        clusterOf[order[i]] = static_cast<std::uint32_t>(clusterCentre.size());
      clusterCentre.push_back(leaf.centre);
    }
  std::vector<std::uint32_t> firstOrder;
  const std::uint32_t count =
      labelPoints(clusterOf, items.itemOfPoint, static_cast<std::uint32_t>(clusterCentre.size()), labels, &firstOrder);
  centres.reserve(count);
  for (const std::uint32_t c : firstOrder) centres.push_back(clusterCentre[c]);
  return count;
}

// Squared distance from c to the farthest corner of an item.
inline double farthest2(const TrianglePiece& corners, const Vec3& c) {
  return std::max({(corners[0] - c).squaredNorm(), (corners[1] - c).squaredNorm(), (corners[2] - c).squaredNorm()});
}

// Calls visit(item) for every item, each cluster's items (cluster[item], of k) on one thread and in ascending order:
// the threads take runs of clusters and each passes over all the items, so a sum or maximum by cluster comes out as
// one thread's loop would make it, whatever the threads.
template <class Visit>
void byCluster(const std::vector<std::uint32_t>& cluster, std::size_t k, Visit&& visit) {
  const unsigned threads = detail::threadsFor(cluster.size(), 0, 16384);
  detail::runParallel(threads, [&](unsigned t) {
    const std::size_t lo = k * t / threads, hi = k * (t + 1) / threads;
    for (std::size_t i = 0; i < cluster.size(); ++i)
      if (cluster[i] >= lo && cluster[i] < hi) visit(i);
  });
}

// The items' farthest corner from the centre of their cluster, squared, by cluster (0 for an empty one).
std::vector<double> farthestByCluster(const TriangleItems& items, const std::vector<std::uint32_t>& cluster,
                                      const std::vector<Vec3>& centre) {
  std::vector<double> far2(centre.size(), 0.0);
  byCluster(cluster, centre.size(), [&](std::size_t i) {
    far2[cluster[i]] = std::max(far2[cluster[i]], farthest2(items.corners[i], centre[cluster[i]]));
  });
  return far2;
}

// For each item, the spheres c with use(c) whose ball (centre[c], sqrt(reach2[c])) holds the item's centroid and
// that accept(item, c) takes; per thread, its own run of items (threadsFor(n, 0, 4096)), as
// list[t][start[t][i - first] .. start[t][i - first + 1]) for item i of thread t's run beginning at first. An item
// that want(item) declines gets an empty list. Empty lists for all when no ball is used. The items of one cluster
// (cluster[item], of k) lie close together and meet the same few balls: a box tree over the balls lists, once per
// cluster, those that meet the box of its wanted items' centroids, and each item tests only those (a tree walk per
// item cost as much as everything else of a thin plate's settling). The lists hold the same spheres as a walk per
// item would, in another order (their callers pick the least by value, then by index: the order does not matter).
struct HolderLists {
  unsigned threads = 1;
  std::vector<std::vector<std::uint32_t>> list, start;
};

template <class Use, class Want, class Accept>
HolderLists ballsHolding(const TriangleItems& items, const std::vector<std::uint32_t>& cluster, std::size_t k,
                         const std::vector<Vec3>& centre, const std::vector<double>& reach2, Use&& use, Want&& want,
                         Accept&& accept) {
  const std::size_t n = items.centroid.size();
  std::vector<Eigen::AlignedBox3d> balls;
  std::vector<std::uint32_t> sphereOf;
  for (std::size_t c = 0; c < centre.size(); ++c) {
    if (!use(c)) continue;
    const double r = std::sqrt(reach2[c]);
    balls.emplace_back(centre[c] - Vec3::Constant(r), centre[c] + Vec3::Constant(r));
    sphereOf.push_back(static_cast<std::uint32_t>(c));
  }
  HolderLists out;
  out.threads = detail::threadsFor(n, 0, 4096);
  out.list.resize(out.threads);
  out.start.resize(out.threads);
  std::vector<BoxNode> nodes;
  std::vector<std::uint32_t> order;
  const bool none = buildBoxTree(balls, 4, 0.0, nodes, order) == kNone;
  for (std::uint32_t& j : order) j = sphereOf[j];
  // Each cluster's wanted centroids' box, and the balls that meet it (a ball holding a centroid meets the box).
  std::vector<char> wanted(n, 0);
  std::vector<Eigen::AlignedBox3d> spread(k);  // empty until extended
  if (!none)
    for (std::size_t item = 0; item < n; ++item)
      if ((wanted[item] = want(item) ? 1 : 0)) spread[cluster[item]].extend(items.centroid[item]);
  std::vector<std::uint32_t> meetStart(k + 1, 0), meet;
  for (std::size_t c = 0; c < k; ++c) {
    meetStart[c] = static_cast<std::uint32_t>(meet.size());
    if (spread[c].isEmpty()) continue;
    const Vec3 lo = spread[c].min(), hi = spread[c].max();
    std::uint32_t stack[64];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
      const BoxNode& node = nodes[stack[--top]];
      bool apart = false;
      for (int a = 0; a < 3; ++a) apart = apart || node.lo[a] > hi[a] || lo[a] > node.hi[a];
      if (apart) continue;
      if (node.count == 0) {
        stack[top++] = node.first;
        stack[top++] = static_cast<std::uint32_t>(&node - nodes.data()) + 1;
        continue;
      }
      for (std::uint32_t j = node.first; j < node.first + node.count; ++j) {
        const std::uint32_t s = order[j];
        // The ball's distance to the box, with a margin for its rounding: never fewer than the items' own tests.
        const Vec3 q = centre[s].cwiseMax(lo).cwiseMin(hi);
        if ((q - centre[s]).squaredNorm() <= reach2[s] * (1.0 + 1e-9)) meet.push_back(s);
      }
    }
  }
  meetStart[k] = static_cast<std::uint32_t>(meet.size());
  detail::runParallel(out.threads, [&](unsigned t) {
    std::vector<std::uint32_t>& list = out.list[t];
    std::vector<std::uint32_t>& start = out.start[t];
    for (std::size_t item = n * t / out.threads; item < n * (t + 1) / out.threads; ++item) {
      start.push_back(static_cast<std::uint32_t>(list.size()));
      if (!wanted[item]) continue;  // none wanted when no ball is used
      const Vec3& p = items.centroid[item];
      const std::uint32_t own = cluster[item];
      for (std::uint32_t j = meetStart[own]; j < meetStart[own + 1]; ++j) {
        const std::uint32_t c = meet[j];
        if ((p - centre[c]).squaredNorm() <= reach2[c] && accept(item, c)) list.push_back(c);
      }
    }
    start.push_back(static_cast<std::uint32_t>(list.size()));
  });
  return out;
}

// Hands each item to the sphere it lies deepest in, keeping the centres: an item goes to the sphere s that
// holds all its corners (at the current radii) with the most room, max over corners |corner - c_s| - R_s least,
// among its own and those whose excess passed the judge (open: not a single item kept whatever its excess, which
// stays with what it wraps); its own is one of them, so no sphere grows. Each radius then shrinks to its items'
// farthest corner: an item at the edge of a large patch that a neighbouring sphere already holds stops setting that
// sphere's radius. A smaller radius about the same centre only lowers the sphere's cap and its volume outside, so the
// judge's bound still holds. Up to 8 rounds (until no item moves), each computed from the previous round's radii,
// so the result does not depend on the order of the items or the threads. cluster[item] in, out; returns the
// radii (0 for a sphere left without items).
std::vector<double> shrinkByHandingOver(const TriangleItems& items, const std::vector<Vec3>& centres,
                                        const std::vector<char>& open, std::vector<std::uint32_t>& cluster) {
  constexpr int kRounds = 8;
  const std::size_t k = centres.size(), n = cluster.size();
  std::vector<double> far2(k, 0.0), radius(k);
  auto fitRadii = [&] {
    far2 = farthestByCluster(items, cluster, centres);
    for (std::size_t c = 0; c < k; ++c) radius[c] = std::sqrt(far2[c]);
  };
  fitRadii();
  // Candidates, once: the open spheres that hold the item at the first radii, and its own. Radii only shrink, so
  // no other sphere can hold it in a later round. (A ball holding the item holds its centroid.)
  const HolderLists held = ballsHolding(
      items, cluster, k, centres, far2, [&](std::size_t c) { return open[c] != 0; }, [](std::size_t) { return true; },
      [&](std::size_t item, std::uint32_t c) { return farthest2(items.corners[item], centres[c]) <= far2[c]; });
  const unsigned threads = held.threads;
  const auto& candidates = held.list;
  const auto& starts = held.start;
  // Rounds: each item decides from the previous round's radii and writes its own entry. Its choice is the least
  // (room, index) over its own sphere and its candidates; when none of their radii changed since its last choice,
  // which was its own, the same choice comes again and the item is passed over (most are, after the first rounds).
  std::vector<char> changed(k, 1);
  for (int round = 0; round < kRounds; ++round) {
    std::vector<char> moved(threads, 0);
    detail::runParallel(threads, [&](unsigned t) {
      const std::size_t first = n * t / threads;
      for (std::size_t item = first; item < n * (t + 1) / threads; ++item) {
        const TrianglePiece& corners = items.corners[item];
        const std::uint32_t own = cluster[item];
        bool again = changed[own] != 0;
        for (std::uint32_t j = starts[t][item - first]; j < starts[t][item - first + 1] && !again; ++j)
          again = changed[candidates[t][j]] != 0;
        if (!again) continue;
        std::uint32_t best = own;
        double room = std::sqrt(farthest2(corners, centres[own])) - radius[own];
        for (std::uint32_t j = starts[t][item - first]; j < starts[t][item - first + 1]; ++j) {
          const std::uint32_t s = candidates[t][j];
          const double need = std::sqrt(farthest2(corners, centres[s])) - radius[s];
          if (need < room || (need == room && s < best)) {
            room = need;
            best = s;
          }
        }
        moved[t] = moved[t] || best != own;
        cluster[item] = best;
      }
    });
    if (std::find(moved.begin(), moved.end(), 1) == moved.end()) break;
    const std::vector<double> before = radius;
    fitRadii();
    for (std::size_t c = 0; c < k; ++c) changed[c] = radius[c] != before[c] ? 1 : 0;
  }
  return radius;
}

// Thin patches. A sphere whose centre lies less than kThinDepth of its radius below the surface, whose corners lie
// within kThinFlat of its radius of a plane and whose items face both ways (their vector areas sum to less than
// kTwoSided of their area) is a patch of a plate, its ball sticking out on both sides. Such a patch holds the most
// for its volume when the patches are compact and alike, as a hexagonal tiling's are: its volume outside grows with
// R^3 while what it covers grows with R^2. The tree's halvings leave rectangles of 1:1 and 2:1 (a grid of them is a
// fixed point of Lloyd's rounds), and items as large as a quarter of the radius leave corners overhanging the patch.
// So the thin patches are settled: their items halved (continuing their triangle's halving) to at most kThinCoarse
// of the radius; each patch's site (its items' centroid by area) moved once by up to kJitter of its reach in a
// direction fixed by its index; then Lloyd's rounds, up to kSettleRounds and until fewer than 1 / kSettleStop of the
// thin items move in a round: each item goes to the nearest site among the thin patches whose reach (farthest corner
// from the site) holds its centroid, and the sites move to the new centroids; each centre then goes to its patch's
// smallest enclosing ball (centreThinPatches), and the items that reach beyond kThinRim of the new radius are halved
// further to kThinFine of it. Lloyd's rounds make the patches compact on average, but the radius is set by the farthest
// corner: kCentreRounds k-centre rounds on the fine items follow (centreRounds: each item to the patch its farthest
// corner is nearest to, each centre to its patch's smallest enclosing ball), then the handing over gives the rim's
// pieces to the neighbour that holds them deeper. Every radius still reaches every corner of its items (the handing
// over fits it), so coverage holds as before. Chosen on thin_bench's plate-0.005 (bench/results/thin_tightness.md):
// finer pieces (0.3 and 0.12 of R) gave 5% less volume at three to five times the build. With the k-centre rounds
// (2026-11-28), a depth of 0.5 R and a flatness of 0.4 R also take the patches of plates about as thick as the spheres
// are wide (plate-0.015-mixed and cap-shell-0.01 at 500 spheres: 27% and 16% less outside) and move the shared meshes
// by under 1% (with Badoiu and Clarkson's steps for the centres and no k-centre rounds, a depth of 0.5 R had cost them
// 2 to 6%); 10 k-centre rounds instead of 5 gain under 1%. For the build (issue 17's 100 ms): 4 k-centre rounds instead
// of 5, and Lloyd's rounds stopped once under 1% of the items move (plate-0.015-mixed at 500 spheres: 9 rounds instead
// of 16; the seven dropped had moved 0.55 to 0.12% of the items) changed the outside volume by -3 to +1.7% on
// thin_bench's 28 rows (no row crossed its target either way) and took 10 to 35% off the builds. Candidates for an item
// are found among the patches whose ball of kReachMargin times their reach holds it (once after the jitter for Lloyd's
// rounds, once before the k-centre rounds). Without the two sides the flat ends of a cylinder 0.05 thick were taken too
// and settled onto their face (their centres at the surface): 16% more outside at 500 spheres.
constexpr double kThinDepth = 0.5;
constexpr double kThinFlat = 0.4;
constexpr double kTwoSided = 0.5;
constexpr double kThinCoarse = 0.6;
constexpr double kThinFine = 0.2;
constexpr double kThinRim = 0.8;
constexpr double kJitter = 0.5;
constexpr int kSettleRounds = 16;
constexpr std::size_t kSettleStop = 100;
constexpr int kCentreRounds = 4;
constexpr double kReachMargin = 1.5;

// A point of the cube [-1/2, 1/2]^3 fixed by c (splitmix64).
Vec3 fixedJitter(std::uint64_t c) {
  double v[3];
  for (double& x : v) {
    std::uint64_t z = (c += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    z ^= z >> 31;
    x = static_cast<double>(z >> 11) * (1.0 / 9007199254740992.0) - 0.5;
  }
  return Vec3(v[0], v[1], v[2]);
}

// The items by cluster, those of the clusters with keep(c) (a counting sort: ascending within a cluster): cluster c's
// items are item[begin[c]] .. item[begin[c + 1] - 1].
struct ItemsByCluster {
  std::vector<std::uint32_t> begin, item;
};

template <class Keep>
ItemsByCluster itemsByCluster(const std::vector<std::uint32_t>& cluster, std::size_t k, Keep&& keep) {
  ItemsByCluster out;
  out.begin.assign(k + 1, 0);
  for (const std::uint32_t c : cluster)
    if (keep(c)) ++out.begin[c + 1];
  for (std::size_t c = 0; c < k; ++c) out.begin[c + 1] += out.begin[c];
  out.item.resize(out.begin[k]);
  std::vector<std::uint32_t> next(out.begin.begin(), out.begin.end() - 1);
  for (std::size_t i = 0; i < cluster.size(); ++i)
    if (keep(cluster[i])) out.item[next[cluster[i]]++] = static_cast<std::uint32_t>(i);
  return out;
}

// The smallest disc holding the points (Welzl's algorithm, iterative, in the order given; the caller shuffles).
struct Disc {
  Eigen::Vector2d c{0.0, 0.0};
  double r2 = -1.0;
  bool holds(const Eigen::Vector2d& p) const { return (p - c).squaredNorm() <= r2 * (1.0 + 1e-12) + 1e-300; }
};

Disc discThrough(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  Disc d;
  d.c = 0.5 * (a + b);
  d.r2 = (a - d.c).squaredNorm();
  return d;
}

// The circle through three points; for (nearly) collinear ones the disc on the farthest pair.
Disc discThrough(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  const Eigen::Vector2d u = b - a, v = c - a;
  const double det = 2.0 * (u.x() * v.y() - u.y() * v.x());
  const double uu = u.squaredNorm(), vv = v.squaredNorm();
  if (std::abs(det) <= 1e-12 * (uu + vv)) {
    Disc best = discThrough(a, b);
    for (const Disc& d : {discThrough(a, c), discThrough(b, c)})
      if (d.r2 > best.r2) best = d;
    return best;
  }
  Disc d;
  d.c = a + Eigen::Vector2d(v.y() * uu - u.y() * vv, u.x() * vv - v.x() * uu) / det;
  d.r2 = (a - d.c).squaredNorm();
  return d;
}

Disc smallestDisc(const Eigen::Vector2d* p, std::size_t count) {
  Disc d;
  for (std::size_t i = 0; i < count; ++i) {
    if (d.holds(p[i])) continue;
    d.c = p[i];
    d.r2 = 0.0;
    for (std::size_t j = 0; j < i; ++j) {
      if (d.holds(p[j])) continue;
      d = discThrough(p[i], p[j]);
      for (std::size_t m = 0; m < j; ++m)
        if (!d.holds(p[m])) d = discThrough(p[i], p[j], p[m]);
    }
  }
  return d;
}

// A thin patch's plane (the least principal axis of its corners as normal) and how far its corners reached from its
// centre at the last centring (0 before the first).
struct PatchFrame {
  Vec3 mean = Vec3::Zero(), u = Vec3::UnitX(), w = Vec3::UnitY(), normal = Vec3::UnitZ();
  double reach2 = 0.0;
  bool set = false;
};

constexpr double kOuterShare = 0.8;  // squared: corners beyond 0.89 of the last reach go to Welzl first

// Each thin patch's centre: in its plane, the centre of the smallest disc holding its corners; across it, midway
// between the nearest and farthest corner. Nearly the smallest enclosing ball of a patch of a thin part, found
// exactly, where Badoiu and Clarkson's steps close in slowly. The disc is first found for the corners beyond
// kOuterShare of the last reach; the others lie within a known distance of the old centre, so when the disc holds that
// ball they are inside (the projection only shortens distances), else every corner is taken.
void centreThinPatches(const TriangleItems& items, const std::vector<char>& thin,
                       const std::vector<std::uint32_t>& cluster, std::vector<PatchFrame>& frames,
                       std::vector<Vec3>& centres) {
  const std::size_t k = centres.size(), n = cluster.size();
  const ItemsByCluster sorted = itemsByCluster(cluster, k, [&](std::uint32_t c) { return thin[c] != 0; });
  const std::vector<std::uint32_t>& begin = sorted.begin;
  const std::vector<std::uint32_t>& members = sorted.item;
  const unsigned threads = detail::threadsFor(n, 0, 4096);
  detail::runParallel(threads, [&](unsigned t) {
    std::vector<Eigen::Vector2d> flat;
    for (std::size_t c = k * t / threads; c < k * (t + 1) / threads; ++c) {
      if (!thin[c] || begin[c] == begin[c + 1]) continue;
      PatchFrame& f = frames[c];
      if (!f.set) {
        Vec3 mean = Vec3::Zero();
        Eigen::Matrix3d moments = Eigen::Matrix3d::Zero();
        for (std::uint32_t j = begin[c]; j < begin[c + 1]; ++j)
          for (const Vec3& v : items.corners[members[j]]) {
            mean += v;
            moments.noalias() += v * v.transpose();
          }
        const double m = 3.0 * (begin[c + 1] - begin[c]);
        mean /= m;
        const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> axes(moments / m - mean * mean.transpose());
        if (axes.info() != Eigen::Success) continue;
        f.mean = mean;
        f.normal = axes.eigenvectors().col(0);
        f.w = axes.eigenvectors().col(1);
        f.u = axes.eigenvectors().col(2);
        f.set = true;
      }
      const Vec3 old = centres[c];
      const Eigen::Vector2d start((old - f.mean).dot(f.u), (old - f.mean).dot(f.w));
      auto project = [&](const Vec3& v) { return Eigen::Vector2d((v - f.mean).dot(f.u), (v - f.mean).dot(f.w)); };
      double lo = kInfinity, hi = -kInfinity, inner2 = 0.0;
      const double threshold = kOuterShare * f.reach2;
      flat.clear();
      for (std::uint32_t j = begin[c]; j < begin[c + 1]; ++j)
        for (const Vec3& v : items.corners[members[j]]) {
          const double across = (v - f.mean).dot(f.normal);
          lo = std::min(lo, across);
          hi = std::max(hi, across);
          const double d2 = (v - old).squaredNorm();
          if (d2 >= threshold)
            flat.push_back(project(v));
          else
            inner2 = std::max(inner2, d2);
        }
      std::uint64_t state = 0x9e3779b97f4a7c15ull * (c + 1);
      auto disc = [&] {
        // A fixed shuffle: Welzl's expected linear time needs a random order; the items come in space order.
        for (std::size_t i = flat.size(); i > 1; --i) {
          state ^= state << 13;
          state ^= state >> 7;
          state ^= state << 17;
          std::swap(flat[i - 1], flat[static_cast<std::size_t>(((state >> 32) * i) >> 32)]);  // i < 2^32
        }
        return smallestDisc(flat.data(), flat.size());
      };
      Disc d = disc();
      if (inner2 > 0.0 && (d.c - start).norm() + std::sqrt(inner2) > std::sqrt(std::max(d.r2, 0.0))) {
        flat.clear();
        for (std::uint32_t j = begin[c]; j < begin[c + 1]; ++j)
          for (const Vec3& v : items.corners[members[j]]) flat.push_back(project(v));
        d = disc();
      }
      f.reach2 = d.r2;
      centres[c] = f.mean + d.c.x() * f.u + d.c.y() * f.w + 0.5 * (lo + hi) * f.normal;
    }
  });
}

// The thin patches near each thin item (for Lloyd's and the k-centre rounds): those with use(c) whose ball about
// centre[c], kReachMargin times sqrt(reach2[c]), holds the item's centroid.
template <class Use>
HolderLists thinCandidates(const TriangleItems& items, const std::vector<char>& thin,
                           const std::vector<std::uint32_t>& cluster, const std::vector<Vec3>& centre,
                           const std::vector<double>& reach2, Use&& use) {
  std::vector<double> around(centre.size());
  for (std::size_t c = 0; c < centre.size(); ++c) around[c] = kReachMargin * kReachMargin * reach2[c];
  return ballsHolding(
      items, cluster, centre.size(), centre, around, use, [&](std::size_t item) { return thin[cluster[item]] != 0; },
      [](std::size_t, std::uint32_t) { return true; });
}

// One round of reassignment over the thin items: each goes to whichever of its own patch (at own(item)) and its
// candidates (at candidate(item, s, nearest so far), infinity for one not admitted) is nearest, the lower index on a
// tie; next[item] out (cluster[item] for the others). Returns how many items moved.
template <class Own, class Candidate>
std::size_t reassign(const HolderLists& held, const std::vector<char>& thin, const std::vector<std::uint32_t>& cluster,
                     std::vector<std::uint32_t>& next, Own&& own, Candidate&& candidate) {
  const std::size_t n = cluster.size();
  std::vector<std::size_t> moved(held.threads, 0);
  detail::runParallel(held.threads, [&](unsigned t) {
    const std::size_t first = n * t / held.threads;
    for (std::size_t item = first; item < n * (t + 1) / held.threads; ++item) {
      const std::uint32_t mine = cluster[item];
      next[item] = mine;
      if (!thin[mine]) continue;
      std::uint32_t best = mine;
      double nearest = own(item);
      for (std::uint32_t j = held.start[t][item - first]; j < held.start[t][item - first + 1]; ++j) {
        const std::uint32_t s = held.list[t][j];
        const double d2 = candidate(item, s, nearest);
        if (d2 < nearest || (d2 == nearest && s < best)) {
          nearest = d2;
          best = s;
        }
      }
      moved[t] += best != mine ? 1 : 0;
      next[item] = best;
    }
  });
  return std::accumulate(moved.begin(), moved.end(), std::size_t{0});
}

// Lloyd's rounds over the thin patches, then each thin centre to its patch's smallest enclosing ball (see kThinDepth):
// cluster[item] in, out. Each round is computed from the previous one, so the result does not depend on the threads.
void settleThinPatches(const TriangleItems& items, const std::vector<char>& thin, std::vector<Vec3>& centres,
                       std::vector<std::uint32_t>& cluster) {
  const std::size_t k = centres.size(), n = cluster.size();
  std::vector<double> area(n), weight(k);
  for (std::size_t i = 0; i < n; ++i) {
    const TrianglePiece& c = items.corners[i];
    area[i] = 0.5 * (c[1] - c[0]).cross(c[2] - c[0]).norm() + std::numeric_limits<double>::min();
  }
  std::vector<Vec3> site(k);
  auto moveSites = [&] {
    std::fill(site.begin(), site.end(), Vec3::Zero());
    std::fill(weight.begin(), weight.end(), 0.0);
    byCluster(cluster, k, [&](std::size_t i) {
      site[cluster[i]] += area[i] * items.centroid[i];
      weight[cluster[i]] += area[i];
    });
    for (std::size_t c = 0; c < k; ++c) site[c] = weight[c] > 0.0 ? Vec3(site[c] / weight[c]) : centres[c];
  };
  moveSites();
  std::vector<double> reach2 = farthestByCluster(items, cluster, site);
  for (std::size_t c = 0; c < k; ++c)
    if (thin[c]) site[c] += kJitter * std::sqrt(reach2[c]) * fixedJitter(c);
  // Candidates, once: the thin patches whose ball about the moved site, kReachMargin times its reach, holds the
  // item's centroid (the sites move little after the first round).
  const HolderLists held =
      thinCandidates(items, thin, cluster, site, reach2, [&](std::size_t c) { return thin[c] && weight[c] > 0.0; });
  std::vector<std::uint32_t> next(n);
  const std::size_t settling = static_cast<std::size_t>(
      std::count_if(cluster.begin(), cluster.end(), [&](std::uint32_t c) { return thin[c] != 0; }));
  for (int round = 0; round < kSettleRounds; ++round) {
    reach2 = farthestByCluster(items, cluster, site);
    const std::size_t moved = reassign(
        held, thin, cluster, next,
        [&](std::size_t item) { return (items.centroid[item] - site[cluster[item]]).squaredNorm(); },
        [&](std::size_t item, std::uint32_t s, double) {
          const double d2 = (items.centroid[item] - site[s]).squaredNorm();
          return weight[s] > 0.0 && d2 <= reach2[s] ? d2 : kInfinity;
        });
    cluster.swap(next);
    moveSites();
    if (moved * kSettleStop <= settling) break;
  }
  // Each centre to its patch's smallest enclosing ball, nearly (centreThinPatches).
  for (std::size_t c = 0; c < k; ++c)
    if (thin[c] && weight[c] > 0.0) centres[c] = site[c];
  std::vector<PatchFrame> frames(k);
  centreThinPatches(items, thin, cluster, frames, centres);
}

// k-centre rounds over the thin patches' (fine) items, up to kCentreRounds: each item goes to the patch, among those
// whose ball of kReachMargin times its reach holds its centroid, that its farthest corner is nearest to, and each
// centre to its patch's smallest enclosing ball (centreThinPatches). Where Lloyd's rounds make the patches compact
// on average, these lower the largest distance, which sets the radius. Each round is computed from the previous one.
void centreRounds(const TriangleItems& items, const std::vector<char>& thin, std::vector<Vec3>& centres,
                  std::vector<std::uint32_t>& cluster) {
  const std::size_t k = centres.size(), n = cluster.size();
  const std::vector<double> reach2 = farthestByCluster(items, cluster, centres);
  const HolderLists held =
      thinCandidates(items, thin, cluster, centres, reach2, [&](std::size_t c) { return thin[c] && reach2[c] > 0.0; });
  // Each item's reach from its centroid: a patch whose centre lies farther than the best distance so far plus that
  // reach cannot be nearer, and is passed over without its three corners (the choice is the same).
  std::vector<double> spread(n, 0.0);
  for (std::size_t i = 0; i < n; ++i)
    if (thin[cluster[i]]) spread[i] = std::sqrt(farthest2(items.corners[i], items.centroid[i]));
  std::vector<std::uint32_t> next(n);
  std::vector<PatchFrame> frames(k);
  for (int round = 0; round < kCentreRounds; ++round) {
    const bool moved = reassign(
        held, thin, cluster, next,
        [&](std::size_t item) { return farthest2(items.corners[item], centres[cluster[item]]); },
        [&](std::size_t item, std::uint32_t s, double nearest) {
          const double gap = std::sqrt(nearest) + spread[item];
          if ((items.centroid[item] - centres[s]).squaredNorm() > gap * gap * (1.0 + 1e-12)) return kInfinity;
          return farthest2(items.corners[item], centres[s]);
        });
    cluster.swap(next);
    if (!moved && round > 0) break;
    centreThinPatches(items, thin, cluster, frames, centres);
  }
}

// Which leaves are thin patches (kThinDepth, kThinFlat, kTwoSided), and their radii (farthest corner from the centre).
std::vector<char> thinPatches(const TriangleItems& items, const std::vector<std::uint32_t>& cluster,
                              const std::vector<Vec3>& centres, const std::vector<char>& open,
                              const std::vector<double>& depth, std::vector<double>& radius) {
  const std::size_t k = centres.size();
  radius = farthestByCluster(items, cluster, centres);
  std::vector<Eigen::Matrix3d> moments(k, Eigen::Matrix3d::Zero());
  std::vector<Vec3> sum(k, Vec3::Zero());
  std::vector<Vec3> facing(k, Vec3::Zero());  // the items' summed vector areas
  std::vector<double> corners(k, 0.0), area(k, 0.0);
  for (std::size_t item = 0; item < cluster.size(); ++item) {
    const std::uint32_t c = cluster[item];
    const TrianglePiece& t = items.corners[item];
    const Vec3 vectorArea = 0.5 * (t[1] - t[0]).cross(t[2] - t[0]);
    facing[c] += vectorArea;
    area[c] += vectorArea.norm();
    for (const Vec3& v : t) {
      const Vec3 q = v - centres[c];
      moments[c].noalias() += q * q.transpose();
      sum[c] += q;
    }
    corners[c] += 3.0;
  }
  std::vector<char> thin(k, 0);
  for (std::size_t c = 0; c < k; ++c) {
    radius[c] = std::sqrt(radius[c]);
    if (!open[c] || !(depth[c] < kThinDepth * radius[c]) || corners[c] == 0.0) continue;
    if (!(facing[c].norm() < kTwoSided * area[c])) continue;  // one side only: a flat face of a thick part
    const Vec3 mean = sum[c] / corners[c];
    const Eigen::Matrix3d covariance = moments[c] / corners[c] - mean * mean.transpose();
    if (!covariance.allFinite()) continue;
    const double least =
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(covariance, Eigen::EigenvaluesOnly).eigenvalues()(0);
    thin[c] = least < kThinFlat * kThinFlat * radius[c] * radius[c];
  }
  return thin;
}

// The items with the thin patches settled (settleThinPatches, kThinCoarse before, kThinFine at the rim after);
// cluster and centres follow. Empty when no leaf is thin.
TriangleItems settleThin(const TriangleItems& treeItems, const std::vector<char>& open,
                         const std::vector<double>& depth, std::vector<Vec3>& centres,
                         std::vector<std::uint32_t>& cluster) {
  std::vector<double> radius;
  const std::vector<char> thin = thinPatches(treeItems, cluster, centres, open, depth, radius);
  if (std::find(thin.begin(), thin.end(), 1) == thin.end()) return {};
  const TriangleItems coarse = splitItems(
      treeItems,
      [&](std::size_t item, const TrianglePiece& piece) {
        const double edge = kThinCoarse * radius[cluster[item]];
        return thin[cluster[item]] && longestEdge2(piece) > edge * edge;
      },
      cluster);
  settleThinPatches(coarse, thin, centres, cluster);
  radius = farthestByCluster(coarse, cluster, centres);
  // Only pieces reaching beyond the rim are halved on: the fine pieces lie along the patch's edge.
  TriangleItems fine = splitItems(
      coarse,
      [&](std::size_t item, const TrianglePiece& piece) {
        const std::uint32_t c = cluster[item];
        return thin[c] && farthest2(piece, centres[c]) > kThinRim * kThinRim * radius[c] &&
               longestEdge2(piece) > kThinFine * kThinFine * radius[c];
      },
      cluster);
  centreRounds(fine, thin, centres, cluster);
  return fine;
}

// The leaves as spheres fitted here (a split triangle's pieces may sit in several leaves): in the order of the
// tree (by where each leaf's range begins, which does not depend on the threads), the items handed over to the
// sphere they lie deepest in (shrinkByHandingOver), each sphere listing its items' triangles (ascending, once)
// with the radius reaching its items' corners; a sphere left without items is dropped. A point is labelled
// with the sphere of its triangle's first piece.
std::uint32_t listLeaves(const std::vector<std::vector<Leaf>>& groups, const std::vector<std::uint32_t>& order,
                         const TriangleItems& treeItems, std::vector<std::uint32_t>& labels, std::vector<Vec3>& centres,
                         ClusterLists& lists) {
  std::vector<const Leaf*> leaves;
  for (const std::vector<Leaf>& group : groups)
    for (const Leaf& leaf : group) leaves.push_back(&leaf);
  std::sort(leaves.begin(), leaves.end(), [](const Leaf* a, const Leaf* b) { return a->range.begin < b->range.begin; });
  std::vector<std::uint32_t> cluster(order.size(), 0);
  std::vector<Vec3> leafCentres;
  std::vector<char> open;
  for (const Leaf* leaf : leaves) {
    for (std::uint32_t i = leaf->range.begin; i < leaf->range.end; ++i)
      cluster[order[i]] = static_cast<std::uint32_t>(leafCentres.size());
    leafCentres.push_back(leaf->centre);
    open.push_back(leaf->passed);
  }
  std::vector<double> depth;
  for (const Leaf* leaf : leaves) depth.push_back(leaf->depth);
  const TriangleItems settled = settleThin(treeItems, open, depth, leafCentres, cluster);
  const TriangleItems& items = settled.triangle.empty() ? treeItems : settled;
  const std::vector<double> radii = shrinkByHandingOver(items, leafCentres, open, cluster);
  // Items by sphere (a counting sort), the spheres without items dropped.
  const ItemsByCluster sorted = itemsByCluster(cluster, leafCentres.size(), [](std::uint32_t) { return true; });
  const std::vector<std::uint32_t>& begin = sorted.begin;
  const std::vector<std::uint32_t>& members = sorted.item;
  std::vector<std::uint32_t> renumber(leafCentres.size(), kNone);
  lists = ClusterLists{};
  lists.offsets.push_back(0);
  centres.clear();
  std::vector<std::uint32_t> listed;
  for (std::size_t c = 0; c < leafCentres.size(); ++c) {
    if (begin[c] == begin[c + 1]) continue;
    renumber[c] = static_cast<std::uint32_t>(centres.size());
    listed.clear();
    for (std::uint32_t j = begin[c]; j < begin[c + 1]; ++j) listed.push_back(items.triangle[members[j]]);
    std::sort(listed.begin(), listed.end());
    listed.erase(std::unique(listed.begin(), listed.end()), listed.end());
    lists.triangles.insert(lists.triangles.end(), listed.begin(), listed.end());
    lists.offsets.push_back(static_cast<std::uint32_t>(lists.triangles.size()));
    lists.radii.push_back(radii[c]);
    centres.push_back(leafCentres[c]);
  }
  for (std::size_t i = 0; i < items.itemOfPoint.size(); ++i) labels[i] = renumber[cluster[items.itemOfPoint[i]]];
  return static_cast<std::uint32_t>(centres.size());
}

}  // namespace

SurfaceDistance::SurfaceDistance(const TriangleMesh& mesh) : mesh_(mesh) {
  const std::size_t n = mesh.size();
  if (n == 0) return;
  // Triangles in Morton order of their centroids, runs of kLeaf per leaf, and a complete binary tree
  // over the leaves in heap layout (children of i at 2i + 1 and 2i + 2): built in O(n log n) by one
  // sort, cheap next to the median-split tree since it is rebuilt on every build(d).
  const Eigen::AlignedBox3d box = mesh.bounds();
  const Vec3 scale = (kMortonMax / box.sizes().array().max(1e-300)).matrix();
  std::vector<std::pair<std::uint64_t, std::uint32_t>> keyed(n);
  for (std::size_t t = 0; t < n; ++t) {
    const Vec3 q = (mesh.centroid(t) - box.min()).cwiseProduct(scale).cwiseMax(0.0).cwiseMin(kMortonMax);
    keyed[t] = {mortonCode(q), static_cast<std::uint32_t>(t)};
  }
  std::sort(keyed.begin(), keyed.end());
  order_.resize(n);
  corners_.resize(9 * n);
  planes_.resize(5 * n);
  // The bound's own rounding: n . p for coordinates up to the box's magnitude.
  const double rounding = 1e-14 * std::max(box.min().cwiseAbs().maxCoeff(), box.max().cwiseAbs().maxCoeff());
  for (std::size_t t = 0; t < n; ++t) {
    order_[t] = keyed[t].second;
    for (int v = 0; v < 3; ++v)
      for (int k = 0; k < 3; ++k) corners_[9 * t + 3 * v + k] = mesh.vertex(order_[t], v)[k];
    // The mesh's unit face normal, the offset and how far the corners lie off that plane (their rounding):
    // |n . p - offset| less that is a lower bound of the distance from p to the triangle (zero normal for a
    // degenerate one).
    const Vec3 &a = mesh.vertex(order_[t], 0), &b = mesh.vertex(order_[t], 1), &c = mesh.vertex(order_[t], 2);
    const Vec3& normal = mesh.normals[order_[t]];
    const double offset = normal.dot(a);
    double off = 0.0;
    for (const Vec3* v : {&a, &b, &c}) off = std::max(off, std::abs(normal.dot(*v) - offset));
    double* plane = planes_.data() + 5 * t;
    plane[0] = normal.x();
    plane[1] = normal.y();
    plane[2] = normal.z();
    plane[3] = offset;
    plane[4] = off * (1.0 + 1e-9) + rounding;
  }
  const std::size_t leaves = (n + kLeaf - 1) / kLeaf;
  leaves_ = 1;
  while (leaves_ < leaves) leaves_ <<= 1;
  boxes_.assign(2 * leaves_ - 1, Box{});
  for (std::size_t l = 0; l < leaves; ++l) {
    Box& b = boxes_[leaves_ - 1 + l];
    for (std::size_t i = l * kLeaf; i < std::min(n, (l + 1) * kLeaf); ++i)
      for (int v = 0; v < 3; ++v)
        for (int k = 0; k < 3; ++k) {
          const double x = corners_[9 * i + 3 * v + k];
          b.lo[k] = std::min(b.lo[k], x);
          b.hi[k] = std::max(b.hi[k], x);
        }
  }
  for (std::size_t i = leaves_ - 1; i-- > 0;)
    for (int k = 0; k < 3; ++k) {
      boxes_[i].lo[k] = std::min(boxes_[2 * i + 1].lo[k], boxes_[2 * i + 2].lo[k]);
      boxes_[i].hi[k] = std::max(boxes_[2 * i + 1].hi[k], boxes_[2 * i + 2].hi[k]);
    }
}

double SurfaceDistance::signedDistance(const Vec3& p, double bound) const {
  if (boxes_.empty()) return std::numeric_limits<double>::infinity();
  // Pruned at the bound (a little beyond it, against rounding); nothing within it: +bound.
  double best = std::isfinite(bound) ? bound * bound * (1.0 + 1e-9) + 1e-300 : std::numeric_limits<double>::infinity();
  std::uint32_t bestTriangle = kNone;
  Vec3 bestPoint = p;
  struct Item {
    std::size_t index;
    double distance2;  // from p to the node's box, computed when it was pushed
  };
  Item stack[64];  // the tree is complete: depth log2(leaves) < 64
  int top = 0;
  stack[top++] = {0, boxDistance2(p, boxes_[0].lo, boxes_[0].hi)};
  const std::size_t n = order_.size();
  while (top > 0) {
    const Item item = stack[--top];
    const std::size_t index = item.index;
    if (item.distance2 >= best) continue;
    if (index >= leaves_ - 1) {
      const std::size_t leaf = index - (leaves_ - 1);
      for (std::size_t i = leaf * kLeaf; i < std::min(n, (leaf + 1) * kLeaf); ++i) {
        // The plane first: a triangle whose plane is farther than the best so far cannot win (the margin is d2's
        // rounding, so the answer stays the one of testing every triangle).
        const double* pl = planes_.data() + 5 * i;
        const double across = std::abs(pl[0] * p.x() + pl[1] * p.y() + pl[2] * p.z() - pl[3]) - pl[4];
        if (across > 0.0 && across * across > best * (1.0 + 1e-9)) continue;
        const double* c = corners_.data() + 9 * i;
        const Vec3 q =
            closestPointOnTriangle(p, Vec3(c[0], c[1], c[2]), Vec3(c[3], c[4], c[5]), Vec3(c[6], c[7], c[8]));
        const double d2 = (q - p).squaredNorm();
        if (d2 < best) {
          best = d2;
          bestTriangle = order_[i];
          bestPoint = q;
        }
      }
      continue;
    }
    const std::size_t left = 2 * index + 1, right = left + 1;
    const double dl = boxDistance2(p, boxes_[left].lo, boxes_[left].hi);
    const double dr = boxDistance2(p, boxes_[right].lo, boxes_[right].hi);
    if (dl <= dr) {  // nearer child on top
      if (dr < best) stack[top++] = {right, dr};
      if (dl < best) stack[top++] = {left, dl};
    } else {
      if (dl < best) stack[top++] = {left, dl};
      if (dr < best) stack[top++] = {right, dr};
    }
  }
  if (bestTriangle == kNone) return bound;
  const double distance = std::sqrt(best);
  return (p - bestPoint).dot(mesh_.normals[bestTriangle]) > 0.0 ? -distance : distance;
}

TightClustering::TightClustering(double pieceEdge) : pieceEdge_(pieceEdge) {
  requireNonNegative(pieceEdge, "piece edge");
}

std::uint32_t TightClustering::cluster(const std::vector<Vec3>& points, double d,
                                       std::vector<std::uint32_t>& labels) const {
  requireNonNegative(d, "clustering distance");
  const std::size_t n = points.size();
  labels.assign(n, 0);
  if (n == 0) return 0;
  if (n >= kNone) throw InvalidParameter("TightClustering: too many points");
  std::vector<std::uint32_t> items = identity(n);
  std::vector<std::uint32_t> clusterOf(n, 0);
  std::uint32_t clusters = 0;
  const double r2 = 0.25 * d * d;
  std::vector<Range> stack{{0, static_cast<std::uint32_t>(n)}};
  while (!stack.empty()) {
    const Range r = stack.back();
    stack.pop_back();
    if (r.end - r.begin == 1 || squaredSpread(points, items, r) <= r2) {
      for (std::uint32_t i = r.begin; i < r.end; ++i) clusterOf[items[i]] = clusters;
      ++clusters;
      continue;
    }
    const std::uint32_t mid = splitAtMean(items, r.begin, r.end, points.data(), false);
    stack.push_back({mid, r.end});
    stack.push_back({r.begin, mid});
  }
  return labelPoints(clusterOf, identity(n), clusters, labels, nullptr);
}

std::uint32_t TightClustering::clusterMesh(const TriangleMesh& mesh, const std::vector<Vec3>& points,
                                           const std::vector<std::uint32_t>& wrapped, double d,
                                           std::vector<std::uint32_t>& labels, std::vector<Vec3>& centres,
                                           ClusterLists* lists) const {
  requireNonNegative(d, "clustering distance");
  centres.clear();
  if (lists) *lists = ClusterLists{};
  const std::size_t n = points.size();
  labels.assign(n, 0);
  if (n == 0) return 0;
  requireWrapped(mesh, n, wrapped);
  const TriangleItems whole = gatherItems(mesh, points, wrapped);
  if (lists == nullptr) {  // the caller fits the spheres: whole triangles, the leaves as they are
    PatchTree tree(mesh, whole, d);
    return labelLeaves(tree.leaves(), tree.order(), whole, labels, centres);
  }
  const double maxEdge = pieceEdge_ * mesh.diagonal();
  const TriangleItems items = hasLongItem(whole, maxEdge) ? splitLongItems(whole, maxEdge) : TriangleItems{};
  const TriangleItems& use = items.triangle.empty() ? whole : items;
  PatchTree tree(mesh, use, d);
  return listLeaves(tree.leaves(), tree.order(), use, labels, centres, *lists);
}

}  // namespace clod_haptics
