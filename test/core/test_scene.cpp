// SceneDetector: several objects in different poses answer like bruteForceQuery per object (the test
// transforms every probe itself), an object moved between queries, the scene-level rejection, levels
// not ready yet, a full contact array, a stream's SceneCaches against the flat scan, and a query that allocates
// nothing.

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>
#include <random>
#include <vector>

#include "allocation_counter.h"
#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/detector.h"
#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/probes.h"
#include "clod_haptics/core/scene.h"
#include "clod_haptics/core/sphere_set.h"
#include "test_helpers.h"

namespace {

using namespace clod_haptics;

constexpr double kRadius = 0.002;
constexpr double kGapCentre = 0.08275;  // between torus_a and torus_b on the x axis

Eigen::Isometry3d makePose(double x, double y, double z, double angle, const Vec3& axis) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translate(Vec3(x, y, z));
  pose.rotate(Eigen::AngleAxisd(angle, axis.normalized()));
  return pose;
}

/** The reference for one object: brute force on the probe transformed into the object frame by the test. */
ContactResult reference(const TriangleMesh& mesh, const Eigen::Isometry3d& worldFromObject, const Vec3& world,
                        double r) {
  const Vec3 local = worldFromObject.inverse() * world;
  return bruteForceQuery(mesh, local, r);
}

/** True when the reference distance is so close to r that rounding may decide either way. */
bool onTheEdge(const ContactResult& ref, double r) { return std::abs(ref.distance - r) <= 1e-9 * r; }

class SceneTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    torus_ = std::make_shared<const TriangleMesh>(loadMesh(std::string(CLOD_PACKAGE_DATA_DIR) + "/meshes/torus.obj"));
    MeshLoadOptions boxOptions;
    boxOptions.scale = 0.02;  // 8 x 4 x 2 cm
    box_ = std::make_shared<const TriangleMesh>(loadMesh(clod_test::testData("box_4x2x1.obj"), boxOptions));
    ClodBuilder torusBuilder(torus_);
    torusLevel_ = std::make_shared<const ClodDetector>(
        torus_, std::make_shared<const ClodSphereSet>(torusBuilder.build(0.003)), FastLevel::Grid, kRadius);
    ClodBuilder boxBuilder(box_);
    boxLevel_ = std::make_shared<const ClodDetector>(
        box_, std::make_shared<const ClodSphereSet>(boxBuilder.build(0.005)), FastLevel::Hierarchy);
  }
  static void TearDownTestSuite() {
    torusLevel_.reset();
    boxLevel_.reset();
    torus_.reset();
    box_.reset();
  }

  /** Three tori (two of them interlocked, so a pointer can touch both) and a box, far from the third. */
  void makeScene(SceneDetector& scene) {
    scene.addObject("torus_a", torus_, torusLevel_, makePose(0, 0, 0, 0.0, Vec3::UnitZ()));
    // Beside torus_a (outer radius 0.082), turned about its axis: 1.5 mm between the rims on the x axis,
    // so a pointer there touches both.
    scene.addObject("torus_b", torus_, torusLevel_, makePose(2 * kGapCentre, 0, 0, 0.3, Vec3::UnitZ()));
    scene.addObject("torus_c", torus_, torusLevel_, makePose(0.5, 0.3, -0.2, 1.1, Vec3(1, 2, 3)));
    scene.addObject("box", box_, boxLevel_, makePose(-0.3, 0.2, 0.1, -0.7, Vec3(0.3, -1, 0.2)));
  }

  /** Probes near every object's surface (in world), plus uniform ones over the whole scene. */
  std::vector<Vec3> scenePrabes(const SceneDetector& scene, std::size_t perObject) {
    std::vector<Vec3> probes;
    for (std::uint32_t i = 0; i < scene.size(); ++i) {
      for (const Vec3& p : nearSurfaceProbes(*scene.mesh(i), perObject, 2.5 * kRadius, 100 + i))
        probes.push_back(scene.pose(i) * p);
    }
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> u(-0.45, 0.65);
    for (std::size_t k = 0; k < perObject; ++k) probes.emplace_back(u(rng), u(rng), u(rng));
    std::uniform_real_distribution<double> g(-0.003, 0.003);
    for (std::size_t k = 0; k < perObject / 10; ++k) probes.emplace_back(kGapCentre + g(rng), g(rng), g(rng));
    return probes;
  }

  /**
   * Checks one scene answer against brute force on every object. With per-object caches the stream follows
   * a push beyond r into an object it was inside at the previous answer: followed (one flag per object, the
   * previous answers' inside) picks the signed reference for those, and is updated from this answer.
   */
  void expectMatchesReference(const SceneDetector& scene, const Vec3& p, double r, const SceneContact* contacts,
                              const SceneQueryResult& out, std::vector<char>* followed = nullptr) {
    std::uint32_t k = 0;
    Vec3 penetration = Vec3::Zero();
    for (std::uint32_t i = 0; i < scene.size(); ++i) {
      if (!scene.active(i)) {  // switched off: never answered, and its push ends
        ASSERT_FALSE(k < out.contacts && contacts[k].object == i) << "inactive object " << scene.name(i);
        if (followed != nullptr) (*followed)[i] = 0;
        continue;
      }
      const bool deep = followed != nullptr && (*followed)[i];
      const ContactResult ref = deep ? bruteForceSignedQuery(*scene.mesh(i), scene.pose(i).inverse() * p, r)
                                     : reference(*scene.mesh(i), scene.pose(i), p, r);
      const bool listed = k < out.contacts && contacts[k].object == i;
      if (followed != nullptr) (*followed)[i] = listed && contacts[k].local.inside;
      if (onTheEdge(ref, r)) {  // either answer is right; a listed one still adds to the penetration
        if (listed) {
          penetration += contacts[k].local.depth * contacts[k].normal;
          ++k;
        }
        continue;
      }
      ASSERT_EQ(listed, ref.contact) << "object " << scene.name(i) << " probe " << p.transpose() << " ref distance "
                                      << ref.distance;
      if (!listed) continue;
      const SceneContact& c = contacts[k++];
      ASSERT_NEAR(c.local.distance, ref.distance, 1e-12);
      ASSERT_EQ(c.local.inside, ref.inside);
      ASSERT_NEAR(c.local.depth, ref.inside ? r + ref.distance : r - ref.distance, 1e-12);
      // The world point is the reference's closest point mapped to the world (ties may pick another
      // triangle with the same point, so compare points, not indices).
      ASSERT_LT((c.point - scene.pose(i) * ref.point).norm(), 1e-9);
      ASSERT_NEAR((c.point - p).norm(), ref.distance, 1e-9);
      ASSERT_NEAR(c.normal.norm(), 1.0, 1e-9);
      ASSERT_LT((c.normal - scene.pose(i).linear() * c.local.normal).norm(), 1e-12);
      penetration += c.local.depth * c.normal;
    }
    ASSERT_EQ(k, out.contacts);
    ASSERT_EQ(out.touched, out.contacts);
    ASSERT_EQ(out.contact, out.contacts > 0);
    ASSERT_LT((out.penetration - penetration).norm(), 1e-12);
    if (out.contact) {
      ASSERT_GE(out.deepest, 0);
      for (std::uint32_t j = 0; j < out.contacts; ++j) ASSERT_LE(contacts[j].local.depth, out.maxDepth);
      ASSERT_EQ(contacts[out.deepest].local.depth, out.maxDepth);
    } else {
      ASSERT_EQ(out.deepest, -1);
    }
    ASSERT_EQ(out.objectsQueried + out.objectsRejected + out.objectsInactive, scene.size());
  }

  static std::shared_ptr<const TriangleMesh> torus_, box_;
  static std::shared_ptr<const ClodDetector> torusLevel_, boxLevel_;
};
std::shared_ptr<const TriangleMesh> SceneTest::torus_, SceneTest::box_;
std::shared_ptr<const ClodDetector> SceneTest::torusLevel_, SceneTest::boxLevel_;

TEST_F(SceneTest, SeveralObjectsMatchBruteForcePerObject) {
  SceneDetector scene;
  makeScene(scene);
  std::vector<SceneContact> contacts(scene.size());
  std::vector<QueryCache> caches(scene.size());
  std::vector<char> followed(scene.size(), 0);
  std::size_t touching = 0, twoAtOnce = 0;
  for (const Vec3& p : scenePrabes(scene, 1500)) {
    SceneQueryResult out;
    scene.query(p, kRadius, DetectionMode::Exact, contacts.data(), contacts.size(), out, caches.data());
    expectMatchesReference(scene, p, kRadius, contacts.data(), out, &followed);
    if (HasFatalFailure()) return;
    touching += out.contact;
    twoAtOnce += out.contacts >= 2;
  }
  // The probe set must exercise contacts, and contacts with two objects at once.
  EXPECT_GT(touching, 1000u);
  EXPECT_GT(twoAtOnce, 0u) << "no probe touched the interlocked tori at once";
}

TEST_F(SceneTest, TwoObjectsAtOnceGiveTwoContactsAndTheSumOfPenetrations) {
  SceneDetector scene;
  makeScene(scene);
  // Search the interlocked region for a pointer inside both tubes' contact range.
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-0.002, 0.002);
  std::vector<SceneContact> contacts(scene.size());
  for (int attempt = 0; attempt < 20000; ++attempt) {
    const Vec3 p(kGapCentre + u(rng), u(rng), u(rng));
    SceneQueryResult out;
    scene.query(p, kRadius, DetectionMode::Exact, contacts.data(), contacts.size(), out);
    if (out.contacts < 2) continue;
    expectMatchesReference(scene, p, kRadius, contacts.data(), out);
    EXPECT_EQ(out.objectsQueried, 2u);
    EXPECT_EQ(contacts[0].object, 0u);
    EXPECT_EQ(contacts[1].object, 1u);
    return;
  }
  FAIL() << "no pointer touched both interlocked tori";
}

TEST_F(SceneTest, MovedObjectAnswersAtItsNewPlaceWithoutRebuild) {
  SceneDetector scene;
  makeScene(scene);
  const std::uint32_t moving = 2;
  const ClodDetector* level = scene.detector(moving).get();
  const Eigen::Isometry3d before = scene.pose(moving);
  const std::vector<Vec3> nearBefore = [&] {
    std::vector<Vec3> v;
    for (const Vec3& p : nearSurfaceProbes(*torus_, 800, 0.5 * kRadius, 3)) v.push_back(before * p);
    return v;
  }();
  std::vector<SceneContact> contacts(scene.size());
  SceneQueryResult out;
  for (int step = 0; step < 5; ++step) {
    const Eigen::Isometry3d pose = makePose(-0.1 * step, 0.05 * step, 0.02 * step, 0.4 * step, Vec3(0, 1, 1));
    scene.setPose(moving, pose);
    EXPECT_EQ(scene.detector(moving).get(), level) << "moving must not rebuild";
    EXPECT_LT((scene.boundCentre(moving) - pose * torus_->bounds().center()).norm(), 1e-12);
    for (const Vec3& local : nearSurfaceProbes(*torus_, 400, 2.5 * kRadius, 40 + step)) {
      const Vec3 p = pose * local;
      scene.query(p, kRadius, DetectionMode::Exact, contacts.data(), contacts.size(), out);
      expectMatchesReference(scene, p, kRadius, contacts.data(), out);
      if (HasFatalFailure()) return;
    }
    if (step > 0) {
      // The old place is empty now: those probes touch nothing of the moved object.
      for (const Vec3& p : nearBefore) {
        scene.query(p, kRadius, DetectionMode::Exact, contacts.data(), contacts.size(), out);
        for (std::uint32_t k = 0; k < out.contacts; ++k) ASSERT_NE(contacts[k].object, moving);
        expectMatchesReference(scene, p, kRadius, contacts.data(), out);
        if (HasFatalFailure()) return;
      }
    }
  }
}

TEST_F(SceneTest, FarObjectsAreRejectedByTheSceneBound) {
  SceneDetector scene;
  makeScene(scene);
  std::vector<SceneContact> contacts(scene.size());
  SceneQueryResult out;
  scene.query(Vec3(5, 5, 5), kRadius, DetectionMode::Exact, contacts.data(), contacts.size(), out);
  EXPECT_EQ(out.objectsRejected, scene.size());
  EXPECT_EQ(out.objectsQueried, 0u);
  EXPECT_FALSE(out.contact);
  // Near the lone torus_c only it is queried; every other object is rejected before its spheres.
  for (const Vec3& local : nearSurfaceProbes(*torus_, 200, kRadius, 9)) {
    const Vec3 p = scene.pose(2) * local;
    scene.query(p, kRadius, DetectionMode::Exact, contacts.data(), contacts.size(), out);
    EXPECT_EQ(out.objectsQueried, 1u);
    EXPECT_EQ(out.objectsRejected, scene.size() - 1);
    for (std::uint32_t k = 0; k < out.contacts; ++k) EXPECT_EQ(contacts[k].object, 2u);
  }
  // A bound is never too tight: every vertex of every object is within its bound.
  for (std::uint32_t i = 0; i < scene.size(); ++i) {
    for (const Vec3& v : scene.mesh(i)->vertices)
      ASSERT_LE((scene.pose(i) * v - scene.boundCentre(i)).norm(), scene.boundRadius(i));
  }
}

TEST_F(SceneTest, ObjectWithoutLevelIsAnsweredByBruteForceThenBySwappedLevel) {
  SceneDetector scene;
  makeScene(scene);
  scene.setDetector(3, nullptr);
  std::vector<SceneContact> contacts(scene.size());
  SceneQueryResult out;
  std::size_t bruteForce = 0;
  for (const Vec3& local : nearSurfaceProbes(*box_, 500, 0.9 * kRadius, 21)) {
    const Vec3 p = scene.pose(3) * local;
    scene.query(p, kRadius, DetectionMode::Exact, contacts.data(), contacts.size(), out);
    bruteForce += out.bruteForce;
    expectMatchesReference(scene, p, kRadius, contacts.data(), out);
    if (HasFatalFailure()) return;
  }
  EXPECT_EQ(bruteForce, 500u);
  scene.setDetector(3, boxLevel_);
  scene.query(scene.pose(3) * box_->vertices[0], kRadius, DetectionMode::Exact, contacts.data(), contacts.size(), out);
  EXPECT_EQ(out.bruteForce, 0u);
  EXPECT_TRUE(out.contact);
}

// In a scene: pushing into the box (8 x 4 x 2 cm) from above its top face to its middle, the
// summed penetration (the force's spring) grows at every step from the first touch, through the box's
// level and through the brute-force fallback of an object without a level, with the per-object caches.
TEST_F(SceneTest, PushingIntoAnObjectKeepsThePenetrationGrowing) {
  for (const bool withLevel : {true, false}) {
    SCOPED_TRACE(withLevel ? "level" : "brute force");
    SceneDetector scene;
    scene.addObject("box", box_, withLevel ? boxLevel_ : nullptr, Eigen::Isometry3d::Identity());
    std::vector<SceneContact> contacts(1);
    std::vector<QueryCache> caches(1);
    double last = -1.0;
    int touching = 0;
    for (int i = 0; i <= 200; ++i) {
      const Vec3 p(-0.1, 0.22, 0.03 + 2 * kRadius - (0.01 + 2 * kRadius) * i / 200.0);
      SceneQueryResult out;
      scene.query(p, kRadius, DetectionMode::Exact, contacts.data(), contacts.size(), out, caches.data());
      if (!out.contact) {
        ASSERT_LT(last, 0.0) << "step " << i << ": the contact was lost while pushing in";
        continue;
      }
      ++touching;
      ASSERT_GT(out.penetration.norm(), last) << "step " << i;
      ASSERT_GT(out.penetration.z(), 0.0) << "step " << i << ": pushes out through the top";
      ASSERT_EQ(out.maxDepth, contacts[0].local.depth);
      last = out.penetration.norm();
    }
    EXPECT_GT(touching, 150);
    EXPECT_NEAR(last, kRadius + 0.01, 1e-9) << "at the middle: r + half the thickness";
  }
}

TEST_F(SceneTest, InactiveObjectsAndAFullArray) {
  SceneDetector scene;
  makeScene(scene);
  std::vector<SceneContact> contacts(scene.size());
  SceneQueryResult out;
  const Vec3 onA = torus_->vertices[0];  // on torus_a (identity pose)
  scene.setActive(0, false);
  scene.query(onA, kRadius, DetectionMode::Exact, contacts.data(), contacts.size(), out);
  EXPECT_EQ(out.objectsInactive, 1u);
  for (std::uint32_t k = 0; k < out.contacts; ++k) EXPECT_NE(contacts[k].object, 0u);
  scene.setActive(0, true);
  scene.query(onA, kRadius, DetectionMode::Exact, contacts.data(), contacts.size(), out);
  ASSERT_TRUE(out.contact);
  EXPECT_EQ(contacts[0].object, 0u);
  // Capacity zero: nothing written, the combined answer still complete.
  SceneQueryResult none;
  scene.query(onA, kRadius, DetectionMode::Exact, nullptr, 0, none);
  EXPECT_TRUE(none.contact);
  EXPECT_EQ(none.contacts, 0u);
  EXPECT_EQ(none.touched, out.touched);
  EXPECT_EQ(none.deepest, -1);
  EXPECT_LT((none.penetration - out.penetration).norm(), 1e-15);
  // Non-finite input: no contact, no throw.
  scene.query(Vec3(NAN, 0, 0), kRadius, DetectionMode::Exact, contacts.data(), contacts.size(), out);
  EXPECT_FALSE(out.contact);
  scene.query(onA, -1.0, DetectionMode::Exact, contacts.data(), contacts.size(), out);
  EXPECT_FALSE(out.contact);
}

TEST_F(SceneTest, BadObjectsAreRefused) {
  SceneDetector scene;
  EXPECT_THROW(scene.addObject("none", nullptr, nullptr, Eigen::Isometry3d::Identity()), InvalidParameter);
  EXPECT_THROW(scene.addObject("wrong level", box_, torusLevel_, Eigen::Isometry3d::Identity()), InvalidParameter);
  Eigen::Isometry3d scaled = Eigen::Isometry3d::Identity();
  scaled.linear() *= 2.0;
  EXPECT_THROW(scene.addObject("scaled", torus_, torusLevel_, scaled), InvalidParameter);
  Eigen::Isometry3d nan = Eigen::Isometry3d::Identity();
  nan.translation().x() = NAN;
  EXPECT_THROW(scene.addObject("nan", torus_, torusLevel_, nan), InvalidParameter);
  const auto i = scene.addObject("ok", torus_, torusLevel_, Eigen::Isometry3d::Identity());
  EXPECT_THROW(scene.setPose(i, scaled), InvalidParameter);
  EXPECT_THROW(scene.setDetector(i, boxLevel_), InvalidParameter);
  EXPECT_EQ(scene.size(), 1u);
}

TEST_F(SceneTest, QueryAllocatesNothing) {
  SceneDetector scene;
  makeScene(scene);
  scene.setDetector(3, nullptr);  // the brute-force path too
  std::vector<SceneContact> contacts(scene.size());
  std::vector<QueryCache> caches(scene.size());
  const std::vector<Vec3> probes = scenePrabes(scene, 200);
  SceneQueryResult out;
  std::size_t touched = 0;
  gAllocations = 0;
  gCounting = true;
  for (const Vec3& p : probes) {
    scene.query(p, kRadius, DetectionMode::Exact, contacts.data(), contacts.size(), out, caches.data());
    touched += out.touched;
  }
  gCounting = false;
  EXPECT_EQ(gAllocations.load(), 0);
  EXPECT_GT(touched, 0u);
  // The same through the tree over the bounds, with a stream's SceneCaches.
  for (int k = 0; k < 8; ++k)
    scene.addObject("far_" + std::to_string(k), torus_, torusLevel_,
                    makePose(1.0 + 0.2 * k, 1.0, 1.0, 0.0, Vec3::UnitZ()));
  SceneCaches stream;
  stream.resize(scene.size());
  touched = 0;
  gAllocations = 0;
  gCounting = true;
  for (const Vec3& p : probes) {
    scene.query(p, kRadius, DetectionMode::Exact, contacts.data(), contacts.size(), out, stream);
    touched += out.touched;
  }
  gCounting = false;
  EXPECT_EQ(gAllocations.load(), 0);
  EXPECT_GT(touched, 0u);
}

// With a stream's SceneCaches (its neighbourhood found through the tree over the bounds, kept while the pointer stays
// near) a scene of twenty objects answers exactly what the flat scan answers with an array of caches (every field,
// every contact, every cache's deep-push flag after each query), and what brute force answers per object: over probes
// near every object with jumps between them, pushes in deeper than r step by step (the neighbourhood kept) and a
// jump away and back, a smaller and then a larger radius, objects moved and switched off and on in the middle of
// the stream (the neighbourhood dropped), and the spheres mode.
TEST_F(SceneTest, ATreeOverManyObjectsAnswersLikeTheFlatScan) {
  SceneDetector scene;
  makeScene(scene);
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int k = 0; k < 16; ++k) {  // around the first four, some overlapping each other's bounds
    const Eigen::Isometry3d pose =
        makePose(0.4 * u(rng), 0.4 * u(rng), 0.3 * u(rng), 3.0 * u(rng), Vec3(u(rng), u(rng), 1.0 + 0.5 * u(rng)));
    if (k % 4 == 3)
      scene.addObject("box_" + std::to_string(k), box_, boxLevel_, pose);
    else
      scene.addObject("torus_" + std::to_string(k), torus_, torusLevel_, pose);
  }
  scene.setDetector(7, nullptr);  // brute force on one of them
  std::vector<Vec3> probes = scenePrabes(scene, 150);
  std::shuffle(probes.begin(), probes.end(), rng);  // jumps between objects
  // Pushes along the inward normal from 2 r out to 3 r in, then a jump far away, and back in deep.
  std::vector<Vec3> pushes;
  for (std::uint32_t i : {0u, 5u, 9u, 14u}) {
    const ContactResult c = bruteForceQuery(*scene.mesh(i), nearSurfaceProbes(*scene.mesh(i), 1, 0.0, 3 + i)[0], 1.0);
    const Vec3 in = -(scene.pose(i).linear() * c.normal), at = scene.pose(i) * c.point;
    for (int step = -10; step <= 15; ++step) pushes.push_back(at + in * (0.2 * kRadius * step));
    pushes.push_back(Vec3(5, 5, 5));
    pushes.push_back(at + in * (3.0 * kRadius));
  }
  std::vector<SceneContact> flatContacts(scene.size()), treeContacts(scene.size());
  std::vector<QueryCache> flatCaches(scene.size());
  SceneCaches treeCaches;
  treeCaches.resize(scene.size());
  std::vector<char> followed(scene.size(), 0);
  std::size_t queries = 0, touching = 0, deep = 0, fewQueried = 0;
  std::uint32_t lastContacts = 0;
  auto compare = [&](const Vec3& p, DetectionMode mode, double r = kRadius) {
    SceneQueryResult flat, tree;
    scene.query(p, r, mode, flatContacts.data(), flatContacts.size(), flat, flatCaches.data());
    scene.query(p, r, mode, treeContacts.data(), treeContacts.size(), tree, treeCaches);
    ++queries;
    lastContacts = tree.contacts;
    ASSERT_EQ(tree.contact, flat.contact);
    ASSERT_EQ(tree.contacts, flat.contacts);
    ASSERT_EQ(tree.touched, flat.touched);
    ASSERT_EQ(tree.deepest, flat.deepest);
    ASSERT_EQ(tree.maxDepth, flat.maxDepth);
    ASSERT_EQ(tree.penetration, flat.penetration);
    ASSERT_EQ(tree.objectsQueried, flat.objectsQueried);
    ASSERT_EQ(tree.objectsRejected, flat.objectsRejected);
    ASSERT_EQ(tree.objectsInactive, flat.objectsInactive);
    ASSERT_EQ(tree.bruteForce, flat.bruteForce);
    for (std::uint32_t k = 0; k < flat.contacts; ++k) {
      ASSERT_EQ(treeContacts[k].object, flatContacts[k].object);
      ASSERT_EQ(treeContacts[k].local.distance, flatContacts[k].local.distance);
      ASSERT_EQ(treeContacts[k].local.depth, flatContacts[k].local.depth);
      ASSERT_EQ(treeContacts[k].local.inside, flatContacts[k].local.inside);
      ASSERT_EQ(treeContacts[k].point, flatContacts[k].point);
      ASSERT_EQ(treeContacts[k].normal, flatContacts[k].normal);
    }
    for (std::uint32_t i = 0; i < scene.size(); ++i)
      ASSERT_EQ(treeCaches.objects[i].lastInside, flatCaches[i].lastInside) << "object " << i;
    if (mode == DetectionMode::Exact && r == kRadius) {
      expectMatchesReference(scene, p, kRadius, treeContacts.data(), tree, &followed);
      touching += tree.contact;
      deep += tree.contact && tree.maxDepth > 2.0 * kRadius;
      fewQueried +=
          tree.objectsQueried + tree.objectsRejected + tree.objectsInactive == scene.size() && tree.objectsQueried <= 2;
    }
  };
  for (std::size_t k = 0; k < probes.size(); ++k) {
    if (k == probes.size() / 3) scene.setPose(3, makePose(0.1, -0.1, 0.05, 0.5, Vec3(1, 0, 0)));
    if (k == probes.size() / 2) scene.setActive(11, false);
    if (k == 2 * probes.size() / 3) scene.setActive(11, true);
    compare(probes[k], DetectionMode::Exact);
    if (HasFatalFailure()) return;
  }
  std::size_t movedIn = 0;
  for (std::size_t k = 0; k < pushes.size(); ++k) {
    // Mid-push, another object is moved onto the one pushed into: the stream's neighbourhood must see it.
    if (k == 12) scene.setPose(18, scene.pose(0) * makePose(0, 0, 0, 0.2, Vec3::UnitZ()));
    compare(pushes[k], DetectionMode::Exact);
    if (HasFatalFailure()) return;
    for (std::uint32_t c = 0; c < lastContacts && k >= 12 && k < 26; ++c) movedIn += treeContacts[c].object == 18;
  }
  EXPECT_GT(movedIn, 0u) << "the moved object must be touched by the push";
  for (std::size_t k = 0; k < pushes.size(); ++k) {  // a smaller radius (the neighbourhood holds), then a larger one
    compare(pushes[k], DetectionMode::Exact, (k / 8) % 2 ? 0.5 * kRadius : 3.0 * kRadius);
    if (HasFatalFailure()) return;
  }
  std::fill(followed.begin(), followed.end(), 0);
  for (std::uint32_t i = 0; i < scene.size(); ++i) followed[i] = treeCaches.objects[i].lastInside;
  for (std::size_t k = 0; k < probes.size(); k += 5) {
    compare(probes[k], DetectionMode::Spheres);
    if (HasFatalFailure()) return;
  }
  // Caches sized for another scene (a caller's mistake): answered as without caches, and left as they were.
  SceneCaches wrong;
  wrong.resize(3);
  wrong.objects[1].lastInside = true;
  for (std::size_t k = 0; k < probes.size(); k += 7) {
    SceneQueryResult plain, withWrong;
    scene.query(probes[k], kRadius, DetectionMode::Exact, flatContacts.data(), flatContacts.size(), plain);
    scene.query(probes[k], kRadius, DetectionMode::Exact, treeContacts.data(), treeContacts.size(), withWrong, wrong);
    ASSERT_EQ(withWrong.contacts, plain.contacts);
    ASSERT_EQ(withWrong.penetration, plain.penetration);
    ASSERT_EQ(withWrong.objectsQueried, plain.objectsQueried);
  }
  EXPECT_EQ(wrong.sceneVersion, 0u);
  EXPECT_EQ(wrong.insideCount, 0u);
  EXPECT_TRUE(wrong.objects[1].lastInside);
  EXPECT_GT(touching, queries / 4);
  EXPECT_GT(deep, 10u) << "the pushes must go deeper than r";
  EXPECT_GT(fewQueried, queries / 2);
}

// A scene of one object answers what its detector answers, in every mode: the scene-level bounds never reject a
// pointer the detector would find in contact, also in spheres mode where the CLOD spheres reach beyond the mesh.
// At the origin and 1e6 away (a mesh in world coordinates, kept relative to its local origin): the scene's bounds
// never reject what the object's detector answers, and exact answers equal the brute force.
TEST(SceneOfOne, AnswersWhatItsDetectorAnswersInEveryMode) {
  const TriangleMesh torus = loadMesh(std::string(CLOD_PACKAGE_DATA_DIR) + "/meshes/torus.obj");
  for (const Vec3& offset : {Vec3::Zero().eval(), Vec3(1e6, -2e5, 3e4)}) {
    SCOPED_TRACE("offset " + std::to_string(offset.x()));
    std::vector<Vec3> moved;
    for (const Vec3& v : torus.vertices) moved.push_back(torus.toModel(v) + offset);
    auto mesh = std::make_shared<const TriangleMesh>(makeMesh(moved, torus.triangles, "torus"));
    auto set = std::make_shared<const ClodSphereSet>(ClodBuilder(mesh).build(0.01));  // coarse: large spheres
    auto level = std::make_shared<const ClodDetector>(mesh, set, FastLevel::Hierarchy);
    SceneDetector scene;
    scene.addObject("torus", mesh, level, Eigen::Isometry3d::Identity());
    std::mt19937 rng(11);
    const Eigen::AlignedBox3d box = mesh->modelBounds();
    std::uniform_real_distribution<double> ux(box.min().x() - 0.02, box.max().x() + 0.02),
        uy(box.min().y() - 0.02, box.max().y() + 0.02), uz(box.min().z() - 0.02, box.max().z() + 0.02);
    std::size_t sphereContacts = 0, outsideMeshBox = 0, exactContacts = 0;
    SceneContact contacts[1];
    for (DetectionMode mode : {DetectionMode::Exact, DetectionMode::Paper, DetectionMode::Spheres}) {
      for (int k = 0; k < 4000; ++k) {
        const Vec3 p(ux(rng), uy(rng), uz(rng));
        const double r = 0.003;
        ContactResult expected;
        level->query(p, r, mode, expected);
        SceneQueryResult out;
        scene.query(p, r, mode, contacts, 1, out);
        ASSERT_EQ(out.contact, expected.contact) << toString(mode) << " probe " << p.transpose();
        if (mode == DetectionMode::Exact) {
          const ContactResult reference = bruteForceQuery(*mesh, p, r);
          ASSERT_EQ(expected.contact, reference.contact) << "probe " << p.transpose();
          if (reference.contact) {
            ++exactContacts;
            EXPECT_NEAR(expected.distance, reference.distance, 1e-12 * r);
            EXPECT_LE((expected.point - reference.point).norm(), 1e-12 * r + 4e-16 * offset.norm());
          }
        }
        if (!expected.contact) continue;
        EXPECT_EQ(contacts[0].local.point, expected.point);
        EXPECT_EQ(contacts[0].local.depth, expected.depth);
        if (mode == DetectionMode::Spheres) {
          ++sphereContacts;
          outsideMeshBox += box.exteriorDistance(p) > r;
        }
      }
    }
    EXPECT_GT(exactContacts, 50u);
    EXPECT_GT(sphereContacts, 100u);
    EXPECT_GT(outsideMeshBox, 0u) << "no probe tested the spheres beyond the mesh's box";
  }
}

}  // namespace
