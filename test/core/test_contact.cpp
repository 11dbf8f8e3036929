// The force law of the core (contact.h): a penalty spring along the outward normal, growing with the signed depth.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include "clod_haptics/core/contact.h"
#include "clod_haptics/core/detector.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/sphere_set.h"
#include "clod_haptics/test_config.h"

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
