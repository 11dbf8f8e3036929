#include "clod_haptics/core/bound_tree.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace clod_haptics {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr std::uint32_t kNoParent = std::numeric_limits<std::uint32_t>::max();

// A centre's coordinate for sorting: NaN (inactive) sorts as 0, anywhere will do.
inline double key(double v) { return std::isfinite(v) ? v : 0.0; }

}  // namespace

void BoundTree::build(const double* x, const double* y, const double* z, const double* radius, const double* grow,
                      std::size_t n) {
  nodes_.clear();
  order_.resize(n);
  std::iota(order_.begin(), order_.end(), 0u);
  leafOf_.assign(n, 0);
  if (n == 0) return;
  nodes_.reserve(2 * n);
  split(0, static_cast<std::uint32_t>(n), kNoParent, x, y, z);
  for (std::size_t i = nodes_.size(); i-- > 0;) {  // children after their parent: leaves, then up
    if (nodes_[i].count > 0)
      fitLeaf(static_cast<std::uint32_t>(i), x, y, z, radius, grow);
    else
      fitInner(static_cast<std::uint32_t>(i));
  }
}

std::uint32_t BoundTree::split(std::uint32_t begin, std::uint32_t end, std::uint32_t parent, const double* x,
                               const double* y, const double* z) {
  const auto index = static_cast<std::uint32_t>(nodes_.size());
  nodes_.push_back(Node{{0, 0, 0}, {0, 0, 0}, 0.0, begin, end - begin, parent});
  if (end - begin <= kLeaf) {
    for (std::uint32_t k = begin; k < end; ++k) leafOf_[order_[k]] = index;
    return index;
  }
  // The longest axis of the centres' extent, split at the median.
  const double* axes[3] = {x, y, z};
  double lo[3] = {kInf, kInf, kInf}, hi[3] = {-kInf, -kInf, -kInf};
  for (std::uint32_t k = begin; k < end; ++k)
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], key(axes[a][order_[k]]));
      hi[a] = std::max(hi[a], key(axes[a][order_[k]]));
    }
  int axis = 0;
  for (int a = 1; a < 3; ++a)
    if (hi[a] - lo[a] > hi[axis] - lo[axis]) axis = a;
  const std::uint32_t mid = begin + (end - begin) / 2;
  const double* along = axes[axis];
  std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end,
                   [along](std::uint32_t a, std::uint32_t b) { return key(along[a]) < key(along[b]); });
  nodes_[index].count = 0;
  split(begin, mid, index, x, y, z);  // the left child: index + 1
  const std::uint32_t right = split(mid, end, index, x, y, z);
  nodes_[index].first = right;
  return index;
}

void BoundTree::fitLeaf(std::uint32_t node, const double* x, const double* y, const double* z, const double* radius,
                        const double* grow) {
  Node& n = nodes_[node];
  for (int a = 0; a < 3; ++a) {
    n.lo[a] = kInf;
    n.hi[a] = -kInf;
  }
  n.grow = 0.0;
  for (std::uint32_t k = n.first; k < n.first + n.count; ++k) {
    const std::uint32_t i = order_[k];
    const double c[3] = {x[i], y[i], z[i]};
    if (!(std::isfinite(c[0]) && std::isfinite(c[1]) && std::isfinite(c[2]) && std::isfinite(radius[i]))) continue;
    for (int a = 0; a < 3; ++a) {
      // Widened for the rounding of c +- radius and of the caller's own test (relative to what it subtracts).
      const double pad = 1e-12 * (std::abs(c[a]) + radius[i]);
      n.lo[a] = std::min(n.lo[a], c[a] - radius[i] - pad);
      n.hi[a] = std::max(n.hi[a], c[a] + radius[i] + pad);
    }
    if (grow != nullptr) n.grow = std::max(n.grow, grow[i] * (1.0 + 1e-12));
  }
}

void BoundTree::fitInner(std::uint32_t node) {
  Node& n = nodes_[node];
  const Node& l = nodes_[node + 1];
  const Node& r = nodes_[n.first];
  for (int a = 0; a < 3; ++a) {
    n.lo[a] = std::min(l.lo[a], r.lo[a]);
    n.hi[a] = std::max(l.hi[a], r.hi[a]);
  }
  n.grow = std::max(l.grow, r.grow);
}

void BoundTree::update(std::uint32_t i, const double* x, const double* y, const double* z, const double* radius,
                       const double* grow) {
  if (i >= leafOf_.size()) return;
  std::uint32_t node = leafOf_[i];
  fitLeaf(node, x, y, z, radius, grow);
  for (node = nodes_[node].parent; node != kNoParent; node = nodes_[node].parent) fitInner(node);
}

std::size_t BoundTree::candidates(const Vec3& p, double r, bool grown, std::uint32_t* out,
                                  std::size_t capacity) const noexcept {
  if (nodes_.empty()) return 0;
  std::size_t found = 0;
  std::uint32_t stack[64];  // depth-first, a median split: depth log2(n / kLeaf) + 1, far below 64
  int top = 0;
  stack[top++] = 0;
  const double px = p.x(), py = p.y(), pz = p.z();
  while (top > 0) {
    const std::uint32_t index = stack[--top];
    const Node& n = nodes_[index];
    const double reach = r + (grown ? n.grow : 0.0);
    // The gap on each axis (0 inside); an empty box gives +inf, never within reach.
    const double dx = std::max(0.0, std::max(n.lo[0] - px, px - n.hi[0]));
    const double dy = std::max(0.0, std::max(n.lo[1] - py, py - n.hi[1]));
    const double dz = std::max(0.0, std::max(n.lo[2] - pz, pz - n.hi[2]));
    if (!(dx * dx + dy * dy + dz * dz <= reach * reach * (1.0 + 1e-12))) continue;
    if (n.count > 0) {
      for (std::uint32_t k = n.first; k < n.first + n.count; ++k) {
        if (found < capacity) out[found] = order_[k];
        ++found;
      }
      continue;
    }
    stack[top++] = n.first;
    stack[top++] = index + 1;
  }
  return found;
}

}  // namespace clod_haptics
