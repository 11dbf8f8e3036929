#pragma once

#include <cstdint>
#include <vector>

#include "clod_haptics/core/mesh.h"

namespace clod_haptics {

/**
 * \brief Points near the surface: area-weighted uniform samples on the triangles, pushed along the
 * face normal by an offset uniform in [-maxOffset, maxOffset] (both sides). Deterministic for a seed.
 * Probes of both functions are in the model frame (TriangleMesh::origin added), as queries take them.
 */
std::vector<Vec3> nearSurfaceProbes(const TriangleMesh& mesh, std::size_t count, double maxOffset, std::uint64_t seed);

/** \brief Points uniform in the mesh's bounding box grown by margin on every side. Deterministic for a seed. */
std::vector<Vec3> uniformProbes(const TriangleMesh& mesh, std::size_t count, double margin, std::uint64_t seed);

/** \brief Sorts points along a Morton (Z-order) curve, the order a coherent stylus stream has. */
void sortMorton(std::vector<Vec3>& points);

}  // namespace clod_haptics
