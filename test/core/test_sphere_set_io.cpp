// Sphere set YAML: an exact write/read round trip, and corrupt files giving FormatError.

#include <gtest/gtest.h>

#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/sphere_set.h"
#include "clod_haptics/core/sphere_set_io.h"
#include "test_helpers.h"

namespace {

using namespace clod_haptics;

class SphereSetIo : public clod_test::TempDirTest {
 protected:
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  std::string write(const std::string& name, const std::string& text) const {
    std::ofstream(path(name)) << text;
    return path(name);
  }
};

void expectEqualSets(const ClodSphereSet& a, const ClodSphereSet& b) {
  EXPECT_EQ(a.meshName, b.meshName);
  EXPECT_EQ(a.scale, b.scale);
  EXPECT_EQ(a.distance, b.distance);
  EXPECT_EQ(a.origin, b.origin);
  EXPECT_EQ(a.centres, b.centres) << "17 significant digits give the same doubles back";
  EXPECT_EQ(a.radii, b.radii);
  EXPECT_EQ(a.offsets, b.offsets);
  EXPECT_EQ(a.triangles, b.triangles);
  EXPECT_EQ(a.size(), b.stats.spheres);
}

TEST_F(SphereSetIo, RoundTripIsExact) {
  for (const char* name : {"elephant.off", "mesh_with_border.off"}) {
    const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh(name));
    const ClodBuilder builder(mesh);
    for (double d : {0.0, 0.02, 0.08}) {
      const ClodSphereSet set = builder.build(d);
      const std::string file = path(std::string(name) + ".yaml");
      writeSphereSetYaml(set, file);
      const ClodSphereSet back = readSphereSetYaml(file);
      SCOPED_TRACE(std::string(name) + " d=" + std::to_string(d));
      expectEqualSets(set, back);
      EXPECT_TRUE(clod_test::coverageProblems(*mesh, back).empty());
    }
  }
}

// A mesh far from zero: the set's centres are relative to the mesh's local origin, which the file keeps, and
// the set read back fits the mesh (fitProblem checks the origin too).
TEST_F(SphereSetIo, FarMeshKeepsItsLocalOrigin) {
  MeshLoadOptions options;
  const TriangleMesh unit = loadMesh(clod_test::testData("cube.obj"));
  std::vector<Vec3> far;
  for (const Vec3& v : unit.vertices) far.push_back(unit.toModel(v) + Vec3(1e6, -3e5, 0.0));
  const auto mesh = std::make_shared<const TriangleMesh>(makeMesh(far, unit.triangles, "far cube"));
  ASSERT_NE(mesh->origin.x(), 0.0);
  const ClodSphereSet set = ClodBuilder(mesh).build(0.1);
  EXPECT_EQ(set.origin, mesh->origin);
  const std::string file = path("far.yaml");
  writeSphereSetYaml(set, file);
  const ClodSphereSet back = readSphereSetYaml(file);
  expectEqualSets(set, back);
  EXPECT_EQ(fitProblem(*mesh, back), "");
  ClodSphereSet moved = back;
  moved.origin.x() += 1.0;
  EXPECT_NE(fitProblem(*mesh, moved).find("local origin"), std::string::npos);
}

TEST_F(SphereSetIo, VersionOneFileReadsWithAZeroOrigin) {
  const auto mesh = clod_test::loadNormalized(clod_test::testData("cube.obj"));
  const ClodSphereSet set = ClodBuilder(mesh).build(0.0);
  std::ostringstream text;
  writeSphereSetYaml(set, text);
  std::string v1 = text.str();
  v1.replace(v1.find("sphere_set/2"), 12, "sphere_set/1");
  v1.erase(v1.find("origin: "), v1.find('\n', v1.find("origin: ")) - v1.find("origin: ") + 1);
  const ClodSphereSet back = readSphereSetYaml(write("v1.yaml", v1));
  expectEqualSets(set, back);
  EXPECT_EQ(back.origin, Vec3::Zero());
}

TEST_F(SphereSetIo, StreamAndFileWritersAgree) {
  const auto mesh = clod_test::loadNormalized(clod_test::testData("cube.obj"));
  const ClodSphereSet set = ClodBuilder(mesh).build(0.1);
  std::ostringstream text;
  writeSphereSetYaml(set, text);
  writeSphereSetYaml(set, path("a.yaml"));
  std::ifstream in(path("a.yaml"));
  std::stringstream file;
  file << in.rdbuf();
  EXPECT_EQ(text.str(), file.str());
  EXPECT_NE(text.str().find("mesh: \"cube.obj\""), std::string::npos);
}

TEST_F(SphereSetIo, UnwritablePathIsFormatError) {
  const auto mesh = clod_test::loadNormalized(clod_test::testData("cube.obj"));
  const ClodSphereSet set = ClodBuilder(mesh).build(0.1);
  EXPECT_THROW(writeSphereSetYaml(set, path("no/such/dir/x.yaml")), FormatError);
}

// A valid file to corrupt line by line.
std::string validText() {
  const auto mesh = clod_test::loadNormalized(clod_test::testData("cube.obj"));
  std::ostringstream text;
  writeSphereSetYaml(ClodBuilder(mesh).build(0.0), text);
  return text.str();
}

std::string replaceLine(const std::string& text, const std::string& prefix, const std::string& replacement) {
  std::istringstream in(text);
  std::ostringstream out;
  std::string line;
  bool done = false;
  while (std::getline(in, line)) {
    if (!done && line.compare(0, prefix.size(), prefix) == 0) {
      out << replacement << "\n";
      done = true;
    } else {
      out << line << "\n";
    }
  }
  EXPECT_TRUE(done) << "no line starts with " << prefix;
  return out.str();
}

TEST_F(SphereSetIo, ValidTextReads) { EXPECT_NO_THROW(readSphereSetYaml(write("ok.yaml", validText()))); }

TEST_F(SphereSetIo, MissingFileIsFormatError) { EXPECT_THROW(readSphereSetYaml(path("absent.yaml")), FormatError); }

TEST_F(SphereSetIo, EmptyFileIsFormatError) { EXPECT_THROW(readSphereSetYaml(write("e.yaml", "")), FormatError); }

TEST_F(SphereSetIo, WrongFormatLineIsFormatError) {
  EXPECT_THROW(readSphereSetYaml(write("f.yaml", replaceLine(validText(), "format:", "format: something/else/2"))),
               FormatError);
}

TEST_F(SphereSetIo, TruncatedHeaderIsFormatError) {
  const std::string text = validText();
  const std::string head = text.substr(0, text.find("clustering_distance"));
  EXPECT_THROW(readSphereSetYaml(write("t.yaml", head)), FormatError);
}

TEST_F(SphereSetIo, NonNumericScaleIsFormatError) {
  EXPECT_THROW(readSphereSetYaml(write("s.yaml", replaceLine(validText(), "scale:", "scale: big"))), FormatError);
}

TEST_F(SphereSetIo, MalformedSphereLineIsFormatError) {
  EXPECT_THROW(readSphereSetYaml(write("m.yaml", replaceLine(validText(), "  - {", "  - {centre: [1, 2], radius: 3}"))),
               FormatError);
  EXPECT_THROW(readSphereSetYaml(write("g.yaml", validText() + "garbage\n")), FormatError);
}

TEST_F(SphereSetIo, NonNumericTriangleIndexIsFormatError) {
  EXPECT_THROW(readSphereSetYaml(write("n.yaml", replaceLine(validText(), "  - {",
                                                             "  - {centre: [0.5, 0.5, 0.5], radius: 1, triangles: [1, x]}"))),
               FormatError);
}

// A sphere file is read back into a detector; values no build can produce must be refused, not
// turned into out-of-range indices or NaN geometry.
TEST_F(SphereSetIo, NegativeOrFractionalTriangleIndexIsFormatError) {
  EXPECT_THROW(readSphereSetYaml(write("neg.yaml", replaceLine(validText(), "  - {",
                                                               "  - {centre: [0.5, 0.5, 0.5], radius: 1, triangles: [-1]}"))),
               FormatError);
  EXPECT_THROW(readSphereSetYaml(write("frac.yaml", replaceLine(validText(), "  - {",
                                                                "  - {centre: [0.5, 0.5, 0.5], radius: 1, triangles: [1.5]}"))),
               FormatError);
}

TEST_F(SphereSetIo, NonFiniteOrNegativeRadiusIsFormatError) {
  EXPECT_THROW(readSphereSetYaml(write("nan.yaml", replaceLine(validText(), "  - {",
                                                               "  - {centre: [0.5, nan, 0.5], radius: 1, triangles: [0]}"))),
               FormatError);
  EXPECT_THROW(readSphereSetYaml(write("r.yaml", replaceLine(validText(), "  - {",
                                                             "  - {centre: [0.5, 0.5, 0.5], radius: -1, triangles: [0]}"))),
               FormatError);
}

}  // namespace
