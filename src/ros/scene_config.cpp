#include "clod_haptics/ros/scene_config.h"

#include <cmath>
#include <set>

#include "clod_haptics/core/errors.h"

namespace clod_haptics {

namespace {

using XmlRpc::XmlRpcValue;

std::string where(std::size_t index, const std::string& name) {
  return "scene object " + std::to_string(index) + (name.empty() ? "" : " ('" + name + "')");
}

bool has(const XmlRpcValue& s, const char* key) {
  return s.getType() == XmlRpcValue::TypeStruct && const_cast<XmlRpcValue&>(s).hasMember(key);
}

const XmlRpcValue& member(const XmlRpcValue& s, const char* key) { return const_cast<XmlRpcValue&>(s)[key]; }

double toDouble(const XmlRpcValue& v, const std::string& what) {
  double d;
  if (v.getType() == XmlRpcValue::TypeDouble) {
    d = static_cast<double>(const_cast<XmlRpcValue&>(v));
  } else if (v.getType() == XmlRpcValue::TypeInt) {
    d = static_cast<int>(const_cast<XmlRpcValue&>(v));
  } else {
    throw InvalidParameter(what + " must be a number");
  }
  if (!std::isfinite(d)) throw InvalidParameter(what + " must be finite");
  return d;
}

std::string toString(const XmlRpcValue& v, const std::string& what) {
  if (v.getType() != XmlRpcValue::TypeString) throw InvalidParameter(what + " must be a string");
  return static_cast<std::string>(const_cast<XmlRpcValue&>(v));
}

Eigen::Vector3d toVector3(const XmlRpcValue& v, const std::string& what) {
  if (v.getType() != XmlRpcValue::TypeArray || v.size() != 3) throw InvalidParameter(what + " must be a list of 3 numbers");
  return Eigen::Vector3d(toDouble(v[0], what + "[0]"), toDouble(v[1], what + "[1]"), toDouble(v[2], what + "[2]"));
}

}  // namespace

SceneConfig parseSceneConfig(const XmlRpc::XmlRpcValue& scene, double defaultDistance) {
  if (scene.getType() != XmlRpcValue::TypeStruct) {
    throw InvalidParameter("the scene must be a map with 'frame_id' and 'objects' (a config/scene_*.yaml file)");
  }
  SceneConfig config;
  if (has(scene, "frame_id")) config.frameId = toString(member(scene, "frame_id"), "scene frame_id");
  if (config.frameId.empty()) throw InvalidParameter("scene frame_id must not be empty");
  if (has(scene, "default_distance")) defaultDistance = toDouble(member(scene, "default_distance"), "default_distance");
  if (defaultDistance < 0.0) throw InvalidParameter("default_distance must not be negative");
  if (!has(scene, "objects")) throw InvalidParameter("the scene has no 'objects' list");
  const XmlRpcValue& objects = member(scene, "objects");
  if (objects.getType() != XmlRpcValue::TypeArray || objects.size() == 0) {
    throw InvalidParameter("scene 'objects' must be a non-empty list");
  }
  std::set<std::string> names;
  for (int i = 0; i < objects.size(); ++i) {
    const XmlRpcValue& o = objects[i];
    const std::size_t index = static_cast<std::size_t>(i);
    if (o.getType() != XmlRpcValue::TypeStruct) throw InvalidParameter(where(index, "") + " must be a map");
    SceneObjectConfig object;
    if (!has(o, "name")) throw InvalidParameter(where(index, "") + " has no 'name'");
    object.name = toString(member(o, "name"), where(index, "") + " name");
    if (object.name.empty()) throw InvalidParameter(where(index, "") + " has an empty name");
    if (!names.insert(object.name).second) throw InvalidParameter(where(index, object.name) + ": duplicate name");
    const std::string at = where(index, object.name);
    if (!has(o, "mesh")) throw InvalidParameter(at + " has no 'mesh' (a path or a package:// URI)");
    object.mesh = toString(member(o, "mesh"), at + " mesh");
    if (object.mesh.empty()) throw InvalidParameter(at + " has an empty mesh");
    object.frameId = has(o, "frame_id") ? toString(member(o, "frame_id"), at + " frame_id") : config.frameId;
    if (object.frameId.empty()) throw InvalidParameter(at + " has an empty frame_id");
    if (has(o, "moving")) {
      if (member(o, "moving").getType() != XmlRpcValue::TypeBoolean) throw InvalidParameter(at + " moving must be true or false");
      object.moving = static_cast<bool>(const_cast<XmlRpcValue&>(member(o, "moving")));
    }
    if (object.moving && object.frameId == config.frameId) {
      throw InvalidParameter(at + " is moving but attached to the scene frame itself; give it its own frame_id");
    }
    const Eigen::Vector3d xyz = has(o, "xyz") ? toVector3(member(o, "xyz"), at + " xyz") : Eigen::Vector3d::Zero();
    const Eigen::Vector3d rpy = has(o, "rpy") ? toVector3(member(o, "rpy"), at + " rpy") : Eigen::Vector3d::Zero();
    object.offset = Eigen::Isometry3d::Identity();
    object.offset.translate(xyz);
    // Fixed axes roll, pitch, yaw (REP 103): R = Rz(yaw) Ry(pitch) Rx(roll).
    object.offset.rotate(Eigen::AngleAxisd(rpy.z(), Eigen::Vector3d::UnitZ()) *
                         Eigen::AngleAxisd(rpy.y(), Eigen::Vector3d::UnitY()) *
                         Eigen::AngleAxisd(rpy.x(), Eigen::Vector3d::UnitX()));
    if (has(o, "scale")) object.scale = toDouble(member(o, "scale"), at + " scale");
    if (!(object.scale > 0.0)) throw InvalidParameter(at + " scale must be positive");
    object.distance = has(o, "clustering_distance") ? toDouble(member(o, "clustering_distance"), at + " clustering_distance")
                                                    : defaultDistance;
    if (object.distance < 0.0) throw InvalidParameter(at + " clustering_distance must not be negative");
    config.objects.push_back(object);
  }
  return config;
}

}  // namespace clod_haptics
