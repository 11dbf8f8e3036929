#include "bench_common.h"

#include <x86intrin.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>
#include <thread>
#include <unordered_map>

#include "clod_haptics/core/geometry.h"

namespace clod_bench {

using clod_haptics::closestPointOnTriangle;
using clod_haptics::finishContact;

// ---------------------------------------------------------------------------------------------
PrunedReference::PrunedReference(const TriangleMesh& mesh, double r) : mesh_(mesh), r_(r) {
  const Eigen::AlignedBox3d box = mesh.bounds();
  const double pad = r * (1.0 + 1e-9) + 1e-12;
  lo_ = box.min() - Vec3::Constant(pad);
  const Vec3 size = box.sizes() + Vec3::Constant(2 * pad);
  // Cells of about 2r, at most 160 per axis (4M cells) and at least one.
  double cell = std::max(2.0 * r, size.maxCoeff() / 160.0);
  inv_ = 1.0 / cell;
  for (int k = 0; k < 3; ++k) n_[k] = std::max(1, static_cast<int>(std::ceil(size[k] * inv_)));
  const std::size_t cells = static_cast<std::size_t>(n_[0]) * n_[1] * n_[2];
  boxes_.resize(6 * mesh.size());
  std::vector<std::uint32_t> count(cells + 1, 0);
  auto range = [&](std::size_t t, int* a, int* b) {
    Vec3 tlo = mesh.vertex(t, 0).cwiseMin(mesh.vertex(t, 1)).cwiseMin(mesh.vertex(t, 2));
    Vec3 thi = mesh.vertex(t, 0).cwiseMax(mesh.vertex(t, 1)).cwiseMax(mesh.vertex(t, 2));
    for (int k = 0; k < 3; ++k) {
      boxes_[6 * t + k] = tlo[k];
      boxes_[6 * t + 3 + k] = thi[k];
      a[k] = std::clamp(static_cast<int>(std::floor((tlo[k] - pad - lo_[k]) * inv_)), 0, n_[k] - 1);
      b[k] = std::clamp(static_cast<int>(std::floor((thi[k] + pad - lo_[k]) * inv_)), 0, n_[k] - 1);
    }
  };
  for (int pass = 0; pass < 2; ++pass) {
    for (std::size_t t = 0; t < mesh.size(); ++t) {
      int a[3], b[3];
      range(t, a, b);
      for (int z = a[2]; z <= b[2]; ++z)
        for (int y = a[1]; y <= b[1]; ++y)
          for (int x = a[0]; x <= b[0]; ++x) {
            const std::size_t c = (static_cast<std::size_t>(z) * n_[1] + y) * n_[0] + x;
            if (pass == 0)
              ++count[c + 1];
            else
              items_[start_[c] + count[c]++] = static_cast<std::uint32_t>(t);
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

ContactResult PrunedReference::query(const Vec3& p) const {
  ContactResult out;
  if (!p.allFinite()) return out;
  int c[3];
  for (int k = 0; k < 3; ++k) {
    const double f = std::floor((p[k] - lo_[k]) * inv_);
    if (f < 0 || f >= n_[k]) return out;  // farther than r from every triangle's box
    c[k] = static_cast<int>(f);
  }
  const std::size_t cell = (static_cast<std::size_t>(c[2]) * n_[1] + c[1]) * n_[0] + c[0];
  const double r2 = r_ * r_;
  double best = std::numeric_limits<double>::infinity();
  std::uint32_t bestTri = 0;
  Vec3 bestPoint = Vec3::Zero();
  for (std::uint32_t i = start_[cell]; i < start_[cell + 1]; ++i) {
    const std::uint32_t t = items_[i];
    const double* b = &boxes_[6 * t];
    double d2 = 0.0;
    for (int k = 0; k < 3; ++k) {
      const double e = std::max({b[k] - p[k], p[k] - b[3 + k], 0.0});
      d2 += e * e;
    }
    if (d2 > r2) continue;  // the whole triangle is farther than r: cannot be a contact
    const Vec3 q = closestPointOnTriangle(p, mesh_.vertex(t, 0), mesh_.vertex(t, 1), mesh_.vertex(t, 2));
    const double dq = (p - q).squaredNorm();
    if (dq < best) {  // ascending index order: ties keep the lowest index, as bruteForceQuery
      best = dq;
      bestTri = t;
      bestPoint = q;
    }
  }
  if (!(best <= r2)) return out;
  out.contact = true;
  out.point = bestPoint;
  out.distance = std::sqrt(best);
  out.triangle = static_cast<std::int32_t>(bestTri);
  finishContact(mesh_, p, r_, out);  // side, signed depth and normal: the rule bruteForceQuery and the detector share
  return out;
}

std::vector<ContactResult> PrunedReference::queryAll(const std::vector<Vec3>& probes, unsigned threads) const {
  std::vector<ContactResult> out(probes.size());
  threads = std::max(1u, threads);
  std::vector<std::thread> pool;
  for (unsigned w = 0; w < threads; ++w)
    pool.emplace_back([&, w] {
      for (std::size_t i = w; i < probes.size(); i += threads) out[i] = query(probes[i]);
    });
  for (auto& t : pool) t.join();
  return out;
}

// ---------------------------------------------------------------------------------------------
double Clock::nsPerTick = 1.0;
double Clock::overheadTicks = 0.0;

void Clock::calibrate() {
  using clk = std::chrono::steady_clock;
  const auto t0 = clk::now();
  const std::uint64_t c0 = __rdtsc();
  while (clk::now() - t0 < std::chrono::milliseconds(100)) {
  }
  const auto t1 = clk::now();
  const std::uint64_t c1 = __rdtsc();
  nsPerTick = std::chrono::duration<double, std::nano>(t1 - t0).count() / static_cast<double>(c1 - c0);
  std::vector<std::uint64_t> empty(10001);
  for (auto& e : empty) {
    _mm_lfence();
    const std::uint64_t a = __rdtsc();
    _mm_lfence();
    _mm_lfence();
    const std::uint64_t b = __rdtsc();
    _mm_lfence();
    e = b - a;
  }
  std::nth_element(empty.begin(), empty.begin() + empty.size() / 2, empty.end());
  overheadTicks = static_cast<double>(empty[empty.size() / 2]);
}

void Timing::summarise() {
  if (ns.empty()) return;
  std::vector<float> s = ns;
  std::sort(s.begin(), s.end());
  auto at = [&](double q) { return static_cast<double>(s[std::min(s.size() - 1, static_cast<std::size_t>(q * s.size()))]); };
  median = at(0.5);
  p10 = at(0.1);
  p90 = at(0.9);
  p99 = at(0.99);
  double sum = 0;
  for (float v : s) sum += v;
  mean = sum / s.size();
  const std::size_t keep = std::max<std::size_t>(1, static_cast<std::size_t>(0.99 * s.size()));
  double kept = 0;
  for (std::size_t i = 0; i < keep; ++i) kept += s[i];
  trimmedMean = kept / keep;
}

// ---------------------------------------------------------------------------------------------
TriangleMesh subdivide(const TriangleMesh& mesh) {
  std::vector<Vec3> vertices = mesh.vertices;
  std::vector<clod_haptics::Triangle> triangles;
  triangles.reserve(4 * mesh.size());
  std::unordered_map<std::uint64_t, std::uint32_t> midpoints;
  midpoints.reserve(3 * mesh.size());
  auto mid = [&](std::uint32_t a, std::uint32_t b) {
    const std::uint64_t key = a < b ? (std::uint64_t(a) << 32 | b) : (std::uint64_t(b) << 32 | a);
    auto it = midpoints.find(key);
    if (it != midpoints.end()) return it->second;
    const std::uint32_t index = static_cast<std::uint32_t>(vertices.size());
    vertices.push_back(0.5 * (vertices[a] + vertices[b]));
    midpoints.emplace(key, index);
    return index;
  };
  for (const auto& t : mesh.triangles) {
    const std::uint32_t ab = mid(t[0], t[1]), bc = mid(t[1], t[2]), ca = mid(t[2], t[0]);
    triangles.push_back({t[0], ab, ca});
    triangles.push_back({ab, t[1], bc});
    triangles.push_back({ca, bc, t[2]});
    triangles.push_back({ab, bc, ca});
  }
  TriangleMesh out = clod_haptics::makeMesh(std::move(vertices), std::move(triangles), mesh.name);
  out.scale = mesh.scale;
  out.offset = mesh.offset;
  return out;
}

// ---------------------------------------------------------------------------------------------
namespace {
// Turns every triangle outward, seen from `centre` (right for a surface star-shaped around it).
void windOutward(const std::vector<Vec3>& vertices, const Vec3& centre, std::vector<clod_haptics::Triangle>& triangles) {
  for (auto& t : triangles) {
    const Vec3 &a = vertices[t[0]], &b = vertices[t[1]], &c = vertices[t[2]];
    if ((b - a).cross(c - a).dot((a + b + c) / 3.0 - centre) < 0.0) std::swap(t[1], t[2]);
  }
}
}  // namespace

TriangleMesh cubeEllipsoid(const Vec3& axes, const Vec3& centre, int m, const std::string& name) {
  std::vector<Vec3> vertices;
  std::vector<clod_haptics::Triangle> triangles;
  std::map<std::array<int, 3>, std::uint32_t> index;  // lattice point on the cube's surface -> vertex
  auto vertex = [&](const std::array<int, 3>& key) {
    const auto it = index.find(key);
    if (it != index.end()) return it->second;
    Vec3 c;
    for (int k = 0; k < 3; ++k) c[k] = std::tan(M_PI / 4.0 * (2.0 * key[k] / m - 1.0));
    vertices.push_back(centre + axes.cwiseProduct(c.normalized()));
    return index[key] = static_cast<std::uint32_t>(vertices.size() - 1);
  };
  for (int a = 0; a < 3; ++a)
    for (int side : {0, m})
      for (int u = 0; u < m; ++u)
        for (int w = 0; w < m; ++w) {
          std::array<std::uint32_t, 4> q;  // the cell's corners, in order around it
          const int du[4] = {0, 1, 1, 0}, dw[4] = {0, 0, 1, 1};
          for (int k = 0; k < 4; ++k) {
            std::array<int, 3> key;
            key[a] = side;
            key[(a + 1) % 3] = u + du[k];
            key[(a + 2) % 3] = w + dw[k];
            q[k] = vertex(key);
          }
          triangles.push_back({q[0], q[1], q[2]});
          triangles.push_back({q[0], q[2], q[3]});
        }
  windOutward(vertices, centre, triangles);
  return clod_haptics::makeMesh(std::move(vertices), std::move(triangles), name);
}

TriangleMesh ellipsoidWithEdge(const Vec3& axes, const Vec3& centre, double edge, const std::string& name) {
  const double trial = meanEdge(cubeEllipsoid(axes, centre, 16, name));
  const int m = std::max(2, static_cast<int>(std::lround(16.0 * trial / edge)));
  return cubeEllipsoid(axes, centre, m, name);
}

TriangleMesh refineHalf(const TriangleMesh& mesh, int times, const std::string& name) {
  if (!mesh.origin.isZero(0.0)) throw std::runtime_error("refineHalf: a mesh with a local origin");
  const double middle = mesh.bounds().center().x();
  std::vector<clod_haptics::Triangle> coarse, fine;
  for (std::size_t t = 0; t < mesh.size(); ++t) (mesh.centroid(t).x() > middle ? fine : coarse).push_back(mesh.triangles[t]);
  TriangleMesh part = clod_haptics::makeMesh(mesh.vertices, std::move(fine), name);
  for (int i = 0; i < times; ++i) part = subdivide(part);  // keeps the vertex array as its prefix
  std::vector<clod_haptics::Triangle> all = std::move(coarse);
  all.insert(all.end(), part.triangles.begin(), part.triangles.end());
  return clod_haptics::makeMesh(std::move(part.vertices), std::move(all), name);
}

TriangleMesh slicedCylinder(const Vec3& centre, double radius, double height, int slices, const std::string& name) {
  std::vector<Vec3> vertices;
  for (int i = 0; i < slices; ++i) {
    const double a = 2.0 * M_PI * i / slices;
    vertices.push_back(centre + Vec3(radius * std::cos(a), radius * std::sin(a), -0.5 * height));
    vertices.push_back(centre + Vec3(radius * std::cos(a), radius * std::sin(a), 0.5 * height));
  }
  const std::uint32_t bottom = static_cast<std::uint32_t>(vertices.size());
  vertices.push_back(centre - Vec3(0, 0, 0.5 * height));
  vertices.push_back(centre + Vec3(0, 0, 0.5 * height));
  std::vector<clod_haptics::Triangle> triangles;
  for (int i = 0; i < slices; ++i) {
    const std::uint32_t b0 = 2 * i, t0 = b0 + 1, b1 = 2 * ((i + 1) % slices), t1 = b1 + 1;
    triangles.push_back({b0, b1, t1});
    triangles.push_back({b0, t1, t0});
    triangles.push_back({bottom, b1, b0});
    triangles.push_back({bottom + 1, t0, t1});
  }
  windOutward(vertices, centre, triangles);
  return clod_haptics::makeMesh(std::move(vertices), std::move(triangles), name);
}

double meanEdge(const TriangleMesh& mesh) {
  double sum = 0.0;
  for (std::size_t t = 0; t < mesh.size(); ++t)
    for (int k = 0; k < 3; ++k) sum += (mesh.vertex(t, k) - mesh.vertex(t, (k + 1) % 3)).norm();
  return mesh.size() ? sum / (3.0 * mesh.size()) : 0.0;
}

std::vector<double> aspectRatios(const TriangleMesh& mesh) {
  std::vector<double> out;
  out.reserve(mesh.size());
  for (std::size_t t = 0; t < mesh.size(); ++t) {
    const Vec3 &a = mesh.vertex(t, 0), &b = mesh.vertex(t, 1), &c = mesh.vertex(t, 2);
    const double longest2 = std::max({(b - a).squaredNorm(), (c - b).squaredNorm(), (a - c).squaredNorm()});
    const double twiceArea = (b - a).cross(c - a).norm();
    if (twiceArea > 0.0) out.push_back(longest2 / twiceArea);  // longest / (2 area / longest)
  }
  return out;
}

std::size_t openEdges(const TriangleMesh& mesh) {
  std::unordered_map<std::uint64_t, int> edges;
  edges.reserve(3 * mesh.size());
  for (const auto& t : mesh.triangles)
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = t[k], b = t[(k + 1) % 3];
      ++edges[a < b ? (std::uint64_t(a) << 32 | b) : (std::uint64_t(b) << 32 | a)];
    }
  std::size_t open = 0;
  for (const auto& e : edges) open += e.second != 2;
  return open;
}

double meshVolume(const TriangleMesh& mesh) {
  double v = 0.0;
  const Vec3 o = mesh.bounds().center();
  for (std::size_t t = 0; t < mesh.size(); ++t)
    v += (mesh.vertex(t, 0) - o).dot((mesh.vertex(t, 1) - o).cross(mesh.vertex(t, 2) - o)) / 6.0;
  return v;
}

std::vector<Vec3> placeOver(const std::vector<Vec3>& trajectory, const TriangleMesh& mesh) {
  if (trajectory.empty()) return {};
  Eigen::AlignedBox3d tb;
  for (const Vec3& p : trajectory) tb.extend(p);
  const Eigen::AlignedBox3d mb = mesh.bounds();
  double s = std::numeric_limits<double>::infinity();
  const double flat = 1e-9 * mb.sizes().maxCoeff();  // a planar mesh has no extent on one axis: skip it
  for (int k = 0; k < 3; ++k)
    if (tb.sizes()[k] > 0 && mb.sizes()[k] > flat) s = std::min(s, mb.sizes()[k] / tb.sizes()[k]);
  if (!std::isfinite(s)) s = 1.0;
  std::vector<Vec3> out;
  out.reserve(trajectory.size());
  for (const Vec3& p : trajectory) out.push_back(mb.center() + s * (p - tb.center()));
  return out;
}

// ---------------------------------------------------------------------------------------------
namespace {
std::size_t statusField(const char* field) {
  std::ifstream in("/proc/self/status");
  std::string line;
  const std::string key = field;
  while (std::getline(in, line))
    if (line.compare(0, key.size(), key) == 0) {
      std::istringstream s(line.substr(key.size() + 1));
      std::size_t kb = 0;
      s >> kb;
      return kb * 1024;
    }
  return 0;
}
}  // namespace

std::size_t peakRssBytes() { return statusField("VmHWM"); }
std::size_t currentRssBytes() { return statusField("VmRSS"); }
bool resetPeakRss() {
  std::ofstream out("/proc/self/clear_refs");
  if (!out) return false;
  out << "5";
  out.flush();
  return static_cast<bool>(out);
}

}  // namespace clod_bench
