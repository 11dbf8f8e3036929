// SweptScene against the brute-force sweep of each object's mesh moved to its world pose: the earliest
// contact over the objects, its point and normal in the world frame; inactive objects and moved objects.

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/detector.h"
#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/probes.h"
#include "clod_haptics/core/sphere_set.h"
#include "clod_haptics/core/swept_scene.h"
#include "test_helpers.h"

namespace {

using namespace clod_haptics;

// The mesh with every vertex moved by pose (the reference's world copy of an object).
TriangleMesh moved(const TriangleMesh& mesh, const Eigen::Isometry3d& pose) {
  std::vector<Vec3> v;
  for (const Vec3& x : mesh.vertices) v.push_back(pose * mesh.toModel(x));
  return makeMesh(std::move(v), mesh.triangles, "moved");
}

Eigen::Isometry3d pose(double angle, const Vec3& axis, const Vec3& t) {
  Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
  p.linear() = Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
  p.translation() = t;
  return p;
}

TEST(SweptScene, EarliestContactOverPosedObjectsMatchesBruteForce) {
  auto head = clod_test::loadNormalized(clod_test::sharedMesh("head.off"));
  auto elephant = clod_test::loadNormalized(clod_test::sharedMesh("elephant.off"));
  const Eigen::Isometry3d p0 = pose(0.3, Vec3(1, 2, 3), Vec3(0.1, 0.0, 0.0));
  const Eigen::Isometry3d p1 = pose(-1.1, Vec3(0, 1, 1), Vec3(0.7, 0.2, -0.1));
  SweptScene scene;
  scene.add(std::make_shared<const SweptSphereQuery>(head), p0);
  scene.add(std::make_shared<const SweptSphereQuery>(elephant), p1);
  const TriangleMesh world0 = moved(*head, p0), world1 = moved(*elephant, p1);
  const std::vector<Vec3> a = uniformProbes(world0, 1500, 0.3, 3);
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> u(-0.6, 0.6);
  const double r = 0.01;
  std::size_t hits = 0, second = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const Vec3 b = a[i] + Vec3(u(rng), u(rng), u(rng));
    SceneSweptContact got;
    scene.sweep(a[i], b, r, got);
    const SweptContact w0 = bruteForceSweep(world0, a[i], b, r), w1 = bruteForceSweep(world1, a[i], b, r);
    const bool any = w0.hit || w1.hit;
    ASSERT_EQ(got.contact.hit, any) << i;
    if (!any) continue;
    ++hits;
    const bool first = w0.hit && (!w1.hit || w0.toi <= w1.toi);
    const SweptContact& want = first ? w0 : w1;
    second += !first;
    // The same sweep in another frame: times agree to rounding, not bit for bit, so among triangles touched at
    // the same time (a shared edge, a start in contact) either may answer; its own time must be the first.
    // (The radius margin depends on the frame's coordinates: 1e-10 of them, over a sweep about 0.5 long.)
    EXPECT_NEAR(got.contact.toi, want.toi, 1e-8) << i;
    if (std::abs(w0.toi - w1.toi) > 1e-8 || !w0.hit || !w1.hit) {
      EXPECT_EQ(got.object, first ? 0 : 1) << i;
    }
    const TriangleMesh& world = got.object == 0 ? world0 : world1;
    const auto t = static_cast<std::size_t>(got.contact.triangle);
    double toi = -1.0;
    bool start = false;
    const Vec3 la = world.toLocal(a[i]);
    EXPECT_TRUE(sweptSphereTriangle(la, world.toLocal(b) - la, sweptRadiusMargin(r, 2.0), world.vertex(t, 0),
                                    world.vertex(t, 1), world.vertex(t, 2), toi, start));
    EXPECT_NEAR(toi, want.toi, 1e-8) << i;
    // Point and normal: the triangle's own, at the centre of that time (r away unless it started closer).
    const Vec3 centre = a[i] + got.contact.toi * (b - a[i]);
    EXPECT_LT((got.contact.centre - centre).norm(), 1e-9) << i;
    if (!got.contact.startInContact) {
      EXPECT_NEAR((got.contact.point - centre).norm(), r, 1e-6) << i;
    }
    EXPECT_LT((got.contact.normal - (centre - got.contact.point).normalized()).norm(), 1e-6) << i;
  }
  EXPECT_GT(hits, 100u);
  EXPECT_GT(second, 20u);
}

TEST(SweptScene, InactiveAndMovedObjects) {
  auto plate = std::make_shared<const TriangleMesh>(
      makeMesh({{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}}, {{0, 1, 2}, {0, 2, 3}}, "plate"));
  SweptScene scene;
  scene.add(std::make_shared<const SweptSphereQuery>(plate), Eigen::Isometry3d::Identity());
  SceneSweptContact c;
  scene.sweep(Vec3(0, 0, 1), Vec3(0, 0, -1), 0.1, c);
  ASSERT_TRUE(c.contact.hit);
  EXPECT_NEAR(c.contact.toi, 0.45, 1e-9);
  scene.setPose(0, pose(0.0, Vec3::UnitZ(), Vec3(0, 0, 0.5)));  // the plate up at z = 0.5
  scene.sweep(Vec3(0, 0, 1), Vec3(0, 0, -1), 0.1, c);
  ASSERT_TRUE(c.contact.hit);
  EXPECT_NEAR(c.contact.toi, 0.2, 1e-9);
  EXPECT_NEAR((c.contact.point - Vec3(0, 0, 0.5)).norm(), 0.0, 1e-9);
  scene.setActive(0, false);
  scene.sweep(Vec3(0, 0, 1), Vec3(0, 0, -1), 0.1, c);
  EXPECT_FALSE(c.contact.hit);
  Eigen::Isometry3d scaled = Eigen::Isometry3d::Identity();
  scaled.linear() *= 2.0;
  EXPECT_THROW(scene.setPose(0, scaled), InvalidParameter);
  EXPECT_THROW(scene.add(nullptr, Eigen::Isometry3d::Identity()), InvalidParameter);
}

// Two plates on top of each other, the second turned: a sphere resting on both and pressed in is blocked at 0 by
// both objects. The lowest object wins, unless the hint names a triangle of the other one that blocks at 0.
TEST(SweptScene, AHintBlockingAtZeroWinsTheTieAcrossObjects) {
  auto plate = std::make_shared<const TriangleMesh>(
      makeMesh({{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}}, {{0, 1, 2}, {0, 2, 3}}, "plate"));
  SweptScene scene;
  scene.add(std::make_shared<const SweptSphereQuery>(plate), Eigen::Isometry3d::Identity());
  scene.add(std::make_shared<const SweptSphereQuery>(plate), pose(0.5, Vec3::UnitZ(), Vec3::Zero()));
  const Vec3 a(0.1, 0.3, 0.1), b = a + Vec3(0.05, 0.0, -0.05);
  // Which triangle of the turned plate lies under a (the reference: its own brute force).
  const SweptContact own = bruteForceSweep(moved(*plate, pose(0.5, Vec3::UnitZ(), Vec3::Zero())), a, b, 0.1);
  ASSERT_TRUE(own.hit);
  ASSERT_EQ(own.toi, 0.0);
  SceneSweptContact c;
  scene.sweep(a, b, 0.1, c);
  EXPECT_EQ(c.object, 0);
  scene.sweep(a, b, 0.1, c, 1, own.triangle);
  EXPECT_EQ(c.object, 1);
  EXPECT_EQ(c.contact.triangle, own.triangle);
  EXPECT_EQ(c.contact.toi, 0.0);
  EXPECT_NEAR((c.contact.normal - Vec3::UnitZ()).norm(), 0.0, 1e-12);
  // A hint that does not block at 0 (the other triangle of the turned plate, or a lifting sphere): no change.
  scene.sweep(a, b, 0.1, c, 1, 1 - own.triangle);
  EXPECT_EQ(c.object, 0);
  scene.sweep(a, a + Vec3(0.05, 0.0, 0.05), 0.1, c, 1, own.triangle);
  EXPECT_FALSE(c.contact.hit);
  // A hint naming no object answers as no hint; blocksAtStart refuses it, and an inactive object.
  scene.sweep(a, b, 0.1, c, 5, own.triangle);
  EXPECT_EQ(c.object, 0);
  SceneSweptContact held;
  EXPECT_FALSE(scene.blocksAtStart(5, own.triangle, a, b, 0.1, held));
  EXPECT_FALSE(scene.blocksAtStart(-1, own.triangle, a, b, 0.1, held));
  EXPECT_TRUE(scene.blocksAtStart(1, own.triangle, a, b, 0.1, held));
  // Lifted a gap above the turned plate: blocked "at once" when within covers the travel to it (the same distance in
  // the world as in the object's frame), answered at 0 with the centre where it is.
  const Vec3 above = a + Vec3(0.0, 0.0, 0.002), down = above + Vec3(0.0, 0.0, -0.05);
  const SweptContact gap = bruteForceSweep(moved(*plate, pose(0.5, Vec3::UnitZ(), Vec3::Zero())), above, down, 0.1);
  ASSERT_TRUE(gap.hit);
  const double travel = gap.toi * 0.05;
  ASSERT_NEAR(travel, 0.002, 1e-9);
  EXPECT_FALSE(scene.blocksAtStart(1, own.triangle, above, down, 0.1, held, 0.5 * travel));
  ASSERT_TRUE(scene.blocksAtStart(1, own.triangle, above, down, 0.1, held, 1.01 * travel));
  EXPECT_EQ(held.object, 1);
  EXPECT_EQ(held.contact.toi, 0.0);
  EXPECT_NEAR((held.contact.centre - above).norm(), 0.0, 1e-12);
  EXPECT_NEAR((held.contact.normal - Vec3::UnitZ()).norm(), 0.0, 1e-12);
  scene.setActive(1, false);
  EXPECT_FALSE(scene.blocksAtStart(1, own.triangle, a, b, 0.1, held));
}

}  // namespace

// clearAt: where a proxy may start. Against brute force on the posed object (the bundled torus, closed, so inside
// is the same in every frame): a point touching it (within r) or inside it at any depth (bruteForceSignedQuery) is
// not clear; with a detector the deep search sees inside, without one only a touch is seen.
TEST(SweptScene, ClearAtIsFalseTouchingOrInsideAnObject) {
  auto torus = std::make_shared<const TriangleMesh>(loadMesh(CLOD_PACKAGE_DATA_DIR "/meshes/torus.obj"));
  const Eigen::Isometry3d p0 = pose(0.7, Vec3(1, -1, 2), Vec3(0.2, -0.1, 0.05));
  auto set = std::make_shared<const ClodSphereSet>(ClodBuilder(torus).build(0.003));
  const double r = 0.002;
  SweptScene withDetector, treeOnly;
  withDetector.add(std::make_shared<const SweptSphereQuery>(
                       torus, std::make_shared<const ClodDetector>(torus, set, FastLevel::Grid, r)),
                   p0);
  treeOnly.add(std::make_shared<const SweptSphereQuery>(torus), p0);
  const TriangleMesh world = moved(*torus, p0);
  std::size_t deep = 0, touching = 0, clear = 0;
  for (const Vec3& p : uniformProbes(world, 3000, 0.01, 9)) {
    const ContactResult near = bruteForceQuery(world, p, r), signedRef = bruteForceSignedQuery(world, p, r);
    const bool inside = signedRef.contact && signedRef.inside;
    EXPECT_EQ(withDetector.clearAt(p, r), !near.contact && !inside) << p.transpose();
    EXPECT_EQ(treeOnly.clearAt(p, r), !near.contact) << p.transpose();
    deep += inside && !near.contact;
    touching += near.contact;
    clear += !near.contact && !inside;
  }
  EXPECT_GT(deep, 100u);
  EXPECT_GT(touching, 100u);
  EXPECT_GT(clear, 100u);
  withDetector.setActive(0, false);
  EXPECT_TRUE(withDetector.clearAt(p0 * torus->toModel(torus->vertices[0]), r)) << "an inactive object is skipped";
}
