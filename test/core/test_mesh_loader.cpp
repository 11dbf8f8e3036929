// Mesh loading: every fixture format (scripts/make_test_fixtures.py), vertex joining, scale and
// normalisation, and each bad input giving its typed error with the path in the message.

#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <random>
#include <string>

#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/mesh.h"
#include "clod_haptics/core/mesh_loader.h"
#include "test_helpers.h"

namespace {

using namespace clod_haptics;
using clod_test::testData;

const Vec3 kCubeMin(1.0, 2.0, 3.0), kCubeMax(3.0, 4.0, 5.0);

// Each undirected edge of a closed, joined mesh is shared by exactly two triangles.
void expectClosed(const TriangleMesh& mesh) {
  std::map<std::pair<std::uint32_t, std::uint32_t>, int> edges;
  for (const Triangle& t : mesh.triangles)
    for (int k = 0; k < 3; ++k) {
      std::uint32_t a = t[k], b = t[(k + 1) % 3];
      if (a > b) std::swap(a, b);
      ++edges[{a, b}];
    }
  for (const auto& e : edges) EXPECT_EQ(e.second, 2) << "edge " << e.first.first << "-" << e.first.second;
}

void expectCube(const std::string& file) {
  SCOPED_TRACE(file);
  const TriangleMesh mesh = loadMesh(testData(file));
  EXPECT_EQ(mesh.vertices.size(), 8u) << "identical vertices must be joined";
  ASSERT_EQ(mesh.size(), 12u);
  ASSERT_EQ(mesh.normals.size(), 12u);
  EXPECT_EQ(mesh.name, file);
  EXPECT_EQ(mesh.scale, 1.0);
  const Eigen::AlignedBox3d box = mesh.bounds();
  EXPECT_TRUE(box.min().isApprox(kCubeMin, 1e-12)) << box.min().transpose();
  EXPECT_TRUE(box.max().isApprox(kCubeMax, 1e-12)) << box.max().transpose();
  // Every vertex is a cube corner; every normal is a unit axis pointing away from the centre.
  const Vec3 centre = 0.5 * (kCubeMin + kCubeMax);
  for (const Vec3& v : mesh.vertices)
    for (int k = 0; k < 3; ++k) EXPECT_TRUE(v[k] == kCubeMin[k] || v[k] == kCubeMax[k]) << v.transpose();
  for (std::size_t t = 0; t < mesh.size(); ++t) {
    EXPECT_NEAR(mesh.normals[t].norm(), 1.0, 1e-12);
    EXPECT_GT(mesh.normals[t].dot(mesh.centroid(t) - centre), 0.0) << "triangle " << t << " wound inward";
  }
  expectClosed(mesh);
}

TEST(MeshLoader, ObjWithOneVertexPerCorner) { expectCube("cube.obj"); }
TEST(MeshLoader, ObjQuadsAreTriangulated) { expectCube("cube_quads.obj"); }
TEST(MeshLoader, StlAscii) { expectCube("cube_ascii.stl"); }
TEST(MeshLoader, StlBinary) { expectCube("cube_binary.stl"); }
TEST(MeshLoader, PlyAscii) { expectCube("cube_ascii.ply"); }
TEST(MeshLoader, PlyBinary) { expectCube("cube_binary.ply"); }
TEST(MeshLoader, Off) { expectCube("cube.off"); }
TEST(MeshLoader, Collada) { expectCube("cube.dae"); }

TEST(MeshLoader, UniformScale) {
  MeshLoadOptions options;
  options.scale = 2.5;
  const TriangleMesh mesh = loadMesh(testData("cube_binary.stl"), options);
  EXPECT_EQ(mesh.scale, 2.5);
  EXPECT_TRUE(mesh.offset.isZero(0.0));
  EXPECT_TRUE(mesh.bounds().min().isApprox(2.5 * kCubeMin, 1e-12));
  EXPECT_TRUE(mesh.bounds().max().isApprox(2.5 * kCubeMax, 1e-12));
  EXPECT_EQ(mesh.vertices.size(), 8u);
}

TEST(MeshLoader, NormalizeFitsUnitCubeKeepingAspect) {
  const TriangleMesh raw = loadMesh(testData("box_4x2x1.obj"));
  MeshLoadOptions options;
  options.normalize = true;
  options.scale = 123.0;  // ignored when normalising
  const TriangleMesh mesh = loadMesh(testData("box_4x2x1.obj"), options);
  const Eigen::AlignedBox3d box = mesh.bounds();
  for (int k = 0; k < 3; ++k) {
    EXPECT_GE(box.min()[k], -1e-15);
    EXPECT_LE(box.max()[k], 1.0 + 1e-15);
    EXPECT_NEAR(box.center()[k], 0.5, 1e-15) << "centred on axis " << k;
  }
  EXPECT_NEAR(box.sizes().maxCoeff(), 1.0, 1e-15);
  EXPECT_TRUE(box.sizes().isApprox(Vec3(1.0, 0.5, 0.25), 1e-15)) << box.sizes().transpose();
  EXPECT_NEAR(mesh.scale, 0.25, 1e-15);
  ASSERT_EQ(mesh.vertices.size(), raw.vertices.size());
  for (std::size_t i = 0; i < raw.vertices.size(); ++i)
    EXPECT_TRUE((raw.vertices[i] * mesh.scale + mesh.offset).isApprox(mesh.vertices[i], 1e-14))
        << "scale and offset describe the transform";
  for (std::size_t t = 0; t < mesh.size(); ++t) EXPECT_TRUE(mesh.normals[t].isApprox(raw.normals[t], 1e-14));
}

TEST(MeshLoader, BadScaleIsInvalidParameter) {
  for (double s : {0.0, -1.0, std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()}) {
    MeshLoadOptions options;
    options.scale = s;
    EXPECT_THROW(loadMesh(testData("cube.obj"), options), InvalidParameter) << "scale " << s;
  }
}

// The typed error, the path in both the message and path(), and a reason that says what went wrong.
void expectLoadError(const std::string& path, const std::vector<std::string>& reasonWords) {
  SCOPED_TRACE(path);
  try {
    loadMesh(path);
    ADD_FAILURE() << "no exception for " << path;
  } catch (const MeshLoadError& e) {
    EXPECT_EQ(e.path(), path);
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    bool any = reasonWords.empty();
    for (const auto& w : reasonWords) any = any || e.reason().find(w) != std::string::npos;
    EXPECT_TRUE(any) << "reason: " << e.reason();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "wrong exception type: " << e.what();
  }
}

TEST(MeshLoader, MissingFile) { expectLoadError(testData("does_not_exist.obj"), {"no such file"}); }
TEST(MeshLoader, DirectoryIsNotAMesh) { expectLoadError(std::string(CLOD_TEST_DATA_DIR), {"directory"}); }
TEST(MeshLoader, UnreadableFormat) { expectLoadError(testData("unreadable.stl"), {"not an STL file"}); }
TEST(MeshLoader, BinaryJunkWithObjName) { expectLoadError(testData("unreadable.obj"), {"not an OBJ file"}); }
TEST(MeshLoader, NoTriangles) { expectLoadError(testData("no_triangles.obj"), {"no triangles"}); }
TEST(MeshLoader, NoFaces) { expectLoadError(testData("no_faces.off"), {"triangle", "face"}); }
TEST(MeshLoader, NanCoordinateOff) {
  expectLoadError(testData("nan_vertex.off"), {"line 8: coordinate x of vertex 5 is 'nan', not a finite number"});
}
TEST(MeshLoader, InfCoordinateOff) { expectLoadError(testData("inf_vertex.off"), {"is 'inf', not a finite number"}); }
TEST(MeshLoader, NanCoordinateObj) { expectLoadError(testData("nan_vertex.obj"), {"is 'nan', not a finite number"}); }

// Hostile files (scripts/make_test_fixtures.py, hostile_*): each is refused with a reason that names the
// problem; none loads as another mesh, none crashes, none makes the loader reserve what the file cannot hold.
TEST(MeshLoader, PlyWithFewerFacesThanItsHeader) {
  expectLoadError(testData("hostile_fewer_faces.ply"), {"header says 12 faces, the file ends after 1"});
}
TEST(MeshLoader, OffFaceIndexBeyondTheVertices) {
  expectLoadError(testData("hostile_off_index_too_large.off"),
                  {"line 15: face 4 uses vertex 8 but the file has 8 vertices"});
}
TEST(MeshLoader, OffNegativeFaceIndex) {
  expectLoadError(testData("hostile_off_index_negative.off"),
                  {"line 15: face 4 uses vertex -1 but the file has 8 vertices"});
}
TEST(MeshLoader, OffFaceIndexThatIsNotANumber) {
  expectLoadError(testData("hostile_off_index_text.off"), {"line 15: face 4: vertex index 'abc' is not a number"});
}
TEST(MeshLoader, ObjFaceIndexBeyondTheVertices) {
  expectLoadError(testData("hostile_obj_index_too_large.obj"),
                  {"line 21: face 12 uses vertex 9 but the file has 8 vertices"});
}
TEST(MeshLoader, TruncatedOff) {
  expectLoadError(testData("truncated_faces.off"), {"line 46: face 7 has 3 vertices but lists 2"});
  expectLoadError(testData("truncated_vertices.off"), {"line 23: coordinate z of vertex 20 missing"});
}
TEST(MeshLoader, GzipFileNamedOff) {
  expectLoadError(testData("hostile_gzip.off"), {"not an OFF file: it is gzip-compressed data"});
}
TEST(MeshLoader, HeaderClaimingTwoBillionVertices) {
  expectLoadError(testData("hostile_huge_count.off"), {"header says 2000000000 vertices, but the 30 bytes"});
  expectLoadError(testData("hostile_huge_count.ply"), {"header says 2000000000 vertices, but the 48 bytes"});
}
TEST(MeshLoader, CoordinateBeyondTheDoubleRange) {
  expectLoadError(testData("hostile_coordinate_1e400.off"),
                  {"line 6: coordinate y of vertex 3 is '1e400', not a finite number"});
}
TEST(MeshLoader, LargestFiniteCoordinatesLoadAsWritten) {
  MeshLoadOptions options;
  options.orientOutward = false;
  const TriangleMesh mesh = loadMesh(testData("coordinate_1e308.off"), options);
  ASSERT_EQ(mesh.vertices.size(), 8u);
  EXPECT_EQ(mesh.vertices[3], Vec3(1.0, 1e308, 3.0));
}

// Every format gives exactly the doubles of the file's text (binary STL: its float32 values), for coordinates
// with 17 significant digits, exponents and an offset of 1e5 (precise_expected.txt, written by the fixture
// script from Python's correctly rounded float()).
std::vector<Vec3> expectedPrecise(const std::string& kind) {
  std::ifstream in(testData("precise_expected.txt"));
  std::vector<Vec3> out;
  std::string word, x, y, z;
  while (in >> word) {
    if (word == "#") {
      std::getline(in, word);
      continue;
    }
    in >> x >> y >> z;
    if (word == kind) out.emplace_back(std::strtod(x.c_str(), nullptr), std::strtod(y.c_str(), nullptr),
                                       std::strtod(z.c_str(), nullptr));
  }
  std::sort(out.begin(), out.end(), [](const Vec3& a, const Vec3& b) {
    return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
  });
  return out;
}
TEST(MeshLoader, EveryFormatReadsTheFilesDoublesExactly) {
  const auto doubles = expectedPrecise("double"), floats = expectedPrecise("float");
  ASSERT_EQ(doubles.size(), 8u);
  ASSERT_EQ(floats.size(), 8u);
  for (const char* file : {"precise.off", "precise.obj", "precise_ascii.ply", "precise_binary_le.ply",
                           "precise_binary_be.ply", "precise_ascii.stl", "precise_binary.stl"}) {
    SCOPED_TRACE(file);
    const TriangleMesh mesh = loadMesh(testData(file));
    EXPECT_EQ(mesh.size(), 12u);
    // The box lies near x = 1e5: stored relative to a local origin, which gives the file's numbers back exactly.
    EXPECT_NE(mesh.origin.x(), 0.0);
    std::vector<Vec3> got;
    for (const Vec3& v : mesh.vertices) got.push_back(mesh.toModel(v));
    std::sort(got.begin(), got.end(), [](const Vec3& a, const Vec3& b) {
      return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
    });
    const auto& want = std::string(file) == "precise_binary.stl" ? floats : doubles;
    ASSERT_EQ(got.size(), want.size());
    for (std::size_t i = 0; i < got.size(); ++i)
      for (int k = 0; k < 3; ++k) EXPECT_EQ(got[i][k], want[i][k]) << "vertex " << i << " axis " << k;
    expectClosed(mesh);
  }
}

// Regressions (fuzz/fuzz_mesh_load): a face index beyond the vertex count is a load error, never an
// out-of-bounds read. Run in a child process so a crash fails this test, not the whole binary.
// ascii: heap-buffer-overflow in mesh_loader.cpp collect(); binary, huge indices: SEGV inside
// assimp's post-processing (aiProcess_ValidateDataStructure would reject both before any step reads).
int loadInChild(const std::string& path, const std::string& reason = "") {
  try {
    loadMesh(path);
  } catch (const MeshLoadError& e) {
    if (e.reason().find(reason) == std::string::npos) return 4;
    return std::string(e.what()).find(path) != std::string::npos ? 0 : 2;
  } catch (...) {
    return 3;
  }
  return 1;  // loaded a mesh with a face the file does not define
}
TEST(MeshLoaderDeathTest, FaceIndexOutOfRangeAsciiPly) {
  ::testing::FLAGS_gtest_death_test_style = "threadsafe";
  EXPECT_EXIT(std::exit(loadInChild(testData("bad_index.ply"))), ::testing::ExitedWithCode(0), "");
}
// Regression (fuzz/fuzz_mesh_load): a PLY with a malformed header ("element vxt er3e6", "end_heaedr")
// sent assimp's PLY reader into an endless seek loop. Bounded here by an alarm in the child.
TEST(MeshLoaderDeathTest, MalformedPlyHeaderDoesNotHang) {
  ::testing::FLAGS_gtest_death_test_style = "threadsafe";
  EXPECT_EXIT(
      {
        ::alarm(20);
        std::exit(loadInChild(testData("hang_malformed_header.ply")));
      },
      ::testing::ExitedWithCode(0), "");
}
// A truncated ASCII PLY aborted the process inside assimp (SIGABRT in its triangulation).
TEST(MeshLoaderDeathTest, TruncatedAsciiPly) {
  ::testing::FLAGS_gtest_death_test_style = "threadsafe";
  EXPECT_EXIT(std::exit(loadInChild(testData("hostile_truncated_ascii.ply"), "header says 12 faces, the file ends after 8")),
              ::testing::ExitedWithCode(0), "");
}
TEST(MeshLoaderDeathTest, FaceIndexOutOfRangeBinaryPly) {
  ::testing::FLAGS_gtest_death_test_style = "threadsafe";
  EXPECT_EXIT(std::exit(loadInChild(testData("bad_index_binary.ply"))), ::testing::ExitedWithCode(0), "");
}

TEST(MeshLoader, ErrorsDeriveFromRuntimeError) {
  try {
    loadMesh(testData("does_not_exist.obj"));
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(dynamic_cast<const ClodError*>(&e), nullptr);
  }
}

TEST(MeshLoader, ZeroAreaTriangleKeptWithZeroNormal) {
  const TriangleMesh mesh = loadMesh(testData("cube_with_zero_area.obj"));
  ASSERT_EQ(mesh.size(), 13u) << "the zero-area triangle must be kept";
  EXPECT_EQ(mesh.vertices.size(), 9u);
  std::size_t zero = 0;
  for (std::size_t t = 0; t < mesh.size(); ++t) {
    ASSERT_TRUE(mesh.normals[t].allFinite()) << "triangle " << t;
    if (mesh.normals[t].isZero(0.0))
      ++zero;
    else
      EXPECT_NEAR(mesh.normals[t].norm(), 1.0, 1e-12);
  }
  EXPECT_EQ(zero, 1u);
  EXPECT_TRUE(mesh.normals[12].isZero(0.0));
  // Normalising keeps it zero, not NaN.
  MeshLoadOptions options;
  options.normalize = true;
  const TriangleMesh normalized = loadMesh(testData("cube_with_zero_area.obj"), options);
  EXPECT_TRUE(normalized.normals[12].isZero(0.0));
}

TEST(MeshLoader, FaceNormalOfDegenerateTriangles) {
  const Vec3 a(1, 2, 3);
  EXPECT_TRUE(faceNormal(a, a, a).isZero(0.0));
  EXPECT_TRUE(faceNormal(a, a + Vec3(1, 1, 1), a + Vec3(2, 2, 2)).isZero(0.0));
  EXPECT_TRUE(faceNormal(a, a + Vec3(1e300, 0, 0), a + Vec3(0, 1e300, 0)).allFinite());
  const Vec3 n = faceNormal(Vec3(0, 0, 0), Vec3(1e-200, 0, 0), Vec3(0, 1e-200, 0));
  EXPECT_TRUE(n.allFinite());
}

TEST(MakeMesh, ValidatesInput) {
  std::vector<Vec3> v{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  EXPECT_NO_THROW(makeMesh(v, {{0, 1, 2}}));
  EXPECT_THROW(makeMesh(v, {}), InvalidParameter);
  EXPECT_THROW(makeMesh(v, {{0, 1, 3}}), InvalidParameter);
  auto bad = v;
  bad[1].y() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(makeMesh(bad, {{0, 1, 2}}), InvalidParameter);
  bad[1].y() = -std::numeric_limits<double>::infinity();
  EXPECT_THROW(makeMesh(bad, {{0, 1, 2}}), InvalidParameter);
}

TEST(MeshLoader, NormalizeOfZeroExtentMeshThrows) {
  TriangleMesh m = makeMesh({Vec3(1, 1, 1), Vec3(1, 1, 1), Vec3(1, 1, 1)}, {{0, 1, 2}});
  MeshLoadOptions options;
  options.normalize = true;
  EXPECT_THROW(transformMesh(m, options), InvalidParameter);
}

TEST(MeshLoader, SharedMeshesLoadClosedCounts) {
  // The shared meshes load with finite coordinates and unit or zero normals.
  const auto meshes = clod_test::sharedMeshes();
  ASSERT_FALSE(meshes.empty());
  for (const auto& path : meshes) {
    SCOPED_TRACE(path);
    const auto mesh = clod_test::loadNormalized(path);
    EXPECT_GT(mesh->size(), 0u);
    for (const Vec3& n : mesh->normals) {
      ASSERT_TRUE(n.allFinite());
      EXPECT_TRUE(n.isZero(0.0) || std::abs(n.norm() - 1.0) < 1e-12);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Polygons of 5 or more corners (OFF, OBJ, PLY) are ear clipped in their plane. Each polygon is given in 2D
// (u, v) and placed at origin + u e1 + v e2; the reference is computed from the 2D corners alone: the area by
// the shoelace formula, inside by a crossing-number test, the orientation by the shoelace's sign along e1 x e2.

struct PlanarPolygon {
  std::string name;
  std::vector<std::array<double, 2>> uv;
  Vec3 origin = Vec3::Zero(), e1 = Vec3::UnitX(), e2 = Vec3::UnitY();

  Vec3 corner(std::size_t i) const { return origin + uv[i][0] * e1 + uv[i][1] * e2; }
  std::array<double, 2> toPlane(const Vec3& p) const { return {(p - origin).dot(e1), (p - origin).dot(e2)}; }
  /** \brief Twice the signed area (positive: counter-clockwise about e1 x e2). */
  double shoelace() const {
    double twice = 0.0;
    for (std::size_t i = 0; i < uv.size(); ++i) {
      const auto &a = uv[i], &b = uv[(i + 1) % uv.size()];
      twice += a[0] * b[1] - b[0] * a[1];
    }
    return twice;
  }
  bool contains(const std::array<double, 2>& q) const {  // crossing number
    bool inside = false;
    for (std::size_t i = 0, j = uv.size() - 1; i < uv.size(); j = i++) {
      const auto &a = uv[i], &b = uv[j];
      if ((a[1] > q[1]) != (b[1] > q[1]) && q[0] < a[0] + (q[1] - a[1]) * (b[0] - a[0]) / (b[1] - a[1]))
        inside = !inside;
    }
    return inside;
  }
  PlanarPolygon reversed() const {
    PlanarPolygon r = *this;
    r.name += " reversed";
    std::reverse(r.uv.begin() + 1, r.uv.end());  // corner 0 stays corner 0
    return r;
  }
  PlanarPolygon inPlane(const std::string& label, const Vec3& normal, const Vec3& at) const {
    PlanarPolygon r = *this;
    r.name += " " + label;
    const Vec3 n = normal.normalized();
    r.e1 = n.unitOrthogonal();
    r.e2 = n.cross(r.e1);
    r.origin = at;
    return r;
  }
};

// An L whose corner 0 (2, 1) is next to the reflex corner (1, 1): the fan's first triangle lies outside.
PlanarPolygon lShape() { return {"L hexagon", {{2, 1}, {1, 1}, {1, 2}, {0, 2}, {0, 0}, {2, 0}}}; }
// The same L from the corner that sees every other one (a fan would do here).
PlanarPolygon lShapeFromCorner() { return {"L hexagon from (0,0)", {{0, 0}, {2, 0}, {2, 1}, {1, 1}, {1, 2}, {0, 2}}}; }
// An arrow pointing along +u; corner 1 (2, 1), where the shaft meets the head, is reflex.
PlanarPolygon arrow() { return {"arrow", {{0, 1}, {2, 1}, {2, 0}, {4, 2}, {2, 4}, {2, 3}, {0, 3}}}; }
// A star with `points` tips (corner 0 a tip, corners 1 and 2 points - 1 reflex), uneven radii.
PlanarPolygon star(int points, const std::string& name) {
  PlanarPolygon p{name, {}};
  for (int i = 0; i < 2 * points; ++i) {
    const double a = M_PI * i / points, r = i % 2 == 0 ? 2.0 + 0.3 * std::sin(3.0 * i) : 0.8;
    p.uv.push_back({r * std::cos(a), r * std::sin(a)});
  }
  return p;
}
// A convex heptagon with uneven sides.
PlanarPolygon heptagon() {
  PlanarPolygon p{"convex heptagon", {}};
  for (double a : {0.0, 0.7, 1.9, 2.6, 3.5, 4.4, 5.5}) p.uv.push_back({3.0 * std::cos(a), 2.0 * std::sin(a)});
  return p;
}

// A comb: a bar along the bottom and `teeth` teeth pointing up, every gap's two bottom corners reflex.
PlanarPolygon comb(int teeth) {
  PlanarPolygon p{"comb", {{0, 0}, {2.0 * teeth - 1.0, 0}}};
  for (int t = teeth - 1; t >= 0; --t) {  // tooth t spans u in [2t, 2t + 1]
    p.uv.push_back({2.0 * t + 1.0, 3.0});
    p.uv.push_back({2.0 * t, 3.0});
    if (t == 0) break;
    p.uv.push_back({2.0 * t, 1.0});
    p.uv.push_back({2.0 * t - 1.0, 1.0});
  }
  return p;
}
// A strip along two turns of a spiral: not star-shaped, no corner sees the whole polygon.
PlanarPolygon spiral() {
  PlanarPolygon p{"spiral strip", {}};
  const int steps = 48;
  for (int i = 0; i <= steps; ++i) {
    const double a = 4.0 * M_PI * i / steps, r = 1.0 + 0.5 * a;
    p.uv.push_back({r * std::cos(a), r * std::sin(a)});
  }
  for (int i = steps; i >= 0; --i) {
    const double a = 4.0 * M_PI * i / steps, r = 1.0 + 0.5 * a + 1.2;
    p.uv.push_back({r * std::cos(a), r * std::sin(a)});
  }
  return p;
}
// A star-shaped polygon of 200 corners at pseudo-random radii (std::mt19937's output is fixed by the standard).
PlanarPolygon randomRadii() {
  PlanarPolygon p{"200 random radii", {}};
  std::mt19937 random(7);
  for (int i = 0; i < 200; ++i) {
    const double a = 2.0 * M_PI * i / 200, r = 0.2 + random() / 4294967296.0;
    p.uv.push_back({r * std::cos(a), r * std::sin(a)});
  }
  return p;
}

std::vector<PlanarPolygon> nonConvexPolygons() {
  std::vector<PlanarPolygon> base = {lShape(), lShapeFromCorner(), arrow(), star(5, "5-point star"), heptagon()};
  base.push_back(star(512, "1024-corner star (the largest ear clipped)"));
  for (const PlanarPolygon& p : {comb(8), spiral(), randomRadii()}) base.push_back(p);
  // Tilted planes, far from every axis plane (each of the three dominant axes) and away from the origin.
  base.push_back(star(5, "5-point star").inPlane("in plane n = (1, 2, 3)", Vec3(1, 2, 3), Vec3(3.5, -7.25, 12.0)));
  base.push_back(arrow().inPlane("in plane n = (-3, 1, 2)", Vec3(-3, 1, 2), Vec3(-40.0, 2.0, 0.5)));
  base.push_back(lShape().inPlane("in plane n = (1, -2, 1.5)", Vec3(1, -2, 1.5), Vec3(1e3, 1e3, -1e3)));
  base.push_back(spiral().inPlane("in plane n = (2, 1, -1)", Vec3(2, 1, -1), Vec3(0.25, -3.0, 8.0)));
  std::vector<PlanarPolygon> all;
  for (const auto& p : base) {
    all.push_back(p);
    all.push_back(p.reversed());
  }
  return all;
}

// Writes one polygon face as OFF, OBJ or ASCII PLY.
void writePolygon(const std::string& path, const std::vector<Vec3>& corners) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  ASSERT_NE(f, nullptr) << path;
  const std::string ext = std::filesystem::path(path).extension().string();
  const std::size_t n = corners.size();
  if (ext == ".off") std::fprintf(f, "OFF\n%zu 1 0\n", n);
  if (ext == ".ply")
    std::fprintf(f,
                 "ply\nformat ascii 1.0\nelement vertex %zu\nproperty double x\nproperty double y\n"
                 "property double z\nelement face 1\nproperty list uint int vertex_indices\nend_header\n",
                 n);
  for (const Vec3& p : corners)
    std::fprintf(f, "%s%.17g %.17g %.17g\n", ext == ".obj" ? "v " : "", p.x(), p.y(), p.z());
  std::fprintf(f, ext == ".obj" ? "f" : "%zu", n);
  for (std::size_t i = 0; i < n; ++i) std::fprintf(f, " %zu", ext == ".obj" ? i + 1 : i);
  std::fprintf(f, "\n");
  std::fclose(f);
}

class PolygonFiles : public clod_test::TempDirTest {
 protected:
  std::string write(const std::string& name, const std::vector<Vec3>& corners) {
    const std::string path = (dir_ / name).string();
    writePolygon(path, corners);
    return path;
  }
  static TriangleMesh load(const std::string& path) {
    MeshLoadOptions options;
    options.orientOutward = false;  // one open polygon: keep the file's winding
    return loadMesh(path, options);
  }
};

// n - 2 triangles that tile the polygon: their areas add up to its area, each centroid lies inside it and each
// normal points along the polygon's own (e1 x e2 times the shoelace's sign).
void expectTiles(const TriangleMesh& mesh, const PlanarPolygon& poly) {
  const std::size_t n = poly.uv.size();
  ASSERT_EQ(mesh.size(), n - 2);
  const double twice = poly.shoelace();
  const Vec3 up = (twice > 0.0 ? 1.0 : -1.0) * poly.e1.cross(poly.e2);
  double area = 0.0;
  int outside = 0, wrongWay = 0;
  for (std::size_t t = 0; t < mesh.size(); ++t) {
    const Vec3 a = mesh.toModel(mesh.vertex(t, 0)), b = mesh.toModel(mesh.vertex(t, 1)),
               c = mesh.toModel(mesh.vertex(t, 2));
    const Vec3 normal = (b - a).cross(c - a);
    area += 0.5 * normal.norm();
    if (normal.dot(up) <= 0.0 && ++wrongWay <= 3) ADD_FAILURE() << "triangle " << t << " wound against the polygon";
    if (!poly.contains(poly.toPlane((a + b + c) / 3.0)) && ++outside <= 3)
      ADD_FAILURE() << "triangle " << t << " has its centroid outside the polygon";
  }
  EXPECT_EQ(wrongWay, 0);
  EXPECT_EQ(outside, 0);
  EXPECT_NEAR(area, 0.5 * std::abs(twice), 1e-12 * std::abs(twice)) << "the triangles' areas add up to the polygon's";
}

TEST_F(PolygonFiles, NonConvexPolygonsAreEarClippedInsideTheirOutline) {
  for (const PlanarPolygon& poly : nonConvexPolygons())
    for (const char* ext : {".obj", ".off", ".ply"}) {
      SCOPED_TRACE(poly.name + " " + ext);
      std::vector<Vec3> corners;
      for (std::size_t i = 0; i < poly.uv.size(); ++i) corners.push_back(poly.corner(i));
      const std::string path = write("polygon" + std::string(ext), corners);
      expectTiles(load(path), poly);
    }
}

// Hostile input terminates and gives n - 2 triangles: corners on one line (zero Newell normal), a figure eight
// (its two loops' areas cancel), all corners at one point, a polygon crossing itself many times.
TEST_F(PolygonFiles, DegeneratePolygonsLoadWithoutCrash) {
  std::vector<std::pair<std::string, std::vector<Vec3>>> cases;
  std::vector<Vec3> line, eight, point, tangle;
  for (int i = 0; i < 7; ++i) line.push_back(Vec3(1, 2, 3) + i * Vec3(0.5, -1.0, 2.0));
  for (int i = 0; i < 8; ++i) eight.push_back(Vec3(std::sin(2 * M_PI * i / 8), std::sin(4 * M_PI * i / 8), 1.0));
  for (int i = 0; i < 6; ++i) point.push_back(Vec3(4, 5, 6));
  for (int i = 0; i < 40; ++i) tangle.push_back(Vec3(std::cos(2.9 * i), std::sin(2.9 * i), 0.01 * (i % 3)));
  cases = {{"collinear", line}, {"figure eight", eight}, {"one point", point}, {"self-crossing", tangle}};
  for (const auto& c : cases)
    for (const char* ext : {".obj", ".off"}) {
      SCOPED_TRACE(c.first + ext);
      const std::string path = write("degenerate" + std::string(ext), c.second);
      TriangleMesh mesh;
      ASSERT_NO_THROW(mesh = load(path));
      EXPECT_EQ(mesh.size(), c.second.size() - 2);
      for (const Triangle& t : mesh.triangles)
        for (std::uint32_t v : t) ASSERT_LT(v, mesh.vertices.size());
      for (const Vec3& n : mesh.normals) EXPECT_TRUE(n.allFinite());
    }
}

// Above 1024 corners a polygon is fanned from corner 0 (ear clipping costs O(n^2) there): a 5000-corner star
// loads in a child bounded by an alarm, as 4998 triangles that all share corner 0 (a fan, not ear clipping).
int loadFannedInChild(const std::string& path, const Vec3& corner0, std::size_t n) {
  ::alarm(60);
  MeshLoadOptions options;
  options.orientOutward = false;
  TriangleMesh mesh;
  try {
    mesh = loadMesh(path, options);
  } catch (...) {
    return 3;
  }
  if (mesh.size() != n - 2) return 1;
  for (std::size_t t = 0; t < mesh.size(); ++t) {
    bool shares = false;
    for (int k = 0; k < 3; ++k) shares = shares || mesh.toModel(mesh.vertex(t, k)) == corner0;
    if (!shares) return 2;
  }
  return 0;
}
TEST_F(PolygonFiles, HugePolygonIsFannedWithoutHanging) {
  ::testing::FLAGS_gtest_death_test_style = "threadsafe";
  const PlanarPolygon poly = star(2500, "5000-corner star");
  std::vector<Vec3> corners;
  for (std::size_t i = 0; i < poly.uv.size(); ++i) corners.push_back(poly.corner(i));
  for (const char* ext : {".obj", ".off"}) {
    const std::string path = write("huge" + std::string(ext), corners);
    EXPECT_EXIT(
        {
          const int code = loadFannedInChild(path, corners[0], corners.size());
          std::filesystem::remove_all(dir_);  // the child's own directory: it exits before TearDown
          std::exit(code);
        },
        ::testing::ExitedWithCode(0), "")
        << ext;
  }
}

}  // namespace
