#pragma once
// Internal to the core (not API): the SIMD kernels of TriangleBvh::forEachPacketHit behind one table of
// plain functions, chosen by what the CPU runs (detected once).

#include "clod_haptics/core/triangle_bvh.h"

namespace clod_haptics {
namespace detail {

/**
 * \brief A packet kernel's test of a node's two children against the active rays, box and cull together
 * (o and inv: [3][kRays] row-major origins and inverse directions): entry[c] gets the entry distances into
 * child c (of the rays tested) and mask[c] the active rays that meet its box and pass cull.keeps, the same
 * values as forEachRayHit's box test and TriangleBvh::keeps.
 */
using PacketChildrenTest = void (*)(const TriangleBvh::Node* const child[2], const double* o, const double* inv,
                                    const PacketCull& cull, unsigned active, double* const entry[2], unsigned mask[2]);

/**
 * \brief The same test in float: a node kept by the double test is kept here, and entry[c] gets lower
 * bounds of the entry distances (see PacketFloat).
 */
using PacketChildrenFloatTest = void (*)(const TriangleBvh::Node* const child[2], const PacketFloat& f, unsigned active,
                                         double* const entry[2], unsigned mask[2]);

/** \brief The kernels of one instruction set. */
struct PacketKernels {
  PacketChildrenTest children;
  PacketChildrenFloatTest childrenFloat;  ///< nullptr where the instruction set has no float form
  PacketTriangleTest triangle;
};

/**
 * \brief The kernels a packet walk uses: AVX2 where the CPU runs it and usePacketAvx2 left it on, else the
 * baseline ones (SSE2 on x86-64).
 */
const PacketKernels& packetKernels();

/** \brief Whether packetKernels() gives the AVX2 kernels. */
bool packetAvx2();

/**
 * \brief Turns the AVX2 kernels off (or back on where the CPU has them), so tests cover both forms: the packet
 * walk's and the swept query's cell scan (cell_scan_avx2.h), which asks packetAvx2() too.
 */
void usePacketAvx2(bool on);

}  // namespace detail
}  // namespace clod_haptics
