#pragma once
// A Hubbard-like reference sphere set (medial-axis approximation, after Hubbard 1996 and Bradshaw's toolkit's
// "medial" method, simplified): a medial ball per surface sample by the shrinking-ball method, N of them chosen by
// farthest-point sampling of their centres, each surface sample given to the chosen ball whose surface is nearest, and
// each sphere grown to reach its samples. Balls that did not shrink or whose centre is outside are left out. Covers
// its samples, not necessarily every point of the surface.

#include <cstdint>

#include "clod_haptics/core/mesh.h"
#include "tightness.h"

namespace clod_bench {

/** \brief The reference set of `target` spheres from `samples` surface samples (deterministic for a seed). */
SphereList medialSpheres(const TriangleMesh& mesh, std::size_t target, std::size_t samples, std::uint64_t seed);

/**
 * \brief The set grown just enough to hold every one of `samples` surface samples (a seed of its own): each sample
 * outside every sphere grows the sphere that needs the least growth to reach it, in sample order. The way of
 * comparing a reference that leaves part of the surface uncovered with sets that cover all of it.
 */
SphereList grownToCover(SphereList spheres, const TriangleMesh& mesh, std::size_t samples, std::uint64_t seed);

/** \brief Area-uniform points on the mesh's triangles (local frame), with the face normal of each. */
void surfaceSamples(const TriangleMesh& mesh, std::size_t count, std::uint64_t seed, std::vector<Vec3>& points,
                    std::vector<Vec3>* normals);

}  // namespace clod_bench
