#pragma once
// Internal to the core (not API): the packet kernels in AVX2, compiled for x86-64 with GCC or Clang (each
// function carries the target attribute, so the rest of the core still runs on any x86-64). Call them
// only where packetAvx2() (dispatch.h) is true.

#include "clod_haptics/core/triangle_bvh.h"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define CLOD_PACKET_AVX2 1

namespace clod_haptics {
namespace detail {

/**
 * \brief PacketChildrenTest (see dispatch.h) with AVX2, four rays per register (groups of four without an
 * active ray skipped): the same values as packetChildrenBaseline.
 */
void packetChildrenAvx2(const TriangleBvh::Node* const child[2], const double* o, const double* inv,
                        const PacketCull& cull, unsigned active, double* const entry[2], unsigned mask[2]);

/**
 * \brief PacketChildrenFloatTest (see dispatch.h) with AVX2, eight rays per register: a node kept by
 * packetChildrenAvx2 is kept here (boxes widened, thresholds rounded up, see PacketFloat), entry[c] gets
 * lower bounds of the entry distances.
 */
void packetChildrenAvx2f(const TriangleBvh::Node* const child[2], const PacketFloat& f, unsigned active,
                         double* const entry[2], unsigned mask[2]);

/**
 * \brief PacketTriangleTest (see triangle_bvh.h) with AVX2, four rays per register (groups of four without
 * an active ray skipped): rayTriangle's operations in the same order, so the same decisions and distances
 * bit for bit.
 */
unsigned packetTriangleAvx2(const double* a, const double* b, const double* c, const double* o, const double* d,
                            unsigned active, double* t);

}  // namespace detail
}  // namespace clod_haptics

#endif
