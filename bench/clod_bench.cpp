// clod_bench: run time against error for every mesh and CLOD level, beside the peers (Embree,
// CGAL, FCL, brute force) on the same probes, sphere tightness against an octree, and growth with
// the triangle count. Writes CSV files for bench/report.py. A benchmark, never a test.
//
//   clod_bench --shared ../shared --out bench/results [--quick] [--meshes a.off,b.off]
//              [--sections sweep,peers,tightness,growth,contact,proxy]

#include <benchmark/benchmark.h>
#include <malloc.h>
#include <sys/wait.h>
#include <unistd.h>
#include <x86intrin.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <limits>
#include <map>
#include <numeric>
#include <random>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "bench_common.h"
#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/clustering.h"
#include "clod_haptics/core/detector.h"
#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/probes.h"
#include "clod_haptics/core/sphere_placement.h"
#include "clod_haptics/core/sphere_set.h"
#include "proxy_bench.h"
#include "tightness.h"

namespace fs = std::filesystem;
using namespace clod_haptics;
using namespace clod_bench;

namespace {

// ---------------------------------------------------------------------------------------------
// Settings
struct Settings {
  bool quick = false;
  std::string shared;
  std::string out;
  std::set<std::string> meshes;  // empty: all
  std::set<std::string> sections{"sweep", "spheres", "peers", "tightness", "growth", "contact", "proxy"};
  double r = 0.005;
  std::vector<double> distances{0.0, 0.01, 0.02, 0.03, 0.04, 0.05, 0.06, 0.07, 0.08};
  std::size_t probes = 100000;          // per probe set (near-surface, uniform)
  double budgetHierarchy = 2.0;         // seconds per (level, mode, probe set) of the sweep
  double budgetFlat = 0.4;              // the flat list at small d costs milliseconds per query
  double budgetBrute = 3.0;             // seconds per probe set for the brute-force peer
  std::size_t bruteMax = 2000;          // and at most this many probes
  int rounds = 2;                       // peer comparison: alternate contenders, keep the best median
  int contactRounds = 3;                // contact section: alternate contenders, keep the lowest mean (and start-up)
  std::size_t mcSamples = 100000;       // tightness: Monte Carlo points per sphere set
  std::size_t surfaceSamples = 200000;  // tightness: surface points for the coverage
  std::size_t growthLimit = 1700000;    // growth: largest subdivided mesh (triangles)
  std::size_t growthProbes = 20000;
  double growthD = 0.02;
  double reportD = 0.02;
};

bool has(const Settings& s, const char* section) { return s.sections.count(section) > 0; }

std::string fmt(double v) {
  if (!std::isfinite(v)) return "nan";
  std::ostringstream o;
  o.precision(6);
  o << v;
  return o.str();
}

double secondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// ---------------------------------------------------------------------------------------------
// Timing: every query timed alone with the time-stamp counter (fenced), the empty-region cost
// subtracted; stops after `budget` seconds once at least minCount queries ran. Queries run in index
// order (0, 1, 2, ...: a stream keeps its order, which a QueryCache relies on), after a warm-up over
// the first 200; onStart runs between the warm-up and the timed run (e.g. to reset a stream's cache).
struct NoStart {
  void operator()() const {}
};
template <class F, class S = NoStart>
Timing timeEach(std::size_t n, double budget, std::size_t minCount, F&& f, S&& onStart = S{}) {
  Timing t;
  t.ns.reserve(n);
  const std::size_t warm = std::min<std::size_t>(n, 200);
  for (std::size_t i = 0; i < warm; ++i) f(i);
  onStart();
  const auto start = std::chrono::steady_clock::now();
  const std::uint64_t budgetTicks = static_cast<std::uint64_t>(budget * 1e9 / Clock::nsPerTick);
  const std::uint64_t begin = __rdtsc();
  for (std::size_t i = 0; i < n; ++i) {
    t.ns.push_back(fencedNs([&] { f(i); }));
    if (i + 1 >= minCount && (i & 63) == 63 && __rdtsc() - begin > budgetTicks) break;
  }
  t.totalSeconds = secondsSince(start);
  t.summarise();
  return t;
}

// ---------------------------------------------------------------------------------------------
// Errors of our answers against the reference on the first n probes.
struct Errors {
  std::size_t n = 0, refContacts = 0, ourContacts = 0, missed = 0, falseContacts = 0, both = 0;
  double meanDistance = 0, maxDistance = 0, meanNormalDeg = 0, maxNormalDeg = 0, maxPoint = 0;
  double meanSpheresHit = 0, meanTrianglesTested = 0;
};

Errors compare(const std::vector<ContactResult>& ours, const std::vector<ContactResult>& ref, std::size_t n) {
  Errors e;
  e.n = n;
  for (std::size_t i = 0; i < n; ++i) {
    const ContactResult &o = ours[i], &f = ref[i];
    e.refContacts += f.contact;
    e.ourContacts += o.contact;
    e.meanSpheresHit += o.spheresHit;
    e.meanTrianglesTested += o.trianglesTested;
    if (f.contact && !o.contact) ++e.missed;
    if (!f.contact && o.contact) ++e.falseContacts;
    if (f.contact && o.contact) {
      ++e.both;
      const double dd = std::abs(o.distance - f.distance);
      e.meanDistance += dd;
      e.maxDistance = std::max(e.maxDistance, dd);
      const double c = std::clamp(o.normal.dot(f.normal) / std::max(1e-300, o.normal.norm() * f.normal.norm()), -1.0, 1.0);
      const double deg = std::acos(c) * 180.0 / M_PI;
      e.meanNormalDeg += deg;
      e.maxNormalDeg = std::max(e.maxNormalDeg, deg);
      e.maxPoint = std::max(e.maxPoint, (o.point - f.point).norm());
    }
  }
  if (e.both) {
    e.meanDistance /= e.both;
    e.meanNormalDeg /= e.both;
  }
  if (n) {
    e.meanSpheresHit /= n;
    e.meanTrianglesTested /= n;
  }
  return e;
}

struct Stats {
  double mean = NAN, median = NAN, p90 = NAN, p99 = NAN, max = NAN;
};

Stats statsOf(std::vector<float> v) {
  Stats st;
  if (v.empty()) return st;
  std::sort(v.begin(), v.end());
  auto at = [&](double q) { return static_cast<double>(v[std::min(v.size() - 1, static_cast<std::size_t>(q * v.size()))]); };
  double sum = 0.0;
  for (float x : v) sum += x;
  st.mean = sum / v.size();
  st.median = at(0.5);
  st.p90 = at(0.9);
  st.p99 = at(0.99);
  st.max = v.back();
  return st;
}

// A peer agrees when the contact flag matches and, in contact, distance and point match to 1e-9.
std::size_t disagreements(const std::vector<Answer>& answers, const std::vector<ContactResult>& ref, std::size_t n,
                          double& maxDistanceDiff) {
  std::size_t bad = 0;
  maxDistanceDiff = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Answer& a = answers[i];
    const ContactResult& f = ref[i];
    if (a.contact != f.contact) {
      ++bad;
      continue;
    }
    if (!a.contact) continue;
    const double dd = std::abs(a.distance - f.distance);
    maxDistanceDiff = std::max(maxDistanceDiff, dd);
    if (dd > 1e-9 || (a.point - f.point).norm() > 1e-9) ++bad;
  }
  return bad;
}

// What a stream with a QueryCache answers: the stateless reference, and after an answer with the centre inside,
// the nearest triangle at any depth while the centre stays behind the surface within the bounds
// (bruteForceSignedQuery's rule; `near` finds it within its radius, brute force beyond).
std::vector<ContactResult> streamReference(const TriangleMesh& mesh, const std::vector<Vec3>& path,
                                           const std::vector<ContactResult>& stateless, const PrunedReference& near,
                                           double r) {
  std::vector<ContactResult> out = stateless;
  const Eigen::AlignedBox3d bounds = mesh.bounds();  // O(triangles): once
  bool inside = false;
  for (std::size_t i = 0; i < path.size(); ++i) {
    if (stateless[i].contact) {
      inside = stateless[i].inside;
      continue;
    }
    if (!inside) continue;
    ContactResult deep = near.query(path[i]);
    if (deep.contact) {
      deep.contact = deep.inside && bounds.contains(mesh.toLocal(path[i]));
    } else {
      deep = bruteForceSignedQuery(mesh, path[i], r);
    }
    if (deep.contact) out[i] = deep;
    inside = deep.contact;
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// Our detector as a peer. With a cache (clod-grid-cache) it holds one QueryCache for the stream of
// probes, reset by startStream() at the start of every timed run; the probes then come in their order.
class ClodPeer : public Peer {
 public:
  ClodPeer(const ClodDetector& detector, std::string name, bool useCache = false)
      : detector_(detector), name_(std::move(name)), useCache_(useCache) {}
  std::string name() const override { return name_; }
  void query(const Vec3& p, double r, Answer& out) const override {
    ContactResult c;
    detector_.query(p, r, DetectionMode::Exact, c, useCache_ ? &cache_ : nullptr);
    out.contact = c.contact;
    out.point = c.point;
    out.distance = c.distance;
    out.triangle = c.triangle;
  }
  void startStream() const override { cache_ = QueryCache{}; }
  /** \brief Queries since the last reset that reused the cached cell. */
  std::uint64_t cacheHits() const { return cache_.hits; }

 private:
  const ClodDetector& detector_;
  std::string name_;
  bool useCache_;
  mutable QueryCache cache_;
};

class BrutePeer : public Peer {
 public:
  explicit BrutePeer(const TriangleMesh& mesh) : mesh_(mesh) {}
  std::string name() const override { return "brute"; }
  void query(const Vec3& p, double r, Answer& out) const override {
    const ContactResult c = bruteForceQuery(mesh_, p, r);
    out.contact = c.contact;
    out.point = c.point;
    out.distance = c.distance;
    out.triangle = c.triangle;
  }

 private:
  const TriangleMesh& mesh_;
};

struct ProbeSet {
  std::string name;
  std::vector<Vec3> points;
  std::vector<ContactResult> ref;     // stateless: what every contender without a cache answers
  std::vector<ContactResult> stream;  // the same points as one stream with a QueryCache (streamReference)
  std::vector<bool> deepFree;         // free for both, but the stream searched beyond r (after an inside answer)
};

// A contender's times on a set split by the stream's deep points: where the stream reference follows the push
// deeper than r (a contact the stateless reference does not have). There the cached contender searches deeper and
// answers contact while the stateless ones answer free; the shallow points are the same question for everyone.
// Among them, deepFree: after an inside answer no triangle within r and the centre outside: free for everyone,
// but the cached contender found that out with the deep search.
struct DeepSplit {
  std::size_t deep = 0, deepFree = 0;
  Stats shallow, deepStats;
};

DeepSplit splitDeep(const std::vector<float>& ns, const ProbeSet& set) {
  DeepSplit out;
  std::vector<float> shallow, deep;
  for (std::size_t i = 0; i < ns.size(); ++i) {
    (set.stream[i].contact != set.ref[i].contact ? deep : shallow).push_back(ns[i]);
    out.deepFree += set.deepFree[i];
  }
  out.deep = deep.size();
  out.shallow = statsOf(std::move(shallow));
  out.deepStats = statsOf(std::move(deep));
  return out;
}

const char* levelName(FastLevel l) { return toString(l); }

// ---------------------------------------------------------------------------------------------
// CSV files, opened once with their header.
struct Csv {
  std::ofstream f;
  Csv(const std::string& path, const std::string& header) : f(path) { f << header << "\n"; }
  template <class... A>
  void row(const A&... a) {
    std::ostringstream o;
    bool first = true;
    ((o << (first ? "" : ",") << a, first = false), ...);
    f << o.str() << "\n";
    f.flush();
  }
};

std::string num(double v) { return fmt(v); }

// ---------------------------------------------------------------------------------------------
// Growth: one point measured in a forked child so the peak resident set belongs to this build.
struct GrowthPoint {
  bool ok = false;
  std::size_t triangles = 0, spheres = 0;
  double placementMs = 0, buildMs = 0, detectorMs = 0, medianNs = 0, meanNs = 0;
  double peakBytes = 0, retainedBytes = 0, setBytes = 0;
  double detectorHeapBytes = 0, detectorPeakBytes = 0;  // the grid detector alone: heap kept, RSS peak
  double builderPeakBytes = 0;                          // peak of the builder phase alone (placement + build)
  double hierarchyMs = 0, hierarchyHeapBytes = 0;       // a hierarchy detector on the same set, for comparison
  std::size_t mismatches = 0, checked = 0;
  bool peakReset = false;
};

GrowthPoint growthChild(const std::string& path, int levels, const Settings& s) {
  GrowthPoint g;
  MeshLoadOptions options;
  options.normalize = true;
  TriangleMesh mesh = loadMesh(path, options);
  for (int i = 0; i < levels; ++i) mesh = subdivide(mesh);
  auto meshPtr = std::make_shared<const TriangleMesh>(std::move(mesh));
  const TriangleMesh& m = *meshPtr;
  g.triangles = m.size();
  const std::vector<Vec3> probes = nearSurfaceProbes(m, s.growthProbes, 3 * s.r, 7);
  malloc_trim(0);
  g.peakReset = resetPeakRss();
  const double base = static_cast<double>(currentRssBytes());
  auto t0 = std::chrono::steady_clock::now();
  auto builder = std::make_unique<ClodBuilder>(meshPtr);
  g.placementMs = secondsSince(t0) * 1e3;
  t0 = std::chrono::steady_clock::now();
  auto set = std::make_shared<const ClodSphereSet>(builder->build(s.growthD));
  g.buildMs = secondsSince(t0) * 1e3;
  // The detector (grid fast level, as a user builds it): its time, the heap it keeps (mallinfo2: live
  // allocations, exact whatever pages malloc reuses) and the resident peak of its construction. The
  // whole-set peak is the larger of the builder's peak and the detector's (same base).
  const double builderPeak = static_cast<double>(peakRssBytes());
  resetPeakRss();
  const double rssBeforeDetector = static_cast<double>(currentRssBytes());
  const struct mallinfo2 heap0 = mallinfo2();
  t0 = std::chrono::steady_clock::now();
  ClodDetector detector(meshPtr, set, FastLevel::Grid, s.r);
  g.detectorMs = secondsSince(t0) * 1e3;
  const struct mallinfo2 heap1 = mallinfo2();
  g.detectorHeapBytes = (static_cast<double>(heap1.uordblks) + static_cast<double>(heap1.hblkhd)) -
                        (static_cast<double>(heap0.uordblks) + static_cast<double>(heap0.hblkhd));
  const double detectorPeak = static_cast<double>(peakRssBytes());
  g.detectorPeakBytes = detectorPeak - rssBeforeDetector;
  g.peakBytes = std::max(builderPeak, detectorPeak) - base;
  g.builderPeakBytes = builderPeak - base;
  {
    const struct mallinfo2 h0 = mallinfo2();
    t0 = std::chrono::steady_clock::now();
    ClodDetector hierarchy(meshPtr, set, FastLevel::Hierarchy);
    g.hierarchyMs = secondsSince(t0) * 1e3;
    const struct mallinfo2 h1 = mallinfo2();
    g.hierarchyHeapBytes = (static_cast<double>(h1.uordblks) + static_cast<double>(h1.hblkhd)) -
                           (static_cast<double>(h0.uordblks) + static_cast<double>(h0.hblkhd));
  }
  builder.reset();
  malloc_trim(0);
  g.retainedBytes = static_cast<double>(currentRssBytes()) - base;
  g.spheres = set->size();
  g.setBytes = static_cast<double>(set->centres.size() * sizeof(Vec3) + set->radii.size() * sizeof(double) +
                                   set->offsets.size() * 4 + set->triangles.size() * 4);
  std::vector<ContactResult> out(probes.size());
  Timing t = timeEach(probes.size(), 10.0, probes.size(), [&](std::size_t i) {
    detector.query(probes[i], s.r, DetectionMode::Exact, out[i]);
    benchmark::DoNotOptimize(out[i]);
  });
  g.medianNs = t.median;
  g.meanNs = t.mean;
  PrunedReference ref(m, s.r);
  g.checked = std::min<std::size_t>(probes.size(), 5000);
  for (std::size_t i = 0; i < g.checked; ++i) {
    const ContactResult f = ref.query(probes[i]);
    if (f.contact != out[i].contact || (f.contact && std::abs(f.distance - out[i].distance) > 1e-12)) ++g.mismatches;
  }
  g.ok = true;
  return g;
}

GrowthPoint growthForked(const std::string& path, int levels, const Settings& s) {
  int fds[2];
  if (pipe(fds) != 0) return {};
  std::cout.flush();
  const pid_t pid = fork();
  if (pid == 0) {
    close(fds[0]);
    GrowthPoint g;
    try {
      g = growthChild(path, levels, s);
    } catch (const std::exception& e) {
      std::cerr << "growth child: " << e.what() << "\n";
    }
    const ssize_t w = write(fds[1], &g, sizeof g);
    (void)w;
    close(fds[1]);
    _exit(0);
  }
  close(fds[1]);
  GrowthPoint g;
  const ssize_t got = read(fds[0], &g, sizeof g);
  close(fds[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  if (got != static_cast<ssize_t>(sizeof g)) g.ok = false;
  return g;
}

// ---------------------------------------------------------------------------------------------
struct Run {
  Settings s;
  std::vector<Vec3> trajectory;  // raw, 1 kHz
  std::string trajectoryNote;
  std::unique_ptr<Csv> build, sweep, spheresMode, peers, tight, growth, checks;
  std::unique_ptr<Csv> contact, startup, models;  // the contact section
};

void benchMesh(Run& run, const std::string& path) {
  const Settings& s = run.s;
  const std::string name = fs::path(path).filename().string();
  MeshLoadOptions options;
  options.normalize = true;
  std::shared_ptr<const TriangleMesh> meshPtr;
  try {
    meshPtr = std::make_shared<const TriangleMesh>(loadMesh(path, options));
  } catch (const ClodError& e) {
    std::cout << "  skip " << name << ": " << e.what() << "\n";
    return;
  }
  const TriangleMesh& mesh = *meshPtr;
  const std::size_t open = openEdges(mesh);
  const auto meshStart = std::chrono::steady_clock::now();
  std::cout << "== " << name << ": " << mesh.size() << " triangles, " << open << " open edges\n" << std::flush;

  // Probe sets, in this order: near-surface, uniform, the stylus trajectory; plus the
  // near-surface set sorted along a Morton curve (a coherent stream).
  std::vector<ProbeSet> sets;
  sets.push_back({"near", nearSurfaceProbes(mesh, s.probes, 3 * s.r, 1), {}, {}, {}});
  sets.push_back({"uniform", uniformProbes(mesh, s.probes, s.r, 2), {}, {}, {}});
  if (!run.trajectory.empty()) sets.push_back({"trajectory", placeOver(run.trajectory, mesh), {}, {}, {}});
  {
    ProbeSet m{"near-morton", sets[0].points, {}, {}, {}};
    sortMorton(m.points);
    sets.push_back(std::move(m));
  }
  auto t0 = std::chrono::steady_clock::now();
  PrunedReference reference(mesh, s.r);
  for (auto& set : sets) set.ref = reference.queryAll(set.points, 2);
  if (has(s, "peers")) {
    // clod-grid-cache runs every set as one stream (in index order, its cache reset at the start), so it
    // follows the push deeper than r after an inside answer; near probes lie within 3r of the surface.
    const PrunedReference deep(mesh, 3.02 * s.r);
    const Eigen::AlignedBox3d bounds = mesh.bounds();
    for (auto& set : sets) {
      set.stream = streamReference(mesh, set.points, set.ref, deep, s.r);
      set.deepFree.assign(set.points.size(), false);
      for (std::size_t i = 1; i < set.points.size(); ++i)
        set.deepFree[i] = set.stream[i - 1].contact && set.stream[i - 1].inside && !set.stream[i].contact &&
                          bounds.contains(mesh.toLocal(set.points[i]));
    }
  }
  std::cout << "  reference on " << sets.size() << " sets: " << secondsSince(t0) << " s\n" << std::flush;

  // The brute-force peer doubles as the check of the pruned reference (bit-identical answers).
  BrutePeer brute(mesh);
  std::map<std::string, std::pair<Timing, std::size_t>> bruteTimes;  // set -> timing, disagreements
  for (auto& set : sets) {
    std::vector<Answer> answers(std::min(s.bruteMax, set.points.size()));
    Timing t = timeEach(answers.size(), s.budgetBrute, 50, [&](std::size_t i) {
      brute.query(set.points[i], s.r, answers[i]);
      benchmark::DoNotOptimize(answers[i]);
    });
    std::size_t exact = 0;
    for (std::size_t i = 0; i < t.ns.size(); ++i) {
      const ContactResult& f = set.ref[i];
      const Answer& a = answers[i];
      const bool same = a.contact == f.contact &&
                        (!a.contact || (a.distance == f.distance && a.point == f.point && a.triangle == f.triangle));
      exact += !same;
    }
    run.checks->row(name, set.name, t.ns.size(), exact);
    double md;
    bruteTimes[set.name] = {t, disagreements(answers, set.ref, t.ns.size(), md)};
    if (exact) std::cout << "  WARNING: pruned reference differs from bruteForceQuery on " << exact << " probes\n";
  }

  // Placement once, then every level.
  t0 = std::chrono::steady_clock::now();
  ClodBuilder builder(meshPtr);
  const double placementMs = secondsSince(t0) * 1e3;
  std::map<double, std::shared_ptr<const ClodSphereSet>> levels;
  std::map<double, double> buildMsOf;
  std::size_t previous = 0;
  for (double d : s.distances) {
    t0 = std::chrono::steady_clock::now();
    auto set = std::make_shared<const ClodSphereSet>(builder.build(d));
    const double buildMs = secondsSince(t0) * 1e3;
    levels[d] = set;
    buildMsOf[d] = buildMs;
    const BuildStats& st = set->stats;
    const double step = previous ? 1.0 - static_cast<double>(set->size()) / previous : 0.0;
    const double total = st.centres ? 1.0 - static_cast<double>(set->size()) / st.centres : 0.0;
    previous = set->size();
    run.build->row(name, mesh.size(), d, st.centres, set->size(), num(step), num(total), num(placementMs), num(buildMs),
                   st.maxTrianglesPerSphere, num(st.meanTrianglesPerSphere), st.unpaired, st.degenerate, open);
  }

  // Sweep: every level, both fast levels, every mode, every probe set.
  if (has(s, "sweep")) {
    const DetectionMode modes[3] = {DetectionMode::Spheres, DetectionMode::Paper, DetectionMode::Exact};
    struct Brief {
      bool contact;
      double distance;
    };
    for (double d : s.distances) {
      // The hierarchy's answers, to check that the grid and the flat list answer the same on their probes.
      std::map<std::pair<int, std::string>, std::vector<Brief>> hierarchyAnswers;
      for (FastLevel level : {FastLevel::Hierarchy, FastLevel::Grid, FastLevel::Flat}) {
        t0 = std::chrono::steady_clock::now();
        ClodDetector detector(meshPtr, levels[d], level, level == FastLevel::Grid ? s.r : 0.0);
        const double detectorMs = secondsSince(t0) * 1e3;
        for (DetectionMode mode : modes) {
          for (auto& set : sets) {
            std::vector<ContactResult> out(set.points.size());
            const double budget = level == FastLevel::Flat ? s.budgetFlat : s.budgetHierarchy;
            Timing t = timeEach(set.points.size(), budget, 200, [&](std::size_t i) {
              detector.query(set.points[i], s.r, mode, out[i]);
              benchmark::DoNotOptimize(out[i]);
            });
            const Errors e = compare(out, set.ref, t.ns.size());
            std::vector<Brief>& h = hierarchyAnswers[{static_cast<int>(mode), set.name}];
            std::size_t contactDiff = 0, distanceDiff = 0;
            if (level == FastLevel::Hierarchy) {
              h.resize(t.ns.size());
              for (std::size_t i = 0; i < h.size(); ++i) h[i] = {out[i].contact, out[i].distance};
            } else {
              for (std::size_t i = 0; i < std::min(h.size(), t.ns.size()); ++i) {
                contactDiff += h[i].contact != out[i].contact;
                distanceDiff += h[i].contact && out[i].contact && std::abs(h[i].distance - out[i].distance) > 1e-12;
              }
            }
            run.sweep->row(name, mesh.size(), d, levels[d]->size(), levelName(level), toString(mode), set.name, e.n,
                           num(t.median), num(t.mean), num(t.trimmedMean), num(t.p10), num(t.p90), num(t.p99), e.refContacts, e.ourContacts,
                           e.missed, e.falseContacts, num(e.meanDistance), num(e.maxDistance), num(e.meanNormalDeg),
                           num(e.maxNormalDeg), num(e.maxPoint), num(e.meanSpheresHit), num(e.meanTrianglesTested),
                           num(detectorMs), contactDiff, distanceDiff);
          }
        }
        std::cout << "  d=" << d << " " << levelName(level) << " (" << levels[d]->size() << " spheres) done at "
                  << secondsSince(meshStart) << " s\n" << std::flush;
      }
    }
  }

  // Spheres mode against the exact mode at every level, through the grid and the hierarchy: the cost per query and
  // the false contacts (a spheres-mode contact where the exact answer has none) on the near and uniform probes.
  if (has(s, "spheres")) {
    for (double d : s.distances) {
      for (FastLevel level : {FastLevel::Grid, FastLevel::Hierarchy}) {
        const ClodDetector detector(meshPtr, levels[d], level, level == FastLevel::Grid ? s.r : 0.0);
        for (std::size_t k = 0; k < 2; ++k) {
          const ProbeSet& set = sets[k];
          std::vector<ContactResult> sph(set.points.size()), exact(set.points.size());
          const Timing ts = timeEach(set.points.size(), 0.5, 2000, [&](std::size_t i) {
            detector.query(set.points[i], s.r, DetectionMode::Spheres, sph[i]);
            benchmark::DoNotOptimize(sph[i]);
          });
          const Timing te = timeEach(ts.ns.size(), 0.5, ts.ns.size(), [&](std::size_t i) {
            detector.query(set.points[i], s.r, DetectionMode::Exact, exact[i]);
            benchmark::DoNotOptimize(exact[i]);
          });
          const Errors e = compare(sph, set.ref, ts.ns.size());
          const Errors x = compare(exact, set.ref, ts.ns.size());
          run.spheresMode->row(name, mesh.size(), d, levels[d]->size(), levelName(level), set.name, e.n, num(ts.median),
                               num(ts.mean), num(te.median), num(te.mean), num(ts.median / te.median), e.refContacts,
                               e.ourContacts, e.falseContacts, num(static_cast<double>(e.falseContacts) / e.n), e.missed,
                               x.missed + x.falseContacts, num(e.meanSpheresHit));
        }
      }
      std::cout << "  spheres mode d=" << d << " done at " << secondsSince(meshStart) << " s\n" << std::flush;
    }
  }

  // Peers, in the same run on the same probes, alternating contenders over rounds.
  if (has(s, "peers")) {
    const auto set = levels.count(s.reportD) ? levels[s.reportD] : levels.begin()->second;
    auto timed = [&](FastLevel level, double gridRadius, double& ms) {
      const auto c0 = std::chrono::steady_clock::now();
      auto det = std::make_unique<ClodDetector>(meshPtr, set, level, gridRadius);
      ms = secondsSince(c0) * 1e3;
      return det;
    };
    double gridMs = 0, hierarchyMs = 0, flatMs = 0;
    const auto grid = timed(FastLevel::Grid, s.r, gridMs);
    const auto hierarchy = timed(FastLevel::Hierarchy, 0.0, hierarchyMs);
    const auto flat = timed(FastLevel::Flat, 0.0, flatMs);
    std::vector<std::unique_ptr<Peer>> peers;
    peers.push_back(std::make_unique<ClodPeer>(*grid, "clod-grid"));
    peers.back()->buildMs = gridMs;
    peers.push_back(std::make_unique<ClodPeer>(*grid, "clod-grid-cache", true));
    peers.back()->buildMs = gridMs;
    peers.push_back(std::make_unique<ClodPeer>(*hierarchy, "clod-hierarchy"));
    peers.back()->buildMs = hierarchyMs;
    peers.push_back(std::make_unique<ClodPeer>(*flat, "clod-flat"));
    peers.back()->buildMs = flatMs;
    using Make = std::function<std::unique_ptr<Peer>(const TriangleMesh&)>;
    const std::vector<Make> makers{[](const TriangleMesh& m) { return makeEmbreePeer(m); }, makeCgalPeer, makeFclPeer};
    for (const Make& make : makers) {
      try {
        peers.push_back(make(mesh));
      } catch (const std::exception& e) {
        std::cout << "  peer failed to build: " << e.what() << "\n";
      }
    }
    for (auto& probeSet : sets) {
      std::map<std::string, Timing> best;
      std::map<std::string, std::size_t> bad;
      std::map<std::string, double> maxDiff;
      for (int round = 0; round < s.rounds; ++round) {
        for (auto& peer : peers) {
          std::vector<Answer> answers(probeSet.points.size());
          const double budget = peer->name() == "clod-flat" ? s.budgetFlat : s.budgetHierarchy;
          Timing t = timeEach(
              probeSet.points.size(), budget, 200,
              [&](std::size_t i) {
                peer->query(probeSet.points[i], s.r, answers[i]);
                benchmark::DoNotOptimize(answers[i]);
              },
              [&] { peer->startStream(); });
          // The cached contender against the stream's reference (deep penetration), the others stateless.
          const bool cached = peer->name() == "clod-grid-cache";
          double md = 0;
          const std::size_t b = disagreements(answers, cached ? probeSet.stream : probeSet.ref, t.ns.size(), md);
          if (!best.count(peer->name()) || t.median < best[peer->name()].median) best[peer->name()] = std::move(t);
          bad[peer->name()] = std::max(bad[peer->name()], b);
          maxDiff[peer->name()] = std::max(maxDiff[peer->name()], md);
        }
      }
      for (auto& peer : peers) {
        const Timing& t = best[peer->name()];
        const DeepSplit ds = splitDeep(t.ns, probeSet);
        run.peers->row(name, mesh.size(), s.reportD, set->size(), probeSet.name, peer->name(), t.ns.size(), num(t.median),
                       num(t.mean), num(t.p90), num(t.p99), bad[peer->name()], num(maxDiff[peer->name()]),
                       num(peer->buildMs), peer->name() == "clod-grid-cache" ? "stream" : "stateless", ds.deep,
                       num(ds.shallow.median), num(ds.shallow.mean), num(ds.deepStats.median), num(ds.deepStats.mean),
                       ds.deepFree);
      }
      const auto& bt = bruteTimes[probeSet.name];
      const DeepSplit ds = splitDeep(bt.first.ns, probeSet);
      run.peers->row(name, mesh.size(), s.reportD, set->size(), probeSet.name, "brute", bt.first.ns.size(),
                     num(bt.first.median), num(bt.first.mean), num(bt.first.p90), num(bt.first.p99), bt.second, 0, 0,
                     "stateless", ds.deep, num(ds.shallow.median), num(ds.shallow.mean), num(ds.deepStats.median),
                     num(ds.deepStats.mean), ds.deepFree);
      // Ours: the grid, with its cache on the stylus trajectory (a coherent stream).
      const std::string ours = probeSet.name == "trajectory" ? "clod-grid-cache" : "clod-grid";
      std::cout << "  peers on " << probeSet.name << ": " << ours << " " << best[ours].median << " ns";
      for (auto& peer : peers)
        if (peer->name() != ours)
          std::cout << ", " << peer->name() << " " << best[peer->name()].median << " ns (x"
                    << best[peer->name()].median / std::max(1e-9, best[ours].median) << ")";
      if (best.count("clod-grid-cache")) {
        const DeepSplit ds = splitDeep(best["clod-grid-cache"].ns, probeSet);
        std::cout << "; clod-grid-cache " << ds.deep << " deep points (median " << ds.deepStats.median
                  << " ns), shallow median " << ds.shallow.median << " ns (" << ds.deepFree << " of them searched deep)";
      }
      std::cout << "\n" << std::flush;
    }
  }

  // Tightness against an octree of the same sphere count.
  if (has(s, "tightness")) {
    t0 = std::chrono::steady_clock::now();
    struct Entry {
      double d;
      std::string kind;
      SphereList spheres;
      int depth = 0;
      double buildMs = 0;
    };
    std::vector<Entry> entries;
    std::vector<double> ds = s.quick ? std::vector<double>{0.0, 0.02, 0.08} : s.distances;
    // The cube clustering on the same placement (the builder runs its own placement once).
    auto c0 = std::chrono::steady_clock::now();
    ClodBuilder cubeBuilder(meshPtr, std::make_shared<PaperPlacement>(), makeClustering("cube"));
    const double cubePlacementMs = secondsSince(c0) * 1e3;
    // The tight clustering on the same placement, with an octree of its own sphere count.
    c0 = std::chrono::steady_clock::now();
    ClodBuilder tightBuilder(meshPtr, std::make_shared<PaperPlacement>(), makeClustering("tight"));
    const double tightPlacementMs = secondsSince(c0) * 1e3;
    for (double d : ds) {
      const ClodSphereSet& set = *levels[d];
      Entry ours{d, "clod", {set.centres, set.radii}, 0, placementMs + buildMsOf[d]};
      entries.push_back(std::move(ours));
      c0 = std::chrono::steady_clock::now();
      const ClodSphereSet cube = cubeBuilder.build(d);
      Entry cubeEntry{d, "clod-cube", {cube.centres, cube.radii}, 0, cubePlacementMs + secondsSince(c0) * 1e3};
      entries.push_back(std::move(cubeEntry));
      c0 = std::chrono::steady_clock::now();
      const ClodSphereSet tight = tightBuilder.build(d);
      Entry tightEntry{d, "clod-tight", {tight.centres, tight.radii}, 0, tightPlacementMs + secondsSince(c0) * 1e3};
      entries.push_back(std::move(tightEntry));
      Entry tightOct{d, "octree-tight", {}, 0, 0};
      tightOct.spheres = octreeSpheres(mesh, tight.size(), tightOct.depth);
      entries.push_back(std::move(tightOct));
      auto o0 = std::chrono::steady_clock::now();
      Entry oct{d, "octree", {}, 0, 0};
      oct.spheres = octreeSpheres(mesh, set.size(), oct.depth);
      oct.buildMs = secondsSince(o0) * 1e3;
      entries.push_back(std::move(oct));
    }
    // Build time of each of our sets as a user pays it (a fresh ClodBuilder: placement, then build(d)),
    // the best of three runs: one run on this shared machine mostly measures the other jobs.
    const std::map<std::string, std::string> strategyOf{
        {"clod", "single-link"}, {"clod-cube", "cube"}, {"clod-tight", "tight"}};
    for (Entry& e : entries) {
      const auto strategy = strategyOf.find(e.kind);
      if (strategy == strategyOf.end()) continue;
      double best = std::numeric_limits<double>::infinity();
      for (int run = 0; run < 3; ++run) {
        const auto b0 = std::chrono::steady_clock::now();
        const ClodBuilder fresh(meshPtr, std::make_shared<PaperPlacement>(), makeClustering(strategy->second));
        const ClodSphereSet built = fresh.build(e.d);
        best = std::min(best, secondsSince(b0) * 1e3);
        if (built.size() != e.spheres.centres.size()) throw std::runtime_error("a rebuilt set differs: " + e.kind);
      }
      e.buildMs = best;
    }
    // Closed, or nearly (a few open edges, e.g. a small hole): the majority of three ray parities
    // is still a sound inside test; the Monte Carlo mesh volume below checks it in every run.
    const bool closed = open * 100 <= 3 * (3 * mesh.size() / 2);  // at most 3% of the edges open
    const double volume = closed ? std::abs(meshVolume(mesh)) : NAN;
    const InsideTest insideTest(mesh);
    auto insideAll = [&](const std::vector<Vec3>& points) {
      std::vector<char> in(points.size(), 0);
      std::vector<std::thread> pool;
      for (unsigned w = 0; w < 2; ++w)
        pool.emplace_back([&, w] {
          for (std::size_t i = w; i < points.size(); i += 2) in[i] = insideTest.inside(points[i]);
        });
      for (auto& t : pool) t.join();
      return in;
    };
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    // Check of the inside test: Monte Carlo volume in the mesh's bounding box against the exact one.
    double mcVolume = NAN;
    if (closed) {
      const Eigen::AlignedBox3d mb = mesh.bounds();
      std::vector<Vec3> pts(s.mcSamples);
      for (auto& p : pts) p = mb.min() + Vec3(unit(rng) * mb.sizes().x(), unit(rng) * mb.sizes().y(), unit(rng) * mb.sizes().z());
      const std::vector<char> in = insideAll(pts);
      mcVolume = mb.volume() * std::count(in.begin(), in.end(), 1) / static_cast<double>(pts.size());
    }
    // Volumes are relative to the inside test's own Monte Carlo mesh volume: the same rule decides
    // what is outside (equal to the exact volume for a closed mesh; see the mc_mesh_volume column).
    const double reference = closed ? mcVolume : NAN;
    const std::vector<Vec3> surface = nearSurfaceProbes(mesh, s.surfaceSamples, 0.0, 13);
    for (const Entry& e : entries) {
      const SphereGrid grid(e.spheres);
      // Union and outside volumes by sampling the spheres themselves: a sphere drawn in proportion to
      // its volume, a point uniform in it, weighted by 1 / (spheres containing it): unbiased, and every
      // sample lands in the union (a box around the spheres would waste most of them).
      std::vector<double> cumulative(e.spheres.radii.size());
      double sphereVolume = 0;
      for (std::size_t i = 0; i < cumulative.size(); ++i) {
        const double r = e.spheres.radii[i];
        sphereVolume += 4.0 / 3.0 * M_PI * r * r * r;
        cumulative[i] = sphereVolume;
      }
      std::vector<Vec3> pts(s.mcSamples);
      std::vector<double> weight(pts.size());
      for (std::size_t j = 0; j < pts.size(); ++j) {
        const std::size_t i = std::min<std::size_t>(
            cumulative.size() - 1, std::lower_bound(cumulative.begin(), cumulative.end(), unit(rng) * sphereVolume) - cumulative.begin());
        Vec3 u;
        do u = Vec3(2 * unit(rng) - 1, 2 * unit(rng) - 1, 2 * unit(rng) - 1);
        while (u.squaredNorm() > 1.0);
        pts[j] = e.spheres.centres[i] + e.spheres.radii[i] * u;
        weight[j] = 1.0 / std::max<std::size_t>(1, grid.count(pts[j]));
      }
      double unionSum = 0, outsideSum = 0;
      std::vector<char> in;
      if (closed) in = insideAll(pts);
      for (std::size_t j = 0; j < pts.size(); ++j) {
        unionSum += weight[j];
        if (closed && !in[j]) outsideSum += weight[j];
      }
      const double unionVolume = sphereVolume * unionSum / pts.size();
      const double outsideVolume = sphereVolume * outsideSum / pts.size();
      std::size_t covered = 0;
      for (const Vec3& p : surface) covered += grid.contains(p);
      run.tight->row(name, mesh.size(), e.d, e.kind, e.spheres.centres.size(), e.depth, num(e.buildMs), open,
                     num(volume), num(mcVolume), num(unionVolume / reference), num(closed ? outsideVolume / reference : NAN),
                     num(sphereVolume / reference), num(static_cast<double>(covered) / surface.size()),
                     surface.size() - covered, pts.size());
    }
    std::cout << "  tightness: " << secondsSince(t0) << " s\n" << std::flush;
  }
  std::cout << "  " << name << " done in " << secondsSince(meshStart) << " s\n" << std::flush;
}

std::string cpuName() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
  return "unknown";
}

std::set<std::string> splitList(const std::string& s) {
  std::set<std::string> out;
  std::stringstream in(s);
  std::string item;
  while (std::getline(in, item, ','))
    if (!item.empty()) out.insert(item);
  return out;
}

// ---------------------------------------------------------------------------------------------
// Contact section (issue 18): the exact query's time on in-contact and free probes apart, and on coherent
// paths over the surface, ours beside Embree and CGAL in the same run; start-up per triangle. Every
// shared mesh and generated models (generated here, deterministic; see bench/README.md).

struct ModelMaker {
  std::string name, kind, source;  // kind: "shared" or "generated"; source: how it was made (no commas)
  std::function<TriangleMesh()> make;
};

TriangleMesh loadNormalised(const std::string& path) {
  MeshLoadOptions options;
  options.normalize = true;
  return loadMesh(path, options);
}

// The generated models: ellipsoids at four edge lengths, uneven density, long thin triangles and (not quick) a
// subdivided shared mesh of about 1M triangles. Filtered by --meshes like the shared ones.
std::vector<ModelMaker> generatedModels(const Settings& s, const fs::path& meshDir) {
  std::vector<ModelMaker> all;
  const Vec3 axes(0.5, 0.4, 0.3), centre = Vec3::Constant(0.5);
  const double r = s.r;
  for (const auto& [label, k] : std::vector<std::pair<std::string, double>>{{"20", 20}, {"5", 5}, {"1", 1}, {"0.1", 0.1}}) {
    // At 0.1 r a unit-size ellipsoid would hold ~18M triangles: that one is a tenth of the size, centred at 0.25
    // (where its local origin stays zero: the peers take model coordinates).
    const bool small = k < 1.0;
    const Vec3 a = small ? Vec3(0.1 * axes) : axes, c = small ? Vec3::Constant(0.25) : centre;
    const std::string name = "ellipsoid-e" + label + "r";
    all.push_back({name, "generated",
                   std::string("ellipsoid ") + (small ? "0.05x0.04x0.03" : "0.5x0.4x0.3") + " cube-sphere; mean edge " +
                       label + " r",
                   [=] { return ellipsoidWithEdge(a, c, k * r, name); }});
  }
  all.push_back({"uneven-16x", "generated",
                 "ellipsoid 0.5x0.4x0.3 at mean edge 10 r; the half x > 0.5 subdivided 4 times (edges 16x shorter)",
                 [=] { return refineHalf(ellipsoidWithEdge(axes, centre, 10 * r, "uneven-16x"), 4, "uneven-16x"); }});
  all.push_back({"slivers-cylinder", "generated", "cylinder radius 0.25 height 1; 1000 full-height side strips; fan caps",
                 [=] { return slicedCylinder(centre, 0.25, 1.0, 1000, "slivers-cylinder"); }});
  const std::string head = (meshDir / "head.off").string();
  if (!s.quick && fs::exists(head))
    all.push_back({"head-x4", "generated", "head.off normalised and subdivided 4 times (subdivide())", [head] {
                     TriangleMesh m = loadNormalised(head);
                     for (int i = 0; i < 4; ++i) m = subdivide(m);
                     return m;
                   }});
  std::vector<ModelMaker> kept;
  for (auto& m : all)
    if (s.meshes.empty() || s.meshes.count(m.name)) kept.push_back(std::move(m));
  return kept;
}

// Ours as the nodes and clod_tool build it: ClodBuilder (the paper's placement, single-link clustering),
// build(d), the grid detector with gridRadius = r (exact queries). Best of the rounds; that build is kept.
struct Ours {
  double placementMs = 0, buildMs = 0, detectorMs = 0;
  // A hierarchy detector on the same set: what the nodes answer with first (~quick_start, the default) while the
  // grid detector is built in the background.
  double quickMs = 0;
  std::size_t quickBytes = 0;
  std::shared_ptr<const ClodSphereSet> set;
  std::unique_ptr<ClodDetector> detector;
  double totalMs() const { return placementMs + buildMs + detectorMs; }
};

Ours buildOurs(const std::shared_ptr<const TriangleMesh>& mesh, const Settings& s) {
  Ours best;
  for (int round = 0; round < std::max(1, s.contactRounds); ++round) {
    Ours o;
    auto t0 = std::chrono::steady_clock::now();
    const ClodBuilder builder(mesh);
    o.placementMs = secondsSince(t0) * 1e3;
    t0 = std::chrono::steady_clock::now();
    o.set = std::make_shared<const ClodSphereSet>(builder.build(s.reportD));
    o.buildMs = secondsSince(t0) * 1e3;
    t0 = std::chrono::steady_clock::now();
    o.detector = std::make_unique<ClodDetector>(mesh, o.set, FastLevel::Grid, s.r);
    o.detectorMs = secondsSince(t0) * 1e3;
    t0 = std::chrono::steady_clock::now();
    const ClodDetector quick(mesh, o.set, FastLevel::Hierarchy, s.r);
    o.quickMs = secondsSince(t0) * 1e3;
    o.quickBytes = quick.bytes();
    if (!best.detector || o.totalMs() < best.totalMs()) best = std::move(o);
  }
  return best;
}

struct ModelInfo {
  std::string name, kind;
  std::size_t triangles = 0, spheres = 0;
};

// Start-up rows: ours (placement + clustering + grid detector) beside Embree's rtcCommitScene (1 and 2
// threads) and CGAL's tree build, each the best of the rounds. Returns the 1-thread Embree and CGAL peers.
std::vector<std::unique_ptr<Peer>> startupRows(Run& run, const ModelInfo& info, const TriangleMesh& mesh, const Ours& ours) {
  const double tri = static_cast<double>(mesh.size());
  auto row = [&](const std::string& who, unsigned threads, double ms, double setupMs, double p, double b, double d,
                 double keptBytes) {
    run.startup->row(info.name, info.kind, mesh.size(), who, threads, num(ms), num(ms * 1e6 / tri),
                     num(tri / (ms * 1e-3)), num(setupMs), num(p), num(b), num(d), info.spheres, num(keptBytes / tri));
  };
  const unsigned ourThreads = std::min(4u, std::max(1u, std::thread::hardware_concurrency()));
  row("clod-grid", ourThreads, ours.totalMs(), ours.totalMs(), ours.placementMs, ours.buildMs, ours.detectorMs,
      static_cast<double>(ours.detector->bytes()));
  const double quickTotal = ours.placementMs + ours.buildMs + ours.quickMs;
  row("clod-quick", ourThreads, quickTotal, quickTotal, ours.placementMs, ours.buildMs, ours.quickMs,
      static_cast<double>(ours.quickBytes));
  const std::vector<std::pair<std::string, int>> contenders{{"embree", 1}, {"embree-2t", 2}, {"cgal", 1}};
  std::vector<std::unique_ptr<Peer>> kept;
  for (const auto& [who, threads] : contenders) {
    std::unique_ptr<Peer> best;
    try {
      for (int round = 0; round < std::max(1, run.s.contactRounds); ++round) {
        auto p = who == "cgal" ? makeCgalPeer(mesh) : makeEmbreePeer(mesh, threads);
        if (!best || p->indexMs < best->indexMs) best = std::move(p);
      }
    } catch (const std::exception& e) {
      std::cout << "  " << who << " failed to build: " << e.what() << "\n";
      continue;
    }
    row(who, threads, best->indexMs, best->buildMs, NAN, NAN, NAN, NAN);
    if (who != "embree-2t") kept.push_back(std::move(best));
  }
  return kept;
}

// A quarter of the probe set: near vertices (even i) and edges (odd i) of triangles drawn uniformly by index,
// offset in a uniform direction by a distance uniform in [0, maxDistance].
std::vector<Vec3> featureProbes(const TriangleMesh& mesh, std::size_t n, double maxDistance, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> gauss;
  std::uniform_int_distribution<std::size_t> pick(0, mesh.size() - 1);
  std::vector<Vec3> out;
  out.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t t = pick(rng);
    const int k = static_cast<int>(rng() % 3);
    Vec3 base = mesh.vertex(t, k);
    if (i % 2) base += unit(rng) * (mesh.vertex(t, (k + 1) % 3) - base);
    Vec3 dir(gauss(rng), gauss(rng), gauss(rng));
    if (!(dir.norm() > 0.0)) dir = Vec3::UnitX();
    out.push_back(mesh.toModel(base) + dir.normalized() * (maxDistance * unit(rng)));
  }
  return out;
}

// The probe set: half within 3r of a face (both sides), a quarter near vertices and edges, a quarter uniform in
// the box grown by r; shuffled, so in-contact and free probes interleave.
std::vector<Vec3> contactProbeSet(const TriangleMesh& mesh, std::size_t n, double r, std::uint64_t seed) {
  std::vector<Vec3> out = nearSurfaceProbes(mesh, n / 2, 3 * r, seed);
  const std::vector<Vec3> feature = featureProbes(mesh, n / 4, 3 * r, seed + 1);
  const std::vector<Vec3> uniform = uniformProbes(mesh, n - n / 2 - n / 4, r, seed + 2);
  out.insert(out.end(), feature.begin(), feature.end());
  out.insert(out.end(), uniform.begin(), uniform.end());
  std::mt19937_64 rng(seed + 3);
  std::shuffle(out.begin(), out.end(), rng);
  return out;
}

// The coherent paths: 1 kHz samples of a walker sliding over the surface at `step` per sample, and a normal
// offset of amplitude 2r at kPathHz (the probe goes in and out of contact). The walker moves in sub-steps of at
// most `subStep` along its heading in the tangent plane, each followed by a return to the nearest surface point
// (`walker` must reach one sub-step), and turns with a curvature swinging between +-1/kTurnRadius every kTurnWave of
// arc; it reverses at a border (a sub-step moving less than a quarter of its length).
constexpr double kPathHz = 2.0, kTurnRadius = 0.05, kTurnWave = 0.3, kModelMetres = 0.15;
const std::vector<double> kPathSpeeds{0.01, 0.1, 0.5, 2.0};  // m/s on the model scaled to 15 cm

Vec3 faceNormalOr(const TriangleMesh& mesh, const ContactResult& c, const Vec3& fallback) {
  if (c.triangle < 0) return fallback;
  const Vec3& n = mesh.normals[static_cast<std::size_t>(c.triangle)];
  return n.isZero(0.0) ? fallback : n;
}

Vec3 tangentOf(const Vec3& v, const Vec3& normal) {
  const Vec3 t = v - v.dot(normal) * normal;
  return t.norm() > 1e-12 ? Vec3(t.normalized()) : Vec3(normal.unitOrthogonal());
}

struct Walker {
  Vec3 q, normal, heading;
  double arc = 0.0;
  // One sub-step of length h; false at a border (the heading is reversed).
  bool move(const TriangleMesh& mesh, const PrunedReference& walker, double h) {
    const double turn = h / kTurnRadius * std::sin(2.0 * M_PI * arc / kTurnWave);
    heading = std::cos(turn) * heading + std::sin(turn) * normal.cross(heading);
    const ContactResult next = walker.query(q + h * heading);
    const double moved = next.contact ? (next.point - q).norm() : 0.0;
    if (moved < 0.25 * h) {
      heading = -heading;
      return false;
    }
    arc += moved;
    q = next.point;
    normal = faceNormalOr(mesh, next, normal);
    heading = tangentOf(heading, normal);
    return true;
  }
};

std::vector<Vec3> surfacePath(const TriangleMesh& mesh, const PrunedReference& walker, double step, double subStep,
                              std::size_t n, double amplitude, std::uint64_t seed) {
  Walker w;
  w.q = nearSurfaceProbes(mesh, 1, 0.0, seed)[0];
  w.normal = faceNormalOr(mesh, walker.query(w.q), Vec3::UnitZ());
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss;
  w.heading = tangentOf(Vec3(gauss(rng), gauss(rng), gauss(rng)), w.normal);
  const int parts = std::max(1, static_cast<int>(std::ceil(step / subStep)));
  std::vector<Vec3> out;
  out.reserve(n);
  for (std::size_t k = 0; k < n; ++k) {
    out.push_back(w.q + amplitude * std::sin(2.0 * M_PI * kPathHz * 1e-3 * k) * w.normal);
    for (int j = 0; j < parts; ++j)
      if (!w.move(mesh, walker, step / parts)) break;
  }
  return out;
}

// Every probe timed alone for each contender, the contenders alternating over the rounds; per contender the
// round with the lowest mean is kept, with its answers.
struct Timed {
  std::vector<float> ns;
  std::vector<Answer> answers;
  double mean = std::numeric_limits<double>::infinity();
};

std::map<std::string, Timed> timeContenders(const std::vector<const Peer*>& peers, const std::vector<Vec3>& points,
                                            const Settings& s) {
  std::map<std::string, Timed> best;
  for (int round = 0; round < std::max(1, s.contactRounds); ++round)
    for (const Peer* peer : peers) {
      std::vector<Answer> answers(points.size());
      Timing t = timeEach(
          points.size(), 1e6, points.size(),
          [&](std::size_t i) {
            peer->query(points[i], s.r, answers[i]);
            benchmark::DoNotOptimize(answers[i]);
          },
          [&] { peer->startStream(); });
      Timed& b = best[peer->name()];
      if (t.mean < b.mean) b = Timed{std::move(t.ns), std::move(answers), t.mean};
    }
  return best;
}

// Two contenders timed on the same points interleaved, point by point, the one going first alternating (by point
// and by round): what one adds to or saves over the other, without the drift between two runs, which on the
// coherent paths was as large as the cache's effect (degtri_sliding at 2 m/s: 0.77 contender after contender, 1.01
// interleaved). Per contender the round with the lowest summed mean is kept, with its answers.
std::pair<Timed, Timed> timePaired(const Peer& a, const Peer& b, const std::vector<Vec3>& points, const Settings& s) {
  std::pair<Timed, Timed> best;
  double bestSum = std::numeric_limits<double>::infinity();
  for (int round = 0; round < std::max(1, s.contactRounds); ++round) {
    Timed ta, tb;
    ta.ns.resize(points.size());
    tb.ns.resize(points.size());
    ta.answers.resize(points.size());
    tb.answers.resize(points.size());
    a.startStream();
    b.startStream();
    auto timeOne = [&](const Peer& peer, Timed& t, std::size_t i) {
      t.ns[i] = fencedNs([&] { peer.query(points[i], s.r, t.answers[i]); });
      benchmark::DoNotOptimize(t.answers[i]);
    };
    for (std::size_t i = 0; i < points.size(); ++i) {
      if ((i + static_cast<std::size_t>(round)) & 1) {
        timeOne(a, ta, i);
        timeOne(b, tb, i);
      } else {
        timeOne(b, tb, i);
        timeOne(a, ta, i);
      }
    }
    double sa = 0.0, sb = 0.0;
    for (std::size_t i = 0; i < points.size(); ++i) {
      sa += ta.ns[i];
      sb += tb.ns[i];
    }
    ta.mean = sa / static_cast<double>(std::max<std::size_t>(1, points.size()));
    tb.mean = sb / static_cast<double>(std::max<std::size_t>(1, points.size()));
    if (ta.mean + tb.mean < bestSum) {
      bestSum = ta.mean + tb.mean;
      best = {std::move(ta), std::move(tb)};
    }
  }
  return best;
}

// One contact.csv row: the statistics of the contender's times on the probes `idx`, its answers against `ref`
// (contact flag; distance and point to 1e-9); prints the first mismatches.
Stats contactRow(Run& run, const ModelInfo& info, const std::string& cls, const std::string& who, const Timed& t,
                 const std::vector<Vec3>& points, const std::vector<ContactResult>& ref, const std::vector<std::size_t>& idx) {
  std::vector<float> ns;
  ns.reserve(idx.size());
  std::size_t mismatches = 0, contacts = 0;
  double maxDiff = 0.0;
  for (std::size_t i : idx) {
    ns.push_back(t.ns[i]);
    const Answer& a = t.answers[i];
    const ContactResult& f = ref[i];
    contacts += f.contact;
    const double dd = a.contact && f.contact ? std::abs(a.distance - f.distance) : 0.0;
    maxDiff = std::max(maxDiff, dd);
    if (a.contact == f.contact && (!f.contact || (dd <= 1e-9 && (a.point - f.point).norm() <= 1e-9))) continue;
    if (++mismatches <= 5)
      std::cout << "  MISMATCH " << info.name << " " << cls << " " << who << " probe " << i << " (" << points[i].transpose()
                << "): reference " << f.contact << " d=" << f.distance << ", answer " << a.contact << " d=" << a.distance << "\n";
  }
  const Stats st = statsOf(std::move(ns));
  run.contact->row(info.name, info.kind, info.triangles, info.spheres, cls, who, idx.size(), contacts, num(st.mean),
                   num(st.median), num(st.p90), num(st.p99), num(st.max), mismatches, num(maxDiff));
  return st;
}

void printRatios(const std::string& label, const std::map<std::string, Stats>& st, const std::string& ours) {
  std::cout << "  " << label << ": " << ours << " mean " << st.at(ours).mean << " p99 " << st.at(ours).p99 << " ns";
  for (const auto& [who, x] : st)
    if (who != ours)
      std::cout << "; " << who << " " << x.mean << " / " << x.p99 << " (x" << x.mean / st.at(ours).mean << " / x"
                << x.p99 / st.at(ours).p99 << ")";
  std::cout << "\n" << std::flush;
}

// The probe set's rows, in-contact and free apart. Returns the number of in-contact probes.
std::size_t probeRows(Run& run, const ModelInfo& info, const TriangleMesh& mesh, const PrunedReference& reference,
                      const std::vector<const Peer*>& peers) {
  const std::vector<Vec3> probes = contactProbeSet(mesh, run.s.probes, run.s.r, 31);
  const std::vector<ContactResult> ref = reference.queryAll(probes, 2);
  std::vector<std::size_t> in, out;
  for (std::size_t i = 0; i < probes.size(); ++i) (ref[i].contact ? in : out).push_back(i);
  const auto timed = timeContenders(peers, probes, run.s);
  for (const auto& [cls, idx] : {std::make_pair(std::string("contact"), &in), std::make_pair(std::string("free"), &out)}) {
    std::map<std::string, Stats> st;
    for (const Peer* p : peers) st[p->name()] = contactRow(run, info, cls, p->name(), timed.at(p->name()), probes, ref, *idx);
    printRatios(cls + " (" + std::to_string(idx->size()) + ")", st, "clod-grid");
  }
  return in.size();
}

// The coherent paths' rows, one per speed: the cached contender against the stream's reference, the others
// against the stateless one; on all the points, and on the shallow ones (without the points where the stream
// follows the push deeper than r, which only the cached contender answers as contacts).
void pathRows(Run& run, const ModelInfo& info, const TriangleMesh& mesh, const PrunedReference& reference,
              const std::vector<const Peer*>& peers) {
  const Settings& s = run.s;
  const double subStep = 0.5 * s.r;
  const PrunedReference walker(mesh, 1.02 * subStep);
  const PrunedReference deep(mesh, 2.02 * s.r);  // a path point lies within 2r of the surface point it was placed at
  for (std::size_t k = 0; k < kPathSpeeds.size(); ++k) {
    const auto t0 = std::chrono::steady_clock::now();
    const double step = kPathSpeeds[k] * 1e-3 / kModelMetres;
    const std::vector<Vec3> path = surfacePath(mesh, walker, step, subStep, s.probes, 2 * s.r, 41 + k);
    const std::vector<ContactResult> stateless = reference.queryAll(path, 2);
    const std::vector<ContactResult> stream = streamReference(mesh, path, stateless, deep, s.r);
    std::cout << "  path " << kPathSpeeds[k] << " m/s made and referenced in " << secondsSince(t0) << " s\n";
    const auto timed = timeContenders(peers, path, s);
    std::vector<std::size_t> all(path.size()), shallow;
    std::iota(all.begin(), all.end(), 0);
    for (std::size_t i : all)
      if (stream[i].contact == stateless[i].contact) shallow.push_back(i);
    const std::string cls = "path-" + fmt(kPathSpeeds[k]);
    for (const auto& [name, idx] : {std::make_pair(cls, &all), std::make_pair(cls + "-shallow", &shallow)}) {
      std::map<std::string, Stats> st;
      for (const Peer* p : peers) {
        const bool cached = p->name() == "clod-grid-cache";
        st[p->name()] = contactRow(run, info, name, p->name(), timed.at(p->name()), path, cached ? stream : stateless, *idx);
      }
      printRatios(name + " (" + std::to_string(idx->size()) + ")", st, "clod-grid-cache");
    }
    // The cache against the stateless query interleaved (timePaired), on the shallow points: rows named "-paired".
    const Peer* grid = nullptr;
    const Peer* cached = nullptr;
    for (const Peer* p : peers) {
      if (p->name() == "clod-grid") grid = p;
      if (p->name() == "clod-grid-cache") cached = p;
    }
    if (grid != nullptr && cached != nullptr) {
      const auto paired = timePaired(*grid, *cached, path, s);
      std::map<std::string, Stats> st;
      st["clod-grid-paired"] =
          contactRow(run, info, cls + "-shallow", "clod-grid-paired", paired.first, path, stateless, shallow);
      st["clod-grid-cache-paired"] =
          contactRow(run, info, cls + "-shallow", "clod-grid-cache-paired", paired.second, path, stream, shallow);
      printRatios(cls + "-shallow interleaved", st, "clod-grid-cache-paired");
    }
  }
}

void contactModel(Run& run, const ModelMaker& maker) {
  const Settings& s = run.s;
  const auto start = std::chrono::steady_clock::now();
  const auto mesh = std::make_shared<const TriangleMesh>(maker.make());
  if (!mesh->origin.isZero(0.0)) throw std::runtime_error("a local origin (the peers take model coordinates)");
  const std::vector<double> aspect = aspectRatios(*mesh);
  std::cout << "== contact " << maker.name << ": " << mesh->size() << " triangles, mean edge " << meanEdge(*mesh) / s.r
            << " r\n" << std::flush;
  const Ours ours = buildOurs(mesh, s);
  const ModelInfo info{maker.name, maker.kind, mesh->size(), ours.set->size()};
  const std::vector<std::unique_ptr<Peer>> others = startupRows(run, info, *mesh, ours);
  std::cout << "  start-up: ours " << ours.totalMs() << " ms (" << ours.set->size() << " spheres), all at "
            << secondsSince(start) << " s\n";
  const ClodPeer grid(*ours.detector, "clod-grid"), cached(*ours.detector, "clod-grid-cache", true);
  std::vector<const Peer*> peers{&grid};
  for (const auto& p : others) peers.push_back(p.get());
  const PrunedReference reference(*mesh, s.r);
  const std::size_t contacts = probeRows(run, info, *mesh, reference, peers);
  std::cout << "  probes done at " << secondsSince(start) << " s\n";
  peers.insert(peers.begin() + 1, &cached);
  pathRows(run, info, *mesh, reference, peers);
  run.models->row(info.name, info.kind, "\"" + maker.source + "\"", info.triangles, info.spheres, num(meanEdge(*mesh) / s.r),
                  num(aspect.empty() ? NAN : *std::min_element(aspect.begin(), aspect.end())),
                  num(statsOf(std::vector<float>(aspect.begin(), aspect.end())).median), openEdges(*mesh), s.probes,
                  contacts, s.probes, num(secondsSince(start)));
  std::cout << "  " << maker.name << " done in " << secondsSince(start) << " s\n" << std::flush;
}

std::string loadAverage() {
  std::ifstream in("/proc/loadavg");
  std::string a, b, c;
  in >> a >> b >> c;
  return a + " " + b + " " + c;
}

void contactSection(Run& run, const std::vector<std::string>& sharedPaths, const fs::path& meshDir) {
  const Settings& s = run.s;
  const std::string o = s.out + "/";
  run.contact = std::make_unique<Csv>(o + "contact.csv",
                                      "model,kind,triangles,spheres,class,contender,n,ref_contacts,mean_ns,median_ns,"
                                      "p90_ns,p99_ns,max_ns,mismatches,max_dist_diff");
  run.startup = std::make_unique<Csv>(o + "startup.csv",
                                      "model,kind,triangles,contender,threads,ms,ns_per_tri,tri_per_s,setup_ms,"
                                      "placement_ms,build_ms,detector_ms,spheres,detector_bytes_per_tri");
  run.models = std::make_unique<Csv>(o + "contact_models.csv",
                                     "model,kind,source,triangles,spheres,mean_edge_over_r,min_aspect,median_aspect,"
                                     "open_edges,probes,probe_contacts,path_points,seconds");
  std::vector<ModelMaker> models;
  for (const std::string& path : sharedPaths)
    models.push_back({fs::path(path).filename().string(), "shared", "../shared/data/meshes normalised to the unit cube",
                      [path] { return loadNormalised(path); }});
  for (auto& m : generatedModels(s, meshDir)) models.push_back(std::move(m));
  const std::string loadBefore = loadAverage();
  const auto start = std::chrono::steady_clock::now();
  for (const ModelMaker& m : models) {
    try {
      contactModel(run, m);
    } catch (const std::exception& e) {
      std::cout << "  contact: FAILED on " << m.name << ": " << e.what() << "\n" << std::flush;
    }
  }
  std::ofstream meta(o + "contact_run.csv");
  const std::time_t now = std::time(nullptr);
  char stamp[64];
  std::strftime(stamp, sizeof stamp, "%Y-%m-%d %H:%M UTC", std::gmtime(&now));
  meta << "key,value\ndate," << stamp << "\ncpu,\"" << cpuName() << "\"\nhardware_threads,"
       << std::thread::hardware_concurrency() << "\nmode," << (s.quick ? "quick" : "full") << "\nseconds," << secondsSince(start)
       << "\nloadavg_before," << loadBefore << "\nloadavg_after," << loadAverage() << "\nradius," << s.r << "\nd,"
       << s.reportD << "\nprobes," << s.probes << "\npath_points," << s.probes << "\nrounds," << s.contactRounds
       << "\npath_amplitude," << 2 * s.r << "\npath_hz," << kPathHz << "\nmodel_metres," << kModelMetres << "\n";
}

}  // namespace

int main(int argc, char** argv) {
  Run run;
  Settings& s = run.s;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::cerr << "missing value after " << a << "\n";
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--quick") {
      s.quick = true;
    } else if (a == "--shared") {
      s.shared = next();
    } else if (a == "--out") {
      s.out = next();
    } else if (a == "--meshes") {
      s.meshes = splitList(next());
    } else if (a == "--sections") {
      s.sections = splitList(next());
    } else {
      std::cerr << "usage: clod_bench --shared DIR --out DIR [--quick] [--meshes a.off,b.off] "
                   "[--sections sweep,spheres,peers,tightness,growth,contact,proxy]\n";
      return 2;
    }
  }
  if (s.shared.empty() || s.out.empty()) {
    std::cerr << "clod_bench: --shared and --out are required\n";
    return 2;
  }
  if (s.quick) {
    s.probes = 10000;
    s.budgetHierarchy = 0.5;
    s.budgetFlat = 0.1;
    s.budgetBrute = 0.5;
    s.bruteMax = 300;
    s.rounds = 1;
    s.contactRounds = 1;
    s.mcSamples = 20000;
    s.surfaceSamples = 30000;
    s.growthLimit = 120000;
    s.growthProbes = 5000;
  }
  fs::create_directories(s.out);
  Clock::calibrate();
  const auto start = std::chrono::steady_clock::now();

  std::vector<std::string> meshes;
  const fs::path meshDir = fs::path(s.shared) / "data" / "meshes";
  if (!fs::is_directory(meshDir)) {
    std::cerr << "clod_bench: no mesh directory " << meshDir << " (set --shared, or CLOD_SHARED_DIR for make bench)\n";
    return 2;
  }
  for (const auto& entry : fs::directory_iterator(meshDir))
    if (entry.path().extension() == ".off" && (s.meshes.empty() || s.meshes.count(entry.path().filename().string())))
      meshes.push_back(entry.path().string());
  std::sort(meshes.begin(), meshes.end(), [](const std::string& a, const std::string& b) {
    return fs::file_size(a) < fs::file_size(b);  // small first: early figures come fast
  });

  const std::string bag = (fs::path(s.shared) / "data" / "bags" / "geomagic_touch_2016-11-29.bag").string();
  std::string error;
  double seconds = 0;
  std::size_t messages = 0;
  run.trajectory = readTrajectory(bag, "/Geomagic/end_effector_pose", 1000.0, error, seconds, messages);
  if (run.trajectory.empty()) {
    run.trajectoryNote = "trajectory unavailable: " + error;
  } else {
    run.trajectoryNote = std::to_string(messages) + " messages over " + fmt(seconds) + " s resampled to " +
                         std::to_string(run.trajectory.size()) + " points at 1 kHz";
  }
  std::cout << "clod_bench: " << (s.quick ? "quick" : "full") << " run, " << meshes.size() << " meshes, "
            << run.trajectoryNote << ", " << Clock::nsPerTick << " ns/tick, timer overhead "
            << Clock::overheadTicks * Clock::nsPerTick << " ns\n" << std::flush;

  const std::string o = s.out + "/";
  // run.csv, build.csv and reference_check.csv describe the per-mesh sections: a run of only the contact or
  // proxy section (which write their own run notes) leaves them as the last full run wrote them.
  const bool perMesh = has(s, "sweep") || has(s, "spheres") || has(s, "peers") || has(s, "tightness");
  if (perMesh) {
    std::ofstream meta(o + "run.csv");
    const std::time_t now = std::time(nullptr);
    char stamp[64];
    std::strftime(stamp, sizeof stamp, "%Y-%m-%d %H:%M UTC", std::gmtime(&now));
    char host[256] = {0};
    gethostname(host, sizeof host - 1);
    meta << "key,value\n"
         << "date," << stamp << "\nmode," << (s.quick ? "quick" : "full") << "\ncpu,\"" << cpuName()
         << "\"\nhardware_threads," << std::thread::hardware_concurrency() << "\nhost," << host
         << "\nradius," << s.r << "\nprobes_per_set," << s.probes << "\nnear_offset," << 3 * s.r
         << "\nuniform_margin," << s.r << "\ntrajectory,\"" << run.trajectoryNote << "\"\nns_per_tick,"
         << Clock::nsPerTick << "\ntimer_overhead_ns," << Clock::overheadTicks * Clock::nsPerTick
         << "\nreport_d," << s.reportD << "\nrounds," << s.rounds << "\nloadavg_before," << loadAverage() << "\n";
    run.build = std::make_unique<Csv>(o + "build.csv",
                                      "mesh,triangles,d,centres,spheres,step_reduction,total_reduction,placement_ms,"
                                      "build_ms,max_tris_per_sphere,mean_tris_per_sphere,unpaired,degenerate,open_edges");
    run.checks = std::make_unique<Csv>(o + "reference_check.csv", "mesh,set,probes,differences_from_bruteForceQuery");
  }
  if (has(s, "sweep"))
    run.sweep = std::make_unique<Csv>(
        o + "sweep.csv",
        "mesh,triangles,d,spheres,level,mode,set,probes,median_ns,mean_ns,trimmed_mean_ns,p10_ns,p90_ns,p99_ns,ref_contacts,contacts,"
        "missed,false_contacts,mean_dist_err,max_dist_err,mean_normal_err_deg,max_normal_err_deg,max_point_err,"
        "mean_spheres_hit,mean_tris_tested,detector_build_ms,contact_diff_vs_hierarchy,distance_diff_vs_hierarchy");
  if (has(s, "spheres"))
    run.spheresMode = std::make_unique<Csv>(
        o + "spheres_mode.csv",
        "mesh,triangles,d,spheres,level,set,probes,spheres_median_ns,spheres_mean_ns,exact_median_ns,exact_mean_ns,"
        "median_ratio,exact_contacts,spheres_contacts,false_contacts,false_contact_rate,missed,exact_errors,"
        "mean_spheres_read");
  if (has(s, "peers"))
    run.peers = std::make_unique<Csv>(o + "peers.csv",
                                      "mesh,triangles,d,spheres,set,peer,probes,median_ns,mean_ns,p90_ns,p99_ns,"
                                      "disagreements,max_dist_diff,build_ms,reference,deep_probes,shallow_median_ns,"
                                      "shallow_mean_ns,deep_median_ns,deep_mean_ns,deep_free_probes");
  if (has(s, "tightness"))
    run.tight = std::make_unique<Csv>(o + "tightness.csv",
                                      "mesh,triangles,d,kind,spheres,octree_depth,build_ms,open_edges,mesh_volume,"
                                      "mc_mesh_volume,union_volume_rel,outside_volume_rel,sum_sphere_volume_rel,"
                                      "surface_covered,surface_gaps,mc_samples");

  // Growth first: each point runs in a forked child of this still single-threaded process.
  if (has(s, "growth")) {
    run.growth = std::make_unique<Csv>(o + "growth.csv",
                                       "mesh,subdivisions,triangles,spheres,placement_ms,build_ms,detector_ms,"
                                       "build_tri_per_s,median_ns,mean_ns,peak_bytes_per_tri,retained_bytes_per_tri,"
                                       "set_bytes_per_tri,peak_reset,checked,mismatches,detector_level,detector_heap_bytes_per_tri,"
                                       "detector_peak_bytes_per_tri,builder_peak_bytes_per_tri,hierarchy_detector_ms,"
                                       "hierarchy_detector_heap_bytes_per_tri");
    for (const std::string& path : meshes) {
      MeshLoadOptions options;
      options.normalize = true;
      std::size_t n = 0;
      try {
        const TriangleMesh m = loadMesh(path, options);
        if (m.size() < 2000) continue;  // the real models only (not the small fixtures)
        n = m.size();
      } catch (const ClodError&) {
        continue;
      }
      const std::string name = fs::path(path).filename().string();
      for (int level = 0; n <= s.growthLimit; ++level, n *= 4) {
        const GrowthPoint g = growthForked(path, level, s);
        if (!g.ok) {
          std::cout << "  growth " << name << " x" << level << ": failed\n";
          break;
        }
        const double tri = static_cast<double>(g.triangles);
        run.growth->row(name, level, g.triangles, g.spheres, num(g.placementMs), num(g.buildMs), num(g.detectorMs),
                        num(tri / ((g.placementMs + g.buildMs) * 1e-3)), num(g.medianNs), num(g.meanNs),
                        num(g.peakBytes / tri), num(g.retainedBytes / tri), num(g.setBytes / tri), g.peakReset ? 1 : 0,
                        g.checked, g.mismatches, "grid", num(g.detectorHeapBytes / tri), num(g.detectorPeakBytes / tri),
                        num(g.builderPeakBytes / tri), num(g.hierarchyMs), num(g.hierarchyHeapBytes / tri));
        std::cout << "  growth " << name << " " << g.triangles << " tris: build " << g.placementMs + g.buildMs
                  << " ms, detector " << g.detectorMs << " ms " << g.detectorHeapBytes / tri << " B/tri, query " << g.medianNs
                  << " ns, peak " << g.peakBytes / tri << " B/tri\n"
                  << std::flush;
      }
    }
  }

  for (const std::string& path : perMesh ? meshes : std::vector<std::string>{}) {
    try {
      benchMesh(run, path);
    } catch (const std::exception& e) {  // one mesh failing (a core change, a bad file) must not stop the others
      std::cout << "  FAILED on " << path << ": " << e.what() << "\n" << std::flush;
    }
  }
  if (has(s, "contact")) contactSection(run, meshes, meshDir);
  if (has(s, "proxy")) proxySection(meshes, s.out, s.quick, run.trajectory);
  // The whole run's length, its sections and the load after it (other jobs share the machine): added to run.csv.
  std::string sections;
  for (const std::string& x : s.sections) sections += (sections.empty() ? "" : " ") + x;
  if (perMesh)
    std::ofstream(o + "run.csv", std::ios::app) << "seconds," << secondsSince(start) << "\nloadavg_after,"
                                                 << loadAverage() << "\nsections," << sections << "\n";
  std::cout << "clod_bench: done in " << secondsSince(start) << " s\n";
  return 0;
}
