#pragma once
// Checks shared by the fuzz targets: a violated invariant aborts, so libFuzzer records the input.

#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/detector.h"
#include "clod_haptics/core/sphere_set.h"

namespace clod_fuzz {

using namespace clod_haptics;

#define CLOD_FUZZ_CHECK(cond, ...)                                     \
  do {                                                                 \
    if (!(cond)) {                                                     \
      std::fprintf(stderr, "invariant violated: %s: ", #cond);         \
      std::fprintf(stderr, __VA_ARGS__);                               \
      std::fprintf(stderr, "\n");                                      \
      std::abort();                                                    \
    }                                                                  \
  } while (0)

/** \brief No NaN or Inf in the set, and every triangle inside a sphere that lists it. */
inline void checkSet(const TriangleMesh& mesh, const ClodSphereSet& set) {
  CLOD_FUZZ_CHECK(set.offsets.size() == set.size() + 1 && set.offsets.back() == set.triangles.size(), "flat arrays");
  std::vector<char> covered(mesh.size(), 0);
  const double size = mesh.diagonal();
  for (std::size_t i = 0; i < set.size(); ++i) {
    CLOD_FUZZ_CHECK(set.centres[i].allFinite() && std::isfinite(set.radii[i]) && set.radii[i] >= 0, "sphere %zu", i);
    const double reach = set.radii[i] * (1 + 1e-12) + 1e-12 * size;
    for (const std::uint32_t* t = set.begin(i); t != set.end(i); ++t) {
      CLOD_FUZZ_CHECK(*t < mesh.size(), "index %u", *t);
      bool in = true;
      for (int k = 0; k < 3; ++k) in = in && (mesh.vertex(*t, k) - set.centres[i]).norm() <= reach;
      if (in) covered[*t] = 1;
    }
  }
  for (std::size_t t = 0; t < mesh.size(); ++t) CLOD_FUZZ_CHECK(covered[t], "triangle %zu uncovered", t);
}

/** \brief exact == brute force; paper within brute force; spheres never misses; results finite. */
inline void checkQuery(const TriangleMesh& mesh, const ClodDetector& det, const Vec3& p, double r) {
  const ContactResult ref = bruteForceQuery(mesh, p, r);
  ContactResult exact, paper, spheres;
  det.query(p, r, DetectionMode::Exact, exact);
  det.query(p, r, DetectionMode::Paper, paper);
  det.query(p, r, DetectionMode::Spheres, spheres);
  CLOD_FUZZ_CHECK(exact.contact == ref.contact, "exact %d vs brute force %d", exact.contact, ref.contact);
  if (ref.contact) {
    const double tol = 1e-9 * std::max(ref.distance, r) + 1e-15 * mesh.diagonal();
    CLOD_FUZZ_CHECK(std::abs(exact.distance - ref.distance) <= tol, "distance %.17g vs %.17g", exact.distance,
                    ref.distance);
    CLOD_FUZZ_CHECK(spheres.contact, "spheres missed");
  }
  // Paper projects onto the plane and brute force reconstructs the point from barycentric weights: they
  // round differently, so a paper contact is accepted when the true distance is within 1e-12 of the
  // model size of r.
  CLOD_FUZZ_CHECK(!paper.contact || ref.contact || bruteForceQuery(mesh, p, r + 1e-12 * mesh.diagonal()).contact,
                  "paper contact that brute force denies (r %.17g)", r);
  for (const ContactResult* c : {&exact, &paper, &spheres})
    if (c->contact)
      CLOD_FUZZ_CHECK(c->point.allFinite() && c->normal.allFinite() && std::isfinite(c->distance) &&
                          std::isfinite(c->depth),
                      "non-finite result");
}

}  // namespace clod_fuzz
