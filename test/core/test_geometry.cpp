// Geometry primitives against independent references: closest point on a triangle (plane projection
// plus the three segments, in long double, and dense barycentric sampling), the paper's
// projection test, and the ray-triangle test.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include "clod_haptics/core/geometry.h"
#include "simd/closest_point_avx2.h"
#include "simd/dispatch.h"

namespace {

using namespace clod_haptics;
using LD = long double;
using V = Eigen::Matrix<LD, 3, 1>;

V toL(const Vec3& v) { return v.cast<LD>(); }

V segmentClosest(const V& p, const V& a, const V& b) {
  const V ab = b - a;
  const LD len2 = ab.squaredNorm();
  if (len2 == 0) return a;
  LD t = (p - a).dot(ab) / len2;
  t = std::min<LD>(1, std::max<LD>(0, t));
  return a + t * ab;
}

// Barycentric coordinates (u, v, w) of the plane projection of p, in long double; false when the
// triangle has no area at this precision.
bool barycentric(const V& p, const V& a, const V& b, const V& c, LD& u, LD& v, LD& w) {
  const V e0 = b - a, e1 = c - a, q = p - a;
  const LD d00 = e0.dot(e0), d01 = e0.dot(e1), d11 = e1.dot(e1), d20 = q.dot(e0), d21 = q.dot(e1);
  const LD den = d00 * d11 - d01 * d01;
  if (!(den > 0)) return false;
  v = (d11 * d20 - d01 * d21) / den;
  w = (d00 * d21 - d01 * d20) / den;
  u = 1 - v - w;
  return true;
}

// Reference distance: the plane projection when it falls inside, else the nearest of the three edges.
LD referenceDistance(const Vec3& pd, const Vec3& ad, const Vec3& bd, const Vec3& cd) {
  const V p = toL(pd), a = toL(ad), b = toL(bd), c = toL(cd);
  LD best = std::min({(p - segmentClosest(p, a, b)).norm(), (p - segmentClosest(p, b, c)).norm(),
                      (p - segmentClosest(p, c, a)).norm()});
  LD u, v, w;
  if (barycentric(p, a, b, c, u, v, w) && u >= 0 && v >= 0 && w >= 0) {
    const V q = u * a + v * b + w * c;
    best = std::min(best, (p - q).norm());
  }
  return best;
}

struct Case {
  Vec3 p, a, b, c;
};

// Random triangles of several shapes: regular, slivers (one tiny height), needles (two nearly equal
// vertices), zero-area (collinear, two or three identical vertices), and large offsets.
Case randomCase(std::mt19937_64& rng, int kind) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto rv = [&]() { return Vec3(u(rng), u(rng), u(rng)); };
  Case k;
  k.a = rv();
  k.b = rv();
  k.c = rv();
  switch (kind % 7) {
    case 0:
    case 1:
      break;
    case 2: {  // sliver: c almost on ab
      const double t = 0.5 + 0.5 * u(rng);
      k.c = k.a + t * (k.b - k.a) + std::pow(10.0, -3.0 - 10.0 * std::abs(u(rng))) * rv();
      break;
    }
    case 3:  // needle
      k.b = k.a + std::pow(10.0, -4.0 - 8.0 * std::abs(u(rng))) * rv();
      break;
    case 4: {  // exactly collinear (on a lattice, so collinear in double too)
      const Vec3 d = Vec3(std::round(8 * u(rng)), std::round(8 * u(rng)), std::round(8 * u(rng))) / 8.0;
      k.b = k.a + d;
      k.c = k.a + 2.0 * d;
      break;
    }
    case 5:  // two identical vertices, or all three
      k.b = k.a;
      if (u(rng) > 0) k.c = k.a;
      break;
    case 6: {  // far from the origin
      const Vec3 o = 1e3 * rv();
      k.a += o;
      k.b += o;
      k.c += o;
      break;
    }
  }
  const Vec3 centre = (k.a + k.b + k.c) / 3.0;
  const double size = std::max({(k.a - k.b).norm(), (k.b - k.c).norm(), (k.c - k.a).norm(), 1e-3});
  k.p = centre + size * 1.5 * rv();
  return k;
}

TEST(ClosestPointOnTriangle, MatchesProjectionAndSegmentsReference) {
  std::mt19937_64 rng(12345);
  const int kCases = 70000;
  int faces = 0, edges = 0, vertices = 0;
  for (int i = 0; i < kCases; ++i) {
    const Case k = randomCase(rng, i);
    TriangleRegion region;
    const Vec3 q = closestPointOnTriangle(k.p, k.a, k.b, k.c, &region);
    const TriangleFeature feature = region.feature;
    ASSERT_TRUE(q.allFinite()) << "case " << i;
    const double size = std::max({(k.a - k.b).norm(), (k.b - k.c).norm(), (k.c - k.a).norm()});
    const double scale = std::max({size, (k.p - k.a).norm(), k.a.cwiseAbs().maxCoeff()});
    const double tol = 1e-12 * scale;
    const LD ref = referenceDistance(k.p, k.a, k.b, k.c);
    const double got = (k.p - q).norm();
    ASSERT_NEAR(got, static_cast<double>(ref), tol) << "case " << i << " kind " << i % 7;
    // The answer lies on the triangle.
    ASSERT_LE(static_cast<double>(referenceDistance(q, k.a, k.b, k.c)), tol) << "case " << i;
    // The feature is what it says.
    if (feature == TriangleFeature::Vertex) {
      ++vertices;  // exactly a corner, or an edge's end to rounding (parameter 0 or 1)
      ASSERT_LE(std::min({(q - k.a).norm(), (q - k.b).norm(), (q - k.c).norm()}), tol) << "case " << i;
    } else if (feature == TriangleFeature::Edge) {
      ++edges;
      const double onEdge = std::min({(q - closestPointOnSegment(q, k.a, k.b)).norm(),
                                      (q - closestPointOnSegment(q, k.b, k.c)).norm(),
                                      (q - closestPointOnSegment(q, k.c, k.a)).norm()});
      ASSERT_LE(onEdge, tol) << "case " << i;
    } else {
      ++faces;
      LD u, v, w;
      ASSERT_TRUE(barycentric(toL(k.p), toL(k.a), toL(k.b), toL(k.c), u, v, w)) << "case " << i;
      ASSERT_GE(static_cast<double>(std::min({u, v, w})), -1e-9) << "face answer outside the face, case " << i;
    }
  }
  // Every feature is exercised.
  EXPECT_GT(faces, 500);
  EXPECT_GT(edges, 1000);
  EXPECT_GT(vertices, 1000);
}

TEST(ClosestPointOnTriangle, NeverFartherThanDenseBarycentricSamples) {
  std::mt19937_64 rng(777);
  for (int i = 0; i < 3000; ++i) {
    const Case k = randomCase(rng, i);
    const Vec3 q = closestPointOnTriangle(k.p, k.a, k.b, k.c);
    const double got = (k.p - q).norm();
    const int n = 40;
    double sampled = std::numeric_limits<double>::infinity();
    for (int s = 0; s <= n; ++s)
      for (int t = 0; s + t <= n; ++t) {
        const double u = double(s) / n, v = double(t) / n;
        const Vec3 x = k.a + u * (k.b - k.a) + v * (k.c - k.a);
        sampled = std::min(sampled, (k.p - x).norm());
      }
    const double scale = std::max({(k.a - k.b).norm(), (k.b - k.c).norm(), (k.p - k.a).norm(), k.a.norm()});
    ASSERT_LE(got, sampled + 1e-12 * scale) << "case " << i;
  }
}

TEST(ClosestPointOnTriangle, PointsOnTheTriangleAreTheirOwnClosestPoint) {
  std::mt19937_64 rng(99);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int i = 0; i < 20000; ++i) {
    const Case k = randomCase(rng, i % 2 == 0 ? 0 : 6);
    double s = u(rng), t = u(rng);
    if (s + t > 1) {
      s = 1 - s;
      t = 1 - t;
    }
    const Vec3 x = k.a + s * (k.b - k.a) + t * (k.c - k.a);
    const Vec3 q = closestPointOnTriangle(x, k.a, k.b, k.c);
    const double scale = std::max({(k.a - k.b).norm(), (k.b - k.c).norm(), k.a.cwiseAbs().maxCoeff()});
    ASSERT_LE((q - x).norm(), 1e-12 * scale) << "case " << i;
  }
  // Corners exactly.
  const Vec3 a(0.1, 0.2, 0.3), b(1.7, 0.2, -0.4), c(0.3, 2.2, 0.9);
  TriangleRegion f;
  EXPECT_EQ(closestPointOnTriangle(a, a, b, c, &f), a);
  EXPECT_EQ(f.feature, TriangleFeature::Vertex);
  EXPECT_EQ(closestPointOnTriangle(b, a, b, c, &f), b);
  EXPECT_EQ(closestPointOnTriangle(c, a, b, c, &f), c);
}

TEST(ClosestPointOnTriangle, ZeroAreaTrianglesGiveFiniteAnswersOnTheirSegments) {
  const Vec3 p(0.3, 0.7, -0.2);
  const Vec3 a(0, 0, 0);
  TriangleRegion f;
  EXPECT_EQ(closestPointOnTriangle(p, a, a, a, &f), a);
  const Vec3 b(1, 1, 1), c(2, 2, 2);
  for (const auto& tri : {std::array<Vec3, 3>{a, b, c}, std::array<Vec3, 3>{c, a, b}, std::array<Vec3, 3>{b, c, a},
                          std::array<Vec3, 3>{a, c, c}, std::array<Vec3, 3>{a, a, c}}) {
    const Vec3 q = closestPointOnTriangle(p, tri[0], tri[1], tri[2], &f);
    ASSERT_TRUE(q.allFinite());
    const Vec3 expected = closestPointOnSegment(p, a, c);
    EXPECT_LE((q - expected).norm(), 1e-15);
  }
}

// Asking for the region does not change the point, bit for bit (the detector's hot loop asks for none and
// finishContact asks once), and the region names where the point is.
TEST(ClosestPointOnTriangle, SamePointWithTheRegionAndTheRegionNamesTheFeature) {
  std::mt19937_64 rng(4242);
  int faces = 0, edges = 0, vertices = 0;
  for (int i = 0; i < 70000; ++i) {
    const Case k = randomCase(rng, i);
    const Vec3 fast = closestPointOnTriangle(k.p, k.a, k.b, k.c);
    TriangleRegion region;
    const Vec3 q = closestPointOnTriangle(k.p, k.a, k.b, k.c, &region);
    ASSERT_EQ(q, fast) << "case " << i;
    const Vec3 corner[3] = {k.a, k.b, k.c};
    if (region.feature == TriangleFeature::Vertex) {
      ++vertices;
      ASSERT_LT(region.index, 3);
      // At that vertex (to rounding, when an edge parameter reached its end).
      const double size = std::max({(k.a - k.b).norm(), (k.b - k.c).norm(), (k.c - k.a).norm(), 1.0});
      ASSERT_LE((q - corner[region.index]).norm(), 1e-12 * size) << "case " << i;
    } else if (region.feature == TriangleFeature::Edge) {
      ++edges;
      ASSERT_LT(region.index, 3);
      const Vec3 a = corner[region.index], b = corner[(region.index + 1) % 3];
      const double scale = std::max({(b - a).norm(), a.cwiseAbs().maxCoeff(), 1.0});
      ASSERT_LE((q - closestPointOnSegment(q, a, b)).norm(), 1e-12 * scale) << "case " << i;
    } else {
      ++faces;
      ASSERT_EQ(region.index, 0);
      // Inside the triangle: its projection onto the plane is inside too.
      Vec3 projected;
      const Vec3 n = (k.b - k.a).cross(k.c - k.a).normalized();
      if (n.allFinite() && (k.b - k.a).cross(k.c - k.a).norm() > 1e-6 * (k.b - k.a).squaredNorm()) {
        EXPECT_TRUE(projectInsideTriangle(q + 1e-9 * n, k.a, k.b, k.c, n, projected) ||
                    (q - projected).norm() < 1e-9) << "case " << i;
      }
    }
  }
  EXPECT_GT(faces, 500);
  EXPECT_GT(edges, 1000);
  EXPECT_GT(vertices, 1000);
}

TEST(ClosestPointOnTriangle, RegionsOfCornersEdgesAndZeroArea) {
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  TriangleRegion r;
  EXPECT_EQ(closestPointOnTriangle(Vec3(-1, -1, 1), a, b, c, &r), a);
  EXPECT_EQ(r.feature, TriangleFeature::Vertex);
  EXPECT_EQ(r.index, 0);
  closestPointOnTriangle(Vec3(2, -0.5, 0), a, b, c, &r);
  EXPECT_EQ(r.feature, TriangleFeature::Vertex);
  EXPECT_EQ(r.index, 1);
  closestPointOnTriangle(Vec3(-0.5, 2, 0), a, b, c, &r);
  EXPECT_EQ(r.feature, TriangleFeature::Vertex);
  EXPECT_EQ(r.index, 2);
  closestPointOnTriangle(Vec3(0.5, -1, 0.3), a, b, c, &r);  // below edge ab
  EXPECT_EQ(r.feature, TriangleFeature::Edge);
  EXPECT_EQ(r.index, 0);
  closestPointOnTriangle(Vec3(1, 1, -0.3), a, b, c, &r);  // beyond edge bc
  EXPECT_EQ(r.feature, TriangleFeature::Edge);
  EXPECT_EQ(r.index, 1);
  closestPointOnTriangle(Vec3(-1, 0.5, 0.2), a, b, c, &r);  // beside edge ca
  EXPECT_EQ(r.feature, TriangleFeature::Edge);
  EXPECT_EQ(r.index, 2);
  closestPointOnTriangle(Vec3(0.2, 0.2, -3), a, b, c, &r);
  EXPECT_EQ(r.feature, TriangleFeature::Face);
  // Zero area: its segments answer, an end of one a vertex.
  const Vec3 d(2, 0, 0);
  const Vec3 q = closestPointOnTriangle(Vec3(0.5, 1, 0), a, b, d, &r);
  EXPECT_EQ(q, closestPointOnTriangle(Vec3(0.5, 1, 0), a, b, d));
  EXPECT_EQ(r.feature, TriangleFeature::Edge);
  closestPointOnTriangle(Vec3(3, 1, 0), a, b, d, &r);
  EXPECT_EQ(r.feature, TriangleFeature::Vertex);
  EXPECT_EQ(r.index, 2);
}

TEST(ClosestPointOnSegment, ClampsAndHandlesZeroLength) {
  const Vec3 a(0, 0, 0), b(2, 0, 0);
  EXPECT_EQ(closestPointOnSegment(Vec3(-1, 1, 0), a, b), a);
  EXPECT_EQ(closestPointOnSegment(Vec3(3, 1, 0), a, b), b);
  EXPECT_TRUE(closestPointOnSegment(Vec3(0.5, 1, 0), a, b).isApprox(Vec3(0.5, 0, 0)));
  EXPECT_EQ(closestPointOnSegment(Vec3(0.5, 1, 0), a, a), a);
}

TEST(ProjectInsideTriangle, AgreesWithBarycentricReference) {
  std::mt19937_64 rng(4242);
  int inside = 0, outside = 0;
  for (int i = 0; i < 50000; ++i) {
    const Case k = randomCase(rng, i % 2 == 0 ? 0 : 6);
    const Vec3 n = (k.b - k.a).cross(k.c - k.a).normalized();
    Vec3 q;
    const bool got = projectInsideTriangle(k.p, k.a, k.b, k.c, n, q);
    LD u, v, w;
    ASSERT_TRUE(barycentric(toL(k.p), toL(k.a), toL(k.b), toL(k.c), u, v, w));
    const double m = static_cast<double>(std::min({u, v, w}));
    if (m > 1e-9) {
      ASSERT_TRUE(got) << "case " << i << " min barycentric " << m;
    } else if (m < -1e-9) {
      ASSERT_FALSE(got) << "case " << i << " min barycentric " << m;
    }
    if (got) {
      ++inside;
      // q is the orthogonal projection: in the plane, and p - q along n.
      const double scale = std::max((k.p - k.a).norm(), k.a.cwiseAbs().maxCoeff());
      EXPECT_NEAR((q - k.a).dot(n), 0.0, 1e-12 * scale);
      EXPECT_LE((k.p - q).cross(n).norm(), 1e-12 * scale);
      // And, inside, it is the closest point.
      EXPECT_LE((q - closestPointOnTriangle(k.p, k.a, k.b, k.c)).norm(), 1e-9 * scale);
    } else {
      ++outside;
    }
  }
  EXPECT_GT(inside, 1000);
  EXPECT_GT(outside, 2000);
}

TEST(ProjectInsideTriangle, ZeroNormalIsOutside) {
  Vec3 q;
  EXPECT_FALSE(projectInsideTriangle(Vec3(0, 0, 1), Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(2, 0, 0), Vec3::Zero(), q));
}

TEST(ProjectInsideTriangle, BoundaryIsInside) {
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0), n(0, 0, 1);
  Vec3 q;
  EXPECT_TRUE(projectInsideTriangle(Vec3(0.5, 0, 3), a, b, c, n, q));  // on an edge
  EXPECT_TRUE(projectInsideTriangle(Vec3(0, 0, -3), a, b, c, n, q));   // on a vertex, from behind
  EXPECT_EQ(q, a);
  EXPECT_FALSE(projectInsideTriangle(Vec3(0.6, 0.6, 1), a, b, c, n, q));
}

TEST(RayTriangle, HitsAndMissesAgainstConstruction) {
  std::mt19937_64 rng(2024);
  std::uniform_real_distribution<double> u(0.0, 1.0), s(-1.0, 1.0);
  int hits = 0;
  for (int i = 0; i < 50000; ++i) {
    const Case k = randomCase(rng, i % 2 == 0 ? 0 : 6);
    const Vec3 n = (k.b - k.a).cross(k.c - k.a).normalized();
    // A target well inside or well outside the triangle.
    double b1 = u(rng), b2 = u(rng);
    if (b1 + b2 > 1) {
      b1 = 1 - b1;
      b2 = 1 - b2;
    }
    const bool wantInside = i % 3 != 0;
    Vec3 target;
    if (wantInside) {
      if (std::min({b1, b2, 1 - b1 - b2}) < 0.02) continue;
      target = k.a + b1 * (k.b - k.a) + b2 * (k.c - k.a);
    } else {
      target = k.a + (1.05 + u(rng)) * (k.b - k.a) + (0.05 + u(rng)) * (k.c - k.a);  // u + v > 1.1
    }
    Vec3 dir(s(rng), s(rng), s(rng));
    if (std::abs(dir.normalized().dot(n)) < 0.2) continue;  // keep grazing rays out of the construction
    const double t0 = 0.1 + 3.0 * u(rng);
    const bool forward = i % 5 != 0;
    const Vec3 origin = forward ? Vec3(target - t0 * dir) : Vec3(target + t0 * dir);  // behind: ray goes away
    double t = -1;
    const bool got = rayTriangle(origin, dir, k.a, k.b, k.c, t);
    if (wantInside && forward) {
      ASSERT_TRUE(got) << "case " << i;
      ASSERT_NEAR(t, t0, 1e-9 * t0) << "case " << i;
      ++hits;
    } else {
      ASSERT_FALSE(got) << "case " << i << " inside " << wantInside << " forward " << forward;
    }
  }
  EXPECT_GT(hits, 10000);
}

TEST(RayTriangle, ParallelAndDegenerate) {
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  double t;
  EXPECT_FALSE(rayTriangle(Vec3(0.2, 0.2, 1), Vec3(1, 0, 0), a, b, c, t));        // parallel to the plane
  EXPECT_FALSE(rayTriangle(Vec3(0.2, 0.2, 1), Vec3(0, 0, -1), a, b, 2 * b, t));  // zero-area triangle
  EXPECT_TRUE(rayTriangle(Vec3(0.2, 0.2, -1), Vec3(0, 0, 1), a, b, c, t));       // back face counts
  EXPECT_DOUBLE_EQ(t, 1.0);
  EXPECT_FALSE(rayTriangle(Vec3(0.2, 0.2, 1), Vec3(0, 0, 1), a, b, c, t));  // triangle behind the origin
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(rayTriangle(Vec3(0.2, 0.2, 1), Vec3(nan, 0, -1), a, b, c, t));
}

TEST(SquaredDistanceToBox, MatchesPerAxisDefinition) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  for (int i = 0; i < 10000; ++i) {
    Vec3 lo(u(rng), u(rng), u(rng)), hi(u(rng), u(rng), u(rng));
    const Vec3 mn = lo.cwiseMin(hi), mx = lo.cwiseMax(hi);
    const Vec3 p(u(rng), u(rng), u(rng));
    double ref = 0;
    for (int k = 0; k < 3; ++k) {
      const double d = p[k] < mn[k] ? mn[k] - p[k] : (p[k] > mx[k] ? p[k] - mx[k] : 0.0);
      ref += d * d;
    }
    ASSERT_DOUBLE_EQ(squaredDistanceToBox(p, mn, mx), ref);
  }
}

#if defined(CLOD_PACKET_AVX2)
std::uint64_t bitsOf(double x) {
  std::uint64_t b;
  std::memcpy(&b, &x, sizeof b);
  return b;
}

// Whether lane of out holds closestPointOnTriangle(p, a, b, c)'s point, squared distance and feature, bit for bit.
::testing::AssertionResult sameAsScalar(const detail::ClosestPoints4& out, int lane, const Vec3& p, const Vec3& a,
                                        const Vec3& b, const Vec3& c) {
  TriangleRegion region;
  const Vec3 q = closestPointOnTriangle(p, a, b, c, &region);
  for (int j = 0; j < 3; ++j)
    if (bitsOf(out.q[j][lane]) != bitsOf(q[j])) return ::testing::AssertionFailure() << "coordinate " << j;
  if (bitsOf(out.d2[lane]) != bitsOf((p - q).squaredNorm())) return ::testing::AssertionFailure() << "squared distance";
  const TriangleRegion got = out.region(static_cast<unsigned>(lane));
  if (got.feature != region.feature || got.index != region.index) return ::testing::AssertionFailure() << "feature";
  return ::testing::AssertionSuccess();
}

// The AVX2 kernel of the grid's scan claims closestPointOnTriangle's values bit for bit on every lane it computes
// (the scalar function is checked against the long-double reference above), and leaves to it only the zero-area
// fallback: on every kind of triangle of randomCase, four at a time, each region met many times.
TEST(ClosestPointsAvx2, SameBitsAsTheScalarFunctionOnEveryLaneItComputes) {
  if (!detail::packetAvx2()) GTEST_SKIP() << "no AVX2 on this CPU";
  std::mt19937_64 rng(17);
  int regions[7] = {}, leftOut = 0, leftOutRegular = 0;
  for (int i = 0; i < 50000; ++i) {
    Case k[4];
    const Vec3 *a[4], *b[4], *c[4];
    for (int lane = 0; lane < 4; ++lane) {
      k[lane] = randomCase(rng, i + lane);
      k[lane].p = k[0].p;  // one point per call, as the scan asks
      a[lane] = &k[lane].a;
      b[lane] = &k[lane].b;
      c[lane] = &k[lane].c;
    }
    detail::ClosestPoints4 out;
    const unsigned computed = detail::closestPointsAvx2(k[0].p, a, b, c, out);
    for (int lane = 0; lane < 4; ++lane) {
      if (!(computed & (1u << lane))) {
        ++leftOut;
        leftOutRegular += (i + lane) % 7 < 2;
        continue;
      }
      ASSERT_TRUE(sameAsScalar(out, lane, k[0].p, k[lane].a, k[lane].b, k[lane].c)) << "case " << i << " lane " << lane;
      ++regions[static_cast<int>(out.kind[lane])];
    }
  }
  for (int r = 0; r < 7; ++r) EXPECT_GT(regions[r], 1000) << "region " << r << " barely met";
  EXPECT_GT(leftOut, 0);          // the degenerate kinds do reach the fallback
  EXPECT_LT(leftOutRegular, 50);  // regular triangles hardly ever
}

// The grid's build asks the other way round: four points (cell centres) against one triangle. The same claim.
TEST(ClosestPointsAvx2, FourPointsAgainstOneTriangleSameBitsAsTheScalarFunction) {
  if (!detail::packetAvx2()) GTEST_SKIP() << "no AVX2 on this CPU";
  std::mt19937_64 rng(23);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int regions[7] = {}, leftOut = 0;
  for (int i = 0; i < 50000; ++i) {
    const Case k = randomCase(rng, i);
    const Vec3 centre = (k.a + k.b + k.c) / 3.0;
    const double size = std::max({(k.a - k.b).norm(), (k.b - k.c).norm(), (k.c - k.a).norm(), 1e-3});
    Vec3 points[4];
    const Vec3* p[4];
    for (int lane = 0; lane < 4; ++lane) {
      points[lane] = centre + size * 1.5 * Vec3(u(rng), u(rng), u(rng));
      p[lane] = &points[lane];
    }
    detail::ClosestPoints4 out;
    const unsigned computed = detail::closestPointsAvx2(p, k.a, k.b, k.c, out);
    for (int lane = 0; lane < 4; ++lane) {
      if (!(computed & (1u << lane))) {
        ++leftOut;
        continue;
      }
      ASSERT_TRUE(sameAsScalar(out, lane, points[lane], k.a, k.b, k.c)) << "case " << i << " lane " << lane;
      ++regions[static_cast<int>(out.kind[lane])];
    }
  }
  for (int r = 0; r < 7; ++r) EXPECT_GT(regions[r], 1000) << "region " << r << " barely met";
  EXPECT_GT(leftOut, 0);  // the degenerate kinds do reach the fallback
}
#endif

}  // namespace
