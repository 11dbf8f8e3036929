// In-contact query breakdown: per model, how long the candidate lists of the cells are, how many of them a query
// scans and how many triangles it tests, and what the query costs, for the in-contact probes. Not a test: it
// prints figures. Usage: clod_breakdown MESH... (files, or "ellipsoid-e0.1r", "slivers-cylinder", "uneven-16x"
// for the contact section's generated models).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "bench_common.h"
#include "clod_haptics/core/detector.h"
#include "clod_haptics/core/mesh_loader.h"
#include "clod_haptics/core/probes.h"
#include "clod_haptics/core/sphere_set.h"

using namespace clod_haptics;

namespace {

constexpr double kR = 0.005, kD = 0.02;  // as the contact section: r, d

TriangleMesh makeModel(const std::string& name) {
  const Vec3 axes(0.5, 0.4, 0.3), centre = Vec3::Constant(0.5);
  if (name == "ellipsoid-e0.1r")
    return clod_bench::ellipsoidWithEdge(0.1 * axes, Vec3::Constant(0.25), 0.1 * kR, name);
  if (name == "slivers-cylinder") return clod_bench::slicedCylinder(centre, 0.25, 1.0, 1000, name);
  if (name == "uneven-16x")
    return clod_bench::refineHalf(clod_bench::ellipsoidWithEdge(axes, centre, 10 * kR, name), 4, name);
  MeshLoadOptions options;
  options.normalize = true;
  return loadMesh(name, options);
}

void printStats(const char* label, std::vector<double> v) {
  if (v.empty()) return;
  std::sort(v.begin(), v.end());
  double sum = 0.0;
  for (double x : v) sum += x;
  auto at = [&](double q) { return v[std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())))]; };
  std::printf("  %-22s mean %9.1f  p50 %9.1f  p90 %9.1f  p99 %9.1f  max %9.1f\n", label,
              sum / static_cast<double>(v.size()), at(0.5), at(0.9), at(0.99), v.back());
}

void breakdown(const std::string& name) {
  const auto mesh = std::make_shared<const TriangleMesh>(makeModel(name));
  const auto set = std::make_shared<const ClodSphereSet>(ClodBuilder(mesh).build(kD));
  const ClodDetector detector(mesh, set, FastLevel::Grid, kR);
  const CellGrid grid(*mesh, *set, kR);  // the grid the detector holds, built again to read its cells
  std::printf("%s: %zu triangles, mean edge %.2f r, cell %.2f r, %.1f candidates per triangle, detector %.0f B/tri\n",
              name.c_str(), mesh->size(), clod_bench::meanEdge(*mesh) / kR, grid.cellSize() / kR,
              static_cast<double>(grid.entries()) / static_cast<double>(mesh->size()),
              static_cast<double>(detector.bytes()) / static_cast<double>(mesh->size()));
  std::vector<double> candidates, scanned, tested, ns;
  for (const Vec3& p : nearSurfaceProbes(*mesh, 100000, 3 * kR, 31)) {
    ContactResult c;
    const auto t0 = std::chrono::steady_clock::now();
    detector.query(p, kR, DetectionMode::Exact, c);
    const double elapsed = std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - t0).count();
    if (!c.contact) continue;
    const Vec3 local = mesh->toLocal(p);
    const std::uint64_t key = grid.keyOf(local);
    const CellGrid::CellRef* ref = grid.find(key);
    if (ref == nullptr) continue;
    const CellGrid::Cell cell = grid.cell(*ref);
    // Entries the sorted scan reads before its stop (distance from the cell centre minus the offset beyond the
    // answer's distance).
    const double offset = (local - grid.centreOf(key)).norm();
    std::uint32_t i = 0;
    while (i < cell.count && grid.centreDistance(cell.entries[i]) - offset <= c.distance) ++i;
    candidates.push_back(cell.count);
    scanned.push_back(i);
    tested.push_back(c.trianglesTested);
    ns.push_back(elapsed);
  }
  std::printf("  %zu of 100000 near-surface probes in contact\n", ns.size());
  printStats("cell candidates", candidates);
  printStats("candidates scanned", scanned);
  printStats("triangles tested", tested);
  printStats("query ns (+ clock)", ns);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: clod_breakdown MESH... (or ellipsoid-e0.1r, slivers-cylinder, uneven-16x)\n");
    return 2;
  }
  for (int i = 1; i < argc; ++i) breakdown(argv[i]);
  return 0;
}
