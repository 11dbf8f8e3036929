// The god-object proxy against analytic answers on thin and concave geometry, beside the penalty
// model as the detector nodes render it (ClodDetector::query with a QueryCache, then penaltyForce):
// the criteria the proxy passes are checked to fail for the penalty model, so each can fail. Also:
// friction, several objects, the proxy never inside a shared mesh over long random paths (brute force),
// and no allocation per tick.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "allocation_counter.h"
#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/contact.h"
#include "clod_haptics/core/detector.h"
#include "clod_haptics/core/haptic_renderer.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/probes.h"
#include "clod_haptics/core/sphere_set.h"
#include "clod_haptics/core/swept_query.h"
#include "test_helpers.h"

namespace {

using namespace clod_haptics;

constexpr double kRadius = 0.002;     // the shipped launch file's pointer
constexpr double kStiffness = 400.0;  // and its stiffness
constexpr double kDt = 1e-3;          // 1 kHz

// Appends a closed box to v and t, outward windings (inward: a cavity).
void appendBox(std::vector<Vec3>& v, std::vector<Triangle>& t, const Vec3& lo, const Vec3& hi, bool inward = false) {
  const std::uint32_t b = static_cast<std::uint32_t>(v.size());
  for (int i = 0; i < 8; ++i) v.emplace_back(i & 1 ? hi.x() : lo.x(), i & 2 ? hi.y() : lo.y(), i & 4 ? hi.z() : lo.z());
  const Triangle faces[12] = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                              {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  for (const Triangle& f : faces)
    t.push_back(inward ? Triangle{b + f[0], b + f[2], b + f[1]} : Triangle{b + f[0], b + f[1], b + f[2]});
}

// A closed box, outward windings.
std::shared_ptr<const TriangleMesh> box(const Vec3& lo, const Vec3& hi) {
  std::vector<Vec3> v;
  std::vector<Triangle> t;
  appendBox(v, t, lo, hi);
  return std::make_shared<const TriangleMesh>(makeMesh(v, t, "box"));
}

// An open surface of quads (corners in order), each wound so that its normal faces `outside`.
std::shared_ptr<const TriangleMesh> quads(const std::vector<std::array<Vec3, 4>>& q, const std::vector<Vec3>& outside) {
  std::vector<Vec3> v;
  std::vector<Triangle> t;
  for (std::size_t i = 0; i < q.size(); ++i) {
    const std::uint32_t b = static_cast<std::uint32_t>(v.size());
    for (const Vec3& c : q[i]) v.push_back(c);
    const bool flip = (q[i][1] - q[i][0]).cross(q[i][2] - q[i][0]).dot(outside[i]) < 0.0;
    t.push_back(flip ? Triangle{b, b + 2, b + 1} : Triangle{b, b + 1, b + 2});
    t.push_back(flip ? Triangle{b, b + 3, b + 2} : Triangle{b, b + 2, b + 3});
  }
  return std::make_shared<const TriangleMesh>(makeMesh(v, t, "quads"));
}

std::shared_ptr<const ClodDetector> detectorOf(const std::shared_ptr<const TriangleMesh>& mesh, double gridRadius) {
  auto set = std::make_shared<const ClodSphereSet>(ClodBuilder(mesh).build(0.005));
  return std::make_shared<const ClodDetector>(mesh, set, FastLevel::Grid, gridRadius);
}

SweptScene sceneOf(const std::shared_ptr<const TriangleMesh>& mesh, double gridRadius = 0.004) {
  SweptScene scene;
  scene.add(std::make_shared<const SweptSphereQuery>(mesh, detectorOf(mesh, gridRadius)),
            Eigen::Isometry3d::Identity());
  return scene;
}

// Device points from `from` to `to` at speed (m/s), one per tick, then `hold` ticks at `to`.
std::vector<Vec3> path(const Vec3& from, const Vec3& to, double speed, int hold = 0) {
  const int n = std::max(1, static_cast<int>(std::ceil((to - from).norm() / (speed * kDt))));
  std::vector<Vec3> out;
  for (int i = 0; i <= n; ++i) out.push_back(from + (to - from) * (static_cast<double>(i) / n));
  for (int i = 0; i < hold; ++i) out.push_back(to);
  return out;
}

// The shipped pointer and stiffness with the given friction and clamp.
ProxyParameters stylus(double muStatic = 0.0, double muDynamic = 0.0, double maxForce = 0.0) {
  ProxyParameters params;
  params.radius = kRadius;
  params.stiffness = kStiffness;
  params.muStatic = muStatic;
  params.muDynamic = muDynamic;
  params.maxForce = maxForce;
  return params;
}

struct Trace {
  std::vector<Vec3> device, force, proxy;
};

Trace runProxy(const SweptScene& scene, const std::vector<Vec3>& devicePath, ProxyParameters params = {}) {
  params.radius = kRadius;
  params.stiffness = kStiffness;
  HapticRenderer renderer(params);
  Trace trace;
  ProxyTick tick;
  for (const Vec3& d : devicePath) {
    renderer.update(scene, d, kDt, tick);
    trace.device.push_back(d);
    trace.force.push_back(tick.force);
    trace.proxy.push_back(tick.proxy);
  }
  return trace;
}

// The penalty model as the detector nodes compute it: one query per tick with the stream's cache.
Trace runPenalty(const std::shared_ptr<const TriangleMesh>& mesh, const std::vector<Vec3>& devicePath) {
  const auto detector = detectorOf(mesh, 0.004);
  QueryCache cache;
  ContactResult c;
  Trace trace;
  for (const Vec3& d : devicePath) {
    detector->query(d, kRadius, DetectionMode::Exact, c, &cache);
    trace.device.push_back(d);
    trace.force.push_back(penaltyForce(c, kStiffness));
    trace.proxy.push_back(d);
  }
  return trace;
}

// Ticks whose force pushes the stylus on along its motion (through the part).
int pushingThrough(const Trace& t, const Vec3& motion) {
  int n = 0;
  for (const Vec3& f : t.force) n += f.dot(motion) > 1e-9;
  return n;
}

double maxForceJump(const Trace& t) {
  double m = 0.0;
  for (std::size_t i = 1; i < t.force.size(); ++i) m = std::max(m, (t.force[i] - t.force[i - 1]).norm());
  return m;
}

// ---- A plate r/4 thick, driven through at 0.05, 0.5 and 2 m/s.

const double kPlate = kRadius / 4.0;

std::vector<Vec3> throughPlate(double speed) {
  return path(Vec3(0.0003, 0.0007, 0.0101), Vec3(0.0003, 0.0007, -0.0101), speed);
}

TEST(HapticRenderer, ProxyStaysOnTheEntrySideOfAThinPlate) {
  const auto mesh = box(Vec3(-0.05, -0.05, -kPlate / 2), Vec3(0.05, 0.05, kPlate / 2));
  const SweptScene scene = sceneOf(mesh);
  for (double speed : {0.05, 0.5, 2.0}) {
    const Trace t = runProxy(scene, throughPlate(speed));
    for (std::size_t i = 0; i < t.proxy.size(); ++i)
      ASSERT_GE(t.proxy[i].z(), kPlate / 2 + kRadius * (1.0 - 1e-9)) << speed << " m/s, tick " << i;
    EXPECT_EQ(pushingThrough(t, -Vec3::UnitZ()), 0) << speed << " m/s";
    // At the end the device is 10.1 mm below the plate's middle: the spring holds it from the top.
    EXPECT_NEAR(t.force.back().z(), kStiffness * (kPlate / 2 + kRadius + 0.0101), 1e-6) << speed << " m/s";
  }
}

// Any rotation, shifted by up to 5 cm.
Eigen::Isometry3d randomPose(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = Eigen::Quaterniond(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5).normalized().matrix();
  pose.translation() = Vec3(u(rng), u(rng), u(rng)) * 0.05;
  return pose;
}

// The shipped pointer and stiffness with friction (half the time), damping and force shading (each 30%) at random.
ProxyParameters randomStylus(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  ProxyParameters params;
  params.radius = kRadius;
  params.stiffness = kStiffness;
  if (u(rng) < 0.5) {
    params.muStatic = u(rng);
    params.muDynamic = params.muStatic * u(rng);
  }
  params.damping = u(rng) < 0.3 ? 1.0 : 0.0;
  params.forceShading = u(rng) < 0.3;
  return params;
}

// Plates the tests above were not written for: 60 mm square, 0.1 to 4 mm thick (or a sheet of no thickness, open),
// tessellated in 1 to 30 squares a side (regular or jittered, so some triangles are long and thin), turned and moved
// at random; the device goes back and forth through them 40 times at 0.01 to 4 m/s, with random friction, damping and
// force shading. The proxy never ends a tick inside (brute force) and never changes side of the plate's middle while
// over its inside (a pop-through; round the rim it may).
TEST(HapticRenderer, ProxyNeverCrossesRandomThinPlatesOrSheets) {
  std::mt19937_64 rng(2026);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::size_t ticks = 0, touching = 0;
  for (int plate = 0; plate < 8; ++plate) {
    const double half = 0.03, thick = 1e-4 * std::pow(40.0, u(rng));
    const bool sheet = plate % 4 == 3, jitter = u(rng) < 0.5;
    const int n = 1 + static_cast<int>(u(rng) * 30.0);
    std::vector<Vec3> v;
    std::vector<Triangle> t;
    // A face: the height field's grid on [-half, half]^2 at height z (wound upwards, or reversed), its inner
    // vertices moved at random when jittered.
    auto face = [&](double z, bool up) {
      const std::uint32_t base = static_cast<std::uint32_t>(v.size());
      const TriangleMesh grid = clod_test::heightField(
          n, [](double, double) { return 0.0; }, Eigen::DiagonalMatrix<double, 3>(half, half, 1.0).toDenseMatrix(),
          Vec3(0.0, 0.0, z));
      for (std::size_t k = 0; k < grid.vertices.size(); ++k) {
        const int i = static_cast<int>(k) % (n + 1), j = static_cast<int>(k) / (n + 1);
        Vec3 x = grid.toModel(grid.vertices[k]);
        if (jitter && i > 0 && i < n && j > 0 && j < n) x += Vec3(u(rng) - 0.5, u(rng) - 0.5, 0.0) * (half / n);
        v.push_back(x);
      }
      for (const Triangle& g : grid.triangles) {
        const Triangle k{base + g[0], base + g[1], base + g[2]};
        t.push_back(up ? k : Triangle{k[0], k[2], k[1]});
      }
      return base;
    };
    const std::uint32_t top = face(sheet ? 0.0 : thick / 2, true);
    if (!sheet) {
      const std::uint32_t bottom = face(-thick / 2, false);
      // The rim: the boundary loop of the top face joined to the bottom's.
      std::vector<std::pair<int, int>> loop;
      for (int i = 0; i < n; ++i) loop.push_back({i, 0});
      for (int j = 0; j < n; ++j) loop.push_back({n, j});
      for (int i = n; i > 0; --i) loop.push_back({i, n});
      for (int j = n; j > 0; --j) loop.push_back({0, j});
      auto at = [n](std::uint32_t base, std::pair<int, int> ij) {  // the height field's vertex (i, j)
        return base + static_cast<std::uint32_t>(ij.second * (n + 1) + ij.first);
      };
      for (std::size_t k = 0; k < loop.size(); ++k) {
        const auto p = loop[k], q = loop[(k + 1) % loop.size()];
        t.push_back({at(top, p), at(bottom, p), at(bottom, q)});
        t.push_back({at(top, p), at(bottom, q), at(top, q)});
      }
    }
    const Eigen::Isometry3d pose = randomPose(rng);
    for (Vec3& x : v) x = pose * x;
    const auto mesh = std::make_shared<const TriangleMesh>(makeMesh(std::move(v), std::move(t), "random plate"));
    const SweptScene scene = sceneOf(mesh, kRadius);  // the grid for the pointer, as the shipped node builds it
    HapticRenderer renderer(randomStylus(rng));
    const Eigen::Isometry3d local = pose.inverse();
    Vec3 device = pose * Vec3(0.0, 0.0, 0.01);
    renderer.reset(device);
    Vec3 last = local * device;
    std::size_t inside = 0, crossings = 0;
    ProxyTick tick;
    for (int leg = 0; leg < 40; ++leg) {
      const Vec3 target = pose * Vec3((u(rng) - 0.5) * 0.07, (u(rng) - 0.5) * 0.07, (u(rng) - 0.5) * 0.03);
      const double speed = 0.01 * std::pow(400.0, u(rng));  // 0.01 to 4 m/s
      const int steps = std::max(1, static_cast<int>((target - device).norm() / (speed * kDt)));
      const Vec3 from = device;
      for (int s = 1; s <= steps; ++s) {
        device = from + (target - from) * (static_cast<double>(s) / steps);
        renderer.update(scene, device, kDt, tick);
        ++ticks;
        touching += tick.contact;
        const Vec3 p = local * tick.proxy;
        const bool over = std::abs(p.x()) < half - kRadius && std::abs(p.y()) < half - kRadius &&
                          std::abs(last.x()) < half - kRadius && std::abs(last.y()) < half - kRadius;
        if (over && (p.z() > 0.0) != (last.z() > 0.0) && ++crossings <= 2)
          ADD_FAILURE() << "plate " << plate << " (" << thick << " thick, " << n << " squares): the proxy went from "
                        << last.z() << " to " << p.z() << " at " << speed << " m/s";
        if (bruteForceQuery(*mesh, tick.proxy, kRadius * (1.0 - 1e-6)).contact && ++inside <= 2)
          ADD_FAILURE() << "plate " << plate << ": the proxy ends a tick inside at " << tick.proxy.transpose();
        last = p;
      }
    }
    EXPECT_EQ(crossings, 0u) << "plate " << plate;
    EXPECT_EQ(inside, 0u) << "plate " << plate;
  }
  EXPECT_GT(touching, ticks / 4) << "the paths must press on the plates";
}

// What the proxy did over device paths through a thin part, checked by brute force: ticks, ticks in contact, ticks
// ending inside the mesh (within r, less rounding) and chords between consecutive proxies that cut it.
struct ChordCheck {
  std::size_t ticks = 0, touching = 0, inside = 0, cuts = 0;
  /** Runs a renderer reset at the path's start along it; a failure names what and the speed. */
  void run(const SweptScene& scene, const TriangleMesh& mesh, const ProxyParameters& params,
           const std::vector<Vec3>& devicePath, const std::string& what, double speed) {
    HapticRenderer renderer(params);
    renderer.reset(devicePath.front());
    Vec3 last = devicePath.front();
    ProxyTick tick;
    for (const Vec3& device : devicePath) {
      renderer.update(scene, device, kDt, tick);
      ++ticks;
      touching += tick.contact;
      if (bruteForceQuery(mesh, tick.proxy, kRadius * (1.0 - 1e-6)).contact && ++inside <= 2)
        ADD_FAILURE() << what << ": the proxy ends a tick inside at " << tick.proxy.transpose();
      if (bruteForceSweep(mesh, last, tick.proxy, 1e-9).hit && ++cuts <= 2)
        ADD_FAILURE() << what << ": the proxy jumped through it at " << speed << " m/s";
      last = tick.proxy;
    }
  }
};

// Thin parts other than plates, posed at random (data the proxy was not tuned on): legs 0.5 to 1.5 mm wide (6 to 24
// sides) and knife wedges (a prism whose section is an isosceles triangle with an apex of 10 to 30 degrees), pushed
// across their axis or into their edge from random sides at 0.05 to 3 m/s, with friction, damping and force shading
// on or off. A pass through such a part between two ticks need not end on its far side (a leg's far side is
// anywhere around it), so the criterion is the chord: the straight segment between two consecutive proxies never
// cuts the part (a proxy sliding round a leg keeps r from its surface, and its chords at up to 3 mm a tick pass more
// than r from the axis), and the proxy never ends a tick within r (less rounding) of it.
TEST(HapticRenderer, ProxyNeverCutsThroughRandomLegsOrWedges) {
  std::mt19937_64 rng(1129);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  ChordCheck all;
  for (int part = 0; part < 12; ++part) {
    const bool wedge = part % 2 == 1;
    std::vector<Vec3> v;
    std::vector<Triangle> t;
    if (!wedge) {  // a leg along z, 60 mm long, closed by two fans
      const double radius = 0.00025 * (1.0 + 2.0 * u(rng));
      const int sides = 6 + static_cast<int>(u(rng) * 19.0);
      for (double z : {-0.03, 0.03}) {
        for (int k = 0; k < sides; ++k) {
          const double a = 2.0 * M_PI * k / sides;
          v.push_back(Vec3(radius * std::cos(a), radius * std::sin(a), z));
        }
        v.push_back(Vec3(0.0, 0.0, z));
      }
      const std::uint32_t n = static_cast<std::uint32_t>(sides), top = n + 1, c0 = n, c1 = 2 * n + 1;
      for (std::uint32_t k = 0; k < n; ++k) {
        const std::uint32_t k1 = (k + 1) % n;
        t.push_back({k, k1, top + k1});
        t.push_back({k, top + k1, top + k});
        t.push_back({c0, k1, k});
        t.push_back({c1, top + k, top + k1});
      }
    } else {  // a wedge along z, its apex edge on the z axis, 10 mm deep towards -x
      const double apex = (10.0 + 20.0 * u(rng)) * M_PI / 180.0, depth = 0.01, h = depth * std::tan(apex / 2.0);
      v = {{0, 0, -0.03}, {-depth, h, -0.03}, {-depth, -h, -0.03}, {0, 0, 0.03}, {-depth, h, 0.03}, {-depth, -h, 0.03}};
      t = {{0, 2, 1}, {3, 4, 5}, {0, 1, 4}, {0, 4, 3}, {1, 2, 5}, {1, 5, 4}, {2, 0, 3}, {2, 3, 5}};
    }
    const Eigen::Isometry3d pose = randomPose(rng);
    for (Vec3& x : v) x = pose * x;
    const auto mesh = std::make_shared<const TriangleMesh>(makeMesh(std::move(v), std::move(t), "random thin part"));
    const SweptScene scene = sceneOf(mesh, kRadius);
    ChordCheck check;
    for (int push = 0; push < 8; ++push) {
      const ProxyParameters params = randomStylus(rng);
      // Towards a point of the axis (the edge), within 60 degrees of square to it; a wedge from its apex side.
      const double around = wedge ? (u(rng) - 0.5) * 2.6 : u(rng) * 2.0 * M_PI, tilt = (u(rng) - 0.5) * 2.1;
      const Vec3 aim = pose * Vec3(0.0, 0.0, (u(rng) - 0.5) * 0.02);
      const Vec3 across = pose.linear() * Vec3(std::cos(around), std::sin(around), 0.0);
      const Vec3 motion = -(std::cos(tilt) * across + std::sin(tilt) * (pose.linear() * Vec3::UnitZ())).normalized();
      const double speed = 0.05 * std::pow(60.0, u(rng));  // 0.05 to 3 m/s
      const std::string what = "part " + std::to_string(part) + (wedge ? " (wedge)" : " (leg)");
      check.run(scene, *mesh, params, path(aim - 0.008 * motion, aim + 0.012 * motion, speed), what, speed);
    }
    EXPECT_EQ(check.inside, 0u) << "part " << part;
    EXPECT_EQ(check.cuts, 0u) << "part " << part;
    all.ticks += check.ticks;
    all.touching += check.touching;
  }
  EXPECT_GT(all.touching, all.ticks / 4) << "the pushes must press on the parts";
}

// More thin geometry no other test has, posed at random: a comb of 0.4 mm fins 2.1 mm apart (narrower than the
// stylus) on a base, each fin a closed box overlapping it; a closed box shell 0.4 mm thick with its cavity; two 0.3 mm
// plates crossing (closed boxes through each other: not a manifold); a torus of 0.5 mm tube; a 0.3 mm disc whose
// faces are fans of long thin triangles. The device goes 15 mm into a random surface point along its inward normal
// tilted up to 50 degrees and back out, at 0.05 to 4 m/s. The chords between consecutive proxies never cut the
// mesh and no tick ends inside it (brute force), as above.
TEST(HapticRenderer, ProxyNeverCutsThroughCombsShellsOrCrossedPlates) {
  std::mt19937_64 rng(20261129);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  struct Shape {
    std::vector<Vec3> v;
    std::vector<Triangle> t;
    void box(const Vec3& lo, const Vec3& hi, bool inward = false) { appendBox(v, t, lo, hi, inward); }
  };
  std::vector<std::pair<const char*, Shape>> shapes;
  {
    Shape comb;
    comb.box(Vec3(-0.015, -0.005, -0.004), Vec3(0.015, 0.005, 0.0));
    for (int i = 0; i < 6; ++i) {
      const double x = -0.00625 + 0.0025 * i;
      comb.box(Vec3(x - 0.0002, -0.005, -0.001), Vec3(x + 0.0002, 0.005, 0.012));
    }
    shapes.push_back({"comb", comb});
    Shape shell;
    shell.box(Vec3::Constant(-0.015), Vec3::Constant(0.015));
    shell.box(Vec3::Constant(-0.0146), Vec3::Constant(0.0146), true);
    shapes.push_back({"box shell", shell});
    Shape crossed;
    crossed.box(Vec3(-0.015, -0.00015, -0.015), Vec3(0.015, 0.00015, 0.015));
    crossed.box(Vec3(-0.00015, -0.015, -0.015), Vec3(0.00015, 0.015, 0.015));
    shapes.push_back({"crossed plates", crossed});
    Shape torus;  // 10 mm from the axis, a tube of 0.5 mm, 48 x 8 quads
    const int nu = 48, nv = 8;
    for (int i = 0; i < nu; ++i)
      for (int j = 0; j < nv; ++j) {
        const double a = 2.0 * M_PI * i / nu, b = 2.0 * M_PI * j / nv;
        torus.v.emplace_back((0.01 + 0.0005 * std::cos(b)) * std::cos(a), (0.01 + 0.0005 * std::cos(b)) * std::sin(a),
                             0.0005 * std::sin(b));
      }
    for (int i = 0; i < nu; ++i)
      for (int j = 0; j < nv; ++j) {
        auto at = [&](int a, int b) { return static_cast<std::uint32_t>((a % nu) * nv + b % nv); };
        torus.t.push_back({at(i, j), at(i + 1, j), at(i + 1, j + 1)});
        torus.t.push_back({at(i, j), at(i + 1, j + 1), at(i, j + 1)});
      }
    shapes.push_back({"torus", torus});
    Shape disc;  // radius 20 mm, 0.3 mm thick, 48 sides: fans of triangles 20 mm long and 2.6 mm wide at the rim
    const int n = 48;
    for (int k = 0; k < n; ++k)
      for (double z : {-0.00015, 0.00015})
        disc.v.emplace_back(0.02 * std::cos(2.0 * M_PI * k / n), 0.02 * std::sin(2.0 * M_PI * k / n), z);
    disc.v.emplace_back(0.0, 0.0, -0.00015);
    disc.v.emplace_back(0.0, 0.0, 0.00015);
    const std::uint32_t bottom = 2 * n, top = 2 * n + 1;
    for (std::uint32_t k = 0; k < static_cast<std::uint32_t>(n); ++k) {
      const std::uint32_t k1 = (k + 1) % n;
      disc.t.push_back({top, 2 * k + 1, 2 * k1 + 1});
      disc.t.push_back({bottom, 2 * k1, 2 * k});
      disc.t.push_back({2 * k, 2 * k1, 2 * k1 + 1});
      disc.t.push_back({2 * k, 2 * k1 + 1, 2 * k + 1});
    }
    shapes.push_back({"disc", disc});
  }
  ChordCheck all;
  for (auto& [name, shape] : shapes) {
    const Eigen::Isometry3d pose = randomPose(rng);
    for (Vec3& x : shape.v) x = pose * x;
    const auto mesh = std::make_shared<const TriangleMesh>(makeMesh(shape.v, shape.t, name));
    const SweptScene scene = sceneOf(mesh, kRadius);
    std::vector<double> area;  // cumulative, to draw surface points uniformly
    for (std::size_t k = 0; k < mesh->size(); ++k)
      area.push_back((area.empty() ? 0.0 : area.back()) +
                     (mesh->vertex(k, 1) - mesh->vertex(k, 0)).cross(mesh->vertex(k, 2) - mesh->vertex(k, 0)).norm());
    ChordCheck check;
    for (int push = 0, tries = 0; push < 12 && tries < 400; ++tries) {
      const std::size_t k =
          static_cast<std::size_t>(std::lower_bound(area.begin(), area.end(), u(rng) * area.back()) - area.begin());
      double a = u(rng), b = u(rng);
      if (a + b > 1.0) {
        a = 1.0 - a;
        b = 1.0 - b;
      }
      const Vec3 &v0 = mesh->vertex(k, 0), &v1 = mesh->vertex(k, 1), &v2 = mesh->vertex(k, 2);
      const Vec3 at = v0 + a * (v1 - v0) + b * (v2 - v0), normal = (v1 - v0).cross(v2 - v0).normalized();
      const Vec3 tilt(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5);
      const Vec3 motion = (-normal + 1.2 * tilt).normalized();
      if (motion.dot(normal) > -std::cos(50.0 * M_PI / 180.0)) continue;
      const Vec3 start = at - 0.015 * motion;
      if (bruteForceQuery(*mesh, start, kRadius * 1.01).contact) continue;  // from free space
      ++push;
      const double speed = 0.05 * std::pow(80.0, u(rng));  // 0.05 to 4 m/s
      std::vector<Vec3> devicePath = path(start, at + 0.015 * motion, speed);
      const std::vector<Vec3> back = path(at + 0.015 * motion, start, speed);
      devicePath.insert(devicePath.end(), back.begin() + 1, back.end());
      check.run(scene, *mesh, randomStylus(rng), devicePath, name, speed);
    }
    EXPECT_EQ(check.inside, 0u) << name;
    EXPECT_EQ(check.cuts, 0u) << name;
    all.ticks += check.ticks;
    all.touching += check.touching;
  }
  EXPECT_GT(all.touching, all.ticks / 4) << "the pushes must press on the shapes";
}

TEST(HapticRenderer, PenaltyModelPopsThroughTheThinPlate) {  // the criterion above can fail
  const auto mesh = box(Vec3(-0.05, -0.05, -kPlate / 2), Vec3(0.05, 0.05, kPlate / 2));
  for (double speed : {0.05, 0.5, 2.0}) {
    const Trace t = runPenalty(mesh, throughPlate(speed));
    EXPECT_GT(pushingThrough(t, -Vec3::UnitZ()), 0) << speed << " m/s";
  }
}

// ---- A 90 degree V-groove along x (walls z = |y|) and an inside corner (floor and two walls).

std::shared_ptr<const TriangleMesh> groove() {
  const double L = 0.05;
  return quads({{Vec3(-L, 0, 0), Vec3(L, 0, 0), Vec3(L, L, L), Vec3(-L, L, L)},
                {Vec3(-L, 0, 0), Vec3(L, 0, 0), Vec3(L, -L, L), Vec3(-L, -L, L)}},
               {Vec3(0, -1, 1), Vec3(0, 1, 1)});
}

// Down the groove's centre line with a sideways wobble (25 Hz, 0.3 mm, ending at zero), 4 mm below its
// bottom, then held still.
std::vector<Vec3> intoGroove() {
  std::vector<Vec3> p = path(Vec3(0.001, 0.0, 0.02), Vec3(0.001, 0.0, -0.004), 0.05, 300);
  for (std::size_t i = 0; i + 300 < p.size(); ++i) p[i].y() = 0.0003 * std::sin(2.0 * M_PI * 25.0 * i * kDt);
  return p;
}

// Settled and continuous: the force at the end is the spring to the analytic rest point, the proxy is
// still over the hold, and no tick changes the force by more than maxJump.
void expectSettled(const Trace& t, const Vec3& rest, double maxJump, const std::string& what) {
  EXPECT_LT((t.proxy.back() - rest).norm(), 1e-7) << what;
  EXPECT_LT((t.force.back() - kStiffness * (rest - t.device.back())).norm(), 1e-4) << what;
  EXPECT_LT((t.proxy.back() - t.proxy[t.proxy.size() - 100]).norm(), 1e-12) << what;
  EXPECT_LT(maxForceJump(t), maxJump) << what;
}

bool settles(const Trace& t, const Vec3& rest, double maxJump) {
  return (t.force.back() - kStiffness * (rest - t.device.back())).norm() < 1e-4 && maxForceJump(t) < maxJump;
}

TEST(HapticRenderer, ProxySettlesInAGrooveAndAnInsideCorner) {
  const Trace g = runProxy(sceneOf(groove()), intoGroove());
  expectSettled(g, Vec3(0.001, 0.0, kRadius * std::sqrt(2.0)), 0.05, "groove");
  const double L = 0.05;
  const auto corner = quads({{Vec3(0, 0, 0), Vec3(L, 0, 0), Vec3(L, L, 0), Vec3(0, L, 0)},
                             {Vec3(0, 0, 0), Vec3(0, L, 0), Vec3(0, L, L), Vec3(0, 0, L)},
                             {Vec3(0, 0, 0), Vec3(L, 0, 0), Vec3(L, 0, L), Vec3(0, 0, L)}},
                            {Vec3::UnitZ(), Vec3::UnitX(), Vec3::UnitY()});
  const Trace c = runProxy(sceneOf(corner), path(Vec3(0.01, 0.012, 0.011), Vec3(-0.003, -0.002, -0.004), 0.05, 200));
  expectSettled(c, Vec3::Constant(kRadius), 0.05, "corner");
  EXPECT_FALSE(settles(runPenalty(groove(), intoGroove()), Vec3(0.001, 0.0, kRadius * std::sqrt(2.0)), 0.05));
  EXPECT_FALSE(settles(runPenalty(corner, path(Vec3(0.01, 0.012, 0.011), Vec3(-0.003, -0.002, -0.004), 0.05, 200)),
                       Vec3::Constant(kRadius), 0.05));
}

// Each quad cut into n x n smaller ones (the same surface, finely tessellated).
std::shared_ptr<const TriangleMesh> finer(const std::vector<std::array<Vec3, 4>>& q, const std::vector<Vec3>& outside,
                                          int n) {
  std::vector<std::array<Vec3, 4>> fine;
  std::vector<Vec3> out;
  for (std::size_t k = 0; k < q.size(); ++k) {
    const Vec3 u = (q[k][1] - q[k][0]) / n, v = (q[k][3] - q[k][0]) / n;
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) {
        const Vec3 o = q[k][0] + u * i + v * j;
        fine.push_back({o, o + u, o + u + v, o + v});
        out.push_back(outside[k]);
      }
  }
  return quads(fine, out);
}

// A proxy wedged into a finely tessellated inside corner (0.5 mm squares: about 60 triangles within reach of its
// rest point) and held there meets the same three walls every tick: it answers them from the last tick's
// constraints, so a tick tests a handful of triangles instead of searching the corner's cells three times. It
// settles where the coarse corner settles.
TEST(HapticRenderer, AWedgedProxyChecksItsLastConstraintsFirst) {
  const double L = 0.02;
  const auto corner = finer({{Vec3(0, 0, 0), Vec3(L, 0, 0), Vec3(L, L, 0), Vec3(0, L, 0)},
                             {Vec3(0, 0, 0), Vec3(0, L, 0), Vec3(0, L, L), Vec3(0, 0, L)},
                             {Vec3(0, 0, 0), Vec3(L, 0, 0), Vec3(L, 0, L), Vec3(0, 0, L)}},
                            {Vec3::UnitZ(), Vec3::UnitX(), Vec3::UnitY()}, 40);
  const SweptScene scene = sceneOf(corner);
  HapticRenderer renderer(stylus());
  ProxyTick tick;
  const std::vector<Vec3> devicePath = path(Vec3(0.01, 0.012, 0.011), Vec3(-0.003, -0.002, -0.004), 0.05, 200);
  std::uint32_t heldTests = 0, heldTicks = 0;
  for (std::size_t i = 0; i < devicePath.size(); ++i) {
    renderer.update(scene, devicePath[i], kDt, tick);
    if (i + 100 >= devicePath.size()) {
      heldTests += tick.trianglesTested;
      ++heldTicks;
      EXPECT_EQ(tick.planes, 3u);
    }
  }
  EXPECT_LT((tick.proxy - Vec3::Constant(kRadius)).norm(), 1e-7);
  EXPECT_LE(heldTests, 8u * heldTicks) << "triangles tested over the last " << heldTicks << " ticks";
}

// A proxy pushed into a finely tessellated crease (a floor and a wall, 0.5 mm squares) and slid along it, the device
// inside both: the proxy runs along the line between two rows of the floor's triangles (x = r is a row boundary), rests
// on both rows, and each slide comes closer to the row it is not above by a rounding's worth. It follows the device
// along the crease (a proxy that took that row for a wall would stop on the line for good, the goal of every iteration
// meeting the same row again), and stays out of both walls.
TEST(HapticRenderer, SlidesAlongTheLineBetweenTwoTrianglesOfAPlane) {
  const double L = 0.02;
  const auto crease = finer({{Vec3(0, 0, 0), Vec3(L, 0, 0), Vec3(L, L, 0), Vec3(0, L, 0)},
                             {Vec3(0, 0, 0), Vec3(0, L, 0), Vec3(0, L, L), Vec3(0, 0, L)}},
                            {Vec3::UnitZ(), Vec3::UnitX()}, 40);
  const SweptScene scene = sceneOf(crease);
  for (double depth : {0.003, 0.004, 0.005}) {
    std::vector<Vec3> device = path(Vec3(0.01, 0.003, 0.011), Vec3(kRadius - depth, 0.003, kRadius - depth), 0.05, 20);
    const std::vector<Vec3> slide = path(device.back(), Vec3(kRadius - depth, 0.017, kRadius - depth), 0.05);
    device.insert(device.end(), slide.begin(), slide.end());
    HapticRenderer renderer(stylus());
    ProxyTick tick;
    int lagging = 0;
    for (std::size_t i = 0; i < device.size(); ++i) {
      renderer.update(scene, device[i], kDt, tick);
      lagging += i > 400 && std::abs(tick.proxy.y() - device[i].y()) > 1e-6;
      ASSERT_GE(tick.proxy.x(), kRadius * (1.0 - 1e-9)) << "depth " << depth << " tick " << i;
      ASSERT_GE(tick.proxy.z(), kRadius * (1.0 - 1e-9)) << "depth " << depth << " tick " << i;
    }
    EXPECT_EQ(lagging, 0) << "depth " << depth;
    EXPECT_NEAR(tick.proxy.y(), 0.017, 1e-6) << "depth " << depth;
  }
}

// Several objects constrain the same proxy: the inside corner made of three separate boxes.
TEST(HapticRenderer, SeveralObjectsMakeOneCorner) {
  SweptScene scene;
  const auto slab = box(Vec3(-0.05, -0.05, -0.01), Vec3(0.05, 0.05, 0.0));
  const auto query = std::make_shared<const SweptSphereQuery>(slab, detectorOf(slab, 0.004));
  Eigen::Isometry3d floor = Eigen::Isometry3d::Identity();
  floor.translation() = Vec3(0.05, 0.05, 0.0);
  scene.add(query, floor);  // top face z = 0 over x, y in [0, 0.1]
  Eigen::Isometry3d wallX = Eigen::Isometry3d::Identity();
  wallX.linear() = Eigen::AngleAxisd(M_PI / 2, Vec3::UnitY()).toRotationMatrix();  // +z to +x, x to -z
  wallX.translation() = Vec3(0.0, 0.05, 0.05);
  scene.add(query, wallX);
  Eigen::Isometry3d wallY = Eigen::Isometry3d::Identity();
  wallY.linear() = Eigen::AngleAxisd(-M_PI / 2, Vec3::UnitX()).toRotationMatrix();  // +z to +y, y to -z
  wallY.translation() = Vec3(0.05, 0.0, 0.05);
  scene.add(query, wallY);
  const Trace c = runProxy(scene, path(Vec3(0.01, 0.012, 0.011), Vec3(-0.003, -0.002, -0.004), 0.05, 200));
  expectSettled(c, Vec3::Constant(kRadius), 0.05, "three objects");
}

// ---- Convex edge and vertex: the proxy rolls over them without buzzing.

int signFlips(const Trace& t, int axis) {
  int flips = 0;
  for (std::size_t i = 1; i < t.force.size(); ++i)
    flips += (t.force[i][axis] > 1e-3 && t.force[i - 1][axis] < -1e-3) ||
             (t.force[i][axis] < -1e-3 && t.force[i - 1][axis] > 1e-3);
  return flips;
}

TEST(HapticRenderer, NoBuzzOverAConvexEdgeAndVertex) {
  const SweptScene scene = sceneOf(box(Vec3(-0.05, -0.05, -0.05), Vec3(0.05, 0.05, 0.0)));
  // Pressed 1 mm in, sliding over the edge x = 0.05, then over the corner (0.05, 0.05, 0).
  for (const Vec3& dir : {Vec3(1, 0, 0), Vec3(1, 1, 0)}) {
    std::vector<Vec3> p = path(Vec3(0.04, 0.04 * dir.y(), 0.01), Vec3(0.04, 0.04 * dir.y(), kRadius - 0.001), 0.05);
    const std::vector<Vec3> slide = path(p.back(), p.back() + 0.03 * dir.normalized(), 0.1);
    p.insert(p.end(), slide.begin(), slide.end());
    const Trace t = runProxy(scene, p);
    EXPECT_EQ(signFlips(t, 0) + signFlips(t, 1) + signFlips(t, 2), 0) << dir.transpose();
    EXPECT_LT(maxForceJump(t), 0.05) << dir.transpose();
    for (const Vec3& q : t.proxy)
      ASSERT_FALSE(bruteForceQuery(*scene.query(0)->mesh(), q, kRadius * (1 - 1e-9)).contact);
  }
}

// ---- Friction: a drag inside the static cone leaves the proxy in place, beyond it the proxy slides and
// lags by muDynamic times the push.

TEST(HapticRenderer, FrictionConeStaticThenDynamic) {
  const SweptScene scene = sceneOf(box(Vec3(-0.05, -0.05, -0.05), Vec3(0.05, 0.05, 0.0)));
  HapticRenderer renderer(stylus(0.5, 0.3));
  ProxyTick tick;
  const double depth = 0.001;  // device 1 mm below the proxy's rest height: normal force 0.4 N
  for (const Vec3& d : path(Vec3(0, 0, 0.01), Vec3(0, 0, kRadius - depth), 0.05)) renderer.update(scene, d, kDt, tick);
  const Vec3 rest = tick.proxy;
  EXPECT_NEAR(rest.z(), kRadius, 1e-9);
  for (const Vec3& d : path(Vec3(0, 0, kRadius - depth), Vec3(0.00045, 0, kRadius - depth), 0.01)) {
    renderer.update(scene, d, kDt, tick);
    ASSERT_EQ(tick.proxy, rest) << "moved inside the static cone at device x " << d.x();
    EXPECT_TRUE(tick.sticking);
  }
  EXPECT_NEAR(tick.force.x(), -kStiffness * 0.00045, 1e-9);  // the friction force resists the drag
  for (const Vec3& d : path(Vec3(0.00045, 0, kRadius - depth), Vec3(0.005, 0, kRadius - depth), 0.01))
    renderer.update(scene, d, kDt, tick);
  EXPECT_GT(tick.proxy.x(), 0.004);
  EXPECT_NEAR(tick.device.x() - tick.proxy.x(), 0.3 * depth, 1e-6);
  EXPECT_NEAR(tick.proxy.z(), kRadius, 1e-6);
  // The penalty model has no friction: the same drag feels no tangential force at all.
  const Trace pen =
      runPenalty(scene.query(0)->mesh(), path(Vec3(0, 0, kRadius - depth), Vec3(0.0004, 0, kRadius - depth), 0.01));
  EXPECT_NEAR(pen.force.back().x(), 0.0, 1e-12);
}

// Friction is decided at the first contact of a tick, before any slide: a sticking proxy sweeps once a tick (the
// contact it rests on answers at once) instead of sliding frictionless first and throwing that slide away (two sweeps
// a tick, the second a search).
TEST(HapticRenderer, AStickingProxySweepsOnceATick) {
  const SweptScene scene = sceneOf(box(Vec3(-0.05, -0.05, -0.05), Vec3(0.05, 0.05, 0.0)));
  HapticRenderer renderer(stylus(0.5, 0.3));
  ProxyTick tick;
  const double depth = 0.001;
  for (const Vec3& d : path(Vec3(0, 0, 0.01), Vec3(0, 0, kRadius - depth), 0.05)) renderer.update(scene, d, kDt, tick);
  const Vec3 rest = tick.proxy;
  int ticks = 0;
  for (const Vec3& d : path(Vec3(0, 0, kRadius - depth), Vec3(0.00045, 0.0001, kRadius - depth), 0.01)) {
    renderer.update(scene, d, kDt, tick);
    if (d.head<2>().norm() <= HapticRenderer::kStillRadii * kRadius) continue;  // within the still distance: no sweep
    ASSERT_TRUE(tick.sticking);
    ASSERT_EQ(tick.proxy, rest);
    EXPECT_EQ(tick.sweeps, 1u) << "device at " << d.transpose();
    ++ticks;
  }
  EXPECT_GT(ticks, 40);
}

// The friction cone's normal is the contact normal where the proxy stands: in a V-groove both walls' (it rests on
// both), so a device pressed straight into the groove and dragged along it by less than mu_s times the push holds the
// proxy; dragged farther, the proxy slides along the groove, lagging by mu_d times the push. With one wall's normal
// the push would count as half drag and the proxy would slide at once.
TEST(HapticRenderer, FrictionInAGrooveUsesBothWalls) {
  const SweptScene scene = sceneOf(groove());
  HapticRenderer renderer(stylus(0.5, 0.3));
  ProxyTick tick;
  const double bottom = kRadius * std::sqrt(2.0), depth = 0.001;
  for (const Vec3& d : path(Vec3(0.001, 0.0, 0.02), Vec3(0.001, 0.0, bottom - depth), 0.05, 50))
    renderer.update(scene, d, kDt, tick);
  const Vec3 rest = tick.proxy;
  ASSERT_NEAR((rest - Vec3(0.001, 0.0, bottom)).norm(), 0.0, 1e-6);
  ASSERT_EQ(tick.planes, 2u);
  for (const Vec3& d : path(Vec3(0.001, 0.0, bottom - depth), Vec3(0.00145, 0.0, bottom - depth), 0.01)) {
    renderer.update(scene, d, kDt, tick);
    ASSERT_EQ(tick.proxy, rest) << "moved inside the static cone at device x " << d.x();
  }
  for (const Vec3& d : path(Vec3(0.00145, 0.0, bottom - depth), Vec3(0.006, 0.0, bottom - depth), 0.01))
    renderer.update(scene, d, kDt, tick);
  EXPECT_TRUE(tick.sliding);
  EXPECT_NEAR(tick.device.x() - tick.proxy.x(), 0.3 * depth, 1e-6);
  EXPECT_NEAR(tick.proxy.y(), 0.0, 1e-9);
  EXPECT_NEAR(tick.proxy.z(), bottom, 1e-6);
}

// A device creeping along a surface slower than the proxy's still distance a tick: the proxy is never left more than
// that distance behind, so the force errs by at most the stiffness times it (0.2 um, 80 uN here), and it follows.
TEST(HapticRenderer, ACreepingDeviceLeavesTheProxyAtMostTheStillDistanceBehind) {
  const SweptScene scene = sceneOf(box(Vec3(-0.05, -0.05, -0.05), Vec3(0.05, 0.05, 0.0)));
  HapticRenderer renderer(stylus());
  ProxyTick tick;
  const double depth = 0.001, still = HapticRenderer::kStillRadii * kRadius, step = 0.3 * still;
  for (const Vec3& d : path(Vec3(0, 0, 0.01), Vec3(0, 0, kRadius - depth), 0.05)) renderer.update(scene, d, kDt, tick);
  ASSERT_NEAR(tick.proxy.z(), kRadius, 1e-9);
  for (int i = 1; i <= 1500; ++i) {
    const Vec3 device(i * step, 0.0, kRadius - depth);
    renderer.update(scene, device, kDt, tick);
    ASSERT_GE(tick.proxy.z(), kRadius * (1.0 - 1e-9)) << "tick " << i;
    ASSERT_LE(std::abs(tick.proxy.x() - device.x()), still * (1.0 + 1e-6)) << "tick " << i;
    ASSERT_LE(std::abs(tick.force.x()), kStiffness * still * (1.0 + 1e-6)) << "tick " << i;
  }
  EXPECT_GT(tick.proxy.x(), 1500 * step - still);  // it followed the whole 0.09 mm
}

// In free space the still distance does not apply: a device creeping by less than it (a hand at rest, the turn of a
// stroke) drags the proxy along exactly, so no force comes without contact; the same after the proxy has touched,
// from the tick the stylus is clear. (With the still distance everywhere the proxy stayed up to 0.2 um behind: 80 uN
// in free space, which the bridge's servo test caught.) A device that moves less than it off the surface the proxy
// rests on or into it leaves the proxy there: that tick is in contact, with the last tick's contact.
TEST(HapticRenderer, AFreeProxyFollowsACreepingDeviceExactly) {
  const SweptScene scene = sceneOf(box(Vec3(-0.05, -0.05, -0.05), Vec3(0.05, 0.05, 0.0)));
  HapticRenderer renderer(stylus());
  ProxyTick tick;
  const double step = 0.3 * HapticRenderer::kStillRadii * kRadius;
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto creep = [&](Vec3 device, int ticks, const char* what) {
    for (int i = 0; i < ticks; ++i) {
      device += Vec3(u(rng), u(rng), u(rng)) * step;
      renderer.update(scene, device, kDt, tick);
      ASSERT_FALSE(tick.contact) << what << ", tick " << i;
      ASSERT_EQ(tick.proxy, device) << what << ", tick " << i;
      ASSERT_EQ(tick.force, Vec3::Zero()) << what << ", tick " << i;
    }
  };
  renderer.reset(Vec3(0.0, 0.0, 0.02));
  creep(Vec3(0.0, 0.0, 0.02), 200, "never touched");
  // Press 1 mm in, pull out to 1 mm clear of the surface in one tick, then creep there.
  for (const Vec3& d : path(Vec3(0, 0, 0.01), Vec3(0, 0, kRadius - 0.001), 0.05)) renderer.update(scene, d, kDt, tick);
  ASSERT_TRUE(tick.contact);
  const ProxyTick pressed = tick;
  for (const double off : {1.0, -1.0, 2.0}) {  // off the surface (the proxy's centre + step), into it, off again
    const Vec3 device = pressed.proxy + Vec3(0.0, 0.0, off * step);
    renderer.update(scene, device, kDt, tick);
    EXPECT_EQ(tick.proxy, pressed.proxy) << off;
    EXPECT_TRUE(tick.contact) << off;
    EXPECT_EQ(tick.triangle, pressed.triangle) << off;
    EXPECT_EQ(tick.point, pressed.point) << off;
    EXPECT_EQ(tick.normal, pressed.normal) << off;
    EXPECT_EQ(tick.planes, pressed.planes) << off;
  }
  renderer.update(scene, Vec3(0.0, 0.0, kRadius + 0.001), kDt, tick);
  creep(tick.device, 200, "after a touch");
}

// ---- The proxy never ends a tick inside a shared mesh, over long random device paths (brute force).

TEST(HapticRenderer, ProxyNeverInsideSharedMeshesOnRandomPaths) {
  bool withFriction = true;  // every other mesh with friction (decided at each tick's first contact)
  for (const std::string& file : clod_test::sharedMeshes()) {
    auto mesh = clod_test::loadNormalized(file);
    auto set = std::make_shared<const ClodSphereSet>(ClodBuilder(mesh).build(0.01));
    SweptScene scene;
    scene.add(std::make_shared<const SweptSphereQuery>(
                  mesh, std::make_shared<const ClodDetector>(mesh, set, FastLevel::Grid, 0.02)),
              Eigen::Isometry3d::Identity());
    const double r = 0.01;
    ProxyParameters params;
    params.radius = r;
    params.stiffness = 1.0;
    params.muStatic = withFriction ? 0.4 : 0.0;
    withFriction = !withFriction;
    params.muDynamic = 0.2;
    HapticRenderer renderer(params);
    renderer.reset(mesh->modelBounds().max() + Vec3::Constant(0.1));
    const std::size_t ticks = mesh->size() > 50000 ? 1500 : 4000;
    const std::vector<Vec3> targets = nearSurfaceProbes(*mesh, ticks / 20 + 1, 0.05, 17);
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> step(0.0005, 0.02);  // 0.05 r to 2 r per tick
    Vec3 device = mesh->modelBounds().max() + Vec3::Constant(0.1);
    std::size_t target = 0, constrained = 0, inside = 0;
    double speed = step(rng);
    ProxyTick tick;
    for (std::size_t i = 0; i < ticks; ++i) {
      const Vec3 toward = targets[target] - device;
      if (toward.norm() <= speed) {
        device = targets[target];
        target = (target + 1) % targets.size();
        speed = step(rng);
      } else {
        device += toward.normalized() * speed;
      }
      renderer.update(scene, device, kDt, tick);
      constrained += tick.contact;
      const bool in = bruteForceQuery(*mesh, tick.proxy, r * (1.0 - 1e-9)).contact;
      if (in && ++inside <= 3) ADD_FAILURE() << clod_test::baseName(file) << " tick " << i << ": proxy inside";
    }
    EXPECT_EQ(inside, 0u) << clod_test::baseName(file);
    EXPECT_GT(constrained, ticks / 10) << clod_test::baseName(file) << ": the path rarely met the surface";
  }
}

// The device jumps many radii between ticks (a burst of poses answered newest-first, a replay skipping ahead, a
// dropped stretch of the stream): the proxy still never ends inside, on the bundled torus as the detector node
// builds it (r = 2 mm, d = 3 mm, grid for r) and on every shared mesh. Probes as the rostest burst draws them.
TEST(HapticRenderer, ProxyNeverInsideAfterLongJumps) {
  struct Case {
    std::shared_ptr<const TriangleMesh> mesh;
    double r, d;
  };
  std::vector<Case> cases;
  cases.push_back({std::make_shared<const TriangleMesh>(loadMesh(CLOD_PACKAGE_DATA_DIR "/meshes/torus.obj")), kRadius,
                   0.003});
  for (const std::string& file : clod_test::sharedMeshes()) cases.push_back({clod_test::loadNormalized(file), 0.01, 0.02});
  for (const Case& c : cases) {
    auto set = std::make_shared<const ClodSphereSet>(ClodBuilder(c.mesh).build(c.d));
    SweptScene scene;
    scene.add(std::make_shared<const SweptSphereQuery>(
                  c.mesh, std::make_shared<const ClodDetector>(c.mesh, set, FastLevel::Grid, c.r)),
              Eigen::Isometry3d::Identity());
    ProxyParameters params;
    params.radius = c.r;
    params.stiffness = kStiffness;
    HapticRenderer renderer(params);
    renderer.reset(c.mesh->modelBounds().max() + Vec3::Constant(4.0 * c.r));
    std::vector<Vec3> targets = nearSurfaceProbes(*c.mesh, 1500, 2.0 * c.r, 77);
    const std::vector<Vec3> far = uniformProbes(*c.mesh, 500, 4.0 * c.r, 78);
    targets.insert(targets.end(), far.begin(), far.end());
    std::shuffle(targets.begin(), targets.end(), std::mt19937_64(3));
    std::size_t inside = 0, constrained = 0;
    ProxyTick tick;
    for (std::size_t i = 0; i < targets.size(); ++i) {
      renderer.update(scene, targets[i], kDt, tick);
      constrained += tick.contact;
      if (bruteForceQuery(*c.mesh, tick.proxy, c.r * (1.0 - 1e-9)).contact && ++inside <= 3)
        ADD_FAILURE() << c.mesh->name << " jump " << i << ": proxy inside at " << tick.proxy.transpose();
    }
    EXPECT_EQ(inside, 0u) << c.mesh->name;
    EXPECT_GT(constrained, targets.size() / 10) << c.mesh->name << ": the jumps rarely met the surface";
  }
}

TEST(HapticRenderer, AllocatesNothingPerTick) {
  const SweptScene scene = sceneOf(groove());
  ProxyParameters params;
  params.muStatic = 0.4;
  params.muDynamic = 0.2;
  params.damping = 0.5;
  params.forceShading = true;
  HapticRenderer renderer(params);
  const std::vector<Vec3> p = intoGroove();
  ProxyTick tick;
  gAllocations = 0;
  gCounting = true;
  for (const Vec3& d : p) renderer.update(scene, d, kDt, tick);
  gCounting = false;
  EXPECT_EQ(gAllocations.load(), 0);
}

TEST(HapticRenderer, ClampDampingAndBadInput) {
  const SweptScene scene = sceneOf(box(Vec3(-0.05, -0.05, -0.05), Vec3(0.05, 0.05, 0.0)));
  ProxyParameters params = stylus(0.0, 0.0, 1.0);
  HapticRenderer renderer(params);
  ProxyTick tick;
  for (const Vec3& d : path(Vec3(0, 0, 0.01), Vec3(0, 0, -0.01), 0.05)) renderer.update(scene, d, kDt, tick);
  EXPECT_NEAR(tick.force.norm(), 1.0, 1e-12);  // 400 N/m over 12 mm would be 4.8 N
  const Vec3 proxy = tick.proxy;
  renderer.update(scene, Vec3(std::nan(""), 0, 0), kDt, tick);
  EXPECT_EQ(tick.force, Vec3::Zero());
  EXPECT_EQ(renderer.proxy(), proxy);
  // Damping opposes the relative velocity: pushing in faster feels stiffer.
  params.maxForce = 0.0;
  params.damping = 2.0;
  HapticRenderer damped(params);
  damped.reset(Vec3(0, 0, 0.01));
  for (const Vec3& d : path(Vec3(0, 0, 0.01), Vec3(0, 0, kRadius - 0.001), 0.05)) damped.update(scene, d, kDt, tick);
  EXPECT_NEAR(tick.force.z(), kStiffness * 0.001 + 2.0 * 0.05, 1e-3);
}

}  // namespace
