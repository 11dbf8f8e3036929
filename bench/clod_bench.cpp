// clod_bench: run time against error for every mesh and CLOD level, beside the peers (Embree,
// CGAL, FCL, brute force) on the same probes, sphere tightness against an octree, and growth with
// the triangle count. Writes CSV files for bench/report.py. A benchmark, never a test.
//
//   clod_bench --shared ../shared --out bench/results [--quick] [--meshes a.off,b.off]
//              [--sections sweep,peers,tightness,growth]

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
#include <iostream>
#include <limits>
#include <map>
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
  std::set<std::string> sections{"sweep", "peers", "tightness", "growth"};
  double r = 0.005;
  std::vector<double> distances{0.0, 0.01, 0.02, 0.03, 0.04, 0.05, 0.06, 0.07, 0.08};
  std::size_t probes = 100000;          // per probe set (near-surface, uniform)
  double budgetHierarchy = 2.0;         // seconds per (level, mode, probe set) of the sweep
  double budgetFlat = 0.4;              // the flat list at small d costs milliseconds per query
  double budgetBrute = 3.0;             // seconds per probe set for the brute-force peer
  std::size_t bruteMax = 2000;          // and at most this many probes
  int rounds = 2;                       // peer comparison: alternate contenders, keep the best median
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
    _mm_lfence();
    const std::uint64_t a = __rdtsc();
    _mm_lfence();
    f(i);
    _mm_lfence();
    const std::uint64_t b = __rdtsc();
    _mm_lfence();
    t.ns.push_back(static_cast<float>(std::max(0.0, (static_cast<double>(b - a) - Clock::overheadTicks) * Clock::nsPerTick)));
    if (i + 1 >= minCount && (i & 63) == 63 && b - begin > budgetTicks) break;
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
  std::vector<ContactResult> ref;
};

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
  std::unique_ptr<Csv> build, sweep, peers, tight, growth, checks;
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
  sets.push_back({"near", nearSurfaceProbes(mesh, s.probes, 3 * s.r, 1), {}});
  sets.push_back({"uniform", uniformProbes(mesh, s.probes, s.r, 2), {}});
  if (!run.trajectory.empty()) sets.push_back({"trajectory", placeOver(run.trajectory, mesh), {}});
  {
    ProbeSet m{"near-morton", sets[0].points, {}};
    sortMorton(m.points);
    sets.push_back(std::move(m));
  }
  auto t0 = std::chrono::steady_clock::now();
  PrunedReference reference(mesh, s.r);
  for (auto& set : sets) set.ref = reference.queryAll(set.points, 2);
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
    for (auto make : {makeEmbreePeer, makeCgalPeer, makeFclPeer}) {
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
          double md = 0;
          const std::size_t b = disagreements(answers, probeSet.ref, t.ns.size(), md);
          if (!best.count(peer->name()) || t.median < best[peer->name()].median) best[peer->name()] = std::move(t);
          bad[peer->name()] = std::max(bad[peer->name()], b);
          maxDiff[peer->name()] = std::max(maxDiff[peer->name()], md);
        }
      }
      for (auto& peer : peers) {
        const Timing& t = best[peer->name()];
        run.peers->row(name, mesh.size(), s.reportD, set->size(), probeSet.name, peer->name(), t.ns.size(), num(t.median),
                       num(t.mean), num(t.p90), num(t.p99), bad[peer->name()], num(maxDiff[peer->name()]),
                       num(peer->buildMs));
      }
      const auto& bt = bruteTimes[probeSet.name];
      run.peers->row(name, mesh.size(), s.reportD, set->size(), probeSet.name, "brute", bt.first.ns.size(),
                     num(bt.first.median), num(bt.first.mean), num(bt.first.p90), num(bt.first.p99), bt.second, 0, 0);
      // Ours: the grid, with its cache on the stylus trajectory (a coherent stream).
      const std::string ours = probeSet.name == "trajectory" ? "clod-grid-cache" : "clod-grid";
      std::cout << "  peers on " << probeSet.name << ": " << ours << " " << best[ours].median << " ns";
      for (auto& peer : peers)
        if (peer->name() != ours)
          std::cout << ", " << peer->name() << " " << best[peer->name()].median << " ns (x"
                    << best[peer->name()].median / std::max(1e-9, best[ours].median) << ")";
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
                   "[--sections sweep,peers,tightness,growth]\n";
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
  {
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
         << "\nreport_d," << s.reportD << "\nrounds," << s.rounds << "\n";
  }
  run.build = std::make_unique<Csv>(o + "build.csv",
                                    "mesh,triangles,d,centres,spheres,step_reduction,total_reduction,placement_ms,build_ms,"
                                    "max_tris_per_sphere,mean_tris_per_sphere,unpaired,degenerate,open_edges");
  run.checks = std::make_unique<Csv>(o + "reference_check.csv", "mesh,set,probes,differences_from_bruteForceQuery");
  if (has(s, "sweep"))
    run.sweep = std::make_unique<Csv>(
        o + "sweep.csv",
        "mesh,triangles,d,spheres,level,mode,set,probes,median_ns,mean_ns,trimmed_mean_ns,p10_ns,p90_ns,p99_ns,ref_contacts,contacts,"
        "missed,false_contacts,mean_dist_err,max_dist_err,mean_normal_err_deg,max_normal_err_deg,max_point_err,"
        "mean_spheres_hit,mean_tris_tested,detector_build_ms,contact_diff_vs_hierarchy,distance_diff_vs_hierarchy");
  if (has(s, "peers"))
    run.peers = std::make_unique<Csv>(o + "peers.csv",
                                      "mesh,triangles,d,spheres,set,peer,probes,median_ns,mean_ns,p90_ns,p99_ns,"
                                      "disagreements,max_dist_diff,build_ms");
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

  for (const std::string& path : meshes) {
    try {
      benchMesh(run, path);
    } catch (const std::exception& e) {  // one mesh failing (a core change, a bad file) must not stop the others
      std::cout << "  FAILED on " << path << ": " << e.what() << "\n" << std::flush;
    }
  }
  std::cout << "clod_bench: done in " << secondsSince(start) << " s\n";
  return 0;
}
