// Mesh parameter resolution: paths, file:// and package:// (needs ROS_PACKAGE_PATH, no roscore).
#include <gtest/gtest.h>

#include <fstream>

#include "clod_haptics/core/errors.h"
#include "clod_haptics/ros/mesh_resource.h"

namespace clod_haptics {
namespace {

TEST(MeshResource, PlainPathsPassThrough) {
  EXPECT_EQ(resolveMeshPath("/tmp/a.obj"), "/tmp/a.obj");
  EXPECT_EQ(resolveMeshPath("relative/b.off"), "relative/b.off");
  EXPECT_EQ(resolveMeshPath("file:///tmp/c.stl"), "/tmp/c.stl");
}

TEST(MeshResource, PackageUriResolvesToTheBundledMesh) {
  const std::string path = resolveMeshPath("package://clod_haptics/data/meshes/torus.obj");
  EXPECT_NE(path.find("/data/meshes/torus.obj"), std::string::npos);
  EXPECT_EQ(path.find("package://"), std::string::npos);
  std::ifstream file(path);
  EXPECT_TRUE(file.good()) << path;
}

TEST(MeshResource, BadUrisThrowMeshLoadError) {
  EXPECT_THROW(resolveMeshPath(""), MeshLoadError);
  EXPECT_THROW(resolveMeshPath("package://"), MeshLoadError);
  EXPECT_THROW(resolveMeshPath("package://no_such_package_xyz/m.obj"), MeshLoadError);
  EXPECT_THROW(resolveMeshPath("http://example.org/m.obj"), MeshLoadError);
}

}  // namespace
}  // namespace clod_haptics

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
