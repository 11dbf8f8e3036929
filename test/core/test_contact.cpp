// The force law of the core (contact.h): a penalty spring along the outward normal, growing with the signed depth.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <random>

#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/contact.h"
#include "clod_haptics/core/detector.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/sphere_set.h"
#include "clod_haptics/test_config.h"
#include "test_helpers.h"

namespace clod_haptics {
namespace {

std::shared_ptr<const TriangleMesh> torus() {
  static auto mesh = std::make_shared<const TriangleMesh>(loadMesh(CLOD_PACKAGE_DATA_DIR "/meshes/torus.obj"));
  return mesh;
}

// A stylus stream pressing into the torus's tube from outside its outer equator to the
// tube's middle circle: the penalty force grows at every step from the first touch, points out, and is
// clamped by max force; the same poses without the stream's cache lose the contact once deeper than r.
TEST(PenaltyForce, PenaltyForceGrowsWhilePushingIn) {
  const auto mesh = torus();
  const auto set = std::make_shared<const ClodSphereSet>(ClodBuilder(mesh).build(0.003));
  const ClodDetector det(mesh, set);
  const double r = 0.002, stiffness = 500.0;
  // The tube's middle at the outer equator: halfway between the inner and outer crossings of the x axis.
  double inner = 0.0;
  for (const Vec3& v : mesh->vertices)
    if (std::abs(v.y()) < 1e-12 && std::abs(v.z()) < 1e-12 && v.x() > 0.0)
      inner = inner == 0.0 ? v.x() : std::min(inner, v.x());
  ASSERT_GT(inner, 0.0);
  const double outer = 0.082, middle = 0.5 * (inner + outer);
  QueryCache cache;
  ContactResult got, stateless;
  double last = -1.0;
  int touching = 0, lostWithoutCache = 0;
  for (int i = 0; i <= 300; ++i) {
    const Vec3 p(outer + 2 * r - (2 * r + outer - middle) * i / 300.0, 0.0, 0.0);
    det.query(p, r, DetectionMode::Exact, got, &cache);
    const Vec3 f = penaltyForce(got, stiffness);
    if (!got.contact) {
      ASSERT_LT(last, 0.0) << "step " << i << ": the contact was lost while pushing in";
      continue;
    }
    ++touching;
    ASSERT_GT(f.norm(), last) << "step " << i;
    ASSERT_GT(f.x(), 0.0) << "step " << i << ": pushes out of the tube";
    ASSERT_LE(penaltyForce(got, stiffness, 0.5).norm(), 0.5 + 1e-12);
    last = f.norm();
    det.query(p, r, DetectionMode::Exact, stateless);
    lostWithoutCache += !stateless.contact;
  }
  EXPECT_GT(touching, 200);
  EXPECT_GT(lostWithoutCache, 50) << "the stream's cache is what follows the push beyond r";
}

TEST(PenaltyForce, IsStiffnessTimesDepthAlongTheNormal) {
  ContactResult r;
  r.contact = true;
  r.depth = 0.001;
  r.normal = Vec3(0.0, 0.6, 0.8);
  const Vec3 f = penaltyForce(r, 500.0);
  EXPECT_NEAR(f.y(), 500.0 * 0.001 * 0.6, 1e-12);
  EXPECT_NEAR(f.z(), 500.0 * 0.001 * 0.8, 1e-12);
  EXPECT_NEAR(penaltyForce(r, 500.0, 0.3).norm(), 0.3, 1e-12);  // clamped
  r.contact = false;
  EXPECT_EQ(penaltyForce(r, 500.0), Vec3::Zero());
  r.contact = true;
  EXPECT_EQ(penaltyForce(r, 0.0), Vec3::Zero());
}

TEST(PenaltyForce, OfAPenetrationVectorIsClampedAndNeverNaN) {
  EXPECT_EQ(penaltyForce(Vec3(0.0, 0.0, 0.001), 400.0), Vec3(0.0, 0.0, 0.4));
  EXPECT_NEAR(penaltyForce(Vec3(0.003, 0.0, 0.004), 400.0, 1.0).norm(), 1.0, 1e-12);
  EXPECT_EQ(penaltyForce(Vec3(0.0, 0.0, 0.001), -1.0), Vec3::Zero());
  EXPECT_EQ(penaltyForce(Vec3(std::nan(""), 0.0, 0.0), 400.0), Vec3::Zero());
  EXPECT_EQ(penaltyForce(Vec3(1e300, 0.0, 0.0), 1e300), Vec3::Zero()) << "an overflow is no force";
}

}  // namespace
}  // namespace clod_haptics

namespace clod_haptics {
namespace {

// finishContact from a feature the caller already has (the detector's winner) answers as the one that finds the
// feature itself: on the torus and every shared mesh, at points around vertices, edges and faces, inside and
// outside, with the nearest triangle and point from brute force. Some of the points lie where the face's normal
// alone would give the wrong side (the feature matters there).
TEST(FinishContact, FromAKnownFeatureAnswersAsFromThePoint) {
  std::vector<std::shared_ptr<const TriangleMesh>> meshes{torus()};
  for (const std::string& path : clod_test::sharedMeshes()) meshes.push_back(clod_test::loadNormalized(path));
  std::size_t regions[3] = {0, 0, 0}, inside = 0, faceWrong = 0;
  for (const auto& mesh : meshes) {
    const TriangleMesh& m = *mesh;
    std::mt19937 rng(5);
    std::uniform_int_distribution<std::size_t> pick(0, m.size() - 1);
    for (int n = 0; n < 300; ++n) {
      const std::size_t t = pick(rng);
      const double edge = (m.vertex(t, 1) - m.vertex(t, 0)).norm();
      std::uniform_real_distribution<double> jitter(-edge, edge);
      const Vec3 targets[3] = {m.vertex(t, 0), 0.5 * (m.vertex(t, 1) + m.vertex(t, 2)),
                               (m.vertex(t, 0) + m.vertex(t, 1) + m.vertex(t, 2)) / 3.0};
      for (const Vec3& target : targets) {
        const Vec3 p = m.toModel(target + Vec3(jitter(rng), jitter(rng), jitter(rng)));
        ContactResult expected = bruteForceQuery(m, p, 4.0 * edge);
        if (!expected.contact) continue;
        const std::uint32_t k = static_cast<std::uint32_t>(expected.triangle);
        const Vec3 local = m.toLocal(p);
        TriangleRegion region;
        const Vec3 q = closestPointOnTriangle(local, m.vertex(k, 0), m.vertex(k, 1), m.vertex(k, 2), &region);
        ContactResult got = expected;
        finishContact(m, local, 4.0 * edge, region, got);
        finishContact(m, local, 4.0 * edge, expected);
        EXPECT_EQ(got.inside, expected.inside) << "point " << p.transpose();
        EXPECT_EQ(got.depth, expected.depth);
        EXPECT_EQ(got.normal, expected.normal);
        ++regions[static_cast<int>(region.feature)];
        inside += got.inside;
        faceWrong += ((local - q).dot(m.normals[k]) < 0.0) != expected.inside;
      }
    }
  }
  // The points reach every kind of feature, on both sides, and places where the feature decides the side.
  EXPECT_GT(regions[0], 0u);
  EXPECT_GT(regions[1], 0u);
  EXPECT_GT(regions[2], 0u);
  EXPECT_GT(inside, 0u);
  EXPECT_GT(faceWrong, 0u);
}

}  // namespace
}  // namespace clod_haptics
