#include "polygon_soup.h"

#include <cmath>
#include <cstring>
#include <limits>
#include <unordered_map>

namespace clod_haptics {
namespace detail {

std::size_t PositionHash::operator()(const Vec3& v) const {
  std::size_t h = 1469598103934665603ull;
  for (int k = 0; k < 3; ++k) {
    double x = v[k] == 0.0 ? 0.0 : v[k];  // +0 and -0 are one position
    std::uint64_t bits;
    std::memcpy(&bits, &x, sizeof bits);
    h = (h ^ bits) * 1099511628211ull;
  }
  return h;
}

namespace {

constexpr std::uint32_t kUnset = std::numeric_limits<std::uint32_t>::max();

// Joins identical positions: each file index gets the id of the first vertex at its position.
class VertexJoiner {
 public:
  VertexJoiner(const std::vector<Vec3>& positions, std::vector<Vec3>& vertices)
      : positions_(positions), vertices_(vertices), ids_(positions.size(), kUnset) {
    byPosition_.reserve(positions.size());
  }
  std::uint32_t id(std::uint32_t index) {
    std::uint32_t& id = ids_[index];
    if (id == kUnset) {
      const auto it = byPosition_.emplace(positions_[index], static_cast<std::uint32_t>(vertices_.size()));
      if (it.second) vertices_.push_back(positions_[index]);
      id = it.first->second;
    }
    return id;
  }

 private:
  const std::vector<Vec3>& positions_;
  std::vector<Vec3>& vertices_;
  std::vector<std::uint32_t> ids_;
  std::unordered_map<Vec3, std::uint32_t, PositionHash> byPosition_;
};

Vec3 unit(const Vec3& v) { return v / v.norm(); }  // NaN for a zero vector, as assimp's Normalize

// The corner a quad is split from: its concave corner if it has one (the angles beside the diagonal add up to
// more than pi), else corner 0. The rule of assimp's triangulation, so quads split as they did.
int quadStart(const std::vector<Vec3>& p, const std::uint32_t* q) {
  for (int i = 0; i < 4; ++i) {
    const Vec3& v = p[q[i]];
    const Vec3 left = unit(p[q[(i + 3) % 4]] - v), diag = unit(p[q[(i + 2) % 4]] - v),
               right = unit(p[q[(i + 1) % 4]] - v);
    if (std::acos(left.dot(diag)) + std::acos(right.dot(diag)) > M_PI) return i;
  }
  return 0;
}

// Polygons of more corners than this keep the fan from corner 0, whatever their shape. Ear clipping costs
// O(n^2) below (every clip re-tests two corners against all remaining ones): about 1e6 steps at 1024 corners,
// but 1e12 for the single million-corner polygon a fuzzed or hostile file can hold, a load that never ends.
constexpr std::uint32_t kMaxEarClipCorners = 1024;

// Ear clipping of one polygon of 5 or more corners in its plane, so that a non-convex polygon (an L, an arrow,
// a star) becomes triangles inside its outline, as the file describes it; a fan from corner 0 covers area
// outside the outline as soon as a corner next to corner 0 is reflex.
//
// The plane is the Newell normal's: the corners are projected onto the two axes other than its dominant
// component, one of them mirrored when that component is negative, so the polygon turns counter-clockwise in
// 2D and every triangle emitted in ring order keeps the polygon's winding. A corner is an ear when it turns
// counter-clockwise (convexity > 0) and no other remaining corner lies inside or on its triangle (corners at
// the position of one of the triangle's own are ignored, as a polygon touching itself there has them).
// Ears are flagged once, and after each clip only the two neighbours are re-tested (Eberly, "Triangulation by
// Ear Clipping"): in a simple polygon no other corner changes. In a self-intersecting or self-touching one a
// flag can go stale, hiding an ear but never inventing one (a clip takes a corner away from every other
// corner's triangle, it never adds one).
// Fallbacks, so that any input ends after n - 3 clips:
//  - no flagged ear left: all corners are re-tested, once per polygon (again at every such step would be
//    O(n^3) for a polygon with no ears at all, such as corners on a line);
//  - still none (degenerate or self-intersecting polygon): the corner of largest convexity is clipped anyway,
//    the largest triangle turning the polygon's way (zero area for corners on a line);
//  - zero or non-finite Newell normal (no plane: corners on a line, a figure eight whose loops cancel): the
//    whole polygon is fanned from corner 0, as before.
// The buffers are members, reused across polygons: a file can hold millions of small ones.
class EarClipper {
 public:
  // Calls emit(i, j, k) with polygon corner numbers (0 to n - 1) for the n - 2 triangles, or returns false
  // (and emits nothing) when the polygon has no plane.
  template <class Emit>
  bool triangulate(const std::vector<Vec3>& positions, const std::uint32_t* corners, std::uint32_t n, Emit&& emit) {
    if (!project(positions, corners, n)) return false;
    prev_.resize(n);
    next_.resize(n);
    ear_.resize(n);
    for (std::uint32_t i = 0; i < n; ++i) {
      prev_[i] = i == 0 ? n - 1 : i - 1;
      next_[i] = i + 1 == n ? 0 : i + 1;
    }
    left_ = n;
    cursor_ = 0;
    retested_ = false;
    flagEars();
    while (left_ > 3) clip(cornerToClip(), emit);
    emit(prev_[cursor_], cursor_, next_[cursor_]);
    return true;
  }

 private:
  // Fills u_, v_ with the corners in the Newell plane, counter-clockwise; false for a zero or non-finite normal.
  bool project(const std::vector<Vec3>& positions, const std::uint32_t* corners, std::uint32_t n) {
    const Vec3& origin = positions[corners[0]];  // relative coordinates: a polygon far from zero keeps its digits
    Vec3 normal = Vec3::Zero();
    for (std::uint32_t i = 0; i < n; ++i) {
      const Vec3 a = positions[corners[i]] - origin, b = positions[corners[i + 1 == n ? 0 : i + 1]] - origin;
      normal +=
          Vec3((a.y() - b.y()) * (a.z() + b.z()), (a.z() - b.z()) * (a.x() + b.x()), (a.x() - b.x()) * (a.y() + b.y()));
    }
    if (!normal.allFinite()) return false;
    int k = 0;
    normal.cwiseAbs().maxCoeff(&k);
    if (normal[k] == 0.0) return false;
    // Newell's component k is twice the signed area in the axes (k + 1, k + 2); mirroring v makes it positive.
    const int ax = (k + 1) % 3, ay = (k + 2) % 3;
    const double mirror = normal[k] > 0.0 ? 1.0 : -1.0;
    u_.resize(n);
    v_.resize(n);
    for (std::uint32_t i = 0; i < n; ++i) {
      const Vec3 d = positions[corners[i]] - origin;
      u_[i] = d[ax];
      v_[i] = mirror * d[ay];
    }
    return true;
  }

  // Twice the signed area of triangle (a, b, c): positive when it turns counter-clockwise, as the polygon.
  double cross(std::uint32_t a, std::uint32_t b, std::uint32_t c) const {
    return (u_[b] - u_[a]) * (v_[c] - v_[a]) - (v_[b] - v_[a]) * (u_[c] - u_[a]);
  }
  double convexity(std::uint32_t i) const { return cross(prev_[i], i, next_[i]); }

  bool samePosition(std::uint32_t a, std::uint32_t b) const { return u_[a] == u_[b] && v_[a] == v_[b]; }

  // Corner q lies inside or on the counter-clockwise triangle (a, b, c), and not at one of its corners.
  bool inTriangle(std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint32_t q) const {
    if (samePosition(q, a) || samePosition(q, b) || samePosition(q, c)) return false;
    return cross(a, b, q) >= 0.0 && cross(b, c, q) >= 0.0 && cross(c, a, q) >= 0.0;
  }

  bool isEar(std::uint32_t i) const {
    const std::uint32_t a = prev_[i], c = next_[i];
    if (!(cross(a, i, c) > 0.0)) return false;  // reflex, straight, or NaN
    for (std::uint32_t q = next_[c]; q != a; q = next_[q])
      if (inTriangle(a, i, c, q)) return false;
    return true;
  }

  void flagEars() {
    std::uint32_t i = cursor_;
    for (std::uint32_t k = 0; k < left_; ++k, i = next_[i]) ear_[i] = isEar(i);
  }

  // The first flagged ear from the cursor on, else (after one re-test) the corner of largest convexity.
  std::uint32_t cornerToClip() {
    for (int pass = 0; pass < 2; ++pass) {
      std::uint32_t i = cursor_;
      for (std::uint32_t k = 0; k < left_; ++k, i = next_[i])
        if (ear_[i]) return i;
      if (retested_) break;
      retested_ = true;
      flagEars();
    }
    std::uint32_t best = cursor_, i = cursor_;
    double bestConvexity = -std::numeric_limits<double>::infinity();
    for (std::uint32_t k = 0; k < left_; ++k, i = next_[i]) {
      const double c = convexity(i);
      if (c > bestConvexity) best = i, bestConvexity = c;  // a NaN never wins: the cursor stays the default
    }
    return best;
  }

  template <class Emit>
  void clip(std::uint32_t i, Emit& emit) {
    const std::uint32_t a = prev_[i], c = next_[i];
    emit(a, i, c);
    next_[a] = c;
    prev_[c] = a;
    --left_;
    cursor_ = c;
    ear_[a] = isEar(a);
    ear_[c] = isEar(c);
  }

  std::vector<double> u_, v_;               // corners in the plane, counter-clockwise
  std::vector<std::uint32_t> prev_, next_;  // the ring of corners not clipped yet
  std::vector<char> ear_;                   // per corner: an ear when last tested
  std::uint32_t left_ = 0, cursor_ = 0;     // corners in the ring; where the search for the next ear starts
  bool retested_ = false;                   // all corners were re-tested after a miss (once per polygon)
};

}  // namespace

void triangulateSoup(const PolygonSoup& soup, std::vector<Vec3>& vertices, std::vector<Triangle>& triangles) {
  VertexJoiner joiner(soup.positions, vertices);
  if (soup.fileOrder)
    for (std::size_t i = 0; i < soup.positions.size(); ++i) joiner.id(static_cast<std::uint32_t>(i));
  else
    for (std::uint32_t c : soup.corners) joiner.id(c);
  triangles.reserve(soup.corners.size() - 2 * soup.ends.size());
  EarClipper clipper;
  std::size_t start = 0;
  for (std::size_t end : soup.ends) {
    const std::uint32_t* c = soup.corners.data() + start;
    const std::size_t n = end - start;
    start = end;
    const auto emit = [&](std::size_t i, std::size_t j, std::size_t k) {
      triangles.push_back({joiner.id(c[i]), joiner.id(c[j]), joiner.id(c[k])});
    };
    if (n >= 5 && n <= kMaxEarClipCorners &&
        clipper.triangulate(soup.positions, c, static_cast<std::uint32_t>(n), emit))
      continue;
    // Triangles and quads (from quadStart, assimp's rule), and the polygons ear clipping leaves: a fan.
    const std::size_t first = n == 4 ? static_cast<std::size_t>(quadStart(soup.positions, c)) : 0;
    for (std::size_t k = 1; k + 1 < n; ++k) emit(first, (first + k) % n, (first + k + 1) % n);
  }
}

}  // namespace detail
}  // namespace clod_haptics
