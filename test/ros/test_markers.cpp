// Marker conversions (no roscore).
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <random>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/sphere_set.h"
#include "clod_haptics/ros/markers.h"
#include "clod_haptics/test_config.h"

namespace clod_haptics {
namespace {

using visualization_msgs::Marker;

const TriangleMesh& torus() {
  static const TriangleMesh mesh = loadMesh(CLOD_PACKAGE_DATA_DIR "/meshes/torus.obj");
  return mesh;
}

std_msgs::Header header() {
  std_msgs::Header h;
  h.frame_id = "world";
  return h;
}

TEST(Markers, MeshIsATriangleListOfEveryCorner) {
  const Marker m = meshMarker(torus(), header(), makeColor(1, 1, 1, 1));
  EXPECT_EQ(m.type, Marker::TRIANGLE_LIST);
  EXPECT_EQ(m.header.frame_id, "world");
  ASSERT_EQ(m.points.size(), 3 * torus().size());
  const Vec3& v = torus().vertex(5, 2);
  EXPECT_EQ(m.points[3 * 5 + 2].x, v.x());
  EXPECT_EQ(m.points[3 * 5 + 2].z, v.z());
  EXPECT_EQ(m.pose.orientation.w, 1.0);
}

// A mesh far from zero: the markers show it where it is (model frame), not at its local coordinates.
TEST(Markers, FarMeshAndItsSpheresAreDrawnInTheModelFrame) {
  std::vector<Vec3> far;
  for (const Vec3& v : torus().vertices) far.push_back(torus().toModel(v) + Vec3(2e5, 0.0, -1e6));
  const auto mesh = std::make_shared<const TriangleMesh>(makeMesh(far, torus().triangles, "far torus"));
  ASSERT_NE(mesh->origin.z(), 0.0);
  const Marker m = meshMarker(*mesh, header(), makeColor(1, 1, 1, 1));
  ASSERT_EQ(m.points.size(), 3 * mesh->size());
  EXPECT_EQ(m.points[3 * 5 + 2].z, far[mesh->triangles[5][2]].z());
  const ClodSphereSet set = ClodBuilder(mesh).build(0.003);
  visualization_msgs::MarkerArray out;
  appendSphereMarkers(set, nullptr, "spheres", header(), makeColor(1, 1, 1, 1), 0, out);
  ASSERT_FALSE(out.markers.empty());
  const Eigen::AlignedBox3d box = mesh->modelBounds();
  for (const Marker& list : out.markers)
    for (const auto& p : list.points) EXPECT_LT(box.exteriorDistance(Vec3(p.x, p.y, p.z)), 0.01) << p.x << " " << p.z;
}

// Every listed sphere is drawn exactly once, at its centre, never smaller than it is and at most one radius class
// (2^(1/8)) larger; fewer markers than before delete the rest.
TEST(Markers, SpheresAreListedByRadiusClassNeverDrawnSmallerAndShrinkingListsDeleteTheRest) {
  ClodSphereSet set;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> coord(-1.0, 1.0), logRadius(-12.0, 1.0);
  for (int i = 0; i < 500; ++i) {
    set.centres.emplace_back(coord(rng), coord(rng), coord(rng));
    set.radii.push_back(std::exp2(logRadius(rng)));
  }
  set.radii[7] = 0.25;  // exactly a class bound: drawn at 0.25, not one class up
  set.offsets.assign(set.radii.size() + 1, 0);
  auto check = [&](const visualization_msgs::MarkerArray& array, const std::vector<std::uint32_t>& listed,
                   const char* ns) {
    std::multiset<std::tuple<double, double, double>> seen;
    std::map<std::tuple<double, double, double>, double> drawn;
    for (const auto& m : array.markers) {
      if (m.action != Marker::ADD) continue;
      EXPECT_EQ(m.type, Marker::SPHERE_LIST);
      EXPECT_EQ(m.ns, ns);
      EXPECT_EQ(m.scale.x, m.scale.y);
      EXPECT_EQ(m.scale.x, m.scale.z);
      for (const auto& p : m.points) {
        seen.insert({p.x, p.y, p.z});
        drawn[{p.x, p.y, p.z}] = m.scale.x / 2.0;
      }
    }
    ASSERT_EQ(seen.size(), listed.size());
    for (std::uint32_t i : listed) {
      const auto key = std::make_tuple(set.centres[i].x(), set.centres[i].y(), set.centres[i].z());
      ASSERT_EQ(seen.count(key), 1u) << "sphere " << i;
      EXPECT_GE(drawn[key], set.radii[i]) << "sphere " << i << " drawn smaller than it is";
      EXPECT_LE(drawn[key], set.radii[i] * std::exp2(1.0 / kSphereClassesPerOctave) * (1.0 + 1e-12)) << "sphere " << i;
    }
  };
  std::vector<std::uint32_t> all(set.size());
  for (std::uint32_t i = 0; i < all.size(); ++i) all[i] = i;
  visualization_msgs::MarkerArray full;
  const std::size_t classes = appendSphereMarkers(set, nullptr, marker_ns::kSpheres, header(), makeColor(0, 0, 1, 0.2f), 0, full);
  EXPECT_EQ(classes, full.markers.size());
  EXPECT_LE(classes, 13u * kSphereClassesPerOctave + 1u);  // radii span 13 octaves
  EXPECT_GT(classes, 50u);
  check(full, all, marker_ns::kSpheres);
  std::set<int> ids;
  for (const auto& m : full.markers) ids.insert(m.id);
  EXPECT_EQ(ids.size(), classes);
  EXPECT_EQ(*ids.rbegin(), static_cast<int>(classes) - 1);

  // Highlight two spheres of different classes after `classes` lists were shown: two ADDs, then DELETEs for the rest.
  const std::vector<std::uint32_t> hit{7, 3};
  visualization_msgs::MarkerArray some;
  const std::size_t k = appendSphereMarkers(set, &hit, marker_ns::kHitSpheres, header(), makeColor(1, 0.5f, 0, 0.5f),
                                            classes, some);
  const std::set<double> hitClasses{std::ceil(8 * std::log2(set.radii[7])), std::ceil(8 * std::log2(set.radii[3]))};
  ASSERT_EQ(k, hitClasses.size());
  ASSERT_EQ(some.markers.size(), classes);
  check(some, hit, marker_ns::kHitSpheres);
  for (std::size_t m = k; m < classes; ++m) {
    EXPECT_EQ(some.markers[m].action, Marker::DELETE);
    EXPECT_EQ(some.markers[m].id, static_cast<int>(m));
  }
  // A radius on a class bound stays in its class: sphere 7 (0.25) is drawn with diameter 0.5 exactly.
  bool found = false;
  for (const auto& m : some.markers)
    for (const auto& p : m.points)
      if (p.x == set.centres[7].x() && p.y == set.centres[7].y() && p.z == set.centres[7].z()) {
        found = true;
        EXPECT_DOUBLE_EQ(m.scale.x, 0.5);
      }
  EXPECT_TRUE(found);
}

TEST(Markers, ContactShowsPointAndNormalOrClearsThem) {
  const Vec3 p(0.083, 0.0, 0.0);
  const ContactResult r = bruteForceQuery(torus(), p, 0.002);
  ASSERT_TRUE(r.contact);
  visualization_msgs::MarkerArray a;
  appendContactMarkers(r, 0.02, header(), a);
  ASSERT_EQ(a.markers.size(), 2u);
  const Marker& arrow = a.markers[1];
  EXPECT_EQ(arrow.type, Marker::ARROW);
  ASSERT_EQ(arrow.points.size(), 2u);
  EXPECT_NEAR(arrow.points[0].x, r.point.x(), 1e-15);
  const Vec3 tip(arrow.points[1].x, arrow.points[1].y, arrow.points[1].z);
  EXPECT_NEAR((tip - r.point).norm(), 0.02, 1e-12);
  EXPECT_NEAR((tip - r.point).normalized().dot(r.normal), 1.0, 1e-12);
  EXPECT_EQ(a.markers[0].pose.position.x, r.point.x());

  ContactResult none;
  visualization_msgs::MarkerArray cleared;
  appendContactMarkers(none, 0.02, header(), cleared);
  ASSERT_EQ(cleared.markers.size(), 2u);
  EXPECT_EQ(cleared.markers[0].action, Marker::DELETE);
  EXPECT_EQ(cleared.markers[1].action, Marker::DELETE);
  EXPECT_EQ(cleared.markers[0].ns, marker_ns::kContact);
  EXPECT_EQ(cleared.markers[1].ns, marker_ns::kNormal);
}

TEST(Markers, ForceIsAnArrowFromThePointScaledPerNewtonAndClearedWhenZero) {
  const Vec3 from(0.1, 0.2, 0.3);
  const Vec3 force(0.0, 0.6, 0.8);  // 1 N
  const Marker m = forceMarker(from, force, 0.03, header());
  EXPECT_EQ(m.ns, marker_ns::kForce);
  EXPECT_EQ(m.type, Marker::ARROW);
  ASSERT_EQ(m.points.size(), 2u);
  const Vec3 tail(m.points[0].x, m.points[0].y, m.points[0].z), tip(m.points[1].x, m.points[1].y, m.points[1].z);
  EXPECT_NEAR((tail - from).norm(), 0.0, 1e-15);
  EXPECT_NEAR((tip - tail - 0.03 * force).norm(), 0.0, 1e-12);
  // 10 N is drawn as 3 N: the arrow stays within the view.
  const Marker big = forceMarker(from, 10.0 * force, 0.03, header());
  EXPECT_NEAR(Vec3(big.points[1].x - from.x(), big.points[1].y - from.y(), big.points[1].z - from.z()).norm(), 0.09,
              1e-12);
  EXPECT_EQ(forceMarker(from, Vec3::Zero(), 0.03, header()).action, Marker::DELETE);
  EXPECT_EQ(forceMarker(from, Vec3(NAN, 0, 0), 0.03, header()).action, Marker::DELETE);
}

TEST(Markers, ContactPointIsSmallerThanTheArrowAndNotRed) {
  ContactResult r;
  r.contact = true;
  r.point = Vec3(0, 0, 0.01);
  r.normal = Vec3::UnitZ();
  visualization_msgs::MarkerArray a;
  appendContactMarkers(r, 0.02, header(), a);
  ASSERT_EQ(a.markers.size(), 2u);
  EXPECT_LT(a.markers[0].scale.x, 0.2 * 0.02);
  EXPECT_GT(a.markers[0].color.b, 0.5f);  // magenta, unlike the red pointer in contact
}

TEST(Markers, PointerIsASphereOfTheRadius) {
  const Marker m = pointerMarker(Vec3(1, 2, 3), 0.002, header(), makeColor(0, 1, 0, 1));
  EXPECT_EQ(m.type, Marker::SPHERE);
  EXPECT_EQ(m.ns, marker_ns::kPointer);
  EXPECT_EQ(m.pose.position.z, 3.0);
  EXPECT_DOUBLE_EQ(m.scale.x, 0.004);
}

}  // namespace
}  // namespace clod_haptics

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
