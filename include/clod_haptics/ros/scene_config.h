#pragma once

#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <xmlrpcpp/XmlRpcValue.h>

namespace clod_haptics {

/** \brief One object of a scene file (config/scene_*.yaml), as read from the parameter server. */
struct SceneObjectConfig {
  std::string name;           ///< unique within the scene
  std::string mesh;           ///< a path or a package:// URI, as given
  std::string frameId;        ///< tf2 frame the object is attached to (default: the scene frame)
  bool moving = false;        ///< true: the frame moves, looked up with tf2 for every pose
  Eigen::Isometry3d offset = Eigen::Isometry3d::Identity();  ///< pose of the mesh in frameId (xyz, rpy)
  double scale = 1.0;         ///< mesh file units to metres
  double distance = 0.003;    ///< clustering distance of the object's level (m)
  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

/** \brief A whole scene: its frame and its objects. */
struct SceneConfig {
  std::string frameId = "world";  ///< the frame contacts and the combined force are expressed in
  std::vector<SceneObjectConfig, Eigen::aligned_allocator<SceneObjectConfig>> objects;
};

/**
 * \brief Reads a scene from a parameter-server struct (what `<rosparam file="scene.yaml"/>` loads):
 * `frame_id` (default "world"), `default_distance` (default defaultDistance) and `objects`, a list
 * of structs with `name` and `mesh` (required), `frame_id`, `moving`, `xyz`, `rpy`, `scale` and
 * `clustering_distance` (optional). Integers are accepted where a double is expected.
 * \throws InvalidParameter naming the object and the field for anything missing, mistyped, not
 * finite, out of range (scale <= 0, distance < 0) or a duplicate name.
 */
SceneConfig parseSceneConfig(const XmlRpc::XmlRpcValue& scene, double defaultDistance = 0.003);

}  // namespace clod_haptics
