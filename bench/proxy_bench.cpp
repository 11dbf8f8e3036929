// The proxy section of clod_bench (see proxy_bench.h). Every model in metres at the stylus scale.
#include "proxy_bench.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <memory>
#include <random>
#include <sstream>

#include "bench_common.h"
#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/detector.h"
#include "clod_haptics/core/haptic_renderer.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/probes.h"
#include "clod_haptics/core/sphere_set.h"

namespace clod_bench {
namespace {

using namespace clod_haptics;

constexpr double kR = 0.002;          // pointer radius (the shipped launch file)
constexpr double kStiffness = 400.0;  // N/m (the shipped launch file)
constexpr double kDt = 1e-3;          // 1 kHz
constexpr double kSharedSize = 0.15;  // shared meshes scaled from the unit cube to 15 cm
constexpr double kSmallSize = 0.04;   // and to 4 cm (a tooth, a figurine): triangles smaller than the stylus
constexpr double kSpeeds[] = {0.05, 0.5, 2.0};

}  // namespace

std::unique_ptr<Model> prepare(std::string name, std::string kind, double sizeMm, TriangleMesh mesh) {
  auto m = std::make_unique<Model>();
  m->name = std::move(name);
  m->kind = std::move(kind);
  m->sizeMm = sizeMm;
  m->mesh = std::make_shared<const TriangleMesh>(std::move(mesh));
  auto set = std::make_shared<const ClodSphereSet>(ClodBuilder(m->mesh).build(0.003));  // the launch file's d
  m->detector = std::make_shared<const ClodDetector>(m->mesh, set, FastLevel::Grid, kR);
  m->scene.add(std::make_shared<const SweptSphereQuery>(m->mesh, m->detector), Eigen::Isometry3d::Identity());
  return m;
}

namespace {

// Several closed pieces in one mesh (overlapping where they join, as a modeller's antler would).
TriangleMesh joined(const std::vector<TriangleMesh>& parts, const std::string& name) {
  std::vector<Vec3> v;
  std::vector<Triangle> t;
  for (const TriangleMesh& p : parts) {
    const std::uint32_t base = static_cast<std::uint32_t>(v.size());
    for (const Vec3& x : p.vertices) v.push_back(p.toModel(x));
    for (const Triangle& tri : p.triangles) t.push_back({tri[0] + base, tri[1] + base, tri[2] + base});
  }
  return makeMesh(std::move(v), std::move(t), name);
}

TriangleMesh transformed(const TriangleMesh& m, const Eigen::Isometry3d& pose, const std::string& name) {
  std::vector<Vec3> v;
  for (const Vec3& x : m.vertices) v.push_back(pose * m.toModel(x));
  return makeMesh(std::move(v), m.triangles, name);
}

// A trunk of radius 1.5 mm along z and three branches of 1 mm leaning out of it.
TriangleMesh antler() {
  std::vector<TriangleMesh> parts{slicedCylinder(Vec3::Zero(), 0.0015, 0.06, 24, "trunk")};
  const double heights[] = {-0.015, 0.0, 0.015}, angles[] = {0.7, 2.8, 4.9};
  for (int i = 0; i < 3; ++i) {
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.linear() =
        (Eigen::AngleAxisd(angles[i], Vec3::UnitZ()) * Eigen::AngleAxisd(0.8, Vec3::UnitX())).toRotationMatrix();
    pose.translation() = Vec3(0, 0, heights[i]) + pose.linear() * Vec3(0, 0, 0.014);
    parts.push_back(transformed(slicedCylinder(Vec3::Zero(), 0.001, 0.03, 16, "branch"), pose, "branch"));
  }
  return joined(parts, "antler");
}

}  // namespace

std::unique_ptr<Model> fineEllipsoid(double edge) {
  std::ostringstream name;
  name << "ellipsoid-edge-" << edge << "r";
  return prepare(name.str(), "fine", edge * kR * 1e3,
                 ellipsoidWithEdge(Vec3(0.015, 0.012, 0.009), Vec3::Zero(), edge * kR, name.str()));
}

std::vector<std::unique_ptr<Model>> thinModels() {
  std::vector<std::unique_ptr<Model>> out;
  for (double t : {0.5, 1.0, 2.0, 3.0, 5.0}) {  // square plates 60 mm wide, t thick (a four-sided prism)
    std::ostringstream name;
    name << "plate-" << t << "mm";
    out.push_back(
        prepare(name.str(), "plate", t, slicedCylinder(Vec3::Zero(), 0.03 * std::sqrt(2.0), t * 1e-3, 4, name.str())));
  }
  for (double d : {1.5, 3.0}) {  // legs: cylinders along z
    std::ostringstream name;
    name << "cylinder-" << d << "mm";
    out.push_back(prepare(name.str(), "cylinder", d, slicedCylinder(Vec3::Zero(), 0.5e-3 * d, 0.06, 24, name.str())));
  }
  out.push_back(prepare("antler", "antler", 3.0, antler()));
  // Finely tessellated surfaces at the stylus's scale (a high-resolution scan): an ellipsoid of semi-axes 15, 12 and
  // 9 mm with edges of 0.25 r and 0.1 r (19k and 122k triangles), where every cell of the grid lists thousands.
  for (double edge : {0.25, 0.1}) out.push_back(fineEllipsoid(edge));
  return out;
}

std::unique_ptr<Model> sharedModel(const std::string& path, double size) {
  MeshLoadOptions options;
  options.normalize = true;
  const TriangleMesh unit = loadMesh(path, options);
  std::vector<Vec3> v;
  for (const Vec3& x : unit.vertices) v.push_back(unit.toModel(x) * size);
  std::string name = std::filesystem::path(path).filename().string();
  if (std::lround(size * 1e3) != std::lround(kSharedSize * 1e3))
    name += "@" + std::to_string(static_cast<int>(std::lround(size * 1e3))) + "mm";
  return prepare(name, "shared", 0.0, makeMesh(std::move(v), unit.triangles, name));
}

std::unique_ptr<Model> sharedModel(const std::string& path) { return sharedModel(path, kSharedSize); }

namespace {

// Device points from a to b at speed, one per tick.
std::vector<Vec3> line(const Vec3& a, const Vec3& b, double speed) {
  const int n = std::max(1, static_cast<int>(std::ceil((b - a).norm() / (speed * kDt))));
  std::vector<Vec3> out;
  for (int i = 0; i <= n; ++i) out.push_back(a + (b - a) * (static_cast<double>(i) / n));
  return out;
}

}  // namespace

// Straight pushes through the part: plates along -z (tilted up to 30 degrees), cylinders across their axis
// with an offset that makes contact, shared meshes and fine ellipsoids along the inward normal of a random surface
// point.
std::vector<std::vector<Vec3>> pushes(const Model& m, double speed, int runs, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<std::vector<Vec3>> out;
  const std::vector<Vec3> surface =
      m.kind == "shared" || m.kind == "fine" ? nearSurfaceProbes(*m.mesh, 20 * runs, 0.0, seed) : std::vector<Vec3>{};
  for (std::size_t i = 0; out.size() < static_cast<std::size_t>(runs) && i < 20u * runs; ++i) {
    Vec3 centre, dir;
    if (m.kind == "plate") {
      centre = Vec3(0.01 * u(rng), 0.01 * u(rng), 0.0);
      dir = Vec3(0.5 * u(rng), 0.5 * u(rng), -1.0).normalized();
    } else if (m.kind == "shared" || m.kind == "fine") {
      const ContactResult c = bruteForceQuery(*m.mesh, surface[i % surface.size()], 1.0);
      centre = c.point;
      dir = -c.normal;
      // The stylus comes from free space: a start inside or touching another part of the model is skipped.
      if (bruteForceSignedQuery(*m.mesh, centre - 0.015 * dir, kR).contact) continue;
    } else {
      const double a = M_PI * u(rng), reach = 0.5e-3 * m.sizeMm + kR;
      dir = Vec3(std::cos(a), std::sin(a), 0.0);
      centre = Vec3(-dir.y(), dir.x(), 0.0) * (0.8 * reach * u(rng)) + Vec3(0, 0, 0.02 * u(rng));
    }
    out.push_back(line(centre - 0.015 * dir, centre + 0.015 * dir, speed));
  }
  return out;
}

// The path from its first point in free space on (empty when it has none): the shipped node starts the proxy only
// once the device is clear of every object (HapticDetector: not touching, outside everything), and a proxy reset
// within r of a surface stays wedged there (every sweep starts in contact) until the device pulls it out. The fine
// ellipsoids get no trajectory: the recording placed over their 3 cm box never leaves the ellipsoid's reach.
std::vector<Vec3> fromFreeSpace(const Model& m, const std::vector<Vec3>& path) {
  std::size_t i = 0;
  while (i < path.size() && bruteForceSignedQuery(*m.mesh, path[i], kR).contact) ++i;
  return std::vector<Vec3>(path.begin() + static_cast<std::ptrdiff_t>(i), path.end());
}

/** The shipped stylus: r = 2 mm, 400 N/m, no friction, no clamp. */
ProxyParameters stylus() {
  ProxyParameters params;
  params.radius = kR;
  params.stiffness = kStiffness;
  return params;
}

ProxyParameters frictionStylus() {
  ProxyParameters params = stylus();
  params.muStatic = 0.5;
  params.muDynamic = 0.4;
  return params;
}

namespace {

/** What one force model did over a run. */
struct Outcome {
  int pushingTicks = 0, contactTicks = 0, insideTicks = 0, popThroughs = 0;
  double maxJump = 0.0;
};

// Whether the point the force pulls the stylus to (device + F / k: the proxy, or for the penalty model the
// surface point pushed out by r) went through the part between two ticks: a sphere of r / 2 swept between
// the two meets the mesh (one sliding along the surface stays r away from it).
bool crossed(const Model& m, const Vec3& from, const Vec3& to) {
  if (from == to) return false;
  SceneSweptContact c;
  m.scene.sweep(from, to, 0.5 * kR, c);
  return c.contact.hit;
}

// The force models of the tables: the penalty spring, the proxy as shipped, the proxy with friction.
enum class ForceModel { Penalty, Proxy, ProxyFriction };
const char* nameOf(ForceModel f) {
  return f == ForceModel::Penalty ? "penalty" : f == ForceModel::Proxy ? "proxy" : "proxy-friction";
}

// The forces a model renders over a path (and, for the proxy, whether it ended a tick inside the mesh).
Outcome run(const Model& m, const std::vector<Vec3>& path, ForceModel model) {
  Outcome o;
  const bool proxy = model != ForceModel::Penalty;
  HapticRenderer renderer(model == ForceModel::ProxyFriction ? frictionStylus() : stylus());
  QueryCache cache;
  ContactResult c;
  ProxyTick tick;
  Vec3 last = Vec3::Zero();
  for (std::size_t i = 0; i < path.size(); ++i) {
    Vec3 f;
    if (proxy) {
      renderer.update(m.scene, path[i], kDt, tick);
      f = tick.force;
      m.detector->query(tick.proxy, kR * (1.0 - 1e-9), DetectionMode::Exact, c);  // exact: ends inside?
      o.insideTicks += c.contact;
    } else {
      m.detector->query(path[i], kR, DetectionMode::Exact, c, &cache);
      f = penaltyForce(c, kStiffness);
    }
    const Vec3 motion = path.back() - path.front();
    o.pushingTicks += f.dot(motion) > 1e-9;
    o.contactTicks += f.squaredNorm() > 0.0;
    if (i > 0) {
      o.maxJump = std::max(o.maxJump, (f - last).norm());
      o.popThroughs += crossed(m, path[i - 1] + last / kStiffness, path[i] + f / kStiffness);
    }
    last = f;
  }
  return o;
}

std::string loadAverage() {
  std::ifstream in("/proc/loadavg");
  std::string a, b, c;
  in >> a >> b >> c;
  return a + " " + b + " " + c;
}

std::string num(double v) {
  std::ostringstream o;
  o.precision(5);
  o << v;
  return o.str();
}

/** The thin-part table: both force models on every model and speed. */
void popThroughs(const std::vector<std::unique_ptr<Model>>& models, int runs, std::ofstream& csv, std::ostream& md) {
  md << "\n| model | speed m/s | runs | force model | pop-throughs | runs with one | ticks pushing along the motion | "
        "max force jump N | proxy inside ticks |\n|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& m : models) {
    for (double speed : kSpeeds) {
      const auto paths = pushes(*m, speed, runs, 7);
      for (ForceModel model : {ForceModel::Penalty, ForceModel::Proxy, ForceModel::ProxyFriction}) {
        const bool proxy = model != ForceModel::Penalty;
        Outcome total;
        int runsPopped = 0;
        for (const auto& p : paths) {
          const Outcome o = run(*m, p, model);
          runsPopped += o.popThroughs > 0;
          total.popThroughs += o.popThroughs;
          total.pushingTicks += o.pushingTicks;
          total.contactTicks += o.contactTicks;
          total.insideTicks += o.insideTicks;
          total.maxJump = std::max(total.maxJump, o.maxJump);
        }
        const char* name = nameOf(model);
        csv << m->name << "," << m->kind << "," << m->sizeMm << "," << speed << "," << paths.size() << "," << name
            << "," << total.popThroughs << "," << runsPopped << "," << total.pushingTicks << "," << num(total.maxJump)
            << "," << total.insideTicks << "," << total.contactTicks << "\n";
        md << "| " << m->name << " | " << speed << " | " << paths.size() << " | " << name << " | " << total.popThroughs
           << " | " << runsPopped << " | " << total.pushingTicks << " | " << num(total.maxJump) << " | "
           << (proxy ? std::to_string(total.insideTicks) : "") << " |\n";
      }
    }
    std::cout << "  proxy: " << m->name << " pop-throughs measured\n" << std::flush;
  }
}

/** Per-tick times (ns) of f over the device path, each tick alone between fenced time-stamp reads. */
std::vector<float> timeTicks(const std::vector<Vec3>& path, const std::function<void(const Vec3&)>& f) {
  std::vector<float> ns;
  ns.reserve(path.size());
  for (const Vec3& p : path) ns.push_back(fencedNs([&] { f(p); }));
  return ns;
}

struct Summary {
  double median = 0, p90 = 0, p99 = 0, max = 0, mean = 0;
};
Summary summarise(std::vector<float> v) {
  Summary s;
  if (v.empty()) return s;
  std::sort(v.begin(), v.end());
  double sum = 0;
  for (float x : v) sum += x;
  s.mean = sum / v.size();
  s.median = v[v.size() / 2];
  s.p90 = v[std::min(v.size() - 1, static_cast<std::size_t>(0.9 * v.size()))];
  s.p99 = v[std::min(v.size() - 1, static_cast<std::size_t>(0.99 * v.size()))];
  s.max = v.back();
  return s;
}

/**
 * The cost table: one point query, the penalty model and the proxy over the same device paths. Each path (a push)
 * starts from a reset renderer and cache, as a user who puts the stylus down somewhere new: the jump between two
 * pushes is not a tick. Each is timed twice: the first pass finds the region's data out of the caches, the repeat
 * (the same path again) in them, as a loop that has been touching there for a while.
 */
void costs(const Model& m, const std::string& pathName, const std::vector<std::vector<Vec3>>& paths, std::ofstream& csv,
           std::ostream& md) {
  ContactResult c;
  QueryCache cache;
  HapticRenderer renderer(stylus()), rubbery(frictionStylus());
  ProxyTick tick;
  Vec3 sink = Vec3::Zero();
  std::uint64_t sweeps = 0;
  const std::pair<const char*, std::function<void(const Vec3&)>> contenders[] = {
      {"point-query",
       [&](const Vec3& p) {
         m.detector->query(p, kR, DetectionMode::Exact, c);
         sink += c.point;
       }},
      {"penalty",
       [&](const Vec3& p) {
         m.detector->query(p, kR, DetectionMode::Exact, c, &cache);
         sink += penaltyForce(c, kStiffness);
       }},
      {"proxy",
       [&](const Vec3& p) {
         renderer.update(m.scene, p, kDt, tick);
         sink += tick.force;
         sweeps += tick.sweeps;
       }},
      {"proxy-friction", [&](const Vec3& p) {
         rubbery.update(m.scene, p, kDt, tick);
         sink += tick.force;
         sweeps += tick.sweeps;
       }}};
  std::size_t ticks = 0;
  for (const auto& path : paths) ticks += path.size();
  for (const auto& contender : contenders) {
    const std::vector<Vec3>& first = paths.front();
    renderer.reset(first.front());
    rubbery.reset(first.front());
    timeTicks(std::vector<Vec3>(first.begin(), first.begin() + std::min<std::size_t>(first.size(), 200)),
              contender.second);
    std::vector<float> times[2];
    sweeps = 0;
    for (const auto& path : paths)
      for (int pass = 0; pass < 2; ++pass) {
        renderer.reset(path.front());
        rubbery.reset(path.front());
        cache = QueryCache();
        const std::vector<float> t = timeTicks(path, contender.second);
        times[pass].insert(times[pass].end(), t.begin(), t.end());
      }
    const double perTick = static_cast<double>(sweeps) / (2.0 * static_cast<double>(ticks));
    for (int pass = 0; pass < 2; ++pass) {
      const Summary s = summarise(times[pass]);
      const char* passName = pass == 0 ? "first" : "repeat";
      csv << m.name << "," << m.mesh->size() << "," << pathName << "," << ticks << "," << contender.first << ","
          << passName << "," << num(s.mean) << "," << num(s.median) << "," << num(s.p90) << "," << num(s.p99) << ","
          << num(s.max) << "," << num(perTick) << "\n";
      md << "| " << m.name << " | " << m.mesh->size() << " | " << pathName << " | " << contender.first << " | "
         << passName << " | " << num(s.mean) << " | " << num(s.median) << " | " << num(s.p90) << " | " << num(s.p99)
         << " | " << num(s.max) << " |\n";
    }
  }
  if (!sink.allFinite()) std::cout << "  (non-finite sink)\n";
}

}  // namespace

void proxySection(const std::vector<std::string>& sharedPaths, const std::string& outDir, bool quick,
                  const std::vector<Vec3>& trajectory) {
  const int runs = quick ? 4 : 12;
  const int costRuns = quick ? 4 : 40;  // more pushes for the cost table: its p99 at 2 m/s rests on 650 ticks
  std::ofstream thin(outDir + "/proxy_thin.csv"), cost(outDir + "/proxy_cost.csv"), md(outDir + "/proxy.md");
  thin << "model,kind,size_mm,speed_mps,runs,force_model,pop_throughs,runs_popped,ticks_pushing_along_motion,"
          "max_force_jump_n,proxy_inside_ticks,force_ticks\n";
  cost << "model,triangles,path,ticks,contender,pass,mean_ns,median_ns,p90_ns,p99_ns,max_ns,sweeps_per_tick\n";
  md << "# Proxy section: god-object proxy beside the penalty model\n\nr = 2 mm, 400 N/m, 1 kHz; shared meshes scaled "
        "to 15 cm; pushes 30 mm long through the part ("
     << runs
     << " per model and speed, from free space). A "
        "pop-through: the point the force pulls the stylus to (the proxy; for the penalty model the nearest surface "
        "point pushed out by r) passes through the part between two ticks (a sphere of r/2 swept between the two "
        "meets the mesh). Ticks pushing along the motion (the issue's measure) also count a proxy that slides round "
        "a thin cylinder and pulls the stylus on beside it. `proxy-friction`: the same proxy with friction as a user "
        "turns it on (mu_static 0.5, mu_dynamic 0.4; the shipped default is frictionless).\n";
  const std::string loadBefore = loadAverage();
  const auto started = std::chrono::steady_clock::now();
  std::vector<std::unique_ptr<Model>> models = thinModels();
  for (double size : {kSharedSize, kSmallSize})
    for (const std::string& path : sharedPaths) {
      try {
        models.push_back(sharedModel(path, size));
      } catch (const std::exception& e) {
        std::cout << "  proxy: skip " << path << ": " << e.what() << "\n";
      }
    }
  popThroughs(models, runs, thin, md);
  md << "\n## Cost per tick (ns)\n\nEach push from a reset renderer (the jump between pushes is not timed), timed "
        "twice: `first` finds the region out of the caches, `repeat` runs the same push again.\n\n| model | triangles "
        "| path | contender | pass | mean | median | p90 | p99 | max |\n|---|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& m : models) {
    if (m->kind != "shared" && m->kind != "fine" && m->name != "antler" && m->name != "plate-0.5mm") continue;
    for (double speed : kSpeeds) {
      costs(*m, "pushes-" + num(speed) + "mps", pushes(*m, speed, costRuns, 11), cost, md);
    }
    if (m->kind == "shared" && !trajectory.empty()) {
      const std::vector<Vec3> path = fromFreeSpace(*m, placeOver(trajectory, *m->mesh));
      if (path.empty())
        std::cout << "  proxy: " << m->name << ": the recording never leaves the model, no trajectory row\n";
      else
        costs(*m, "trajectory", {path}, cost, md);
    }
    std::cout << "  proxy: " << m->name << " costs measured\n" << std::flush;
  }
  md << "\nRun: " << (quick ? "quick" : "full") << ", "
     << std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count() << " s, load average before "
     << loadBefore << ", after " << loadAverage()
     << " (2 cores shared with other jobs: the p99 and max columns include preemption).\n";
}

}  // namespace clod_bench
