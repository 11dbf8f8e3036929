// TightPlacement: one sphere per triangle, centred half way to the first surface behind it, checked
// against a brute-force ray cast over every triangle; the statistics on open and degenerate meshes.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "clod_haptics/core/geometry.h"
#include "clod_haptics/core/tight_placement.h"
#include "test_helpers.h"

namespace {

using namespace clod_haptics;

TEST(TightPlacement, HalfWayToTheFirstSurfaceBehindEachTriangle) {
  for (const std::string name : {"head.off", "mesh_with_border.off", "degtri_sliding.off"}) {
    const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh(name));
    for (unsigned threads : {1u, 0u}) {
      PlacementStats stats;
      const std::vector<PlacedSphere> placed = TightPlacement(threads).place(*mesh, &stats);
      ASSERT_EQ(placed.size(), mesh->size()) << name;
      EXPECT_EQ(stats.triangles, mesh->size());
      EXPECT_EQ(stats.paired + stats.unpaired + stats.degenerate, mesh->size()) << name;
      std::size_t paired = 0, unpaired = 0, degenerate = 0;
      const double minT = 1e-12 * mesh->diagonal();
      for (std::size_t t = 0; t < mesh->size(); ++t) {
        const PlacedSphere& s = placed[t];
        ASSERT_EQ(s.triangle, t);
        ASSERT_TRUE(s.centre.allFinite() && std::isfinite(s.radius)) << name << " triangle " << t;
        // Reference: the nearest hit of the inward ray among all other triangles.
        const Vec3 c = mesh->centroid(t);
        Vec3 expected = c;
        if (mesh->normals[t].isZero(0.0)) {
          ++degenerate;
        } else {
          double first = std::numeric_limits<double>::infinity();
          for (std::size_t o = 0; o < mesh->size(); ++o) {
            double hit;
            if (o != t &&
                rayTriangle(c, -mesh->normals[t], mesh->vertex(o, 0), mesh->vertex(o, 1), mesh->vertex(o, 2), hit) &&
                hit > minT)
              first = std::min(first, hit);
          }
          if (std::isfinite(first)) {
            ++paired;
            expected = c - 0.5 * first * mesh->normals[t];
          } else {
            ++unpaired;
          }
        }
        EXPECT_LE((s.centre - expected).norm(), 1e-12) << name << " triangle " << t;
        double far = 0.0;
        for (int v = 0; v < 3; ++v) far = std::max(far, (mesh->vertex(t, v) - s.centre).norm());
        EXPECT_NEAR(s.radius, far, 1e-12);
      }
      EXPECT_EQ(stats.paired, paired) << name;
      EXPECT_EQ(stats.unpaired, unpaired) << name;
      EXPECT_EQ(stats.degenerate, degenerate) << name;
      if (name == "mesh_with_border.off") {
        EXPECT_GT(unpaired, 0u);
      }
      if (name == "head.off") {
        EXPECT_GT(paired, mesh->size() / 2);
      }
    }
  }
}

}  // namespace
