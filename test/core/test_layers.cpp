// The include structure: no include cycle anywhere in include/ and src/, the core never includes the ROS or device
// layers, and inside the core no header or source includes one of a higher layer (the table below). A new core
// header must be given a layer here, so its place is a decision, not an accident.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <regex>
#include <set>
#include <string>
#include <vector>

#include "clod_haptics/test_config.h"

namespace {

namespace fs = std::filesystem;

const fs::path kRoot = fs::path(CLOD_PACKAGE_DATA_DIR).parent_path();

// Lower layers first; a core file may include files of its own layer or below, never above.
const std::map<std::string, int> kCoreLayer = {
    {"errors", 0},           {"user_path", 0},
    {"atomic_file", 0},      {"latency_histogram", 0},
    {"parallel", 0},         {"float_rounding", 0},
    {"checksum", 0},         {"vector_bytes", 0},
    {"enum_names", 0},       {"mesh", 1},
    {"geometry", 1},         {"mesh_loader", 1},
    {"morton", 1},           {"probes", 1},
    {"contact", 2},          {"brute_force", 2},
    {"sphere_placement", 3}, {"clustering", 3},
    {"tight_clustering", 3}, {"sphere_set", 4},
    {"sphere_set_io", 4},    {"box_tree", 2},
    {"triangle_bvh", 2},     {"mesh_box_tree", 2},
    {"cell_grid", 5},        {"sphere_trees", 5},
    {"detector", 6},         {"scene", 7},
    {"sphere_cache", 7},     {"grid_cache", 7},
    {"binary_io", 7},        {"mesh_cache", 7},
    {"scene_assets", 8},     {"polygon_soup", 1},
    {"text_scanner", 1},     {"read_off", 1},
    {"read_obj", 1},         {"read_ply", 1},
    {"read_stl", 1},         {"swept_query", 7},
    {"swept_scene", 8},      {"haptic_renderer", 9},
    {"triangle_pieces", 1},  {"bound_tree", 1},
    {"grid_entry_codes", 0}, {"eigen_abi", 0},
    {"wide_box_tree", 2},
};

/** Every header and source of the package, by path relative to the root, with the files it includes. */
std::map<std::string, std::vector<std::string>> includeGraph() {
  std::map<std::string, std::vector<std::string>> graph;
  const std::regex include("^\\s*#\\s*include\\s+\"([^\"]+)\"");
  for (const char* top : {"include", "src"}) {
    for (const auto& entry : fs::recursive_directory_iterator(kRoot / top)) {
      const std::string ext = entry.path().extension().string();
      if (ext != ".h" && ext != ".cpp") continue;
      const std::string file = fs::relative(entry.path(), kRoot).string();
      auto& edges = graph[file];
      std::ifstream in(entry.path());
      std::string line;
      std::smatch m;
      while (std::getline(in, line)) {
        if (!std::regex_search(line, m, include)) continue;
        const std::string name = m[1];
        // "clod_haptics/..." from include/, anything else next to the including file.
        const fs::path target =
            name.rfind("clod_haptics/", 0) == 0 ? fs::path("include") / name : fs::path(file).parent_path() / name;
        edges.push_back(target.lexically_normal().string());
      }
    }
  }
  return graph;
}

std::string stem(const std::string& path) { return fs::path(path).stem().string(); }
bool inCore(const std::string& path) {
  return path.rfind("include/clod_haptics/core/", 0) == 0 || path.rfind("src/core/", 0) == 0;
}

TEST(Layers, TheIncludeGraphHasNoCycle) {
  const auto graph = includeGraph();
  ASSERT_GT(graph.size(), 50u) << "read the sources from " << kRoot;
  std::map<std::string, int> state;  // 0 new, 1 on the current path, 2 done
  std::vector<std::string> path;
  std::function<void(const std::string&)> visit = [&](const std::string& file) {
    state[file] = 1;
    path.push_back(file);
    auto it = graph.find(file);
    if (it != graph.end()) {
      for (const std::string& next : it->second) {
        if (state[next] == 1) {
          std::string cycle;
          for (auto p = std::find(path.begin(), path.end(), next); p != path.end(); ++p) cycle += *p + " -> ";
          ADD_FAILURE() << "include cycle: " << cycle << next;
        } else if (state[next] == 0) {
          visit(next);
        }
      }
    }
    path.pop_back();
    state[file] = 2;
  };
  for (const auto& node : graph)
    if (state[node.first] == 0) visit(node.first);
}

TEST(Layers, TheCoreIncludesOnlyItsOwnLayerOrBelow) {
  std::size_t checked = 0;
  for (const auto& [file, includes] : includeGraph()) {
    if (!inCore(file) || file.find("/simd/") != std::string::npos) continue;
    const auto own = kCoreLayer.find(stem(file));
    ASSERT_NE(own, kCoreLayer.end()) << file << " has no layer in kCoreLayer (test/core/test_layers.cpp)";
    for (const std::string& target : includes) {
      if (target.find("/simd/") != std::string::npos) continue;  // kernels of the file that includes them
      ASSERT_TRUE(inCore(target) || target.rfind("src/core/", 0) == 0)
          << file << " includes " << target << ": the core must not see the ROS or device layers";
      const auto other = kCoreLayer.find(stem(target));
      ASSERT_NE(other, kCoreLayer.end()) << target << " has no layer in kCoreLayer";
      EXPECT_LE(other->second, own->second)
          << file << " (layer " << own->second << ") includes " << target << " (layer " << other->second << ")";
      ++checked;
    }
  }
  EXPECT_GT(checked, 40u);
}

}  // namespace
