#include "tightness.h"

#include <algorithm>
#include <cmath>
#include <queue>

namespace clod_bench {

bool triangleBoxOverlap(const Vec3& centre, double half, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 v[3] = {a - centre, b - centre, c - centre};
  const double eps = 1e-12 * std::max(1.0, half);
  // Box axes.
  for (int k = 0; k < 3; ++k) {
    const double lo = std::min({v[0][k], v[1][k], v[2][k]}), hi = std::max({v[0][k], v[1][k], v[2][k]});
    if (lo > half + eps || hi < -half - eps) return false;
  }
  const Vec3 e[3] = {v[1] - v[0], v[2] - v[1], v[0] - v[2]};
  auto separated = [&](const Vec3& axis) {
    if (axis.squaredNorm() == 0.0) return false;
    const double p0 = axis.dot(v[0]), p1 = axis.dot(v[1]), p2 = axis.dot(v[2]);
    const double rad = half * (std::abs(axis.x()) + std::abs(axis.y()) + std::abs(axis.z()));
    const double tol = eps * axis.lpNorm<1>();
    return std::min({p0, p1, p2}) > rad + tol || std::max({p0, p1, p2}) < -rad - tol;
  };
  if (separated(e[0].cross(e[1]))) return false;  // triangle plane
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k)
      if (separated(e[i].cross(Vec3::Unit(k)))) return false;
  return true;
}

SphereList octreeSpheres(const TriangleMesh& mesh, std::size_t target, int& maxDepth) {
  struct Cell {
    Vec3 centre;
    double half;
    int depth;
    std::vector<std::uint32_t> tris;
  };
  auto larger = [](const Cell* x, const Cell* y) {  // largest first, then the most triangles
    return x->depth != y->depth ? x->depth > y->depth : x->tris.size() < y->tris.size();
  };
  std::priority_queue<Cell*, std::vector<Cell*>, decltype(larger)> open(larger);
  std::vector<std::unique_ptr<Cell>> cells;
  const Eigen::AlignedBox3d box = mesh.bounds();
  auto root = std::make_unique<Cell>();
  root->centre = box.center();
  root->half = 0.5 * box.sizes().maxCoeff() * (1.0 + 1e-9);
  root->depth = 0;
  root->tris.resize(mesh.size());
  for (std::size_t t = 0; t < mesh.size(); ++t) root->tris[t] = static_cast<std::uint32_t>(t);
  open.push(root.get());
  cells.push_back(std::move(root));
  std::size_t leaves = 1;
  std::vector<Cell*> done;
  while (leaves < target && !open.empty()) {
    Cell* cell = open.top();
    open.pop();
    --leaves;
    for (int o = 0; o < 8; ++o) {
      auto child = std::make_unique<Cell>();
      child->half = 0.5 * cell->half;
      child->depth = cell->depth + 1;
      child->centre = cell->centre + child->half * Vec3(o & 1 ? 1 : -1, o & 2 ? 1 : -1, o & 4 ? 1 : -1);
      for (std::uint32_t t : cell->tris)
        if (triangleBoxOverlap(child->centre, child->half, mesh.vertex(t, 0), mesh.vertex(t, 1), mesh.vertex(t, 2)))
          child->tris.push_back(t);
      if (child->tris.empty()) continue;
      ++leaves;
      open.push(child.get());
      cells.push_back(std::move(child));
    }
    cell->tris.clear();
    cell->tris.shrink_to_fit();
  }
  SphereList out;
  maxDepth = 0;
  while (!open.empty()) {
    const Cell* cell = open.top();
    open.pop();
    out.centres.push_back(cell->centre);
    out.radii.push_back(cell->half * std::sqrt(3.0));
    maxDepth = std::max(maxDepth, cell->depth);
  }
  return out;
}

SphereGrid::SphereGrid(const SphereList& spheres) : s_(spheres) {
  box_.setEmpty();
  double mean = 0.0;
  for (std::size_t i = 0; i < s_.centres.size(); ++i) {
    box_.extend(s_.centres[i] - Vec3::Constant(s_.radii[i]));
    box_.extend(s_.centres[i] + Vec3::Constant(s_.radii[i]));
    mean += s_.radii[i];
  }
  if (s_.centres.empty()) return;
  mean /= s_.centres.size();
  const double cell = std::max(2.0 * mean, box_.sizes().maxCoeff() / 128.0);
  inv_ = 1.0 / cell;
  for (int k = 0; k < 3; ++k) n_[k] = std::max(1, static_cast<int>(std::ceil(box_.sizes()[k] * inv_)));
  const std::size_t cells = static_cast<std::size_t>(n_[0]) * n_[1] * n_[2];
  std::vector<std::uint32_t> count(cells + 1, 0);
  for (int pass = 0; pass < 2; ++pass) {
    for (std::size_t i = 0; i < s_.centres.size(); ++i) {
      int a[3], b[3];
      for (int k = 0; k < 3; ++k) {
        a[k] = std::clamp(static_cast<int>(std::floor((s_.centres[i][k] - s_.radii[i] - box_.min()[k]) * inv_)), 0, n_[k] - 1);
        b[k] = std::clamp(static_cast<int>(std::floor((s_.centres[i][k] + s_.radii[i] - box_.min()[k]) * inv_)), 0, n_[k] - 1);
      }
      for (int z = a[2]; z <= b[2]; ++z)
        for (int y = a[1]; y <= b[1]; ++y)
          for (int x = a[0]; x <= b[0]; ++x) {
            const std::size_t c = (static_cast<std::size_t>(z) * n_[1] + y) * n_[0] + x;
            if (pass == 0)
              ++count[c + 1];
            else
              items_[start_[c] + count[c]++] = static_cast<std::uint32_t>(i);
          }
    }
    if (pass == 0) {
      for (std::size_t c = 0; c < cells; ++c) count[c + 1] += count[c];
      start_ = count;
      items_.resize(count[cells]);
      std::fill(count.begin(), count.end(), 0);
    }
  }
}

bool SphereGrid::contains(const Vec3& p) const { return visit(p, true) > 0; }

std::size_t SphereGrid::count(const Vec3& p) const { return visit(p, false); }

std::size_t SphereGrid::visit(const Vec3& p, bool firstOnly) const {
  if (s_.centres.empty()) return 0;
  int c[3];
  for (int k = 0; k < 3; ++k) {
    const double f = std::floor((p[k] - box_.min()[k]) * inv_);
    if (f < -1 || f > n_[k]) return 0;
    c[k] = std::clamp(static_cast<int>(f), 0, n_[k] - 1);  // boundary points land in the edge cell
  }
  const std::size_t cell = (static_cast<std::size_t>(c[2]) * n_[1] + c[1]) * n_[0] + c[0];
  std::size_t n = 0;
  for (std::uint32_t i = start_[cell]; i < start_[cell + 1]; ++i) {
    const std::uint32_t s = items_[i];
    const double r = s_.radii[s];
    if ((p - s_.centres[s]).squaredNorm() <= r * r * (1.0 + 1e-12)) {
      ++n;
      if (firstOnly) return n;
    }
  }
  return n;
}

bool InsideTest::inside(const Vec3& p) const {
  static const Vec3 dirs[3] = {Vec3(0.5773, 0.5774, 0.5772).normalized(), Vec3(-0.31, 0.8127, -0.4931).normalized(),
                               Vec3(0.7071, -0.1233, -0.6963).normalized()};
  int votes = 0;
  for (const Vec3& d : dirs) {
    // Winding number along the ray: +1 leaving through a face (normal along the ray), -1 entering.
    // Non-zero is inside (union of overlapping parts; a part wound inside out still counts).
    int winding = 0;
    double tMax = 1e30;  // never lowered: every crossing counts
    bvh_.forEachRayHit(p, d, tMax, [&](std::uint32_t t, double) {
      const double c = mesh_.normals[t].dot(d);
      winding += c > 0 ? 1 : c < 0 ? -1 : 0;
    });
    votes += winding != 0;
  }
  return votes >= 2;
}

}  // namespace clod_bench
