#pragma once
// Shared pieces of the clod_haptics benchmark: the peer interface, the exact pruned reference,
// the per-query timer and small helpers. Not part of the library; never a test.

#include <x86intrin.h>

#include <algorithm>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "clod_haptics/core/contact.h"
#include "clod_haptics/core/mesh.h"

namespace clod_bench {

using clod_haptics::ContactResult;
using clod_haptics::TriangleMesh;
using clod_haptics::Vec3;

/** \brief What every contender answers for one probe: is a triangle within r, and the closest point. */
struct Answer {
  bool contact = false;
  Vec3 point = Vec3::Zero();
  double distance = 0.0;
  std::int32_t triangle = -1;
};

/**
 * \brief One contender of the peer comparison, answering the same radius-bounded question as
 * ClodDetector::query in Exact mode. query() must not allocate.
 */
class Peer {
 public:
  virtual ~Peer() = default;
  /** \brief Short name used in the CSV ("embree", "cgal", "fcl", "brute", "clod-grid", "clod-grid-cache", ...). */
  virtual std::string name() const = 0;
  /** \brief Answers for pointer centre p and radius r. */
  virtual void query(const Vec3& p, double r, Answer& out) const = 0;
  /** \brief Called at the start of every timed run over a probe stream (a stateful peer resets its cache). */
  virtual void startStream() const {}
  /** \brief Wall time of the structure's construction, milliseconds. */
  double buildMs = 0.0;
  /** \brief The index build alone, milliseconds (Embree: rtcCommitScene; CGAL: build and distance acceleration). */
  double indexMs = 0.0;
};

// Peers living in their own translation units (CGAL is header-heavy: compiled once).
std::unique_ptr<Peer> makeCgalPeer(const TriangleMesh& mesh);
std::unique_ptr<Peer> makeFclPeer(const TriangleMesh& mesh);
/** \brief Embree on a device of `threads` threads (the query comparisons use 1; the start-up table also 2). */
std::unique_ptr<Peer> makeEmbreePeer(const TriangleMesh& mesh, int threads = 1);

/**
 * \brief The exact reference, pruned: a uniform grid holds every triangle in the cells its box
 * grown by r overlaps, in ascending index order. A probe tests only its cell's triangles, with the
 * same closest-point routine and tie rule (lowest index) as bruteForceQuery, so for a radius at most
 * r it returns bit-identical answers (checked against bruteForceQuery on a sample in every run).
 */
class PrunedReference {
 public:
  PrunedReference(const TriangleMesh& mesh, double r);
  /** \brief Same answer as clod_haptics::bruteForceQuery(mesh, p, r) (trianglesTested aside). */
  ContactResult query(const Vec3& p) const;
  /** \brief Answers for all probes on `threads` threads. */
  std::vector<ContactResult> queryAll(const std::vector<Vec3>& probes, unsigned threads) const;

 private:
  const TriangleMesh& mesh_;
  double r_;
  Vec3 lo_;
  double inv_;
  int n_[3];
  std::vector<std::uint32_t> start_;
  std::vector<std::uint32_t> items_;
  std::vector<double> boxes_;  // 6 per triangle: lo, hi
};

/** \brief Converts cycles of the time-stamp counter to nanoseconds (calibrated once at start). */
struct Clock {
  static void calibrate();
  static double nsPerTick;
  static double overheadTicks;  // median cost of an empty timed region
};

/** \brief The time (ns) of one call of f between fenced time-stamp reads, the empty region's cost subtracted. */
template <class F>
float fencedNs(F&& f) {
  _mm_lfence();
  const std::uint64_t a = __rdtsc();
  _mm_lfence();
  f();
  _mm_lfence();
  const std::uint64_t b = __rdtsc();
  _mm_lfence();
  return static_cast<float>(std::max(0.0, (static_cast<double>(b - a) - Clock::overheadTicks) * Clock::nsPerTick));
}

/** \brief Per-query times (ns) and summary statistics. */
struct Timing {
  std::vector<float> ns;
  double median = 0, mean = 0, p10 = 0, p90 = 0, p99 = 0, totalSeconds = 0;
  double trimmedMean = 0;  // mean of the times up to the 99th percentile: drops preemption spikes
  void summarise();
};

/** \brief Subdivides every triangle into four at its edge midpoints (shared midpoints: stays closed). */
TriangleMesh subdivide(const TriangleMesh& mesh);

// Generated models (the contact section): deterministic, in the unit cube's frame, wound outward.

/**
 * \brief An ellipsoid with semi-axes `axes` around `centre`: a cube's six faces cut into m x m cells at the
 * tangents of evenly spaced angles (equal-angle cube sphere), projected on the unit sphere and stretched by
 * the axes. Closed, 12 m^2 triangles.
 */
TriangleMesh cubeEllipsoid(const Vec3& axes, const Vec3& centre, int m, const std::string& name);

/** \brief cubeEllipsoid with m chosen so the mean edge is about `edge` (from a trial at m = 16). */
TriangleMesh ellipsoidWithEdge(const Vec3& axes, const Vec3& centre, double edge, const std::string& name);

/**
 * \brief The triangles whose centroid lies beyond the middle of the bounds on x, subdivided `times` times
 * (subdivide(): flat, so the surface is unchanged; T-junctions along the seam), the others kept.
 */
TriangleMesh refineHalf(const TriangleMesh& mesh, int times, const std::string& name);

/**
 * \brief A closed cylinder along z: `slices` side strips, each cut into two triangles of the full height,
 * and the caps as fans from their centres. Long thin triangles for a fine slicing.
 */
TriangleMesh slicedCylinder(const Vec3& centre, double radius, double height, int slices, const std::string& name);

/** \brief Mean length of the triangles' edges (an edge counted once per triangle). */
double meanEdge(const TriangleMesh& mesh);

/** \brief Aspect ratio of each non-degenerate triangle: its longest edge over the altitude onto that edge. */
std::vector<double> aspectRatios(const TriangleMesh& mesh);

/** \brief Number of edges not shared by exactly two triangles (0 for a closed manifold mesh). */
std::size_t openEdges(const TriangleMesh& mesh);

/** \brief Enclosed volume by the divergence theorem (meaningful for a closed, consistently wound mesh). */
double meshVolume(const TriangleMesh& mesh);

/** \brief Stylus tip positions (metres or millimetres as recorded) resampled at 1 kHz; empty on failure. */
std::vector<Vec3> readTrajectory(const std::string& bagPath, const std::string& topic, double rateHz,
                                 std::string& error, double& seconds, std::size_t& messages);

/** \brief Places a trajectory over the mesh: uniform scale into its bounding box, centred. */
std::vector<Vec3> placeOver(const std::vector<Vec3>& trajectory, const TriangleMesh& mesh);

/** \brief Peak resident set (VmHWM) and current resident set (VmRSS) in bytes; resetPeak writes /proc/self/clear_refs. */
std::size_t peakRssBytes();
std::size_t currentRssBytes();
bool resetPeakRss();

}  // namespace clod_bench
