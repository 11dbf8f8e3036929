#pragma once

#include "clod_haptics/core/contact.h"
#include "clod_haptics/core/mesh.h"

namespace clod_haptics {

/**
 * \brief The reference answer: the closest point over all triangles, in double precision, and a
 * contact when its distance is at most r. Ties go to the lowest triangle index. O(n) per query;
 * tests and benchmarks use it as ground truth. Side, depth and normal by finishContact (the sign rule
 * the detector shares). p and the answer's point are in the model frame (mesh.origin added back).
 */
ContactResult bruteForceQuery(const TriangleMesh& mesh, const Vec3& p, double r);

/**
 * \brief The reference of deep penetration: as bruteForceQuery, and also a contact (depth r + distance,
 * inside) when the centre is behind the surface at any depth, within the mesh's bounding box. What
 * ClodDetector::query answers for a stream whose previous answer had the centre inside. O(n).
 */
ContactResult bruteForceSignedQuery(const TriangleMesh& mesh, const Vec3& p, double r);

}  // namespace clod_haptics
