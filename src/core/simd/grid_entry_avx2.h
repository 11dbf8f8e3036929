#pragma once
// Internal to the core (not API): the cell grid build's entry bytes for four cells at once in AVX2 (the distance of
// the triangle from each cell's centre, its 8-bit code and finer byte, and the quantised direction), bit for bit what
// the scalar encoders of grid_entry_codes.h give. Compiled for x86-64 with GCC or Clang (the function carries the
// target attribute); call it only where packetAvx2() (dispatch.h) is true.

#include <cstdint>

#include "clod_haptics/core/geometry.h"
#include "closest_point_avx2.h"
#include "packet_avx2.h"

namespace clod_haptics {
namespace detail {

/** \brief Four entries' fields, one per lane (see gridEntriesAvx2). */
struct GridEntries4 {
  double distance[4];           ///< |centre - closest point|, as Vec3::norm computes it
  std::uint8_t code[4];         ///< distanceCode(roundDown(distance), unit)
  std::uint8_t finer[4];        ///< finerCode(roundDown(distance), code, unit, scale)
  std::int8_t direction[4][3];  ///< quantiseDirection of (centre - closest) / distance, per axis
};

/**
 * \brief A triangle's two cheap bounds on the cells near it: a cell's centre p is kept when it lies within limit of
 * the triangle's plane (|normal . (p - corner)| <= limit; every centre when planar is false) and within the ball
 * ((p - mid) . (p - mid) <= ball2).
 */
struct TriangleBounds {
  bool planar;
  Vec3 normal, corner;
  double limit;
  Vec3 mid;
  double ball2;
};

#if defined(CLOD_PACKET_AVX2)
/**
 * \brief Bit k set: the cell of centre (x, y, originZ + (z + k + 0.5) h) passes both bounds, k = 0..3, computed as
 * the scalar build computes them (Vec3 arithmetic, the same order).
 */
unsigned columnCellsAvx2(double x, double y, double originZ, double h, std::int64_t z, const TriangleBounds& bounds);

/**
 * \brief For k = 0..3: the entry of the cell centred at *centre[k] whose triangle's closest point is lane k of
 * closest (q[.][k]), in out. Returns the lanes encoded: a lane whose distance is not above tiny (the scalar build
 * then stores no direction) or whose distance code the scalar rounding loop would step more than twice is left out,
 * for the caller to encode with the scalar functions; out.distance is set for every lane.
 */
unsigned gridEntriesAvx2(const Vec3* const centre[4], const ClosestPoints4& closest, double unit, double scale,
                         double tiny, GridEntries4& out);
#endif

}  // namespace detail
}  // namespace clod_haptics
