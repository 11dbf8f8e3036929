// clod_tool: build CLOD sphere sets, run queries and print the paper's Table 2, without roscore.

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/detector.h"
#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/probes.h"
#include "clod_haptics/core/sphere_set.h"
#include "clod_haptics/core/sphere_set_io.h"
#include "clod_tool_io.h"

namespace {

using namespace clod_haptics;
using namespace clod_tool;
using Clock = std::chrono::steady_clock;

const char* kUsage =
    "usage (every command also takes --clustering single-link|cube|tight, default single-link):\n"
    "  clod_tool build --mesh M [--scale S | --normalize] (--distance D | --count N) --out SPHERES.yaml [--json]\n"
    "                  (--count N: the level with at most N spheres, the least such distance by bisection)\n"
    "  clod_tool query --mesh M [--scale S | --normalize] --distance D --radius R --mode exact|paper|spheres\n"
    "                  --probes P.csv --out RESULT.csv [--fast grid|hierarchy|flat] [--json]\n"
    "  clod_tool sweep --mesh M [--scale S | --normalize] --distances 0,0.01,...,0.08 [--radius R]\n"
    "                  [--mode exact|paper] [--fast grid|hierarchy|flat] [--count N] [--json]\n"
    "bounds: --radius, --distance(s) in [0, 1e12]; --scale in [1e-12, 1e12], the scaled mesh's coordinates\n"
    "  within 1e12 and its largest side at least 1e-12; --count an integer in [1, 1e7] (sweep: probes, default\n"
    "  20000; build: spheres).\n"
    "probes: 'x,y,z' rows of finite numbers within 1e12, lines of at most 4096 bytes, an optional\n"
    "  non-numeric header row.\n";

double msSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

// The bounds of the numeric options (kMaxLength says why lengths stop at 1e12).
// --radius: 0 is a point probe; above kMaxLength the grid and the squared distances leave their range.
constexpr Bound kRadius{0.0, kMaxLength};
// --distance, --distances: clustering distances, lengths like the radius.
constexpr Bound kDistance{0.0, kMaxLength};
// --scale: a unit conversion (pm to m, m to Tm) needs no more than 1e12 either way; the loaded mesh is
// then checked against kMaxLength and kMinExtent.
constexpr Bound kScale{1e-12, 1e12};
// --count: at least one probe; at most 1e7, whose probes (24 bytes), per-query timings (8 bytes) and
// answers stay within a few hundred MB and whose timing passes stay within minutes per distance.
constexpr Bound kCount{1.0, 1e7, true};

MeshLoadOptions loadOptions(const Args& args) {
  MeshLoadOptions o;
  if (args.has("--scale") && args.has("--normalize")) {
    throw ToolError(kUsageError, "--scale and --normalize exclude each other");
  }
  o.normalize = args.has("--normalize");
  o.scale = args.number("--scale", kScale, 1.0);
  return o;
}

// The loaded mesh within the lengths the arithmetic keeps finite: every coordinate within kMaxLength and
// the largest side at least kMinExtent. Blamed on --scale when given, else on the file.
void checkMeshSize(const TriangleMesh& mesh, const Args& args) {
  double largest = 0.0;
  Vec3 low = Vec3::Constant(INFINITY), high = Vec3::Constant(-INFINITY);
  for (const Vec3& local : mesh.vertices) {
    const Vec3 v = mesh.toModel(local);
    largest = std::max(largest, v.cwiseAbs().maxCoeff());
    low = low.cwiseMin(v);
    high = high.cwiseMax(v);
  }
  const double side = mesh.vertices.empty() ? 0.0 : (high - low).maxCoeff();
  if (largest <= kMaxLength && side >= kMinExtent) return;
  char problem[200];
  std::snprintf(problem, sizeof problem, "has coordinates up to %g and a largest side of %g; the bounds are %g and %g",
                largest, side, kMaxLength, kMinExtent);
  if (args.has("--scale")) throw ToolError(kUsageError, "--scale " + args.get("--scale") + ": the mesh " + problem);
  throw ToolError(kInputError, "mesh '" + args.get("--mesh") + "' " + problem + " (try --scale or --normalize)");
}

// Progress on stderr once a build has run for a second: a bar on a terminal, percentage lines otherwise.
std::function<void(double)> progressPrinter(Clock::time_point start) {
  const bool tty = isatty(STDERR_FILENO);
  auto last = std::make_shared<int>(-1);
  return [=](double fraction) {
    if (msSince(start) < 1000.0) return;
    const int percent = static_cast<int>(fraction * 100.0);
    if (percent == *last || (!tty && percent % 10 != 0 && percent != 100)) return;
    *last = percent;
    if (tty) {
      const int width = 40, filled = percent * width / 100;
      std::fprintf(stderr, "\rplacing spheres [%s%s] %3d%%", std::string(filled, '#').c_str(),
                   std::string(width - filled, ' ').c_str(), percent);
      if (percent == 100) std::fprintf(stderr, "\n");
    } else {
      std::fprintf(stderr, "placing spheres: %d%%\n", percent);
    }
  };
}

struct Loaded {
  std::shared_ptr<TriangleMesh> mesh;
  std::unique_ptr<ClodBuilder> builder;
  double loadMs = 0.0;
  double placementMs = 0.0;
};

std::shared_ptr<const Clustering> clusteringArg(const Args& args) {
  try {
    return requireClustering(args.get("--clustering", "single-link"), "--clustering");
  } catch (const InvalidParameter& e) {
    throw ToolError(kUsageError, e.what());
  }
}

// Loads the mesh, checks its size and places the spheres (options and strategy are parsed before, so a bad
// command line fails before the expensive work).
Loaded loadAndPlace(const Args& args, const MeshLoadOptions& options, std::shared_ptr<const Clustering> clustering) {
  Loaded l;
  auto start = Clock::now();
  l.mesh = std::make_shared<TriangleMesh>(loadMesh(args.get("--mesh"), options));
  checkMeshSize(*l.mesh, args);
  l.loadMs = msSince(start);
  start = Clock::now();
  l.builder = std::make_unique<ClodBuilder>(l.mesh, std::make_shared<PaperPlacement>(0, progressPrinter(start)),
                                            std::move(clustering));
  l.placementMs = msSince(start);
  return l;
}

DetectionMode modeArg(const Args& args, const char* fallback) {
  DetectionMode mode;
  const std::string m = args.get("--mode", fallback);
  if (!parseDetectionMode(m.c_str(), mode)) {
    throw ToolError(kUsageError, "--mode must be exact, paper or spheres, got '" + m + "'");
  }
  return mode;
}

FastLevel fastArg(const Args& args) {
  FastLevel level;
  const std::string f = args.get("--fast", "grid");
  if (!parseFastLevel(f.c_str(), level)) {
    throw ToolError(kUsageError, "--fast must be grid, hierarchy or flat, got '" + f + "'");
  }
  return level;
}

// Median per-query time: each query timed alone, minus the timer's own cost.
struct Timing {
  double meanNs;
  double medianNs;
};

template <class Query>
Timing timeQueries(std::size_t n, Query&& query) {
  if (n == 0) return {0.0, 0.0};
  // Mean: one clock pair around the whole run (twice, keep the faster to skip cold caches).
  double mean = 1e300;
  for (int rep = 0; rep < 2; ++rep) {
    const auto start = Clock::now();
    for (std::size_t i = 0; i < n; ++i) query(i);
    mean = std::min(mean, std::chrono::duration<double, std::nano>(Clock::now() - start).count() / n);
  }
  std::vector<double> each(n), empty(std::min<std::size_t>(n, 10000));
  for (auto& e : empty) {
    const auto a = Clock::now();
    const auto b = Clock::now();
    e = std::chrono::duration<double, std::nano>(b - a).count();
  }
  for (std::size_t i = 0; i < n; ++i) {
    const auto a = Clock::now();
    query(i);
    const auto b = Clock::now();
    each[i] = std::chrono::duration<double, std::nano>(b - a).count();
  }
  auto median = [](std::vector<double>& v) {
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  const double overhead = median(empty);
  return {mean, std::max(0.0, median(each) - overhead)};
}

// Every option of a command parsed before any work: a bad value fails at once.
struct MeshArgs {
  MeshLoadOptions options;
  std::shared_ptr<const Clustering> clustering;
  explicit MeshArgs(const Args& args) : options(loadOptions(args)), clustering(clusteringArg(args)) {}
};

int cmdBuild(int argc, char** argv) {
  Args args(argc, argv, {"--mesh", "--scale", "--distance", "--count", "--out", "--clustering"}, {"--normalize", "--json"});
  if (args.has("--distance") == args.has("--count"))
    throw ToolError(kUsageError, "build takes one of --distance and --count");
  const bool byCount = args.has("--count");
  const double d0 = byCount ? 0.0 : args.number("--distance", kDistance);
  const double maxSpheres = byCount ? args.number("--count", kCount) : 0.0;
  const MeshArgs meshArgs(args);
  const std::string out = args.get("--out");
  checkWritable("--out", out);
  Loaded l = loadAndPlace(args, meshArgs.options, meshArgs.clustering);
  const auto start = Clock::now();
  const ClodSphereSet set =
      byCount ? l.builder->buildAtMost(static_cast<std::size_t>(maxSpheres)) : l.builder->build(d0);
  const double d = set.distance;
  const double clusterMs = msSince(start);
  writeOutput("--out", out, [&](std::ostream& stream) { writeSphereSetYaml(set, stream); });
  const double buildMs = l.placementMs + clusterMs;
  if (args.has("--json")) {
    std::printf(
        "{\"command\":\"build\",\"mesh\":\"%s\",\"triangles\":%zu,\"distance\":%.17g,\"centres\":%zu,\"spheres\":%zu,"
        "\"unpaired\":%zu,\"degenerate\":%zu,\"load_ms\":%.3f,\"placement_ms\":%.3f,\"clustering_ms\":%.3f,"
        "\"build_ms\":%.3f,\"out\":\"%s\"}\n",
        l.mesh->name.c_str(), l.mesh->size(), d, set.stats.centres, set.stats.spheres, set.stats.unpaired,
        set.stats.degenerate, l.loadMs, l.placementMs, clusterMs, buildMs, out.c_str());
  } else {
    std::printf("mesh %s: %zu triangles (%zu without an opposite triangle, %zu zero-area)\n", l.mesh->name.c_str(),
                l.mesh->size(), set.stats.unpaired, set.stats.degenerate);
    std::printf("centres before clustering: %zu\ncentres after clustering (d = %g): %zu\n", set.stats.centres, d,
                set.stats.spheres);
    std::printf("build time: %.2f ms (placement %.2f ms, clustering %.2f ms); load %.2f ms\nwrote %s\n", buildMs,
                l.placementMs, clusterMs, l.loadMs, out.c_str());
  }
  return 0;
}

// RESULT.csv: one row per probe, the contact's distance, point and triangle, or empty cells for none.
void writeResultsCsv(std::ostream& out, const std::vector<ContactResult>& results) {
  out << "index,contact,distance,px,py,pz,triangle\n";
  out.precision(17);
  for (std::size_t i = 0; i < results.size(); ++i) {
    const ContactResult& c = results[i];
    if (c.contact) {
      out << i << ",1," << c.distance << ',' << c.point.x() << ',' << c.point.y() << ',' << c.point.z() << ','
          << c.triangle << '\n';
    } else {
      out << i << ",0,,,,,\n";
    }
  }
}

int cmdQuery(int argc, char** argv) {
  Args args(argc, argv,
            {"--mesh", "--scale", "--distance", "--radius", "--mode", "--probes", "--out", "--fast", "--clustering"},
            {"--normalize", "--json"});
  const double d = args.number("--distance", kDistance);
  const double r = args.number("--radius", kRadius);
  const DetectionMode mode = modeArg(args, "exact");
  const FastLevel fast = fastArg(args);
  const MeshArgs meshArgs(args);
  const std::string outPath = args.get("--out");
  checkWritable("--out", outPath);
  const std::vector<Vec3> probes = readProbes(args.get("--probes"));
  Loaded l = loadAndPlace(args, meshArgs.options, meshArgs.clustering);
  auto start = Clock::now();
  auto set = std::make_shared<const ClodSphereSet>(l.builder->build(d));
  const double buildMs = l.placementMs + msSince(start);
  const ClodDetector detector(l.mesh, set, fast, r);

  std::vector<ContactResult> results(probes.size());
  const Timing timing = timeQueries(probes.size(), [&](std::size_t i) { detector.query(probes[i], r, mode, results[i]); });
  writeOutput("--out", outPath, [&](std::ostream& out) { writeResultsCsv(out, results); });
  const std::size_t contacts =
      std::count_if(results.begin(), results.end(), [](const ContactResult& c) { return c.contact; });
  if (args.has("--json")) {
    std::printf(
        "{\"command\":\"query\",\"mesh\":\"%s\",\"triangles\":%zu,\"distance\":%.17g,\"radius\":%.17g,\"mode\":\"%s\","
        "\"centres\":%zu,\"spheres\":%zu,\"probes\":%zu,\"contacts\":%zu,\"build_ms\":%.3f,"
        "\"ns_per_query_mean\":%.2f,\"ns_per_query_median\":%.2f}\n",
        l.mesh->name.c_str(), l.mesh->size(), d, r, toString(mode), set->stats.centres, set->stats.spheres,
        probes.size(), contacts, buildMs, timing.meanNs, timing.medianNs);
  } else {
    std::printf("%zu probes, %zu contacts (mode %s, d = %g, r = %g, %zu spheres)\n", probes.size(), contacts,
                toString(mode), d, r, set->stats.spheres);
    std::printf("mean time per query: %.1f ns (median %.1f ns)\nwrote %s\n", timing.meanNs, timing.medianNs,
                outPath.c_str());
  }
  return 0;
}

std::vector<double> parseList(const std::string& text) {
  std::vector<double> values;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) values.push_back(parseBounded("--distances", item, kDistance));
  if (values.empty()) throw ToolError(kUsageError, "--distances is empty");
  return values;
}

int cmdSweep(int argc, char** argv) {
  Args args(argc, argv, {"--mesh", "--scale", "--distances", "--radius", "--mode", "--fast", "--count", "--clustering"},
            {"--normalize", "--json"});
  const std::vector<double> distances = parseList(args.get("--distances"));
  const double r = args.number("--radius", kRadius, 0.005);
  const DetectionMode mode = modeArg(args, "exact");
  if (mode == DetectionMode::Spheres) {
    throw ToolError(kUsageError, "sweep times a precise level: --mode exact or paper");
  }
  const FastLevel fast = fastArg(args);
  const double count = args.number("--count", kCount, 20000);
  const MeshArgs meshArgs(args);
  Loaded l = loadAndPlace(args, meshArgs.options, meshArgs.clustering);
  // Probes near the surface (within 2r on either side), the stylus's working zone; fixed seed.
  const std::vector<Vec3> probes = nearSurfaceProbes(*l.mesh, static_cast<std::size_t>(count), 2.0 * r, 20161129);

  const bool json = args.has("--json");
  if (!json) {
    std::printf("mesh %s: %zu triangles, placement %.1f ms, %zu probes near the surface, r = %g, mode %s, fast %s\n",
                l.mesh->name.c_str(), l.mesh->size(), l.placementMs, probes.size(), r, toString(mode), toString(fast));
    std::printf("%8s %9s %10s %11s %10s %10s %10s %10s %12s %9s %8s %8s\n", "d", "centres", "step_red%",
                "total_red%", "build_ms", "fast_us", "precise_us", "total_us", "rate_Hz", "contacts", "spheres", "tris");
  } else {
    std::printf("{\"command\":\"sweep\",\"mesh\":\"%s\",\"triangles\":%zu,\"radius\":%.17g,\"mode\":\"%s\","
                "\"placement_ms\":%.3f,\"rows\":[",
                l.mesh->name.c_str(), l.mesh->size(), r, toString(mode), l.placementMs);
  }
  double previous = 0.0, first = 0.0;
  for (std::size_t k = 0; k < distances.size(); ++k) {
    const auto start = Clock::now();
    auto set = std::make_shared<const ClodSphereSet>(l.builder->build(distances[k]));
    const double clusterMs = msSince(start);
    const ClodDetector detector(l.mesh, set, fast, r);
    ContactResult result;
    std::size_t contacts = 0;
    double spheresHit = 0.0, trianglesTested = 0.0;
    for (const Vec3& p : probes) {
      detector.query(p, r, mode, result);
      contacts += result.contact;
      spheresHit += result.spheresHit;
      trianglesTested += result.trianglesTested;
    }
    spheresHit /= std::max<std::size_t>(1, probes.size());
    trianglesTested /= std::max<std::size_t>(1, probes.size());
    // Fast level alone (the same descent the precise modes use), then the whole query.
    std::uint64_t sink = 0;
    const Timing fastT = timeQueries(probes.size(), [&](std::size_t i) { sink += detector.fastLevelHits(probes[i], r); });
    if (sink == 0xffffffffffffull) std::printf(" ");  // keeps the fast-level loop from being optimised away
    const Timing totalT = timeQueries(probes.size(), [&](std::size_t i) { detector.query(probes[i], r, mode, result); });
    const double centres = static_cast<double>(set->size());
    if (k == 0) first = previous = centres;
    const double step = previous > 0 ? 100.0 * (previous - centres) / previous : 0.0;
    const double total = first > 0 ? 100.0 * (first - centres) / first : 0.0;
    const double totalUs = totalT.meanNs / 1000.0, fastUs = fastT.meanNs / 1000.0;
    const double preciseUs = std::max(0.0, totalUs - fastUs);
    const double rate = totalUs > 0 ? 1e6 / totalUs : 0.0;
    if (json) {
      std::printf("%s{\"distance\":%.17g,\"centres\":%zu,\"step_reduction\":%.3f,\"total_reduction\":%.3f,"
                  "\"build_ms\":%.3f,\"fast_us\":%.4f,\"precise_us\":%.4f,\"total_us\":%.4f,\"rate_hz\":%.1f,"
                  "\"ns_per_query_median\":%.2f,\"contacts\":%zu,\"spheres_hit_mean\":%.2f,"
                  "\"triangles_tested_mean\":%.2f}",
                  k ? "," : "", distances[k], set->size(), step, total, l.placementMs + clusterMs, fastUs, preciseUs,
                  totalUs, rate, totalT.medianNs, contacts, spheresHit, trianglesTested);
    } else {
      std::printf("%8.4g %9zu %10.1f %11.1f %10.2f %10.4f %10.4f %10.4f %12.0f %9zu %8.1f %8.1f\n", distances[k],
                  set->size(), step, total, l.placementMs + clusterMs, fastUs, preciseUs, totalUs, rate, contacts,
                  spheresHit, trianglesTested);
    }
    previous = centres;
  }
  if (json) std::printf("]}\n");
  return 0;
}

int runCommand(int argc, char** argv) {
  const std::string command = argv[1];
  if (command == "build") return cmdBuild(argc, argv);
  if (command == "query") return cmdQuery(argc, argv);
  if (command == "sweep") return cmdSweep(argc, argv);
  throw ToolError(kUsageError, "unknown command '" + command + "' (build, query or sweep)");
}

// Prints an error as one line on stderr (after what stdout holds) and returns its exit code.
ExitCode failed(const char* what, ExitCode code) {
  std::fflush(stdout);
  std::fprintf(stderr, "clod_tool: %s\n", what);
  return code;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2 || std::string(argv[1]) == "--help" || std::string(argv[1]) == "-h") {
    std::FILE* to = argc < 2 ? stderr : stdout;
    std::fputs(kUsage, to);
    std::fputs(exitCodeTable().c_str(), to);
    return argc < 2 ? kUsageError : kOk;
  }
  try {
    const int code = runCommand(argc, argv);
    finishStdout();
    return code;
  } catch (const ToolError& e) {
    return failed(e.what(), e.code());
  } catch (const MeshLoadError& e) {
    return failed(e.what(), kInputError);
  } catch (const InvalidParameter& e) {
    return failed(e.what(), kUsageError);
  } catch (const std::bad_alloc&) {
    return failed("out of memory", kInternalError);
  } catch (const std::exception& e) {
    return failed(e.what(), kInternalError);
  }
}
