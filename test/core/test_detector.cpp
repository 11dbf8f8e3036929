// ClodDetector against bruteForceQuery on 100,000 probes per shared mesh (near the surface and
// uniform in the bounding box), in the three modes, plus a check that query() allocates nothing.

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <limits>
#include <map>
#include <new>
#include <random>
#include <utility>
#include <vector>

#include "allocation_counter.h"
#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/cell_grid.h"
#include "clod_haptics/core/detector.h"
#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/geometry.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/probes.h"
#include "clod_haptics/core/sphere_set.h"
#include "simd/dispatch.h"
#include "test_helpers.h"

namespace {

using namespace clod_haptics;
using Clock = std::chrono::steady_clock;

constexpr unsigned kThreads = 2;
constexpr std::size_t kNearProbes = 50000, kUniformProbes = 50000;
constexpr double kMaxRadius = 0.02;  // brute force runs once at this radius; smaller radii are derived

double seconds(Clock::time_point since) { return std::chrono::duration<double>(Clock::now() - since).count(); }

// Brute force at kMaxRadius answers every smaller radius r too: the closest point does not depend on
// r, and the contact is distance <= r. Probes within rounding of r are re-asked at r itself.
bool referenceContact(const TriangleMesh& mesh, const Vec3& p, const ContactResult& atMax, double r) {
  if (!atMax.contact) return false;
  if (std::abs(atMax.distance - r) <= 1e-9 * r) return bruteForceQuery(mesh, p, r).contact;
  return atMax.distance <= r;
}

// The reference, made affordable: bruteForceQuery(mesh, p, R) depends only on the triangles within R
// of p (the closest one, if any, is among them; ties go to the lowest index and the sub-mesh keeps
// the order). So probes are grouped by grid cell and bruteForceQuery runs on the sub-mesh of the
// triangles whose bounding box grown by R meets the cell: the same answer, verified against the
// full bruteForceQuery in ReferenceEqualsFullBruteForce.
std::vector<ContactResult> referenceQueries(const TriangleMesh& mesh, const std::vector<Vec3>& probes, double R) {
  const Eigen::AlignedBox3d box = mesh.bounds();
  const double cell = std::max(2.0 * R, box.sizes().maxCoeff() / 64.0);
  using Key = std::array<std::int64_t, 3>;
  auto keyOf = [&](const Vec3& p) {
    const Vec3 q = (p - box.min()) / cell;
    return Key{std::int64_t(std::floor(q.x())), std::int64_t(std::floor(q.y())), std::int64_t(std::floor(q.z()))};
  };
  std::map<Key, std::vector<std::uint32_t>> cellTriangles;
  for (std::size_t t = 0; t < mesh.size(); ++t) {
    Eigen::AlignedBox3d b;
    for (int k = 0; k < 3; ++k) b.extend(mesh.vertex(t, k));
    const Key lo = keyOf(b.min() - Vec3::Constant(R)), hi = keyOf(b.max() + Vec3::Constant(R));
    for (std::int64_t x = lo[0]; x <= hi[0]; ++x)
      for (std::int64_t y = lo[1]; y <= hi[1]; ++y)
        for (std::int64_t z = lo[2]; z <= hi[2]; ++z) cellTriangles[{x, y, z}].push_back(std::uint32_t(t));
  }
  std::map<Key, std::vector<std::size_t>> cellProbes;
  for (std::size_t i = 0; i < probes.size(); ++i) cellProbes[keyOf(probes[i])].push_back(i);
  std::vector<const std::pair<const Key, std::vector<std::size_t>>*> groups;
  for (const auto& g : cellProbes) groups.push_back(&g);

  std::vector<ContactResult> out(probes.size());
  clod_test::parallelFor(groups.size(), kThreads, [&](std::size_t b, std::size_t e) {
    for (std::size_t g = b; g < e; ++g) {
      const auto it = cellTriangles.find(groups[g]->first);
      if (it == cellTriangles.end()) continue;              // no triangle within R of this cell: no contact
      const std::vector<std::uint32_t>& tris = it->second;  // ascending
      std::vector<Vec3> vertices;
      std::vector<Triangle> triangles;
      std::map<std::uint32_t, std::uint32_t> local;
      for (std::uint32_t t : tris) {
        Triangle tri;
        for (int k = 0; k < 3; ++k) {
          const auto ins = local.emplace(mesh.triangles[t][k], std::uint32_t(vertices.size()));
          if (ins.second) vertices.push_back(mesh.vertices[mesh.triangles[t][k]]);
          tri[k] = ins.first->second;
        }
        triangles.push_back(tri);
      }
      // The whole mesh's local frame: the same arithmetic as the full brute force, bit for bit.
      const TriangleMesh sub = makeLocalMesh(std::move(vertices), std::move(triangles), "cell", mesh.origin);
      for (std::size_t i : groups[g]->second) {
        out[i] = bruteForceQuery(sub, probes[i], R);
        if (out[i].contact) out[i].triangle = std::int32_t(tris[std::size_t(out[i].triangle)]);
      }
    }
  });
  return out;
}

struct Counts {
  std::size_t probes = 0, contacts = 0, exactMismatch = 0, paperFalse = 0, paperMissEdge = 0, paperMissRounding = 0,
              paperMissFace = 0, paperTooNear = 0, spheresMiss = 0, badResult = 0;
  void add(const Counts& o) {
    probes += o.probes;
    contacts += o.contacts;
    exactMismatch += o.exactMismatch;
    paperFalse += o.paperFalse;
    paperMissEdge += o.paperMissEdge;
    paperMissRounding += o.paperMissRounding;
    paperMissFace += o.paperMissFace;
    paperTooNear += o.paperTooNear;
    spheresMiss += o.spheresMiss;
    badResult += o.badResult;
  }
};

// The minimum barycentric coordinate of q in triangle t (long double), to tell a projection that
// falls outside only by rounding from one that is really outside.
double minBarycentric(const TriangleMesh& mesh, std::size_t t, const Vec3& q) {
  using V = Eigen::Matrix<long double, 3, 1>;
  const V a = mesh.vertex(t, 0).cast<long double>(), e0 = mesh.vertex(t, 1).cast<long double>() - a,
          e1 = mesh.vertex(t, 2).cast<long double>() - a, x = q.cast<long double>() - a;
  const long double d00 = e0.dot(e0), d01 = e0.dot(e1), d11 = e1.dot(e1), d20 = x.dot(e0), d21 = x.dot(e1);
  const long double den = d00 * d11 - d01 * d01;
  if (!(den > 0)) return -1.0;
  const long double v = (d11 * d20 - d01 * d21) / den, w = (d00 * d21 - d01 * d20) / den;
  return static_cast<double>(std::min({1 - v - w, v, w}));
}

// A contact result is sane: finite, unit normal, depth = r - distance outside and r + distance inside,
// point at that distance, within r unless inside (a followed deep push).
bool sane(const ContactResult& c, const Vec3& p, double r, double tol) {
  if (!c.contact) return true;
  const double depth = c.inside ? r + c.distance : r - c.distance;
  return c.point.allFinite() && c.normal.allFinite() && std::abs(c.normal.norm() - 1.0) < 1e-9 &&
         std::isfinite(c.distance) && c.distance >= 0.0 && (c.inside || c.distance <= r + tol) &&
         std::abs(c.depth - depth) <= tol && std::abs((p - c.point).norm() - c.distance) <= tol;
}

Counts compareRange(const TriangleMesh& mesh, const ClodDetector& det, const std::vector<Vec3>& probes,
                    const std::vector<ContactResult>& bf, double r, std::size_t begin, std::size_t end,
                    std::size_t stride, bool useCache, std::vector<std::string>& failures) {
  Counts k;
  ContactResult exact, paper, spheres;
  QueryCache cacheExact, cachePaper, cacheSpheres;  // one stream per mode, in probe (Morton) order
  bool exactInside = false, paperInside = false;    // the streams' previous answers: centre inside
  std::size_t deepChecks = 0;
  const Eigen::AlignedBox3d bounds = mesh.bounds();
  const double tolAbs = 1e-12 * mesh.diagonal();
  auto fail = [&](const std::string& s) {
    if (failures.size() < 10) failures.push_back(s);
  };
  for (std::size_t i = begin; i < end; ++i) {
    if (i % stride != 0) continue;
    ++k.probes;
    const Vec3& p = probes[i];
    const bool ref = referenceContact(mesh, p, bf[i], r);
    k.contacts += ref;
    det.query(p, r, DetectionMode::Exact, exact, useCache ? &cacheExact : nullptr);
    det.query(p, r, DetectionMode::Paper, paper, useCache ? &cachePaper : nullptr);
    det.query(p, r, DetectionMode::Spheres, spheres, useCache ? &cacheSpheres : nullptr);
    const double tol = 1e-9 * std::max(bf[i].distance, r);
    // A stream that was inside follows the push beyond r (QueryCache): those answers are checked against
    // the signed reference, from bf when the nearest triangle is within its radius, else (every 16th, the
    // full brute force is slow) from bruteForceSignedQuery itself.
    const bool followed = useCache && exactInside && !ref;
    exactInside = exact.contact && exact.inside;
    const bool paperFollowed = useCache && paperInside && paper.contact && paper.inside && paper.distance > r;
    paperInside = paper.contact && paper.inside;
    if (followed) {
      ContactResult signedRef;
      bool known = true;
      if (bf[i].contact) {
        signedRef = bf[i];
        signedRef.contact = bf[i].inside && bounds.contains(p);
      } else if (deepChecks++ % 16 == 0) {
        signedRef = bruteForceSignedQuery(mesh, p, r);
      } else {
        known = false;
      }
      if (known && (exact.contact != signedRef.contact ||
                    (exact.contact &&
                     (std::abs(exact.distance - signedRef.distance) > tol || exact.inside != signedRef.inside)))) {
        ++k.exactMismatch;
        fail("exact probe " + std::to_string(i) + " (deep, followed): contact " + std::to_string(exact.contact) +
             " vs " + std::to_string(signedRef.contact) + ", distance " + std::to_string(exact.distance) + " vs " +
             std::to_string(signedRef.distance));
      }
    } else if (exact.contact != ref ||
               (ref && (std::abs(exact.distance - bf[i].distance) > tol || exact.inside != bf[i].inside))) {
      ++k.exactMismatch;
      fail("exact probe " + std::to_string(i) + ": contact " + std::to_string(exact.contact) + " vs " +
           std::to_string(ref) + ", distance " + std::to_string(exact.distance) + " vs " +
           std::to_string(bf[i].distance));
    }
    if (exact.contact) {
      const std::size_t t = static_cast<std::size_t>(exact.triangle);
      const bool onTriangle =
          exact.triangle >= 0 && t < mesh.size() &&
          (closestPointOnTriangle(exact.point, mesh.vertex(t, 0), mesh.vertex(t, 1), mesh.vertex(t, 2)) - exact.point)
                  .norm() <= tolAbs;
      if (!onTriangle || !sane(exact, p, r, tolAbs + tol) || exact.sphere < 0) {
        ++k.badResult;
        fail("exact probe " + std::to_string(i) + ": inconsistent result fields");
      }
    }
    // paper: never a contact brute force denies (but a followed deep push); misses only where the closest
    // point is on an edge or vertex.
    if (paper.contact && !ref && !paperFollowed) {
      ++k.paperFalse;
      fail("paper probe " + std::to_string(i) + " reports a contact brute force denies");
    }
    if (paper.contact && bf[i].contact && paper.distance < bf[i].distance - tol) ++k.paperTooNear;
    if (paper.contact && !sane(paper, p, r, tolAbs + tol)) ++k.badResult;
    if (ref && !paper.contact) {
      const std::size_t t = static_cast<std::size_t>(bf[i].triangle);
      TriangleRegion region;
      closestPointOnTriangle(p, mesh.vertex(t, 0), mesh.vertex(t, 1), mesh.vertex(t, 2), &region);
      const TriangleFeature feature = region.feature;
      if (feature != TriangleFeature::Face) {
        ++k.paperMissEdge;
      } else if (minBarycentric(mesh, t, bf[i].point) <= 1e-9) {
        ++k.paperMissRounding;  // on an edge to within rounding: Voronoi and cross-product tests disagree
      } else {
        ++k.paperMissFace;
        fail("paper probe " + std::to_string(i) + " misses a contact inside triangle " + std::to_string(t));
      }
    }
    // spheres: the coarsest answer never misses.
    if (ref && !spheres.contact) {
      ++k.spheresMiss;
      fail("spheres probe " + std::to_string(i) + " misses a contact");
    }
  }
  return k;
}

class DetectorVsBruteForce : public ::testing::TestWithParam<std::string> {};

TEST_P(DetectorVsBruteForce, HundredThousandProbes) {
  const auto start = Clock::now();
  const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh(GetParam()));
  std::vector<Vec3> probes = nearSurfaceProbes(*mesh, kNearProbes, kMaxRadius, 11);
  const auto uniform = uniformProbes(*mesh, kUniformProbes, kMaxRadius, 12);
  probes.insert(probes.end(), uniform.begin(), uniform.end());
  sortMorton(probes);  // the order of a coherent stylus stream, for the QueryCache runs
  ASSERT_GE(probes.size(), 100000u);

  const std::vector<ContactResult> bf = referenceQueries(*mesh, probes, kMaxRadius);
  const double bfSeconds = seconds(start);
  const auto builderStart = Clock::now();
  const ClodBuilder builder(mesh);
  std::printf("[ INFO     ] %s: placement %.1f s\n", GetParam().c_str(), seconds(builderStart));

  struct Config {
    double d;
    FastLevel fast;
    double r;
    std::size_t stride;  // compare every stride-th probe
    bool cache;          // pass a QueryCache (temporal coherence)
    double gridRadius;   // for FastLevel::Grid; 0 = the detector's default
  };
  // The default Grid fast level at the paper's working point d = 0.02, within its radius (with and
  // without the stream cache), beyond it (hierarchy fallback) and with a grid built for r = 0.02, on
  // every probe; the hierarchy at d = 0.02 and 0.08 on every 2nd probe; d = 0 (every unclustered
  // sphere) and the flat fast level on every 4th probe, to bound the run time.
  const double gridDefault = 0.0;
  for (const Config& cfg : {Config{0.02, FastLevel::Grid, 0.005, 1, false, gridDefault},
                            Config{0.02, FastLevel::Grid, 0.005, 1, true, gridDefault},
                            Config{0.02, FastLevel::Grid, kMaxRadius, 1, true, gridDefault},
                            Config{0.02, FastLevel::Grid, kMaxRadius, 1, false, kMaxRadius},
                            Config{0.02, FastLevel::Hierarchy, 0.005, 2, false, gridDefault},
                            Config{0.08, FastLevel::Hierarchy, kMaxRadius, 2, false, gridDefault},
                            Config{0.0, FastLevel::Hierarchy, 0.005, 4, false, gridDefault},
                            Config{0.02, FastLevel::Flat, 0.005, 4, false, gridDefault}}) {
    const auto configStart = Clock::now();
    const auto set = std::make_shared<const ClodSphereSet>(builder.build(cfg.d));
    const ClodDetector det(mesh, set, cfg.fast, cfg.gridRadius);
    {
      const double r = cfg.r;
      const char* fastName = cfg.fast == FastLevel::Flat ? "flat" : cfg.fast == FastLevel::Grid ? "grid" : "hierarchy";
      SCOPED_TRACE(GetParam() + " d=" + std::to_string(cfg.d) + " r=" + std::to_string(r) + " " + fastName +
                   (cfg.cache ? " cache" : ""));
      std::vector<Counts> parts(kThreads);
      std::vector<std::vector<std::string>> failures(kThreads);
      const std::size_t chunk = (probes.size() + kThreads - 1) / kThreads;
      clod_test::parallelFor(probes.size(), kThreads, [&](std::size_t b, std::size_t e) {
        const std::size_t part = b / chunk;
        parts[part] = compareRange(*mesh, det, probes, bf, r, b, e, cfg.stride, cfg.cache, failures[part]);
      });
      Counts k;
      for (std::size_t t = 0; t < kThreads; ++t) {
        k.add(parts[t]);
        for (const auto& f : failures[t]) ADD_FAILURE() << f;
      }
      EXPECT_EQ(k.exactMismatch, 0u);
      EXPECT_EQ(k.badResult, 0u);
      EXPECT_EQ(k.paperFalse, 0u);
      EXPECT_EQ(k.paperTooNear, 0u) << "paper's distance is to a surface point, never below the true one";
      EXPECT_EQ(k.paperMissFace, 0u);
      EXPECT_EQ(k.probes, (probes.size() + cfg.stride - 1) / cfg.stride);
      EXPECT_LE(k.paperMissRounding, k.probes / 10000) << "rounding-only misses should be rare";
      EXPECT_EQ(k.spheresMiss, 0u);
      EXPECT_GT(k.contacts, k.probes / 50) << "the probe set must exercise contacts";
      std::printf(
          "[ INFO     ] %-22s d=%.2f r=%.3f %-9s%-6s: %zu spheres, %zu probes, %zu contacts, paper misses %zu "
          "(edge/vertex closest point; %zu more on an edge within rounding), %.1f s\n",
          GetParam().c_str(), cfg.d, r, fastName, cfg.cache ? " cache" : "", set->size(), k.probes, k.contacts,
          k.paperMissEdge, k.paperMissRounding, seconds(configStart));
    }
  }
  std::printf("[ INFO     ] %s: %zu triangles, reference %.1f s on %u threads, total %.1f s\n", GetParam().c_str(),
              mesh->size(), bfSeconds, kThreads, seconds(start));
}

TEST_P(DetectorVsBruteForce, ReferenceEqualsFullBruteForce) {
  // The culled reference gives exactly what the full bruteForceQuery gives.
  const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh(GetParam()));
  std::vector<Vec3> probes = nearSurfaceProbes(*mesh, 3000, kMaxRadius, 11);
  const auto uniform = uniformProbes(*mesh, 1000, kMaxRadius, 12);
  probes.insert(probes.end(), uniform.begin(), uniform.end());
  const std::vector<ContactResult> culled = referenceQueries(*mesh, probes, kMaxRadius);
  std::vector<ContactResult> full(probes.size());
  clod_test::parallelFor(probes.size(), kThreads, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) full[i] = bruteForceQuery(*mesh, probes[i], kMaxRadius);
  });
  std::size_t contacts = 0;
  for (std::size_t i = 0; i < probes.size(); ++i) {
    ASSERT_EQ(culled[i].contact, full[i].contact) << "probe " << i;
    if (!full[i].contact) continue;
    ++contacts;
    ASSERT_EQ(culled[i].distance, full[i].distance) << "probe " << i;
    ASSERT_EQ(culled[i].point, full[i].point) << "probe " << i;
    ASSERT_EQ(culled[i].triangle, full[i].triangle) << "probe " << i;
    ASSERT_EQ(culled[i].normal, full[i].normal) << "probe " << i;
  }
  EXPECT_GT(contacts, probes.size() / 4);
}

// Spheres mode's answer by definition, over every sphere of the level: contact when some sphere is within r of the
// pointer (|p - c| <= radius + r), through the sphere whose surface is nearest (|p - c| - radius least, the lower
// index on a tie).
struct SphereReference {
  bool contact = false;
  std::int32_t sphere = -1;
  double gap = 0.0;
};
SphereReference bruteForceSpheres(const ClodSphereSet& set, const Vec3& p, double r) {
  SphereReference ref;
  ref.gap = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < set.size(); ++i) {
    const double gap = (p - set.centres[i]).norm() - set.radii[i];
    if (gap < ref.gap) {
      ref.gap = gap;
      ref.sphere = static_cast<std::int32_t>(i);
    }
  }
  ref.contact = ref.gap <= r;
  return ref;
}

TEST_P(DetectorVsBruteForce, SpheresModeEqualsEverySphereOverlappingThePointer) {
  const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh(GetParam()));
  const ClodBuilder builder(mesh);
  const double tol = 1e-9;  // normalised meshes: the padding and the rounding of |p - c| are far below it
  for (double d : {0.0, 0.01, 0.02, 0.05}) {
    const auto set = std::make_shared<const ClodSphereSet>(builder.build(d));
    // Bounded cost of the reference (probes x spheres), at least 1000 probes.
    const std::size_t count = std::max<std::size_t>(1000, std::min<std::size_t>(20000, 100000000 / set->size()));
    std::vector<Vec3> probes = nearSurfaceProbes(*mesh, count / 2, kMaxRadius, 21);
    const auto uniform = uniformProbes(*mesh, count / 2, kMaxRadius, 22);
    probes.insert(probes.end(), uniform.begin(), uniform.end());
    for (double r : {0.0, 0.005, kMaxRadius}) {
      std::vector<SphereReference> ref(probes.size());
      clod_test::parallelFor(probes.size(), kThreads, [&](std::size_t b, std::size_t e) {
        for (std::size_t i = b; i < e; ++i) ref[i] = bruteForceSpheres(*set, probes[i], r);
      });
      for (FastLevel fast : {FastLevel::Grid, FastLevel::Hierarchy, FastLevel::Flat}) {
        const ClodDetector det(mesh, set, fast);
        SCOPED_TRACE(GetParam() + " d=" + std::to_string(d) + " r=" + std::to_string(r) + " " + toString(fast));
        std::size_t contacts = 0, wrong = 0;
        for (std::size_t i = 0; i < probes.size(); ++i) {
          ContactResult got;
          det.query(probes[i], r, DetectionMode::Spheres, got);
          const SphereReference& e = ref[i];
          contacts += e.contact;
          // Within rounding of the pointer's reach, either answer is right.
          if (got.contact != e.contact && std::abs(e.gap - r) <= tol) continue;
          bool ok = got.contact == e.contact;
          if (ok && e.contact) {
            const double gotGap = (probes[i] - set->centres[got.sphere]).norm() - set->radii[got.sphere];
            ok = got.sphere == e.sphere || std::abs(gotGap - e.gap) <= tol;
            ok = ok && std::abs(got.distance - std::max(0.0, e.gap)) <= tol &&
                 std::abs(got.depth - (r - got.distance)) <= tol;
          }
          if (!ok && wrong++ < 5)
            ADD_FAILURE() << "probe " << i << ": contact " << got.contact << " sphere " << got.sphere << " vs "
                          << e.contact << " sphere " << e.sphere << " (gap " << e.gap << ")";
        }
        EXPECT_EQ(wrong, 0u);
        if (r > 0.0) {
          EXPECT_GT(contacts, probes.size() / 50) << "the probes must exercise contacts";
        }
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(SharedMeshes, DetectorVsBruteForce,
                         ::testing::Values("degtri_sliding.off", "elephant.off", "head.off", "mannequin-devil.off",
                                           "mesh_with_border.off", "refined_elephant.off"),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                           std::string name = info.param.substr(0, info.param.find('.'));
                           for (char& c : name)
                             if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
                           return name;
                         });

TEST(DetectorVsBruteForceList, CoversEverySharedMesh) {
  // The parameter list above must name every mesh of the shared directory.
  const std::vector<std::string> known{"degtri_sliding.off",  "elephant.off",         "head.off",
                                       "mannequin-devil.off", "mesh_with_border.off", "refined_elephant.off"};
  const auto meshes = clod_test::sharedMeshes();
  ASSERT_FALSE(meshes.empty());
  for (const auto& path : meshes)
    EXPECT_NE(std::find(known.begin(), known.end(), clod_test::baseName(path)), known.end())
        << "add " << path << " to DetectorVsBruteForce";
}

TEST(ClodDetector, QueryAllocatesNothing) {
  const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh("head.off"));
  const ClodBuilder builder(mesh);
  std::vector<Vec3> probes = nearSurfaceProbes(*mesh, 5000, 0.02, 3);
  const auto far = uniformProbes(*mesh, 1000, 0.5, 4);
  probes.insert(probes.end(), far.begin(), far.end());
  for (double d : {0.0, 0.02, 0.08})
    for (FastLevel fast : {FastLevel::Grid, FastLevel::Hierarchy, FastLevel::Flat}) {
      const ClodDetector det(mesh, std::make_shared<const ClodSphereSet>(builder.build(d)), fast);
      ContactResult out;
      QueryCache cache;
      std::size_t contacts = 0;
      gAllocations = 0;
      gCounting = true;
      for (DetectionMode mode : {DetectionMode::Exact, DetectionMode::Paper, DetectionMode::Spheres})
        for (const Vec3& p : probes)
          for (double r : {0.0, 0.005, 0.05, 1.0}) {
            det.query(p, r, mode, out);
            contacts += out.contact;
            det.query(p, r, mode, out, &cache);
            contacts += out.contact;
          }
      gCounting = false;
      EXPECT_EQ(gAllocations.load(), 0) << "d=" << d;
      EXPECT_GT(contacts, 0u);
    }
  // The counter works: an allocation while armed is seen.
  gAllocations = 0;
  gCounting = true;
  auto* leak = new std::vector<int>(10);
  gCounting = false;
  delete leak;
  EXPECT_GE(gAllocations.load(), 1);
}

// Regression (fuzz/fuzz_mesh_load, minimised): two triangles of a mutated STL cube. The Grid fast
// level missed every contact near the vertex (3, 3, 0) for r up to 1e-3; Hierarchy and Flat did not.
TEST(ClodDetector, GridRegressionTwoTriangles) {
  const auto mesh = std::make_shared<const TriangleMesh>(makeMesh(
      {Vec3(3, 3, 2), Vec3(3, 3, 0), Vec3(0, 0, 0), Vec3(3.0000009536743164, 2, 3), Vec3(3, 4, 5), Vec3(3, 2, 5)},
      {{0, 1, 2}, {3, 4, 5}}, "fuzz-two-triangles"));
  const ClodBuilder builder(mesh);
  std::mt19937_64 rng(1);
  std::normal_distribution<double> g(0.0, 1.0);
  for (double d : {0.0, 0.5})
    for (FastLevel fast : {FastLevel::Grid, FastLevel::Hierarchy, FastLevel::Flat}) {
      const ClodDetector det(mesh, std::make_shared<const ClodSphereSet>(builder.build(d)), fast);
      for (double r : {0.0, 1e-9, 1e-3, 0.05, 0.5}) {
        std::size_t contacts = 0, mismatches = 0;
        ContactResult got;
        for (int i = 0; i < 500; ++i) {
          Vec3 offset = Vec3(g(rng), g(rng), g(rng)).normalized() * (0.9 * r * std::abs(g(rng)));
          if (i == 0) offset.setZero();
          const Vec3 p = Vec3(3, 3, 0) + offset;
          const ContactResult ref = bruteForceQuery(*mesh, p, r);
          det.query(p, r, DetectionMode::Exact, got);
          contacts += ref.contact;
          mismatches += got.contact != ref.contact;
        }
        EXPECT_EQ(mismatches, 0u) << "fast level " << int(fast) << " d=" << d << " r=" << r << ": " << contacts
                                  << " brute-force contacts";
      }
    }
}

// Triangles far smaller than the radius crowd every cell of the grid with thousands of candidates; such a cell is
// answered through the tree over the mesh (kTreeAboveEntries). A finely tessellated bumpy sheet at r = 0.16 (edges
// of 0.1 r): most probes land in a crowded cell, and every answer, with and without a QueryCache, is brute force's.
TEST(ClodDetector, CrowdedCellsAnswerAsBruteForce) {
  const auto mesh = std::make_shared<const TriangleMesh>(clod_test::heightField(
      120, [](double x, double y) { return 0.1 * std::sin(3.0 * (x + 1.0)) * std::cos(2.5 * (y + 1.0)); },
      Eigen::Matrix3d::Identity(), Vec3::Zero()));
  const auto set = std::make_shared<const ClodSphereSet>(ClodBuilder(mesh).build(0.02));
  constexpr double r = 0.16;
  const ClodDetector det(mesh, set, FastLevel::Grid, r);
  const CellGrid grid(*mesh, *set, r);  // the grid the detector holds, built again to count its cells
  std::vector<Vec3> probes = nearSurfaceProbes(*mesh, 1500, r, 21);
  sortMorton(probes);
  std::size_t crowded = 0, contacts = 0;
  // The tree walked four nodes a test in AVX2 (WideBoxTree), and as a CPU without AVX2 walks it.
  for (const bool avx2 : {true, false}) {
    SCOPED_TRACE(avx2 ? "AVX2" : "no AVX2");
    detail::usePacketAvx2(avx2);
    QueryCache cache;
    for (const Vec3& p : probes) {
      const CellGrid::CellRef* ref = grid.find(grid.keyOf(mesh->toLocal(p)));
      crowded += ref != nullptr && grid.cell(*ref).count > ClodDetector::kTreeAboveEntries;
      const ContactResult ref0 = bruteForceQuery(*mesh, p, r);
      contacts += ref0.contact;
      ContactResult got, cached;
      det.query(p, r, DetectionMode::Exact, got);
      det.query(p, r, DetectionMode::Exact, cached, &cache);
      for (const ContactResult* o : {&got, &cached}) {
        ASSERT_EQ(o->contact, ref0.contact) << p.transpose();
        if (!ref0.contact) continue;
        ASSERT_EQ(o->distance, ref0.distance) << p.transpose();
        ASSERT_EQ(o->triangle, ref0.triangle) << p.transpose();
        ASSERT_EQ(o->point, ref0.point) << p.transpose();
        ASSERT_EQ(o->inside, ref0.inside) << p.transpose();
      }
    }
  }
  detail::usePacketAvx2(true);
  EXPECT_GT(crowded, probes.size()) << "the sheet must crowd the cells beyond kTreeAboveEntries";
  EXPECT_GT(contacts, probes.size());
}

// The soundness of a stream's neighbourhood (QueryCache::nearTriangle), checked over its cell's whole list with
// closestPointOnTriangle: it lists, nearest first, once each and at the distances it says, every triangle of that
// list within min(r + m, d0 + 2 m) of its anchor (m: the margin it claims, d0: the anchor's nearest distance within
// r): what a query within m of the anchor, in that cell, may answer. Returns how many triangles that bound took in.
std::size_t expectSoundNeighbourhood(const ClodDetector& det, const TriangleMesh& mesh, const QueryCache& cache,
                                     double r) {
  if (!(cache.nearMargin >= 0.0)) return 0;
  const CellGrid& grid = det.grid();
  const CellGrid::CellRef* ref = grid.find(cache.nearKey);
  EXPECT_NE(ref, nullptr) << mesh.name << ": a neighbourhood of an empty cell";
  if (ref == nullptr) return 0;
  const Vec3& a = cache.nearAnchor;  // local frame, as the mesh's vertices
  const auto distance = [&](std::uint32_t t) {
    return (a - closestPointOnTriangle(a, mesh.vertex(t, 0), mesh.vertex(t, 1), mesh.vertex(t, 2))).norm();
  };
  for (std::uint32_t i = 0; i < cache.nearCount; ++i) {
    EXPECT_NEAR(cache.nearDistance[i], distance(cache.nearTriangle[i]), 1e-12 * r) << mesh.name;
    if (i > 0) {
      EXPECT_LE(cache.nearDistance[i - 1], cache.nearDistance[i]) << mesh.name << ": not nearest first";
    }
    EXPECT_EQ(std::count(cache.nearTriangle, cache.nearTriangle + cache.nearCount, cache.nearTriangle[i]), 1)
        << mesh.name << ": triangle " << cache.nearTriangle[i] << " listed twice (room wasted)";
  }
  const ContactResult nearest = bruteForceQuery(mesh, mesh.toModel(a), r);
  const double d0 = nearest.contact ? nearest.distance : std::numeric_limits<double>::infinity();
  const double m = cache.nearMargin, bound = std::min(r + m, d0 + 2.0 * m);
  const CellGrid::Cell cell = grid.cell(*ref);
  std::size_t needed = 0;
  for (std::uint32_t k = 0; k < cell.count; ++k) {
    const std::uint32_t t = cell.entries[k].triangle;
    if (!(distance(t) <= bound)) continue;
    ++needed;
    const std::uint32_t* end = cache.nearTriangle + cache.nearCount;
    EXPECT_NE(std::find(cache.nearTriangle, end, t), end)
        << mesh.name << ": triangle " << t << " at " << distance(t) << " (within " << bound << " of the anchor, margin "
        << m << ") is not listed";
  }
  return needed;
}

// A slow stream (steps of 0.001 r to 0.03 r) answers most queries from its QueryCache's neighbourhood: the triangles
// of one cell within the radius plus a margin of the centre it was filled at. Every answer is brute force's (and the
// stateless query's, bit for bit), on every shared mesh and on a sheet of triangles a third of r wide, where more
// triangles lie within reach than the neighbourhood holds (its margin then shrinks). Paths from surface points along
// a drifting tangent, in and out of the surface within 0.9 r (a stream that was inside and then finds nothing within
// r is checked against the signed reference, as the push it follows).
TEST(ClodDetector, ASlowStreamAnswersFromItsNeighbourhoodAsBruteForce) {
  struct Case {
    std::shared_ptr<const TriangleMesh> mesh;
    double r;
  };
  std::vector<Case> cases;
  for (const std::string& file : clod_test::sharedMeshes()) cases.push_back({clod_test::loadNormalized(file), 0.01});
  cases.push_back({std::make_shared<const TriangleMesh>(clod_test::heightField(
                       120, [](double x, double y) { return 0.1 * std::sin(2.0 * x) * std::cos(1.5 * y); },
                       Eigen::Matrix3d::Identity(), Vec3::Zero())),
                   0.05});
  for (const Case& c : cases) {
    const TriangleMesh& mesh = *c.mesh;
    const double r = c.r;
    const ClodDetector det(c.mesh, std::make_shared<const ClodSphereSet>(ClodBuilder(c.mesh).build(2.0 * r)),
                           FastLevel::Grid, r);
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    const std::vector<Vec3> starts = nearSurfaceProbes(mesh, 12, 0.0, 9);
    QueryCache cache;
    std::size_t queries = 0, contacts = 0, full = 0, fills = 0;
    bool inside = false;
    for (const Vec3& start : starts) {
      const ContactResult at = bruteForceQuery(mesh, start, 1.0);
      const Vec3 n = at.normal;
      Vec3 t = n.unitOrthogonal();
      double along = 0.0, phase = 2.0 * M_PI * u(rng);
      for (int i = 0; i < 250; ++i) {
        const double step = r * (0.001 + 0.03 * u(rng) * u(rng));
        t = (t + 0.05 * n.cross(t)).normalized();  // the heading turns slowly about the normal
        along += step;
        phase += step / r;
        const Vec3 p = at.point + 0.9 * r * std::sin(phase) * n + along * t;
        const ContactResult ref = bruteForceQuery(mesh, p, r);
        ContactResult got, stateless;
        const Vec3 anchorBefore = cache.nearAnchor;
        det.query(p, r, DetectionMode::Exact, got, &cache);
        det.query(p, r, DetectionMode::Exact, stateless);
        if (cache.nearAnchor != anchorBefore) {  // filled here
          ++fills;
          expectSoundNeighbourhood(det, mesh, cache, r);
        }
        ++queries;
        contacts += ref.contact;
        full += cache.nearCount == QueryCache::kNear;
        if (!ref.contact && inside) {  // followed beyond r: the signed reference
          const ContactResult deep = bruteForceSignedQuery(mesh, p, r);
          ASSERT_EQ(got.contact, deep.contact) << mesh.name << " " << p.transpose();
          if (deep.contact) {
            ASSERT_EQ(got.distance, deep.distance) << mesh.name << " " << p.transpose();
          }
        } else {
          ASSERT_EQ(got.contact, ref.contact) << mesh.name << " " << p.transpose();
          if (ref.contact) {
            ASSERT_EQ(got.triangle, ref.triangle) << mesh.name << " " << p.transpose();
            ASSERT_EQ(got.distance, ref.distance) << mesh.name << " " << p.transpose();
            ASSERT_EQ(got.point, ref.point) << mesh.name << " " << p.transpose();
            ASSERT_EQ(got.inside, ref.inside) << mesh.name << " " << p.transpose();
            ASSERT_EQ(got.sphere, stateless.sphere) << mesh.name << " " << p.transpose();
          }
        }
        inside = got.contact && got.inside;
      }
    }
    // The neighbourhood answered most of the stream, and the paths touched the surface.
    EXPECT_GT(cache.nearHits, queries / 3) << mesh.name;
    EXPECT_GT(fills, 10u) << mesh.name;
    EXPECT_GT(contacts, queries / 4) << mesh.name;
    if (r == 0.05) {
      EXPECT_GT(full, 0u) << "the sheet must fill a neighbourhood to capacity";
    }
  }
}

// A stream over det that steps 0.01 onto a: its query at a fills a neighbourhood there (a slow stream).
void fillNeighbourhoodAt(const ClodDetector& det, const Vec3& a, double r, QueryCache& cache) {
  ContactResult c;
  det.query(a - Vec3(0.01, 0, 0), r, DetectionMode::Exact, c, &cache);
  det.query(a, r, DetectionMode::Exact, c, &cache);
}

// The neighbourhood must hold more than the triangles near its anchor: moving by m away from the anchor's nearest
// triangle (at d0) towards another, the query's nearest can be one up to d0 + 2 m from the anchor. Two parallel
// triangles 0.85 apart (r = 1), the anchor 0.3 above the lower one after a step of 0.01: the upper one (0.55 from
// the anchor) is listed whenever the margin exceeds (0.55 - 0.3) / 2, and a query 0.99 of the margin higher is
// answered from the neighbourhood as brute force answers it.
TEST(ClodDetector, ANeighbourhoodHoldsTheTriangleBeyondTheNearestOne) {
  const double r = 1.0, h = 0.85;
  const auto mesh = std::make_shared<const TriangleMesh>(
      makeMesh({Vec3(-5, -5, 0), Vec3(5, -5, 0), Vec3(0, 6, 0), Vec3(-5, -5, h), Vec3(0, 6, h), Vec3(5, -5, h)},
               {{0, 1, 2}, {3, 4, 5}}, "two plates"));
  const ClodDetector det(mesh, std::make_shared<const ClodSphereSet>(ClodBuilder(mesh).build(0.5)), FastLevel::Grid, r);
  const Vec3 a(0.1, 0.1, 0.3);
  QueryCache cache;
  fillNeighbourhoodAt(det, a, r, cache);
  ASSERT_GT(cache.nearMargin, 0.125) << "a step of 0.01 r fills a neighbourhood wide enough to need the upper plate";
  EXPECT_EQ(expectSoundNeighbourhood(det, *mesh, cache, r), 2u);
  const Vec3 p = a + Vec3(0, 0, 0.99 * cache.nearMargin);
  ContactResult got;
  det.query(p, r, DetectionMode::Exact, got, &cache);
  const ContactResult ref = bruteForceQuery(*mesh, p, r);
  EXPECT_EQ(cache.nearHits, 1u) << "the last query must come from the neighbourhood filled at the anchor";
  ASSERT_EQ(got.contact, ref.contact);
  EXPECT_EQ(got.triangle, ref.triangle);
  EXPECT_EQ(got.distance, ref.distance);
}

// When more triangles lie within reach than the neighbourhood holds, its reach shrinks to the farthest one kept and
// its margin to what that reach covers: a lower plate of 0.02-area triangles, the anchor 0.3 above it, a roof 0.9 up.
// The neighbourhood is full, sound (every triangle its margin needs is listed), and a query at 0.99 of that margin
// towards the roof is answered from it as brute force answers it.
TEST(ClodDetector, AFullNeighbourhoodHoldsOnlyWhatItsReachCovers) {
  const double r = 1.0, h = 0.9;
  // The plate: 30 x 30 squares of 0.2 on [-3, 3]^2 (the height field's square scaled by 3).
  const TriangleMesh plate = clod_test::heightField(
      30, [](double, double) { return 0.0; }, 3.0 * Eigen::Matrix3d::Identity(), Vec3::Zero());
  std::vector<Vec3> v;
  for (const Vec3& x : plate.vertices) v.push_back(plate.toModel(x));
  std::vector<Triangle> t = plate.triangles;
  const std::uint32_t top = static_cast<std::uint32_t>(v.size());
  v.insert(v.end(), {Vec3(-5, -5, h), Vec3(0, 6, h), Vec3(5, -5, h)});
  t.push_back({top, top + 1, top + 2});
  const auto mesh = std::make_shared<const TriangleMesh>(makeMesh(std::move(v), std::move(t), "plate and roof"));
  const ClodDetector det(mesh, std::make_shared<const ClodSphereSet>(ClodBuilder(mesh).build(0.5)), FastLevel::Grid, r);
  const Vec3 a(0.05, 0.07, 0.3);
  QueryCache cache;
  fillNeighbourhoodAt(det, a, r, cache);
  ASSERT_EQ(cache.nearCount, QueryCache::kNear) << "the fill at the anchor must run out of room";
  ASSERT_GT(cache.nearMargin, 0.0);
  expectSoundNeighbourhood(det, *mesh, cache, r);
  for (const Vec3& dir : {Vec3(0, 0, 1), Vec3(0, 0, -1), Vec3(1, 0, 0), Vec3(0.6, 0.8, 0)}) {
    const Vec3 p = a + 0.99 * cache.nearMargin * dir;
    const std::uint64_t hits = cache.nearHits;
    ContactResult got;
    det.query(p, r, DetectionMode::Exact, got, &cache);
    const ContactResult ref = bruteForceQuery(*mesh, p, r);
    EXPECT_EQ(cache.nearHits, hits + 1) << "within the margin: answered from the neighbourhood";
    ASSERT_EQ(got.contact, ref.contact) << p.transpose();
    EXPECT_EQ(got.triangle, ref.triangle) << p.transpose();
    EXPECT_EQ(got.distance, ref.distance) << p.transpose();
  }
}

TEST(ClodDetector, InvalidQueriesAnswerNoContact) {
  const auto mesh = clod_test::loadNormalized(clod_test::testData("cube.obj"));
  const ClodBuilder builder(mesh);
  const ClodDetector det(mesh, std::make_shared<const ClodSphereSet>(builder.build(0.02)));
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  ContactResult out;
  for (DetectionMode mode : {DetectionMode::Exact, DetectionMode::Paper, DetectionMode::Spheres}) {
    det.query(Vec3(0.5, 0.5, 1.0), 0.1, mode, out);
    EXPECT_TRUE(out.contact) << toString(mode);
    det.query(Vec3(nan, 0.5, 1.0), 0.1, mode, out);
    EXPECT_FALSE(out.contact);
    det.query(Vec3(0.5, inf, 1.0), 0.1, mode, out);
    EXPECT_FALSE(out.contact);
    det.query(Vec3(0.5, 0.5, 1.0), nan, mode, out);
    EXPECT_FALSE(out.contact);
    det.query(Vec3(0.5, 0.5, 1.0), inf, mode, out);
    EXPECT_FALSE(out.contact);
    det.query(Vec3(0.5, 0.5, 1.0), -0.1, mode, out);
    EXPECT_FALSE(out.contact);
  }
  std::vector<std::uint32_t> hits{1, 2, 3};
  det.hitSpheres(Vec3(nan, 0, 0), 0.1, hits);
  EXPECT_TRUE(hits.empty());
}

TEST(ClodDetector, HitSpheresMatchesDirectOverlapTest) {
  const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh("elephant.off"));
  const ClodBuilder builder(mesh);
  for (double d : {0.0, 0.04})
    for (FastLevel fast : {FastLevel::Grid, FastLevel::Hierarchy, FastLevel::Flat}) {
      const auto set = std::make_shared<const ClodSphereSet>(builder.build(d));
      const ClodDetector det(mesh, set, fast);
      const auto probes = uniformProbes(*mesh, 2000, 0.05, 21);
      std::vector<std::uint32_t> hits;
      for (const Vec3& p : probes) {
        const double r = 0.01;
        det.hitSpheres(p, r, hits);
        ASSERT_TRUE(std::is_sorted(hits.begin(), hits.end()));
        std::vector<std::uint32_t> direct;
        for (std::size_t i = 0; i < set->size(); ++i) {
          const double gap = (p - set->centres[i]).norm() - set->radii[i] - r;
          if (gap <= 0) direct.push_back(static_cast<std::uint32_t>(i));
          if (gap > 1e-9) {
            ASSERT_EQ(std::count(hits.begin(), hits.end(), i), 0) << "sphere " << i << " too far";
          }
        }
        for (std::uint32_t i : direct) ASSERT_TRUE(std::binary_search(hits.begin(), hits.end(), i)) << "missed " << i;
      }
    }
}

TEST(ClodDetector, AllFastLevelsAndTheCacheGiveTheSameAnswers) {
  const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh("mannequin-devil.off"));
  const ClodBuilder builder(mesh);
  const auto set = std::make_shared<const ClodSphereSet>(builder.build(0.03));
  const ClodDetector tree(mesh, set, FastLevel::Hierarchy), flat(mesh, set, FastLevel::Flat),
      grid(mesh, set, FastLevel::Grid);
  auto probes = nearSurfaceProbes(*mesh, 20000, 0.01, 5);
  sortMorton(probes);
  ContactResult a, b, c, g, deep;
  std::size_t followed = 0;
  for (DetectionMode mode : {DetectionMode::Exact, DetectionMode::Paper, DetectionMode::Spheres}) {
    QueryCache cache;
    for (const Vec3& p : probes) {
      tree.query(p, 0.005, mode, a);
      flat.query(p, 0.005, mode, b);
      grid.query(p, 0.005, mode, c);
      grid.query(p, 0.005, mode, g, &cache);
      // The cached stream also follows a push beyond r after an inside answer: the same nearest triangle
      // as a stateless query with a radius reaching it.
      if (!a.contact && g.contact) {
        ASSERT_TRUE(g.inside) << toString(mode);
        ASSERT_GT(g.distance, 0.005) << toString(mode);
        tree.query(p, g.distance * (1.0 + 1e-12), mode, deep);
        ASSERT_TRUE(deep.contact && deep.inside) << toString(mode);
        ASSERT_EQ(deep.distance, g.distance) << toString(mode);
        ASSERT_EQ(deep.triangle, g.triangle) << toString(mode);
        ++followed;
        continue;
      }
      for (const ContactResult* o : {&b, &c, &g}) {
        ASSERT_EQ(a.contact, o->contact) << toString(mode);
        if (a.contact) {
          ASSERT_EQ(a.distance, o->distance) << toString(mode);
          ASSERT_EQ(a.triangle, o->triangle) << toString(mode);
          ASSERT_EQ(a.inside, o->inside) << toString(mode);
          ASSERT_EQ(a.depth, o->depth) << toString(mode);
        }
      }
    }
  }
  EXPECT_GT(followed, 0u) << "the probes (0.01 both sides, r 0.005) must exercise a followed push";
}

// A QueryCache outlives the detector that filled it when a stream swaps levels (the ROS detector keeps one
// cache across reconfigures), and the next detector is often allocated at the freed one's address. Here the
// two detectors alternate between the torus and the same torus with its triangles listed in reverse order:
// the same cells, other triangle numbers. A cache that took the new detector for the old one would read the
// freed grid's cell (the old numbering, or garbage) and miss contacts. Many build/free cycles through
// make_shared, one cache, every answer against brute force.
TEST(ClodDetector, ACacheNeverReadsAFreedDetectorReusedAtItsAddress) {
  const auto torus = clod_test::loadNormalized(clod_test::testData("../../data/meshes/torus.obj"));
  // The second mesh: the torus's triangles in reverse order, and 300 tiny ones in the middle of its hole (inside
  // its bounds, so the grid's origin and cell size stay, but its arrays get another size and layout).
  std::vector<Triangle> reversed(torus->triangles.rbegin(), torus->triangles.rend());
  std::vector<Vec3> vertices = torus->vertices;
  const Vec3 hole = torus->bounds().center();
  for (int i = 0; i < 300; ++i) {
    const Vec3 a = hole + Vec3(1e-4 * (i % 20), 1e-4 * (i / 20), 0.0);
    const auto v = static_cast<std::uint32_t>(vertices.size());
    vertices.insert(vertices.end(), {a, a + Vec3(5e-5, 0.0, 0.0), a + Vec3(0.0, 5e-5, 2e-5)});
    reversed.push_back(Triangle{v, v + 1, v + 2});
  }
  const auto renumbered = std::make_shared<const TriangleMesh>(makeMesh(vertices, reversed, "torus reversed"));
  const std::shared_ptr<const TriangleMesh> meshes[2] = {torus, renumbered};
  // Levels of both meshes at several distances: other sphere lists, other grid contents.
  std::vector<std::pair<int, std::shared_ptr<const ClodSphereSet>>> levels;
  for (double d : {0.0, 0.03, 0.06, 0.01})
    for (int m = 0; m < 2; ++m)
      levels.emplace_back(m, std::make_shared<const ClodSphereSet>(ClodBuilder(meshes[m]).build(d)));
  // Within r of the surface: every answer is the bounded query's (no deep-penetration follow-up).
  auto probes = nearSurfaceProbes(*torus, 300, 0.0045, 11);
  sortMorton(probes);
  const double r = 0.005;
  std::vector<ContactResult> reference[2];
  for (int m = 0; m < 2; ++m)
    for (const Vec3& p : probes) reference[m].push_back(bruteForceQuery(*meshes[m], p, r));

  QueryCache cache;
  std::size_t reused = 0, checked = 0;
  const void* previous = nullptr;
  for (int cycle = 0; cycle < 60; ++cycle) {
    const int which = levels[cycle % levels.size()].first;
    auto detector = std::make_shared<const ClodDetector>(meshes[which], levels[cycle % levels.size()].second,
                                                         FastLevel::Grid, 0.02);
    if (detector.get() == previous) ++reused;
    previous = detector.get();
    EXPECT_NE(detector->id(), 0u);
    // The first pose is the previous detector's last one: the cell the cache remembers.
    const std::size_t start = (static_cast<std::size_t>(cycle) * 5) % probes.size();
    for (std::size_t k = 0; k < 6; ++k) {
      const std::size_t i = (start + k) % probes.size();
      ContactResult out;
      detector->query(probes[i], r, DetectionMode::Exact, out, &cache);
      const ContactResult& ref = reference[which][i];
      ASSERT_EQ(out.contact, ref.contact) << "cycle " << cycle << " pose " << k << " probe " << i;
      if (out.contact) {
        ASSERT_NEAR(out.distance, ref.distance, 1e-12) << "cycle " << cycle << " probe " << i;
        ASSERT_EQ(out.triangle, ref.triangle) << "cycle " << cycle << " probe " << i;
      }
      ++checked;
    }
    detector.reset();  // the level swap frees it; the cache keeps its entry
  }
  EXPECT_EQ(checked, 60u * 6u);
  // The test is only a test if the allocator did reuse addresses (glibc does for same-size blocks). AddressSanitizer
  // quarantines freed blocks instead, and reports any read of a freed detector itself.
#if !defined(__SANITIZE_ADDRESS__)
  EXPECT_GT(reused, 0u) << "no detector was allocated at a freed one's address: the reuse was not exercised";
#endif
}

// bytes() counts what each level keeps: at least a few bytes a triangle (grid, tree over the mesh) for the grid
// level, a record of 13 doubles per triangle for the hierarchy and the flat list; and no more than a few KB a
// triangle on a mesh of thousands.
TEST(ClodDetector, BytesCountWhatTheLevelKeeps) {
  const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh("elephant.off"));
  const auto set = std::make_shared<const ClodSphereSet>(ClodBuilder(mesh).build(0.02));
  const double n = static_cast<double>(mesh->size());
  const ClodDetector grid(mesh, set, FastLevel::Grid, 0.005), flat(mesh, set, FastLevel::Flat);
  const ClodDetector tree(mesh, set, FastLevel::Hierarchy);
  EXPECT_GE(static_cast<double>(grid.bytes()), 8.0 * n);  // the grid and the tree over the mesh
  EXPECT_GE(static_cast<double>(flat.bytes()), 104.0 * n);
  EXPECT_GT(tree.bytes(), flat.bytes());  // the same records, and the trees
  for (const ClodDetector* d : {&grid, &flat, &tree}) EXPECT_LT(static_cast<double>(d->bytes()), 4000.0 * n);
}

// The grid level keeps at most kBytesPerTriangle where its cells may be coarser at no cost: on shared meshes of a
// few thousand triangles at the nodes' r (before, head.off took 521 bytes a triangle, mesh_with_border.off 646),
// with the answers of the brute force.
TEST(ClodDetector, AGridLevelOfLargeTrianglesKeepsItsMemoryTarget) {
  for (const char* name : {"head.off", "mesh_with_border.off", "elephant.off"}) {
    SCOPED_TRACE(name);
    const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh(name));
    const auto set = std::make_shared<const ClodSphereSet>(ClodBuilder(mesh).build(0.02));
    const double r = 0.005;
    const ClodDetector grid(mesh, set, FastLevel::Grid, r);
    EXPECT_LE(static_cast<double>(grid.bytes()), ClodDetector::kBytesPerTriangle * static_cast<double>(mesh->size()));
    int mismatches = 0;
    for (const Vec3& p : nearSurfaceProbes(*mesh, 3000, 2 * r, 5)) {
      ContactResult ours;
      grid.query(p, r, DetectionMode::Exact, ours);
      const ContactResult ref = bruteForceQuery(*mesh, p, r);
      if (ours.contact != ref.contact || (ref.contact && ours.distance != ref.distance)) ++mismatches;
    }
    EXPECT_EQ(mismatches, 0);
  }
}

TEST(ClodDetector, IdsAreUniqueAndNeverZero) {
  const auto mesh = clod_test::loadNormalized(clod_test::testData("../../data/meshes/torus.obj"));
  const auto set = std::make_shared<const ClodSphereSet>(ClodBuilder(mesh).build(0.02));
  std::uint64_t last = 0;
  for (int i = 0; i < 5; ++i) {
    const ClodDetector d(mesh, set, FastLevel::Hierarchy);
    EXPECT_GT(d.id(), last);
    last = d.id();
  }
}

// The force must not collapse while the stylus pushes in. A stylus stream (one
// QueryCache) pushes straight into box_4x2x1 (x -7..-3, y 10..12, z 0.5..1.5, loaded through the loader),
// through the middle of the top face, of the edge y = 12, z = 1.5 and of the corner (-3, 12, 1.5), in
// small steps from outside to the box's middle. From the first touch to the middle, the depth (and so the
// spring force, stiffness * depth) strictly increases at every step, the force points out of the box, and
// every answer is the signed brute-force reference's.
struct Push {
  const char* name;
  Vec3 feature;  // where the line crosses the surface
};

void expectMonotonePush(const std::shared_ptr<const TriangleMesh>& mesh, const ClodDetector& det, const Push& push,
                        double r, DetectionMode mode) {
  SCOPED_TRACE(std::string(push.name) + " " + toString(mode));
  const Vec3 middle(-5.0, 11.0, 1.0);
  const Vec3 out = (push.feature - middle).normalized();  // outward along the line
  const double inward = (push.feature - middle).norm();   // feature to middle
  const Vec3 start = push.feature + 2.0 * r * out;
  const int steps = 500;
  const double stiffness = 1000.0;
  QueryCache cache;
  ContactResult got, stateless;
  double lastDepth = -1.0, lastForce = -1.0;
  int touching = 0, deepSteps = 0;
  bool touched = false;
  for (int i = 0; i <= steps; ++i) {
    const Vec3 p = start + (2.0 * r + inward) * (double(i) / steps) * (-out);
    det.query(p, r, mode, got, &cache);
    const ContactResult ref = bruteForceSignedQuery(*mesh, p, r);
    ASSERT_EQ(got.contact, ref.contact) << "step " << i << " p " << p.transpose();
    if (!got.contact) {
      ASSERT_FALSE(touched) << "step " << i << ": the contact was lost while pushing in";
      continue;
    }
    touched = true;
    ++touching;
    ASSERT_NEAR(got.distance, ref.distance, 1e-12) << "step " << i;
    ASSERT_EQ(got.inside, ref.inside) << "step " << i;
    ASSERT_NEAR(got.depth, ref.depth, 1e-12) << "step " << i;
    // The geometric truth of the box: inside is strictly within all six faces.
    const bool inBox = p.x() > -7 && p.x() < -3 && p.y() > 10 && p.y() < 12 && p.z() > 0.5 && p.z() < 1.5;
    ASSERT_EQ(got.inside, inBox) << "step " << i << " p " << p.transpose();
    const Vec3 force = stiffness * got.depth * got.normal;
    ASSERT_GT(got.depth, lastDepth) << "step " << i << ": the depth fell while pushing in";
    ASSERT_GT(force.norm(), lastForce) << "step " << i << ": the force fell while pushing in";
    // At the middle itself the far face is as near as the near one (the tie may pick either).
    if (i < steps) {
      ASSERT_GT(force.dot(out), 0.0) << "step " << i << ": the force does not push out";
    }
    lastDepth = got.depth;
    lastForce = force.norm();
    if (got.distance > r) {
      ++deepSteps;
      // Stateless, the same pose is no contact: the deep push is followed only by a stream.
      det.query(p, r, mode, stateless);
      ASSERT_FALSE(stateless.contact) << "step " << i;
    }
  }
  EXPECT_GT(touching, steps / 2);
  EXPECT_GT(deepSteps, steps / 3) << "most of the push is deeper than r";
  EXPECT_NEAR(lastDepth, r + 0.5, 1e-9) << "at the middle: r + half the box's thickness";
}

TEST(ClodDetector, PushingInKeepsTheForceGrowing) {
  const auto mesh = std::make_shared<const TriangleMesh>(loadMesh(clod_test::testData("box_4x2x1.obj")));
  const ClodBuilder builder(mesh);
  const auto set = std::make_shared<const ClodSphereSet>(builder.build(0.1));
  const double r = 0.05;
  const Push pushes[] = {
      {"face", Vec3(-5.0, 11.0, 1.5)}, {"edge", Vec3(-5.0, 12.0, 1.5)}, {"vertex", Vec3(-3.0, 12.0, 1.5)}};
  // The grid serving r (deep search: grid, then hierarchy), the grid below r, the hierarchy, the flat list.
  for (const auto& [fast, gridRadius] : {std::pair{FastLevel::Grid, 0.2}, std::pair{FastLevel::Grid, 0.0},
                                         std::pair{FastLevel::Hierarchy, 0.0}, std::pair{FastLevel::Flat, 0.0}}) {
    const ClodDetector det(mesh, set, fast, gridRadius);
    for (const Push& push : pushes) {
      SCOPED_TRACE("fast level " + std::to_string(int(fast)) + " grid radius " + std::to_string(gridRadius));
      expectMonotonePush(mesh, det, push, r, DetectionMode::Exact);
      if (HasFatalFailure()) return;
    }
  }
  // Paper mode through the face (its precise test sees faces only).
  const ClodDetector det(mesh, set, FastLevel::Grid);
  expectMonotonePush(mesh, det, pushes[0], r, DetectionMode::Paper);
}

// Compares a followed stream's answers with the signed brute force (bruteForceSignedQuery): the stream entered within
// r, so it follows the push, and the signed reference answers as such a stream (contact, depth r + distance) wherever
// the centre is behind the surface. Except where the reference calls a centre behind the surface that the stream
// never entered (a free point farther than r from the surface: it left the model and came back deeper, or the nearest
// feature's pseudo-normal points away, as on mannequin-devil's overlapping parts): counted apart, not compared.
struct SignedStreamCheck {
  double r, tol;
  int wrong = 0, deep = 0, unentered = 0;
  void operator()(const ContactResult& got, const ContactResult& ref, int push, int step) {
    if (!got.contact && ref.contact && ref.inside && ref.distance > r) {
      ++unentered;
      return;
    }
    if (got.contact && got.inside && got.distance > r) ++deep;
    const bool same =
        got.contact == ref.contact && (!got.contact || (std::abs(got.distance - ref.distance) <= tol &&
                                                        got.inside == ref.inside && got.triangle == ref.triangle));
    if (!same && wrong++ < 5)
      ADD_FAILURE() << "push " << push << " step " << step << ": contact " << got.contact << " vs " << ref.contact
                    << ", distance " << got.distance << " vs " << ref.distance << ", triangle " << got.triangle
                    << " vs " << ref.triangle;
  }
};

// Pushes into three shared meshes, each from the centroid of a random triangle along steps `at(centroid, inward
// normal, step)`, one QueryCache a push, every answer checked with SignedStreamCheck.
void checkFollowedPushes(std::uint64_t seed, int pushes, int firstStep, int lastStep,
                         const std::function<Vec3(const Vec3&, const Vec3&, int, double)>& at, int minDeep,
                         int maxUnentered) {
  for (const char* name : {"elephant.off", "head.off", "mannequin-devil.off"}) {
    SCOPED_TRACE(name);
    const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh(name));
    const auto set = std::make_shared<const ClodSphereSet>(ClodBuilder(mesh).build(0.02));
    const double r = 0.005, tol = 1e-12 * mesh->diagonal();
    const ClodDetector det(mesh, set, FastLevel::Grid, r);
    std::mt19937_64 rng(seed);
    std::uniform_int_distribution<std::size_t> pick(0, mesh->size() - 1);
    SignedStreamCheck check{r, tol};
    for (int push = 0; push < pushes; ++push) {
      const std::size_t t = pick(rng);
      const Vec3 n = mesh->normals[t];
      if (!(n.squaredNorm() > 0.5)) continue;
      const Vec3 c = mesh->toModel(mesh->centroid(t));
      QueryCache cache;
      for (int step = firstStep; step <= lastStep; ++step) {
        const Vec3 p = at(c, -n, step, r);
        ContactResult got;
        det.query(p, r, DetectionMode::Exact, got, &cache);
        check(got, bruteForceSignedQuery(*mesh, p, r), push, step);
      }
    }
    EXPECT_EQ(check.wrong, 0);
    EXPECT_GT(check.deep, minDeep) << "the pushes must reach beyond r";
    EXPECT_LT(check.unentered, maxUnentered);
  }
}

// A stream pushed from outside to 6 r behind the surface along the inward normal of random triangles, r / 8 a step:
// every answer (contact, distance, inside, triangle) is the signed brute force's. The first steps beyond r are
// answered from the grid cell of the centre (listedWithin), the deeper ones by the tree over the mesh: both are
// checked against every triangle.
TEST(ClodDetector, ADeepPushIsAnsweredAsTheSignedBruteForce) {
  checkFollowedPushes(
      29, 24, -16, 48,
      [](const Vec3& c, const Vec3& in, int step, double r) { return Vec3(c + (step * r / 8.0) * in); }, 100, 50);
}

// A push followed at speed: the stream enters, then slides 2.7 r a query (2 m/s at 1 kHz on a 15 cm model) at 1.5 r
// deep, so the last answer's triangle lies farther than the grid cell of the next centre lists and the nearest is
// looked for in that cell first (deepFromCell's bounded scan), else in the tree.
TEST(ClodDetector, AFastPushIsAnsweredAsTheSignedBruteForce) {
  checkFollowedPushes(
      31, 48, -4, 16,
      [](const Vec3& c, const Vec3& in, int step, double r) {
        const Vec3 deep = c + 1.5 * r * in;
        return step <= 0 ? Vec3(c + (step + 4) / 4.0 * (deep - c)) : Vec3(deep + 2.7 * r * step * in.unitOrthogonal());
      },
      100, 200);
}

// Leaving again: a stream that was deep inside and jumps outside (beyond r) answers no contact, and a later
// deep pose without passing through the surface is not followed.
TEST(ClodDetector, AFollowedPushEndsOutside) {
  const auto mesh = std::make_shared<const TriangleMesh>(loadMesh(clod_test::testData("box_4x2x1.obj")));
  const auto set = std::make_shared<const ClodSphereSet>(ClodBuilder(mesh).build(0.1));
  const double r = 0.05;
  for (FastLevel fast : {FastLevel::Grid, FastLevel::Hierarchy, FastLevel::Flat}) {
    const ClodDetector det(mesh, set, fast);
    QueryCache cache;
    ContactResult out;
    det.query(Vec3(-5, 11, 1.49), r, DetectionMode::Exact, out, &cache);
    ASSERT_TRUE(out.contact && out.inside);
    det.query(Vec3(-5, 11, 1.2), r, DetectionMode::Exact, out, &cache);  // 0.3 deep
    ASSERT_TRUE(out.contact && out.inside);
    EXPECT_NEAR(out.depth, r + 0.3, 1e-12);
    EXPECT_TRUE(out.normal.isApprox(Vec3::UnitZ(), 1e-12));
    det.query(Vec3(-5, 11, 1.7), r, DetectionMode::Exact, out, &cache);  // jumped out, 0.2 above
    EXPECT_FALSE(out.contact);
    EXPECT_FALSE(cache.lastInside);
    det.query(Vec3(-5, 11, 1.2), r, DetectionMode::Exact, out, &cache);
    EXPECT_FALSE(out.contact) << "not followed: the stream's last answer was outside";
    // Outside the model's box a followed stream answers no contact without searching the whole model.
    cache.lastInside = true;
    det.query(Vec3(-5, 11, 3.0), r, DetectionMode::Exact, out, &cache);
    EXPECT_FALSE(out.contact);
    EXPECT_FALSE(cache.lastInside);
  }
}

// A level built for another mesh is refused with a typed error, never read past the mesh's arrays (it was a
// heap-buffer-overflow under ASan): the torus's set (3,200 triangles listed) against the 12-triangle box, and
// the torus's own set on the torus scaled by 2 (indices in range, coverage broken).
TEST(ClodDetector, ASetThatDoesNotFitTheMeshIsRefused) {
  const auto torus = clod_test::loadNormalized(clod_test::testData("../../data/meshes/torus.obj"));
  const auto box = std::make_shared<const TriangleMesh>(loadMesh(clod_test::testData("box_4x2x1.obj")));
  const auto set = std::make_shared<const ClodSphereSet>(ClodBuilder(torus).build(0.01));
  ASSERT_EQ(fitProblem(*torus, *set), "");
  for (FastLevel level : {FastLevel::Grid, FastLevel::Hierarchy, FastLevel::Flat}) {
    EXPECT_THROW(ClodDetector(box, set, level), SphereSetMismatch);
    try {
      ClodDetector(box, set, level);
    } catch (const SphereSetMismatch& e) {
      EXPECT_NE(std::string(e.what()).find("does not fit mesh 'box_4x2x1.obj'"), std::string::npos) << e.what();
    }
  }
  std::vector<Vec3> doubled = torus->vertices;
  for (Vec3& v : doubled) v *= 2.0;
  const auto bigger = std::make_shared<const TriangleMesh>(makeMesh(doubled, torus->triangles, "torus x2"));
  EXPECT_THROW(ClodDetector(bigger, set), SphereSetMismatch);
  EXPECT_NO_THROW(ClodDetector(torus, set));
}

TEST(FastLevel, Parses) {
  FastLevel level;
  EXPECT_TRUE(parseFastLevel("flat", level));
  EXPECT_EQ(level, FastLevel::Flat);
  EXPECT_TRUE(parseFastLevel("hierarchy", level));
  EXPECT_EQ(level, FastLevel::Hierarchy);
  EXPECT_TRUE(parseFastLevel("grid", level));
  EXPECT_EQ(level, FastLevel::Grid);
  EXPECT_FALSE(parseFastLevel("tree", level));
  EXPECT_FALSE(parseFastLevel(nullptr, level));
  DetectionMode mode;
  for (DetectionMode m : {DetectionMode::Exact, DetectionMode::Paper, DetectionMode::Spheres}) {
    EXPECT_TRUE(parseDetectionMode(toString(m), mode));
    EXPECT_EQ(mode, m);
  }
  EXPECT_FALSE(parseDetectionMode("Exact", mode));
  EXPECT_FALSE(parseDetectionMode(nullptr, mode));
}

}  // namespace
