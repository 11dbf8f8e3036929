#include "clod_haptics/core/sphere_placement.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>

#include "clod_haptics/core/triangle_bvh.h"
#include "parallel.h"

namespace clod_haptics {
namespace {

double farthestVertex(const TriangleMesh& mesh, std::size_t t, const Vec3& centre) {
  double r2 = 0.0;
  for (int k = 0; k < 3; ++k) r2 = std::max(r2, (mesh.vertex(t, k) - centre).squaredNorm());
  return std::sqrt(r2);
}

// The threshold steps of the paper, tau_k = -0.99 + 0.01 k. The opposite triangle is the nearest hit
// with dot < tau_k for the smallest k that admits any hit; with m the smallest dot among all hits
// that k is the first with tau_k > m, so one pass over the hits finds it.
constexpr double kTau0 = -0.99;
constexpr double kTauStep = 0.01;

inline double tau(int k) { return kTau0 + kTauStep * k; }

int firstAdmittingStep(double minDot) {
  // A dot of unit vectors; clamped to [-1, 1] (NaN to -1) so that a normal off unit length cannot overflow the int.
  if (!(minDot >= -1.0)) minDot = -1.0;
  if (minDot > 1.0) minDot = 1.0;
  int k = static_cast<int>(std::floor((minDot - kTau0) / kTauStep)) + 1;
  k = std::max(k, 0);
  while (k > 0 && minDot < tau(k - 1)) --k;  // guard the floor against rounding
  while (!(minDot < tau(k))) ++k;
  return k;
}

struct Hit {
  std::uint32_t triangle;
  double t;
  double dot;
};

// Hits a ray keeps for its final choice; past that the hits are enumerated again.
constexpr int kKeep = 64;

// Steps added to the highest step of a packet to guess the next packet's: a guess too low costs a ray a
// second walk, one too high skips less.
constexpr int kGuessMargin = 20;

constexpr double kInfinity = std::numeric_limits<double>::infinity();

// One ray: from a triangle's centroid along its inward normal.
struct Ray {
  std::uint32_t triangle;
  Vec3 normal;
  double minDot;  // the smallest dot of a hit's normal with the ray's normal
  int k;          // step of minDot; -1 before the first hit
  double bestT;   // the nearest hit with dot < tau_k
  int seen;       // hits so far (kept up to kKeep)
  int guess;      // a step the ray's answer is expected at or below, or -1 (see RayWalker)
  Hit kept[kKeep];
  // Back to no hits and no guess.
  void reset() {
    minDot = kInfinity;
    k = -1;
    bestT = kInfinity;
    seen = 0;
    guess = -1;
  }
  void rebest() {
    const double limit = tau(k);
    bestT = kInfinity;
    for (int h = 0; h < std::min(seen, kKeep); ++h)
      if (kept[h].dot < limit) bestT = std::min(bestT, kept[h].t);
  }
};

// One thread's ray casts, one ray per triangle. With m the smallest dot seen so far and k its step, a
// subtree matters only if its normals can reach below tau_{k-1} (a lower step) or below tau_k nearer
// than the best hit at step k; the origin's neighbourhood, visited last, mostly faces along the normal
// and is skipped. Skipping is exact in any visiting order (k only falls and the best distance only
// shrinks), so the rays go in packets of neighbours.
// Before its first hit a ray has nothing to skip by. So each ray also gets a guess g from its neighbours
// (the previous packet's highest step plus a margin) and skips every subtree whose normals cannot go
// below tau_g. Every hit below tau_g is still found, so when the ray ends at a step k <= g its answer
// (which only involves hits below tau_k) is exact; when it ends above g or without a hit it walks again
// without the guess.
class RayWalker {
 public:
  static constexpr int W = TriangleBvh::kPacket;

  RayWalker(const TriangleMesh& mesh, const TriangleBvh& bvh, double minT, std::vector<std::uint32_t>& opposite,
            std::vector<std::uint16_t>& steps)
      : mesh_(mesh), bvh_(bvh), minT_(minT), opposite_(opposite), steps_(steps) {
    for (int r = 0; r < W; ++r) {  // lanes past a packet's count stay defined (and masked out)
      rays_[r].normal = Vec3::Zero();
      rays_[r].reset();
      setCull(r);
    }
  }

  // The rays of triangles bvh.order()[begin, end), in the hierarchy's leaf order: consecutive rays start
  // close together and walk mostly the same nodes, so a packet of them walks each shared node once.
  void cast(std::size_t begin, std::size_t end) {
    for (std::size_t j = begin; j < end;) castPacket(loadPacket(j, end));
  }

 private:
  // The next rays from order()[j, end) (triangles without a normal cast none), with the guess; returns
  // how many.
  int loadPacket(std::size_t& j, std::size_t end) {
    int count = 0;
    for (; j < end && count < W; ++j) {
      const std::uint32_t t = bvh_.order()[j];
      const Vec3& normal = mesh_.normals[t];
      if (normal.isZero(0.0)) continue;
      Ray& ray = rays_[count];
      ray.triangle = t;
      ray.normal = normal;
      ray.reset();
      origins_[count] = mesh_.centroid(t);
      dirs_[count] = -normal;
      ++count;
    }
    for (int r = 0; r < count; ++r) {
      rays_[r].guess = guess_;
      setCull(r);
    }
    return count;
  }

  // Walks the packet, again without the guess the rays it failed, and guesses for the next packet.
  void castPacket(int count) {
    bvh_.forEachPacketHit(origins_, dirs_, count, cull_,
                          [this](int r, std::uint32_t tri, double dist) { hit(r, tri, dist); });
    int highest = -1;
    for (int r = 0; r < count; ++r) {
      const Ray& ray = rays_[r];
      if (ray.guess >= 0 && (ray.k < 0 || ray.k > ray.guess)) walkAgain(r);
      highest = std::max(highest, ray.k);
      finish(r);
    }
    guess_ = highest >= 0 ? highest + kGuessMargin : -1;
  }

  // Ray r's cull (see PacketCull): a subtree matters only if its normals can go below tau_guess and
  // either below tau_{k-1} (a lower step) or below tau_k nearer than the best hit at step k; before the
  // first hit (and once the hit buffer overflowed) nothing but the guess skips.
  void setCull(int r) {
    const Ray& ray = rays_[r];
    for (int k = 0; k < 3; ++k) cull_.axis[k][r] = ray.normal[k];
    cull_.cap[r] = ray.guess >= 0 ? tau(ray.guess) : kInfinity;
    if (ray.k < 0 || ray.seen > kKeep) {
      cull_.below[r] = kInfinity;
      return;
    }
    cull_.below[r] = ray.k >= 1 ? tau(ray.k - 1) : -kInfinity;
    cull_.nearBelow[r] = tau(ray.k);
    cull_.within[r] = ray.bestT;
  }

  void hit(int r, std::uint32_t tri, double dist) {
    Ray& ray = rays_[r];
    if (tri == ray.triangle || dist <= minT_) return;
    const double dot = mesh_.normals[tri].dot(ray.normal);
    if (ray.seen < kKeep) ray.kept[ray.seen] = {tri, dist, dot};
    ++ray.seen;
    if (dot < ray.minDot) {
      ray.minDot = dot;
      const int step = firstAdmittingStep(dot);
      if (step != ray.k) {
        ray.k = step;
        ray.rebest();
        setCull(r);
        return;
      }
    }
    if (ray.k >= 0 && dot < tau(ray.k)) ray.bestT = std::min(ray.bestT, dist);
    setCull(r);
  }

  // Nothing below tau_guess: the answer may lie in a skipped subtree. Walks ray r again without the guess.
  void walkAgain(int r) {
    rays_[r].reset();
    setCull(r);
    double all = kInfinity;
    bvh_.forEachRayHit(
        origins_[r], dirs_[r], all, [&](std::uint32_t tri, double dist) { hit(r, tri, dist); },
        [&](const TriangleBvh::Node& node, double entry) { return TriangleBvh::keeps(cull_, r, node, entry); });
  }

  // The answer of a walked ray: the nearest hit with dot < tau_k (lowest index on ties).
  void finish(int r) {
    const Ray& ray = rays_[r];
    const std::uint32_t t = ray.triangle;
    if (ray.seen == 0) return;  // the ray escapes: no opposite triangle
    std::uint32_t best = std::numeric_limits<std::uint32_t>::max();
    const double limit = tau(ray.k);
    double bestT = kInfinity;
    auto consider = [&](std::uint32_t tri, double dist, double dot) {
      if (dot < limit && (dist < bestT || (dist == bestT && tri < best))) {
        bestT = dist;
        best = tri;
      }
    };
    if (ray.seen <= kKeep) {
      for (int h = 0; h < ray.seen; ++h) consider(ray.kept[h].triangle, ray.kept[h].t, ray.kept[h].dot);
    } else {
      // More hits than the buffer holds (pruning was off after it overflowed, so minDot and k
      // are over every hit): enumerate the hits again.
      double all = kInfinity;
      bvh_.forEachRayHit(origins_[r], dirs_[r], all, [&](std::uint32_t tri, double dist) {
        if (tri == t || dist <= minT_) return;
        consider(tri, dist, mesh_.normals[tri].dot(ray.normal));
      });
    }
    opposite_[t] = best;
    steps_[t] = static_cast<std::uint16_t>(std::min(ray.k, 65535));
  }

  const TriangleMesh& mesh_;
  const TriangleBvh& bvh_;
  const double minT_;
  std::vector<std::uint32_t>& opposite_;
  std::vector<std::uint16_t>& steps_;
  Ray rays_[W];
  Vec3 origins_[W], dirs_[W];
  PacketCull cull_;
  int guess_ = -1;  // the step guessed for the next packet
};

}  // namespace

PlacedCentres SpherePlacement::placeCentres(const TriangleMesh& mesh, PlacementStats* stats) const {
  const std::vector<PlacedSphere> placed = place(mesh, stats);
  PlacedCentres out;
  out.centres.reserve(placed.size());
  out.wrapped.reserve(placed.size());
  for (const PlacedSphere& s : placed) {
    out.centres.push_back(s.centre);
    out.wrapped.push_back(s.triangle);
  }
  return out;
}

// Per triangle: the opposite triangle (or UINT32_MAX) and the relaxation steps taken.
struct PaperPlacement::Opposites {
  std::vector<std::uint32_t> opposite;
  std::vector<std::uint16_t> steps;
};

PaperPlacement::Opposites PaperPlacement::castRays(const TriangleMesh& mesh) const {
  const std::size_t n = mesh.size();
  // Ray casts are compute-bound: every hardware thread, at least 1024 rays each.
  const unsigned threads = detail::threadsFor(n, threads_, 1024, std::numeric_limits<unsigned>::max());
  const TriangleBvh bvh(mesh, 4, threads);      // freed on return, before the spheres are written
  const double minT = 1e-12 * mesh.diagonal();  // ignore hits at the origin itself (coplanar duplicates)
  Opposites found{std::vector<std::uint32_t>(n, std::numeric_limits<std::uint32_t>::max()),
                  std::vector<std::uint16_t>(n, 0)};
  std::atomic<std::size_t> next{0};
  detail::runParallel(threads, [&](unsigned t) {
    constexpr std::size_t kChunk = 256;
    RayWalker walker(mesh, bvh, minT, found.opposite, found.steps);
    for (std::size_t begin; (begin = next.fetch_add(kChunk)) < n;) {
      if (t == 0 && progress_) progress_(static_cast<double>(begin) / static_cast<double>(n));
      walker.cast(begin, std::min(n, begin + kChunk));
    }
  });
  if (progress_) progress_(1.0);
  return found;
}

namespace {

// Calls emit(centre, triangle) for the placed spheres of triangles [begin, end) in order (two per
// paired triangle, one at the centroid otherwise) and adds their counts to s.
template <class Emit>
void forEachSphere(const TriangleMesh& mesh, const std::vector<std::uint32_t>& opposite,
                   const std::vector<std::uint16_t>& steps, std::size_t begin, std::size_t end, PlacementStats& s,
                   Emit&& emit) {
  for (std::size_t t = begin; t < end; ++t) {
    const Vec3 c0 = mesh.centroid(t);
    const std::uint32_t o = opposite[t];
    if (o == std::numeric_limits<std::uint32_t>::max()) {
      if (mesh.normals[t].isZero(0.0))
        ++s.degenerate;
      else
        ++s.unpaired;
      emit(c0, static_cast<std::uint32_t>(t));
      continue;
    }
    ++s.paired;
    s.relaxations += steps[t];
    const Vec3 c1 = mesh.centroid(o);
    emit(Vec3(c0 + 0.25 * (c1 - c0)), static_cast<std::uint32_t>(t));
    emit(Vec3(c0 + 0.75 * (c1 - c0)), o);
  }
}

std::size_t sphereCount(const std::vector<std::uint32_t>& opposite, std::size_t begin, std::size_t end) {
  std::size_t count = 0;
  for (std::size_t t = begin; t < end; ++t) count += opposite[t] == std::numeric_limits<std::uint32_t>::max() ? 1 : 2;
  return count;
}

}  // namespace

std::vector<PlacedSphere> PaperPlacement::place(const TriangleMesh& mesh, PlacementStats* stats) const {
  const auto start = std::chrono::steady_clock::now();
  const Opposites found = castRays(mesh);
  std::vector<PlacedSphere> spheres;
  spheres.reserve(sphereCount(found.opposite, 0, mesh.size()));
  PlacementStats s;
  s.triangles = mesh.size();
  forEachSphere(mesh, found.opposite, found.steps, 0, mesh.size(), s, [&](const Vec3& centre, std::uint32_t t) {
    spheres.push_back({centre, farthestVertex(mesh, t, centre), t});
  });
  s.milliseconds = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  if (stats) *stats = s;
  return spheres;
}

PlacedCentres PaperPlacement::placeCentres(const TriangleMesh& mesh, PlacementStats* stats) const {
  const auto start = std::chrono::steady_clock::now();
  const Opposites found = castRays(mesh);
  // The spheres written straight to their places, the triangles split in parts on threads (each part's
  // first sphere index counted beforehand): the same arrays as one pass in order.
  const std::size_t n = mesh.size();
  const unsigned parts = detail::threadsFor(n, threads_, 2048);
  std::vector<std::size_t> cut(parts + 1),
      at(parts + 1, 0);  // part j: triangles [cut[j], cut[j+1]), spheres from at[j]
  for (unsigned j = 0; j <= parts; ++j) cut[j] = n * j / parts;
  for (unsigned j = 0; j < parts; ++j) at[j + 1] = at[j] + sphereCount(found.opposite, cut[j], cut[j + 1]);
  PlacedCentres out;
  out.centres.resize(at[parts]);
  out.wrapped.resize(at[parts]);
  std::vector<PlacementStats> partStats(parts);
  detail::runParallel(parts, [&](unsigned j) {
    std::size_t next = at[j];
    forEachSphere(mesh, found.opposite, found.steps, cut[j], cut[j + 1], partStats[j],
                  [&](const Vec3& centre, std::uint32_t t) {
                    out.centres[next] = centre;
                    out.wrapped[next] = t;
                    ++next;
                  });
  });
  PlacementStats s;
  s.triangles = n;
  for (const PlacementStats& part : partStats) {
    s.paired += part.paired;
    s.unpaired += part.unpaired;
    s.degenerate += part.degenerate;
    s.relaxations += part.relaxations;
  }
  s.milliseconds = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  if (stats) *stats = s;
  return out;
}

}  // namespace clod_haptics
