// The installed core from a downstream package: load the bundled mesh, build a level, and query points
// near the surface against the brute-force answer over all triangles.
#include <clod_haptics/core/brute_force.h>
#include <clod_haptics/core/detector.h>
#include <clod_haptics/core/sphere_set.h>

#include <random>

#include "downstream_common.h"

using namespace clod_haptics;

TEST(DownstreamCore, InstalledCoreAnswersAsBruteForce) {
  const auto mesh = downstream::installedTorus();
  ASSERT_GT(mesh->triangles.size(), 100u);
  const ClodBuilder builder(mesh);
  const auto level = std::make_shared<const ClodSphereSet>(builder.build(0.02));
  ASSERT_GT(level->size(), 0u);
  const ClodDetector detector(mesh, level);
  std::mt19937 random(19);
  std::uniform_int_distribution<std::size_t> pickVertex(0, mesh->vertices.size() - 1);
  std::uniform_real_distribution<double> jitter(-0.05, 0.05);
  const double r = 0.02;
  int contacts = 0;
  for (int i = 0; i < 2000; ++i) {
    const Vec3 p =
        mesh->vertices[pickVertex(random)] + mesh->origin + Vec3(jitter(random), jitter(random), jitter(random));
    ContactResult got;
    detector.query(p, r, DetectionMode::Exact, got);
    const ContactResult expected = bruteForceQuery(*mesh, p, r);
    ASSERT_EQ(got.contact, expected.contact) << "probe " << i;
    if (expected.contact) {
      ++contacts;
      EXPECT_NEAR(got.distance, expected.distance, 1e-9) << "probe " << i;
      EXPECT_NEAR((got.point - expected.point).norm(), 0.0, 1e-9) << "probe " << i;
    }
  }
  EXPECT_GT(contacts, 200) << "too few probes touch the mesh to test anything";
  EXPECT_LT(contacts, 1900) << "too few probes miss the mesh to test anything";
}
