// Scene files as the parameter server holds them (XmlRpc): fields, defaults, and clear errors for bad input.

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "clod_haptics/core/errors.h"
#include "clod_haptics/ros/scene_config.h"

namespace {

using namespace clod_haptics;
using XmlRpc::XmlRpcValue;

XmlRpcValue object(const std::string& name, const std::string& mesh) {
  XmlRpcValue o;
  o["name"] = name;
  o["mesh"] = mesh;
  return o;
}

XmlRpcValue vec(double a, double b, double c) {
  XmlRpcValue v;
  v.setSize(3);
  v[0] = a;
  v[1] = b;
  v[2] = c;
  return v;
}

XmlRpcValue sceneOf(std::initializer_list<XmlRpcValue> objects) {
  XmlRpcValue scene;
  scene["frame_id"] = std::string("world");
  XmlRpcValue list;
  list.setSize(static_cast<int>(objects.size()));
  int i = 0;
  for (const auto& o : objects) list[i++] = o;
  scene["objects"] = list;
  return scene;
}

/** Expects InvalidParameter whose message contains every fragment. */
void expectInvalid(const XmlRpcValue& scene, const std::string& fragment) {
  try {
    parseSceneConfig(scene);
    ADD_FAILURE() << "accepted a scene that should fail with '" << fragment << "'";
  } catch (const InvalidParameter& e) {
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
  }
}

TEST(SceneConfig, FieldsAndDefaults) {
  XmlRpcValue full = object("b", "package://clod_haptics/data/meshes/torus.obj");
  full["frame_id"] = std::string("tool");
  full["moving"] = true;
  full["xyz"] = vec(1.0, 2.0, 3.0);
  XmlRpcValue rpy;
  rpy.setSize(3);
  rpy[0] = 0;  // integers are accepted
  rpy[1] = 0;
  rpy[2] = M_PI / 2;
  full["rpy"] = rpy;
  full["scale"] = 0.5;
  full["clustering_distance"] = 0.01;
  XmlRpcValue scene = sceneOf({object("a", "/tmp/a.obj"), full});
  scene["default_distance"] = 0.004;
  const SceneConfig config = parseSceneConfig(scene);
  ASSERT_EQ(config.objects.size(), 2u);
  EXPECT_EQ(config.frameId, "world");
  const auto& a = config.objects[0];
  EXPECT_EQ(a.name, "a");
  EXPECT_EQ(a.frameId, "world");  // defaults to the scene frame
  EXPECT_FALSE(a.moving);
  EXPECT_EQ(a.scale, 1.0);
  EXPECT_EQ(a.distance, 0.004);
  EXPECT_TRUE(a.offset.isApprox(Eigen::Isometry3d::Identity()));
  const auto& b = config.objects[1];
  EXPECT_EQ(b.frameId, "tool");
  EXPECT_TRUE(b.moving);
  EXPECT_EQ(b.scale, 0.5);
  EXPECT_EQ(b.distance, 0.01);
  // Yaw 90 degrees: x goes to y; then the translation.
  EXPECT_LT((b.offset * Eigen::Vector3d(1, 0, 0) - Eigen::Vector3d(1, 3, 3)).norm(), 1e-12);
}

TEST(SceneConfig, RollPitchYawAreFixedAxes) {
  XmlRpcValue o = object("a", "m.obj");
  o["rpy"] = vec(0.3, -0.2, 1.1);
  const auto config = parseSceneConfig(sceneOf({o}));
  const Eigen::Matrix3d expected = (Eigen::AngleAxisd(1.1, Eigen::Vector3d::UnitZ()) *
                                    Eigen::AngleAxisd(-0.2, Eigen::Vector3d::UnitY()) *
                                    Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX()))
                                       .toRotationMatrix();
  EXPECT_TRUE(config.objects[0].offset.linear().isApprox(expected, 1e-12));
}

TEST(SceneConfig, BadScenesGiveClearErrors) {
  expectInvalid(XmlRpcValue(std::string("scene.yaml")), "must be a map");
  XmlRpcValue noObjects;
  noObjects["frame_id"] = std::string("world");
  expectInvalid(noObjects, "no 'objects'");
  XmlRpcValue empty = sceneOf({});
  expectInvalid(empty, "non-empty list");
  XmlRpcValue noName;
  noName["mesh"] = std::string("m.obj");
  expectInvalid(sceneOf({noName}), "has no 'name'");
  XmlRpcValue noMesh;
  noMesh["name"] = std::string("lonely");
  expectInvalid(sceneOf({noMesh}), "'lonely') has no 'mesh'");
  expectInvalid(sceneOf({object("a", "m.obj"), object("a", "n.obj")}), "duplicate name");
  XmlRpcValue badScale = object("s", "m.obj");
  badScale["scale"] = -1.0;
  expectInvalid(sceneOf({badScale}), "scale must be positive");
  XmlRpcValue textScale = object("s", "m.obj");
  textScale["scale"] = std::string("big");
  expectInvalid(sceneOf({textScale}), "scale must be a number");
  XmlRpcValue badDistance = object("d", "m.obj");
  badDistance["clustering_distance"] = -0.1;
  expectInvalid(sceneOf({badDistance}), "clustering_distance must not be negative");
  XmlRpcValue nanXyz = object("x", "m.obj");
  nanXyz["xyz"] = vec(0.0, NAN, 0.0);
  expectInvalid(sceneOf({nanXyz}), "xyz[1] must be finite");
  XmlRpcValue shortXyz = object("x", "m.obj");
  XmlRpcValue two;
  two.setSize(2);
  two[0] = 1.0;
  two[1] = 2.0;
  shortXyz["xyz"] = two;
  expectInvalid(sceneOf({shortXyz}), "list of 3 numbers");
  XmlRpcValue movingWorld = object("m", "m.obj");
  movingWorld["moving"] = true;
  expectInvalid(sceneOf({movingWorld}), "own frame_id");
  XmlRpcValue movingText = object("m", "m.obj");
  movingText["moving"] = std::string("yes");
  expectInvalid(sceneOf({movingText}), "true or false");
}

}  // namespace
