// proxy_ticks: the cost of the shipped proxy's ticks on one mesh, for comparing two builds (python3 bench/ab.py).
//
//   proxy_ticks MESH [--runs N] [--bag BAG] [--only-trajectory] [--size MM] [--mu-static MS] [--mu-dynamic MD]
//
// MESH: a mesh file, scaled to 15 cm (or to MM millimetres: the section also runs them at 40), or ellipsoid-edge-E, the
// section's ellipsoid with edges of E r (0.1 and 0.25 there): the bench's proxy section's models (proxy_bench.h), its
// stylus (r = 2 mm, 400 N/m, 1 kHz) and its paths: N pushes (default 40, as the section's cost table) at 0.5 and 2 m/s,
// and the recorded Geomagic trajectory placed over the model from where the stylus is first clear of it (when BAG is
// given). --mu-static and --mu-dynamic set the stylus's friction (default 0, as shipped; MD defaults to MS, and is
// clamped to it). Each path is run twice from a reset renderer: `1st` finds its region out of the caches, `rep` runs it
// again. Prints one line per path set and pass: name, pass, ticks, mean, p50, p90, p99, max (ns), and the top 1% of
// ticks' sweeps and triangles tested; then a hash of every tick's proxy position (the bits of its coordinates), so that
// two builds that claim the same answers can show it. No result files: the numbers drift with this machine's load, so
// compare builds by alternating them (python3 bench/ab.py).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "bench_common.h"
#include "clod_haptics/core/haptic_renderer.h"
#include "proxy_bench.h"

using namespace clod_haptics;

namespace {

constexpr double kDt = 1e-3;

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
    std::fprintf(stderr,
                 "usage: proxy_ticks MESH [--runs N] [--bag BAG] [--only-trajectory] [--size MM] [--mu-static MS] "
                 "[--mu-dynamic MD]\n");
    return 2;
  }
  int runs = 40;
  std::string bag;
  bool onlyTrajectory = false;
  double sizeMm = 150.0, muStatic = 0.0, muDynamic = -1.0;
  for (int i = 2; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--runs") && i + 1 < argc) {
      char* end = nullptr;
      const long n = std::strtol(argv[++i], &end, 10);
      if (*end != '\0' || n < 1 || n > 100000) {
        std::fprintf(stderr, "proxy_ticks: --runs takes a whole number from 1 to 100000, got '%s'\n", argv[i]);
        return 2;
      }
      runs = static_cast<int>(n);
    } else if (!std::strcmp(argv[i], "--bag") && i + 1 < argc) {
      bag = argv[++i];
    } else if (!std::strcmp(argv[i], "--size") && i + 1 < argc) {
      char* end = nullptr;
      sizeMm = std::strtod(argv[++i], &end);
      if (*end != '\0' || !(sizeMm > 0.0) || !std::isfinite(sizeMm)) {
        std::fprintf(stderr, "proxy_ticks: --size takes a positive number of millimetres, got '%s'\n", argv[i]);
        return 2;
      }
    } else if ((!std::strcmp(argv[i], "--mu-static") || !std::strcmp(argv[i], "--mu-dynamic")) && i + 1 < argc) {
      const bool isStatic = !std::strcmp(argv[i], "--mu-static");
      char* end = nullptr;
      const double mu = std::strtod(argv[++i], &end);
      if (*end != '\0' || !(mu >= 0.0) || !std::isfinite(mu)) {
        std::fprintf(stderr, "proxy_ticks: %s takes a friction coefficient of 0 or more, got '%s'\n", argv[i - 1],
                     argv[i]);
        return 2;
      }
      (isStatic ? muStatic : muDynamic) = mu;
    } else if (!std::strcmp(argv[i], "--only-trajectory")) {
      onlyTrajectory = true;
    } else {
      std::fprintf(stderr, "proxy_ticks: unknown or incomplete argument '%s'\n", argv[i]);
      return 2;
    }
  }
  clod_bench::Clock::calibrate();
  const std::string source = argv[1];
  const std::string fine = "ellipsoid-edge-";
  std::unique_ptr<clod_bench::Model> model;
  try {
    if (source.rfind(fine, 0) == 0) {
      char* end = nullptr;
      const double edge = std::strtod(source.c_str() + fine.size(), &end);
      if (*end != '\0' || !(edge > 0.0) || !std::isfinite(edge))
        throw std::invalid_argument("the edge (in r) must be a positive number, as in ellipsoid-edge-0.1");
      model = clod_bench::fineEllipsoid(edge);
    } else {
      model = clod_bench::sharedModel(source, sizeMm * 1e-3);
    }
  } catch (const std::exception& e) {  // a missing or broken mesh, an edge the ellipsoid cannot take
    std::fprintf(stderr, "proxy_ticks: %s: %s\n", source.c_str(), e.what());
    return 1;
  }

  std::vector<std::pair<std::string, std::vector<std::vector<Vec3>>>> sets;
  if (!onlyTrajectory)
    for (double speed : {0.5, 2.0})  // the section's cost table draws its pushes with seed 11
      sets.push_back({speed == 0.5 ? "push0.5" : "push2", clod_bench::pushes(*model, speed, runs, 11)});
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
    sets.push_back({"traj", {clod_bench::fromFreeSpace(*model, clod_bench::placeOver(recorded, *model->mesh))}});
  }

  ProxyParameters stylus = clod_bench::stylus();
  stylus.muStatic = muStatic;
  stylus.muDynamic = muDynamic < 0.0 ? muStatic : muDynamic;
  HapticRenderer renderer(stylus);
  ProxyTick tick;
  Vec3 sink = Vec3::Zero();
  std::uint64_t hash = 1469598103934665603ull;  // FNV-1a over the proxy's coordinates, tick after tick
  auto mix = [&hash](const Vec3& p) {
    for (int k = 0; k < 3; ++k) {
      std::uint64_t bits;
      std::memcpy(&bits, &p[k], sizeof bits);
      for (int b = 0; b < 8; ++b) hash = (hash ^ ((bits >> (8 * b)) & 0xffu)) * 1099511628211ull;
    }
  };
  for (const auto& [name, paths] : sets) {
    std::vector<float> t[2];
    std::vector<std::uint32_t> sweeps[2], tested[2];
    for (const auto& path : paths) {
      if (path.empty()) continue;
      for (int pass = 0; pass < 2; ++pass) {
        renderer.reset(path.front());
        for (const Vec3& device : path) {
          t[pass].push_back(clod_bench::fencedNs([&] { renderer.update(model->scene, device, kDt, tick); }));
          sweeps[pass].push_back(tick.sweeps);
          tested[pass].push_back(tick.trianglesTested);
          sink += tick.force;
          mix(tick.proxy);
        }
      }
    }
    report(name.c_str(), "1st", t[0], sweeps[0], tested[0]);
    report(name.c_str(), "rep", t[1], sweeps[1], tested[1]);
  }
  std::printf("proxy positions hash %016llx\n", static_cast<unsigned long long>(hash));
  return sink.allFinite() ? 0 : 1;
}
