// clod_tool, the command-line program: build, query (its RESULT.csv against bruteForceQuery),
// sweep --json, and every bad input giving one line on stderr and the exit code of its kind (1 input,
// 2 usage, 3 output): numbers outside their bounds, probe files that cannot be read or are malformed,
// outputs that cannot be written (which leave the previous file and no temporary behind).

#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/probes.h"
#include "clod_haptics/core/sphere_set.h"
#include "clod_haptics/core/sphere_set_io.h"
#include "test_helpers.h"

namespace {

using namespace clod_haptics;

struct ToolRun {
  int code = -1;
  std::string out, err;
};

std::string readAll(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

class ClodTool : public clod_test::TempDirTest {
 protected:
  void SetUp() override {
    TempDirTest::SetUp();
    ASSERT_TRUE(std::filesystem::exists(CLOD_TOOL_PATH)) << CLOD_TOOL_PATH;
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  // Runs the tool through the shell; shell goes before the command (ulimit, trap), stdoutTo is where its
  // standard output goes (stdout.txt in the test's directory by default).
  ToolRun run(const std::vector<std::string>& args, const std::string& shell = "",
              const std::string& stdoutTo = "") const {
    std::string cmd = shell + quote(CLOD_TOOL_PATH);
    for (const auto& a : args) cmd += " " + quote(a);
    cmd += " >" + quote(stdoutTo.empty() ? path("stdout.txt") : stdoutTo) + " 2>" + quote(path("stderr.txt")) +
           " </dev/null";
    ToolRun r;
    const int status = std::system(cmd.c_str());
    r.code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
    r.out = readAll(path("stdout.txt"));
    r.err = readAll(path("stderr.txt"));
    return r;
  }

  // A usage or input error: non-zero exit, exactly one non-empty line on stderr.
  void expectOneLineError(const std::vector<std::string>& args, const std::string& mentions = "") const {
    const ToolRun r = run(args);
    std::string joined;
    for (const auto& a : args) joined += a + " ";
    EXPECT_NE(r.code, 0) << joined;
    EXPECT_LT(r.code, 128) << "crashed: " << joined;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << joined << "\nstderr: " << r.err;
    EXPECT_GT(r.err.size(), 10u) << joined;
    if (!mentions.empty()) {
      EXPECT_NE(r.err.find(mentions), std::string::npos) << joined << "\nstderr: " << r.err;
    }
  }

  // An error with exit code: exactly one line on stderr, mentioning each of mentions.
  void expectExit(int code, const std::vector<std::string>& args, const std::vector<std::string>& mentions,
                  const std::string& shell = "") const {
    const ToolRun r = run(args, shell);
    std::string joined;
    for (const auto& a : args) joined += a + " ";
    EXPECT_EQ(r.code, code) << joined << "\nstderr: " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << joined << "\nstderr: " << r.err;
    for (const auto& m : mentions) EXPECT_NE(r.err.find(m), std::string::npos) << joined << "\nstderr: " << r.err;
  }

  // The files in the test's directory other than the tool's stdout.txt and stderr.txt.
  std::vector<std::string> filesLeft() const {
    std::vector<std::string> names;
    for (const auto& e : std::filesystem::directory_iterator(dir_)) {
      const std::string name = e.path().filename().string();
      if (name != "stdout.txt" && name != "stderr.txt") names.push_back(name);
    }
    std::sort(names.begin(), names.end());
    return names;
  }

  void writeFile(const std::string& name, const std::string& text) const {
    std::ofstream out(path(name), std::ios::binary);
    out << text;
  }
};

// The integer value of "key": N in a one-line JSON object.
long jsonInt(const std::string& json, const std::string& key) {
  std::smatch m;
  if (!std::regex_search(json, m, std::regex("\"" + key + "\":(-?[0-9]+)"))) return -1;
  return std::stol(m[1]);
}
double jsonNumber(const std::string& json, const std::string& key) {
  std::smatch m;
  if (!std::regex_search(json, m, std::regex("\"" + key + "\":(-?[0-9.eE+-]+)"))) return std::nan("");
  return std::stod(m[1]);
}

TEST_F(ClodTool, BuildWritesTheSameSetAsTheLibrary) {
  const std::string mesh = clod_test::sharedMesh("elephant.off");
  const ToolRun r = run({"build", "--mesh", mesh, "--normalize", "--distance", "0.02", "--out", path("s.yaml")});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto m = clod_test::loadNormalized(mesh);
  const ClodBuilder builder(m);
  const ClodSphereSet expected = builder.build(0.02);
  EXPECT_NE(r.out.find("before clustering: " + std::to_string(builder.placed().size())), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(": " + std::to_string(expected.size())), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("build time"), std::string::npos) << r.out;
  const ClodSphereSet written = readSphereSetYaml(path("s.yaml"));
  EXPECT_EQ(written.size(), expected.size());
  EXPECT_EQ(written.triangles, expected.triangles);
  EXPECT_EQ(written.distance, 0.02);
  EXPECT_TRUE(clod_test::coverageProblems(*m, written).empty());
}

TEST_F(ClodTool, BuildJsonIsOneObjectWithCounts) {
  const std::string mesh = clod_test::sharedMesh("head.off");
  const ToolRun r = run({"build", "--mesh", mesh, "--normalize", "--distance", "0.05", "--out", path("s.yaml"), "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
  EXPECT_EQ(r.out.front(), '{');
  const auto m = clod_test::loadNormalized(mesh);
  const ClodBuilder builder(m);
  EXPECT_EQ(jsonInt(r.out, "spheres"), static_cast<long>(builder.build(0.05).size())) << r.out;
  EXPECT_EQ(jsonInt(r.out, "centres"), static_cast<long>(builder.placed().size())) << r.out;
  EXPECT_EQ(jsonInt(r.out, "triangles"), static_cast<long>(m->size()));
  EXPECT_GE(jsonNumber(r.out, "build_ms"), 0.0) << r.out;
}

TEST_F(ClodTool, BuildCountFindsTheLevelWithAtMostThatManySpheres) {
  const std::string mesh = clod_test::sharedMesh("head.off");
  const ToolRun r = run({"build", "--mesh", mesh, "--normalize", "--count", "100", "--out", path("s.yaml"), "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto m = clod_test::loadNormalized(mesh);
  const ClodBuilder builder(m);
  const double d = jsonNumber(r.out, "distance");
  EXPECT_LE(jsonInt(r.out, "spheres"), 100) << r.out;
  EXPECT_EQ(jsonInt(r.out, "spheres"), static_cast<long>(builder.build(d).size())) << r.out;
  // Least: a slightly smaller distance gives more than 100 spheres.
  EXPECT_GT(builder.build(d - 1e-5).size(), 100u) << r.out;
  const ClodSphereSet written = readSphereSetYaml(path("s.yaml"));
  EXPECT_EQ(written.size(), static_cast<std::size_t>(jsonInt(r.out, "spheres")));
  EXPECT_TRUE(clod_test::coverageProblems(*m, written).empty());
  const ToolRun both = run({"build", "--mesh", mesh, "--normalize", "--count", "100", "--distance", "0.02", "--out",
                            path("t.yaml")});
  EXPECT_NE(both.code, 0);
  EXPECT_NE(both.err.find("one of --distance and --count"), std::string::npos) << both.err;
  const ToolRun zero = run({"build", "--mesh", mesh, "--normalize", "--count", "0", "--out", path("t.yaml")});
  EXPECT_NE(zero.code, 0);
}

TEST_F(ClodTool, BuildWithScale) {
  const ToolRun r = run({"build", "--mesh", clod_test::testData("cube.obj"), "--scale", "3", "--distance", "0", "--out",
                     path("s.yaml")});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(readSphereSetYaml(path("s.yaml")).scale, 3.0);
}

// Writes probes (with a header line) and compares the tool's RESULT.csv with brute force.
void compareQueryOutput(const ClodTool& t, const ToolRun& r, const TriangleMesh& mesh, const std::vector<Vec3>& probes,
                        double radius, bool exact, const std::string& resultPath) {
  ASSERT_EQ(r.code, 0) << r.err;
  std::ifstream in(resultPath);
  std::string line;
  ASSERT_TRUE(std::getline(in, line));
  EXPECT_EQ(line, "index,contact,distance,px,py,pz,triangle");
  std::size_t rows = 0, contacts = 0;
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) f.push_back(cell);
    while (f.size() < 7) f.push_back("");
    ASSERT_EQ(f.size(), 7u) << line;
    ASSERT_EQ(std::stoul(f[0]), rows) << line;
    const ContactResult ref = bruteForceQuery(mesh, probes[rows], radius);
    const bool contact = f[1] == "1";
    ASSERT_TRUE(f[1] == "0" || f[1] == "1") << line;
    if (exact) {
      ASSERT_EQ(contact, ref.contact) << "row " << rows << ": " << line;
    } else {
      ASSERT_TRUE(!contact || ref.contact) << "paper contact that brute force denies, row " << rows;
    }
    if (contact) {
      ++contacts;
      const double d = std::stod(f[2]);
      const Vec3 q(std::stod(f[3]), std::stod(f[4]), std::stod(f[5]));
      if (exact) {
        EXPECT_NEAR(d, ref.distance, 1e-9 * std::max(ref.distance, radius)) << "row " << rows;
      }
      EXPECT_NEAR((probes[rows] - q).norm(), d, 1e-9 * radius) << "row " << rows;
      const int tri = std::stoi(f[6]);
      ASSERT_GE(tri, 0);
      ASSERT_LT(static_cast<std::size_t>(tri), mesh.size());
    } else {
      for (int k = 2; k < 7; ++k) EXPECT_TRUE(f[k].empty()) << "row " << rows << ": " << line;
    }
    ++rows;
  }
  EXPECT_EQ(rows, probes.size());
  EXPECT_GT(contacts, probes.size() / 20);
  (void)t;
}

TEST_F(ClodTool, QueryResultMatchesBruteForce) {
  const std::string meshPath = clod_test::sharedMesh("mannequin-devil.off");
  const auto mesh = clod_test::loadNormalized(meshPath);
  std::vector<Vec3> probes = nearSurfaceProbes(*mesh, 3000, 0.01, 8);
  const auto uniform = uniformProbes(*mesh, 1000, 0.01, 9);
  probes.insert(probes.end(), uniform.begin(), uniform.end());
  {
    std::ofstream csv(path("p.csv"));
    csv << "x,y,z\n";
    csv.precision(17);
    for (const Vec3& p : probes) csv << p.x() << "," << p.y() << "," << p.z() << "\n";
  }
  for (const char* mode : {"exact", "paper"}) {
    SCOPED_TRACE(mode);
    const ToolRun r = run({"query", "--mesh", meshPath, "--normalize", "--distance", "0.02", "--radius", "0.005", "--mode",
                       mode, "--probes", path("p.csv"), "--out", path("r.csv"), "--json"});
    compareQueryOutput(*this, r, *mesh, probes, 0.005, std::string(mode) == "exact", path("r.csv"));
    EXPECT_EQ(jsonInt(r.out, "probes"), static_cast<long>(probes.size())) << r.out;
    EXPECT_GT(jsonNumber(r.out, "ns_per_query_mean"), 0.0) << r.out;
    EXPECT_GE(jsonNumber(r.out, "ns_per_query_median"), 0.0) << r.out;
  }
  // Without --json: a human summary with the mean time per query.
  const ToolRun r = run({"query", "--mesh", meshPath, "--normalize", "--distance", "0.02", "--radius", "0.005", "--probes",
                     path("p.csv"), "--out", path("r.csv")});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("mean time per query"), std::string::npos) << r.out;
}

TEST_F(ClodTool, QueryWithoutHeaderAndWithScale) {
  const auto mesh = std::make_shared<TriangleMesh>(loadMesh(clod_test::testData("cube.obj"), {2.0, false}));
  std::vector<Vec3> probes = nearSurfaceProbes(*mesh, 500, 0.3, 1);
  {
    std::ofstream csv(path("p.csv"));
    csv.precision(17);
    for (const Vec3& p : probes) csv << p.x() << ", " << p.y() << ", " << p.z() << "\r\n";
  }
  const ToolRun r = run({"query", "--mesh", clod_test::testData("cube.obj"), "--scale", "2", "--distance", "0.5",
                     "--radius", "0.2", "--mode", "exact", "--probes", path("p.csv"), "--out", path("r.csv")});
  compareQueryOutput(*this, r, *mesh, probes, 0.2, true, path("r.csv"));
}

TEST_F(ClodTool, SweepJsonHasOneRowPerDistance) {
  const ToolRun r = run({"sweep", "--mesh", clod_test::sharedMesh("head.off"), "--normalize", "--distances",
                     "0,0.01,0.02,0.04,0.08", "--count", "2000", "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
  std::regex row("\\{\"distance\":[^}]*\\}");
  std::vector<long> centres;
  for (auto it = std::sregex_iterator(r.out.begin(), r.out.end(), row); it != std::sregex_iterator(); ++it)
    centres.push_back(jsonInt(it->str(), "centres"));
  ASSERT_EQ(centres.size(), 5u) << r.out;
  const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh("head.off"));
  const ClodBuilder builder(mesh);
  const double ds[] = {0, 0.01, 0.02, 0.04, 0.08};
  for (std::size_t k = 0; k < centres.size(); ++k) {
    EXPECT_EQ(centres[k], static_cast<long>(builder.build(ds[k]).size())) << "d=" << ds[k];
    if (k) {
      EXPECT_LE(centres[k], centres[k - 1]);
    }
  }
  for (const char* key : {"step_reduction", "total_reduction", "fast_us", "precise_us", "total_us", "rate_hz"})
    EXPECT_NE(r.out.find(std::string("\"") + key + "\""), std::string::npos) << key;
}

TEST_F(ClodTool, SweepTablePrintsHeader) {
  const ToolRun r = run({"sweep", "--mesh", clod_test::testData("cube.obj"), "--normalize", "--distances", "0,0.5",
                     "--count", "100"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("centres"), std::string::npos);
  EXPECT_NE(r.out.find("rate_Hz"), std::string::npos);
}

TEST_F(ClodTool, ErrorsAreOneLineAndNonZero) {
  const std::string mesh = clod_test::testData("cube.obj");
  const std::string out = path("o.yaml");
  {
    std::ofstream csv(path("p.csv"));
    csv << "x,y,z\n0.5,0.5,0.5\n";
  }
  const std::string probes = path("p.csv");
  EXPECT_NE(run({}).code, 0) << "no command is a usage error (the usage text goes to stderr)";
  expectOneLineError({"frobnicate"}, "frobnicate");
  expectOneLineError({"build", "--mesh", mesh, "--distance", "0.1", "--out", out, "--bogus"}, "--bogus");
  expectOneLineError({"build", "--mesh", mesh, "--distance"});
  expectOneLineError({"build", "--mesh", mesh, "--out", out}, "--distance");
  expectOneLineError({"build", "--mesh", path("missing.obj"), "--distance", "0.1", "--out", out}, "missing.obj");
  expectOneLineError({"build", "--mesh", clod_test::testData("unreadable.stl"), "--distance", "0.1", "--out", out},
                     "unreadable.stl");
  expectOneLineError({"build", "--mesh", clod_test::testData("nan_vertex.off"), "--distance", "0.1", "--out", out},
                     "nan_vertex.off");
  for (const char* bad : {"-0.1", "nan", "NaN", "inf", "abc", "0.1x", ""})
    expectOneLineError({"build", "--mesh", mesh, "--distance", bad, "--out", out}, "--distance");
  expectOneLineError({"build", "--mesh", mesh, "--scale", "-2", "--distance", "0.1", "--out", out}, "--scale");
  expectOneLineError({"build", "--mesh", mesh, "--scale", "nan", "--distance", "0.1", "--out", out}, "--scale");
  expectOneLineError({"build", "--mesh", mesh, "--scale", "2", "--normalize", "--distance", "0.1", "--out", out});
  expectOneLineError({"build", "--mesh", mesh, "--distance", "0.1", "--out", path("no/dir/o.yaml")});
  for (const char* bad : {"-0.01", "nan", "-inf", "inf"})
    expectOneLineError({"query", "--mesh", mesh, "--distance", "0.1", "--radius", bad, "--probes", probes, "--out",
                        path("r.csv")},
                       "--radius");
  expectOneLineError({"query", "--mesh", mesh, "--distance", "nan", "--radius", "0.1", "--probes", probes, "--out",
                      path("r.csv")},
                     "--distance");
  expectOneLineError({"query", "--mesh", mesh, "--distance", "0.1", "--radius", "0.1", "--mode", "fuzzy", "--probes",
                      probes, "--out", path("r.csv")},
                     "--mode");
  expectOneLineError({"query", "--mesh", mesh, "--distance", "0.1", "--radius", "0.1", "--probes", path("none.csv"),
                      "--out", path("r.csv")},
                     "none.csv");
  {
    std::ofstream csv(path("bad.csv"));
    csv << "x,y,z\n0.5,0.5,0.5\n1,2\n";
  }
  expectOneLineError({"query", "--mesh", mesh, "--distance", "0.1", "--radius", "0.1", "--probes", path("bad.csv"),
                      "--out", path("r.csv")},
                     "bad.csv");
  expectOneLineError({"sweep", "--mesh", mesh, "--distances", "0,-0.01"}, "--distances");
  expectOneLineError({"sweep", "--mesh", mesh, "--distances", "0,nan"}, "--distances");
  expectOneLineError({"sweep", "--mesh", mesh, "--distances", "0.1", "--radius", "nan"}, "--radius");
}

TEST_F(ClodTool, HelpGoesToStdoutWithZeroExit) {
  const ToolRun r = run({"--help"});
  EXPECT_EQ(r.code, 0);
  EXPECT_NE(r.out.find("usage"), std::string::npos);
}

// The exit codes --help lists: 1 input, 2 usage, 3 output; the same code for the same error in every command.
TEST_F(ClodTool, HelpListsTheExitCodes) {
  const ToolRun r = run({"--help"});
  EXPECT_NE(r.out.find("exit codes"), std::string::npos) << r.out;
  for (const char* line : {"0  success", "1  input error", "2  usage error", "3  output error", "4  internal error"})
    EXPECT_NE(r.out.find(line), std::string::npos) << line;
}

TEST_F(ClodTool, OneExitCodePerKindOfError) {
  const std::string mesh = clod_test::testData("cube.obj");
  writeFile("p.csv", "0.5,0.5,0.5\n");
  const std::vector<std::string> query = {"query", "--mesh", mesh, "--distance", "0.1", "--radius", "0.1", "--probes"};
  auto with = [](std::vector<std::string> a, const std::vector<std::string>& more) {
    a.insert(a.end(), more.begin(), more.end());
    return a;
  };
  expectExit(1, {"build", "--mesh", path("missing.obj"), "--distance", "0.1", "--out", path("s.yaml")},
             {"missing.obj"});
  expectExit(1, with(query, {path("none.csv"), "--out", path("r.csv")}), {"none.csv"});
  expectExit(2, with(query, {path("p.csv"), "--out", path("r.csv"), "--mode", "fuzzy"}), {"--mode"});
  expectExit(3, {"build", "--mesh", mesh, "--distance", "0.1", "--out", path("no/dir/s.yaml")}, {"--out", "no/dir"});
  expectExit(3, with(query, {path("p.csv"), "--out", path("no/dir/r.csv")}), {"--out", "no/dir"});
  expectExit(3, {"build", "--mesh", mesh, "--distance", "0.1", "--out", dir_.string()}, {"is a directory"});
}

// --out is checked before the mesh is even loaded: a missing mesh with a bad --out reports the --out.
TEST_F(ClodTool, BuildChecksOutBeforeBuilding) {
  expectExit(3, {"build", "--mesh", path("missing.obj"), "--distance", "0.1", "--out", path("no/dir/s.yaml")},
             {"--out"});
}

TEST_F(ClodTool, RadiusAboveTheBoundIsRefused) {
  writeFile("p.csv", "2,3,3\n");
  for (const char* radius : {"1e13", "1e152", "1e308", "1e400"})
    expectExit(2, {"query", "--mesh", clod_test::testData("cube.obj"), "--distance", "0.1", "--radius", radius,
                   "--probes", path("p.csv"), "--out", path("r.csv")},
               {"--radius", "1e+12"});
  EXPECT_TRUE(filesLeft() == std::vector<std::string>{"p.csv"});
  // The bound itself is accepted, and a probe 1 from the cube touches a pointer that large.
  const ToolRun r = run({"query", "--mesh", clod_test::testData("cube.obj"), "--distance", "0.1", "--radius", "1e12",
                         "--probes", path("p.csv"), "--out", path("r.csv"), "--json"});
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(jsonInt(r.out, "contacts"), 1) << r.out;
}

// A subnormal number is a number: accepted where the bound allows it.
TEST_F(ClodTool, SubnormalNumbersAreNumbers) {
  const std::string mesh = clod_test::testData("cube.obj");
  ToolRun r = run({"build", "--mesh", mesh, "--distance", "1e-320", "--out", path("s.yaml")});
  EXPECT_EQ(r.code, 0) << r.err;
  writeFile("p.csv", "2,3,3\n0,0,0\n");
  r = run({"query", "--mesh", mesh, "--distance", "0", "--radius", "1e-320", "--probes", path("p.csv"), "--out",
           path("r.csv"), "--json"});
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(jsonInt(r.out, "probes"), 2) << r.out;
}

TEST_F(ClodTool, ScaleThatOverflowsIsRefused) {
  const std::string mesh = clod_test::testData("cube.obj");  // coordinates 1 to 5
  for (const char* scale : {"1e160", "1e308", "1e-13", "0"})
    expectExit(2, {"build", "--mesh", mesh, "--scale", scale, "--distance", "0", "--out", path("s.yaml")},
               {"--scale", "1e+12"});
  // Within the option's bound, but the scaled cube reaches 5e12.
  expectExit(2, {"build", "--mesh", mesh, "--scale", "1e12", "--distance", "0", "--out", path("s.yaml")},
             {"--scale", "5e+12"});
  EXPECT_TRUE(filesLeft().empty());
  const ToolRun r = run({"build", "--mesh", mesh, "--scale", "1e11", "--distance", "0", "--out", path("s.yaml")});
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(readAll(path("s.yaml")).find("inf"), std::string::npos);
}

TEST_F(ClodTool, SweepCountIsAnIntegerWithinItsBound) {
  for (const char* count : {"1e308", "0", "-1", "2.5", "1e8", "nan"})
    expectExit(2, {"sweep", "--mesh", clod_test::testData("cube.obj"), "--distances", "0", "--count", count},
               {"--count", "1e+07"});
}

TEST_F(ClodTool, QueryWriteErrorIsAnOutputError) {
  writeFile("p.csv", "2,3,3\n");
  expectExit(3, {"query", "--mesh", clod_test::testData("cube.obj"), "--distance", "0.1", "--radius", "0.1",
                 "--probes", path("p.csv"), "--out", "/dev/full"},
             {"/dev/full", "No space left"});
}

TEST_F(ClodTool, StdoutWriteErrorIsAnOutputError) {
  const ToolRun r = run({"build", "--mesh", clod_test::testData("cube.obj"), "--distance", "0.1", "--out",
                         path("s.yaml")},
                        "", "/dev/full");
  EXPECT_EQ(r.code, 3) << r.err;
  EXPECT_NE(r.err.find("standard output"), std::string::npos) << r.err;
}

// A full disk (a file size limit, SIGXFSZ ignored so the write fails with EFBIG) in the middle of RESULT.csv
// and SPHERES.yaml: exit 3, the previous file intact, no temporary file left.
TEST_F(ClodTool, FullDiskLeavesThePreviousFileAndNoTemporary) {
  const std::string mesh = clod_test::sharedMesh("head.off");
  std::string csv;
  for (const Vec3& p : nearSurfaceProbes(*clod_test::loadNormalized(mesh), 2000, 0.01, 3))
    csv += std::to_string(p.x()) + "," + std::to_string(p.y()) + "," + std::to_string(p.z()) + "\n";
  writeFile("p.csv", csv);
  writeFile("r.csv", "previous\n");
  writeFile("s.yaml", "previous\n");
  const std::string limit = "ulimit -f 16; trap '' XFSZ; ";
  expectExit(3, {"query", "--mesh", mesh, "--normalize", "--distance", "0.02", "--radius", "0.01", "--probes",
                 path("p.csv"), "--out", path("r.csv")},
             {"--out", "r.csv"}, limit);
  expectExit(3, {"build", "--mesh", mesh, "--normalize", "--distance", "0", "--out", path("s.yaml")},
             {"--out", "s.yaml"}, limit);
  EXPECT_EQ(readAll(path("r.csv")), "previous\n");
  EXPECT_EQ(readAll(path("s.yaml")), "previous\n");
  EXPECT_EQ(filesLeft(), (std::vector<std::string>{"p.csv", "r.csv", "s.yaml"}));
}

class ClodToolProbes : public ClodTool {
 protected:
  void expectProbeError(const std::string& probes, const std::vector<std::string>& mentions,
                        const std::string& shell = "") const {
    expectExit(1, {"query", "--mesh", clod_test::testData("cube.obj"), "--distance", "0.1", "--radius", "0.1",
                   "--probes", probes, "--out", path("r.csv")},
               mentions, shell);
    EXPECT_FALSE(std::filesystem::exists(path("r.csv"))) << probes;
  }
};

TEST_F(ClodToolProbes, ReadErrorIsNotTheEndOfTheFile) {
  std::filesystem::create_directories(path("dir.csv"));
  expectProbeError(path("dir.csv"), {"dir.csv", "Is a directory"});
}

// A line of NUL bytes: refused at 4096 bytes, not read into memory without bound.
TEST_F(ClodToolProbes, LongLineIsRefused) {
  writeFile("zeros.csv", std::string(100000, '\0'));
  expectProbeError(path("zeros.csv"), {"zeros.csv:1:", "4096"});
  writeFile("digits.csv", "0.5,0.5," + std::string(5000, '5') + "\n");
  expectProbeError(path("digits.csv"), {"digits.csv:1:", "4096"});
  expectProbeError("/dev/zero", {"/dev/zero:1:", "4096"}, "timeout -s KILL 60 ");
}

TEST_F(ClodToolProbes, MalformedFirstLineIsAnError) {
  writeFile("two.csv", "1,2\n0.5,0.5,0.5\n");
  expectProbeError(path("two.csv"), {"two.csv:1:", "3 columns"});
  writeFile("mixed.csv", "x,2,z\n0.5,0.5,0.5\n");
  expectProbeError(path("mixed.csv"), {"mixed.csv:1:", "'x'"});
  writeFile("header2.csv", "x,y\n0.5,0.5,0.5\n");
  expectProbeError(path("header2.csv"), {"header2.csv:1:", "3 columns"});
  writeFile("second.csv", "x,y,z\nx,y,z\n");
  expectProbeError(path("second.csv"), {"second.csv:2:"});
}

TEST_F(ClodToolProbes, CoordinatesAreFiniteAndBounded) {
  for (const char* row : {"nan,0,0", "0,inf,0", "0,0,1e13", "1e400,0,0", "0,0,1x", "0,0,"}) {
    writeFile("p.csv", std::string("x,y,z\n0.5,0.5,0.5\n") + row + "\n");
    expectProbeError(path("p.csv"), {"p.csv:3:"});
  }
}

}  // namespace
