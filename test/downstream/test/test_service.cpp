// The installed sphere_builder node's get_sphere_set from a downstream package, against a level built
// here with the installed core; the brief request's counts against the full lists.
#include <clod_haptics/GetSphereSet.h>
#include <clod_haptics/core/sphere_set.h>
#include <ros/ros.h>

#include "downstream_common.h"

using namespace clod_haptics;

TEST(DownstreamService, InstalledNodeServesTheLevelBuiltHere) {
  const std::string service = "/sphere_builder/get_sphere_set";
  ASSERT_TRUE(ros::service::waitForService(service, ros::Duration(120.0)));
  const double d = 0.02;
  const ClodSphereSet expected = ClodBuilder(downstream::installedTorus()).build(d);
  GetSphereSet full;
  full.request.distance = d;
  ASSERT_TRUE(ros::service::call(service, full));
  ASSERT_TRUE(full.response.success) << full.response.message;
  ASSERT_EQ(full.response.sphere_set.spheres.size(), expected.size());
  GetSphereSet brief;
  brief.request.distance = d;
  brief.request.brief = true;
  ASSERT_TRUE(ros::service::call(service, brief));
  ASSERT_TRUE(brief.response.success) << brief.response.message;
  ASSERT_EQ(brief.response.triangle_counts.size(), expected.size());
  EXPECT_TRUE(brief.response.sphere_set.spheres.empty());
  for (std::size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(full.response.sphere_set.spheres[i].triangles.size(), expected.offsets[i + 1] - expected.offsets[i]);
    EXPECT_EQ(brief.response.triangle_counts[i], expected.offsets[i + 1] - expected.offsets[i]);
  }
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_downstream_service");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
