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

}  // namespace

void triangulateSoup(const PolygonSoup& soup, std::vector<Vec3>& vertices, std::vector<Triangle>& triangles) {
  VertexJoiner joiner(soup.positions, vertices);
  if (soup.fileOrder)
    for (std::size_t i = 0; i < soup.positions.size(); ++i) joiner.id(static_cast<std::uint32_t>(i));
  else
    for (std::uint32_t c : soup.corners) joiner.id(c);
  triangles.reserve(soup.corners.size() - 2 * soup.ends.size());
  std::size_t start = 0;
  for (std::size_t end : soup.ends) {
    const std::uint32_t* c = soup.corners.data() + start;
    const std::size_t n = end - start;
    const std::size_t first = n == 4 ? static_cast<std::size_t>(quadStart(soup.positions, c)) : 0;
    for (std::size_t k = 1; k + 1 < n; ++k)
      triangles.push_back({joiner.id(c[first]), joiner.id(c[(first + k) % n]), joiner.id(c[(first + k + 1) % n])});
    start = end;
  }
}

}  // namespace detail
}  // namespace clod_haptics
