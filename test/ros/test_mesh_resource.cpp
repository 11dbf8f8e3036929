// Mesh parameter resolution: paths, file:// and package:// (needs ROS_PACKAGE_PATH, no roscore), and
// the rule for relative paths a user typed (resolveUserPath, core/user_path.h): the launch directory
// $PWD first, then the working directory, and an error naming every path tried.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>

#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/user_path.h"
#include "clod_haptics/ros/mesh_resource.h"
#include "../scoped_pwd.h"

namespace clod_haptics {
namespace {

namespace fs = std::filesystem;

/** A fresh directory tree under the test's temp dir: launch/ (the user's shell), work/ (ROS_HOME). */
class UserPathTree : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::path(::testing::TempDir()) /
            ("clod_user_path_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(root_);
    fs::create_directories(root_ / "launch" / "sub");
    fs::create_directories(root_ / "work");
    fs::create_directories(root_ / "meshes");
    root_ = fs::canonical(root_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(root_, ec);
  }
  std::string touch(const fs::path& relative) const {
    std::ofstream(root_ / relative) << "OFF\n";
    return (root_ / relative).string();
  }
  UserPathBase base() const { return {(root_ / "launch").string(), (root_ / "work").string(), root_.string()}; }

  fs::path root_;
};

using clod_test::ScopedPwd;

TEST(MeshResource, AbsolutePathsAndFileUrisPassThrough) {
  EXPECT_EQ(resolveMeshPath("/tmp/a.obj"), "/tmp/a.obj");
  EXPECT_EQ(resolveMeshPath("file:///tmp/c.stl"), "/tmp/c.stl");
}

TEST_F(UserPathTree, RelativePathIsFoundRelativeToTheLaunchDirectoryFirst) {
  const std::string inLaunch = touch("launch/sub/m.off");
  touch("work/sub/m.off");  // the same name under the working directory loses
  const UserPathResolution r = resolveUserPath("sub/m.off", base());
  EXPECT_TRUE(r.found());
  EXPECT_EQ(r.path, inLaunch);
  ASSERT_EQ(r.tried.size(), 2u);
  EXPECT_EQ(r.tried[1].path, (root_ / "work/sub/m.off").string());
}

TEST_F(UserPathTree, DotDotIsResolvedAgainstTheLaunchDirectory) {
  const std::string mesh = touch("meshes/m.off");
  const UserPathResolution r = resolveUserPath("../meshes/m.off", base());
  EXPECT_EQ(r.path, mesh);  // written without "..", as the user would read it
  EXPECT_EQ(r.tried.front().path, mesh);
}

TEST_F(UserPathTree, WorkingDirectoryIsTheFallback) {
  const std::string inWork = touch("work/m.off");
  EXPECT_EQ(resolveUserPath("m.off", base()).path, inWork);
  // Without $PWD only the working directory is tried, and the message says $PWD was missing.
  UserPathBase noPwd = base();
  noPwd.launchDir.clear();
  const UserPathResolution r = resolveUserPath("m.off", noPwd);
  EXPECT_EQ(r.path, inWork);
  ASSERT_EQ(r.tried.size(), 1u);
  EXPECT_NE(r.tried[0].origin.find("$PWD"), std::string::npos) << r.tried[0].origin;
  // A relative $PWD means nothing: ignored.
  noPwd.launchDir = "launch";
  EXPECT_EQ(resolveUserPath("m.off", noPwd).tried.size(), 1u);
}

TEST_F(UserPathTree, SameDirectoryIsTriedOnce) {
  UserPathBase same = base();
  same.workingDir = same.launchDir;
  const UserPathResolution r = resolveUserPath("missing.off", same);
  EXPECT_FALSE(r.found());
  ASSERT_EQ(r.tried.size(), 1u);
  EXPECT_NE(r.tried[0].origin.find("also the node's working directory"), std::string::npos) << r.tried[0].origin;
}

TEST_F(UserPathTree, NotFoundListsEveryPathTried) {
  UserPathBase deeper = base();
  deeper.workingDir = (root_ / "work" / "deeper").string();
  const UserPathResolution r = resolveUserPath("../x.off", deeper);
  EXPECT_FALSE(r.found());
  EXPECT_TRUE(r.path.empty());
  EXPECT_EQ(r.triedText(), (root_ / "x.off").string() + " (relative to the launch directory $PWD) and " +
                               (root_ / "work/x.off").string() + " (the node's working directory)");
}

TEST_F(UserPathTree, DirectoriesAreNotFilesAndAbsolutePathsAreOneCandidate) {
  EXPECT_FALSE(resolveUserPath("sub", base()).found());  // launch/sub is a directory
  const std::string mesh = touch("meshes/m.off");
  const UserPathResolution r = resolveUserPath(mesh, base());
  EXPECT_EQ(r.path, mesh);
  ASSERT_EQ(r.tried.size(), 1u);
  EXPECT_FALSE(resolveUserPath((root_ / "none.off").string(), base()).found());
  EXPECT_FALSE(resolveUserPath("", base()).found());
}

TEST_F(UserPathTree, TildeIsHome) {
  const std::string mesh = touch("meshes/m.off");
  EXPECT_EQ(resolveUserPath("~/meshes/m.off", base()).path, mesh);  // base().home is root_
}

TEST_F(UserPathTree, MeshParameterRelativeToTheLaunchDirectory) {
  const std::string mesh = touch("meshes/m.off");
  ScopedPwd pwd((root_ / "launch").string());
  EXPECT_EQ(resolveMeshPath("../meshes/m.off"), mesh);
  EXPECT_EQ(resolveMeshPath("file://../meshes/m.off"), mesh);
}

TEST_F(UserPathTree, MissingRelativeMeshNamesEveryPathTried) {
  ScopedPwd pwd((root_ / "launch").string());
  try {
    resolveMeshPath("../x.off");
    FAIL() << "a missing relative mesh must throw";
  } catch (const MeshLoadError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("'../x.off'"), std::string::npos) << what;
    EXPECT_NE(what.find((root_ / "x.off").string() + " (relative to the launch directory $PWD)"), std::string::npos)
        << what;
    EXPECT_NE(what.find("(the node's working directory)"), std::string::npos) << what;
    EXPECT_NE(
        what.find(fs::weakly_canonical(fs::current_path() / "../x.off").string() + " (the node's working directory)"),
        std::string::npos)
        << what;
  }
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
