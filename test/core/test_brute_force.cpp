// bruteForceQuery, the reference every other test trusts: checked against a loop written here over
// closestPointOnTriangle, the tie rule (lowest index), the contact boundary and the normal.

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <vector>

#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/contact.h"
#include "clod_haptics/core/geometry.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/probes.h"
#include "test_helpers.h"

namespace {

using namespace clod_haptics;

TEST(BruteForce, MatchesAnIndependentLoop) {
  const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh("head.off"));
  auto probes = nearSurfaceProbes(*mesh, 2000, 0.03, 4);
  const auto u = uniformProbes(*mesh, 500, 0.03, 5);
  probes.insert(probes.end(), u.begin(), u.end());
  std::size_t contacts = 0;
  for (const Vec3& p : probes) {
    double best = std::numeric_limits<double>::infinity();
    std::size_t bestT = 0;
    for (std::size_t t = 0; t < mesh->size(); ++t) {
      const double d = (p - closestPointOnTriangle(p, mesh->vertex(t, 0), mesh->vertex(t, 1), mesh->vertex(t, 2))).norm();
      if (d < best) {
        best = d;
        bestT = t;
      }
    }
    const double r = 0.01;
    const ContactResult c = bruteForceQuery(*mesh, p, r);
    ASSERT_EQ(c.contact, best <= r) << p.transpose();
    ASSERT_EQ(c.trianglesTested, mesh->size());
    if (!c.contact) continue;
    ++contacts;
    EXPECT_NEAR(c.distance, best, 1e-15);
    EXPECT_EQ(std::size_t(c.triangle), bestT);
    EXPECT_EQ(c.inside, pointBehindSurface(*mesh, p, bestT, c.point));
    EXPECT_DOUBLE_EQ(c.depth, c.inside ? r + c.distance : r - c.distance);
    EXPECT_NEAR((p - c.point).norm(), c.distance, 1e-15);
    EXPECT_NEAR(c.normal.norm(), 1.0, 1e-12);
    if (c.distance > 0.0) {
      // Outward: from the point towards the centre outside, away from it inside.
      EXPECT_NEAR(c.normal.dot(p - c.point), c.inside ? -c.distance : c.distance, 1e-12);
    }
    EXPECT_EQ(c.sphere, -1);
  }
  EXPECT_GT(contacts, 500u);
}

TEST(BruteForce, TiesGoToTheLowestIndexAndBoundaryCounts) {
  // Two coincident triangles (the second listed first in index order is the lower one).
  const auto mesh = std::make_shared<const TriangleMesh>(makeMesh(
      {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)}, {{0, 1, 2}, {0, 2, 1}, {0, 1, 2}}, "coincident"));
  ContactResult c = bruteForceQuery(*mesh, Vec3(0.25, 0.25, 0.5), 0.5);
  ASSERT_TRUE(c.contact) << "distance exactly r is a contact";
  EXPECT_EQ(c.triangle, 0);
  EXPECT_EQ(c.distance, 0.5);
  EXPECT_TRUE(c.normal.isApprox(Vec3(0, 0, 1)));
  EXPECT_FALSE(bruteForceQuery(*mesh, Vec3(0.25, 0.25, 0.5), std::nextafter(0.5, 0.0)).contact);
  // From behind triangle 0 (the tie winner; an open sheet, so the face's side decides): inside, the
  // normal on that face's side so the penalty force pushes out through the front, depth r + distance.
  c = bruteForceQuery(*mesh, Vec3(0.25, 0.25, -0.5), 1.0);
  ASSERT_TRUE(c.contact);
  EXPECT_EQ(c.triangle, 0);
  EXPECT_TRUE(c.inside);
  EXPECT_EQ(c.depth, 1.5);
  EXPECT_TRUE(c.normal.isApprox(Vec3(0, 0, 1)));
  // On the surface: the face normal.
  c = bruteForceQuery(*mesh, Vec3(0.25, 0.25, 0.0), 0.0);
  ASSERT_TRUE(c.contact);
  EXPECT_EQ(c.distance, 0.0);
  EXPECT_FALSE(c.inside) << "on the surface is outside";
  EXPECT_TRUE(c.normal.isApprox(Vec3(0, 0, 1)));
}

TEST(BruteForce, InvalidInputIsNoContact) {
  const auto mesh = clod_test::loadNormalized(clod_test::testData("cube.obj"));
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(bruteForceQuery(*mesh, Vec3(nan, 0, 0), 1.0).contact);
  EXPECT_FALSE(bruteForceQuery(*mesh, Vec3(0, inf, 0), 1.0).contact);
  EXPECT_FALSE(bruteForceQuery(*mesh, Vec3(0.5, 0.5, 0.5), nan).contact);
  EXPECT_FALSE(bruteForceQuery(*mesh, Vec3(0.5, 0.5, 0.5), -1.0).contact);
  EXPECT_FALSE(bruteForceQuery(*mesh, Vec3(0.5, 0.5, 0.5), inf).contact);
}

// --- The sign rule (pointBehindSurface) against geometric truth -------------------------------------

// A UV sphere of radius 1 whose vertex radii are scaled by radius(k): star-shaped around the origin
// whatever the radii (every vertex keeps its direction), convex for constant radii, with concave edges
// and vertices (saddles, pits) for varying ones. Closed, consistently wound outward.
TriangleMesh radialMesh(int rings, int sectors, const std::function<double(std::size_t)>& radius) {
  std::vector<Vec3> v;
  std::vector<Triangle> t;
  v.emplace_back(0, 0, radius(0));  // north pole
  for (int i = 1; i < rings; ++i) {
    const double theta = M_PI * i / rings;
    for (int j = 0; j < sectors; ++j) {
      const double phi = 2 * M_PI * j / sectors;
      const Vec3 dir(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
      v.push_back(radius(v.size()) * dir);
    }
  }
  v.emplace_back(0, 0, -radius(v.size()));  // south pole
  const auto id = [&](int ring, int j) { return std::uint32_t(1 + (ring - 1) * sectors + (j % sectors)); };
  const std::uint32_t south = std::uint32_t(v.size() - 1);
  for (int j = 0; j < sectors; ++j) t.push_back({0, id(1, j), id(1, j + 1)});
  for (int i = 1; i + 1 < rings; ++i)
    for (int j = 0; j < sectors; ++j) {
      t.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      t.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
  for (int j = 0; j < sectors; ++j) t.push_back({id(rings - 1, j), south, id(rings - 1, j + 1)});
  return makeMesh(std::move(v), std::move(t), "radial");
}

// Truth for a star-shaped mesh around the origin: p is inside when it is nearer the origin than the
// surface along the ray from the origin through p. Returns false (no verdict) within margin of the surface.
bool starInside(const TriangleMesh& mesh, const Vec3& p, double margin, bool& inside) {
  const double len = p.norm();
  if (len < margin) {
    inside = true;
    return true;
  }
  const Vec3 dir = p / len;
  for (std::size_t t = 0; t < mesh.size(); ++t) {
    double hit;
    if (rayTriangle(Vec3::Zero(), dir, mesh.vertex(t, 0), mesh.vertex(t, 1), mesh.vertex(t, 2), hit)) {
      if (std::abs(hit - len) < margin) return false;
      inside = len < hit;
      return true;
    }
  }
  return false;
}

// Probes near the surface (most of them, where faces, edges and vertices are closest) and in the whole
// box; the sign of each against the truth, counting which feature decided.
void expectSignsMatchTruth(const TriangleMesh& mesh, std::uint64_t seed, std::size_t count) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.6, 1.6), unit(0.0, 1.0), offset(-0.15, 0.15);
  std::size_t checked = 0, inside = 0, byFeature[3] = {0, 0, 0};
  for (std::size_t k = 0; k < count; ++k) {
    Vec3 p;
    if (k % 3 == 0) {
      p = Vec3(u(rng), u(rng), u(rng));
    } else {  // near a vertex or an edge of a random triangle (where the pseudo-normals matter)
      const std::size_t t = rng() % mesh.size();
      const double a = unit(rng), b = k % 3 == 1 ? 0.0 : unit(rng) * (1 - a);
      p = mesh.vertex(t, 0) + a * (mesh.vertex(t, 1) - mesh.vertex(t, 0)) + b * (mesh.vertex(t, 2) - mesh.vertex(t, 0)) +
          Vec3(offset(rng), offset(rng), offset(rng));
    }
    bool truth;
    if (!starInside(mesh, p, 1e-9, truth)) continue;
    const ContactResult c = bruteForceQuery(mesh, p, 10.0);  // always a contact: the nearest feature
    ASSERT_TRUE(c.contact);
    TriangleRegion region;
    closestPointOnTriangle(p, mesh.vertex(c.triangle, 0), mesh.vertex(c.triangle, 1), mesh.vertex(c.triangle, 2), &region);
    ASSERT_EQ(c.inside, truth) << "probe " << p.transpose() << " feature " << int(region.feature);
    ASSERT_EQ(pointBehindSurface(mesh, p, std::uint32_t(c.triangle), c.point), truth);
    ++checked;
    inside += truth;
    ++byFeature[int(region.feature)];
  }
  EXPECT_GT(checked, count * 9 / 10);
  EXPECT_GT(inside, checked / 10);
  EXPECT_GT(checked - inside, checked / 10);
  EXPECT_GT(byFeature[int(TriangleFeature::Edge)], checked / 50) << "edges must decide some probes";
  EXPECT_GT(byFeature[int(TriangleFeature::Vertex)], checked / 50) << "vertices must decide some probes";
}

TEST(SignRule, ConvexSphereMeshMatchesTheGeometricTruth) {
  const TriangleMesh mesh = radialMesh(12, 16, [](std::size_t) { return 1.0; });
  expectSignsMatchTruth(mesh, 1, 6000);
}

TEST(SignRule, BumpyStarShapedMeshMatchesTheGeometricTruth) {
  // Radii 0.6 .. 1.4 at random: concave edges and vertices inside and outside.
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> radius(0.6, 1.4);
  std::vector<double> radii(1000);
  for (double& x : radii) x = radius(rng);
  const TriangleMesh mesh = radialMesh(10, 14, [&](std::size_t k) { return radii[k]; });
  expectSignsMatchTruth(mesh, 2, 6000);
}

TEST(SignRule, BoxFromTheLoaderMatchesItsCoordinates) {
  const TriangleMesh mesh = loadMesh(clod_test::testData("box_4x2x1.obj"));
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> x(-7.5, -2.5), y(9.5, 12.5), z(0.0, 2.0);
  std::size_t inside = 0;
  for (int k = 0; k < 5000; ++k) {
    const Vec3 p(x(rng), y(rng), z(rng));
    const ContactResult c = bruteForceQuery(mesh, p, 100.0);
    ASSERT_TRUE(c.contact);
    const bool truth = p.x() > -7 && p.x() < -3 && p.y() > 10 && p.y() < 12 && p.z() > 0.5 && p.z() < 1.5;
    ASSERT_EQ(c.inside, truth) << p.transpose();
    inside += truth;
    // Deep inside: the signed reference answers at any depth; stateless, no contact beyond r.
    const ContactResult deep = bruteForceSignedQuery(mesh, p, 0.01);
    ASSERT_EQ(deep.contact, truth || c.distance <= 0.01) << p.transpose();
    if (deep.contact) {
      ASSERT_EQ(deep.distance, c.distance);
      ASSERT_EQ(deep.depth, truth ? 0.01 + c.distance : 0.01 - c.distance);
    }
  }
  EXPECT_GT(inside, 500);
}

TEST(SignRule, PseudoNormalsOfTheBoxFeatures) {
  const TriangleMesh mesh = loadMesh(clod_test::testData("box_4x2x1.obj"));
  // Every edge of a box: the sum of two perpendicular unit normals; every corner: along the diagonal.
  for (std::uint32_t t = 0; t < mesh.size(); ++t) {
    for (std::uint8_t k = 0; k < 3; ++k) {
      const Vec3 e = pseudoNormal(mesh, t, {TriangleFeature::Edge, k});
      const Vec3 a = mesh.vertex(t, k), b = mesh.vertex(t, (k + 1) % 3);
      // A face diagonal joins two coplanar triangles: twice the face normal; a box edge: two faces.
      const bool diagonal = ((b - a).array() != 0.0).count() == 2;
      if (diagonal) {
        EXPECT_TRUE(e.isApprox(2.0 * mesh.normals[t], 1e-12)) << t << " " << int(k);
      } else {
        EXPECT_NEAR(e.norm(), std::sqrt(2.0), 1e-12);
        EXPECT_NEAR(e.dot(mesh.normals[t]), 1.0, 1e-12);
      }
      const Vec3 v = pseudoNormal(mesh, t, {TriangleFeature::Vertex, k}).normalized();
      const Vec3 c = mesh.vertex(t, k) - Vec3(-5, 11, 1);
      EXPECT_TRUE(v.isApprox(c.cwiseSign() / std::sqrt(3.0), 1e-6)) << "corner " << mesh.vertex(t, k).transpose();
    }
    EXPECT_EQ(pseudoNormal(mesh, t, {TriangleFeature::Face, 0}), mesh.normals[t]);
  }
}

TEST(BruteForceSigned, OpenSheetAndInvalidInput) {
  const TriangleMesh mesh = makeMesh({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)}, {{0, 1, 2}}, "sheet");
  // Behind the sheet but outside its (flat) box: never followed.
  EXPECT_FALSE(bruteForceSignedQuery(mesh, Vec3(0.25, 0.25, -0.5), 0.1).contact);
  EXPECT_TRUE(bruteForceSignedQuery(mesh, Vec3(0.25, 0.25, -0.05), 0.1).contact);
  EXPECT_FALSE(bruteForceSignedQuery(mesh, Vec3(0.25, 0.25, 0.5), 0.1).contact);
  EXPECT_FALSE(bruteForceSignedQuery(mesh, Vec3(std::nan(""), 0, 0), 0.1).contact);
}

// finishContact's normal is never NaN (the guarantees contactNormal had, now of the function that replaced it):
// outside it points from the contact to the centre, behind the face still outward, on the surface it is the
// face's, on a zero-area triangle with the centre on it some unit vector, and a tiny offset stays finite.
TEST(FinishContact, NormalNeverNaN) {
  auto finish = [](const TriangleMesh& mesh, const Vec3& p, const Vec3& q) {
    ContactResult c;
    c.contact = true;
    c.triangle = 0;
    c.point = q;
    c.distance = (p - q).norm();
    finishContact(mesh, p, 1.0, c);
    return c.normal;
  };
  const TriangleMesh flat = makeMesh({Vec3(-1, -1, 0), Vec3(1, -1, 0), Vec3(0, 1, 0)}, {Triangle{0, 1, 2}});
  ASSERT_TRUE(flat.normals[0].isApprox(Vec3(0, 0, 1)));
  EXPECT_TRUE(finish(flat, Vec3(0, 0, 2), Vec3(0, 0, 0)).isApprox(Vec3(0, 0, 1)));
  EXPECT_TRUE(finish(flat, Vec3(0, 0, -2), Vec3(0, 0, 0)).isApprox(Vec3(0, 0, 1))) << "behind the face: outward";
  EXPECT_TRUE(finish(flat, Vec3(1, 0, 1), Vec3(0, 0, 0)).isApprox(Vec3(1, 0, 1).normalized()));
  EXPECT_EQ(finish(flat, Vec3(0, 0, 0), Vec3(0, 0, 0)), flat.normals[0]) << "on the surface: the face normal";
  EXPECT_TRUE(finish(flat, Vec3(1e-300, 0, 0), Vec3(0, 0, 0)).allFinite());
  const TriangleMesh sliver = makeMesh({Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3(2, 2, 2)}, {Triangle{0, 1, 2}});
  const Vec3 z = finish(sliver, Vec3(1, 1, 1), Vec3(1, 1, 1));
  EXPECT_TRUE(z.allFinite());
  EXPECT_NEAR(z.norm(), 1.0, 1e-15) << "zero-area triangle, pointer on it: some unit vector";
}

}  // namespace
