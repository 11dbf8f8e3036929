// Numerical stability: degenerate geometry, extreme scales and offsets, probes exactly on
// features, and property tests over random meshes. Every check is against bruteForceQuery.
//
// There is no float path in the core: meshes, spheres and queries are double throughout, so no float
// error bound applies. Tolerances below are relative to the model size, never absolute.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/detector.h"
#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/geometry.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/probes.h"
#include "clod_haptics/core/sphere_set.h"
#include "test_helpers.h"

namespace {

using namespace clod_haptics;

// ---------------------------------------------------------------------------------------------
// Mesh makers

TriangleMesh cubeMesh(const Vec3& lo = Vec3::Zero(), double edge = 1.0) {
  std::vector<Vec3> v;
  for (int z = 0; z < 2; ++z)
    for (int y = 0; y < 2; ++y)
      for (int x = 0; x < 2; ++x) v.push_back(lo + edge * Vec3(x, y, z));
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  std::vector<Triangle> t;
  for (const auto& q : quads) {
    t.push_back({std::uint32_t(q[0]), std::uint32_t(q[1]), std::uint32_t(q[2])});
    t.push_back({std::uint32_t(q[0]), std::uint32_t(q[2]), std::uint32_t(q[3])});
  }
  return makeMesh(v, t, "cube");
}

// A closed star-shaped mesh: a latitude-longitude sphere whose vertex radii are random.
TriangleMesh randomBlob(std::mt19937_64& rng, int rings, int segments, double roughness) {
  std::uniform_real_distribution<double> u(1.0 - roughness, 1.0);
  std::vector<Vec3> v{Vec3(0, 0, u(rng))};
  for (int i = 1; i < rings; ++i)
    for (int j = 0; j < segments; ++j) {
      const double th = M_PI * i / rings, ph = 2 * M_PI * j / segments;
      v.push_back(u(rng) * Vec3(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th)));
    }
  v.push_back(Vec3(0, 0, -u(rng)));
  const auto id = [&](int i, int j) { return std::uint32_t(1 + (i - 1) * segments + (j % segments)); };
  const std::uint32_t south = std::uint32_t(v.size() - 1);
  std::vector<Triangle> t;
  for (int j = 0; j < segments; ++j) t.push_back({0, id(1, j), id(1, j + 1)});
  for (int i = 1; i + 1 < rings; ++i)
    for (int j = 0; j < segments; ++j) {
      t.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      t.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
  for (int j = 0; j < segments; ++j) t.push_back({id(rings - 1, j), south, id(rings - 1, j + 1)});
  return makeMesh(v, t, "blob");
}

// Random triangles in the unit cube: open, self-intersecting, some slivers and zero-area ones.
TriangleMesh randomSoup(std::mt19937_64& rng, int count) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Vec3> v;
  std::vector<Triangle> t;
  for (int k = 0; k < count; ++k) {
    const Vec3 a(u(rng), u(rng), u(rng));
    Vec3 b = a + 0.3 * Vec3(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5);
    Vec3 c = a + 0.3 * Vec3(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5);
    if (k % 7 == 3) c = a + 0.37 * (b - a) + 1e-13 * Vec3(u(rng), u(rng), u(rng));  // sliver
    if (k % 11 == 5) c = b;                                                          // zero area
    const std::uint32_t base = std::uint32_t(v.size());
    v.insert(v.end(), {a, b, c});
    t.push_back({base, base + 1, base + 2});
  }
  return makeMesh(v, t, "soup");
}

std::shared_ptr<const TriangleMesh> normalized(TriangleMesh m) {
  MeshLoadOptions o;
  o.normalize = true;
  transformMesh(m, o);
  return std::make_shared<const TriangleMesh>(std::move(m));
}

// ---------------------------------------------------------------------------------------------
// The checker: no NaN or Inf in the set, coverage, exact == brute force, paper within brute force,
// spheres never missing a contact; contact fields finite.

std::vector<Vec3> probesFor(const TriangleMesh& mesh, std::size_t near, std::size_t uniform, double offset,
                            std::uint64_t seed) {
  std::vector<Vec3> probes = nearSurfaceProbes(mesh, near, offset, seed);
  const auto u = uniformProbes(mesh, uniform, offset, seed + 1);
  probes.insert(probes.end(), u.begin(), u.end());
  for (const Vec3& v : mesh.vertices) probes.push_back(v);  // exactly on vertices
  for (std::size_t t = 0; t < mesh.size() && t < 200; ++t) {
    probes.push_back(0.5 * (mesh.vertex(t, 0) + mesh.vertex(t, 1)));  // on an edge
    probes.push_back(mesh.centroid(t));                              // on the face
  }
  return probes;
}

struct CheckStats {
  std::size_t probes = 0, contacts = 0;
};

void checkAgainstBruteForce(const std::shared_ptr<const TriangleMesh>& mesh, const ClodSphereSet& setValue,
                            const std::vector<Vec3>& probes, const std::vector<double>& radii, const std::string& label,
                            CheckStats* stats = nullptr) {
  SCOPED_TRACE(label);
  for (std::size_t i = 0; i < setValue.size(); ++i) {
    ASSERT_TRUE(setValue.centres[i].allFinite()) << "sphere " << i;
    ASSERT_TRUE(std::isfinite(setValue.radii[i])) << "sphere " << i;
  }
  const auto problems = clod_test::coverageProblems(*mesh, setValue);
  ASSERT_TRUE(problems.empty()) << clod_test::join(problems);
  const auto set = std::make_shared<const ClodSphereSet>(setValue);
  const double size = std::max(mesh->diagonal(), std::numeric_limits<double>::min());
  for (FastLevel fast : {FastLevel::Grid, FastLevel::Hierarchy, FastLevel::Flat}) {
    const ClodDetector det(mesh, set, fast);
    ContactResult exact, paper, spheres;
    int failures = 0;
    for (double r : radii)
      for (std::size_t i = 0; i < probes.size() && failures < 5; ++i) {
        const Vec3& p = probes[i];
        const ContactResult ref = bruteForceQuery(*mesh, p, r);
        det.query(p, r, DetectionMode::Exact, exact);
        det.query(p, r, DetectionMode::Paper, paper);
        det.query(p, r, DetectionMode::Spheres, spheres);
        if (stats && fast == FastLevel::Hierarchy) {
          ++stats->probes;
          stats->contacts += ref.contact;
        }
        const double tol = 1e-9 * std::max(ref.distance, r) + 1e-15 * size;
        bool ok = exact.contact == ref.contact && (!ref.contact || std::abs(exact.distance - ref.distance) <= tol);
        if (exact.contact)
          ok = ok && exact.point.allFinite() && exact.normal.allFinite() && std::abs(exact.normal.norm() - 1) < 1e-9 &&
               std::isfinite(exact.depth);
        // Paper projects onto the plane, brute force reconstructs the point from barycentric weights: for a
        // probe on the surface they round differently, so a paper contact is accepted when the true
        // distance is within rounding (1e-12 of the model size) of r.
        ok = ok && (!paper.contact || ref.contact ||
                    (bruteForceQuery(*mesh, p, r + 1e-12 * size).contact && paper.distance <= r));
        if (paper.contact) ok = ok && paper.normal.allFinite() && paper.distance >= ref.distance - tol;
        ok = ok && (!ref.contact || spheres.contact);
        if (spheres.contact) ok = ok && spheres.point.allFinite() && spheres.normal.allFinite();
        if (!ok) {
          ++failures;
          ADD_FAILURE() << (fast == FastLevel::Flat ? "flat" : fast == FastLevel::Grid ? "grid" : "hierarchy") << " probe " << i << " ("
                        << p.transpose() << ") r=" << r << ": brute force contact " << ref.contact << " distance "
                        << ref.distance << "; exact " << exact.contact << " " << exact.distance << "; paper "
                        << paper.contact << "; spheres " << spheres.contact;
        }
      }
  }
}

void checkMesh(const std::shared_ptr<const TriangleMesh>& mesh, const std::string& label, std::size_t nearProbes = 1500,
               std::size_t uniformProbesCount = 500) {
  const ClodBuilder builder(mesh);
  const PlacementStats& ps = builder.placementStats();
  EXPECT_EQ(ps.paired + ps.unpaired + ps.degenerate, mesh->size()) << label;
  const double size = mesh->diagonal();
  const auto probes = probesFor(*mesh, nearProbes, uniformProbesCount, 0.02 * size, 77);
  for (double d : {0.0, 0.02, 0.08}) {
    const ClodSphereSet set = builder.build(d * size);
    checkAgainstBruteForce(mesh, set, probes, {0.0, 0.005 * size, 0.03 * size}, label + " d=" + std::to_string(d));
  }
}

// ---------------------------------------------------------------------------------------------
// Degenerate input

TEST(Degenerate, SlidingDegenerateTriangles) {
  checkMesh(clod_test::loadNormalized(clod_test::sharedMesh("degtri_sliding.off")), "degtri_sliding.off");
}

TEST(Degenerate, OpenMeshWithBorder) {
  checkMesh(clod_test::loadNormalized(clod_test::sharedMesh("mesh_with_border.off")), "mesh_with_border.off");
}

TEST(Degenerate, DuplicateAndCollinearVertices) {
  // A cube whose every triangle has its own copies of the vertices, plus triangles whose three
  // vertices are collinear (one on an edge midpoint) or identical.
  const TriangleMesh cube = cubeMesh();
  std::vector<Vec3> v;
  std::vector<Triangle> t;
  for (std::size_t k = 0; k < cube.size(); ++k) {
    const std::uint32_t base = std::uint32_t(v.size());
    for (int j = 0; j < 3; ++j) v.push_back(cube.vertex(k, j));
    t.push_back({base, base + 1, base + 2});
  }
  const std::uint32_t mid = std::uint32_t(v.size());
  v.push_back(0.5 * (v[0] + v[1]));
  t.push_back({0, mid, 1});        // collinear: on the midpoint of the edge v0-v1
  t.push_back({mid, mid, mid});    // one point
  t.push_back({0, 0, mid});        // two identical vertices
  const auto mesh = normalized(makeMesh(v, t, "duplicates"));
  checkMesh(mesh, "duplicate and collinear vertices");
  const ClodBuilder builder(mesh);
  EXPECT_EQ(builder.placementStats().degenerate, 3u);
}

TEST(Degenerate, DuplicateTriangles) {
  TriangleMesh cube = cubeMesh();
  auto t = cube.triangles;
  t.insert(t.end(), cube.triangles.begin(), cube.triangles.end());
  t.insert(t.end(), cube.triangles.begin(), cube.triangles.end());
  checkMesh(normalized(makeMesh(cube.vertices, t, "triplicated cube")), "duplicate triangles");
}

TEST(Degenerate, NonManifoldEdges) {
  // Five fins sharing one edge, and two cubes touching along an edge.
  std::vector<Vec3> v{Vec3(0, 0, 0), Vec3(0, 0, 1)};
  std::vector<Triangle> t;
  for (int k = 0; k < 5; ++k) {
    const double a = 2 * M_PI * k / 5;
    v.push_back(Vec3(std::cos(a), std::sin(a), 0.5));
    t.push_back({0, 1, std::uint32_t(v.size() - 1)});
  }
  checkMesh(normalized(makeMesh(v, t, "fins")), "fins on one edge");
  TriangleMesh a = cubeMesh(Vec3(0, 0, 0)), b = cubeMesh(Vec3(1, 1, 0));
  std::vector<Vec3> vv = a.vertices;
  vv.insert(vv.end(), b.vertices.begin(), b.vertices.end());
  std::vector<Triangle> tt = a.triangles;
  for (Triangle tri : b.triangles) tt.push_back({tri[0] + 8, tri[1] + 8, tri[2] + 8});
  checkMesh(normalized(makeMesh(vv, tt, "edge-touching cubes")), "cubes sharing an edge");
}

TEST(Degenerate, SingleTriangle) {
  const auto mesh = normalized(makeMesh({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0.2, 0.7, 0)}, {{0, 1, 2}}, "one"));
  checkMesh(mesh, "single triangle");
  const ClodBuilder builder(mesh);
  EXPECT_EQ(builder.placed().size(), 1u);
  EXPECT_EQ(builder.placementStats().unpaired, 1u);
  EXPECT_EQ(builder.build(0.0).size(), 1u);
}

TEST(Degenerate, FlatPlanarMeshHasNoOppositeTriangles) {
  std::vector<Vec3> v;
  std::vector<Triangle> t;
  const int n = 12;
  for (int i = 0; i <= n; ++i)
    for (int j = 0; j <= n; ++j) v.push_back(Vec3(double(i) / n, double(j) / n, 0.0));
  const auto id = [&](int i, int j) { return std::uint32_t(i * (n + 1) + j); };
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      t.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      t.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
  const auto mesh = normalized(makeMesh(v, t, "plane"));
  checkMesh(mesh, "flat plane");
  const ClodBuilder builder(mesh);
  EXPECT_EQ(builder.placementStats().paired, 0u);
  EXPECT_EQ(builder.placementStats().unpaired, mesh->size());
}

TEST(Degenerate, SelfIntersectingMeshes) {
  // Two interpenetrating cubes, and a cube pierced by a fin.
  TriangleMesh a = cubeMesh(Vec3(0, 0, 0)), b = cubeMesh(Vec3(0.4, 0.3, 0.2));
  std::vector<Vec3> v = a.vertices;
  v.insert(v.end(), b.vertices.begin(), b.vertices.end());
  std::vector<Triangle> t = a.triangles;
  for (Triangle tri : b.triangles) t.push_back({tri[0] + 8, tri[1] + 8, tri[2] + 8});
  v.insert(v.end(), {Vec3(-0.5, 0.5, 0.5), Vec3(1.5, 0.5, 0.4), Vec3(0.5, 0.5, 1.6)});
  t.push_back({16, 17, 18});
  checkMesh(normalized(makeMesh(v, t, "self-intersecting")), "self-intersecting");
}

TEST(Degenerate, AllTrianglesZeroArea) {
  std::vector<Vec3> v{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(2, 0, 0), Vec3(0, 1, 1)};
  const auto mesh = normalized(makeMesh(v, {{0, 1, 2}, {3, 3, 3}, {0, 3, 3}}, "zero area only"));
  checkMesh(mesh, "only zero-area triangles");
  EXPECT_EQ(ClodBuilder(mesh).placementStats().degenerate, 3u);
}

TEST(Degenerate, CoincidentOppositeFaces) {
  // A zero-thickness slab: two coincident squares facing away from each other.
  std::vector<Vec3> v{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0)};
  std::vector<Triangle> t{{0, 1, 2}, {0, 2, 3}, {0, 2, 1}, {0, 3, 2}};
  checkMesh(normalized(makeMesh(v, t, "zero thickness")), "zero-thickness slab");
}

// ---------------------------------------------------------------------------------------------
// Scale and offset: same sphere counts and the same contacts in scaled coordinates.

struct Scaled {
  std::shared_ptr<const TriangleMesh> mesh;
  double s;
  Vec3 offset;
};

Scaled scaledCopy(const TriangleMesh& base, double s, const Vec3& offset) {
  std::vector<Vec3> v = base.vertices;
  for (Vec3& x : v) x = x * s + offset;
  return {std::make_shared<const TriangleMesh>(makeMesh(v, base.triangles, base.name)), s, offset};
}

TEST(ScaleAndOffset, SameSpheresAndContactsAtEveryScale) {
  const auto base = clod_test::loadNormalized(clod_test::sharedMesh("head.off"));
  const ClodBuilder baseBuilder(base);
  const std::vector<double> ds{0.0, 0.02, 0.08};
  const std::vector<double> radii{0.002, 0.01};
  std::vector<std::size_t> baseCounts;
  for (double d : ds) baseCounts.push_back(baseBuilder.build(d).size());
  const auto probes = probesFor(*base, 3000, 1000, 0.02, 5);
  std::vector<std::vector<ContactResult>> baseRef(radii.size());
  for (std::size_t k = 0; k < radii.size(); ++k)
    for (const Vec3& p : probes) baseRef[k].push_back(bruteForceQuery(*base, p, radii[k]));

  std::vector<Scaled> cases;
  for (double s : {1e-6, 1e-3, 1.0, 1e3, 1e6}) cases.push_back(scaledCopy(*base, s, Vec3::Zero()));
  cases.push_back(scaledCopy(*base, 1.0, Vec3(1e6, -1e6, 1e6)));
  cases.push_back(scaledCopy(*base, 1e3, Vec3(1e6, 1e6, 1e6)));
  for (const Scaled& c : cases) {
    const std::string label = "scale " + std::to_string(c.s) + " offset " + std::to_string(c.offset.x());
    SCOPED_TRACE(label);
    const ClodBuilder builder(c.mesh);
    EXPECT_EQ(builder.placementStats().paired, baseBuilder.placementStats().paired);
    // Coordinates carry |offset| * 2^-52 of rounding: contacts are compared outside that band.
    const double size = c.mesh->diagonal();
    const double band = 1e-9 * size + 64 * std::numeric_limits<double>::epsilon() * c.offset.norm();
    for (std::size_t k = 0; k < ds.size(); ++k) {
      const ClodSphereSet set = builder.build(ds[k] * c.s);
      EXPECT_EQ(set.size(), baseCounts[k]) << "d=" << ds[k];
      const auto problems = clod_test::coverageProblems(*c.mesh, set);
      EXPECT_TRUE(problems.empty()) << clod_test::join(problems);
      const ClodDetector det(c.mesh, std::make_shared<const ClodSphereSet>(set));
      ContactResult got;
      std::size_t differ = 0, skipped = 0;
      for (std::size_t kr = 0; kr < radii.size(); ++kr) {
        const double r = radii[kr] * c.s;
        for (std::size_t i = 0; i < probes.size(); ++i) {
          const ContactResult& ref = baseRef[kr][i];
          const Vec3 p = probes[i] * c.s + c.offset;
          det.query(p, r, DetectionMode::Exact, got);
          if (ref.contact && std::abs(ref.distance * c.s - r) <= band) {
            ++skipped;
            continue;
          }
          const bool same = got.contact == ref.contact &&
                            (!got.contact || std::abs(got.distance - ref.distance * c.s) <= band + 1e-9 * r);
          if (!same && ++differ <= 5)
            ADD_FAILURE() << "d=" << ds[k] << " r=" << r << " probe " << i << ": scale-1 contact " << ref.contact
                          << " distance*s " << ref.distance * c.s << ", scaled contact " << got.contact << " distance "
                          << got.distance;
        }
      }
      EXPECT_EQ(differ, 0u) << "d=" << ds[k];
      EXPECT_LT(skipped, probes.size() / 100);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Probes exactly on features

TEST(FeatureProbes, VerticesEdgesFacesRadiusBoundaryAndBothSides) {
  const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh("elephant.off"));
  const ClodBuilder builder(mesh);
  const auto set = std::make_shared<const ClodSphereSet>(builder.build(0.02));
  const ClodDetector det(mesh, set);
  const double size = mesh->diagonal();
  std::mt19937_64 rng(31);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  ContactResult got;
  std::size_t cases = 0;
  auto expectAgrees = [&](const Vec3& p, double r, const char* what, std::size_t t) {
    const ContactResult ref = bruteForceQuery(*mesh, p, r);
    det.query(p, r, DetectionMode::Exact, got);
    ++cases;
    ASSERT_EQ(got.contact, ref.contact) << what << " triangle " << t << " r=" << r;
    if (ref.contact) {
      ASSERT_NEAR(got.distance, ref.distance, 1e-9 * std::max(ref.distance, r) + 1e-15 * size) << what << " " << t;
      ASSERT_LE((got.point - ref.point).norm(), 1e-9 * size) << what << " " << t;
      ASSERT_TRUE(got.normal.allFinite());
    }
  };
  for (std::size_t t = 0; t < mesh->size(); t += 7) {
    const Vec3 &a = mesh->vertex(t, 0), &b = mesh->vertex(t, 1), &c = mesh->vertex(t, 2);
    // On a vertex: distance exactly 0, contact even at r = 0.
    det.query(a, 0.0, DetectionMode::Exact, got);
    ASSERT_TRUE(got.contact) << "vertex of triangle " << t;
    ASSERT_EQ(got.distance, 0.0);
    expectAgrees(a, 0.0, "vertex", t);
    expectAgrees(b, 0.004, "vertex", t);
    // On an edge and on the face (to rounding).
    const double s = u(rng);
    expectAgrees(a + s * (b - a), 0.0, "edge", t);
    expectAgrees(a + s * (c - a), 0.003, "edge", t);
    double w1 = u(rng), w2 = u(rng);
    if (w1 + w2 > 1) {
      w1 = 1 - w1;
      w2 = 1 - w2;
    }
    const Vec3 q = a + w1 * (b - a) + w2 * (c - a);
    expectAgrees(q, 0.0, "face", t);
    expectAgrees(q, 0.005, "face", t);
    const Vec3& n = mesh->normals[t];
    if (n.isZero(0.0)) continue;
    // Both sides of the face at 1e-12 relative distance.
    for (double side : {1.0, -1.0}) {
      const Vec3 p = q + side * 1e-12 * size * n;
      expectAgrees(p, 1e-12 * size, "face side", t);
      expectAgrees(p, 2e-12 * size, "face side", t);
      expectAgrees(p, 0.0, "face side", t);
    }
    // On the pointer-radius boundary: the pointer just touching, just short, just over.
    const double r = 0.004;
    const Vec3 outside = q + r * n;
    for (double rr : {r, std::nextafter(r, 0.0), std::nextafter(r, 1.0), r * (1 - 1e-12), r * (1 + 1e-12)})
      expectAgrees(outside, rr, "radius boundary", t);
  }
  EXPECT_GT(cases, 5000u);
}

TEST(FeatureProbes, CubeFeaturesHaveExactAnswers) {
  const auto mesh = std::make_shared<const TriangleMesh>(cubeMesh());
  const ClodBuilder builder(mesh);
  const ClodDetector det(mesh, std::make_shared<const ClodSphereSet>(builder.build(0.0)));
  ContactResult got;
  // Above the middle of the top face: distance 0.25, normal +z.
  det.query(Vec3(0.5, 0.5, 1.25), 0.25, DetectionMode::Exact, got);
  ASSERT_TRUE(got.contact);
  EXPECT_EQ(got.distance, 0.25);
  EXPECT_TRUE(got.normal.isApprox(Vec3(0, 0, 1)));
  det.query(Vec3(0.5, 0.5, 1.25), std::nextafter(0.25, 0.0), DetectionMode::Exact, got);
  EXPECT_FALSE(got.contact);
  // Beyond a corner: the corner is the closest point; paper misses it, exact and spheres do not.
  const Vec3 p(1.1, 1.1, 1.1);
  det.query(p, 0.2, DetectionMode::Exact, got);
  ASSERT_TRUE(got.contact);
  EXPECT_EQ(got.point, Vec3(1, 1, 1));
  det.query(p, 0.2, DetectionMode::Paper, got);
  EXPECT_FALSE(got.contact) << "Algorithm 2 sees faces only";
  det.query(p, 0.2, DetectionMode::Spheres, got);
  EXPECT_TRUE(got.contact);
  // Inside the cube, at the centre: every face at 0.5.
  det.query(Vec3(0.5, 0.5, 0.5), 0.5, DetectionMode::Exact, got);
  ASSERT_TRUE(got.contact);
  EXPECT_EQ(got.distance, 0.5);
  EXPECT_TRUE(got.normal.allFinite());
}

// ---------------------------------------------------------------------------------------------
// Property tests over random meshes and probes (fixed seeds)

TEST(Property, RandomClosedBlobs) {
  std::mt19937_64 rng(20240611);
  CheckStats stats;
  for (int m = 0; m < 24; ++m) {
    const auto mesh = normalized(randomBlob(rng, 6 + m % 9, 8 + m % 13, 0.1 + 0.6 * (m % 4) / 3.0));
    const ClodBuilder builder(mesh);
    const double d = std::uniform_real_distribution<double>(0.0, 0.1)(rng);
    const auto probes = probesFor(*mesh, 150, 50, 0.03, 1000 + m);
    checkAgainstBruteForce(mesh, builder.build(d), probes, {0.0, 0.01, 0.04}, "blob " + std::to_string(m), &stats);
  }
  EXPECT_GT(stats.probes, 5000u);
  EXPECT_GT(stats.contacts, stats.probes / 10);
}

TEST(Property, RandomTriangleSoups) {
  std::mt19937_64 rng(777001);
  CheckStats stats;
  for (int m = 0; m < 24; ++m) {
    const auto mesh = normalized(randomSoup(rng, 5 + 12 * m));
    const ClodBuilder builder(mesh);
    const double d = std::uniform_real_distribution<double>(0.0, 0.1)(rng);
    const auto probes = probesFor(*mesh, 150, 50, 0.03, 2000 + m);
    checkAgainstBruteForce(mesh, builder.build(d), probes, {0.0, 0.01, 0.04}, "soup " + std::to_string(m), &stats);
  }
  EXPECT_GT(stats.probes, 5000u);
  EXPECT_GT(stats.contacts, stats.probes / 10);
}

TEST(Property, RandomMeshesAtRandomScaleAndOffset) {
  // Not normalised: coordinates of a few units away from the origin, as a mesh file gives them.
  std::mt19937_64 rng(4711);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  CheckStats stats;
  for (int m = 0; m < 24; ++m) {
    TriangleMesh raw = m % 2 ? randomSoup(rng, 10 + 7 * m) : randomBlob(rng, 5 + m % 7, 6 + m % 11, 0.5);
    const double s = std::pow(10.0, 1.5 * u(rng));
    const Vec3 offset = 5.0 * Vec3(u(rng), u(rng), u(rng));
    std::vector<Vec3> v = raw.vertices;
    for (Vec3& x : v) x = s * x + offset;
    const auto mesh = std::make_shared<const TriangleMesh>(makeMesh(v, raw.triangles, "random"));
    const double size = mesh->diagonal();
    const ClodBuilder builder(mesh);
    const double d = std::uniform_real_distribution<double>(0.0, 0.1)(rng) * size;
    const auto probes = probesFor(*mesh, 150, 50, 0.03 * size, 3000 + m);
    checkAgainstBruteForce(mesh, builder.build(d), probes, {0.0, 0.003 * size, 0.02 * size},
                           "random mesh " + std::to_string(m), &stats);
  }
  EXPECT_GT(stats.probes, 5000u);
  EXPECT_GT(stats.contacts, stats.probes / 10);
}

// Regression (fuzz/fuzz_query): a finite but huge probe and radius. r * r and |p - q|^2 both overflow to
// inf, and inf <= inf reported a contact at distance inf (depth -inf): an infinite force. Finite
// inputs must give either no contact or finite fields, in the detector and in the reference alike.
TEST(Property, HugeFiniteInputsGiveFiniteAnswersOrNone) {
  const auto mesh = std::make_shared<const TriangleMesh>(cubeMesh());
  const ClodBuilder builder(mesh);
  const Vec3 p(2.4987006400419e-310, 7.290346720383824e-304, -5.486124089170283e+303);
  const double r = 4.737909208752573e+226;
  auto finiteOrNone = [](const ContactResult& c) {
    return !c.contact || (c.point.allFinite() && c.normal.allFinite() && std::isfinite(c.distance) &&
                          std::isfinite(c.depth));
  };
  EXPECT_TRUE(finiteOrNone(bruteForceQuery(*mesh, p, r))) << "bruteForceQuery";
  for (double d : {0.0, 0.3})
    for (FastLevel fast : {FastLevel::Grid, FastLevel::Hierarchy, FastLevel::Flat}) {
      const ClodDetector det(mesh, std::make_shared<const ClodSphereSet>(builder.build(d)), fast);
      for (DetectionMode mode : {DetectionMode::Exact, DetectionMode::Paper, DetectionMode::Spheres}) {
        ContactResult c;
        det.query(p, r, mode, c);
        EXPECT_TRUE(finiteOrNone(c)) << "fast " << int(fast) << " mode " << toString(mode) << " d=" << d
                                     << ": contact with distance " << c.distance << " depth " << c.depth;
        det.query(Vec3(0.5, 0.5, 1e200), 1e180, mode, c);
        EXPECT_TRUE(finiteOrNone(c)) << "p.z = 1e200, r = 1e180";
      }
    }
}

TEST(Property, RandomQueriesAreNeverNaN) {
  // Arbitrary (also huge and tiny) finite probes and radii on a real mesh: finite answers or none.
  const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh("head.off"));
  const ClodDetector det(mesh, std::make_shared<const ClodSphereSet>(ClodBuilder(mesh).build(0.03)));
  std::mt19937_64 rng(99);
  std::uniform_real_distribution<double> e(-300.0, 300.0), u(-1.0, 1.0);
  ContactResult got;
  for (int i = 0; i < 20000; ++i) {
    const Vec3 p = i % 2 ? Vec3(u(rng), u(rng), u(rng)) * std::pow(10.0, e(rng) / 30.0)
                         : Vec3(std::pow(10.0, e(rng)) * u(rng), u(rng), u(rng));
    const double r = std::pow(10.0, e(rng) / 20.0);
    for (DetectionMode mode : {DetectionMode::Exact, DetectionMode::Paper, DetectionMode::Spheres}) {
      det.query(p, r, mode, got);
      if (got.contact) {
        ASSERT_TRUE(got.point.allFinite() && got.normal.allFinite() && std::isfinite(got.distance) &&
                    std::isfinite(got.depth))
            << "probe " << p.transpose() << " r " << r << " mode " << toString(mode);
      }
    }
  }
}

}  // namespace
