// libFuzzer target: queries on arbitrary bytes. Fixed meshes (a cube, a thin sliver slab and a mesh
// with zero-area triangles) are built once per clustering distance; each input is read as records of
// (x, y, z, r as raw doubles, one mode byte), so NaN, Inf, denormals and huge values all occur. Every
// query must be finite and agree with brute force; queries never allocate or throw.

#include <cstdint>
#include <cmath>
#include <cstring>
#include <memory>
#include <vector>

#include "clod_haptics/core/mesh.h"
#include "fuzz_common.h"

namespace {

using namespace clod_haptics;

struct Fixture {
  std::shared_ptr<const TriangleMesh> mesh;
  std::vector<std::unique_ptr<ClodDetector>> detectors;
};

std::vector<Fixture> makeFixtures() {
  std::vector<TriangleMesh> meshes;
  {
    std::vector<Vec3> v;
    for (int z = 0; z < 2; ++z)
      for (int y = 0; y < 2; ++y)
        for (int x = 0; x < 2; ++x) v.emplace_back(x, y, z);
    meshes.push_back(makeMesh(v, {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, {0, 1, 5}, {0, 5, 4},
                                  {2, 6, 7}, {2, 7, 3}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}},
                              "cube"));
  }
  meshes.push_back(makeMesh({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0.5, 1e-9, 0), Vec3(0.5, 0, 1e-9), Vec3(2, 0, 0)},
                            {{0, 1, 2}, {0, 3, 1}, {0, 1, 4}, {2, 2, 2}}, "slivers"));
  std::vector<Fixture> fixtures;
  for (auto& m : meshes) {
    Fixture f;
    f.mesh = std::make_shared<const TriangleMesh>(std::move(m));
    const ClodBuilder builder(f.mesh, std::make_shared<PaperPlacement>(1));
    for (double d : {0.0, 0.3})
      for (FastLevel fast : {FastLevel::Hierarchy, FastLevel::Flat})
        f.detectors.push_back(
            std::make_unique<ClodDetector>(f.mesh, std::make_shared<const ClodSphereSet>(builder.build(d)), fast));
    fixtures.push_back(std::move(f));
  }
  return fixtures;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const std::vector<Fixture> fixtures = makeFixtures();
  constexpr std::size_t kRecord = 4 * sizeof(double) + 1;
  for (std::size_t off = 0; off + kRecord <= size; off += kRecord) {
    double v[4];
    std::memcpy(v, data + off, sizeof v);
    // Magnitudes below 1e-100 are flushed to zero: their squares underflow, where a distance of 1e-68
    // and one of 0 both look like 0 to any double-precision test (not a meaningful haptic input).
    for (double& x : v)
      if (std::abs(x) < 1e-100) x = 0.0;
    const std::uint8_t sel = data[off + 4 * sizeof(double)];
    const Fixture& f = fixtures[sel % fixtures.size()];
    const ClodDetector& det = *f.detectors[(sel >> 2) % f.detectors.size()];
    const Vec3 p(v[0], v[1], v[2]);
    const double r = v[3];
    if (p.allFinite() && std::isfinite(r) && r >= 0.0 && p.cwiseAbs().maxCoeff() < 1e100 && r < 1e100) {
      clod_fuzz::checkQuery(*f.mesh, det, p, r);
    } else {
      ContactResult out;
      for (DetectionMode mode : {DetectionMode::Exact, DetectionMode::Paper, DetectionMode::Spheres}) {
        det.query(p, r, mode, out);
        if (out.contact)
          CLOD_FUZZ_CHECK(out.point.allFinite() && out.normal.allFinite() && std::isfinite(out.distance),
                          "non-finite result for an extreme input");
        if (!p.allFinite() || !std::isfinite(r) || r < 0.0) CLOD_FUZZ_CHECK(!out.contact, "contact for invalid input");
      }
    }
  }
  return 0;
}
