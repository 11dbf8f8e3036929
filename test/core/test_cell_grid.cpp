// CellGrid, the Grid fast level's precomputed candidates, checked against its documented contract:
// every triangle within radius + h sqrt(3)/2 of a cell's centre is listed, entries are sorted (by the
// centre distance to 1/256 of its code's unit, then by triangle), the float centre distance is rounded
// down, the float supporting-plane bound (minus slack) never exceeds the true distance from a point of the
// cell to the triangle (the float path's error bound), and a cell counts the distinct spheres listing its
// triangles.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <set>
#include <vector>

#include "binary_io.h"
#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/cell_grid.h"
#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/geometry.h"
#include "clod_haptics/core/probes.h"
#include "float_rounding.h"
#include "grid_entry_codes.h"
#include "simd/dispatch.h"
#include "simd/grid_entry_avx2.h"
#include "test_helpers.h"

namespace {

using namespace clod_haptics;

double distanceToTriangle(const TriangleMesh& mesh, std::size_t t, const Vec3& p) {
  return (p - closestPointOnTriangle(p, mesh.vertex(t, 0), mesh.vertex(t, 1), mesh.vertex(t, 2))).norm();
}

// Checks the contract on the cells of the given probes; returns the number of cells checked. With the grid's
// sphere set, also each cell's count of distinct spheres (those first listing its triangles).
std::size_t checkGrid(const TriangleMesh& mesh, const CellGrid& grid, const std::vector<Vec3>& probes,
                      const std::string& label, const ClodSphereSet* set = nullptr) {
  SCOPED_TRACE(label);
  const std::vector<std::uint32_t> sphereOf =
      set ? firstSphereOfTriangles(*set, mesh.size()) : std::vector<std::uint32_t>();
  const double h = grid.cellSize();
  const double reach = grid.radius() + 0.8660254037844386 * h;
  std::set<std::uint64_t> checked;
  int failures = 0;
  for (const Vec3& p : probes) {
    if (failures > 5) break;
    const std::uint64_t key = grid.keyOf(p);
    const CellGrid::CellRef* ref = grid.find(key);
    if (ref == nullptr) {
      // No cell: no triangle within the grid radius of p.
      if (bruteForceQuery(mesh, p, grid.radius() * (1 - 1e-9)).contact) {
        ++failures;
        ADD_FAILURE() << "no cell for " << p.transpose() << " but a triangle is within the grid radius";
      }
      continue;
    }
    const Vec3 centre = grid.centreOf(key);
    const Vec3 rel = p - centre;
    if (rel.cwiseAbs().maxCoeff() > 0.5 * h * (1 + 1e-9)) {
      ++failures;
      ADD_FAILURE() << "probe " << p.transpose() << " is not in the cell whose centre is " << centre.transpose();
    }
    // The index entry's proof of no contact (the slab) never hides a triangle.
    for (double r : {grid.radius(), 0.5 * grid.radius()})
      if (grid.noContact(*ref, rel, r) && bruteForceQuery(mesh, p, r).contact) {
        ++failures;
        ADD_FAILURE() << "the index entry proves no contact for " << p.transpose() << " (r " << r << ", slab offset "
                      << ref->offset << ", half width " << ref->halfWidth << ") but a triangle is within r";
      }
    const CellGrid::Cell cell = grid.cell(*ref);
    const CellGrid::Entry* e = cell.entries;
    std::vector<char> listed(mesh.size(), 0);
    double previous = 0.0;  // the centre distance of the entry before
    for (std::uint32_t i = 0; i < cell.count; ++i) {
      const std::size_t t = e[i].triangle;
      if (t >= mesh.size()) {
        ADD_FAILURE() << "triangle index " << t << " out of range";
        return checked.size();
      }
      listed[t] = 1;
      const double dc = distanceToTriangle(mesh, t, centre);
      if (i > 0) {
        EXPECT_LE(e[i - 1].distance, e[i].distance) << "entries sorted";
        // Within a code, nearest first (to 1/256 of the code's unit), equal distances in triangle order.
        if (e[i - 1].distance == e[i].distance) {
          EXPECT_LE(previous, dc + grid.distanceUnit() / 256.0 + 1e-12)
              << "triangles " << e[i - 1].triangle << ", " << t;
          if (previous == dc) {
            EXPECT_LT(e[i - 1].triangle, e[i].triangle) << "equal distances in triangle order";
          }
        }
      }
      previous = dc;
      EXPECT_LE(grid.centreDistance(e[i]), dc) << "centre distance rounded down, triangle " << t;
      EXPECT_GE(grid.centreDistance(e[i]), dc - grid.distanceUnit() - 1e-6 * h - 1e-12) << "triangle " << t;
      // The bound used to skip a triangle for this p.
      const double bound = grid.centreDistance(e[i]) + rel.x() * e[i].dir(0) + rel.y() * e[i].dir(1) +
                           rel.z() * e[i].dir(2) - grid.slack();
      const double truth = distanceToTriangle(mesh, t, p);
      if (bound > truth) {
        ++failures;
        ADD_FAILURE() << "bound " << bound << " exceeds the distance " << truth << " from " << p.transpose()
                      << " to triangle " << t << " (centre distance " << dc << ", direction " << e[i].dir(0) << " "
                      << e[i].dir(1) << " " << e[i].dir(2) << ")";
      }
    }
    if (!checked.insert(key).second) continue;
    if (set) {
      std::set<std::uint32_t> spheres;
      for (std::uint32_t i = 0; i < cell.count; ++i) spheres.insert(sphereOf[e[i].triangle]);
      EXPECT_EQ(cell.spheres, spheres.size()) << "distinct spheres of the cell at " << centre.transpose();
    }
    for (std::size_t t = 0; t < mesh.size(); ++t)
      if (!listed[t] && distanceToTriangle(mesh, t, centre) <= reach * (1 - 1e-9)) {
        ++failures;
        ADD_FAILURE() << "triangle " << t << " is within reach of cell centre " << centre.transpose()
                      << " but not listed";
      }
  }
  return checked.size();
}

std::vector<Vec3> probesNear(const TriangleMesh& mesh, double offset, std::uint64_t seed) {
  std::vector<Vec3> probes = nearSurfaceProbes(mesh, 3000, offset, seed);
  const auto u = uniformProbes(mesh, 500, offset, seed + 1);
  probes.insert(probes.end(), u.begin(), u.end());
  for (const Vec3& v : mesh.vertices) probes.push_back(v);
  return probes;
}

// A cylinder of radius 0.25 and height 1 made of 1,000 full-height strips (2,000 slivers 0.3 r wide and 200 r long
// at r = 0.005), open at both ends.
std::shared_ptr<const TriangleMesh> stripCylinder() {
  std::vector<Vec3> vertices;
  std::vector<Triangle> triangles;
  const std::uint32_t strips = 1000;
  for (std::uint32_t i = 0; i < strips; ++i) {
    const double a = 2.0 * M_PI * i / strips;
    vertices.push_back(Vec3(0.5 + 0.25 * std::cos(a), 0.5 + 0.25 * std::sin(a), 0.0));
    vertices.push_back(Vec3(0.5 + 0.25 * std::cos(a), 0.5 + 0.25 * std::sin(a), 1.0));
  }
  for (std::uint32_t i = 0; i < strips; ++i) {
    const std::uint32_t j = (i + 1) % strips;
    triangles.push_back({2 * i, 2 * j, 2 * j + 1});
    triangles.push_back({2 * i, 2 * j + 1, 2 * i + 1});
  }
  return std::make_shared<const TriangleMesh>(makeMesh(vertices, triangles, "strips"));
}

TEST(CellGrid, ContractOnSharedMeshes) {
  for (const char* name : {"head.off", "mesh_with_border.off", "degtri_sliding.off"}) {
    const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh(name));
    const ClodSphereSet set = ClodBuilder(mesh).build(0.02);
    for (double radius : {0.005, 0.02}) {
      // The default grid (coarser cells where they are cheap, few of them on the 8-triangle mesh) and the finest.
      const CellGrid grid(*mesh, set, radius);
      const CellGrid fine(*mesh, set, radius, 24.0, CellGrid::Index::Auto, 1e6,
                          std::numeric_limits<double>::infinity());
      for (const CellGrid* g : {&grid, &fine}) {
        EXPECT_FALSE(g->empty());
        EXPECT_GE(g->cellSize(), 2 * radius * (1 - 1e-12));
        EXPECT_GT(checkGrid(*mesh, *g, probesNear(*mesh, 2 * radius, 3), name, &set), g == &fine ? 100u : 20u);
      }
    }
  }
}

// Triangles in planes through the cell-centre lattice (x = y): a cell centre can lie on a triangle
// to within rounding, where the direction from the triangle to the centre is noise.
TEST(CellGrid, ContractOnPlanesThroughCellCentres) {
  const auto mesh = std::make_shared<const TriangleMesh>(makeMesh(
      {Vec3(3, 3, 2), Vec3(3, 3, 0), Vec3(0, 0, 0), Vec3(3.0000009536743164, 2, 3), Vec3(3, 4, 5), Vec3(3, 2, 5)},
      {{0, 1, 2}, {3, 4, 5}}, "fuzz-two-triangles"));
  const ClodSphereSet set = ClodBuilder(mesh).build(0.0);
  const CellGrid grid(*mesh, set, 0.01 * mesh->diagonal());
  std::vector<Vec3> probes = probesNear(*mesh, 0.02, 5);
  probes.push_back(Vec3(3, 3, 0));
  checkGrid(*mesh, grid, probes, "two triangles");
  // A square in the plane x = y, both orientations.
  const auto diag =
      std::make_shared<const TriangleMesh>(makeMesh({Vec3(0, 0, 0), Vec3(1, 1, 0), Vec3(1, 1, 1), Vec3(0, 0, 1)},
                                                    {{0, 1, 2}, {0, 2, 3}, {0, 2, 1}, {0, 3, 2}}, "x=y"));
  const ClodSphereSet diagSet = ClodBuilder(diag).build(0.0);
  for (double radius : {0.005, 0.01, 0.0125, 0.02})
    checkGrid(*diag, CellGrid(*diag, diagSet, radius), probesNear(*diag, 2 * radius, 7),
              "x=y r=" + std::to_string(radius));
}

// Cells of hundreds of candidates (triangles far smaller than a cell, as on a finely subdivided scan): the
// candidates of many z slices, each collected by two threads and sorted apart, keep the contract once merged, and
// the grid is the same whatever the slicing.
TEST(CellGrid, ContractOnCrowdedCells) {
  const auto mesh = std::make_shared<const TriangleMesh>(clod_test::heightField(
      120, [](double x, double y) { return 0.1 * std::sin(3.0 * (x + 1.0)) * std::cos(2.5 * (y + 1.0)); },
      Eigen::Matrix3d::Identity(), Vec3::Zero()));
  const ClodSphereSet set = ClodBuilder(mesh).build(0.02);
  const CellGrid whole(*mesh, set, 0.16);
  const CellGrid sliced(*mesh, set, 0.16, 24.0, CellGrid::Index::Auto, 3000.0);
  EXPECT_GT(whole.largestCell(), 200u);
  std::vector<Vec3> probes = nearSurfaceProbes(*mesh, 600, 0.16, 23);
  EXPECT_GT(checkGrid(*mesh, sliced, probes, "crowded, sliced", &set), 20u);
  ASSERT_EQ(whole.entries(), sliced.entries());
  for (const Vec3& p : probes) {
    const CellGrid::CellRef* a = whole.find(whole.keyOf(p));
    const CellGrid::CellRef* b = sliced.find(sliced.keyOf(p));
    ASSERT_EQ(a == nullptr, b == nullptr);
    if (a == nullptr) continue;
    const CellGrid::Cell ca = whole.cell(*a), cb = sliced.cell(*b);
    ASSERT_EQ(ca.count, cb.count);
    for (std::uint32_t i = 0; i < ca.count; ++i) {
      ASSERT_EQ(ca.entries[i].triangle, cb.entries[i].triangle);
      ASSERT_EQ(ca.entries[i].distance, cb.entries[i].distance);
    }
    EXPECT_EQ(a->halfWidth, b->halfWidth);
  }
}

// The dense bit index and the hash table find the same cells with the same candidates and proofs, and
// a build in many slices gives the same grid as a build in one.
TEST(CellGrid, DenseAndHashedIndexAgree) {
  for (const char* name : {"head.off", "mesh_with_border.off", "degtri_sliding.off"}) {
    SCOPED_TRACE(name);
    const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh(name));
    const ClodSphereSet set = ClodBuilder(mesh).build(0.02);
    const CellGrid dense(*mesh, set, 0.005, 24.0, CellGrid::Index::Dense);
    // Built in many z slices (a few hundred candidates each) rather than the one slice of this size.
    const CellGrid hashed(*mesh, set, 0.005, 24.0, CellGrid::Index::Hashed, 300.0);
    EXPECT_TRUE(dense.dense());
    EXPECT_FALSE(hashed.dense());
    ASSERT_EQ(dense.cells(), hashed.cells());
    ASSERT_EQ(dense.entries(), hashed.entries());
    std::size_t found = 0;
    for (const Vec3& p : probesNear(*mesh, 0.015, 11)) {
      const std::uint64_t key = dense.keyOf(p);
      ASSERT_EQ(key, hashed.keyOf(p));
      const CellGrid::CellRef* a = dense.find(key);
      const CellGrid::CellRef* b = hashed.find(key);
      ASSERT_EQ(a == nullptr, b == nullptr) << p.transpose();
      if (a == nullptr) continue;
      ++found;
      EXPECT_EQ(a->normal[0], b->normal[0]);
      EXPECT_EQ(a->offset, b->offset);
      EXPECT_EQ(a->halfWidth, b->halfWidth);
      const CellGrid::Cell ca = dense.cell(*a), cb = hashed.cell(*b);
      ASSERT_EQ(ca.count, cb.count);
      EXPECT_EQ(ca.spheres, cb.spheres);
      for (std::uint32_t i = 0; i < ca.count; ++i) {
        EXPECT_EQ(ca.entries[i].triangle, cb.entries[i].triangle);
        EXPECT_EQ(ca.entries[i].distance, cb.entries[i].distance);
      }
    }
    EXPECT_GT(found, 1000u);
    // And the hashed grid keeps the contract too.
    checkGrid(*mesh, hashed, probesNear(*mesh, 0.01, 13), std::string(name) + " hashed");
  }
}

// largestCell, which the swept query reads to skip a cell lookup on grids without a crowded cell, is the count of
// the most crowded cell, found here by visiting every cell of the box the candidates can lie in.
TEST(CellGrid, LargestCellIsTheMostCrowdedCell) {
  for (const char* name : {"head.off", "mesh_with_border.off"}) {
    SCOPED_TRACE(name);
    const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh(name));
    const ClodSphereSet set = ClodBuilder(mesh).build(0.02);
    for (double r : {0.005, 0.02}) {
      const CellGrid grid(*mesh, set, r);
      const double margin = grid.radius() + 2.0 * grid.cellSize();
      std::int64_t lo[3], hi[3];
      grid.cellCoordinates(mesh->bounds().min() - Vec3::Constant(margin), lo);
      grid.cellCoordinates(mesh->bounds().max() + Vec3::Constant(margin), hi);
      std::uint32_t largest = 0;
      std::size_t cells = 0;
      for (std::int64_t z = lo[2]; z <= hi[2]; ++z)
        for (std::int64_t y = lo[1]; y <= hi[1]; ++y)
          for (std::int64_t x = lo[0]; x <= hi[0]; ++x) {
            const CellGrid::CellRef* ref = grid.find(grid.keyAt(x, y, z));
            if (ref == nullptr) continue;
            ++cells;
            largest = std::max(largest, grid.cell(*ref).count);
          }
      EXPECT_EQ(cells, grid.cells());  // every cell visited
      EXPECT_GT(largest, 0u);
      EXPECT_EQ(grid.largestCell(), largest);
    }
  }
}

// The cell side is grown beyond its 3 r for the hard memory budget (candidates) only as far as that budget needs: a
// grown grid holds at least 0.4 of its budget of candidates (one growth step of 1.25 fewer would exceed it), a grid
// never much more than the budget (the size target, bytesPerTriangle, is switched off here: see the next test). Long
// thin triangles are the shape a bounding-box estimate gets wrong: it took a sliver for the cube of its length and grew
// the cells of a strip cylinder to 13 r with 5% of the budget used, every cell then listing tens of strips more than
// the pointer can touch.
TEST(CellGrid, CellsGrowOnlyAsFarAsTheBudgetNeeds) {
  // The strip cylinder: at r = 0.005 its cells stay at 3 r, at r = 0.002 they must grow.
  std::vector<std::pair<std::string, std::shared_ptr<const TriangleMesh>>> meshes{
      {"strip cylinder", stripCylinder()},
      {"head.off", clod_test::loadNormalized(clod_test::sharedMesh("head.off"))},
      {"cube.obj", clod_test::loadNormalized(clod_test::testData("cube.obj"))}};
  for (const auto& [name, mesh] : meshes) {
    SCOPED_TRACE(name);
    const ClodSphereSet set = ClodBuilder(mesh).build(0.0);
    for (const double r : {0.005, 0.002}) {
      const double budget = std::max(1e6, 24.0 * static_cast<double>(mesh->size()));
      const CellGrid grid(*mesh, set, r, 24.0, CellGrid::Index::Auto, 1e6, std::numeric_limits<double>::infinity());
      const double entries = static_cast<double>(grid.entries());
      const bool grown = grid.cellSize() > 3.0 * r * (1.0 + 1e-9);
      if (name == "strip cylinder") {
        EXPECT_EQ(grown, r < 0.004) << "cell " << grid.cellSize() / r << " r";
        // And its grid keeps the contract.
        if (r > 0.004) checkGrid(*mesh, grid, probesNear(*mesh, 2 * r, 17), "strips");
      }
      EXPECT_LE(entries, 1.5 * budget) << "r " << r << ", cell " << grid.cellSize() / r << " r";
      if (grown) {
        EXPECT_GE(entries, 0.4 * budget) << "r " << r << ", cell " << grid.cellSize() / r << " r";
      }
    }
  }
}

// Beyond the hard budget, the grid takes coarser cells to fit bytesPerTriangle only where a cell keeps a few
// candidates and at most 2.5 times the side the queries chose: on a mesh of large triangles it shrinks (and keeps the
// contract), on the strip cylinder (slivers 200 r long, tens of them within reach of each cell) it keeps its 3 r.
TEST(CellGrid, CoarserCellsOnlyWhereACellStaysCheap) {
  const auto strip = stripCylinder();
  const auto head = clod_test::loadNormalized(clod_test::sharedMesh("head.off"));
  const double r = 0.005, unlimited = std::numeric_limits<double>::infinity();
  {
    const ClodSphereSet set = ClodBuilder(head).build(0.02);
    const CellGrid fine(*head, set, r, 24.0, CellGrid::Index::Auto, 1e6, unlimited);
    const CellGrid coarse(*head, set, r, 24.0, CellGrid::Index::Auto, 1e6, 64.0);
    const double n = static_cast<double>(head->size());
    EXPECT_GT(coarse.cellSize(), fine.cellSize() * 1.2);
    EXPECT_LE(coarse.cellSize(), 2.5 * fine.cellSize() * (1 + 1e-9));
    EXPECT_LT(static_cast<double>(coarse.bytes()), 0.5 * static_cast<double>(fine.bytes()));
    EXPECT_GT(static_cast<double>(fine.bytes()), 64.0 * n);
    checkGrid(*head, coarse, probesNear(*head, 2 * r, 23), "head, coarse", &set);
  }
  {
    const ClodSphereSet set = ClodBuilder(strip).build(0.0);
    const CellGrid fine(*strip, set, r, 24.0, CellGrid::Index::Auto, 1e6, unlimited);
    const CellGrid small(*strip, set, r, 24.0, CellGrid::Index::Auto, 1e6, 64.0);
    EXPECT_EQ(small.cellSize(), fine.cellSize());
    EXPECT_GT(static_cast<double>(small.bytes()), 64.0 * static_cast<double>(strip->size()));
  }
}

// A grid's bytes as the disk cache writes them: every array and scalar.
std::vector<char> bytesOf(const CellGrid& grid) {
  const detail::CacheMagic magic = {'T', 'E', 'S', 'T', 'G', 'R', 'I', 'D'};
  detail::ByteWriter out(magic, 1);
  grid.writeTo(out);
  return out.bytes();
}

// A level's grid made from another level's grid of the mesh (a change of d) is the grid that level builds, bit for
// bit: the candidates come from the mesh and the radius, each cell's count of distinct spheres from the level. From a
// grid of another radius, or of another mesh, it is built.
TEST(CellGrid, ForLevelIsTheGridThatLevelBuilds) {
  for (const char* name : {"head.off", "mannequin-devil.off", "mesh_with_border.off"}) {
    SCOPED_TRACE(name);
    const auto mesh = clod_test::loadNormalized(clod_test::sharedMesh(name));
    const ClodBuilder builder(mesh);
    const ClodSphereSet fine = builder.build(0.0), coarse = builder.build(0.04);
    const CellGrid fineGrid(*mesh, fine, 0.005), coarseGrid(*mesh, coarse, 0.005);
    ASSERT_NE(bytesOf(fineGrid), bytesOf(coarseGrid));  // the levels' sphere counts differ
    bool reused = false;
    const CellGrid made =
        CellGrid::forLevel(fineGrid, *mesh, coarse, 0.005, 24.0, CellGrid::Index::Auto, 1e6, 192.0, &reused);
    EXPECT_TRUE(reused);
    EXPECT_EQ(bytesOf(made), bytesOf(coarseGrid));
    checkGrid(*mesh, made, probesNear(*mesh, 0.01, 5), name, &coarse);
    // Another radius: built, the same grid.
    const CellGrid wider(*mesh, fine, 0.008);
    EXPECT_EQ(
        bytesOf(CellGrid::forLevel(wider, *mesh, coarse, 0.005, 24.0, CellGrid::Index::Auto, 1e6, 192.0, &reused)),
        bytesOf(coarseGrid));
    EXPECT_FALSE(reused);
  }
  // A grid of another mesh: built (its cells are not this mesh's).
  const auto head = clod_test::loadNormalized(clod_test::sharedMesh("head.off"));
  const auto elephant = clod_test::loadNormalized(clod_test::sharedMesh("elephant.off"));
  const ClodSphereSet set = ClodBuilder(elephant).build(0.02);
  bool reused = true;
  const CellGrid grid = CellGrid::forLevel(CellGrid(*head, ClodBuilder(head).build(0.02), 0.005), *elephant, set, 0.005,
                                           24.0, CellGrid::Index::Auto, 1e6, 192.0, &reused);
  EXPECT_FALSE(reused);
  EXPECT_EQ(bytesOf(grid), bytesOf(CellGrid(*elephant, set, 0.005)));
}

TEST(CellGrid, BadRadiusThrows) {
  const auto mesh = clod_test::loadNormalized(clod_test::testData("cube.obj"));
  const ClodSphereSet set = ClodBuilder(mesh).build(0.0);
  for (double r : {0.0, -1.0, std::nan(""), double(INFINITY)})
    EXPECT_THROW(CellGrid(*mesh, set, r), InvalidParameter) << r;
}

TEST(CellGrid, OutsideKeyForFarPoints) {
  const auto mesh = clod_test::loadNormalized(clod_test::testData("cube.obj"));
  const ClodSphereSet set = ClodBuilder(mesh).build(0.0);
  const CellGrid grid(*mesh, set, 0.01);
  EXPECT_EQ(grid.keyOf(Vec3(100, 0.5, 0.5)), CellGrid::kOutside);
  EXPECT_EQ(grid.keyOf(Vec3(0.5, -100, 0.5)), CellGrid::kOutside);
  EXPECT_EQ(grid.find(CellGrid::kOutside), nullptr);
  EXPECT_NE(grid.find(grid.keyOf(Vec3(0.5, 0.5, 1.0))), nullptr) << "a point on the surface has candidates";
}

#if defined(CLOD_PACKET_AVX2)
// The grid's build encodes its entries four at a time in AVX2 where the CPU has it, and claims the scalar encoders'
// bytes and distance bit for bit on every lane it encodes (the grid is the same on every machine). Distances at and
// beside the codes' steps (whole multiples of the unit, and the float rounding's neighbours), directions at the
// quantisation's half steps, lengths below the tiny limit (left to the scalar path) and far beyond 255 units.
TEST(GridEntriesAvx2, SameBytesAsTheScalarEncodersOnEveryLaneItEncodes) {
  if (!detail::packetAvx2()) GTEST_SKIP() << "no AVX2 on this CPU";
  std::mt19937_64 rng(29);
  std::uniform_real_distribution<double> u(-1.0, 1.0), w(0.0, 300.0);
  const double tiny = 1e-9;
  int encoded = 0, leftOut = 0, onStep = 0, halfStep = 0;
  for (int i = 0; i < 200000; ++i) {
    // Steps that floats hold exactly, and steps that divisions round (the code's correction loop).
    const double unit = i % 2 ? 1.0 / 64.0 : 0.0137, scale = 256.0 / unit;
    Vec3 centres[4];
    const Vec3* at[4];
    detail::ClosestPoints4 q;
    for (int lane = 0; lane < 4; ++lane) {
      Vec3 dir(u(rng), u(rng), u(rng));
      if (dir.norm() < 1e-3) dir = Vec3::UnitX();
      dir.normalize();
      if (i % 5 == 1) {  // one component near a half step of the quantisation, the others scaled to keep |dir| = 1
        const int k = lane % 3;
        const double half = (std::floor(127.0 * dir[k]) + 0.5) / 127.0;
        const double rest = std::sqrt((1.0 - half * half) / std::max(1e-12, 1.0 - dir[k] * dir[k]));
        dir *= rest;
        dir[k] = half;
      }
      double length = w(rng) * unit;
      Vec3 closest(u(rng), u(rng), u(rng));
      if (i % 5 == 2 || i % 5 == 3) {  // along an axis from the origin: the norm is the length, exactly
        closest = Vec3::Zero();
        dir = Vec3::Unit(lane % 3) * (lane < 2 ? 1.0 : -1.0);
        length = std::floor(w(rng)) * unit;                                     // on a step
        if (i % 5 == 3) length = std::nextafter(length, lane % 2 ? 0.0 : 1.0);  // or beside it
      }
      if (i % 97 == 4) length = lane == 0 ? 0.0 : 1e-12;  // not above tiny
      if (i % 89 == 5) length = 1e3 * unit * (lane + 1);  // beyond the last code
      centres[lane] = closest + length * dir;
      at[lane] = &centres[lane];
      for (int k = 0; k < 3; ++k) q.q[k][lane] = closest[k];
    }
    detail::GridEntries4 e;
    const unsigned lanes = detail::gridEntriesAvx2(at, q, unit, scale, tiny, e);
    for (int lane = 0; lane < 4; ++lane) {
      const Vec3 toCentre = centres[lane] - Vec3(q.q[0][lane], q.q[1][lane], q.q[2][lane]);
      const double d = toCentre.norm();
      std::uint64_t bitsGot, bitsWant;
      std::memcpy(&bitsGot, &e.distance[lane], sizeof bitsGot);
      std::memcpy(&bitsWant, &d, sizeof bitsWant);
      ASSERT_EQ(bitsGot, bitsWant) << "case " << i << " lane " << lane;
      if (!(lanes & (1u << lane))) {
        ++leftOut;
        ASSERT_FALSE(d > tiny) << "only a distance the scalar path stores without a direction is left to it";
        continue;
      }
      ++encoded;
      const float rounded = detail::roundDown(d);
      const std::uint8_t code = detail::distanceCode(rounded, unit);
      onStep += static_cast<double>(rounded) == code * unit;
      ASSERT_EQ(e.code[lane], code) << "case " << i << " lane " << lane;
      ASSERT_EQ(e.finer[lane], detail::finerCode(rounded, code, unit, scale)) << "case " << i << " lane " << lane;
      const Vec3 dir = toCentre / d;
      for (int k = 0; k < 3; ++k) {
        halfStep += std::abs(std::abs(127.0 * dir[k] - std::trunc(127.0 * dir[k])) - 0.5) < 1e-9;
        ASSERT_EQ(e.direction[lane][k], detail::quantiseDirection(dir[k])) << "case " << i << " lane " << lane;
      }
    }
  }
  // Units whose division rounds a float distance up onto a whole code (the scalar rounding loop steps back): unit =
  // f / q for a float f, the distance f along an axis (its norm exactly f).
  std::uniform_real_distribution<float> fw(0.01f, 1.0f);
  std::uniform_int_distribution<int> qw(1, 255);
  int stepped = 0;
  for (int i = 0; i < 2000000 && stepped < 500; ++i) {
    const float f = fw(rng);
    const double unit = static_cast<double>(f) / qw(rng), scale = 256.0 / unit;
    const double d = static_cast<double>(f), first = std::min(255.0, std::floor(d / unit));
    if (!(first > 0.0 && first * unit > d)) continue;
    ++stepped;
    Vec3 centres[4];
    const Vec3* at[4];
    detail::ClosestPoints4 q;
    for (int lane = 0; lane < 4; ++lane) {
      centres[lane] = Vec3::Unit(lane % 3) * d;
      at[lane] = &centres[lane];
      for (int k = 0; k < 3; ++k) q.q[k][lane] = 0.0;
    }
    detail::GridEntries4 e;
    ASSERT_EQ(detail::gridEntriesAvx2(at, q, unit, scale, tiny, e), 0xFu);
    const std::uint8_t code = detail::distanceCode(f, unit);
    for (int lane = 0; lane < 4; ++lane) {
      ASSERT_EQ(e.code[lane], code) << f << " / " << unit;
      ASSERT_EQ(e.finer[lane], detail::finerCode(f, code, unit, scale)) << f << " / " << unit;
    }
  }
  EXPECT_GT(stepped, 0) << "no unit made the scalar loop step back";
  EXPECT_GT(encoded, 700000);
  EXPECT_GT(leftOut, 0);      // the tiny lengths do reach the scalar path
  EXPECT_GT(onStep, 1000);    // distances exactly on a code's step were met
  EXPECT_GT(halfStep, 1000);  // and directions within 1e-9 of a half step
}

// The build's cheap bounds, four cells of a column at a time: the same verdict as the scalar test on the same
// centres, also for limits and balls set exactly to a lane's own value (a tie must fall the same way).
TEST(GridEntriesAvx2, ColumnBoundsAsTheScalarBounds) {
  if (!detail::packetAvx2()) GTEST_SKIP() << "no AVX2 on this CPU";
  std::mt19937_64 rng(31);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const double h = 0.021;
  int kept = 0, dropped = 0;
  for (int i = 0; i < 100000; ++i) {
    detail::TriangleBounds b;
    b.planar = i % 7 != 0;
    b.normal = Vec3(u(rng), u(rng), u(rng)).normalized();
    b.corner = Vec3(u(rng), u(rng), u(rng));
    b.mid = b.corner + 0.05 * Vec3(u(rng), u(rng), u(rng));
    const double x = u(rng), y = u(rng), originZ = u(rng);
    const std::int64_t z = static_cast<std::int64_t>(std::floor(100.0 * u(rng)));
    Vec3 centre[4];
    for (int k = 0; k < 4; ++k) centre[k] = Vec3(x, y, originZ + (static_cast<double>(z + k) + 0.5) * h);
    const int tie = i % 4;
    b.limit = i % 3 == 0 ? std::abs(b.normal.dot(centre[tie] - b.corner)) : 0.5 * std::abs(u(rng));
    b.ball2 = i % 3 == 1 ? (centre[tie] - b.mid).squaredNorm() : 2.0 * std::abs(u(rng));
    unsigned want = 0;
    for (int k = 0; k < 4; ++k) {
      const bool keep = !(b.planar && std::abs(b.normal.dot(centre[k] - b.corner)) > b.limit) &&
                        !((centre[k] - b.mid).squaredNorm() > b.ball2);
      want |= static_cast<unsigned>(keep) << k;
    }
    ASSERT_EQ(detail::columnCellsAvx2(x, y, originZ, h, z, b), want) << "case " << i;
    kept += __builtin_popcount(want);
    dropped += 4 - __builtin_popcount(want);
  }
  EXPECT_GT(kept, 10000);
  EXPECT_GT(dropped, 10000);
}
#endif

}  // namespace
