// TightClustering ("tight"): coverage on every shared mesh, exact detection equal to brute force on its
// sets, a sphere count that never grows with d, one sphere per triangle, the excess bound it promises
// (checked with a brute-force distance), the points-only fallback and SurfaceDistance.

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/clustering.h"
#include "clod_haptics/core/detector.h"
#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/geometry.h"
#include "clod_haptics/core/probes.h"
#include "clod_haptics/core/sphere_set.h"
#include "clod_haptics/core/tight_clustering.h"
#include "test_helpers.h"

namespace {

using namespace clod_haptics;
using clod_test::coverageProblems;

// Brute-force signed distance: the nearest point over all triangles, negative on the outer side of
// the nearest triangle's face normal. ambiguous is set when triangles within a hair of the nearest
// distance disagree on the side (a centre equidistant from two faces).
double referenceSignedDistance(const TriangleMesh& mesh, const Vec3& p, bool& ambiguous) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t t = 0; t < mesh.size(); ++t)
    best =
        std::min(best, (closestPointOnTriangle(p, mesh.vertex(t, 0), mesh.vertex(t, 1), mesh.vertex(t, 2)) - p).norm());
  int inside = 0, outside = 0;
  for (std::size_t t = 0; t < mesh.size(); ++t) {
    const Vec3 q = closestPointOnTriangle(p, mesh.vertex(t, 0), mesh.vertex(t, 1), mesh.vertex(t, 2));
    if ((q - p).norm() > best * (1.0 + 1e-9) + 1e-15) continue;
    ((p - q).dot(mesh.normals[t]) > 0.0 ? outside : inside) += 1;
  }
  ambiguous = inside > 0 && outside > 0;
  return outside > 0 && inside == 0 ? -best : best;
}

// Probes whose exact answer for a pointer of radius r differs from the brute-force reference (contact, or distance
// beyond 1e-9 r); probes on the boundary (distance r within 1e-9 r) are skipped: either answer is right. contacts:
// the reference contacts among the probes compared.
std::size_t mismatches(const ClodDetector& detector, const std::vector<Vec3>& probes,
                       const std::vector<ContactResult>& reference, double r, std::size_t& contacts) {
  std::size_t wrong = 0;
  ContactResult out;
  for (std::size_t i = 0; i < probes.size(); ++i) {
    const ContactResult& ref = reference[i];
    if (std::abs(ref.distance - r) <= 1e-9 * r) continue;
    detector.query(probes[i], r, DetectionMode::Exact, out);
    contacts += ref.contact;
    wrong += out.contact != ref.contact || (ref.contact && std::abs(out.distance - ref.distance) > 1e-9 * r);
  }
  return wrong;
}

TEST(TightClustering, RegisteredByName) {
  EXPECT_NE(std::dynamic_pointer_cast<const TightClustering>(makeClustering("tight")), nullptr);
  EXPECT_EQ(makeClustering("Tight"), nullptr);
}

TEST(TightClustering, CoverageAndOneSpherePerTriangleOnEverySharedMesh) {
  const auto meshes = clod_test::sharedMeshes();
  ASSERT_GE(meshes.size(), 6u);
  for (const auto& path : meshes) {
    const auto mesh = clod_test::loadNormalized(path);
    const ClodBuilder builder(mesh, std::make_shared<PaperPlacement>(), makeClustering("tight"));
    for (double d : {0.0, 0.02, 0.04, 0.08}) {
      if (d == 0.0 && mesh->size() > 30000) continue;  // one sphere per triangle: seconds, nothing new
      SCOPED_TRACE(clod_test::baseName(path) + " d=" + std::to_string(d));
      const ClodSphereSet set = builder.build(d);
      const auto problems = coverageProblems(*mesh, set);
      EXPECT_TRUE(problems.empty()) << clod_test::join(problems);
      EXPECT_EQ(set.stats.spheres, set.size());
      // Each triangle is listed by at least one sphere. One within the piece edge is listed by exactly one unless it
      // lies in a thin patch, whose items are halved further (then coverageProblems checks the union of its spheres);
      // at d = 0 no patch is thin (no sphere of one piece passes the bound) and the partition is exact.
      const double pieceEdge = TightClustering::kDefaultPieceEdge * mesh->diagonal();
      std::vector<std::size_t> listed(mesh->size(), 0), pieces(mesh->size(), 0);
      for (std::uint32_t t : set.triangles) ++listed[t];
      std::size_t allPieces = 0;
      for (std::size_t t = 0; t < mesh->size(); ++t) {
        const Vec3 &a = mesh->vertex(t, 0), &b = mesh->vertex(t, 1), &c = mesh->vertex(t, 2);
        // Pieces by a recount of the halving rule: halve the longest edge until every edge is within the piece edge.
        std::vector<std::array<Vec3, 3>> stack{{a, b, c}};
        while (!stack.empty()) {
          const std::array<Vec3, 3> p = stack.back();
          stack.pop_back();
          const double e[3] = {(p[1] - p[0]).norm(), (p[2] - p[1]).norm(), (p[0] - p[2]).norm()};
          const int k = e[0] >= e[1] && e[0] >= e[2] ? 0 : (e[1] >= e[2] ? 1 : 2);
          if (e[k] <= pieceEdge) {
            ++pieces[t];
            continue;
          }
          const Vec3 m = 0.5 * (p[k] + p[(k + 1) % 3]);
          stack.push_back({p[k], m, p[(k + 2) % 3]});
          stack.push_back({m, p[(k + 1) % 3], p[(k + 2) % 3]});
        }
        allPieces += pieces[t];
        ASSERT_GE(listed[t], 1u) << "triangle " << t;
        if (d == 0.0) {
          ASSERT_LE(listed[t], pieces[t]) << "triangle " << t;
        }
      }
      if (d == 0.0) {
        EXPECT_EQ(set.size(), allPieces) << "d = 0: one sphere per piece (per triangle within the piece edge)";
      }
      // Radii stay tight: a sphere listing only triangles listed once and not split has some listed vertex on it; one
      // listing a split triangle reaches no farther than its triangles' vertices.
      for (std::size_t i = 0; i < set.size(); ++i) {
        double far = 0.0;
        bool split = false;
        for (const std::uint32_t* t = set.begin(i); t != set.end(i); ++t) {
          split = split || pieces[*t] > 1 || listed[*t] > 1;
          for (int v = 0; v < 3; ++v) far = std::max(far, (mesh->vertex(*t, v) - set.centres[i]).norm());
        }
        if (split) {
          ASSERT_LE(set.radii[i], far * (1 + 1e-12)) << "sphere " << i;
        } else {
          ASSERT_NEAR(set.radii[i], far, 1e-12) << "sphere " << i;
        }
      }
    }
  }
}

TEST(TightClustering, SphereCountNonIncreasingInDistance) {
  for (const auto& path : clod_test::sharedMeshes()) {
    const auto mesh = clod_test::loadNormalized(path);
    const ClodBuilder builder(mesh, std::make_shared<PaperPlacement>(), makeClustering("tight"));
    std::size_t previous = std::numeric_limits<std::size_t>::max();
    for (double d : {0.0, 0.005, 0.01, 0.02, 0.03, 0.04, 0.05, 0.06, 0.08, 0.12, 0.2, 0.5, 2.0}) {
      if (d == 0.0 && mesh->size() > 30000) continue;  // n spheres, as the coverage test checks
      const std::size_t n = builder.build(d).size();
      EXPECT_LE(n, previous) << clod_test::baseName(path) << " d=" << d;
      previous = n;
    }
    // In the unit cube no sphere's cap exceeds R^3 <= 3^(3/2) < 2^3: d = 2 keeps the root.
    EXPECT_EQ(previous, 1u) << clod_test::baseName(path);
  }
}

TEST(TightClustering, CapOfEverySphereHoldsAtMostABallOfRadiusD) {
  // The strategy's own promise, checked with a brute-force signed distance: for every sphere with more
  // than one triangle, h = R - rho and h^2 (3R - h) / 4 <= d^3.
  for (const std::string name : {"head.off", "elephant.off"}) {
    const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh(name));
    const ClodBuilder builder(mesh, std::make_shared<PaperPlacement>(), makeClustering("tight"));
    for (double d : {0.02, 0.05}) {
      SCOPED_TRACE(name + " d=" + std::to_string(d));
      const ClodSphereSet set = builder.build(d);
      std::size_t checked = 0;
      for (std::size_t i = 0; i < set.size(); ++i) {
        if (set.end(i) - set.begin(i) < 2) continue;
        bool ambiguous = false;
        const double rho = referenceSignedDistance(*mesh, set.centres[i], ambiguous);
        if (ambiguous) continue;
        const double r = set.radii[i];
        const double h = std::clamp(r - rho, 0.0, 2.0 * r);
        EXPECT_LE(0.25 * h * h * (3.0 * r - h), d * d * d * (1.0 + 1e-9)) << "sphere " << i;
        ++checked;
      }
      EXPECT_GT(checked, 0u);
    }
  }
}

// A closed box centred at the origin with half sizes h, each face a grid of n x n quads (two triangles each),
// outward wound; faces do not share vertices.
std::shared_ptr<const TriangleMesh> boxMesh(const Vec3& h, int n, const std::string& name) {
  std::vector<Vec3> v;
  std::vector<Triangle> t;
  for (int axis = 0; axis < 3; ++axis)
    for (int sign : {-1, 1}) {
      const int a = (axis + 1) % 3, b = (axis + 2) % 3;
      Vec3 origin = Vec3::Zero(), du = Vec3::Zero(), dv = Vec3::Zero();
      origin[axis] = sign * h[axis];
      origin[a] = -h[a];
      origin[b] = -h[b];
      du[a] = 2 * h[a];
      dv[b] = 2 * h[b];
      const auto first = static_cast<std::uint32_t>(v.size());
      for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) v.push_back(origin + du * (double(i) / n) + dv * (double(j) / n));
      auto at = [&](int i, int j) { return first + static_cast<std::uint32_t>(j * (n + 1) + i); };
      for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
          if (sign > 0) {  // du x dv points along +axis
            t.push_back(Triangle{{at(i, j), at(i + 1, j), at(i + 1, j + 1)}});
            t.push_back(Triangle{{at(i, j), at(i + 1, j + 1), at(i, j + 1)}});
          } else {
            t.push_back(Triangle{{at(i, j), at(i + 1, j + 1), at(i + 1, j)}});
            t.push_back(Triangle{{at(i, j), at(i, j + 1), at(i + 1, j + 1)}});
          }
        }
    }
  return std::make_shared<const TriangleMesh>(makeMesh(v, t, name));
}

// A closed cylinder along x from -half to half of radius a, `segments` around, `rings` along (1: long triangles).
std::shared_ptr<const TriangleMesh> cylinderMesh(double a, double half, int segments, int rings,
                                                 const std::string& name) {
  std::vector<Vec3> v;
  std::vector<Triangle> t;
  for (int k = 0; k <= rings; ++k)
    for (int s = 0; s < segments; ++s) {
      const double phi = 2 * M_PI * s / segments;
      v.push_back(Vec3(-half + 2 * half * k / rings, a * std::cos(phi), a * std::sin(phi)));
    }
  auto at = [&](int k, int s) { return static_cast<std::uint32_t>(k * segments + (s % segments)); };
  for (int k = 0; k < rings; ++k)
    for (int s = 0; s < segments; ++s) {
      t.push_back(Triangle{{at(k, s), at(k + 1, s + 1), at(k + 1, s)}});
      t.push_back(Triangle{{at(k, s), at(k, s + 1), at(k + 1, s + 1)}});
    }
  const auto c0 = static_cast<std::uint32_t>(v.size());
  v.push_back(Vec3(-half, 0, 0));
  v.push_back(Vec3(half, 0, 0));
  for (int s = 0; s < segments; ++s) {
    t.push_back(Triangle{{c0, at(0, s), at(0, s + 1)}});
    t.push_back(Triangle{{c0 + 1, at(rings, s + 1), at(rings, s)}});
  }
  return std::make_shared<const TriangleMesh>(makeMesh(v, t, name));
}

// A hollow tube along x from -half to half: a wall of thickness t about the radius a, `segments` around, `rings`
// along, its ends closed by flat rings; outward wound (the inner wall faces the axis).
std::shared_ptr<const TriangleMesh> tubeShellMesh(double a, double t, double half, int segments, int rings,
                                                  const std::string& name) {
  std::vector<Vec3> v;
  std::vector<Triangle> tri;
  for (const double radius : {a + 0.5 * t, a - 0.5 * t})
    for (int k = 0; k <= rings; ++k)
      for (int s = 0; s < segments; ++s) {
        const double phi = 2 * M_PI * s / segments;
        v.push_back(Vec3(-half + 2 * half * k / rings, radius * std::cos(phi), radius * std::sin(phi)));
      }
  auto at = [&](int wall, int k, int s) {
    return static_cast<std::uint32_t>((wall * (rings + 1) + k) * segments + (s % segments));
  };
  auto quad = [&](std::uint32_t p, std::uint32_t q, std::uint32_t r, std::uint32_t u) {  // p q r u counterclockwise
    tri.push_back(Triangle{{p, q, r}});
    tri.push_back(Triangle{{p, r, u}});
  };
  for (int k = 0; k < rings; ++k)
    for (int s = 0; s < segments; ++s) {
      quad(at(0, k, s), at(0, k, s + 1), at(0, k + 1, s + 1), at(0, k + 1, s));  // outer wall, facing out
      quad(at(1, k, s), at(1, k + 1, s), at(1, k + 1, s + 1), at(1, k, s + 1));  // inner wall, facing the axis
    }
  for (int s = 0; s < segments; ++s) {
    quad(at(0, 0, s), at(1, 0, s), at(1, 0, s + 1), at(0, 0, s + 1));                  // x = -half, facing -x
    quad(at(0, rings, s), at(0, rings, s + 1), at(1, rings, s + 1), at(1, rings, s));  // x = half, facing +x
  }
  return std::make_shared<const TriangleMesh>(makeMesh(v, tri, name));
}

// Thin-part models: plates 0.005 to 0.03 thick (fine and long triangles), thin cylinders (rings and long triangles).
std::vector<std::shared_ptr<const TriangleMesh>> thinMeshes() {
  return {
      boxMesh(Vec3(0.4, 0.25, 0.0025), 24, "plate 0.005"), boxMesh(Vec3(0.4, 0.25, 0.015), 1, "plate 0.03 long"),
      boxMesh(Vec3(0.4, 0.25, 0.005), 12, "plate 0.01"),   cylinderMesh(0.01, 0.4, 12, 1, "cylinder 0.02 long"),
      cylinderMesh(0.02, 0.4, 16, 30, "cylinder 0.04"),    tubeShellMesh(0.2, 0.004, 0.2, 48, 20, "tube shell 0.004")};
}

// Every point of every triangle lies in some sphere listing that triangle: checked at the points of a barycentric
// grid on every triangle (corners and edges included), 8 steps per edge or 4 per smallest listing radius along the
// longest edge if more (a triangle split over small spheres). Returns the misses.
std::size_t uncoveredSamples(const TriangleMesh& mesh, const ClodSphereSet& set) {
  std::vector<std::vector<std::uint32_t>> listing(mesh.size());
  for (std::size_t i = 0; i < set.size(); ++i)
    for (const std::uint32_t* t = set.begin(i); t != set.end(i); ++t)
      listing[*t].push_back(static_cast<std::uint32_t>(i));
  std::size_t misses = 0;
  for (std::size_t t = 0; t < mesh.size(); ++t)
    misses += clod_test::missedSamples(mesh, set, t, listing[t],
                                       clod_test::samplingSteps(mesh, set, t, listing[t], 512.0), 1e-9, 1e-12);
  return misses;
}

TEST(TightClustering, EveryPointOfEveryTriangleIsInASphereListingIt) {
  std::vector<std::shared_ptr<const TriangleMesh>> meshes = thinMeshes();
  for (const auto& path : clod_test::sharedMeshes()) meshes.push_back(clod_test::loadNormalized(path));
  for (const auto& mesh : meshes) {
    const ClodBuilder builder(mesh, std::make_shared<PaperPlacement>(), makeClustering("tight"));
    for (double d : {0.0, 0.01, 0.02, 0.05}) {
      if (d == 0.0 && mesh->size() > 30000) continue;  // one sphere per triangle: seconds, nothing new
      SCOPED_TRACE(mesh->name + " d=" + std::to_string(d));
      EXPECT_EQ(uncoveredSamples(*mesh, builder.build(d)), 0u);
    }
  }
}

TEST(TightClustering, SpheresInThinPartsScoreTheVolumeOutsideOnEverySide) {
  // Analytic bound of the volume outside: a ball of radius R meets a plate of thickness t in at most pi R^2 t and
  // a cylinder of radius a in at most 2 pi a^2 R, so over 4/3 pi at least R^3 - 3/4 t R^2 (plate) or R^3 - 3/2 a^2 R
  // (cylinder) of it is outside. A set scoring every side keeps that below d^3 (the 32-direction estimate within
  // half of it); a score of one side lets spheres of several thicknesses through.
  struct Case {
    std::shared_ptr<const TriangleMesh> mesh;
    bool plate;
    double size;  // thickness t or radius a
  };
  for (const Case& c : {Case{boxMesh(Vec3(0.4, 0.25, 0.005), 40, "plate 0.01"), true, 0.01},
                        Case{boxMesh(Vec3(0.4, 0.25, 0.0025), 40, "plate 0.005"), true, 0.005},
                        Case{cylinderMesh(0.015, 0.4, 16, 60, "cylinder 0.03"), false, 0.015}}) {
    const ClodBuilder builder(c.mesh, std::make_shared<PaperPlacement>(), makeClustering("tight"));
    std::size_t checked = 0;  // spheres of more than one triangle, over the distances
    for (double d : {0.01, 0.02, 0.04}) {
      SCOPED_TRACE(c.mesh->name + " d=" + std::to_string(d));
      const ClodSphereSet set = builder.build(d);
      std::size_t over = 0;
      for (std::size_t i = 0; i < set.size(); ++i) {
        if (set.end(i) - set.begin(i) < 2) continue;
        const double r = set.radii[i];
        const double outside = c.plate ? r * r * r - 0.75 * c.size * r * r : r * r * r - 1.5 * c.size * c.size * r;
        over += outside > 1.5 * d * d * d;
        ++checked;
      }
      EXPECT_EQ(over, 0u) << "of " << set.size() << " spheres";
    }
    EXPECT_GT(checked, 10u) << c.mesh->name;
  }
}

TEST(TightClustering, ThinPlatePatchesApproachTheDensestCovering) {
  // A plate of thickness t much less than R: each sphere meets a face in a disc of radius at most R, so the discs
  // cover the face, sum pi R_i^2 >= A, and (power means) sum R_i^3 >= N (A / (pi N))^(3/2): the least volume any N
  // spheres covering it can have. Equal discs on a hexagonal lattice need 1.209 A, about 1.33 times that bound in
  // volume; square patches 1.57 A (1.97 times), 2:1 rectangles 1.96 A (2.76 times). Thin patches are settled towards
  // the hexagons (not reached: the plate's edges, the pieces). Measured: 1.90 to 2.01 times the bound with 4 k-centre
  // rounds and Lloyd's rounds stopped under 1% moving (1.88 to 1.96 with 5 rounds and no stop), 2.00 to 2.11 before
  // the k-centre rounds; the tree's patches as cut (before settling) 2.59 to 3.03.
  for (const auto& c : {std::make_pair(Vec3(0.3, 0.2, 0.002), 30), std::make_pair(Vec3(0.25, 0.25, 0.004), 20)}) {
    const auto mesh = boxMesh(c.first, c.second, "plate");
    const double area = 4.0 * c.first.x() * c.first.y();
    const ClodBuilder builder(mesh, std::make_shared<PaperPlacement>(), makeClustering("tight"));
    for (std::size_t n : {100u, 300u}) {
      const ClodSphereSet set = builder.buildAtMost(n);
      ASSERT_TRUE(coverageProblems(*mesh, set).empty());
      const double count = static_cast<double>(set.size());
      double volume = 0.0;
      for (double r : set.radii) volume += r * r * r;
      const double bound = count * std::pow(area / (M_PI * count), 1.5);
      EXPECT_LT(volume / bound, 2.1) << set.size() << " spheres, half sizes " << c.first.transpose();
    }
  }
}

TEST(TightClustering, HollowTubesAreCutIntoPatchesOfTheirWall) {
  // A hollow tube's wall is a plate rolled up: N spheres covering it need sum R_i^3 of at least about
  // N (A / (pi N))^(3/2), A the wall's area (the plate's bound; a ball of radius R well under the tube's radius meets
  // the wall's middle surface in about pi R^2). Cut into rings, the tree gave spheres up to 0.41 to 0.75 of the
  // tube's radius, centred in the empty space the tube encloses: 3.3 to 4.7 times that bound (measured before the
  // hollow rule); cut into patches of the wall, 2.0 to 2.2 times, the largest sphere 0.15 to 0.27 of the radius
  // (with 5 k-centre rounds 1.90 to 2.05 times, 0.14 to 0.25; with 4 and Lloyd's rounds stopped under 1% moving 1.95
  // to 2.09 times, 0.15 to 0.26).
  for (const auto& c : {std::make_pair(0.2, 0.004), std::make_pair(0.15, 0.01)}) {
    const double a = c.first, t = c.second, half = 0.2;
    const auto mesh = tubeShellMesh(a, t, half, 48, 20, "tube shell");
    double volume = 0.0;  // the winding: outward, so positive
    for (std::size_t k = 0; k < mesh->size(); ++k)
      volume += mesh->vertex(k, 0).dot(mesh->vertex(k, 1).cross(mesh->vertex(k, 2))) / 6.0;
    ASSERT_NEAR(volume, 2 * M_PI * a * t * 2 * half, 0.05 * 2 * M_PI * a * t * 2 * half);
    const double area = 2 * M_PI * a * 2 * half;
    const ClodBuilder builder(mesh, std::make_shared<PaperPlacement>(), makeClustering("tight"));
    for (std::size_t n : {150u, 400u}) {
      const ClodSphereSet set = builder.buildAtMost(n);
      ASSERT_TRUE(coverageProblems(*mesh, set).empty());
      const double count = static_cast<double>(set.size());
      double cubes = 0.0, largest = 0.0;
      for (double r : set.radii) {
        cubes += r * r * r;
        largest = std::max(largest, r);
      }
      const double bound = count * std::pow(area / (M_PI * count), 1.5);
      EXPECT_LT(cubes / bound, 3.0) << set.size() << " spheres, radius " << a << ", wall " << t;
      EXPECT_LT(largest, 0.35 * a) << set.size() << " spheres, radius " << a << ", wall " << t;
    }
  }
}

TEST(TightClustering, ExactDetectionEqualsBruteForce) {
  for (const std::string name : {"head.off", "mannequin-devil.off", "mesh_with_border.off"}) {
    const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh(name));
    const ClodBuilder builder(mesh, std::make_shared<PaperPlacement>(), makeClustering("tight"));
    std::vector<Vec3> probes = nearSurfaceProbes(*mesh, 1500, 0.03, 21);
    const std::vector<Vec3> uniform = uniformProbes(*mesh, 500, 0.03, 22);
    probes.insert(probes.end(), uniform.begin(), uniform.end());
    for (double r : {0.005, 0.02}) {
      std::vector<ContactResult> reference(probes.size());
      clod_test::parallelFor(probes.size(), 2, [&](std::size_t b, std::size_t e) {
        for (std::size_t i = b; i < e; ++i) reference[i] = bruteForceQuery(*mesh, probes[i], r);
      });
      for (double d : {0.01, 0.04, 0.1}) {
        const auto set = std::make_shared<const ClodSphereSet>(builder.build(d));
        for (const FastLevel fast : {FastLevel::Grid, FastLevel::Hierarchy}) {
          const ClodDetector detector(mesh, set, fast, r);
          std::size_t contacts = 0;
          EXPECT_EQ(mismatches(detector, probes, reference, r, contacts), 0u) << name << " d=" << d << " r=" << r;
          EXPECT_GT(contacts, 0u) << name;
        }
      }
    }
  }
}

TEST(TightClustering, LongTrianglesAreSplitOverSmallerSpheres) {
  // Models of long triangles (a plate of 12, a cylinder of 48, 0.8 long, 0.02 to 0.03 thick): each triangle is
  // split into pieces over several spheres, so no sphere has to hold a whole long triangle. Against the same
  // strategy without splitting (pieceEdge 0): coverage from the definition, a largest sphere several times smaller,
  // and exact detection equal to brute force through every fast level.
  for (const auto& mesh :
       {boxMesh(Vec3(0.4, 0.25, 0.015), 1, "plate 0.03 long"), cylinderMesh(0.01, 0.4, 12, 1, "cylinder 0.02 long")}) {
    const ClodBuilder split(mesh, std::make_shared<PaperPlacement>(), std::make_shared<TightClustering>());
    const ClodBuilder whole(mesh, std::make_shared<PaperPlacement>(), std::make_shared<TightClustering>(0.0));
    const double pieceEdge = TightClustering::kDefaultPieceEdge * mesh->diagonal();
    std::vector<Vec3> probes = nearSurfaceProbes(*mesh, 1500, 0.03, 31);
    const std::vector<Vec3> uniform = uniformProbes(*mesh, 300, 0.03, 32);
    probes.insert(probes.end(), uniform.begin(), uniform.end());
    const double r = 0.005;
    std::vector<ContactResult> reference(probes.size()), referenceFar(probes.size());
    for (std::size_t i = 0; i < probes.size(); ++i) {
      reference[i] = bruteForceQuery(*mesh, probes[i], r);
      referenceFar[i] = bruteForceQuery(*mesh, probes[i], 3 * r);
    }
    for (double d : {0.0, 0.005, 0.01, 0.02}) {
      SCOPED_TRACE(mesh->name + " d=" + std::to_string(d));
      const auto set = std::make_shared<const ClodSphereSet>(split.build(d));
      const ClodSphereSet unsplit = whole.build(d);
      EXPECT_EQ(fitProblem(*mesh, *set), "");
      const auto problems = coverageProblems(*mesh, *set);
      EXPECT_TRUE(problems.empty()) << clod_test::join(problems);
      EXPECT_EQ(uncoveredSamples(*mesh, *set), 0u);
      EXPECT_GT(set->triangles.size(), mesh->size()) << "long triangles are listed by several spheres";
      const double largest = *std::max_element(set->radii.begin(), set->radii.end());
      const double largestWhole = *std::max_element(unsplit.radii.begin(), unsplit.radii.end());
      // A piece's edges are within the piece edge: a single piece's sphere reaches it from an inward centre.
      EXPECT_LT(largest, 0.25 * largestWhole) << largest << " against " << largestWhole;
      if (d <= 0.005) {
        EXPECT_LE(largest, 2.0 * pieceEdge);
      }
      for (const FastLevel fast : {FastLevel::Flat, FastLevel::Hierarchy, FastLevel::Grid}) {
        const ClodDetector detector(mesh, set, fast, r);
        std::size_t contacts = 0, farContacts = 0;
        EXPECT_EQ(mismatches(detector, probes, reference, r, contacts), 0u) << "fast level " << static_cast<int>(fast);
        // Through the spheres alone (the grid's radius is r: a larger pointer goes through the levels' trees).
        EXPECT_EQ(mismatches(detector, probes, referenceFar, 3 * r, farContacts), 0u)
            << "fast level " << static_cast<int>(fast) << ", pointer 3r";
        EXPECT_GT(contacts, 0u);
      }
    }
  }
}

TEST(TightClustering, RepeatedAndConcurrentBuildsAgree) {
  // The subtrees run on several threads: the result must not depend on their timing.
  const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh("mannequin-devil.off"));
  const ClodBuilder builder(mesh, std::make_shared<PaperPlacement>(), makeClustering("tight"));
  std::vector<ClodSphereSet> sets(4);
  clod_test::parallelFor(sets.size(), 2, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) sets[i] = builder.build(0.03);
  });
  for (std::size_t i = 1; i < sets.size(); ++i) {
    EXPECT_EQ(sets[i].centres, sets[0].centres);
    EXPECT_EQ(sets[i].radii, sets[0].radii);
    EXPECT_EQ(sets[i].offsets, sets[0].offsets);
    EXPECT_EQ(sets[i].triangles, sets[0].triangles);
  }
}

// The paper's placement as clusterMesh takes it: the points, and the triangle each wraps.
void placePoints(const TriangleMesh& mesh, std::vector<Vec3>& points, std::vector<std::uint32_t>& wrapped) {
  for (const auto& p : PaperPlacement().place(mesh, nullptr)) {
    points.push_back(p.centre);
    wrapped.push_back(p.triangle);
  }
}

TEST(TightClustering, LabelsFollowTrianglesAndAreNumberedInOrder) {
  const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh("elephant.off"));
  std::vector<Vec3> points;
  std::vector<std::uint32_t> wrapped;
  placePoints(*mesh, points, wrapped);
  std::vector<std::uint32_t> labels;
  std::vector<Vec3> centres;
  const std::uint32_t k = TightClustering().clusterMesh(*mesh, points, wrapped, 0.03, labels, centres, nullptr);
  ASSERT_EQ(labels.size(), points.size());
  ASSERT_EQ(centres.size(), k);
  std::uint32_t next = 0;
  std::vector<std::uint32_t> clusterOfTriangle(mesh->size(), std::numeric_limits<std::uint32_t>::max());
  for (std::size_t i = 0; i < labels.size(); ++i) {
    ASSERT_LE(labels[i], next) << "labels in the order of each cluster's first point";
    if (labels[i] == next) ++next;
    std::uint32_t& c = clusterOfTriangle[wrapped[i]];
    if (c == std::numeric_limits<std::uint32_t>::max()) c = labels[i];
    EXPECT_EQ(c, labels[i]) << "every point wrapping one triangle is in that triangle's cluster";
  }
  EXPECT_EQ(next, k);
  for (const Vec3& c : centres) EXPECT_TRUE(c.allFinite());
}

TEST(TightClustering, HandingOverShrinksSpheresAndGrowsNone) {
  // The same tree cut two ways: clusterMesh without lists gives the leaves as cut (the builder would fit each to
  // its triangles); the builder's set hands each triangle to the sphere it lies deepest in. Every sphere of the
  // second is a leaf of the first (the same centre) with a radius no larger, except the thin patches, which move
  // (settled; none larger than the largest leaf), and the spheres' total volume falls.
  for (const std::string name : {"head.off", "elephant.off", "mannequin-devil.off"}) {
    const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh(name));
    std::vector<Vec3> points;
    std::vector<std::uint32_t> wrapped;
    placePoints(*mesh, points, wrapped);
    const auto whole = std::make_shared<TightClustering>(0.0);  // no pieces: the leaves hold whole triangles
    const ClodBuilder builder(mesh, std::make_shared<PaperPlacement>(), whole);
    for (double d : {0.02, 0.05}) {
      SCOPED_TRACE(name + " d=" + std::to_string(d));
      std::vector<std::uint32_t> labels;
      std::vector<Vec3> centres;
      const std::uint32_t k = whole->clusterMesh(*mesh, points, wrapped, d, labels, centres, nullptr);
      std::vector<double> leafRadius(k, 0.0);  // each leaf's reach over its triangles' vertices
      for (std::size_t i = 0; i < labels.size(); ++i)
        for (int v = 0; v < 3; ++v)
          leafRadius[labels[i]] =
              std::max(leafRadius[labels[i]], (mesh->vertex(wrapped[i], v) - centres[labels[i]]).norm());
      const ClodSphereSet set = builder.build(d);
      ASSERT_LE(set.size(), k);
      double before = 0.0, after = 0.0;
      for (double r : leafRadius) before += r * r * r;
      const double largest = *std::max_element(leafRadius.begin(), leafRadius.end());
      std::size_t moved = 0;
      for (std::size_t i = 0; i < set.size(); ++i) {
        after += set.radii[i] * set.radii[i] * set.radii[i];
        const auto leaf = std::find(centres.begin(), centres.end(), set.centres[i]);
        if (leaf == centres.end()) {
          ++moved;
          EXPECT_LE(set.radii[i], largest) << "sphere " << i << ", settled";
          continue;
        }
        EXPECT_LE(set.radii[i], leafRadius[leaf - centres.begin()] * (1 + 1e-12)) << "sphere " << i << " grew";
      }
      // Measured: head 0 of 1,235 and 248 settled; elephant 10 of 1,388 and 28 of 208 (its ears); mannequin-devil
      // 120 of 1,526 and 42 of 299. Most spheres stay leaves.
      EXPECT_LT(moved, set.size() / 2) << "settled";
      // Measured: 0.69 to 0.93 of the volume as cut (head at d = 0.02 the least changed).
      EXPECT_LT(after, 0.95 * before) << "the spheres' volume, handed over against as cut";
    }
  }
}

TEST(TightClustering, ThinCylinderIsCutIntoRings) {
  // A cylinder of radius a = 0.025 and length 0.8 (16 x 40 faces): covering it with N spheres, the best patches are
  // whole rings of length 0.8 / N around a centre on the axis, each reached by R = sqrt(a^2 + (0.4 / N)^2). Cutting
  // across a ring (what the principal axis of the patch does once the ring is shorter than its girth) leaves
  // patches whose spheres are larger. At the least d with at most N spheres, no sphere is more than 1.25 times that
  // R (the ends are capped by fans of triangles from the axis).
  const auto mesh = cylinderMesh(0.025, 0.4, 16, 40, "cylinder 0.05");
  const ClodBuilder builder(mesh, std::make_shared<PaperPlacement>(), makeClustering("tight"));
  for (std::size_t n : {40u, 100u}) {
    const ClodSphereSet set = builder.buildAtMost(n);
    ASSERT_LE(set.size(), n);
    const double ring = std::sqrt(0.025 * 0.025 + std::pow(0.4 / static_cast<double>(set.size()), 2));
    const double largest = *std::max_element(set.radii.begin(), set.radii.end());
    // Measured: 1.18 and 1.10 times; cutting by the principal axis alone gave 1.47 and 1.34.
    EXPECT_LE(largest, 1.25 * ring) << set.size() << " spheres";
  }
}

TEST(TightClustering, RingsOfLongTrianglesSitOnTheAxis) {
  // A cylinder of radius a = 0.01 and length 0.8 whose 12 sides are long triangles end to end, split into pieces: a
  // ring of pieces is reached by the smallest ball from its axis, and a centre off the axis needs a larger one. The
  // placement's points and the pushed centroids lean to the side where more pieces of a ring lie; the middle of the
  // ring's box does not. At the least d with at most N spheres, away from the ends (where the rings meet the caps'
  // fans, and arcs of both take spheres of their own): every centre within a / 10 of the axis, every radius at most
  // 1.3 a. Measured: on the axis to 1e-4 a, radii up to 1.18 a at 150 and 500 spheres (93 in the level, 62 away from
  // the ends); without the box's middle, up to 0.26 a (149 spheres) and 0.51 a (498) off the axis, radii up to 1.75 a
  // and 1.19 a.
  const double a = 0.01, half = 0.4;
  const auto mesh = cylinderMesh(a, half, 12, 1, "cylinder 0.02 long");
  const ClodBuilder builder(mesh, std::make_shared<PaperPlacement>(), makeClustering("tight"));
  for (std::size_t n : {150u, 500u}) {
    const ClodSphereSet set = builder.buildAtMost(n);
    ASSERT_LE(set.size(), n);
    std::size_t inner = 0;
    double off = 0.0, largest = 0.0;
    for (std::size_t i = 0; i < set.size(); ++i) {
      if (std::abs(set.centres[i].x()) > half - 2.0 * a) continue;
      ++inner;
      off = std::max(off, std::hypot(set.centres[i].y(), set.centres[i].z()));
      largest = std::max(largest, set.radii[i]);
    }
    EXPECT_GT(inner, 40u) << set.size() << " spheres";
    EXPECT_LE(off, 0.1 * a) << set.size() << " spheres";
    EXPECT_LE(largest, 1.3 * a) << set.size() << " spheres";
  }
}

TEST(TightClustering, PointsOnlyClustersStayWithinHalfD) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Vec3> points(3000);
  for (auto& p : points) p = Vec3(u(rng), u(rng), 0.2 * u(rng));
  const TightClustering clustering;
  std::vector<std::uint32_t> labels;
  EXPECT_EQ(clustering.cluster(points, 0.0, labels), points.size());
  std::size_t previous = points.size();
  for (double d : {0.01, 0.05, 0.1, 0.3, 3.0}) {
    const std::uint32_t k = clustering.cluster(points, d, labels);
    EXPECT_LE(k, previous);
    previous = k;
    std::vector<Vec3> sum(k, Vec3::Zero());
    std::vector<int> count(k, 0);
    for (std::size_t i = 0; i < points.size(); ++i) {
      sum[labels[i]] += points[i];
      ++count[labels[i]];
    }
    for (std::size_t i = 0; i < points.size(); ++i)
      EXPECT_LE((points[i] - sum[labels[i]] / count[labels[i]]).norm(), 0.5 * d * (1.0 + 1e-12)) << "d=" << d;
  }
  EXPECT_EQ(previous, 1u);
}

TEST(TightClustering, BadInputThrowsInvalidParameter) {
  const auto mesh = clod_test::loadNormalized(clod_test::testData("cube.obj"));
  const TightClustering clustering;
  std::vector<Vec3> points{Vec3::Zero(), Vec3::Ones()};
  std::vector<std::uint32_t> labels;
  std::vector<Vec3> centres;
  for (double d : {-0.01, std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()}) {
    EXPECT_THROW(clustering.cluster(points, d, labels), InvalidParameter);
    EXPECT_THROW(clustering.clusterMesh(*mesh, points, {0, 1}, d, labels, centres, nullptr), InvalidParameter);
  }
  EXPECT_THROW(clustering.clusterMesh(*mesh, points, {0}, 0.1, labels, centres, nullptr), InvalidParameter);
  EXPECT_THROW(clustering.clusterMesh(*mesh, points, {0, 99}, 0.1, labels, centres, nullptr), InvalidParameter);
  EXPECT_EQ(clustering.clusterMesh(*mesh, {}, {}, 0.1, labels, centres, nullptr), 0u);
  const ClodBuilder builder(mesh, std::make_shared<PaperPlacement>(), makeClustering("tight"));
  EXPECT_THROW(builder.build(-1.0), InvalidParameter);
  // The piece edge: negative, NaN or infinite is refused when the strategy is made.
  for (double edge : {-0.01, std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()})
    EXPECT_THROW(TightClustering{edge}, InvalidParameter) << edge;
}

TEST(SurfaceDistance, MatchesBruteForce) {
  for (const char* name : {"head.off", "elephant.off"}) {
    const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh(name));
    const SurfaceDistance surface(*mesh);
    // Anywhere around the model, and close to its surface (where neighbouring triangles' planes pass near the probe).
    std::vector<Vec3> probes = uniformProbes(*mesh, 2000, 0.2, 31);
    for (const Vec3& p : nearSurfaceProbes(*mesh, 2000, 0.01, 32)) probes.push_back(p);
    std::size_t checked = 0;
    for (const Vec3& p : probes) {
      bool ambiguous = false;
      const double ref = referenceSignedDistance(*mesh, p, ambiguous);
      const double got = surface.signedDistance(p);
      EXPECT_NEAR(std::abs(got), std::abs(ref), 1e-12);
      if (!ambiguous) {
        EXPECT_EQ(got > 0.0, ref > 0.0) << p.transpose();
        ++checked;
      }
      // Bounded: the same value when the surface is within the bound, else +bound.
      const double bound = 0.5 * std::abs(ref);
      EXPECT_EQ(surface.signedDistance(p, bound), bound);
      EXPECT_NEAR(std::abs(surface.signedDistance(p, 2.0 * std::abs(ref) + 1e-9)), std::abs(ref), 1e-12);
    }
    EXPECT_GT(checked, probes.size() / 2);
  }
}

TEST(SurfaceDistance, InsideAClosedCubeIsPositive) {
  const auto mesh = clod_test::loadNormalized(clod_test::testData("cube.obj"));
  const SurfaceDistance surface(*mesh);
  const Vec3 centre = mesh->bounds().center();
  const double half = 0.5 * mesh->bounds().sizes().maxCoeff();
  EXPECT_NEAR(surface.signedDistance(centre), half, 1e-12);
  EXPECT_NEAR(surface.signedDistance(centre + Vec3(2.0 * half, 0, 0)), -half, 1e-12);
}

}  // namespace
