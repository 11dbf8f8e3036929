// The swept-sphere query: the exact triangle test against the distance function sampled along the
// sweep (closestPointOnTriangle, an independent reference), and SweptSphereQuery (grid and tree) against
// bruteForceSweep on every shared mesh and on random triangle soups, with grazing, starting-in-contact
// and zero-length sweeps, plus a check that sweep() allocates nothing.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <vector>

#include "allocation_counter.h"
#include "clod_haptics/core/detector.h"
#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/geometry.h"
#include "clod_haptics/core/probes.h"
#include "clod_haptics/core/sphere_set.h"
#include "clod_haptics/core/swept_query.h"
#include "simd/cell_scan_avx2.h"
#include "simd/dispatch.h"
#include "simd/record_filter_avx2.h"
#include "test_helpers.h"

namespace {

using namespace clod_haptics;
using clod_test::randomUnit;

double distanceAt(const Vec3& c, const Vec3& v0, const Vec3& v1, const Vec3& v2) {
  return (c - closestPointOnTriangle(c, v0, v1, v2)).norm();
}

// The reference first contact of a sweep with one triangle: the distance f(t) is convex along the
// line, so its minimum is found by golden-section search and the first t with f = r by bisection
// before it. Returns -1 when f stays above r on [0, 1]; sets minimum to min f.
double referenceEntry(const Vec3& a, const Vec3& d, double r, const Vec3& v0, const Vec3& v1, const Vec3& v2,
                      double& minimum) {
  auto f = [&](double t) { return distanceAt(a + t * d, v0, v1, v2); };
  double lo = 0.0, hi = 1.0;
  for (int i = 0; i < 200; ++i) {
    const double m1 = lo + (hi - lo) * 0.381966, m2 = hi - (hi - lo) * 0.381966;
    if (f(m1) <= f(m2))
      hi = m2;
    else
      lo = m1;
  }
  const double tMin = 0.5 * (lo + hi);
  minimum = std::min({f(0.0), f(tMin), f(1.0)});
  if (f(0.0) <= r) return 0.0;
  const double tEnd = f(1.0) <= r ? 1.0 : tMin;
  if (f(tEnd) > r) return -1.0;
  lo = 0.0;
  hi = tEnd;
  for (int i = 0; i < 200; ++i) {
    const double m = 0.5 * (lo + hi);
    (f(m) <= r ? hi : lo) = m;
  }
  return hi;
}

TEST(SweptSphereTriangle, MatchesTheSampledDistanceOnRandomSweeps) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0), len(0.0, 3.0), rad(0.01, 0.5);
  int hits = 0, misses = 0, ambiguous = 0;
  for (int i = 0; i < 40000; ++i) {
    const Vec3 v0(u(rng), u(rng), u(rng)), v1(u(rng), u(rng), u(rng)), v2(u(rng), u(rng), u(rng));
    const double r = rad(rng);
    const Vec3 a = Vec3(u(rng), u(rng), u(rng)) * 2.0;
    const Vec3 d = randomUnit(rng) * len(rng);
    double minimum;
    const double ref = referenceEntry(a, d, r, v0, v1, v2, minimum);
    double toi = -1.0;
    bool start = false;
    const bool hit = sweptSphereTriangle(a, d, sweptRadiusMargin(r, 2.0), v0, v1, v2, toi, start);
    if (std::abs(minimum - r) < 1e-7 * r) {  // grazing within the sampling's accuracy: either answer
      ++ambiguous;
      continue;
    }
    if (ref < 0.0) {
      EXPECT_FALSE(hit) << "case " << i << ": reported a contact on a free path, toi " << toi;
      ++misses;
      continue;
    }
    if (ref == 0.0) {  // starts in contact: a hit exactly when the motion approaches
      const Vec3 w = a - closestPointOnTriangle(a, v0, v1, v2);
      EXPECT_EQ(hit, w.dot(d) < 0.0 || w.norm() <= 1e-9 * r) << "case " << i;
      if (hit) {
        EXPECT_EQ(toi, 0.0);
      }
      continue;
    }
    ++hits;
    ASSERT_TRUE(hit) << "case " << i << ": missed a contact at t = " << ref;
    // Never later than the true contact; earlier by no more than the radius margin allows.
    EXPECT_LE(toi, ref + 1e-12) << "case " << i;
    EXPECT_GE(toi, ref - 1e-7) << "case " << i;
    EXPECT_GE(distanceAt(a + toi * d, v0, v1, v2), r * (1.0 - 1e-9)) << "case " << i;
    // Cut at a best time so far (a search's tMax, as the tests that end early use it): the same contact when it
    // comes by then, none when it comes clearly after.
    const double tMax = ref * std::pow(2.0, u(rng));  // half to twice the contact's time
    double cut = -1.0;
    const bool hitBefore = sweptSphereTriangle(a, d, sweptRadiusMargin(r, 2.0), v0, v1, v2, cut, start, tMax);
    if (tMax >= ref + 1e-7) {
      EXPECT_TRUE(hitBefore) << "case " << i << ": tMax " << tMax << " cut a contact at " << ref;
      if (hitBefore) {
        EXPECT_EQ(cut, toi) << "case " << i;
      }
    } else if (tMax < ref - 1e-7) {
      EXPECT_FALSE(hitBefore) << "case " << i << ": a contact at " << cut << " after tMax " << tMax;
    }
  }
  EXPECT_GT(hits, 500);
  EXPECT_GT(misses, 1000);
  EXPECT_LT(ambiguous, 100);
}

TEST(SweptSphereTriangle, GrazingEdgesAndVertices) {
  const Vec3 v0(0, 0, 0), v1(1, 0, 0), v2(0, 1, 0);
  const double r = 0.1;
  const double R = sweptRadiusMargin(r, 2.0);
  for (double angle = 0.05; angle < 3.1; angle += 0.1) {
    // A line parallel to the edge v0 -> v1 at distance s from it, in the plane spanned by -y and z.
    const Vec3 side(0.0, -std::cos(angle), std::sin(angle));
    for (double s : {r * (1.0 - 1e-9), r * (1.0 + 1e-6)}) {
      const Vec3 a = Vec3(-1.0, 0.0, 0.0) + s * side;
      const Vec3 d(3.0, 0.0, 0.0);
      double toi;
      bool start;
      const bool hit = sweptSphereTriangle(a, d, R, v0, v1, v2, toi, start);
      if (side.y() > 0.0) continue;  // the line passes over the face: not a grazing case
      EXPECT_EQ(hit, s < r) << "angle " << angle << " s " << s;
    }
  }
  // Grazing a vertex from a direction outside the triangle's plane.
  const Vec3 dir = Vec3(1.0, 1.0, 1.0).normalized();
  const Vec3 off = Vec3(1.0, -1.0, 0.0).normalized();
  for (double s : {r * (1.0 - 1e-9), r * (1.0 + 1e-6)}) {
    const Vec3 a = v1 - 2.0 * dir + s * off;
    double toi;
    bool start;
    EXPECT_EQ(sweptSphereTriangle(a, 4.0 * dir, R, v0, v1, v2, toi, start), s < r) << s;
  }
}

TEST(SweptSphereTriangle, StartInContactAndZeroLength) {
  const Vec3 v0(0, 0, 0), v1(1, 0, 0), v2(0, 1, 0);
  const double r = 0.1, R = sweptRadiusMargin(r, 1.0);
  const Vec3 a(0.2, 0.2, 0.05);  // touching the face from above
  double toi = -1.0;
  bool start = false;
  EXPECT_TRUE(sweptSphereTriangle(a, Vec3(0, 0, -0.01), R, v0, v1, v2, toi, start));  // pushing in
  EXPECT_EQ(toi, 0.0);
  EXPECT_TRUE(start);
  EXPECT_FALSE(sweptSphereTriangle(a, Vec3(0.1, 0, 0), R, v0, v1, v2, toi, start));  // sliding
  EXPECT_FALSE(sweptSphereTriangle(a, Vec3(0, 0, 0.1), R, v0, v1, v2, toi, start));  // leaving
  EXPECT_TRUE(sweptSphereTriangle(a, Vec3::Zero(), R, v0, v1, v2, toi, start));      // zero length: in contact
  EXPECT_FALSE(sweptSphereTriangle(Vec3(0.2, 0.2, 0.2), Vec3::Zero(), R, v0, v1, v2, toi, start));  // free
  // The centre on the triangle: blocked whichever way it moves.
  EXPECT_TRUE(sweptSphereTriangle(Vec3(0.2, 0.2, 0.0), Vec3(0, 0, 0.1), R, v0, v1, v2, toi, start));
}

// Sweeps starting exactly at the test radius from a face (where a proxy rests) and moving into it: the
// distance and the plane offset round independently there, and neither may let the sweep through.
TEST(SweptSphereTriangle, StartOnTheContactShellMovingIn) {
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(-1.0, 1.0), w(0.05, 0.9);
  int missed = 0;
  for (int i = 0; i < 20000; ++i) {
    const Vec3 v0(u(rng), u(rng), u(rng)), v1(u(rng), u(rng), u(rng)), v2(u(rng), u(rng), u(rng));
    const Vec3 n = (v1 - v0).cross(v2 - v0).normalized();
    const double b1 = w(rng), b2 = w(rng) * (1.0 - b1);
    const double r = 0.01 + 0.1 * w(rng), R = sweptRadiusMargin(r, 2.0);
    const Vec3 a = v0 + b1 * (v1 - v0) + b2 * (v2 - v0) + n * R;
    const Vec3 d = (-n + 0.3 * randomUnit(rng)) * 0.01 * r;
    double toi;
    bool start;
    if (d.dot(n) < 0.0 && !sweptSphereTriangle(a, d, R, v0, v1, v2, toi, start)) ++missed;
  }
  EXPECT_EQ(missed, 0);
}

// A plate of two triangles at z = 0: the answer's fields from the definition.
TEST(SweptSphereQuery, AnswerFieldsOnAPlate) {
  auto mesh = std::make_shared<const TriangleMesh>(
      makeMesh({{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}}, {{0, 1, 2}, {0, 2, 3}}, "plate"));
  const SweptSphereQuery query(mesh);
  SweptContact c;
  query.sweep(Vec3(0.3, -0.2, 1.0), Vec3(0.3, -0.2, -1.0), 0.25, c);
  ASSERT_TRUE(c.hit);
  EXPECT_NEAR(c.toi, 0.375, 1e-9);
  EXPECT_LE(c.toi, 0.375);
  EXPECT_NEAR((c.point - Vec3(0.3, -0.2, 0.0)).norm(), 0.0, 1e-9);
  EXPECT_NEAR((c.normal - Vec3::UnitZ()).norm(), 0.0, 1e-12);
  EXPECT_NEAR((c.centre - Vec3(0.3, -0.2, 0.25)).norm(), 0.0, 1e-9);
  EXPECT_EQ(c.region.feature, TriangleFeature::Face);
  EXPECT_FALSE(c.startInContact);
  query.sweep(Vec3(0.3, -0.2, 1.0), Vec3(0.3, -0.2, 0.5), 0.25, c);
  EXPECT_FALSE(c.hit);
  query.sweep(Vec3(0.3, -0.2, 1.0), Vec3(0.3, -0.2, 1.0) + Vec3(1, 0, 0) * std::nan(""), 0.25, c);
  EXPECT_FALSE(c.hit);
}

// A sphere resting on the diagonal of a two-triangle plate and pressed into it is blocked at 0 by both: the
// lowest index wins, unless the hint is the other one (a proxy passes its last contact). A hint that does not
// block at 0 (a triangle far away, or the plate when the sphere lifts) leaves the answer to the index rule.
TEST(SweptSphereQuery, AHintBlockingAtZeroWinsTheTie) {
  auto mesh = std::make_shared<const TriangleMesh>(
      makeMesh({{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}, {5, 5, 5}, {6, 5, 5}, {5, 6, 5}},
               {{0, 1, 2}, {0, 2, 3}, {4, 5, 6}}, "plate and a far triangle"));
  auto set = std::make_shared<const ClodSphereSet>(ClodBuilder(mesh).build(0.1));
  auto detector = std::make_shared<const ClodDetector>(mesh, set, FastLevel::Grid, 0.3);
  const SweptSphereQuery withGrid(mesh, detector), treeOnly(mesh);
  const double r = 0.25;
  const Vec3 a(0.2, 0.2, r);  // above the shared diagonal, touching both triangles
  const Vec3 in = a + Vec3(0.01, -0.01, -0.1), up = a + Vec3(0.1, 0.0, 0.1);
  struct Case {
    Vec3 b;
    std::int32_t hint, want;
    double toi;
  };
  for (const Case& k :
       {Case{in, -1, 0, 0.0}, Case{in, 1, 1, 0.0}, Case{in, 0, 0, 0.0}, Case{in, 2, 0, 0.0}, Case{up, 1, -1, 1.0}}) {
    const SweptContact reference = bruteForceSweep(*mesh, a, k.b, r, k.hint);
    EXPECT_EQ(reference.triangle, k.want) << "hint " << k.hint;
    EXPECT_EQ(reference.hit, k.want >= 0);
    if (k.want >= 0) {
      EXPECT_EQ(reference.toi, k.toi);
      EXPECT_TRUE(reference.startInContact);
    }
    for (const SweptSphereQuery* query : {&withGrid, &treeOnly}) {
      SweptContact c;
      query->sweep(a, k.b, r, c, k.hint);
      EXPECT_EQ(c.hit, reference.hit) << "hint " << k.hint;
      EXPECT_EQ(c.triangle, reference.triangle) << "hint " << k.hint;
      EXPECT_EQ(c.toi, reference.toi);
      EXPECT_EQ(c.normal, reference.normal);
      // The same check alone: true exactly when the hint is the answer, with the answer's fields.
      SweptContact held;
      ASSERT_EQ(query->blocksAtStart(k.hint, a, k.b, r, held), k.hint >= 0 && k.want == k.hint) << "hint " << k.hint;
      if (k.hint >= 0 && k.want == k.hint) {
        EXPECT_EQ(held.triangle, reference.triangle);
        EXPECT_EQ(held.point, reference.point);
        EXPECT_EQ(held.normal, reference.normal);
        EXPECT_TRUE(held.startInContact);
      }
    }
  }
}

// blocksAtStart with a distance within: a sphere a gap above a plate, moving into it, is blocked "at once" exactly when
// the brute force's first contact comes before the centre has moved within (its time times the sweep's length); the
// answer is then given at toi = 0, the point the triangle's closest to the centre at a. Moving along the plate or away
// from it, no within makes it block. Random gaps, directions and withins on a random triangle.
TEST(SweptSphereQuery, BlocksAtStartWithinADistanceAgreesWithTheBruteForce) {
  std::mt19937_64 rng(29);
  std::uniform_real_distribution<double> unit(-1.0, 1.0), fraction(0.0, 1.0);
  int blocked = 0, free = 0;
  for (int k = 0; k < 400; ++k) {
    const Vec3 v0(unit(rng), unit(rng), 0.1 * unit(rng)), v1(unit(rng), unit(rng), 0.1 * unit(rng)),
        v2(unit(rng), unit(rng), 0.1 * unit(rng));
    auto mesh = std::make_shared<const TriangleMesh>(makeMesh({v0, v1, v2}, {{0, 1, 2}}, "one triangle"));
    if (!(mesh->normals[0].squaredNorm() > 0.5)) continue;
    const SweptSphereQuery query(mesh);
    const double r = 0.05 + 0.2 * fraction(rng), gap = r * std::pow(10.0, -1.0 - 9.0 * fraction(rng));
    const Vec3 n = mesh->normals[0], centre = (v0 + v1 + v2) / 3.0;
    const Vec3 a = centre + 0.3 * fraction(rng) * (v0 - centre) + (r + gap) * n;
    const Vec3 b = a + Vec3(unit(rng), unit(rng), unit(rng)) * 0.5 * r;
    const SweptContact reference = bruteForceSweep(*mesh, a, b, r);
    const double travel = reference.hit ? reference.toi * (b - a).norm() : 0.0;
    for (double within : {0.0, 0.5 * travel, travel * (1.0 + 1e-9), 2.0 * travel + 1e-9 * r, r}) {
      SweptContact out;
      const bool want = reference.hit && (reference.toi == 0.0 || travel <= within);
      ASSERT_EQ(query.blocksAtStart(0, a, b, r, out, within), want)
          << "case " << k << " gap " << gap << " within " << within << " travel " << travel;
      if (!want) continue;
      ++blocked;
      EXPECT_TRUE(out.hit);
      EXPECT_EQ(out.toi, 0.0);
      EXPECT_EQ(out.triangle, 0);
      EXPECT_EQ(out.point, closestPointOnTriangle(a, v0, v1, v2));
      EXPECT_NEAR((out.normal - (a - out.point).normalized()).norm(), 0.0, 1e-12);
    }
    free += reference.hit ? 0 : 1;
  }
  EXPECT_GT(blocked, 200);  // both outcomes seen many times
  EXPECT_GT(free, 50);
}

// blocksAtStart on bad input: a triangle out of range, non-finite points, a negative radius or a negative or NaN
// within answer false and leave out as it was.
TEST(SweptSphereQuery, BlocksAtStartRefusesBadInput) {
  auto mesh = std::make_shared<const TriangleMesh>(
      makeMesh({{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}}, {{0, 1, 2}, {0, 2, 3}}, "plate"));
  const SweptSphereQuery query(mesh);
  const Vec3 a(0.2, 0.2, 0.25), in = a + Vec3(0.0, 0.0, -0.1);
  SweptContact out;
  ASSERT_TRUE(query.blocksAtStart(1, a, in, 0.25, out));  // the good case, for contrast
  const double nan = std::nan("");
  struct Case {
    std::int32_t triangle;
    Vec3 a, b;
    double r;
  };
  for (const Case& k : {Case{-1, a, in, 0.25}, Case{2, a, in, 0.25}, Case{1, Vec3(nan, 0, 0), in, 0.25},
                        Case{1, a, Vec3(0, nan, 0), 0.25}, Case{1, a, in, -0.25}, Case{1, a, in, nan}}) {
    SweptContact untouched;
    untouched.triangle = 7;
    EXPECT_FALSE(query.blocksAtStart(k.triangle, k.a, k.b, k.r, untouched)) << "triangle " << k.triangle;
    EXPECT_EQ(untouched.triangle, 7);
    EXPECT_FALSE(untouched.hit);
  }
  for (double within : {-1e-9, nan}) {
    SweptContact untouched;
    untouched.triangle = 7;
    EXPECT_FALSE(query.blocksAtStart(1, a, in, 0.25, untouched, within)) << "within " << within;
    EXPECT_EQ(untouched.triangle, 7);
  }
}

// Sweeps around a mesh: from points near the surface, in random directions, of lengths from a
// hundredth of the radius to many cells, plus zero-length ones and ones aimed through the surface.
struct Sweep {
  Vec3 a, b;
  std::int32_t rest = -1;  ///< the triangle the sphere rests on at a (a proxy's hint), -1 when none
};
std::vector<Sweep> sweepsNear(const TriangleMesh& mesh, std::size_t count, double r, std::uint64_t seed) {
  const std::vector<Vec3> starts = nearSurfaceProbes(mesh, count, 3.0 * r, seed);
  std::mt19937_64 rng(seed + 1);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Sweep> out;
  for (std::size_t i = 0; i < starts.size(); ++i) {
    const double kind = u(rng);
    double length = r * std::pow(10.0, -2.0 + 3.0 * u(rng));  // 0.01 r to 10 r
    if (kind < 0.05) length = 0.0;
    if (kind > 0.95) length = 0.3 * mesh.diagonal();
    out.push_back({starts[i], starts[i] + randomUnit(rng) * length});
  }
  return out;
}

void expectSameAsBruteForce(const TriangleMesh& mesh, const SweptSphereQuery& query, const std::vector<Sweep>& sweeps,
                            double r, const std::string& label) {
  std::vector<SweptContact> got(sweeps.size()), want(sweeps.size());
  clod_test::parallelFor(sweeps.size(), 2, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) {
      const SweptContact plain = bruteForceSweep(mesh, sweeps[i].a, sweeps[i].b, r);
      // A hint (the answer's triangle, another one, or none) changes the work; the answer only where the hint
      // blocks at 0 too (it then wins the tie), the same for both.
      // A sphere resting on a triangle gets that one half the time (a proxy's hint: its last contact).
      const std::int32_t hint = sweeps[i].rest >= 0 && i % 2 == 0 ? sweeps[i].rest
                                : i % 3 == 0                      ? -1
                                : i % 3 == 1                      ? plain.triangle
                                                                  : static_cast<std::int32_t>(i % mesh.size());
      want[i] = bruteForceSweep(mesh, sweeps[i].a, sweeps[i].b, r, hint);
      query.sweep(sweeps[i].a, sweeps[i].b, r, got[i], hint);
    }
  });
  std::size_t hits = 0, starts = 0, mismatches = 0;
  for (std::size_t i = 0; i < sweeps.size(); ++i) {
    hits += want[i].hit;
    starts += want[i].hit && want[i].startInContact;
    const bool same = got[i].hit == want[i].hit &&
                      (!want[i].hit || (got[i].toi == want[i].toi && got[i].triangle == want[i].triangle &&
                                        got[i].point == want[i].point && got[i].normal == want[i].normal));
    if (!same && ++mismatches <= 5)
      ADD_FAILURE() << label << " sweep " << i << ": got hit " << got[i].hit << " toi " << got[i].toi << " tri "
                    << got[i].triangle << ", want hit " << want[i].hit << " toi " << want[i].toi << " tri "
                    << want[i].triangle;
  }
  EXPECT_EQ(mismatches, 0u) << label;
  EXPECT_GT(hits, sweeps.size() / 10) << label << ": too few contacts to mean anything";
  EXPECT_GT(starts, 0u) << label << ": no sweep started in contact";
}

TEST(SweptSphereQuery, SameAsBruteForceOnSharedMeshes) {
  for (const std::string& path : clod_test::sharedMeshes()) {
    auto mesh = clod_test::loadNormalized(path);
    auto set = std::make_shared<const ClodSphereSet>(ClodBuilder(mesh).build(0.01));
    auto detector = std::make_shared<const ClodDetector>(mesh, set, FastLevel::Grid, 0.02);
    const SweptSphereQuery withGrid(mesh, detector), treeOnly(mesh);
    const std::size_t count = mesh->size() > 50000 ? 600 : 2000;
    for (double r : {0.004, 0.02, 0.05}) {  // 0.05: beyond the grid's radius, the tree answers
      const std::vector<Sweep> sweeps = sweepsNear(*mesh, count, r, 11);
      const std::string label = clod_test::baseName(path) + " r " + std::to_string(r);
      expectSameAsBruteForce(*mesh, withGrid, sweeps, r, label + " grid");
      if (r == 0.004) expectSameAsBruteForce(*mesh, treeOnly, sweeps, r, label + " tree");
    }
  }
}

// Random triangle soups, some far from the origin (a local frame) and with slivers.
TEST(SweptSphereQuery, SameAsBruteForceOnRandomMeshes) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int m = 0; m < 6; ++m) {
    const Vec3 shift = m % 2 ? Vec3(1e4, -3e3, 5e2) : Vec3::Zero();
    std::vector<Vec3> vertices;
    std::vector<Triangle> triangles;
    for (std::uint32_t t = 0; t < 2000; ++t) {
      const Vec3 c(u(rng), u(rng), u(rng));
      const double size = 0.01 + 0.05 * u(rng);
      for (int k = 0; k < 3; ++k)
        vertices.push_back(shift + c + randomUnit(rng) * size * (k == 2 && t % 7 == 0 ? 1e-9 : 1.0));
      triangles.push_back({3 * t, 3 * t + 1, 3 * t + 2});
    }
    auto mesh = std::make_shared<const TriangleMesh>(makeMesh(vertices, triangles, "soup"));
    auto set = std::make_shared<const ClodSphereSet>(ClodBuilder(mesh).build(0.02));
    auto detector = std::make_shared<const ClodDetector>(mesh, set, FastLevel::Grid, 0.03);
    const SweptSphereQuery query(mesh, detector);
    for (double r : {0.005, 0.03}) {
      std::vector<Sweep> sweeps = sweepsNear(*mesh, 1500, r, 100 + m);
      expectSameAsBruteForce(*mesh, query, sweeps, r, "soup " + std::to_string(m) + " r " + std::to_string(r));
    }
  }
}

// A proxy's sweeps: the sphere resting on a finely tessellated surface (its centre at r, or a hair off, from a
// surface point along the face normal) and moving along it, slightly into it or out of it. Every coplanar or
// nearly coplanar neighbour is then within a hair of r over the sweep: the grazing cases the query's plane bound
// decides, on flat, concave and convex surfaces, near the origin and far from it.
TEST(SweptSphereQuery, SameAsBruteForceOnTheContactShell) {
  double (*const shapes[])(double, double) = {
      [](double, double) { return 0.0; },                         // flat
      [](double x, double y) { return 0.3 * (x * x + y * y); },   // bowl (concave from above)
      [](double x, double y) { return -0.3 * (x * x + y * y); },  // dome
      [](double x, double) { return 0.5 * std::abs(x); },         // V-groove
  };
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int s = 0; s < 4; ++s)
    for (const Vec3& shift : {Vec3(0, 0, 0), Vec3(3e3, -1e3, 2e2)}) {
      const Eigen::Matrix3d rotation = Eigen::AngleAxisd(0.3 + s, randomUnit(rng)).toRotationMatrix();
      auto mesh = std::make_shared<const TriangleMesh>(clod_test::heightField(80, shapes[s], rotation, shift));
      auto set = std::make_shared<const ClodSphereSet>(ClodBuilder(mesh).build(0.02));
      const double r = 0.08;  // triangles of 0.025: 3 to 4 across the radius, tens under the ball
      auto detector = std::make_shared<const ClodDetector>(mesh, set, FastLevel::Grid, r);
      const SweptSphereQuery withGrid(mesh, detector), treeOnly(mesh);
      std::vector<Sweep> sweeps;
      for (int i = 0; i < 1500; ++i) {
        const std::size_t t = static_cast<std::size_t>(u(rng) * 0.999 * static_cast<double>(mesh->size()));
        const double w0 = u(rng), w1 = u(rng) * (1.0 - w0);
        const Vec3 q = mesh->toModel(mesh->vertex(t, 0) + w0 * (mesh->vertex(t, 1) - mesh->vertex(t, 0)) +
                                     w1 * (mesh->vertex(t, 2) - mesh->vertex(t, 0)));
        Vec3 n = rotation * Vec3::UnitZ();
        n = mesh->normals[t].dot(n) > 0.0 ? Vec3(mesh->normals[t]) : Vec3(-mesh->normals[t]);
        const double hair[] = {0.0, 1e-12, -1e-12, 1e-9, 1e-6};
        const Vec3 a = q + n * r * (1.0 + hair[i % 5]);
        Vec3 tangent = randomUnit(rng);
        tangent = (tangent - tangent.dot(n) * n).normalized();
        const double normalPart[] = {0.0, -1e-3, 1e-3, -0.2};
        const double length = r * std::pow(10.0, -3.0 + 3.5 * u(rng));  // 0.001 r to 3 r
        sweeps.push_back({a, a + length * (tangent + normalPart[(i / 5) % 4] * n), static_cast<std::int32_t>(t)});
      }
      const std::string label = "shape " + std::to_string(s) + (shift.isZero() ? "" : " far");
      expectSameAsBruteForce(*mesh, withGrid, sweeps, r, label + " grid");
      expectSameAsBruteForce(*mesh, treeOnly, sweeps, r, label + " tree");
      // The grid's cell scan and the tree's leaves without their AVX2 filters (the form a CPU without AVX2 runs).
      detail::usePacketAvx2(false);
      expectSameAsBruteForce(*mesh, withGrid, sweeps, r, label + " grid, no AVX2");
      expectSameAsBruteForce(*mesh, treeOnly, sweeps, r, label + " tree, no AVX2");
      detail::usePacketAvx2(true);
    }
}

// Triangles far smaller than r crowd the grid's cells beyond ClodDetector::kTreeAboveEntries: a sweep that starts in
// or ends in such a cell goes through the tree over the mesh instead (its boxes judged by their distance to the part of
// the sweep inside them). A bumpy height field of 28,800 triangles at r = 0.2 (edges of 0.08 r): random sweeps near
// it, a proxy's sweeps resting on it and sweeps coming down into it from free space, every answer brute force's.
TEST(SweptSphereQuery, SameAsBruteForceInCrowdedCells) {
  auto mesh = std::make_shared<const TriangleMesh>(clod_test::heightField(
      120, [](double x, double y) { return 0.1 * std::sin(3.0 * x) * std::cos(2.0 * y); }, Eigen::Matrix3d::Identity(),
      Vec3(0.5, -0.25, 2.0)));
  auto set = std::make_shared<const ClodSphereSet>(ClodBuilder(mesh).build(0.02));
  const double r = 0.2;
  auto detector = std::make_shared<const ClodDetector>(mesh, set, FastLevel::Grid, r);
  const SweptSphereQuery query(mesh, detector);
  std::vector<Sweep> sweeps = sweepsNear(*mesh, 500, r, 41);
  std::mt19937_64 rng(43);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int i = 0; i < 300; ++i) {  // resting on the surface (a hair off), sliding along it, slightly in or out
    const std::size_t t = static_cast<std::size_t>(u(rng) * 0.999 * static_cast<double>(mesh->size()));
    const Vec3 q = mesh->toModel(mesh->centroid(t));
    const Vec3 n = mesh->normals[t].z() > 0.0 ? Vec3(mesh->normals[t]) : Vec3(-mesh->normals[t]);
    const Vec3 a = q + n * r * (1.0 + (i % 3) * 1e-9);
    Vec3 tangent = randomUnit(rng);
    tangent = (tangent - tangent.dot(n) * n).normalized();
    const double normalPart[] = {0.0, -1e-3, 1e-3};
    sweeps.push_back({a, a + r * (0.01 + u(rng)) * (tangent + normalPart[i % 3] * n), static_cast<std::int32_t>(t)});
  }
  for (int i = 0; i < 200; ++i) {  // a stylus coming down from free space into it: from a sparse cell to a crowded one
    const Vec3 q(0.5 + 2.0 * (u(rng) - 0.5), -0.25 + 2.0 * (u(rng) - 0.5), 2.0);
    const Vec3 a = q + Vec3(0.0, 0.0, r * (2.0 + 6.0 * u(rng)));
    sweeps.push_back({a, q + Vec3(0.2 * r * (u(rng) - 0.5), 0.2 * r * (u(rng) - 0.5), -r * u(rng))});
  }
  const CellGrid& grid = detector->grid();
  auto crowdedAt = [&](const Vec3& p) {
    const CellGrid::CellRef* ref = grid.find(grid.keyOf(mesh->toLocal(p)));
    return ref != nullptr && grid.cell(*ref).count > ClodDetector::kTreeAboveEntries;
  };
  std::size_t crowded = 0, intoCrowded = 0;
  for (const Sweep& w : sweeps) {
    crowded += crowdedAt(w.a);
    intoCrowded += !crowdedAt(w.a) && crowdedAt(w.b);
  }
  EXPECT_GT(crowded, sweeps.size() / 2) << "the height field must crowd the cells beyond kTreeAboveEntries";
  EXPECT_GT(intoCrowded, 20u) << "sweeps from a sparse cell into a crowded one";
  expectSameAsBruteForce(*mesh, query, sweeps, r, "crowded height field");
  detail::usePacketAvx2(false);  // the tree's leaves and small subtrees without the records' AVX2 filter
  expectSameAsBruteForce(*mesh, query, sweeps, r, "crowded height field, no AVX2");
  detail::usePacketAvx2(true);
}

#if defined(CLOD_PACKET_AVX2)
// The AVX2 filter of a cell scan against the double test it stands in front of (SweptSphereQuery::sweepCell):
// random entries and piece ends, the threshold set near the entries' bounds so that many sit a hair either side.
// It may keep more; it must never drop an entry the double test keeps.
TEST(CellScanAvx2, KeepsEveryEntryTheDoubleTestKeeps) {
  if (!__builtin_cpu_supports("avx2")) GTEST_SKIP() << "no AVX2 on this CPU";
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_int_distribution<int> byte(0, 255), signedByte(-127, 127);
  std::size_t kept = 0, dropped = 0, extra = 0;
  for (int round = 0; round < 20000; ++round) {
    const double h = std::pow(10.0, -4.0 + 4.0 * (0.5 + 0.5 * u(rng)));  // cells from 0.1 mm to 1 m
    const double unit = 1.5 * h / 255.0, along = 1.7320508075688772 / 254.0, slack = 0.01 * h;
    const Vec3 r0 = Vec3(u(rng), u(rng), u(rng)) * h, r1 = r0 + Vec3(u(rng), u(rng), u(rng)) * h * 0.5;
    const double n0 = r0.norm(), n1 = r1.norm();
    CellGrid::Entry e[8];
    double bound[8];
    for (int i = 0; i < 8; ++i) {
      e[i].triangle = static_cast<std::uint32_t>(i);
      e[i].distance = static_cast<std::uint8_t>(byte(rng));
      for (int k = 0; k < 3; ++k) e[i].direction[k] = static_cast<std::int8_t>(signedByte(rng));
      const double dc = e[i].distance * unit;
      const double u0 = (r0.x() * e[i].direction[0] + r0.y() * e[i].direction[1] + r0.z() * e[i].direction[2]) / 127.0;
      const double u1 = (r1.x() * e[i].direction[0] + r1.y() * e[i].direction[1] + r1.z() * e[i].direction[2]) / 127.0;
      bound[i] = std::min(u0 - along * n0, u1 - along * n1) + dc - slack;
    }
    // R at one entry's bound, nudged by a few ulps either way: the double test's edge.
    const double R = bound[round % 8] * (1.0 + 1e-15 * (round % 5 - 2));
    const detail::CellScanBounds b =
        detail::cellScanBounds(r0, r1, -along * n0, -along * n1, unit, R + slack, std::max(n0, n1) + slack);
    const unsigned mask = detail::cellScanBlockAvx2(e, b);
    for (int i = 0; i < 8; ++i) {
      const bool keep = !(bound[i] > R), got = (mask >> i) & 1u;
      kept += keep;
      dropped += keep && !got;
      extra += !keep && got;
    }
  }
  EXPECT_EQ(dropped, 0u);
  EXPECT_GT(kept, 10000u);
  EXPECT_LT(extra, kept / 10) << "a filter that keeps everything passes the first check and helps nobody";
}
// The records' AVX2 filter (SweptSphereQuery::sweepCell) against the geometry itself, not the scalar bounds it stands
// in front of: random triangles (records made as SweptSphereQuery makes them: bounding ball, unit normal, thickness)
// and sweeps passing them at every angle, the reach set at the least distance sampled along the sweep, nudged a few
// ulps either way. A triangle that some sampled centre comes within the reach of must be kept; most of the others
// should be dropped (the ball, the plane, and the plane and ball together).
TEST(RecordFilterAvx2, KeepsEveryTriangleASweepComesWithinReachOf) {
  if (!__builtin_cpu_supports("avx2")) GTEST_SKIP() << "no AVX2 on this CPU";
  std::mt19937_64 rng(29);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  clod_test::FilterTally tally;
  for (int round = 0; round < 4000; ++round) {
    double scale;  // triangles of 1 mm to 10 m
    const Vec3 a = clod_test::randomPoint(rng, round, scale);
    // In any direction, from a thousandth of the triangles' size to three times it; of zero length now and then.
    const Vec3 d =
        round % 7 == 0 ? Vec3(Vec3::Zero()) : Vec3(randomUnit(rng) * scale * std::pow(10.0, -3.0 + 3.5 * u(rng)));
    const double end = round % 3 == 0 ? u(rng) : 1.0;
    double record[4][8];
    const double* pointers[4];
    double nearest[4];
    for (int k = 0; k < 4; ++k) {
      Vec3 v[3];
      const Vec3 around = a + d * u(rng) + randomUnit(rng) * scale * (0.2 + 1.5 * u(rng));
      for (Vec3& corner : v) corner = around + randomUnit(rng) * scale * (k == 3 ? 2.0 : 0.5) * u(rng);
      if (round % 5 == 0) v[2] = v[0] + (v[1] - v[0]) * u(rng);  // degenerate now and then
      const Vec3 c = (v[0] + v[1] + v[2]) / 3.0;
      double rho = 0.0, thick = 0.0;
      for (const Vec3& corner : v) rho = std::max(rho, (corner - c).norm());
      const Vec3 cross = (v[1] - v[0]).cross(v[2] - v[0]);
      const Vec3 n = cross.norm() > 0.0 ? Vec3(cross.normalized()) : Vec3::Zero();
      for (const Vec3& corner : v) thick = std::max(thick, std::abs(n.dot(corner - c)));
      for (int j = 0; j < 3; ++j) {
        record[k][j] = c[j];
        record[k][4 + j] = n[j];
      }
      record[k][3] = rho;
      record[k][7] = thick * (1.0 + 1e-9) + 1e-12 * rho;
      pointers[k] = record[k];
      nearest[k] = std::numeric_limits<double>::infinity();
      for (int i = 0; i <= 400; ++i) {
        const Vec3 p = a + (end * i / 400.0) * d;
        nearest[k] = std::min(nearest[k], (closestPointOnTriangle(p, v[0], v[1], v[2]) - p).norm());
      }
    }
    // The reach at one triangle's sampled distance (that one sits on the edge), the others by their own chance.
    const double reach = nearest[round % 4] * (1.0 + 1e-15 * (round % 5 - 2)) + (round % 4 == 3 ? 0.0 : 1e-300);
    const double dd = d.squaredNorm();
    const detail::RecordFilterSweep sweep{
        {a.x(), a.y(), a.z()}, {d.x(), d.y(), d.z()}, end, dd > 0.0 ? 1.0 / dd : 0.0, reach, reach};
    const unsigned mask = detail::recordFilterAvx2(pointers, sweep);
    for (int k = 0; k < 4; ++k) tally.count(nearest[k] <= reach, (mask >> k) & 1u);
  }
  tally.expectConservative(2000, "triangles");
}
#endif

TEST(SweptSphereQuery, AllocatesNothing) {
  auto mesh = clod_test::loadNormalized(clod_test::sharedMesh("elephant.off"));
  auto set = std::make_shared<const ClodSphereSet>(ClodBuilder(mesh).build(0.01));
  auto detector = std::make_shared<const ClodDetector>(mesh, set, FastLevel::Grid, 0.02);
  const SweptSphereQuery query(mesh, detector);
  const std::vector<Sweep> sweeps = sweepsNear(*mesh, 500, 0.01, 5);
  SweptContact c;
  gAllocations = 0;
  gCounting = true;
  for (const Sweep& s : sweeps) {
    query.sweep(s.a, s.b, 0.01, c);  // grid
    query.sweep(s.a, s.b, 0.05, c);  // tree
  }
  gCounting = false;
  EXPECT_EQ(gAllocations.load(), 0);
}

TEST(SweptSphereQuery, RejectsAnotherMeshsDetector) {
  auto mesh = clod_test::loadNormalized(clod_test::sharedMesh("head.off"));
  auto other = clod_test::loadNormalized(clod_test::sharedMesh("head.off"));
  auto set = std::make_shared<const ClodSphereSet>(ClodBuilder(mesh).build(0.01));
  auto detector = std::make_shared<const ClodDetector>(mesh, set, FastLevel::Grid, 0.02);
  EXPECT_THROW(SweptSphereQuery(other, detector), InvalidParameter);
  EXPECT_THROW(SweptSphereQuery(nullptr), InvalidParameter);
}

}  // namespace
