#pragma once

#include <algorithm>
#include <array>

#include "clod_haptics/core/mesh.h"

namespace clod_haptics {

/**
 * \brief Pieces of a long triangle, for a sphere set whose spheres may each cover part of a triangle.
 *
 * A triangle is halved across its longest edge: the edge's midpoint, 0.5 * (p + q), joined to the opposite
 * corner. Halving repeats on each half until no edge is longer than maxEdge or maxDepth halvings are done. The
 * longest edge is the first of the largest squared lengths (edges ab, bc, ca in that order), so the same
 * corners give the same pieces bit for bit. This is what lets fitProblem check a split triangle's coverage
 * without the pieces being stored: it halves the same way until each piece lies in one sphere listing the triangle.
 * The pieces tile the triangle up to the rounding of the midpoints.
 */
using TrianglePiece = std::array<Vec3, 3>;

/** \brief Halvings at most per triangle (up to 2^12 pieces), for the builder and the coverage check alike. */
constexpr int kMaxPieceDepth = 12;

/** \brief The two halves of a piece, across its longest edge. */
inline void halvePiece(const TrianglePiece& t, TrianglePiece& first, TrianglePiece& second) {
  const double e0 = (t[1] - t[0]).squaredNorm(), e1 = (t[2] - t[1]).squaredNorm(), e2 = (t[0] - t[2]).squaredNorm();
  const int k = e0 >= e1 && e0 >= e2 ? 0 : (e1 >= e2 ? 1 : 2);  // the longest edge runs from corner k to k + 1
  const Vec3& p = t[k];
  const Vec3& q = t[(k + 1) % 3];
  const Vec3& opposite = t[(k + 2) % 3];
  const Vec3 mid = 0.5 * (p + q);
  first = {p, mid, opposite};
  second = {mid, q, opposite};
}

/** \brief The longest squared edge length of a piece. */
inline double longestEdge2(const TrianglePiece& t) {
  return std::max({(t[1] - t[0]).squaredNorm(), (t[2] - t[1]).squaredNorm(), (t[0] - t[2]).squaredNorm()});
}

/**
 * \brief Calls visit(piece, halvings) for each piece of t, t itself being depth halvings below its triangle: a piece
 * that split(piece) asks to halve is halved, up to maxDepth more halvings, depth first, the first half before the
 * second. Further halvings of a piece continue the same halving of its triangle, so coveredByPieces finds them.
 */
template <class Split, class Visit>
void halveWhile(const TrianglePiece& t, int maxDepth, int depth, Split&& split, Visit&& visit) {
  if (maxDepth <= 0 || !split(t)) {
    visit(t, depth);
    return;
  }
  TrianglePiece first, second;
  halvePiece(t, first, second);
  halveWhile(first, maxDepth - 1, depth + 1, split, visit);
  halveWhile(second, maxDepth - 1, depth + 1, split, visit);
}

/**
 * \brief Calls visit(piece) for each piece of t, halved until no edge exceeds maxEdge or maxDepth halvings,
 * depth first, the first half before the second. A triangle within maxEdge (or maxEdge not positive) is one
 * piece, itself.
 */
template <class Visit>
void forEachPiece(const TrianglePiece& t, double maxEdge, int maxDepth, Visit&& visit) {
  halveWhile(
      t, maxDepth, 0,
      [maxEdge](const TrianglePiece& piece) { return maxEdge > 0.0 && longestEdge2(piece) > maxEdge * maxEdge; },
      [&](const TrianglePiece& piece, int) { visit(piece); });
}

/**
 * \brief Whether the pieces of t, halved as forEachPiece halves them, each lie within one region that
 * inside(piece) accepts, halving a piece that none accepts up to maxDepth times. A conservative test of a
 * triangle's coverage by a union of balls (a ball holds a piece when it holds its three corners).
 */
template <class Inside>
bool coveredByPieces(const TrianglePiece& t, int maxDepth, Inside&& inside) {
  if (inside(t)) return true;
  if (maxDepth <= 0) return false;
  TrianglePiece first, second;
  halvePiece(t, first, second);
  return coveredByPieces(first, maxDepth - 1, inside) && coveredByPieces(second, maxDepth - 1, inside);
}

}  // namespace clod_haptics
