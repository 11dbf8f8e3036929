// bruteForceQuery, the reference every other test trusts: checked against a loop written here over
// closestPointOnTriangle, the tie rule (lowest index), the contact boundary and the normal.

#include <gtest/gtest.h>

#include <limits>

#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/contact.h"
#include "clod_haptics/core/geometry.h"
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
    EXPECT_DOUBLE_EQ(c.depth, r - c.distance);
    EXPECT_NEAR((p - c.point).norm(), c.distance, 1e-15);
    EXPECT_NEAR(c.normal.norm(), 1.0, 1e-12);
    EXPECT_GE(c.normal.dot(mesh->normals[bestT]), 0.0) << "normal on the face's side";
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
  // From behind triangle 0 (the tie winner): the normal is flipped to that face's side (documented in
  // contactNormal), so the penalty force pushes out through the front.
  c = bruteForceQuery(*mesh, Vec3(0.25, 0.25, -0.5), 1.0);
  ASSERT_TRUE(c.contact);
  EXPECT_EQ(c.triangle, 0);
  EXPECT_TRUE(c.normal.isApprox(Vec3(0, 0, 1)));
  // On the surface: the face normal.
  c = bruteForceQuery(*mesh, Vec3(0.25, 0.25, 0.0), 0.0);
  ASSERT_TRUE(c.contact);
  EXPECT_EQ(c.distance, 0.0);
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

TEST(ContactNormal, NeverNaN) {
  const Vec3 n(0, 0, 1);
  EXPECT_TRUE(contactNormal(Vec3(0, 0, 2), Vec3(0, 0, 0), n).isApprox(Vec3(0, 0, 1)));
  EXPECT_TRUE(contactNormal(Vec3(0, 0, -2), Vec3(0, 0, 0), n).isApprox(Vec3(0, 0, 1))) << "flipped to n's side";
  EXPECT_TRUE(contactNormal(Vec3(1, 0, 1), Vec3(0, 0, 0), n).isApprox(Vec3(1, 0, 1).normalized()));
  EXPECT_EQ(contactNormal(Vec3(1, 2, 3), Vec3(1, 2, 3), n), n) << "on the surface: the face normal";
  const Vec3 z = contactNormal(Vec3(1, 2, 3), Vec3(1, 2, 3), Vec3::Zero());
  EXPECT_TRUE(z.allFinite());
  EXPECT_NEAR(z.norm(), 1.0, 1e-15) << "zero-area triangle, pointer on it: some unit vector";
  EXPECT_TRUE(contactNormal(Vec3(1e-300, 0, 0), Vec3(0, 0, 0), n).allFinite());
}

}  // namespace
