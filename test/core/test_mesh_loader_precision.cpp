// Exactness through the loader: a mesh written to a file far from the origin (offsets 1e3 to 1e6) or at scales
// 1e-6 to 1e6, loaded by loadMesh as a user loads it, queried by the default exact detector, and compared with
// a quad-precision brute force on the file's own numbers (quad_reference.h). Tolerances are relative to the
// pointer radius or the distance, 1e-12: a mesh kept in world coordinates at 1e6 misses it by about 1e4 (its
// double spacing there is 1.2e-10), a mesh kept relative to its local origin meets it.

#include <gtest/gtest.h>

#include <cfloat>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <unistd.h>

#include "clod_haptics/core/detector.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/sphere_set.h"
#include "mesh_writers.h"
#include "quad_reference.h"
#include "test_helpers.h"

namespace {

using namespace clod_haptics;
using clod_test::Quad;

// A torus in the unit cube with a ripple and uneven rings: small and long triangles, every edge direction.
clod_test::QuadMesh rippledTorus() {
  clod_test::QuadMesh m;
  const int nu = 56, nv = 20;
  for (int i = 0; i < nu; ++i) {
    const double u = 2.0 * M_PI * (i + 0.3 * std::sin(3.0 * i)) / nu;
    for (int j = 0; j < nv; ++j) {
      const double v = 2.0 * M_PI * j / nv;
      const double tube = 0.12 * (1.0 + 0.25 * std::sin(5.0 * u) * std::cos(2.0 * v));
      const double ring = 0.33 + tube * std::cos(v);
      m.vertices.push_back({0.5 + ring * std::cos(u), 0.5 + ring * std::sin(u), 0.5 + tube * std::sin(v)});
    }
  }
  for (int i = 0; i < nu; ++i)
    for (int j = 0; j < nv; ++j) {
      const auto a = std::uint32_t(i * nv + j), b = std::uint32_t(((i + 1) % nu) * nv + j),
                 c = std::uint32_t(((i + 1) % nu) * nv + (j + 1) % nv), d = std::uint32_t(i * nv + (j + 1) % nv);
      m.triangles.push_back({a, b, c});
      m.triangles.push_back({a, c, d});
    }
  return m;
}

// A shared mesh in the unit cube (its file's numbers scaled there: the test's starting shape).
clod_test::QuadMesh sharedUnitMesh(const std::string& name) {
  const TriangleMesh mesh = *clod_test::loadNormalized(clod_test::sharedMesh(name));
  clod_test::QuadMesh m;
  for (const Vec3& v : mesh.vertices) {
    const Vec3 w = mesh.toModel(v);
    m.vertices.push_back({w.x(), w.y(), w.z()});
  }
  for (const Triangle& t : mesh.triangles) m.triangles.push_back({t[0], t[1], t[2]});
  return m;
}

struct Placement {
  std::string label;
  double fileScale;   // the file's numbers: unit shape * fileScale + fileOffset * (1, -0.5, 0.25)
  double fileOffset;
  double loadScale;   // MeshLoadOptions::scale
  bool normalize;
};

struct Errors {
  std::size_t probes = 0, contacts = 0, flagChecks = 0;
  double maxRelDistance = 0.0, maxPointError = 0.0;
};

// Writes the placed mesh as OFF with round-tripping digits; returns the file's numbers as written.
clod_test::QuadMesh writePlaced(const clod_test::QuadMesh& unit, const Placement& pl, const std::string& path) {
  clod_test::QuadMesh file = unit;
  const double dir[3] = {1.0, -0.5, 0.25};
  for (auto& v : file.vertices)
    for (int k = 0; k < 3; ++k) v[k] = v[k] * pl.fileScale + pl.fileOffset * dir[k];
  std::FILE* f = std::fopen(path.c_str(), "w");
  std::fprintf(f, "OFF\n%zu %zu 0\n", file.vertices.size(), file.triangles.size());
  for (const auto& v : file.vertices) std::fprintf(f, "%.17g %.17g %.17g\n", v[0], v[1], v[2]);
  for (const auto& t : file.triangles) std::fprintf(f, "3 %u %u %u\n", t[0], t[1], t[2]);
  std::fclose(f);
  return file;
}

// The exact map from the file to the model frame that the load options ask for.
void setModelMap(clod_test::QuadMesh& file, const Placement& pl) {
  if (!pl.normalize) {
    file.scale = Quad(pl.loadScale);
    return;
  }
  Quad lo[3], hi[3];
  for (int k = 0; k < 3; ++k) lo[k] = hi[k] = Quad(file.vertices[0][k]);
  for (const auto& v : file.vertices)
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], Quad(v[k]));
      hi[k] = std::max(hi[k], Quad(v[k]));
    }
  const Quad extent = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
  file.scale = 1 / extent;
  file.shift = {Quad(0.5) - (lo[0] + hi[0]) / 2 * file.scale, Quad(0.5) - (lo[1] + hi[1]) / 2 * file.scale,
                Quad(0.5) - (lo[2] + hi[2]) / 2 * file.scale};
}

// Probes in the model frame (doubles): near faces on both sides, near vertices and edges, and uniform.
std::vector<std::array<double, 3>> probesFor(const std::vector<std::array<double, 3>>& model,
                                            const clod_test::QuadMesh& mesh, double r,
                                            std::size_t count, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0), sym(-1.0, 1.0);
  std::uniform_int_distribution<std::size_t> anyTri(0, mesh.triangles.size() - 1);
  std::array<double, 3> lo = model[0], hi = model[0];
  for (const auto& v : model)
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], v[k]);
      hi[k] = std::max(hi[k], v[k]);
    }
  std::vector<std::array<double, 3>> out;
  for (std::size_t i = 0; i < count; ++i) {
    const auto& t = mesh.triangles[anyTri(rng)];
    double u = unit(rng), v = unit(rng);
    if (u + v > 1.0) u = 1.0 - u, v = 1.0 - v;
    if (i % 4 == 2) {  // near an edge, or a vertex
      v = 0.0;
      if (i % 8 == 2) u = std::round(u);
    }
    std::array<double, 3> p{};
    const double reach = (i % 4 == 3) ? 0.0 : 3.0 * r;
    for (int k = 0; k < 3; ++k) {
      const double a = model[t[0]][k], b = model[t[1]][k], c = model[t[2]][k];
      // Offsets relative to the first vertex: no cancellation at large offsets.
      p[k] = (i % 4 == 3) ? lo[k] + unit(rng) * (hi[k] - lo[k]) : a + (u * (b - a) + v * (c - a) + sym(rng) * reach);
    }
    out.push_back(p);
  }
  return out;
}

// Loads path with options as a user does, queries the default exact detector at probes near the surface, and
// compares every answer with the quad-precision brute force on file (the numbers as written, mapped to the model
// frame exactly). size: the model's largest side; r = 0.005 and d = 0.02 of it, as on a unit model.
Errors checkLoaded(const clod_test::QuadMesh& file, const std::string& path, const MeshLoadOptions& options,
                   double size, const std::string& label, std::size_t probeCount) {
  const auto mesh = std::make_shared<const TriangleMesh>(loadMesh(path, options));
  const double r = 0.005 * size, d = 0.02 * size;
  const auto set = std::make_shared<const ClodSphereSet>(ClodBuilder(mesh).build(d));
  const ClodDetector detector(mesh, set);  // the defaults clod_tool and the nodes use

  std::vector<std::array<double, 3>> model;
  double magnitude = 0.0;
  for (std::uint32_t v = 0; v < file.vertices.size(); ++v) {
    const clod_test::Q3 q = file.model(v);
    model.push_back({double(q.x), double(q.y), double(q.z)});
    for (int k = 0; k < 3; ++k) magnitude = std::max(magnitude, std::abs(model.back()[k]));
  }
  // A contact point is a double of the model frame: good to a unit in the last place of its coordinates.
  const double pointUlp = 4.0 * DBL_EPSILON * magnitude;
  const auto probes = probesFor(model, file, r, probeCount, 77);

  struct Row {
    bool checked = false, flagWrong = false, contact = false;
    double relDistance = 0.0, pointError = 0.0, distance = 0.0, reference = 0.0;
  };
  std::vector<Row> rows(probes.size());
  clod_test::parallelFor(probes.size(), 2, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) {
      const auto& p = probes[i];
      const auto ref = clod_test::quadNearest(file, model, p, 64.0 * DBL_EPSILON * magnitude + 1e-9 * size);
      ContactResult got;
      detector.query(Vec3(p[0], p[1], p[2]), r, DetectionMode::Exact, got);
      Row& row = rows[i];
      row.reference = static_cast<double>(ref.distance);
      row.distance = got.distance;
      const double tol = 1e-12 * std::max(row.reference, r);
      if (std::abs(row.reference - r) > tol) {  // a probe within rounding of the radius may go either way
        row.checked = true;
        row.flagWrong = got.contact != (row.reference <= r);
      }
      if (!got.contact || row.reference > r) continue;
      row.contact = true;
      row.relDistance = std::abs(got.distance - row.reference) / std::max(row.reference, r);
      long double pointErr = INFINITY;
      for (const auto& q : ref.points) {
        const long double dx = got.point.x() - q[0], dy = got.point.y() - q[1], dz = got.point.z() - q[2];
        pointErr = std::min(pointErr, std::sqrt(dx * dx + dy * dy + dz * dz));
      }
      row.pointError = double(pointErr);
    }
  });
  Errors e;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const Row& row = rows[i];
    ++e.probes;
    e.flagChecks += row.checked;
    EXPECT_FALSE(row.flagWrong) << label << " probe " << i << ": contact " << !row.contact << ", reference distance "
                                << row.reference << ", r " << r;
    if (!row.contact) continue;
    ++e.contacts;
    e.maxRelDistance = std::max(e.maxRelDistance, row.relDistance);
    e.maxPointError = std::max(e.maxPointError, row.pointError / size);
    EXPECT_LE(row.relDistance, 1e-12) << label << " probe " << i << ": distance " << row.distance << ", reference "
                                      << row.reference;
    EXPECT_LE(row.pointError, 1e-12 * size + pointUlp) << label << " probe " << i;
  }
  std::printf("[ INFO     ] %-30s %5zu probes, %4zu contacts, max |d - d_ref| / max(d_ref, r) %.2e, max point "
              "error / size %.2e (coordinates up to %.3g, origin %.17g %.17g %.17g)\n",
              label.c_str(), e.probes, e.contacts, e.maxRelDistance, e.maxPointError, magnitude, mesh->origin.x(),
              mesh->origin.y(), mesh->origin.z());
  EXPECT_GT(e.contacts, e.probes / 10) << label;
  return e;
}

Errors checkPlacement(const clod_test::QuadMesh& unit, const Placement& pl, const std::string& dir) {
  const std::string path = dir + "/" + pl.label + ".off";
  clod_test::QuadMesh file = writePlaced(unit, pl, path);
  setModelMap(file, pl);
  MeshLoadOptions options;
  options.scale = pl.loadScale;
  options.normalize = pl.normalize;
  options.orientOutward = false;  // the file's winding as written
  const double size = pl.normalize ? 1.0 : pl.fileScale * pl.loadScale;
  return checkLoaded(file, path, options, size, pl.label, 1200);
}

std::vector<Placement> placements() {
  std::vector<Placement> out;
  for (double offset : {0.0, 1e3, 1e5, 1e6}) {
    char label[64];
    std::snprintf(label, sizeof label, "offset_%g", offset);
    out.push_back({label, 1.0, offset, 1.0, false});
  }
  for (double scale : {1e-6, 1e-3, 1e3, 1e6}) {
    char label[64];
    std::snprintf(label, sizeof label, "file_scale_%g", scale);
    out.push_back({label, scale, 0.0, 1.0, false});
    std::snprintf(label, sizeof label, "file_scale_%g_off_1e6", scale);
    out.push_back({label, scale, 1e6 * scale, 1.0, false});
  }
  out.push_back({"load_scale_1e-3_off_1e5", 1.0, 1e5, 1e-3, false});
  out.push_back({"load_scale_1e3_off_1e5", 1.0, 1e5, 1e3, false});
  out.push_back({"normalize_off_1e6", 1.0, 1e6, 1.0, true});
  return out;
}

using LoaderPrecision = clod_test::TempDirTest;

TEST_F(LoaderPrecision, RippledTorusEqualsQuadBruteForceAtEveryOffsetAndScale) {
  const auto unit = rippledTorus();
  for (const Placement& pl : placements()) checkPlacement(unit, pl, dir_.string());
}

TEST_F(LoaderPrecision, SharedHeadEqualsQuadBruteForceAtEveryOffsetAndScale) {
  const auto unit = sharedUnitMesh("head.off");
  for (const Placement& pl : placements()) checkPlacement(unit, pl, dir_.string());
}

// The done-when figure of the loader: every shared mesh, written in every format the double readers take, at
// its place and moved by 1e6, loaded with the defaults users get (scale 1, windings made outward), equals the
// quad brute force on the file's numbers within 1e-12 of the distance or the radius.
TEST_F(LoaderPrecision, EverySharedMeshInEveryFormatEqualsQuadBruteForce) {
  for (const std::string& path : clod_test::sharedMeshes()) {
    const TriangleMesh original = loadMesh(path);
    clod_test::Soup3 numbers;
    for (const Vec3& v : original.vertices) {
      const Vec3 w = original.toModel(v);
      numbers.push_back({w.x(), w.y(), w.z()});
    }
    clod_test::Faces3 faces;
    for (const Triangle& t : original.triangles) faces.push_back({t[0], t[1], t[2]});
    const double size = original.bounds().sizes().maxCoeff();
    for (double offset : {0.0, 1e6}) {
      clod_test::Soup3 placed = numbers;
      for (auto& p : placed) p = {p[0] + offset, p[1] - 0.5 * offset, p[2] + 0.25 * offset};
      for (const std::string& format : clod_test::meshFormats()) {
        const std::string label = clod_test::baseName(path) + " " + format + (offset != 0.0 ? " +1e6" : "");
        const std::string file = (dir_ / ("shared." + format)).string();
        ASSERT_TRUE(clod_test::writeMeshAs(format, placed, faces, file)) << label;
        clod_test::QuadMesh reference;
        reference.vertices = clod_test::numbersAsWritten(format, placed);
        reference.triangles = faces;
        checkLoaded(reference, file, MeshLoadOptions(), size, label, 500);
      }
    }
  }
}

TEST(LocalOrigin, FarMeshStoredRelativeToItsCentreExactly) {
  // The Sterbenz argument of chooseLocalOrigin, on numbers with all 53 bits used.
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> jitter(-0.5, 0.5);
  for (double offset : {1e3, 1e5, 1e6, 1e12, -1e9}) {
    std::vector<Vec3> vertices;
    for (int i = 0; i < 30; ++i) vertices.emplace_back(offset + jitter(rng), jitter(rng), offset * 0.5 + jitter(rng));
    std::vector<Triangle> triangles;
    for (std::uint32_t i = 0; i + 2 < 30; ++i) triangles.push_back({i, i + 1, i + 2});
    const TriangleMesh mesh = makeMesh(vertices, triangles);
    EXPECT_NE(mesh.origin.x(), 0.0);
    EXPECT_EQ(mesh.origin.y(), 0.0);  // this axis is near zero: kept as given
    for (std::size_t i = 0; i < vertices.size(); ++i) {
      EXPECT_EQ(mesh.toModel(mesh.vertices[i]), vertices[i]) << "offset " << offset << " vertex " << i;
      EXPECT_LE(mesh.vertices[i].cwiseAbs().maxCoeff(), 2.0);
    }
  }
}

}  // namespace
