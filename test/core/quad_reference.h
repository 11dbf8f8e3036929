#pragma once
// An independent reference for exactness tests: the distance from a point to a triangle soup in quadruple
// precision (GCC's __float128, 113-bit significand), on the file's own numbers. A product of two doubles is
// exact in it, so "the file's coordinates times the scale" is represented without rounding, and the closest
// point (Ericson, Real-Time Collision Detection, 5.1.5) carries errors near 1e-34 of the coordinates: far
// below what a double answer can show, at any offset the tests use. Written apart from the library's
// geometry.cpp (no shared code), so a mistake there cannot hide here.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

namespace clod_test {

using Quad = __float128;

struct Q3 {
  Quad x = 0, y = 0, z = 0;
};
inline Q3 operator-(const Q3& a, const Q3& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline Q3 operator+(const Q3& a, const Q3& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline Q3 operator*(Quad s, const Q3& a) { return {s * a.x, s * a.y, s * a.z}; }
inline Quad dot(const Q3& a, const Q3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

/** \brief The closest point of triangle (a, b, c) to p (Ericson's region test). */
inline Q3 closestOnTriangle(const Q3& p, const Q3& a, const Q3& b, const Q3& c) {
  const Q3 ab = b - a, ac = c - a, ap = p - a;
  const Quad d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Q3 bp = p - b;
  const Quad d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const Quad vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + (d1 / (d1 - d3)) * ab;
  const Q3 cp = p - c;
  const Quad d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const Quad vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + (d2 / (d2 - d6)) * ac;
  const Quad va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return b + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b);
  const Quad denom = 1 / (va + vb + vc);
  return a + (vb * denom) * ab + (vc * denom) * ac;
}

/** \brief A triangle soup of the file's doubles, with the exact affine map the loader was asked for. */
struct QuadMesh {
  std::vector<std::array<double, 3>> vertices;  ///< the file's numbers
  std::vector<std::array<std::uint32_t, 3>> triangles;
  Quad scale = 1;                               ///< model = file * scale + shift, exactly
  Q3 shift;

  Q3 model(std::uint32_t v) const {
    const auto& f = vertices[v];
    return {Quad(f[0]) * scale + shift.x, Quad(f[1]) * scale + shift.y, Quad(f[2]) * scale + shift.z};
  }
};

/** \brief The nearest distance and the closest points within a relative tie margin of it. */
struct QuadAnswer {
  long double distance = std::numeric_limits<long double>::infinity();
  std::vector<std::array<long double, 3>> points;  ///< closest points of the (near-)tied triangles
};

/**
 * \brief Nearest distance from p (model frame) to the mesh, in quad precision. The double prefilter keeps the
 * triangles whose double-precision distance is within `slack` of the best one (slack must exceed the prefilter's
 * rounding: a few units in the last place of the model coordinates); the quad pass decides among them.
 */
inline QuadAnswer quadNearest(const QuadMesh& mesh, const std::vector<std::array<double, 3>>& modelDoubles,
                              const std::array<double, 3>& p, double slack) {
  // Prefilter in double on the model coordinates (rounded), squared distances to the triangle's box.
  const std::size_t n = mesh.triangles.size();
  std::vector<double> lower(n);
  double bestUpper = std::numeric_limits<double>::infinity();
  for (std::size_t t = 0; t < n; ++t) {
    double lo2 = 0.0, far2 = 0.0;
    for (int k = 0; k < 3; ++k) {
      const double a = modelDoubles[mesh.triangles[t][0]][k], b = modelDoubles[mesh.triangles[t][1]][k],
                   c = modelDoubles[mesh.triangles[t][2]][k];
      const double lo = std::min({a, b, c}), hi = std::max({a, b, c});
      const double gap = p[k] < lo ? lo - p[k] : (p[k] > hi ? p[k] - hi : 0.0);
      lo2 += gap * gap;
      const double spread = std::max(std::abs(p[k] - lo), std::abs(p[k] - hi));
      far2 += spread * spread;
    }
    lower[t] = std::sqrt(lo2);
    bestUpper = std::min(bestUpper, std::sqrt(far2));
  }
  const Q3 q{Quad(p[0]), Quad(p[1]), Quad(p[2])};
  QuadAnswer answer;
  std::vector<std::pair<Quad, Q3>> found;
  Quad best2 = std::numeric_limits<double>::infinity();
  for (std::size_t t = 0; t < n; ++t) {
    if (lower[t] > bestUpper + slack) continue;
    const Q3 c = closestOnTriangle(q, mesh.model(mesh.triangles[t][0]), mesh.model(mesh.triangles[t][1]),
                                   mesh.model(mesh.triangles[t][2]));
    const Q3 d = q - c;
    const Quad d2 = dot(d, d);
    found.emplace_back(d2, c);
    best2 = std::min(best2, d2);
  }
  answer.distance = std::sqrt(static_cast<long double>(best2));
  for (const auto& f : found)
    if (f.first <= best2 * Quad(1.0 + 1e-9))
      answer.points.push_back({static_cast<long double>(f.second.x), static_cast<long double>(f.second.y),
                               static_cast<long double>(f.second.z)});
  return answer;
}

}  // namespace clod_test
