// Marker conversions (no roscore).
#include <gtest/gtest.h>

#include <set>
#include <string>

#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/mesh_loader.h"
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

TEST(Markers, SpheresHaveTheirDiameterAndShrinkingListsDeleteTheRest) {
  ClodSphereSet set;
  set.centres = {Vec3(0, 0, 0), Vec3(1, 2, 3), Vec3(4, 5, 6)};
  set.radii = {0.5, 0.25, 1.0};
  set.offsets = {0, 0, 0, 0};
  visualization_msgs::MarkerArray all;
  appendSphereMarkers(set, nullptr, marker_ns::kSpheres, header(), makeColor(0, 0, 1, 0.2f), 0, all);
  ASSERT_EQ(all.markers.size(), 3u);
  EXPECT_EQ(all.markers[1].type, Marker::SPHERE);
  EXPECT_EQ(all.markers[1].pose.position.y, 2.0);
  EXPECT_EQ(all.markers[1].scale.x, 0.5);
  EXPECT_EQ(all.markers[2].scale.z, 2.0);
  std::set<int> ids;
  for (const auto& m : all.markers) ids.insert(m.id);
  EXPECT_EQ(ids.size(), 3u);

  // Highlight sphere 2 only, after 3 were shown: one ADD (id 0, sphere 2's geometry) and two DELETEs.
  const std::vector<std::uint32_t> hit{2};
  visualization_msgs::MarkerArray some;
  appendSphereMarkers(set, &hit, marker_ns::kHitSpheres, header(), makeColor(1, 0.5f, 0, 0.5f), 3, some);
  ASSERT_EQ(some.markers.size(), 3u);
  EXPECT_EQ(some.markers[0].action, Marker::ADD);
  EXPECT_EQ(some.markers[0].ns, marker_ns::kHitSpheres);
  EXPECT_EQ(some.markers[0].pose.position.x, 4.0);
  EXPECT_EQ(some.markers[1].action, Marker::DELETE);
  EXPECT_EQ(some.markers[1].id, 1);
  EXPECT_EQ(some.markers[2].action, Marker::DELETE);
  EXPECT_EQ(some.markers[2].id, 2);
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
