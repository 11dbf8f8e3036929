// rostest: a node started without a usable mesh must log a clear error and exit non-zero, not hang.
// Runs the real binaries (paths configured by CMake) against the test's master.
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>

#include "clod_haptics/test_config.h"
#include "run_command.h"

namespace {

using clod_haptics_test::Outcome;
using clod_haptics_test::run;

void expectCleanFailure(const Outcome& o, const std::string& mention) {
  EXPECT_NE(o.exitCode, 0) << o.output;
  EXPECT_NE(o.exitCode, 124) << "timed out (hung) instead of exiting: " << o.output;
  EXPECT_NE(o.exitCode, -1) << "crashed: " << o.output;
  EXPECT_NE(o.output.find(mention), std::string::npos) << "the error should mention '" << mention << "': " << o.output;
  EXPECT_NE(o.output.find("ERROR"), std::string::npos) << o.output;
}

TEST(BadParameters, SphereBuilderWithoutMeshParameterExitsNonZero) {
  expectCleanFailure(run(std::string(CLOD_SPHERE_BUILDER_PATH) + " __name:=sb_no_mesh"), "sb_no_mesh/mesh");
}

TEST(BadParameters, SphereBuilderWithMissingFileExitsNonZero) {
  expectCleanFailure(run(std::string(CLOD_SPHERE_BUILDER_PATH) + " __name:=sb_missing _mesh:=/nonexistent/x.obj"),
                     "/nonexistent/x.obj");
}

TEST(BadParameters, SphereBuilderWithUnreadableFileExitsNonZero) {
  const std::string path = CLOD_TEST_DATA_DIR "/ros_unreadable_mesh.obj";
  expectCleanFailure(run(std::string(CLOD_SPHERE_BUILDER_PATH) + " __name:=sb_unreadable _mesh:=" + path),
                     "ros_unreadable_mesh.obj");
}

TEST(BadParameters, SphereBuilderWithUnknownPackageExitsNonZero) {
  expectCleanFailure(
      run(std::string(CLOD_SPHERE_BUILDER_PATH) + " __name:=sb_pkg _mesh:=package://no_such_pkg_xyz/m.obj"),
      "no_such_pkg_xyz");
}

TEST(BadParameters, SphereBuilderWithUnknownClusteringExitsNonZero) {
  expectCleanFailure(run(std::string(CLOD_SPHERE_BUILDER_PATH) +
                         " __name:=sb_clustering _mesh:=package://clod_haptics/data/meshes/torus.obj _clustering:=chain"),
                     "sb_clustering/clustering");
}

TEST(BadParameters, DetectorNodeWithUnknownClusteringExitsNonZero) {
  expectCleanFailure(run(std::string(CLOD_DETECTOR_PATH) +
                         " __name:=det_clustering _mesh:=package://clod_haptics/data/meshes/torus.obj _clustering:=x"),
                     "det_clustering/clustering");
}

TEST(BadParameters, DetectorNodeWithUnknownPosePolicyExitsNonZero) {
  expectCleanFailure(run(std::string(CLOD_DETECTOR_PATH) + " __name:=det_bad_policy _pose_policy:=newest _mesh:=" +
                         CLOD_PACKAGE_DATA_DIR "/meshes/torus.obj"),
                     "~pose_policy must be all");
}

TEST(BadParameters, DetectorNodeWithOutOfRangeRealtimePriorityExitsNonZero) {
  expectCleanFailure(run(std::string(CLOD_DETECTOR_PATH) + " __name:=det_bad_rt _realtime_priority:=100 _mesh:=" +
                         CLOD_PACKAGE_DATA_DIR "/meshes/torus.obj"),
                     "~realtime_priority must be in 0..99");
}

TEST(BadParameters, DetectorNodeWithoutMeshParameterExitsNonZero) {
  expectCleanFailure(run(std::string(CLOD_DETECTOR_PATH) + " __name:=det_no_mesh"), "det_no_mesh/mesh");
}

TEST(BadParameters, SphereBuilderWithAGoodMeshKeepsRunning) {
  // The control: the same binary with a good mesh is still running when the time limit ends it.
  const Outcome o = run(
      std::string(CLOD_SPHERE_BUILDER_PATH) + " __name:=sb_good _mesh:=package://clod_haptics/data/meshes/torus.obj",
      8.0, "INT");
  EXPECT_TRUE(o.exitCode == 124 || o.exitCode == 0) << o.exitCode << ": " << o.output;
  EXPECT_NE(o.output.find("serving"), std::string::npos) << o.output;
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_bad_parameters");
  return RUN_ALL_TESTS();
}
