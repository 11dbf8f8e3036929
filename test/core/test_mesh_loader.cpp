// Mesh loading: every fixture format (scripts/make_test_fixtures.py), vertex joining, scale and
// normalisation, and each bad input giving its typed error with the path in the message.

#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <map>
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

}  // namespace
