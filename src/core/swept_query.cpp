#include "clod_haptics/core/swept_query.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "clod_haptics/core/contact.h"
#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/mesh_box_tree.h"
#include "simd/cell_scan_avx2.h"
#include "simd/dispatch.h"
#include "simd/node_filter_avx2.h"
#include "simd/record_filter_avx2.h"
#include "wide_box_tree.h"

namespace clod_haptics {
namespace {

constexpr double kNever = std::numeric_limits<double>::infinity();

#if defined(CLOD_PACKET_AVX2)
// The triangles held[0, n) (n at most 4) through the records' ball and plane bounds in AVX2, looser than the scalar
// ones, over the part of the sweep up to end (the rest is the sweep's own); test(t) for each one kept, in order.
template <class RecordOf, class Test>
inline void filterFour(const std::uint32_t* held, int n, double end, detail::RecordFilterSweep& sweep,
                       const RecordOf& recordOf, const Test& test) {
  const double* record[4];
  for (int k = 0; k < 4; ++k) record[k] = recordOf(held[std::min(k, n - 1)]);
  sweep.end = end;
  const unsigned keep = detail::recordFilterAvx2(record, sweep) & ((1u << n) - 1u);
  for (int k = 0; k < n; ++k)
    if (keep & (1u << k)) test(held[k]);
}
#endif

// First t in [0, 1] at which the centre a + t d enters the sphere of radius R around v, the centre
// starting outside it (m = a - v). C / (-B + sqrt(disc)) is the smaller root without cancellation.
inline double sphereEntry(const Vec3& m, const Vec3& d, double dd, double R) {
  const double B = m.dot(d);
  if (!(B < 0.0)) return kNever;  // moving away from v, or not at all
  const double C = m.squaredNorm() - R * R;
  const double disc = B * B - dd * C;
  if (disc < 0.0) return kNever;
  return std::max(0.0, C / (-B + std::sqrt(disc)));
}

// First t at which the centre comes within R of the edge e0 -> e1 through its side (the cylinder
// around the segment); the ends are the vertex spheres' business. |(m + t d) x e|^2 = R^2 |e|^2 is
// A t^2 + 2 B t + C = 0.
inline double edgeEntry(const Vec3& e0, const Vec3& e1, const Vec3& a, const Vec3& d, double dd, double R) {
  const Vec3 e = e1 - e0, m = a - e0;
  const double ee = e.squaredNorm();
  if (!(ee > 0.0)) return kNever;
  const double md = m.dot(e), nd = d.dot(e);
  const double A = ee * dd - nd * nd;
  const double B = ee * m.dot(d) - md * nd;
  const double C = ee * (m.squaredNorm() - R * R) - md * md;
  if (C <= 0.0) {  // already within R of the edge's line: within the side only by rounding, then now
    return B < 0.0 && md >= 0.0 && md <= ee ? 0.0 : kNever;
  }
  if (!(B < 0.0) || !(A > 0.0)) return kNever;  // moving away from the line, or along it
  const double disc = B * B - A * C;
  if (disc < 0.0) return kNever;
  const double t = C / (-B + std::sqrt(disc));
  const double s = md + t * nd;  // along the edge, times ee
  return s >= 0.0 && s <= ee ? t : kNever;
}

// First t at which the centre reaches the plane of the face at distance R with its projection inside
// the triangle (n: the unnormalised normal, nn its squared length).
inline double faceEntry(const Vec3& v0, const Vec3& v1, const Vec3& v2, const Vec3& a, const Vec3& d, double R) {
  const Vec3 n = (v1 - v0).cross(v2 - v0);
  const double nn = n.squaredNorm();
  if (!(nn > 0.0)) return kNever;
  const double s0 = n.dot(a - v0), sd = n.dot(d), Rn = R * std::sqrt(nn);
  double t;
  if (s0 > Rn && sd < 0.0) {
    t = (s0 - Rn) / -sd;
  } else if (s0 < -Rn && sd > 0.0) {
    t = (-s0 - Rn) / sd;
  } else if (std::abs(s0) <= Rn && s0 * sd < 0.0) {
    t = 0.0;  // within R of the plane by rounding only (the caller saw the centre farther): touching now
  } else {
    return kNever;
  }
  if (t > 1.0) return kNever;
  const Vec3 c = a + t * d;
  const bool inside = (v1 - v0).cross(c - v0).dot(n) >= 0.0 && (v2 - v1).cross(c - v1).dot(n) >= 0.0 &&
                      (v0 - v2).cross(c - v2).dot(n) >= 0.0;
  return inside ? t : kNever;
}

// The ball around a triangle the capsule test uses: its centroid and the distance to its farthest corner.
inline void boundingBall(const Vec3& v0, const Vec3& v1, const Vec3& v2, Vec3& c, double& rho) {
  c = (v0 + v1 + v2) * (1.0 / 3.0);
  rho = std::sqrt(std::max({(v0 - c).squaredNorm(), (v1 - c).squaredNorm(), (v2 - c).squaredNorm()}));
}

// Whether the capsule (a -> a + tMax d, radius R) cannot reach the ball (c, rho) around a triangle.
// invdd: 1 / |d|^2, or 0 for a zero-length sweep.
inline bool capsuleMissesBall(const Vec3& c, double rho, const Vec3& a, const Vec3& d, double invdd, double R,
                              double tMax) {
  const double t = std::clamp((c - a).dot(d) * invdd, 0.0, std::min(1.0, tMax));
  const double reach = (rho + R) * (1.0 + 1e-12);
  return (a + t * d - c).squaredNorm() > reach * reach;
}

// Whether the sweep up to tMax stays farther than reach from every point of a triangle that lies within rho of c
// and within thick of the plane through c with unit normal n. Such a point is at least max(0, |s| - thick) from the
// centre across the plane (s: the centre's height over it) and |q - c| - rho along it (q: the centre's projection),
// and the smallest sum of squares over the sweep is at least the sum of the two smallest. It drops the neighbours
// of a contact on a flat or concave surface, which the ball test keeps: a sphere resting on a finely tessellated
// plane has every triangle within r of its footprint inside the ball, and only those under its centre within reach.
inline bool planeBoundMisses(const Vec3& c, double rho, const Vec3& n, double thick, const Vec3& a, const Vec3& d,
                             double reach, double tMax) {
  const double end = std::min(1.0, tMax);
  const Vec3 m = a - c;
  const double s0 = n.dot(m), sd = n.dot(d), s1 = s0 + end * sd;
  const double across = s0 * s1 <= 0.0 ? 0.0 : std::max(0.0, std::min(std::abs(s0), std::abs(s1)) - thick);
  if (across > reach) return true;
  const Vec3 mp = m - s0 * n, dp = d - sd * n;  // the centre's motion projected on the plane
  const double dpp = dp.squaredNorm();
  const double t = dpp > 0.0 ? std::clamp(-mp.dot(dp) / dpp, 0.0, end) : 0.0;
  // The square root only between the two easy cases: a projection within rho (along 0, and across <= reach above)
  // or beyond rho + reach (along > reach) settles without it.
  const double q2 = (mp + t * dp).squaredNorm();
  if (q2 <= rho * rho) return false;
  if (q2 > (rho + reach) * (rho + reach) * (1.0 + 1e-12)) return true;
  const double along = std::sqrt(q2) - rho;
  return across * across + along * along > reach * reach;
}

// sweptSphereTriangle after the capsule test.
bool exactSweep(const Vec3& a, const Vec3& d, double dd, double R, const Vec3& v0, const Vec3& v1, const Vec3& v2,
                double& toi, bool& startInContact, double tMax) {
  // The plane first: a centre that stays farther than R from the triangle's plane, on one side, over the
  // whole piece of the sweep that can still win, is farther than R from the triangle (on refined_elephant a
  // quarter of the proxy's exact tests end here; its neighbours on a curved surface stay within the slab).
  const Vec3 n = (v1 - v0).cross(v2 - v0);
  const double Rn = R * std::sqrt(n.squaredNorm());
  const double s0 = n.dot(a - v0), s1 = s0 + std::min(1.0, tMax) * n.dot(d);
  if ((s0 > Rn && s1 > Rn) || (s0 < -Rn && s1 < -Rn)) return false;
  const Vec3 w = a - closestPointOnTriangle(a, v0, v1, v2);
  const double f2 = w.squaredNorm();
  if (f2 <= R * R) {
    // In contact at a: a hit now only for a point query, a centre on the triangle, or a motion closer.
    startInContact = true;
    toi = 0.0;
    const double onTriangle = 1e-9 * R;  // closer than this the side is rounding: blocked either way
    return dd == 0.0 || f2 <= onTriangle * onTriangle || w.dot(d) < 0.0;
  }
  if (dd == 0.0) return false;
  // Nor before tMax when the centre starts farther from the triangle than R and the length it moves by then: its
  // distance falls by at most that. Beside a sphere nestled in a fine concave patch, most of the triangles within the
  // bounds before are a little farther than R and the sweep up to its best time is short: they end here, not in the
  // seven entry times below.
  const double reach = (R + std::min(1.0, tMax) * std::sqrt(dd)) * (1.0 + 1e-9);
  if (f2 > reach * reach) return false;
  double t = faceEntry(v0, v1, v2, a, d, R);
  // A face contact is the first: before it the centre was farther than R from the plane, so from the triangle.
  if (t <= std::min(1.0, tMax)) {
    startInContact = false;
    toi = t;
    return true;
  }
  t = std::min(t, edgeEntry(v0, v1, a, d, dd, R));
  t = std::min(t, edgeEntry(v1, v2, a, d, dd, R));
  t = std::min(t, edgeEntry(v2, v0, a, d, dd, R));
  t = std::min(t, sphereEntry(a - v0, d, dd, R));
  t = std::min(t, sphereEntry(a - v1, d, dd, R));
  t = std::min(t, sphereEntry(a - v2, d, dd, R));
  if (!(t <= std::min(1.0, tMax))) return false;
  startInContact = false;
  toi = t;
  return true;
}

}  // namespace

bool sweptSphereTriangle(const Vec3& a, const Vec3& d, double R, const Vec3& v0, const Vec3& v1, const Vec3& v2,
                         double& toi, bool& startInContact, double tMax) noexcept {
  const double dd = d.squaredNorm();
  if (!(tMax >= 0.0)) return false;
  Vec3 c;
  double rho;
  boundingBall(v0, v1, v2, c, rho);
  if (capsuleMissesBall(c, rho, a, d, dd > 0.0 ? 1.0 / dd : 0.0, R, tMax)) return false;
  return exactSweep(a, d, dd, R, v0, v1, v2, toi, startInContact, tMax);
}

/**
 * The smallest time of impact so far, ties to the lowest triangle; and the triangles tested lately, by their
 * low bits (a triangle is listed by most of the cells around it, and a sweep meets several): a second test of
 * one would answer the same, as the best time only decreases.
 */
struct SweptSphereQuery::Best {
  double toi = kNever;
  std::int32_t triangle = -1;
  bool start = false;
  std::uint32_t tested = 0;
  double reach = 0.0;  // R with the rounding slack of planeBoundMisses
  double invdd = 0.0;  // 1 / |d|^2 of the sweep (0 for a zero-length one)
  // A plane the sweep starts above (unit normal n, offset: heights n . x - offset): the hint's tangent plane, made on
  // first use (a sweep that tests nothing beyond its bounds pays nothing for it). See below().
  const TriangleMesh* mesh = nullptr;
  std::int32_t hint = -1;
  Vec3 from = Vec3::Zero(), motion = Vec3::Zero();
  double radius = 0.0;
  int plane = 0;  // 0: not made yet, 1: made, -1: none (the hint too far, or touched by the centre)
  Vec3 n = Vec3::Zero();
  double offset = 0.0, startHeight = 0.0, climb = 0.0;  // the centre's height at a, and its change over the sweep
  /** The plane through the hint's point nearest the sweep's start, facing it, when that point lies within 2 R. */
  bool makePlane() {
    plane = -1;
    const std::size_t h = static_cast<std::size_t>(hint);
    const Vec3 w = from - closestPointOnTriangle(from, mesh->vertex(h, 0), mesh->vertex(h, 1), mesh->vertex(h, 2));
    const double len = w.norm();
    if (!(len > 0.0 && len < 2.0 * radius)) return false;
    plane = 1;
    n = w / len;
    offset = n.dot(from - w);
    startHeight = n.dot(from) - offset;
    climb = n.dot(motion);
    return true;
  }
  /** Whether there is a plane: the hint's, made now when not yet tried. */
  bool planeReady() { return hint >= 0 && plane >= 0 && (plane == 1 || makePlane()); }
  /** The height under the plane that lies farther than reach below every centre up to the best time so far. */
  double clearance() const { return startHeight + std::min(0.0, std::min(1.0, toi) * climb) - reach; }
  /**
   * Whether a triangle with these corners lies wholly below the plane by more than reach under the sweep up to the
   * best time so far: then every point of it is farther than R from every centre that can still win (a height
   * difference bounds the distance), and it needs no test. A sphere sliding over a locally convex surface keeps its
   * last contact's tangent plane under it, with every neighbouring triangle below: their own planes, tilted towards
   * the centre, cannot tell that.
   */
  bool below(const Vec3& v0, const Vec3& v1, const Vec3& v2) {
    if (!planeReady()) return false;
    return std::max({n.dot(v0), n.dot(v1), n.dot(v2)}) - offset < clearance();
  }
  /**
   * The same for everything below a node of the tree over the mesh, from its slab and ball (NodeSlab: every vertex
   * within thick of the plane through centre with unit normal m and within radius of centre): the highest point of
   * that ball and slab along n is radius above the centre when the ball's top lies in the slab, else where the
   * slab's face meets the ball (|n . m| thick + |n - (n . m) m| sqrt(radius^2 - thick^2)).
   */
  bool below(const NodeSlab& slab) {
    if (!(slab.radius < std::numeric_limits<double>::infinity()) || !planeReady()) return false;
    // across sqrt(radius^2 - thick^2) as one square root (its rounding within the margin below).
    const double along = n.dot(slab.normal), across2 = (n - along * slab.normal).squaredNorm();
    const double rise =
        std::abs(along) * slab.radius <= slab.thick
            ? slab.radius
            : std::abs(along) * slab.thick +
                  std::sqrt(across2 * std::max(0.0, slab.radius * slab.radius - slab.thick * slab.thick));
    // The slab's normal is unit to rounding: the rise gets a relative margin, the centre's height its own.
    return n.dot(slab.centre) - offset + rise * (1.0 + 1e-9) + 1e-9 * slab.thick < clearance();
  }
  // 256 slots: a slide of a few radii over a fine mesh meets a few hundred triangles; with fewer, most of
  // them came back for a second test (refined_elephant at 2 m/s: 476 tests of 211 triangles with 64 slots).
  static constexpr std::uint32_t kSeen = 256;
  std::uint32_t seen[kSeen];
  Best() { std::fill(seen, seen + kSeen, ~0u); }
  /** Whether triangle t is met for the first time lately (then it is counted as tested, and its test runs). */
  bool admit(std::uint32_t t) {
    std::uint32_t& slot = seen[t & (kSeen - 1)];
    if (slot == t) return false;
    slot = t;
    ++tested;
    return true;
  }
  void offer(std::uint32_t t, double toiT, bool startT) {
    if (toiT < toi || (toiT == toi && static_cast<std::int32_t>(t) < triangle)) {
      toi = toiT;
      triangle = static_cast<std::int32_t>(t);
      start = startT;
    }
  }
};

namespace {

// Largest absolute coordinate of the sweep (the magnitude its rounding is relative to).
double magnitudeOf(const Vec3& a, const Vec3& b) { return std::max(a.cwiseAbs().maxCoeff(), b.cwiseAbs().maxCoeff()); }

// Point, normal and region of a contact at toi (a, d local; the answer in the model frame).
void finish(const TriangleMesh& mesh, const Vec3& a, const Vec3& d, SweptContact& out) {
  const Triangle& tri = mesh.triangles[static_cast<std::size_t>(out.triangle)];
  const Vec3& v0 = mesh.vertices[tri[0]];
  const Vec3& v1 = mesh.vertices[tri[1]];
  const Vec3& v2 = mesh.vertices[tri[2]];
  const Vec3 centre = out.toi >= 1.0 ? Vec3(a + d) : Vec3(a + out.toi * d);
  const Vec3 point = closestPointOnTriangle(centre, v0, v1, v2, &out.region);
  Vec3 normal = centre - point;
  const double len = normal.norm();
  if (len > 0.0) {
    normal /= len;
  } else {  // the centre on the triangle: the face's side the sweep comes from
    normal = mesh.normals[static_cast<std::size_t>(out.triangle)];
    if (normal.dot(d) > 0.0) normal = -normal;
    if (!(normal.squaredNorm() > 0.0)) normal = d.squaredNorm() > 0.0 ? Vec3(-d.normalized()) : Vec3::UnitZ();
  }
  out.centre = mesh.toModel(centre);
  out.point = mesh.toModel(point);
  out.normal = normal;
}

// Whether triangle t blocks the sweep (a -> a + d, local frame, test radius R) at toi = 0, or before the centre has
// moved within; then out is the answer at toi = 0 with that triangle.
bool blockedAtStartBy(const TriangleMesh& mesh, std::size_t t, const Vec3& a, const Vec3& d, double R,
                      SweptContact& out, double within = 0.0) {
  double toi;
  bool start = false;
  if (!sweptSphereTriangle(a, d, R, mesh.vertex(t, 0), mesh.vertex(t, 1), mesh.vertex(t, 2), toi, start)) return false;
  if (toi != 0.0 && !(toi * d.norm() <= within)) return false;
  out = SweptContact{};
  out.trianglesTested = 1;
  out.hit = true;
  out.toi = 0.0;
  out.triangle = static_cast<std::int32_t>(t);
  out.startInContact = start;
  finish(mesh, a, d, out);
  return true;
}

}  // namespace

SweptContact bruteForceSweep(const TriangleMesh& mesh, const Vec3& a, const Vec3& b, double r, std::int32_t hint) {
  SweptContact out;
  if (!validPointer(a, r) || !b.allFinite()) return out;
  const Vec3 la = mesh.toLocal(a), lb = mesh.toLocal(b), d = lb - la;
  const double R = sweptRadiusMargin(r, magnitudeOf(la, lb));
  double best = kNever;
  // Blocked at 0 by the hint: it wins the tie.
  if (hint >= 0 && static_cast<std::size_t>(hint) < mesh.size() &&
      blockedAtStartBy(mesh, static_cast<std::size_t>(hint), la, d, R, out))
    return out;
  for (std::size_t t = 0; t < mesh.size(); ++t) {
    double toi;
    bool start = false;
    ++out.trianglesTested;
    if (sweptSphereTriangle(la, d, R, mesh.vertex(t, 0), mesh.vertex(t, 1), mesh.vertex(t, 2), toi, start, best) &&
        toi < best) {
      best = toi;
      out.triangle = static_cast<std::int32_t>(t);
      out.startInContact = start;
    }
  }
  if (out.triangle < 0) return out;
  out.hit = true;
  out.toi = best;
  finish(mesh, la, d, out);
  return out;
}

SweptSphereQuery::SweptSphereQuery(std::shared_ptr<const TriangleMesh> mesh,
                                   std::shared_ptr<const ClodDetector> detector)
    : mesh_(std::move(mesh)), detector_(std::move(detector)) {
  if (!mesh_) throw InvalidParameter("SweptSphereQuery: null mesh");
  if (detector_ && detector_->mesh() != mesh_) throw InvalidParameter("SweptSphereQuery: detector of another mesh");
  if (detector_ && !detector_->grid().empty()) grid_ = &detector_->grid();
  records_.resize(mesh_->size());
  for (std::size_t t = 0; t < mesh_->size(); ++t) {
    double* rec = records_[t].v;
    const Vec3 &v0 = mesh_->vertex(t, 0), &v1 = mesh_->vertex(t, 1), &v2 = mesh_->vertex(t, 2);
    Vec3 c;
    boundingBall(v0, v1, v2, c, rec[3]);
    // The mesh's unit face normal (zero for a degenerate triangle, whose bound is then the ball's); the thickness
    // measures how far the corners lie off its plane, so its rounding is covered too.
    const Vec3& n = mesh_->normals[t];
    double thick = 0.0;
    for (const Vec3* v : {&v0, &v1, &v2}) thick = std::max(thick, std::abs(n.dot(*v - c)));
    for (int k = 0; k < 3; ++k) {
      rec[k] = c[k];
      rec[4 + k] = n[k];
    }
    rec[7] = thick * (1.0 + 1e-9) + 1e-12 * rec[3];  // its own rounding covered
  }
  // One tree over the mesh, shared: the grid detector's, else the mesh's own when it fits, else built here.
  tree_ = detector_ && detector_->meshTree() ? detector_->meshTree() : meshBoxTreeOf(*mesh_);
  std::vector<std::uint32_t> first;
  smallSubtrees(*tree_, kSmallSubtree, small_, first);
#if defined(CLOD_PACKET_AVX2)
  wide_ = WideBoxTree::build(*tree_, small_, first);  // walked where the CPU runs AVX2 (sweep)
#endif
}

const double* SweptSphereQuery::recordOf(std::uint32_t t) const noexcept { return records_[t].v; }

bool SweptSphereQuery::crowdedAt(const Vec3& local) const noexcept {
  // Most grids have no crowded cell at all: then no lookup.
  if (grid_->largestCell() <= ClodDetector::kTreeAboveEntries) return false;
  const CellGrid::CellRef* ref = grid_->find(grid_->keyOf(local));
  return ref != nullptr && grid_->cell(*ref).count > ClodDetector::kTreeAboveEntries;
}

void SweptSphereQuery::testTriangle(std::uint32_t t, const Vec3& a, const Vec3& d, double R,
                                    Best& best) const noexcept {
  if (!best.admit(t)) return;
  // One record: the ball first (often all a test reads), then the rest.
  const double* rec = recordOf(t);
  if (capsuleMissesBall(Vec3(rec[0], rec[1], rec[2]), rec[3], a, d, best.invdd, R, best.toi)) return;
  testRecord(t, a, d, R, best);
}

void SweptSphereQuery::testRecord(std::uint32_t t, const Vec3& a, const Vec3& d, double R, Best& best) const noexcept {
  const double* rec = recordOf(t);
  const Vec3 c(rec[0], rec[1], rec[2]);
  const double dd = d.squaredNorm();
  if (planeBoundMisses(c, rec[3], Vec3(rec[4], rec[5], rec[6]), rec[7], a, d, best.reach, best.toi)) return;
  const Vec3 &v0 = mesh_->vertex(t, 0), &v1 = mesh_->vertex(t, 1), &v2 = mesh_->vertex(t, 2);
  if (best.below(v0, v1, v2)) return;
  double toi;
  bool start = false;
  if (exactSweep(a, d, dd, R, v0, v1, v2, toi, start, best.toi)) best.offer(t, toi, start);
}

void SweptSphereQuery::sweep(const Vec3& a, const Vec3& b, double r, SweptContact& out,
                             std::int32_t hint) const noexcept {
  out = SweptContact{};
  if (!validPointer(a, r) || !b.allFinite()) return;
  const Vec3 la = mesh_->toLocal(a), lb = mesh_->toLocal(b), d = lb - la;
  const double R = sweptRadiusMargin(r, magnitudeOf(la, lb));
  Best best;
  // The bound's own rounding: relative to R, and to the coordinates it subtracts.
  best.reach = R * (1.0 + 1e-9) + 1e-14 * magnitudeOf(la, lb);
  const double dd = d.squaredNorm();
  best.invdd = dd > 0.0 ? 1.0 / dd : 0.0;
  // A likely first contact tested first: its time bounds the search from the start. Its tangent plane lets the search
  // pass over the triangles wholly below it (Best::below).
  if (hint >= 0 && static_cast<std::size_t>(hint) < mesh_->size()) {
    testTriangle(static_cast<std::uint32_t>(hint), la, d, R, best);
    best.mesh = mesh_.get();
    best.hint = hint;
    best.from = la;
    best.motion = d;
    best.radius = R;
  }
  // Blocked at 0 by the hint: it is the answer (bruteForceSweep's tie rule), nothing comes earlier. Otherwise the
  // grid serves a sweep of up to a few thousand cells; a longer one takes the tree, which skips empty space, and so
  // does one that starts or ends in a crowded cell (triangles far smaller than r, as ClodDetector's point query):
  // there the cell's bounds keep every triangle a few tenths of r beside the path, the tree's only those beside its
  // boxes. The end counts too: a stylus coming from free space into a finely tessellated surface starts in a sparse
  // cell and meets the crowded one (ellipsoid-edge-0.1r at 2 m/s: 1,000 to 1,900 triangles past the bounds of such a
  // sweep, 40 to 160 us a tick).
  if (best.toi > 0.0) {
    if (grid_ != nullptr && r <= grid_->radius() && d.norm() <= 4096.0 * grid_->cellSize() && !crowdedAt(la) &&
        !crowdedAt(la + d))
      sweepGrid(la, d, R, best);
    else if (wide_ && detail::packetAvx2())
      sweepWide(la, d, R, best);
    else
      sweepTree(la, d, R, best);
  }
  out.trianglesTested = best.tested;
  if (best.triangle < 0) return;
  out.hit = true;
  out.toi = best.toi;
  out.triangle = best.triangle;
  out.startInContact = best.start;
  finish(*mesh_, la, d, out);
}

namespace {

// 1 / d per axis, 0 where d is 0 (clipToBox does not read it there): computed once per sweep.
Vec3 reciprocals(const Vec3& d) {
  Vec3 inv = Vec3::Zero();
  for (int k = 0; k < 3; ++k)
    if (d[k] != 0.0) inv[k] = 1.0 / d[k];
  return inv;
}

// Narrows [c0, c1] to the times at which a + t d lies in the box [lo, hi]; false when none. Each slab's times are
// widened by widen for their rounding. inv: reciprocals(d).
bool clipToBox(const Vec3& lo, const Vec3& hi, const Vec3& a, const Vec3& d, const Vec3& inv, double widen, double& c0,
               double& c1) {
  for (int k = 0; k < 3; ++k) {
    if (d[k] == 0.0) {
      if (a[k] < lo[k] || a[k] > hi[k]) return false;
      continue;
    }
    double enter = (lo[k] - a[k]) * inv[k], leave = (hi[k] - a[k]) * inv[k];
    if (enter > leave) std::swap(enter, leave);
    c0 = std::max(c0, enter - widen);
    c1 = std::min(c1, leave + widen);
  }
  return c0 <= c1;
}

}  // namespace

bool SweptSphereQuery::blocksAtStart(std::int32_t triangle, const Vec3& a, const Vec3& b, double r, SweptContact& out,
                                     double within) const noexcept {
  if (triangle < 0 || static_cast<std::size_t>(triangle) >= mesh_->size()) return false;
  if (!validPointer(a, r) || !b.allFinite()) return false;
  const Vec3 la = mesh_->toLocal(a), lb = mesh_->toLocal(b);
  if (!(within >= 0.0)) return false;
  return blockedAtStartBy(*mesh_, static_cast<std::size_t>(triangle), la, lb - la,
                          sweptRadiusMargin(r, magnitudeOf(la, lb)), out, within);
}

void SweptSphereQuery::sweepGrid(const Vec3& a, const Vec3& d, double R, Best& best) const noexcept {
  const CellGrid& grid = *grid_;
  const double h = grid.cellSize();
  const int pieces = std::max(1, static_cast<int>(std::ceil(d.norm() / h)));
  // Covers the rounding of the pieces' ends and of the cell coordinates.
  const double pad = 1e-9 * h + 1e-12 * magnitudeOf(a, a + d);
  const Vec3 inv = reciprocals(d);
  for (int k = 0; k < pieces; ++k) {
    const double t0 = static_cast<double>(k) / pieces, t1 = static_cast<double>(k + 1) / pieces;
    const Vec3 p0 = a + t0 * d, p1 = k + 1 == pieces ? Vec3(a + d) : Vec3(a + t1 * d);
    // The cells the piece's box meets (no more than 3 along an axis: the piece is at most a cell long), each with
    // the part [c0, c1] of the piece inside it (its box grown by pad), in the order the piece enters them. A
    // contact's centre lies in some cell, whose candidates reach every triangle within the grid radius of its
    // points, and a scan's bounds hold on that part alone (tighter than on the whole piece); a cell entered after
    // the best time so far holds no earlier contact, and the nearest cells, scanned first, shrink that time.
    struct Part {
      std::uint64_t key;
      const CellGrid::CellRef* ref;
      double c0, c1;
    } parts[27];
    int count = 0;
    std::int64_t lo[3], hi[3];
    grid.cellCoordinates(p0.cwiseMin(p1) - Vec3::Constant(pad), lo);
    grid.cellCoordinates(p0.cwiseMax(p1) + Vec3::Constant(pad), hi);
    for (std::int64_t z = lo[2]; z <= hi[2]; ++z)
      for (std::int64_t y = lo[1]; y <= hi[1]; ++y)
        for (std::int64_t x = lo[0]; x <= hi[0] && count < 27; ++x) {  // 3 x 3 x 3 at most
          const std::uint64_t key = grid.keyAt(x, y, z);
          double c0 = t0, c1 = std::min(t1, best.toi);
          // A cell with no triangle within the grid radius is skipped before any clipping (free space).
          const CellGrid::CellRef* ref = key == CellGrid::kOutside ? nullptr : grid.find(key);
          if (ref == nullptr) continue;
          // The cell's box grown by pad (the pieces' rounding), its times by 1e-12 (the slabs' own).
          const Vec3 centre = grid.centreOf(key), half = Vec3::Constant(0.5 * h + pad);
          if (!clipToBox(centre - half, centre + half, a, d, inv, 1e-12, c0, c1)) continue;
          int i = count++;
          for (; i > 0 && parts[i - 1].c0 > c0; --i) parts[i] = parts[i - 1];
          parts[i] = {key, ref, c0, c1};
        }
    for (int i = 0; i < count && parts[i].c0 <= best.toi; ++i) {
      const double c0 = parts[i].c0, c1 = std::min(parts[i].c1, best.toi);
      sweepCell(*parts[i].ref, parts[i].key, c0 <= t0 ? p0 : Vec3(a + c0 * d), c1 >= t1 ? p1 : Vec3(a + c1 * d), a, d,
                R, c0, c1, best);
    }
    // Every contact at a time up to t1 has its centre in the pieces seen: the first one is known.
    if (best.toi <= t1) return;
  }
}

void SweptSphereQuery::sweepCell(const CellGrid::CellRef& ref, std::uint64_t key, const Vec3& p0, const Vec3& p1,
                                 const Vec3& a, const Vec3& d, double R, double t0, double t1,
                                 Best& best) const noexcept {
  const CellGrid& grid = *grid_;
  if (best.toi < t0) return;  // every contact through this piece comes later
  const CellGrid::Cell cell = grid.cell(ref);
  const Vec3 centre = grid.centreOf(key);
  // The bounds hold for the piece up to the best time so far (a contact after it cannot win): its far end
  // moves back each time a contact is found.
  const Vec3 r0 = p0 - centre;
  const double n0 = r0.norm();
  Vec3 r1;
  double n1 = 0.0, reach = 0.0, end = -1.0;
  // The 8-bit directions' rounding (|u - stored| <= sqrt(3) / 254) grows with the distance from the centre.
  const double slack = grid.slack(), along = 1.7320508075688772 / 254.0;
  auto shrink = [&]() {
    end = std::min(t1, best.toi);
    r1 = (end >= t1 ? p1 : Vec3(a + end * d)) - centre;
    n1 = r1.norm();
    reach = std::max(n0, n1) + slack;
  };
  shrink();
  const double unit = grid.distanceUnit();
  // The entry's own bounds: 0 when the scan is over, 1 to pass it over, 2 to test its triangle.
  auto judge = [&](const CellGrid::Entry& e) {
    const double dc = e.distance * unit;
    // distance(p, T) >= dc - |p - centre| on the whole piece (the farthest point is an end): sorted, so stop.
    if (dc - reach > R) return 0;
    // distance(p, T) >= dc + (p - centre) . u, linear along the piece: its smaller end bounds it.
    const double u0 = (r0.x() * e.direction[0] + r0.y() * e.direction[1] + r0.z() * e.direction[2]) * (1.0 / 127.0);
    const double u1 = (r1.x() * e.direction[0] + r1.y() * e.direction[1] + r1.z() * e.direction[2]) * (1.0 / 127.0);
    return std::min(u0 - along * n0, u1 - along * n1) + dc - slack > R ? 1 : 2;
  };
  // The double test of one entry: whether the scan goes on.
  auto visit = [&](const CellGrid::Entry& e) {
    const int verdict = judge(e);
    if (verdict == 2) {
      testTriangle(e.triangle, a, d, R, best);
      if (best.toi < end) shrink();
    }
    return verdict != 0;
  };
  std::uint32_t i = 0;
#if defined(CLOD_PACKET_AVX2)
  // Eight entries at a time through a float filter that keeps every entry the double test (judge) keeps; the
  // triangles it keeps go on four at a time through the records' ball and plane bounds in AVX2 (looser than the
  // scalar ones), the survivors to the exact test, in order. Up to 16 are held, their records prefetched as they are
  // admitted: a sweep into a region it has not touched lately waits for each record's line, and 16 loads in flight
  // wait together (4 at a time, as before, waited about a third longer on the first pass over refined_elephant).
  if (cell.count >= 16 && detail::packetAvx2()) {
    constexpr int kBatch = 16;
    std::uint32_t batch[kBatch];
    int held = 0;
    detail::RecordFilterSweep sweep{{a.x(), a.y(), a.z()}, {d.x(), d.y(), d.z()}, 1.0, best.invdd, R, best.reach};
    const auto record = [this](std::uint32_t t) { return recordOf(t); };
    auto flush = [&]() {
      for (int base = 0; base < held; base += 4)
        filterFour(batch + base, std::min(4, held - base), std::min(1.0, best.toi), sweep, record,
                   [&](std::uint32_t t) {
                     testRecord(t, a, d, R, best);
                     if (best.toi < end) shrink();
                   });
      held = 0;
    };
    double boundsEnd = end;
    detail::CellScanBounds bounds = detail::cellScanBounds(r0, r1, -along * n0, -along * n1, unit, R + slack, reach);
    for (; i + 8 <= cell.count; i += 8) {
      if (cell.entries[i].distance * unit - reach > R) break;
      // The float filter keeps every entry the double bounds keep, and almost no other (on the proxy's slow ticks
      // 903,692 of 904,124 passed both): its entries go to the records' filter without a second test.
      for (unsigned m = detail::cellScanBlockAvx2(cell.entries + i, bounds); m != 0; m &= m - 1) {
        const CellGrid::Entry& e = cell.entries[i + static_cast<std::uint32_t>(__builtin_ctz(m))];
        if (!best.admit(e.triangle)) continue;
        __builtin_prefetch(recordOf(e.triangle));
        batch[held++] = e.triangle;
      }
      if (held + 8 > kBatch) flush();
      if (end != boundsEnd) {  // a contact shortened the piece: tighter bounds for the rest
        boundsEnd = end;
        bounds = detail::cellScanBounds(r0, r1, -along * n0, -along * n1, unit, R + slack, reach);
      }
    }
    flush();
    if (i + 8 <= cell.count) return;  // stopped by the first entry of a block: sorted, the rest is farther
  }
#endif
  for (; i < cell.count; ++i)
    if (!visit(cell.entries[i])) return;
}

namespace {

// Where the segment a -> a + d (t in [0, 1]) enters a node's box grown by R, or kNever when it misses it, or when
// the part of the segment inside that grown box, up to tMax, stays farther than R from what lies below the node:
// from the box itself (that part's bounding box is at least as close to the node's box as any of its points: the
// squared distance of two boxes adds the gaps on each axis) or from the node's slab and ball (planeBoundMisses on
// that part, with reach: R and its rounding slack). Both drop the nodes beside a sphere sliding over a surface,
// which the grown box keeps for R on either side of its path.
// inv: reciprocals(d).
inline double enterNode(const BoxNode& n, const NodeSlab& slab, const Vec3& a, const Vec3& d, const Vec3& inv, double R,
                        double reach, double tMax) {
  double t0 = 0.0, t1 = 1.0;
  const Vec3 lo(n.lo[0], n.lo[1], n.lo[2]), hi(n.hi[0], n.hi[1], n.hi[2]);
  const Vec3 grow = Vec3::Constant(R);
  if (!clipToBox(lo - grow, hi + grow, a, d, inv, 0.0, t0, t1)) return kNever;
  t1 = std::min(t1, tMax);
  if (t1 < t0) return t0;  // after the best time: the caller skips it
  const Vec3 p0 = a + t0 * d, p1 = a + t1 * d;
  const Vec3 gap = (lo - p0.cwiseMax(p1)).cwiseMax(p0.cwiseMin(p1) - hi).cwiseMax(0.0);
  if (gap.squaredNorm() > R * R) return kNever;
  if (!(slab.radius < kNever)) return t0;  // a node without a slab (too much below it)
  return planeBoundMisses(slab.centre, slab.radius, slab.normal, slab.thick, p0, p1 - p0, reach, 1.0) ? kNever : t0;
}

// What the tree walks grow a node's box by (sweepTree, sweepWide): the grown box holds every centre within R of the
// node's triangles, its rounding covered by a margin.
inline double treeGrow(double R, const Vec3& a, const Vec3& d) {
  return R * (1.0 + 1e-12) + 1e-12 * magnitudeOf(a, a + d);
}

}  // namespace

void SweptSphereQuery::testRun(std::uint32_t from, std::uint32_t few, const Vec3& a, const Vec3& d, double R,
                               Best& best) const noexcept {
  const std::vector<std::uint32_t>& order = tree_->order;
  const std::uint32_t end = from + few;
  // The records requested together: a walk into a region it has not touched lately waits for each.
  for (std::uint32_t i = from; i < end; ++i) __builtin_prefetch(recordOf(order[i]));
#if defined(CLOD_PACKET_AVX2)
  // Through the records' ball and plane bounds four at a time, as sweepCell's batches.
  if (detail::packetAvx2()) {
    detail::RecordFilterSweep filter{{a.x(), a.y(), a.z()}, {d.x(), d.y(), d.z()}, 1.0, best.invdd, R, best.reach};
    const auto record = [this](std::uint32_t t) { return recordOf(t); };
    for (std::uint32_t i = from; i < end;) {
      std::uint32_t held[4];
      int n = 0;
      for (; i < end && n < 4; ++i)
        if (best.admit(order[i])) held[n++] = order[i];
      if (n > 0)
        filterFour(held, n, std::min(1.0, best.toi), filter, record,
                   [&](std::uint32_t t) { testRecord(t, a, d, R, best); });
    }
    return;
  }
#endif
  for (std::uint32_t i = from; i < end; ++i) testTriangle(order[i], a, d, R, best);
}

void SweptSphereQuery::sweepTree(const Vec3& a, const Vec3& d, double R, Best& best) const noexcept {
  const std::vector<BoxNode>& nodes = tree_->nodes;
  const std::vector<std::uint32_t>& order = tree_->order;
  if (nodes.empty()) return;
  const NodeSlab* slabs = tree_->slabs.data();  // one per node (meshBoxTreeOf)
  const double grow = treeGrow(R, a, d);
  const Vec3 inv = reciprocals(d);
  struct Item {
    std::uint32_t node;
    double t;
  };
  Item stack[128];
  int top = 0;
  const double t = enterNode(nodes[0], slabs[0], a, d, inv, grow, best.reach, best.toi);
  if (t != kNever) stack[top++] = {0, t};
  while (top > 0) {
    const Item item = stack[--top];
    if (item.t > best.toi) continue;  // every contact inside comes later
    const BoxNode& node = nodes[item.node];
    const std::uint32_t few = small_[item.node];
    if (few > 0) {
      // Its triangles lie together in the order array from its leftmost leaf's on (left children follow their parent).
      std::uint32_t leftmost = item.node;
      while (nodes[leftmost].count == 0) ++leftmost;
      testRun(nodes[leftmost].first, few, a, d, R, best);
      continue;
    }
    if (node.count > 0) {
      for (std::uint32_t i = node.first; i < node.first + node.count; ++i) testTriangle(order[i], a, d, R, best);
      continue;
    }
    const std::uint32_t left = item.node + 1, right = node.first;
    prefetchChildren(nodes.data(), slabs, left, right);
    const double tl = best.below(slabs[left])
                          ? kNever
                          : enterNode(nodes[left], slabs[left], a, d, inv, grow, best.reach, best.toi),
                 tr = best.below(slabs[right])
                          ? kNever
                          : enterNode(nodes[right], slabs[right], a, d, inv, grow, best.reach, best.toi);
    // The nearer child on top of the stack.
    if (tl <= tr) {
      if (tr != kNever) stack[top++] = {right, tr};
      if (tl != kNever) stack[top++] = {left, tl};
    } else {
      if (tl != kNever) stack[top++] = {left, tl};
      stack[top++] = {right, tr};
    }
  }
}

void SweptSphereQuery::sweepWide(const Vec3& a, const Vec3& d, double R, Best& best) const noexcept {
#if defined(CLOD_PACKET_AVX2)
  const Vec3 inv = reciprocals(d);
  detail::NodeFilterSweep s{};
  for (int k = 0; k < 3; ++k) {
    s.a[k] = a[k];
    s.d[k] = d[k];
    s.inv[k] = inv[k];
  }
  s.grow = treeGrow(R, a, d);
  s.reach = best.reach;
  wide_->walk([&] { return best.toi; },  // every contact inside a node entered later comes later
              [&](const WideBoxTree::Node& node, double* enter) {
                s.tMax = best.toi;
                s.plane = best.planeReady();
                if (s.plane) {
                  for (int k = 0; k < 3; ++k) s.n[k] = best.n[k];
                  s.offset = best.offset;
                  s.clearance = best.clearance();
                }
                return detail::nodeFilterAvx2(node.lanes, node.count, s, enter);
              },
              [&](std::uint32_t first, std::uint32_t few) { testRun(first, few, a, d, R, best); });
#else
  sweepTree(a, d, R, best);
#endif
}

}  // namespace clod_haptics
