// rostest of sphere_builder: service round trip against the core's ClodBuilder, bad requests, one
// build for concurrent requests of a level, the latched default level, a restart through the disk caches.
// Parameters (~): mesh, scale, normalize (same as the node's), distances (list), default_distance.
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include "clod_haptics/GetSphereSet.h"
#include "clod_haptics/SphereSet.h"
#include "clod_haptics/core/clustering.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/sphere_set.h"
#include "clod_haptics/ros/conversions.h"
#include "clod_haptics/ros/mesh_resource.h"
#include "clod_haptics/ros/sphere_builder_node.h"
#include "test_timing.h"

namespace clod_haptics {
namespace {

const std::string kService = "/sphere_builder/get_sphere_set";

std::shared_ptr<const TriangleMesh> referenceMesh() {
  static std::shared_ptr<const TriangleMesh> mesh = [] {
    ros::NodeHandle pnh("~");
    std::string uri;
    pnh.getParam("mesh", uri);
    MeshLoadOptions options;
    pnh.param("scale", options.scale, 1.0);
    pnh.param("normalize", options.normalize, false);
    return std::make_shared<const TriangleMesh>(loadMesh(resolveMeshPath(uri), options));
  }();
  return mesh;
}

/** The reference builder: the core's ClodBuilder with the clustering the node was started with (~clustering). */
const ClodBuilder& referenceBuilder() {
  static const ClodBuilder builder = [] {
    std::string clustering;
    ros::NodeHandle("~").param<std::string>("clustering", clustering, "single-link");
    return ClodBuilder(referenceMesh(), std::make_shared<PaperPlacement>(),
                       requireClustering(clustering, "~clustering"));
  }();
  return builder;
}

bool call(double d, GetSphereSet& srv) {
  srv.request.distance = d;
  return ros::service::call(kService, srv);
}

TEST(SphereBuilder, RoundTripMatchesTheCoreCountAndShrinksWithDistance) {
  ASSERT_TRUE(ros::service::waitForService(kService, ros::Duration(clod_haptics_test::scaled(60.0))));
  std::vector<double> distances;
  ros::NodeHandle("~").getParam("distances", distances);
  ASSERT_EQ(distances.size(), 3u);
  const ClodBuilder& reference = referenceBuilder();
  std::size_t previous = std::numeric_limits<std::size_t>::max();
  for (double d : distances) {
    GetSphereSet srv;
    ASSERT_TRUE(call(d, srv)) << "d = " << d;
    ASSERT_TRUE(srv.response.success) << srv.response.message;
    const ClodSphereSet expected = reference.build(d);
    const SphereSet& msg = srv.response.sphere_set;
    EXPECT_EQ(msg.spheres.size(), expected.size()) << "d = " << d;
    EXPECT_EQ(msg.stats.spheres, expected.size());
    EXPECT_EQ(msg.stats.centres, expected.stats.centres);
    EXPECT_EQ(msg.stats.triangles, referenceMesh()->size());
    EXPECT_DOUBLE_EQ(msg.distance, d);
    EXPECT_EQ(msg.header.frame_id, "world");
    EXPECT_LT(msg.spheres.size(), previous) << "the count must shrink as d grows (d = " << d << ")";
    previous = msg.spheres.size();
    // Same spheres as the core's, and they wrap every triangle of the mesh.
    const ClodSphereSet got = fromMsg(msg);
    EXPECT_EQ(got.triangles, expected.triangles);
    EXPECT_EQ(fitProblem(*referenceMesh(), got), "") << "d = " << d;
  }
}

TEST(SphereBuilder, BriefRequestGivesSizesWithoutTheSpheres) {
  ASSERT_TRUE(ros::service::waitForService(kService, ros::Duration(clod_haptics_test::scaled(60.0))));
  const double d = 0.02;
  const ClodSphereSet expected = referenceBuilder().build(d);
  GetSphereSet brief;
  brief.request.brief = true;
  ASSERT_TRUE(call(d, brief));
  ASSERT_TRUE(brief.response.success) << brief.response.message;
  const SphereSet& msg = brief.response.sphere_set;
  EXPECT_TRUE(msg.spheres.empty());
  ASSERT_EQ(brief.response.triangle_counts.size(), expected.size());
  EXPECT_EQ(msg.stats.spheres, expected.size());
  EXPECT_EQ(msg.stats.triangles, referenceMesh()->size());
  EXPECT_DOUBLE_EQ(msg.distance, d);
  std::size_t total = 0;
  for (std::size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(brief.response.triangle_counts[i], expected.offsets[i + 1] - expected.offsets[i]) << "sphere " << i;
    total += brief.response.triangle_counts[i];
  }
  EXPECT_GE(total, referenceMesh()->size()) << "every triangle is wrapped by at least one sphere";
  // The default request still carries the lists (what the detector asks for), and no counts.
  GetSphereSet full;
  ASSERT_TRUE(call(d, full));
  EXPECT_TRUE(full.response.triangle_counts.empty());
  EXPECT_EQ(fromMsg(full.response.sphere_set).triangles, expected.triangles);
  EXPECT_LT(ros::serialization::serializationLength(brief.response) * 4,
            ros::serialization::serializationLength(full.response));
}

TEST(SphereBuilder, BadRequestsAreRefusedAndTheNodeKeepsServing) {
  ASSERT_TRUE(ros::service::waitForService(kService, ros::Duration(clod_haptics_test::scaled(60.0))));
  for (double bad :
       {-0.01, -1e-12, std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()}) {
    GetSphereSet srv;
    ASSERT_TRUE(call(bad, srv)) << "the service must answer, not fail, for d = " << bad;
    EXPECT_FALSE(srv.response.success) << "d = " << bad;
    EXPECT_FALSE(srv.response.message.empty());
    EXPECT_TRUE(srv.response.sphere_set.spheres.empty());
  }
  GetSphereSet good;
  ASSERT_TRUE(call(0.03, good));
  EXPECT_TRUE(good.response.success) << good.response.message;
  EXPECT_FALSE(good.response.sphere_set.spheres.empty());
}

TEST(SphereBuilder, ConcurrentRequestsForANewLevelShareOneBuild) {
  ASSERT_TRUE(ros::service::waitForService(kService, ros::Duration(clod_haptics_test::scaled(60.0))));
  const double d = 0.0123;  // asked by no other test
  constexpr int kClients = 6;
  std::vector<GetSphereSet> answers(kClients);
  std::vector<char> ok(kClients, 0);
  std::atomic<int> ready{0};
  std::vector<std::thread> threads;
  for (int k = 0; k < kClients; ++k) {
    threads.emplace_back([&, k] {
      ++ready;
      while (ready < kClients) std::this_thread::yield();
      ok[k] = call(d, answers[k]);
    });
  }
  for (auto& t : threads) t.join();
  int built = 0;
  for (int k = 0; k < kClients; ++k) {
    ASSERT_TRUE(ok[k]);
    ASSERT_TRUE(answers[k].response.success) << answers[k].response.message;
    built += answers[k].response.message.rfind("built", 0) == 0 ? 1 : 0;
    EXPECT_EQ(answers[k].response.sphere_set.spheres.size(), answers[0].response.sphere_set.spheres.size());
  }
  EXPECT_EQ(built, 1) << "exactly one request may build the level; the others wait for it or hit the cache";
  GetSphereSet again;
  ASSERT_TRUE(call(d, again));
  EXPECT_EQ(again.response.message.rfind("cached", 0), 0u) << again.response.message;
}

TEST(SphereBuilder, DefaultLevelIsPublishedLatched) {
  double d = 0.0;
  ros::NodeHandle("~").param("default_distance", d, 0.02);
  ros::NodeHandle nh;
  SphereSetConstPtr latched;
  auto sub = nh.subscribe<SphereSet>("/sphere_builder/sphere_set", 1, [&](const SphereSetConstPtr& m) { latched = m; });
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(clod_haptics_test::scaled(30.0));
  while (!latched && ros::WallTime::now() < end) ros::WallDuration(0.01).sleep();
  ASSERT_TRUE(latched) << "nothing latched on /sphere_builder/sphere_set";
  EXPECT_DOUBLE_EQ(latched->distance, d);
  EXPECT_EQ(latched->spheres.size(), referenceBuilder().build(d).size());
}

// With ~use_cache, a sphere_builder started again over the same mesh and cache directory reads the mesh and its
// default level from the disk caches and runs no placement; its level is the core's, sphere for sphere. (Two
// in-process nodes in a namespace of their own, one after the other: each advertises its service.)
TEST(SphereBuilder, RestartReadsTheMeshAndTheDefaultLevelFromTheDiskCache) {
  ros::NodeHandle pnh("~");
  std::string uri, clustering;
  pnh.getParam("mesh", uri);
  pnh.param<std::string>("clustering", clustering, "single-link");
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("clod_sphere_builder_restart_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  ros::NodeHandle probe("~restart_probe");
  probe.setParam("mesh", uri);
  probe.setParam("scale", pnh.param("scale", 1.0));
  probe.setParam("normalize", pnh.param("normalize", false));
  probe.setParam("clustering", clustering);
  probe.setParam("default_distance", 0.004);
  probe.setParam("use_cache", true);
  probe.setParam("cache_dir", dir.string());
  {
    SphereBuilderNode first(ros::NodeHandle(), probe);
    EXPECT_TRUE(first.placementRan()) << "an empty cache: the first start places";
  }
  SphereBuilderNode second(ros::NodeHandle(), probe);
  EXPECT_FALSE(second.placementRan()) << "the restart read the mesh and the default level from " << dir;
  const auto set = second.level(0.004);
  const ClodSphereSet want = referenceBuilder().build(0.004);
  ASSERT_EQ(set->size(), want.size());
  EXPECT_EQ(set->offsets, want.offsets);
  EXPECT_EQ(set->triangles, want.triangles);
  for (std::size_t i = 0; i < want.size(); ++i) {
    EXPECT_EQ(set->centres[i], want.centres[i]) << "sphere " << i;
    EXPECT_EQ(set->radii[i], want.radii[i]) << "sphere " << i;
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace clod_haptics

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_sphere_builder");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  const int result = RUN_ALL_TESTS();
  ros::shutdown();
  return result;
}
