#pragma once
// Internal to the core (not API): the packet kernels every CPU runs, two rays per SSE2 register where the
// compiler targets SSE2 (every x86-64) and plain C++ otherwise, the same values either way.

#include "clod_haptics/core/triangle_bvh.h"

namespace clod_haptics {
namespace detail {

/**
 * \brief Where every ray of a packet enters node's box (entry, all kRays lanes) and the mask of the rays
 * that meet it: the values of forEachRayHit's box test. o and inv: [3][kRays] row-major, 16-byte aligned.
 */
unsigned packetBoxBaseline(const TriangleBvh::Node& node, const double* o, const double* inv, double* entry);

/** \brief The rays of active that pass TriangleBvh::keeps at node, ray r entering it at entry[r]. */
inline unsigned packetKept(const PacketCull& cull, const TriangleBvh::Node& node, const double* entry,
                           unsigned active) {
  unsigned mask = 0;
  for (unsigned m = active; m; m &= m - 1) {
    const int r = __builtin_ctz(m);
    if (TriangleBvh::keeps(cull, r, node, entry[r])) mask |= 1u << r;
  }
  return mask;
}

/** \brief PacketChildrenTest (see dispatch.h) from packetBoxBaseline and packetKept. */
void packetChildrenBaseline(const TriangleBvh::Node* const child[2], const double* o, const double* inv,
                            const PacketCull& cull, unsigned active, double* const entry[2], unsigned mask[2]);

/** \brief PacketTriangleTest (see triangle_bvh.h) by rayTriangle, ray after ray. */
unsigned packetTriangleBaseline(const double* a, const double* b, const double* c, const double* o, const double* d,
                                unsigned active, double* t);

}  // namespace detail
}  // namespace clod_haptics
