#pragma once

#include "clod_haptics/core/contact.h"
#include "clod_haptics/core/mesh.h"

namespace clod_haptics {

/**
 * \brief The reference answer: the closest point over all triangles, in double precision, and a
 * contact when its distance is at most r. Ties go to the lowest triangle index. O(n) per query;
 * tests and benchmarks use it as ground truth.
 */
ContactResult bruteForceQuery(const TriangleMesh& mesh, const Vec3& p, double r);

}  // namespace clod_haptics
