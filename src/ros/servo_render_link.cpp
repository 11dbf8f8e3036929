#include "clod_haptics/ros/servo_render_link.h"

#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include <chrono>
#include <cstdio>
#include <stdexcept>

#include "clod_haptics/core/detector.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/sphere_set.h"
#include "clod_haptics/ros/conversions.h"
#include "clod_haptics/ros/mesh_resource.h"

namespace clod_haptics {
namespace device {

namespace {

// The grid's clustering distance: any level gives the same sweep (the grid lists triangles); a coarse one is quick.
constexpr double kGridDistance = 0.02;

std::shared_ptr<const SweptScene> loadScene(const ros::NodeHandle& detector, double radius, std::string& what) {
  std::string mesh, scene;
  if (detector.getParam("scene", scene) && !scene.empty())
    throw std::runtime_error("the detector runs a scene file (" + scene + "); servo rendering takes one static mesh");
  if (!detector.getParam("mesh", mesh) || mesh.empty())
    throw std::runtime_error("no parameter " + detector.resolveName("mesh") + " (is the detector running?)");
  MeshLoadOptions options;
  detector.param("scale", options.scale, options.scale);
  detector.param("normalize", options.normalize, options.normalize);
  const auto start = std::chrono::steady_clock::now();
  auto loaded = std::make_shared<const TriangleMesh>(loadMesh(resolveMeshPath(mesh), options));
  auto set = std::make_shared<const ClodSphereSet>(ClodBuilder(loaded).build(kGridDistance * loaded->diagonal()));
  auto level = std::make_shared<const ClodDetector>(loaded, set, FastLevel::Grid, radius);
  auto built = std::make_shared<SweptScene>();
  built->add(std::make_shared<const SweptSphereQuery>(loaded, level), Eigen::Isometry3d::Identity());
  char line[256];
  std::snprintf(line, sizeof line, "%s (%zu triangles, grid for r = %g m) in %.0f ms", mesh.c_str(), loaded->size(),
                radius, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
  what = line;
  return built;
}

Eigen::Isometry3d sceneFromDevice(const std::string& sceneFrame, const std::string& deviceFrame) {
  if (sceneFrame == deviceFrame || deviceFrame.empty()) return Eigen::Isometry3d::Identity();
  tf2_ros::Buffer buffer;
  tf2_ros::TransformListener listener(buffer);
  try {
    return toIsometry(buffer.lookupTransform(sceneFrame, deviceFrame, ros::Time(0), ros::Duration(5.0)).transform);
  } catch (const tf2::TransformException& e) {
    throw std::runtime_error("no transform from the device's frame '" + deviceFrame + "' to the mesh's '" + sceneFrame +
                             "': " + e.what());
  }
}

}  // namespace

ServoRenderLink::ServoRenderLink(ros::NodeHandle nh, const std::string& detectorNs, const std::string& deviceFrame) {
  const ros::NodeHandle detector(nh, detectorNs);
  std::string frame = "world";
  detector.param("frame_id", frame, frame);
  // The detector's reconfigurable parameters as its server publishes them (Detector.cfg's defaults where unset).
  config_ = DetectorConfig::__getDefault__();
  config_.__fromServer__(detector);
  follow();
  std::string what;
  auto scene = loadScene(detector, settings_.proxy.radius, what);
  settings_.sceneFromDevice = sceneFromDevice(frame, deviceFrame);
  renderer_ = std::make_shared<ServoRenderer>(std::move(scene), settings_);
  description_ = what + (frame == deviceFrame ? "" : ", device frame '" + deviceFrame + "' to '" + frame + "'");
  updates_ = nh.subscribe<dynamic_reconfigure::Config>(
      detector.resolveName("parameter_updates"), 10,
      [this](const dynamic_reconfigure::Config::ConstPtr& config) { apply(*config); });
}

void ServoRenderLink::follow() {
  ProxyParameters& p = settings_.proxy;
  p.radius = config_.pointer_radius;
  p.stiffness = config_.stiffness;
  p.damping = config_.damping;
  p.maxForce = config_.max_force;
  p.muStatic = config_.mu_static;
  p.muDynamic = config_.mu_dynamic;
  p.forceShading = config_.force_shading;
  settings_.enabled = config_.force_model == "proxy";
  enabled_ = settings_.enabled;
}

void ServoRenderLink::apply(const dynamic_reconfigure::Config& config) {
  // The fields the update carries; the others keep their values.
  dynamic_reconfigure::Config copy = config;
  config_.__fromMessage__(copy);
  follow();
  renderer_->configure(settings_);
}

}  // namespace device
}  // namespace clod_haptics
