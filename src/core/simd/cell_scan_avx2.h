#pragma once
// Internal to the core (not API): the scan of a grid cell's candidates in AVX2, eight entries per register in
// float, a filter that keeps every entry the double test keeps (that test then decides): the swept query's
// (SweptSphereQuery::sweepCell) for a piece of a sweep, the point query's (ClodDetector::scanCell) for a piece of
// zero length. Compiled for x86-64 with GCC or Clang (the function carries the target attribute);
// call it only where packetAvx2() (dispatch.h) is true.

#include "clod_haptics/core/cell_grid.h"
#include "packet_avx2.h"

namespace clod_haptics {
namespace detail {

/**
 * \brief One piece of a sweep seen from a cell's centre, in float: an entry (distance dc, stored direction u)
 * is kept when min(r0 . u + off0, r1 . u + off1) + dc <= limit.
 */
struct CellScanBounds {
  float r0[3], r1[3];  ///< the piece's ends less the cell centre, divided by 127 (the directions' scale)
  float off0, off1;    ///< the directions' rounding at each end (negative)
  float unit;          ///< the grid's distance unit
  float limit;         ///< the double test's threshold, raised to cover float rounding
};

/** \brief Float bounds that keep every entry the double test keeps (see CellScanBounds). */
CellScanBounds cellScanBounds(const Vec3& r0, const Vec3& r1, double off0, double off1, double unit, double limit,
                              double reach);

#if defined(CLOD_PACKET_AVX2)
/** \brief Bit i set: entry i of e[0, 8) may pass (see CellScanBounds); never clears one the double test keeps. */
unsigned cellScanBlockAvx2(const CellGrid::Entry* e, const CellScanBounds& b);
#endif

}  // namespace detail
}  // namespace clod_haptics
