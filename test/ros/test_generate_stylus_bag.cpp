// scripts/generate_stylus_bag.py: the motion it writes, read back with the bag reader and measured
// against the mesh with the core's brute-force reference: 1 kHz, free space at the start and end,
// pressed in by --depth during the slide, sliding about --slide-length along the surface.
#include <gtest/gtest.h>

#include <string>

#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/ros/bag_source.h"
#include "clod_haptics/test_config.h"
#include "../rostest/run_command.h"

using namespace clod_haptics;

namespace {

const std::string kScript = CLOD_PACKAGE_DATA_DIR "/../scripts/generate_stylus_bag.py";

using clod_haptics_test::Outcome;

/** Runs the generator with the Python catkin uses (the one with rosbag), capturing its output. */
Outcome runGenerator(const std::string& args) {
  return clod_haptics_test::capture(std::string(CLOD_PYTHON) + " " + kScript + " " + args);
}

struct Case {
  std::string mesh;
  double scale;
};

void checkMotion(const Case& c) {
  SCOPED_TRACE(c.mesh);
  const std::string bag = ::testing::TempDir() + "clod_generated.bag";
  const double depth = 0.0015, height = 0.03, slideLength = 0.08;
  const Outcome o = runGenerator("--mesh " + c.mesh + " --scale " + std::to_string(c.scale) + " --out " + bag);
  ASSERT_EQ(o.exitCode, 0) << o.output;
  EXPECT_NE(o.output.find("7501 poses at 1000 Hz"), std::string::npos) << o.output;
  const device::BagMotion motion = device::readStylusBag(bag);
  const auto& samples = motion.trajectory.samples();
  // Phases (defaults): approach 1.5 s, press 0.75 s, slide 4 s, retract 1.25 s, at 1 kHz.
  ASSERT_EQ(samples.size(), 7501u);
  for (std::size_t k = 1; k < samples.size(); ++k) ASSERT_NEAR(samples[k].time - samples[k - 1].time, 0.001, 1e-6);
  EXPECT_EQ(motion.topic, "/phantom/pose");
  EXPECT_EQ(motion.frameId, "world");

  MeshLoadOptions options;
  options.scale = c.scale;
  const TriangleMesh mesh = loadMesh(c.mesh, options);
  auto distance = [&](std::size_t k) { return bruteForceQuery(mesh, samples[k].position, 1.0).distance; };
  auto inside = [&](std::size_t k) {  // behind the closest face
    const ContactResult r = bruteForceQuery(mesh, samples[k].position, 1.0);
    return (samples[k].position - r.point).dot(mesh.normals[r.triangle]) < 0.0;
  };

  // Free space at both ends, well beyond a 2 mm pointer.
  EXPECT_GT(distance(0), 0.5 * height);
  EXPECT_GT(distance(samples.size() - 1), 0.5 * height);
  EXPECT_FALSE(inside(0));
  // The approach closes in on the surface.
  for (std::size_t k = 100; k <= 1400; k += 100) EXPECT_LT(distance(k), distance(k - 100) + 1e-9) << k;
  // The slide: pressed in by about depth, behind the surface, all along.
  std::size_t nearDepth = 0, slide = 0;
  double pathLength = 0.0;
  for (std::size_t k = 2300; k <= 6200; ++k) {
    const double d = distance(k);
    ++slide;
    EXPECT_GT(d, 0.3 * depth) << "sample " << k;
    EXPECT_LT(d, 1.5 * depth) << "sample " << k;
    if (std::abs(d - depth) < 0.3e-3) ++nearDepth;
    if (k % 100 == 0) {
      EXPECT_TRUE(inside(k)) << "sample " << k;
    }
    if (k > 2300) pathLength += (samples[k].position - samples[k - 1].position).norm();
  }
  EXPECT_GT(nearDepth, slide * 9 / 10);
  // Nearly all of the slide length lies between these samples (the ends ease in and out).
  EXPECT_GT(pathLength, 0.8 * slideLength);
  EXPECT_LT(pathLength, 1.2 * slideLength);
}

}  // namespace

TEST(GenerateStylusBag, BundledTorus) { checkMotion({CLOD_PACKAGE_DATA_DIR "/meshes/torus.obj", 1.0}); }

TEST(GenerateStylusBag, SharedHeadOff) { checkMotion({CLOD_SHARED_MESH_DIR "/head.off", 0.01}); }

TEST(GenerateStylusBag, BadMeshOrArgumentsFail) {
  const std::string bag = ::testing::TempDir() + "clod_generated_bad.bag";
  for (const std::string& mesh :
       {std::string("/nonexistent/mesh.obj"), std::string(CLOD_TEST_DATA_DIR "/no_triangles.obj")}) {
    const Outcome o = runGenerator("--mesh " + mesh + " --out " + bag);
    EXPECT_EQ(o.exitCode, 1) << o.output;
    EXPECT_NE(o.output.find("cannot read mesh " + mesh), std::string::npos) << o.output;
  }
  const Outcome o = runGenerator("--mesh " CLOD_PACKAGE_DATA_DIR "/meshes/torus.obj --rate -5 --out " + bag);
  EXPECT_EQ(o.exitCode, 2) << o.output;  // argparse usage error
  EXPECT_NE(o.output.find("--rate must be positive"), std::string::npos) << o.output;
}
