// The detector's defaults are kept once in the code (DetectorParameters, cfg/Detector.cfg) and documented in
// config/detector.yaml, which the launch files load: the three must agree, or a node started without the YAML
// behaves differently from the launched one.
#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include "clod_haptics/ros/haptic_detector.h"
#include "clod_haptics/test_config.h"

namespace clod_haptics {
namespace {

/** The top-level `key: value` lines of a flat YAML file, comments and quotes stripped. */
std::map<std::string, std::string> readFlatYaml(const std::string& path) {
  std::map<std::string, std::string> out;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#' || line[0] == ' ') continue;
    const auto colon = line.find(':');
    if (colon == std::string::npos) continue;
    std::string value = line.substr(colon + 1);
    value = value.substr(0, value.find('#'));
    const auto first = value.find_first_not_of(' '), last = value.find_last_not_of(' ');
    value = first == std::string::npos ? "" : value.substr(first, last - first + 1);
    if (value.size() >= 2 && value.front() == '"' && value.back() == '"') value = value.substr(1, value.size() - 2);
    out[line.substr(0, colon)] = value;
  }
  return out;
}

std::string str(bool b) { return b ? "true" : "false"; }
double num(const std::map<std::string, std::string>& yaml, const std::string& key) { return std::stod(yaml.at(key)); }

TEST(HapticDetectorDefaults, ConfigDetectorYamlStatesTheCodesDefaults) {
  const auto yaml = readFlatYaml(std::string(CLOD_PACKAGE_DATA_DIR) + "/../config/detector.yaml");
  ASSERT_GT(yaml.size(), 30u);
  const DetectorParameters p;
  EXPECT_EQ(yaml.at("frame_id"), p.frameId);
  EXPECT_EQ(num(yaml, "scale"), p.scale);
  EXPECT_EQ(yaml.at("normalize"), str(p.normalize));
  EXPECT_EQ(yaml.at("pose_topic"), p.poseTopic);
  EXPECT_EQ(yaml.at("use_cache"), str(p.useCache));
  EXPECT_EQ(yaml.at("cache_dir"), p.cacheDir);
  EXPECT_EQ(yaml.at("cache_meshes"), str(p.cacheMeshes));
  EXPECT_EQ(yaml.at("sphere_service"), p.sphereService);
  EXPECT_EQ(yaml.at("use_service"), str(p.useService));
  EXPECT_EQ(num(yaml, "service_timeout"), p.serviceTimeout);
  EXPECT_EQ(yaml.at("clustering"), p.clustering);
  EXPECT_EQ(yaml.at("fast_level"), "grid");
  EXPECT_EQ(p.fastLevel, FastLevel::Grid);
  EXPECT_EQ(num(yaml, "grid_radius"), p.gridRadius);
  EXPECT_EQ(yaml.at("quick_start"), str(p.quickStart));
  EXPECT_EQ(yaml.at("grid_on_demand"), str(p.gridOnDemand));
  EXPECT_EQ(yaml.at("detectors_on_demand"), str(p.detectorsOnDemand));
  EXPECT_EQ(num(yaml, "prefetch_margin"), p.prefetchMargin);
  EXPECT_EQ(num(yaml, "static_retry"), p.staticRetry);
  EXPECT_EQ(yaml.at("pose_policy"), p.posePolicy == PosePolicy::All ? "all" : "latest");
  EXPECT_EQ(num(yaml, "pose_queue_size"), p.poseQueueSize);
  EXPECT_EQ(num(yaml, "publish_queue_size"), p.publishQueueSize);
  EXPECT_EQ(num(yaml, "realtime_priority"), p.realtimePriority);
  EXPECT_EQ(num(yaml, "marker_rate"), p.markerRate);

  const DetectorConfig cfg = DetectorConfig::__getDefault__();
  EXPECT_EQ(num(yaml, "clustering_distance"), cfg.clustering_distance);
  EXPECT_EQ(num(yaml, "pointer_radius"), cfg.pointer_radius);
  EXPECT_EQ(yaml.at("detection_mode"), cfg.detection_mode);
  EXPECT_EQ(num(yaml, "stiffness"), cfg.stiffness);
  EXPECT_EQ(num(yaml, "max_force"), cfg.max_force);
  EXPECT_EQ(yaml.at("force_model"), cfg.force_model);
  EXPECT_EQ(cfg.force_model, "proxy");  // the shipped default
  EXPECT_EQ(num(yaml, "damping"), cfg.damping);
  EXPECT_EQ(num(yaml, "mu_static"), cfg.mu_static);
  EXPECT_EQ(num(yaml, "mu_dynamic"), cfg.mu_dynamic);
  EXPECT_EQ(yaml.at("force_shading"), str(cfg.force_shading));
  EXPECT_EQ(yaml.at("show_mesh"), str(cfg.show_mesh));
  EXPECT_EQ(yaml.at("show_spheres"), str(cfg.show_spheres));
  EXPECT_EQ(yaml.at("show_hit_spheres"), str(cfg.show_hit_spheres));
  EXPECT_EQ(yaml.at("show_contact"), str(cfg.show_contact));
  EXPECT_EQ(yaml.at("show_pointer"), str(cfg.show_pointer));
}

}  // namespace
}  // namespace clod_haptics

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
