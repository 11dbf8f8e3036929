// Conversions core <-> messages (no roscore).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>

#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/detector.h"
#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/sphere_set.h"
#include "clod_haptics/ros/conversions.h"
#include "clod_haptics/test_config.h"

namespace clod_haptics {
namespace {

std::shared_ptr<const TriangleMesh> torus() {
  static auto mesh = std::make_shared<const TriangleMesh>(loadMesh(CLOD_PACKAGE_DATA_DIR "/meshes/torus.obj"));
  return mesh;
}

TEST(Conversions, SphereSetRoundTripKeepsEverything) {
  ClodBuilder builder(torus());
  const ClodSphereSet set = builder.build(0.003);
  ASSERT_GT(set.size(), 1u);
  std_msgs::Header header;
  header.frame_id = "mesh";
  SphereSet msg;
  toMsg(set, header, msg);
  EXPECT_EQ(msg.header.frame_id, "mesh");
  EXPECT_EQ(msg.spheres.size(), set.size());
  EXPECT_EQ(msg.stats.spheres, set.stats.spheres);
  EXPECT_EQ(msg.stats.triangles, torus()->size());
  EXPECT_DOUBLE_EQ(msg.distance, 0.003);

  const ClodSphereSet back = fromMsg(msg);
  EXPECT_EQ(back.meshName, set.meshName);
  EXPECT_DOUBLE_EQ(back.distance, set.distance);
  ASSERT_EQ(back.size(), set.size());
  EXPECT_EQ(back.offsets, set.offsets);
  EXPECT_EQ(back.triangles, set.triangles);
  for (std::size_t i = 0; i < set.size(); ++i) {
    EXPECT_EQ(back.centres[i], set.centres[i]);
    EXPECT_EQ(back.radii[i], set.radii[i]);
  }
  EXPECT_EQ(back.stats.centres, set.stats.centres);
  EXPECT_EQ(fitProblem(*torus(), back), "");
}

TEST(Conversions, SphereSetMessageCarriesTheLocalOrigin) {
  std::vector<Vec3> far;
  for (const Vec3& v : torus()->vertices) far.push_back(torus()->toModel(v) + Vec3(0.0, 5e5, 0.0));
  const auto mesh = std::make_shared<const TriangleMesh>(makeMesh(far, torus()->triangles, "far torus"));
  ASSERT_NE(mesh->origin.y(), 0.0);
  const ClodSphereSet set = ClodBuilder(mesh).build(0.003);
  SphereSet msg;
  toMsg(set, std_msgs::Header(), msg);
  EXPECT_EQ(msg.origin.y, mesh->origin.y());
  const ClodSphereSet back = fromMsg(msg);
  EXPECT_EQ(back.origin, set.origin);
  EXPECT_EQ(fitProblem(*mesh, back), "");
  msg.origin.x = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(fromMsg(msg), FormatError);
}

TEST(Conversions, FromMsgRejectsNonFiniteAndNegativeRadius) {
  SphereSet msg;
  msg.spheres.resize(1);
  msg.spheres[0].radius = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(fromMsg(msg), FormatError);
  msg.spheres[0].radius = -1.0;
  EXPECT_THROW(fromMsg(msg), FormatError);
  msg.spheres[0].radius = 1.0;
  msg.spheres[0].center.x = std::numeric_limits<double>::infinity();
  EXPECT_THROW(fromMsg(msg), FormatError);
}

TEST(Conversions, CoverageCheckCatchesAnotherMeshOrScale) {
  ClodBuilder builder(torus());
  ClodSphereSet set = builder.build(0.003);
  EXPECT_EQ(fitProblem(*torus(), set), "");

  ClodSphereSet shrunk = set;
  shrunk.radii[0] *= 0.5;  // a triangle now sticks out
  EXPECT_NE(fitProblem(*torus(), shrunk), "");

  ClodSphereSet outOfRange = set;
  outOfRange.triangles[0] = static_cast<std::uint32_t>(torus()->size());
  EXPECT_NE(fitProblem(*torus(), outOfRange).find("lists triangle"), std::string::npos);

  // The same file loaded at twice the scale does not fit the set.
  MeshLoadOptions options;
  options.scale = 2.0;
  const TriangleMesh bigger = loadMesh(CLOD_PACKAGE_DATA_DIR "/meshes/torus.obj", options);
  EXPECT_NE(fitProblem(bigger, set), "");

  ClodSphereSet missing = set;  // drop the last sphere: its triangles may be uncovered
  missing.centres.clear();
  missing.radii.clear();
  missing.offsets.assign(1, 0);
  missing.triangles.clear();
  EXPECT_NE(fitProblem(*torus(), missing).find("in no sphere"), std::string::npos);
}

TEST(Conversions, ContactMessageMatchesTheCoreResult) {
  const Vec3 p(0.083, 0.0, 0.0);  // 1 mm outside the torus's outer equator
  const ContactResult r = bruteForceQuery(*torus(), p, 0.002);
  ASSERT_TRUE(r.contact);
  Contact msg;
  toMsg(r, p, 0.002, msg);
  EXPECT_TRUE(msg.in_contact);
  EXPECT_DOUBLE_EQ(msg.point.x, r.point.x());
  EXPECT_DOUBLE_EQ(msg.normal.x, r.normal.x());
  EXPECT_DOUBLE_EQ(msg.distance, r.distance);
  EXPECT_DOUBLE_EQ(msg.depth, r.depth);
  EXPECT_FALSE(msg.inside);
  EXPECT_EQ(msg.triangle, r.triangle);
  EXPECT_DOUBLE_EQ(msg.pointer.x, 0.083);
  EXPECT_DOUBLE_EQ(msg.pointer_radius, 0.002);

  // No contact clears the stale fields of a reused message.
  const ContactResult none = bruteForceQuery(*torus(), Vec3(0.2, 0.0, 0.0), 0.002);
  ASSERT_FALSE(none.contact);
  toMsg(none, Vec3(0.2, 0.0, 0.0), 0.002, msg);
  EXPECT_FALSE(msg.in_contact);
  EXPECT_EQ(msg.triangle, -1);
  EXPECT_EQ(msg.sphere, -1);
  EXPECT_EQ(msg.depth, 0.0);
  EXPECT_EQ(msg.normal.x, 0.0);

  // Behind the surface: inside, and the depth r + distance.
  const Vec3 in(0.0805, 0.0, 0.0);  // 1.5 mm inside the outer equator
  const ContactResult deep = bruteForceQuery(*torus(), in, 0.002);
  ASSERT_TRUE(deep.contact && deep.inside);
  toMsg(deep, in, 0.002, msg);
  EXPECT_TRUE(msg.inside);
  EXPECT_DOUBLE_EQ(msg.depth, 0.002 + deep.distance);
  toMsg(none, Vec3(0.2, 0.0, 0.0), 0.002, msg);
  EXPECT_FALSE(msg.inside) << "cleared with the other stale fields";
}

TEST(Conversions, ForceToWrenchHasNoTorque) {
  geometry_msgs::Wrench w;
  toMsg(Vec3(1.0, 2.0, 3.0), w);
  EXPECT_EQ(w.force.z, 3.0);
  EXPECT_EQ(w.torque.x, 0.0);
}

TEST(Conversions, IsFiniteRejectsNanAndInfAnywhere) {
  geometry_msgs::Pose pose;
  pose.orientation.w = 1.0;
  EXPECT_TRUE(isFinite(pose));
  for (int k = 0; k < 7; ++k) {
    geometry_msgs::Pose bad = pose;
    double* fields[7] = {&bad.position.x,    &bad.position.y,    &bad.position.z,   &bad.orientation.x,
                         &bad.orientation.y, &bad.orientation.z, &bad.orientation.w};
    *fields[k] = (k % 2) ? std::numeric_limits<double>::infinity() : std::numeric_limits<double>::quiet_NaN();
    EXPECT_FALSE(isFinite(bad)) << "field " << k;
  }
}

}  // namespace
}  // namespace clod_haptics

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
