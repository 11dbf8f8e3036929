#pragma once
// Internal to the core (not API): closestPointOnTriangle for four triangles (or four points) at once in AVX2, for the
// grid's exact scan and its build, where a test's branches (which of seven regions) mispredict on most candidates.
// Compiled for x86-64 with GCC or Clang (the function carries the target attribute); call it only where packetAvx2()
// (dispatch.h) is true.

#include <cstdint>

#include "clod_haptics/core/geometry.h"
#include "packet_avx2.h"

namespace clod_haptics {
namespace detail {

/**
 * \brief Four closest points, one per lane: the point, its squared distance from p, and the region it was found
 * in (with an edge's parameter), from which region() gives the feature; the scan asks it only of a new best.
 */
struct ClosestPoints4 {
  /** \brief The scalar function's regions, in the order it tries them. */
  enum Kind { kVertexA, kVertexB, kEdgeAB, kVertexC, kEdgeAC, kEdgeBC, kFace };
  double q[3][4];
  double d2[4];
  double kind[4];   ///< a Kind, per lane
  double param[4];  ///< an edge's parameter t (from its first vertex), per lane
  /** \brief The feature of lane k, as closestPointOnTriangle reports it. */
  TriangleRegion region(unsigned k) const {
    const auto onEdge = [t = param[k]](std::uint8_t from, std::uint8_t to, std::uint8_t edge) {
      return t <= 0.0   ? TriangleRegion{TriangleFeature::Vertex, from}
             : t >= 1.0 ? TriangleRegion{TriangleFeature::Vertex, to}
                        : TriangleRegion{TriangleFeature::Edge, edge};
    };
    switch (static_cast<int>(kind[k])) {
      case kVertexA:
        return {TriangleFeature::Vertex, 0};
      case kVertexB:
        return {TriangleFeature::Vertex, 1};
      case kEdgeAB:
        return onEdge(0, 1, 0);
      case kVertexC:
        return {TriangleFeature::Vertex, 2};
      case kEdgeAC:
        return onEdge(0, 2, 2);  // edge 2 runs from c to a; t is measured from a
      case kEdgeBC:
        return onEdge(1, 2, 1);
      default:
        return {TriangleFeature::Face, 0};
    }
  }
};

#if defined(CLOD_PACKET_AVX2)
/**
 * \brief closestPointOnTriangle(p, *a[k], *b[k], *c[k], &region) for k = 0..3, lane by lane with the scalar
 * function's operations in its order (no fused multiply-add), so the same point, the same squared distance
 * ((p - q).squaredNorm(): (x^2 + y^2) + z^2) and the same region bit for bit. Returns the lanes computed: a lane
 * that takes the scalar function's zero-area fallback (closestOnEdges: a degenerate edge or a sliver face) is left
 * out, for the caller to run the scalar function on.
 */
unsigned closestPointsAvx2(const Vec3& p, const Vec3* const a[4], const Vec3* const b[4], const Vec3* const c[4],
                           ClosestPoints4& out);
/**
 * \brief The same for four points and one triangle: closestPointOnTriangle(*p[k], a, b, c) for k = 0..3, bit for bit
 * (the cell grid's build, where a small triangle's cells around it fall in different regions).
 */
unsigned closestPointsAvx2(const Vec3* const p[4], const Vec3& a, const Vec3& b, const Vec3& c, ClosestPoints4& out);
#endif

}  // namespace detail
}  // namespace clod_haptics
