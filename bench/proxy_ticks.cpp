// proxy_ticks: the cost of the shipped proxy's ticks on one mesh, for comparing two builds (python3 bench/ab.py).
//
//   proxy_ticks MESH [--runs N] [--bag BAG] [--only-trajectory]
//
// MESH: a mesh file, scaled to 15 cm as the bench's proxy section does, or ellipsoid-edge-E, the section's ellipsoid
// of 15 x 12 x 9 mm with edges of E r (0.1 and 0.25 there); r = 2 mm, 400 N/m, 1 kHz. Paths: N pushes (default
// 40) 30 mm long along the inward normal of random surface points at 0.5 and 2 m/s, and the recorded Geomagic
// trajectory placed over the model from where the stylus is first clear of it (when BAG is given). Each path is run
// twice from a reset renderer: `1st` finds its region out of the caches, `rep` runs it again. Prints one line per path
// set and pass: name, pass, ticks, mean, p50, p90, p99, max (ns), and the top 1% of ticks' sweeps and triangles tested.
// No result files: the numbers drift with this machine's load, so compare builds by alternating them (python3
// bench/ab.py).
#include <algorithm>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "bench_common.h"
#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/detector.h"
#include "clod_haptics/core/haptic_renderer.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/probes.h"
#include "clod_haptics/core/sphere_set.h"
#include "clod_haptics/core/swept_scene.h"

using namespace clod_haptics;

namespace {

constexpr double kR = 0.002, kDt = 1e-3, kSize = 0.15;

std::vector<Vec3> line(const Vec3& a, const Vec3& b, double speed) {
  const int n = std::max(1, static_cast<int>(std::ceil((b - a).norm() / (speed * kDt))));
  std::vector<Vec3> out;
  for (int i = 0; i <= n; ++i) out.push_back(a + (b - a) * (static_cast<double>(i) / n));
  return out;
}

// The bench's pushes (proxy_bench.cpp): from 15 mm outside a surface point to 15 mm inside, skipping starts that touch.
std::vector<std::vector<Vec3>> pushes(const TriangleMesh& mesh, double speed, int runs) {
  const std::vector<Vec3> surface = nearSurfaceProbes(mesh, 20 * static_cast<std::size_t>(runs), 0.0, 11);
  std::vector<std::vector<Vec3>> out;
  for (std::size_t i = 0; out.size() < static_cast<std::size_t>(runs) && i < surface.size(); ++i) {
    const ContactResult c = bruteForceQuery(mesh, surface[i], 1.0);
    const Vec3 centre = c.point, dir = -c.normal;
    if (bruteForceSignedQuery(mesh, centre - 0.015 * dir, kR).contact) continue;
    out.push_back(line(centre - 0.015 * dir, centre + 0.015 * dir, speed));
  }
  return out;
}

void report(const char* name, const char* pass, std::vector<float> t, const std::vector<std::uint32_t>& sweeps,
            const std::vector<std::uint32_t>& tested) {
  if (t.empty()) return;
  std::vector<std::size_t> order(t.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return t[a] < t[b]; });
  auto at = [&](double q) { return t[order[std::min(order.size() - 1, static_cast<std::size_t>(q * order.size()))]]; };
  double mean = 0.0;
  for (float x : t) mean += x;
  mean /= static_cast<double>(t.size());
  const std::size_t top = static_cast<std::size_t>(0.99 * static_cast<double>(order.size()));
  double s = 0.0, k = 0.0;
  for (std::size_t i = top; i < order.size(); ++i) {
    s += sweeps[order[i]];
    k += tested[order[i]];
  }
  const double n = static_cast<double>(order.size() - top);
  std::printf("%-8s %s n=%zu mean %.0f p50 %.0f p90 %.0f p99 %.0f max %.0f ns | top 1%%: sweeps %.2f tested %.0f\n",
              name, pass, t.size(), mean, at(0.5), at(0.9), at(0.99), at(1.0), s / n, k / n);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: proxy_ticks MESH [--runs N] [--bag BAG] [--only-trajectory]\n");
    return 2;
  }
  int runs = 40;
  std::string bag;
  bool onlyTrajectory = false;
  for (int i = 2; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--runs") && i + 1 < argc)
      runs = std::atoi(argv[++i]);
    else if (!std::strcmp(argv[i], "--bag") && i + 1 < argc)
      bag = argv[++i];
    else if (!std::strcmp(argv[i], "--only-trajectory"))
      onlyTrajectory = true;
  }
  clod_bench::Clock::calibrate();
  std::shared_ptr<const TriangleMesh> mesh;
  const std::string source = argv[1];
  if (source.rfind("ellipsoid-edge-", 0) == 0) {  // the proxy section's fine ellipsoids: ellipsoid-edge-0.1 (in r)
    const double edge = std::atof(source.c_str() + std::strlen("ellipsoid-edge-"));
    mesh = std::make_shared<const TriangleMesh>(
        clod_bench::ellipsoidWithEdge(Vec3(0.015, 0.012, 0.009), Vec3::Zero(), edge * kR, source));
  } else {
    MeshLoadOptions options;
    options.normalize = true;
    const TriangleMesh unit = loadMesh(source, options);
    std::vector<Vec3> v;
    for (const Vec3& x : unit.vertices) v.push_back(unit.toModel(x) * kSize);
    mesh = std::make_shared<const TriangleMesh>(makeMesh(std::move(v), unit.triangles, unit.name));
  }
  auto set = std::make_shared<const ClodSphereSet>(ClodBuilder(mesh).build(0.003));  // the launch file's d
  auto detector = std::make_shared<const ClodDetector>(mesh, set, FastLevel::Grid, kR);
  SweptScene scene;
  scene.add(std::make_shared<const SweptSphereQuery>(mesh, detector), Eigen::Isometry3d::Identity());

  std::vector<std::pair<std::string, std::vector<std::vector<Vec3>>>> sets;
  if (!onlyTrajectory)
    for (double speed : {0.5, 2.0}) sets.push_back({speed == 0.5 ? "push0.5" : "push2", pushes(*mesh, speed, runs)});
  if (!bag.empty()) {
    std::string error;
    double seconds = 0.0;
    std::size_t messages = 0;
    const std::vector<Vec3> recorded =
        clod_bench::readTrajectory(bag, "/Geomagic/end_effector_pose", 1000.0, error, seconds, messages);
    if (recorded.empty()) {
      std::fprintf(stderr, "proxy_ticks: %s\n", error.c_str());
      return 1;
    }
    const std::vector<Vec3> placed = clod_bench::placeOver(recorded, *mesh);
    std::size_t first = 0;
    while (first < placed.size() && bruteForceSignedQuery(*mesh, placed[first], kR).contact) ++first;
    sets.push_back({"traj", {std::vector<Vec3>(placed.begin() + static_cast<std::ptrdiff_t>(first), placed.end())}});
  }

  ProxyParameters params;
  params.radius = kR;
  params.stiffness = 400.0;
  HapticRenderer renderer(params);
  ProxyTick tick;
  Vec3 sink = Vec3::Zero();
  for (const auto& [name, paths] : sets) {
    std::vector<float> t[2];
    std::vector<std::uint32_t> sweeps[2], tested[2];
    for (const auto& path : paths) {
      if (path.empty()) continue;
      for (int pass = 0; pass < 2; ++pass) {
        renderer.reset(path.front());
        for (const Vec3& device : path) {
          t[pass].push_back(clod_bench::fencedNs([&] { renderer.update(scene, device, kDt, tick); }));
          sweeps[pass].push_back(tick.sweeps);
          tested[pass].push_back(tick.trianglesTested);
          sink += tick.force;
        }
      }
    }
    report(name.c_str(), "1st", t[0], sweeps[0], tested[0]);
    report(name.c_str(), "rep", t[1], sweeps[1], tested[1]);
  }
  return sink.allFinite() ? 0 : 1;
}
