// Scene benchmark: a scene of 50 objects totalling more than a million triangles.
//  1. Start-up: every object's level built (empty disk cache) against read from the disk cache by a
//     fresh SceneAssets on the same directory (a restart). Target: the cache at least 10x faster.
//  2. Query: a pointer stream near one object, answered by the whole scene (SceneDetector) against
//     that object's detector alone in its own frame, and against a peer without the scene-level
//     bound (every object's detector queried). Target: scene / alone <= 1.5.
// Not a test: it prints figures and ratios measured in the same run.
//
//   scene_bench [--shared DIR] [--objects 50] [--elephants 10] [--heads 10] [--queries 20000] [--rounds 7]
//               [--cache DIR (default: a fresh temp dir, removed at the end)] [--targets 8]
//               [--fast grid|hierarchy] [--startup 0 (queries only)]

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <unistd.h>

#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/probes.h"
#include "clod_haptics/core/scene.h"
#include "clod_haptics/core/scene_assets.h"
#include "clod_haptics/core/sphere_cache.h"

using namespace clod_haptics;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

namespace {

double msSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

/** Keeps the compiler from dropping a result (benchmark::DoNotOptimize equivalent). */
template <class T>
inline void doNotOptimize(const T& value) {
  asm volatile("" : : "r,m"(value) : "memory");
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

struct Options {
  std::string shared = "../shared";
  std::string cache;
  int objects = 50;
  int elephants = 10;
  int heads = 10;  // cheap objects (head.off, 2.9k triangles): the scene's overhead weighs most on them
  int queries = 20000;
  int rounds = 7;
  int targets = 8;          // objects 17 t mod 50: two heads (2, 17), two elephants (0, 35), four devils
  double distance = 0.003;  // m, about 2% of an object
  double radius = 0.002;    // m
  FastLevel fast = FastLevel::Grid;
  bool startup = true;  // --startup 0: skip the start-up comparison (queries only)
};

Options parse(int argc, char** argv) {
  Options o;
  if (const char* env = std::getenv("CLOD_SHARED_DIR")) o.shared = env;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    const char* value = argv[i + 1];
    if (key == "--shared") o.shared = value;
    else if (key == "--cache") o.cache = value;
    else if (key == "--objects") o.objects = std::atoi(value);
    else if (key == "--elephants") o.elephants = std::atoi(value);
    else if (key == "--heads") o.heads = std::atoi(value);
    else if (key == "--queries") o.queries = std::atoi(value);
    else if (key == "--rounds") o.rounds = std::atoi(value);
    else if (key == "--targets") o.targets = std::atoi(value);
    else if (key == "--startup") o.startup = std::atoi(value) != 0;
    else if (key == "--fast") {
      if (!parseFastLevel(value, o.fast)) {
        std::fprintf(stderr, "--fast must be grid, hierarchy or flat\n");
        std::exit(2);
      }
    }
    else {
      std::fprintf(stderr, "unknown option %s\n", key.c_str());
      std::exit(2);
    }
  }
  return o;
}

/** A copy of a unit-cube mesh scaled to size metres: each copy has its own content (and cache key). */
std::shared_ptr<const TriangleMesh> scaledCopy(const TriangleMesh& unit, double size, const std::string& name) {
  std::vector<Vec3> vertices = unit.vertices;
  for (Vec3& v : vertices) v *= size;
  return std::make_shared<const TriangleMesh>(makeMesh(std::move(vertices), unit.triangles, name));
}

struct Scene {
  std::vector<std::shared_ptr<const TriangleMesh>> meshes;  // replaced by the meshes prepare() loads
  std::vector<std::string> files;                           // each object's mesh written as an OFF file
  std::vector<Eigen::Isometry3d, Eigen::aligned_allocator<Eigen::Isometry3d>> poses;
  std::size_t triangles = 0;
};

Scene makeScene(const Options& o) {
  const std::string dir = o.shared + "/data/meshes/";
  MeshLoadOptions unit;
  unit.normalize = true;
  const auto start = Clock::now();
  const TriangleMesh elephant = loadMesh(dir + "refined_elephant.off", unit);
  const TriangleMesh devil = loadMesh(dir + "mannequin-devil.off", unit);
  const TriangleMesh head = loadMesh(dir + "head.off", unit);
  std::printf("loaded refined_elephant.off (%zu triangles), mannequin-devil.off (%zu) and head.off (%zu) in %.0f ms\n",
              elephant.size(), devil.size(), head.size(), msSince(start));
  Scene scene;
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> size(0.14, 0.18), angle(-M_PI, M_PI);
  const int columns = 10;
  for (int i = 0; i < o.objects; ++i) {
    // Elephants and heads spread through the grid (every fifth object from 0 and from 2), devils elsewhere; every
    // copy a slightly different size.
    const int stride = std::max(1, o.objects / std::max(1, o.elephants));
    const bool isElephant = o.elephants > 0 && i % stride == 0 && i / stride < o.elephants;
    const int headStride = std::max(1, o.objects / std::max(1, o.heads));
    const bool isHead =
        !isElephant && o.heads > 0 && i % headStride == std::min(2, headStride - 1) && i / headStride < o.heads;
    const TriangleMesh& unitMesh = isElephant ? elephant : isHead ? head : devil;
    const char* kind = isElephant ? "elephant_" : isHead ? "head_" : "devil_";
    scene.meshes.push_back(scaledCopy(unitMesh, size(rng), kind + std::to_string(i)));
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.translate(Vec3(0.25 * (i % columns), 0.25 * (i / columns), 0.0));
    pose.rotate(Eigen::AngleAxisd(angle(rng), Vec3::UnitZ()));
    pose.translate(-Vec3::Constant(0.08));  // roughly centre the object on its grid point
    scene.poses.push_back(pose);
    scene.triangles += scene.meshes.back()->size();
  }
  return scene;
}

/** Writes a mesh as an OFF file (17 significant digits), the format of the shared meshes. */
void writeOff(const TriangleMesh& mesh, const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (!f) {
    std::fprintf(stderr, "cannot write %s\n", path.c_str());
    std::exit(2);
  }
  std::fprintf(f, "OFF\n%zu %zu 0\n", mesh.vertices.size(), mesh.triangles.size());
  for (const Vec3& v : mesh.vertices) std::fprintf(f, "%.17g %.17g %.17g\n", v.x(), v.y(), v.z());
  for (const Triangle& t : mesh.triangles) std::fprintf(f, "3 %u %u %u\n", t[0], t[1], t[2]);
  std::fclose(f);
}

struct Startup {
  double meshMs = 0.0;   // every object's mesh loaded (parsed, or read from the mesh cache)
  double setsMs = 0.0;   // every object's sphere set in memory (read or built): the node's start-up
  double serveMs = 0.0;  // and every object's hierarchy detector (quick start, in the background)
  double totalMs = 0.0;  // every object has its final (grid) detector, as the node with grid_on_demand=false
  double skippedQuickMs = 0.0;  // hierarchy detectors the node skips then: their grids come from the disk cache
  std::size_t gridsCached = 0;
  double cacheMs = 0.0, serveDetectorMs = 0.0, gridDetectorMs = 0.0, hashMs = 0.0;
  double firstGridMs = 0.0;  // the grid of one object (the one the pointer reaches first, grid_on_demand)
  double firstQuickMs = 0.0;  // the hierarchy detector of that object
  std::size_t hits = 0, built = 0;
  std::vector<std::shared_ptr<const ClodDetector>> levels;
  std::vector<std::shared_ptr<const TriangleMesh>> meshes;
  std::size_t meshHits = 0;
};

/**
 * What the scene node does at start-up with quick_start and grid_on_demand=false: stage 1 a hierarchy detector for
 * each object whose grid is not in the disk cache (an object whose grid is cached reads it at once), stage 2 the grid
 * ones; totalMs is that, end to end. The hierarchy detectors of the objects skipped are built afterwards (not in
 * totalMs), for the +hierarchy figure: every object answering with a hierarchy first, as with grid_on_demand=true.
 */
Startup prepare(const Scene& scene, const std::string& cacheDir, const Options& o) {
  Startup s;
  const auto start = Clock::now();
  // A fresh cache object and asset store: what a restarted node has.
  SceneAssets assets(std::make_shared<SphereSetCache>(cacheDir), o.fast, o.radius, false);
  assets.setMeshCache(std::make_shared<MeshCache>(cacheDir));
  for (const std::string& file : scene.files) {
    SceneAssets::MeshInfo info;
    s.meshes.push_back(assets.mesh(file, MeshLoadOptions{}, &info));
    s.meshHits += info.cache.source == CacheSource::Hit;
  }
  s.meshMs = msSince(start);
  for (const auto& mesh : s.meshes) {
    const auto h0 = Clock::now();
    assets.hash(mesh);
    s.hashMs += msSince(h0);
    SceneAssets::LevelInfo info;
    assets.spheres(mesh, o.distance, &info);
    s.cacheMs += info.cache.ms;
    (info.cache.source == CacheSource::Hit ? s.hits : s.built)++;
  }
  s.setsMs = msSince(start);
  std::vector<bool> cached;
  for (const auto& mesh : s.meshes) {
    cached.push_back(o.fast == FastLevel::Grid && assets.gridCached(mesh, o.distance));
    s.gridsCached += cached.back();
  }
  auto quick = [&](std::size_t i) {
    SceneAssets::LevelInfo info;
    s.levels[i] = assets.level(s.meshes[i], o.distance, FastLevel::Hierarchy, &info);
    s.serveDetectorMs += info.detectorMs;
    if (i == 0) s.firstQuickMs = info.detectorMs;
    return info.detectorMs;
  };
  s.levels.resize(s.meshes.size());
  for (std::size_t i = 0; i < s.meshes.size(); ++i)
    if (!cached[i]) quick(i);
  if (o.fast != FastLevel::Hierarchy) {
    for (std::size_t i = 0; i < scene.meshes.size(); ++i) {
      SceneAssets::LevelInfo info;
      s.levels[i] = assets.level(s.meshes[i], o.distance, o.fast, &info);
      s.gridDetectorMs += info.detectorMs;
      if (i == 0) s.firstGridMs = info.detectorMs;
    }
  }
  s.totalMs = msSince(start);
  for (std::size_t i = 0; i < s.meshes.size(); ++i)
    if (cached[i]) {
      const auto keep = s.levels[i];
      s.skippedQuickMs += quick(i);
      if (i == 0) s.firstQuickMs = 0.0;  // the object near the pointer reads its grid at once
      s.levels[i] = keep;
    }
  s.serveMs = s.setsMs + s.serveDetectorMs;
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  std::setvbuf(stdout, nullptr, _IOLBF, 0);
  const Options o = parse(argc, argv);
  const bool ownCache = o.cache.empty();
  const std::string cacheDir =
      ownCache ? (fs::temp_directory_path() / ("clod_scene_bench_" + std::to_string(::getpid()))).string() : o.cache;
  if (ownCache) fs::remove_all(cacheDir);

  Scene scene = makeScene(o);
  // Each object's mesh as a file, as a scene file would name them (not timed).
  fs::create_directories(cacheDir + "/meshes");
  for (std::size_t i = 0; i < scene.meshes.size(); ++i) {
    scene.files.push_back(cacheDir + "/meshes/" + scene.meshes[i]->name + ".off");
    writeOff(*scene.meshes[i], scene.files.back());
  }
  std::printf("scene: %zu objects, %zu triangles; d = %g m, pointer radius %g m; cache %s\n", scene.meshes.size(),
              scene.triangles, o.distance, o.radius, cacheDir.c_str());

  // ---- 1. Start-up: build (empty cache) against a restart reading the cache.
  // A restart is a fresh process: each run's detectors are freed before the next (the last restart's are kept for
  // the queries), so no run pays for the memory of the ones before it.
  auto release = [](Startup& s) {
    s.levels.clear();
    s.meshes.clear();
  };
  Startup cold = prepare(scene, cacheDir, o);
  std::vector<Startup> warms;
  for (int k = 0; k < (o.startup ? 3 : 0); ++k) {
    if (k == 0) release(cold);
    if (k > 0) release(warms.back());
    warms.push_back(prepare(scene, cacheDir, o));
  }
  const Startup last = o.startup ? warms.back() : cold;
  if (!o.startup) warms.assign(3, cold);
  std::sort(warms.begin(), warms.end(), [](const Startup& a, const Startup& b) { return a.setsMs < b.setsMs; });
  std::printf("\n[start-up] meshes: %.0f ms parsing %zu files (%zu from the mesh cache) / %.0f ms from the mesh cache "
              "(%zu hits)\n",
              cold.meshMs, scene.files.size(), cold.meshHits, warms[1].meshMs, warms[1].meshHits);
  const Startup& warm = warms[1];  // median of three restarts
  std::printf("\n[start-up] ms          %10s %10s %8s\n", "build", "cache", "ratio");
  std::printf("[start-up] levels      %10.0f %10.0f %7.1fx  (every object's mesh and sphere set in memory: the node's "
              "start-up; target >= 10x)\n",
              cold.setsMs, warm.setsMs, cold.setsMs / warm.setsMs);
  std::printf("[start-up] +hierarchy  %10.0f %10.0f %7.1fx  (and every object's hierarchy detector: quick_start, "
              "background)\n",
              cold.serveMs, warm.serveMs, cold.serveMs / warm.serveMs);
  std::printf("[start-up] near object %10.0f %10.0f %7.1fx  (levels + the hierarchy and grid detectors of the "
              "object near the pointer, which the node prepares first; no hierarchy when its grid is cached)\n",
              cold.setsMs + cold.firstQuickMs + cold.firstGridMs, warm.setsMs + warm.firstQuickMs + warm.firstGridMs,
              (cold.setsMs + cold.firstQuickMs + cold.firstGridMs) / (warm.setsMs + warm.firstQuickMs + warm.firstGridMs));
  std::printf("[start-up] all grids   %10.0f %10.0f %7.1fx  (every grid detector: grid_on_demand=false; the restart "
              "reads %zu of %zu grids from the cache and skips their %.0f ms of hierarchy detectors)\n",
              cold.totalMs, warm.totalMs, cold.totalMs / warm.totalMs, warm.gridsCached, scene.meshes.size(),
              warm.skippedQuickMs);
  std::printf("[start-up] parts: sphere sets %.0f / %.0f ms (placement+clustering+store / cache reads), hierarchy "
              "detectors %.0f / %.0f ms, grid detectors %.0f / %.0f ms, hashing %.0f / %.0f ms\n",
              cold.cacheMs, warm.cacheMs, cold.serveDetectorMs, warm.serveDetectorMs, cold.gridDetectorMs,
              warm.gridDetectorMs, cold.hashMs, warm.hashMs);
  std::printf("[start-up] build: %zu built, %zu hits; restart: %zu built, %zu hits; levels alone %.0fx faster from "
              "the cache\n",
              cold.built, cold.hits, warm.built, warm.hits, (cold.cacheMs + cold.hashMs) / (warm.cacheMs + warm.hashMs));

  // ---- 2. Queries near one object.
  SceneDetector sceneDetector;
  for (std::size_t i = 0; i < scene.meshes.size(); ++i)
    sceneDetector.addObject(last.meshes[i]->name, last.meshes[i], last.levels[i], scene.poses[i]);
  std::vector<SceneContact> contacts(sceneDetector.size());
  SceneCaches caches;  // one stream's, as the node keeps it
  caches.resize(sceneDetector.size());

  std::printf("\n[query] %d queries per run, median of %d interleaved rounds, ns per query\n", o.queries, o.rounds);
  std::printf("%-14s %9s %9s %9s %12s %9s %11s %12s %9s\n", "object", "triangles", "alone", "scene", "scene/alone*",
              "flat", "flat/alone*", "no-bound", "touched");
  std::vector<double> ratios, flatRatioAll;
  bool allMatch = true;
  for (int t = 0; t < o.targets; ++t) {
    const std::uint32_t target =
        static_cast<std::uint32_t>((t * 17) % static_cast<int>(sceneDetector.size()));
    const ClodDetector& alone = *last.levels[target];
    const TriangleMesh& mesh = *last.meshes[target];
    // A coherent stream near the surface (Morton order), as a stylus sweeping over the object.
    std::vector<Vec3> local = nearSurfaceProbes(mesh, static_cast<std::size_t>(o.queries), 2.0 * o.radius, 7 + t);
    sortMorton(local);
    std::vector<Vec3> world;
    for (const Vec3& p : local) world.push_back(scene.poses[target] * p);

    // Agreement first (not timed): the scene's answer for the target equals the detector alone.
    std::size_t touched = 0;
    for (std::size_t k = 0; k < local.size(); k += 7) {
      ContactResult a;
      alone.query(local[k], o.radius, DetectionMode::Exact, a);
      SceneQueryResult out;
      sceneDetector.query(world[k], o.radius, DetectionMode::Exact, contacts.data(), contacts.size(), out);
      const SceneContact* mine = nullptr;
      for (std::uint32_t c = 0; c < out.contacts; ++c)
        if (contacts[c].object == target) mine = &contacts[c];
      if ((mine != nullptr) != a.contact || (mine && std::abs(mine->local.distance - a.distance) > 1e-9)) {
        allMatch = false;
      }
    }

    std::vector<double> aloneNs, sceneNs, flatNs, naiveNs;
    for (int round = 0; round < o.rounds; ++round) {
      QueryCache aloneCache;
      auto start = Clock::now();
      double sum = 0.0;
      for (const Vec3& p : local) {
        ContactResult r;
        alone.query(p, o.radius, DetectionMode::Exact, r, &aloneCache);
        sum += r.depth;
      }
      doNotOptimize(sum);
      aloneNs.push_back(msSince(start) * 1e6 / local.size());

      caches.resize(sceneDetector.size());
      start = Clock::now();
      sum = 0.0;
      touched = 0;
      for (const Vec3& p : world) {
        SceneQueryResult out;
        sceneDetector.query(p, o.radius, DetectionMode::Exact, contacts.data(), contacts.size(), out, caches);
        sum += out.penetration.x();
        touched += out.touched;
      }
      doNotOptimize(sum);
      sceneNs.push_back(msSince(start) * 1e6 / world.size());

      // The same scene with an array of caches instead of a stream's: every bound tested, every cache touched.
      std::vector<QueryCache> flatCaches(sceneDetector.size());
      start = Clock::now();
      sum = 0.0;
      for (const Vec3& p : world) {
        SceneQueryResult out;
        sceneDetector.query(p, o.radius, DetectionMode::Exact, contacts.data(), contacts.size(), out,
                            flatCaches.data());
        sum += out.penetration.x();
      }
      doNotOptimize(sum);
      flatNs.push_back(msSince(start) * 1e6 / world.size());

      // Peer: the same scene without the scene-level bound (every object transformed and queried).
      caches.resize(sceneDetector.size());
      start = Clock::now();
      sum = 0.0;
      for (const Vec3& p : world) {
        for (std::size_t i = 0; i < scene.meshes.size(); ++i) {
          ContactResult r;
          last.levels[i]->query(scene.poses[i].inverse(Eigen::Isometry) * p, o.radius, DetectionMode::Exact, r,
                                &caches.objects[i]);
          sum += r.depth;
        }
      }
      doNotOptimize(sum);
      naiveNs.push_back(msSince(start) * 1e6 / world.size());
    }
    // Alone and scene run back to back in each round: the ratio per round cancels most of the drift
    // a shared machine adds; the median over rounds is reported.
    std::vector<double> roundRatios;
    std::vector<double> flatRatios;
    for (std::size_t k = 0; k < sceneNs.size(); ++k) {
      roundRatios.push_back(sceneNs[k] / aloneNs[k]);
      flatRatios.push_back(flatNs[k] / aloneNs[k]);
    }
    const double ratio = median(roundRatios);
    ratios.push_back(ratio);
    flatRatioAll.push_back(median(flatRatios));
    std::printf("%-14s %9zu %9.0f %9.0f %12.2f %9.0f %11.2f %12.0f %9zu\n", mesh.name.c_str(), mesh.size(),
                median(aloneNs), median(sceneNs), ratio, median(flatNs), flatRatioAll.back(), median(naiveNs), touched);
  }
  // The fixed cost of the scene: a pointer far from every object (all rejected by their bound), moving a hair a query
  // (the stream's neighbourhood kept), jumping a metre a query (found again every time), and with an array of caches.
  {
    std::vector<double> restingNs, jumpingNs, flatNs;
    std::vector<QueryCache> flatCaches(sceneDetector.size());
    for (int round = 0; round < o.rounds; ++round) {
      for (int kind = 0; kind < 3; ++kind) {
        const auto start = Clock::now();
        double sum = 0.0;
        for (int k = 0; k < o.queries; ++k) {
          SceneQueryResult out;
          const Vec3 p(-1.0 - (kind == 1 ? 1.0 * (k % 2) : 1e-6 * k), -1.0, 0.5);
          if (kind == 2)
            sceneDetector.query(p, o.radius, DetectionMode::Exact, contacts.data(), contacts.size(), out,
                                flatCaches.data());
          else
            sceneDetector.query(p, o.radius, DetectionMode::Exact, contacts.data(), contacts.size(), out, caches);
          sum += out.objectsRejected;
        }
        doNotOptimize(sum);
        (kind == 0 ? restingNs : kind == 1 ? jumpingNs : flatNs).push_back(msSince(start) * 1e6 / o.queries);
      }
    }
    std::printf(
        "[query] pointer far from every object (all %zu rejected by the scene bound), ns per query: resting "
        "%.0f, jumping 1 m a query %.0f, flat (array of caches) %.0f\n",
        sceneDetector.size(), median(restingNs), median(jumpingNs), median(flatNs));
  }
  std::printf("[query] * median over rounds of the per-round ratio (alone and scene measured back to back)\n");
  std::printf(
      "[query] scene/alone (a stream's SceneCaches, as the node): median %.2f, worst %.2f (target <= 1.2); "
      "flat: median %.2f, worst %.2f; answers %s\n",
      median(ratios), *std::max_element(ratios.begin(), ratios.end()), median(flatRatioAll),
      *std::max_element(flatRatioAll.begin(), flatRatioAll.end()), allMatch ? "identical" : "DIFFER");

  if (ownCache) fs::remove_all(cacheDir);
  return allMatch ? 0 : 1;
}
