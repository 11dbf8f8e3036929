#pragma once
// Helpers shared by the core tests: fixture paths, the coverage check computed directly from the
// definition, and a small parallel loop (the brute-force reference is O(triangles) per probe).

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <limits>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <unistd.h>

#include "clod_haptics/core/mesh.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/sphere_set.h"
#include "clod_haptics/test_config.h"

namespace clod_test {

using namespace clod_haptics;

/** \brief A random unit vector (normal draws, normalised). */
inline Vec3 randomUnit(std::mt19937_64& rng) {
  std::normal_distribution<double> n;
  Vec3 v(n(rng), n(rng), n(rng));
  return v.normalized();
}

/**
 * \brief A point for a round of a randomised bound test, and the scale of the geometry to put around it (1 mm to
 * 10 m): near the origin, or on odd rounds 1e3 scales away (coordinates much larger than the geometry).
 */
inline Vec3 randomPoint(std::mt19937_64& rng, int round, double& scale) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  scale = std::pow(10.0, -3.0 + 4.0 * u(rng));
  const Vec3 origin = Vec3(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5) * (round % 2 ? 1e3 * scale : 0.0);
  return origin + Vec3(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5) * 4.0 * scale;
}

/**
 * \brief The tally of a conservative filter against the geometry: items the reference puts within reach (every one
 * must be kept) and beyond it (most should be dropped, or the filter helps nobody).
 */
struct FilterTally {
  std::size_t within = 0, dropped = 0, beyond = 0, kept = 0;
  void count(bool reached, bool got) {
    within += reached;
    dropped += reached && !got;
    beyond += !reached;
    kept += !reached && got;
  }
  /** Nothing within reach dropped, more than `least` within reach seen, under half of the others kept. */
  void expectConservative(std::size_t least, const std::string& items) const {
    EXPECT_EQ(dropped, 0u) << "of " << within << " " << items << " within reach";
    EXPECT_GT(within, least);
    EXPECT_LT(kept, beyond / 2) << "a filter that keeps everything passes the first check and helps nobody";
  }
};

/** \brief A finely tessellated surface z = f(x, y) over [-1, 1]^2, n x n squares (two triangles each), turned by
 * rotation and moved by shift. */
inline TriangleMesh heightField(int n, double (*f)(double, double), const Eigen::Matrix3d& rotation,
                                const Vec3& shift) {
  std::vector<Vec3> vertices;
  std::vector<Triangle> triangles;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      const double x = -1.0 + 2.0 * i / n, y = -1.0 + 2.0 * j / n;
      vertices.push_back(shift + rotation * Vec3(x, y, f(x, y)));
    }
  const auto at = [n](int i, int j) { return static_cast<std::uint32_t>(j * (n + 1) + i); };
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      triangles.push_back({at(i, j), at(i + 1, j), at(i + 1, j + 1)});
      triangles.push_back({at(i, j), at(i + 1, j + 1), at(i, j + 1)});
    }
  return makeMesh(std::move(vertices), std::move(triangles), "height field");
}

/** \brief A fixture with a fresh directory of its own (per process and test), removed after the test. */
class TempDirTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("clod_test_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  std::filesystem::path dir_;
};

/** \brief Path of a fixture in the repository's test/data. */
inline std::string testData(const std::string& name) { return std::string(CLOD_TEST_DATA_DIR) + "/" + name; }

/**
 * \brief Every mesh file in ../shared/data/meshes, sorted. A missing or empty directory is a test
 * failure (CI has it), never a silent skip.
 */
inline std::vector<std::string> sharedMeshes() {
  std::vector<std::string> out;
  std::error_code ec;
  const std::filesystem::path dir(CLOD_SHARED_MESH_DIR);
  if (!std::filesystem::is_directory(dir, ec)) {
    ADD_FAILURE() << "shared mesh directory missing: " << dir << " (set CLOD_SHARED_DIR when configuring)";
    return out;
  }
  for (const auto& entry : std::filesystem::directory_iterator(dir, ec))
    if (entry.is_regular_file()) out.push_back(entry.path().string());
  std::sort(out.begin(), out.end());
  if (out.empty()) ADD_FAILURE() << "shared mesh directory is empty: " << dir;
  return out;
}

/** \brief Path of one shared mesh; a missing file is a test failure. */
inline std::string sharedMesh(const std::string& name) {
  const std::string path = std::string(CLOD_SHARED_MESH_DIR) + "/" + name;
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) ADD_FAILURE() << "shared mesh missing: " << path;
  return path;
}

/** \brief File name without the directory, for messages. */
inline std::string baseName(const std::string& path) { return std::filesystem::path(path).filename().string(); }

/** \brief Loads a mesh normalised into the unit cube. */
inline std::shared_ptr<const TriangleMesh> loadNormalized(const std::string& path) {
  MeshLoadOptions options;
  options.normalize = true;
  return std::make_shared<const TriangleMesh>(loadMesh(path, options));
}

/**
 * \brief Steps per edge of the barycentric grid that samples triangle t against the spheres `listing`: 4 per smallest
 * listing radius along the longest edge, at least 8 and at most maxSteps.
 */
inline int samplingSteps(const TriangleMesh& mesh, const ClodSphereSet& set, std::size_t t,
                         const std::vector<std::uint32_t>& listing, double maxSteps) {
  const Vec3 &a = mesh.vertex(t, 0), &b = mesh.vertex(t, 1), &c = mesh.vertex(t, 2);
  const double longest = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
  double smallest = std::numeric_limits<double>::infinity();
  for (std::uint32_t i : listing) smallest = std::min(smallest, set.radii[i]);
  return static_cast<int>(std::clamp(std::ceil(4.0 * longest / smallest), 8.0, maxSteps));
}

/**
 * \brief The points of a barycentric grid of `steps` per edge on triangle t (corners and edges included) that lie in
 * none of the spheres `listing`, each taken to reach radius * (1 + relTol) + absTol. The sphere that held the
 * previous point is tried first: neighbouring points mostly share one.
 */
inline std::size_t missedSamples(const TriangleMesh& mesh, const ClodSphereSet& set, std::size_t t,
                                 const std::vector<std::uint32_t>& listing, int steps, double relTol, double absTol) {
  const Vec3 &a = mesh.vertex(t, 0), &b = mesh.vertex(t, 1), &c = mesh.vertex(t, 2);
  std::size_t misses = 0, last = 0;
  for (int i = 0; i <= steps; ++i)
    for (int j = 0; i + j <= steps; ++j) {
      const double u = double(i) / steps, w = double(j) / steps;
      const Vec3 p = (1 - u - w) * a + u * b + w * c;
      auto holds = [&](std::size_t k) {
        return (p - set.centres[listing[k]]).norm() <= set.radii[listing[k]] * (1.0 + relTol) + absTol;
      };
      bool inside = last < listing.size() && holds(last);
      for (std::size_t k = 0; k < listing.size() && !inside; ++k)
        if (holds(k)) inside = true, last = k;
      misses += !inside;
    }
  return misses;
}

/**
 * \brief Checks the coverage invariant from its definition: every point of every triangle lies within the radius
 * (times 1 + relTol, plus relTol of the model size) of a sphere that lists the triangle. A triangle passes at once
 * when one listing sphere holds its three vertices; a triangle split over several spheres is sampled instead, on a
 * barycentric grid at least 4 steps per smallest listing radius along its longest edge (not by the halving the
 * library uses, so the check is independent of it). Also checks the flat arrays are well formed and finite.
 * Returns the problems found.
 */
inline std::vector<std::string> coverageProblems(const TriangleMesh& mesh, const ClodSphereSet& set,
                                                 double relTol = 1e-12) {
  std::vector<std::string> problems;
  auto report = [&](const std::string& what) {
    if (problems.size() < 20) problems.push_back(what);
  };
  if (set.radii.size() != set.centres.size() || set.offsets.size() != set.centres.size() + 1 ||
      set.offsets.front() != 0 || set.offsets.back() != set.triangles.size()) {
    report("malformed flat arrays");
    return problems;
  }
  const double size = mesh.diagonal();
  std::vector<char> covered(mesh.size(), 0);
  for (std::size_t i = 0; i < set.size(); ++i) {
    if (set.offsets[i] > set.offsets[i + 1]) {
      report("offsets decrease at sphere " + std::to_string(i));
      return problems;
    }
    if (!set.centres[i].allFinite() || !std::isfinite(set.radii[i]) || set.radii[i] < 0.0)
      report("sphere " + std::to_string(i) + " has a non-finite centre or a bad radius");
    const double reach = set.radii[i] * (1.0 + relTol) + relTol * size;
    for (const std::uint32_t* t = set.begin(i); t != set.end(i); ++t) {
      if (*t >= mesh.size()) {
        report("sphere " + std::to_string(i) + " lists triangle " + std::to_string(*t) + " out of range");
        continue;
      }
      bool inside = true;
      for (int k = 0; k < 3; ++k) inside = inside && (mesh.vertex(*t, k) - set.centres[i]).norm() <= reach;
      if (inside) {
        covered[*t] = 1;
      } else if (!covered[*t]) {
        covered[*t] = 2;  // listed, not whole in this sphere
      }
    }
  }
  std::vector<std::vector<std::uint32_t>> listing(mesh.size());
  for (std::size_t i = 0; i < set.size(); ++i)
    for (const std::uint32_t* t = set.begin(i); t != set.end(i); ++t)
      if (*t < mesh.size() && covered[*t] == 2) listing[*t].push_back(static_cast<std::uint32_t>(i));
  for (std::size_t t = 0; t < mesh.size(); ++t) {
    if (covered[t] != 2) continue;
    const int steps = samplingSteps(mesh, set, t, listing[t], 1024.0);
    covered[t] = missedSamples(mesh, set, t, listing[t], steps, relTol, relTol * size) == 0 ? 1 : 0;
  }
  for (std::size_t t = 0; t < mesh.size(); ++t)
    if (!covered[t]) report("triangle " + std::to_string(t) + " is inside no sphere that lists it");
  return problems;
}

/** \brief Joins problems into one message. */
inline std::string join(const std::vector<std::string>& lines) {
  std::ostringstream out;
  for (const auto& l : lines) out << "\n  " << l;
  return out.str();
}

/** \brief Runs body(begin, end) over [0, n) split into contiguous chunks on `threads` threads. */
inline void parallelFor(std::size_t n, unsigned threads, const std::function<void(std::size_t, std::size_t)>& body) {
  threads = std::max(1u, threads);
  std::vector<std::thread> pool;
  const std::size_t chunk = (n + threads - 1) / threads;
  for (unsigned k = 0; k < threads; ++k) {
    const std::size_t begin = std::min(n, k * chunk), end = std::min(n, begin + chunk);
    if (begin < end) pool.emplace_back(body, begin, end);
  }
  for (auto& th : pool) th.join();
}

}  // namespace clod_test
