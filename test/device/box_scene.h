#pragma once
// The scene the servo-rendering tests press into: a closed box 10 cm wide and 2 cm tall whose top face is z = 0
// (outward windings), with a grid detector for the shipped pointer radius.

#include <memory>
#include <vector>

#include "clod_haptics/core/detector.h"
#include "clod_haptics/core/sphere_set.h"
#include "clod_haptics/core/swept_scene.h"

namespace clod_haptics_test {

using namespace clod_haptics;

constexpr double kRadius = 0.002;  // the shipped launch file's pointer

inline std::shared_ptr<const SweptScene> boxScene() {
  const Vec3 lo(-0.05, -0.05, -0.02), hi(0.05, 0.05, 0.0);
  std::vector<Vec3> v;
  for (int i = 0; i < 8; ++i) v.emplace_back(i & 1 ? hi.x() : lo.x(), i & 2 ? hi.y() : lo.y(), i & 4 ? hi.z() : lo.z());
  const std::vector<Triangle> t = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                                   {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  auto mesh = std::make_shared<const TriangleMesh>(makeMesh(v, t, "box"));
  auto set = std::make_shared<const ClodSphereSet>(ClodBuilder(mesh).build(0.01));
  auto level = std::make_shared<const ClodDetector>(mesh, set, FastLevel::Grid, kRadius);
  auto scene = std::make_shared<SweptScene>();
  scene->add(std::make_shared<const SweptSphereQuery>(mesh, level), Eigen::Isometry3d::Identity());
  return scene;
}

}  // namespace clod_haptics_test
