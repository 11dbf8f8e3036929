// SweptScene against the brute-force sweep of each object's mesh moved to its world pose: the earliest
// contact over the objects, its point and normal in the world frame; inactive objects and moved objects.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
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

// Twelve objects (more than SweptScene::kTreeAbove: the tree over their bounds picks the ones a sweep may reach),
// some overlapping, two switched off and one moved half-way: every sweep's earliest contact is brute force's over
// the active objects' world copies, hinted (the last answer's object and triangle, as a proxy gives them) or not.
TEST(SweptScene, ManyObjectsThroughTheTreeMatchBruteForce) {
  // Parts of 15 cm in a 3 m room, sweeps up to 0.5 long: a sweep may pass many bounds and reach one only near its end.
  auto small = [](const TriangleMesh& unit) {
    std::vector<Vec3> v;
    for (const Vec3& x : unit.vertices) v.push_back(0.15 * unit.toModel(x));
    return std::make_shared<const TriangleMesh>(makeMesh(std::move(v), unit.triangles, unit.name));
  };
  auto head = small(*clod_test::loadNormalized(clod_test::sharedMesh("head.off")));
  auto elephant = small(*clod_test::loadNormalized(clod_test::sharedMesh("elephant.off")));
  std::mt19937_64 rng(8);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  SweptScene scene;
  std::vector<std::shared_ptr<const TriangleMesh>> meshes;
  std::vector<Eigen::Isometry3d, Eigen::aligned_allocator<Eigen::Isometry3d>> poses;
  for (int i = 0; i < 12; ++i) {
    meshes.push_back(i % 3 == 2 ? elephant : head);
    poses.push_back(pose(3.0 * u(rng), Vec3(u(rng), u(rng), 1.0), Vec3(0.4 * u(rng), 0.4 * u(rng), 0.1 * u(rng))));
    scene.add(std::make_shared<const SweptSphereQuery>(meshes.back()), poses.back());
  }
  ASSERT_GT(scene.size(), SweptScene::kTreeAbove);
  std::vector<char> active(12, 1);
  scene.setActive(4, false);
  scene.setActive(9, false);
  active[4] = active[9] = 0;
  std::vector<TriangleMesh> world;
  for (int i = 0; i < 12; ++i) world.push_back(moved(*meshes[i], poses[i]));
  const double r = 0.002;
  std::size_t hits = 0, hinted = 0, objectsHit = 0;
  std::vector<char> seen(12, 0);
  SceneSweptContact last;
  for (int k = 0; k < 700; ++k) {
    if (k == 350) {  // object 1 moved onto object 0
      poses[1] = poses[0] * pose(0.4, Vec3::UnitZ(), Vec3(0.01, 0.0, 0.0));
      scene.setPose(1, poses[1]);
      world[1] = moved(*meshes[1], poses[1]);
    }
    const std::size_t target = static_cast<std::size_t>(k) % 12;
    const Vec3 a = k % 4 == 0 ? uniformProbes(world[target], 1, 0.3, 100 + k)[0]
                              : nearSurfaceProbes(world[target], 1, 3.0 * r, 100 + k)[0];
    const double length = std::pow(10.0, -3.0 + 2.7 * (0.5 + 0.5 * u(rng)));  // 0.001 to 0.5
    const Vec3 b = a + length * Vec3(u(rng), u(rng), u(rng)).normalized();
    const bool useHint = k % 2 == 1 && last.object >= 0;
    SceneSweptContact got;
    scene.sweep(a, b, r, got, useHint ? last.object : -1, useHint ? last.contact.triangle : -1);
    hinted += useHint;
    SweptContact want;
    std::int32_t wantObject = -1;
    double second = std::numeric_limits<double>::infinity();  // the next object's time (ambiguity when close)
    for (std::size_t i = 0; i < 12; ++i) {
      if (!active[i]) continue;
      const SweptContact w = bruteForceSweep(world[i], a, b, r);
      if (!w.hit) continue;
      if (wantObject < 0 || w.toi < want.toi) {
        if (wantObject >= 0) second = std::min(second, want.toi);
        want = w;
        wantObject = static_cast<std::int32_t>(i);
      } else {
        second = std::min(second, w.toi);
      }
    }
    ASSERT_EQ(got.contact.hit, wantObject >= 0) << k;
    if (wantObject < 0) continue;
    ++hits;
    // Times from two frames agree to rounding of the distance travelled (1e-10 of the coordinates), not bit for bit.
    EXPECT_NEAR(got.contact.toi * length, want.toi * length, 1e-9) << k;
    // The same time from two objects (an overlap, a start touching both) may go to either, or to a hint's object.
    if ((second - want.toi) * length > 1e-9 && !(useHint && got.contact.toi == 0.0)) {
      EXPECT_EQ(got.object, wantObject) << k;
    }
    ASSERT_GE(got.object, 0);
    EXPECT_TRUE(active[static_cast<std::size_t>(got.object)]) << k;
    objectsHit += !seen[static_cast<std::size_t>(got.object)];
    seen[static_cast<std::size_t>(got.object)] = 1;
    last = got;
  }
  EXPECT_GT(hits, 200u);
  EXPECT_GT(hinted, 200u);
  EXPECT_GE(objectsHit, 9u) << "sweeps must reach most of the active objects";
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
