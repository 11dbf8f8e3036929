#pragma once
// Internal to the core (not API): the swept query's two cheap bounds (SweptSphereQuery::testTriangle's ball and the
// across-the-plane part of its plane bound) for four triangles at once in AVX2, in double, on their records as the
// query lays them out (ball centre x, y, z, radius, unit normal x, y, z, thickness first). Looser than the scalar
// bounds by a relative 1e-9, so it keeps every triangle they keep; the scalar tests then decide. Compiled for x86-64
// with GCC or Clang (the function carries the target attribute); call it only where packetAvx2() (dispatch.h) is true.

#include <cstdint>

#include "packet_avx2.h"

namespace clod_haptics {
namespace detail {

/** \brief One sweep as the record filter sees it. */
struct RecordFilterSweep {
  double a[3], d[3];  ///< start and motion (the mesh's local frame)
  double end;         ///< the part of the sweep that can still win: t in [0, end]
  double invdd;       ///< 1 / |d|^2, 0 for a zero-length sweep
  double R;           ///< the test radius
  double across;      ///< the plane bound's reach (R with its rounding slack)
};

#if defined(CLOD_PACKET_AVX2)
/**
 * \brief Bit k set: the triangle whose record starts at record[k] may touch the sweep by the ball bound, the
 * across-plane bound and the two parts of the plane bound together (across and along it, planeBoundMisses); never
 * clears one that the scalar bounds keep.
 */
unsigned recordFilterAvx2(const double* const record[4], const RecordFilterSweep& s);
#endif

}  // namespace detail
}  // namespace clod_haptics
