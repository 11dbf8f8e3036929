// TriangleMesh's adjacency (computeAdjacency): neighbours across manifold edges only, corners with their
// angles, and that both survive the loader's later edits (normalising, reversing every winding).

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <unistd.h>

#include "clod_haptics/core/brute_force.h"
#include "clod_haptics/core/contact.h"
#include "clod_haptics/core/mesh.h"
#include "clod_haptics/core/mesh_loader.h"
#include "test_helpers.h"

namespace {

using namespace clod_haptics;

bool hasVertex(const Triangle& t, std::uint32_t v) { return t[0] == v || t[1] == v || t[2] == v; }

// The adjacency from its definition: for every triangle and edge, the other triangles holding both ends.
void expectClosedManifoldAdjacency(const TriangleMesh& mesh) {
  ASSERT_EQ(mesh.neighbours.size(), mesh.size());
  ASSERT_EQ(mesh.cornerOffsets.size(), mesh.vertices.size() + 1);
  ASSERT_EQ(mesh.cornerTriangles.size(), 3 * mesh.size());
  for (std::size_t t = 0; t < mesh.size(); ++t) {
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = mesh.triangles[t][k], b = mesh.triangles[t][(k + 1) % 3];
      std::vector<std::int32_t> sharing;
      for (std::size_t o = 0; o < mesh.size(); ++o)
        if (o != t && hasVertex(mesh.triangles[o], a) && hasVertex(mesh.triangles[o], b))
          sharing.push_back(std::int32_t(o));
      ASSERT_EQ(sharing.size(), 1u) << "closed manifold: one triangle across each edge";
      int listed = 0;
      for (std::int32_t n : mesh.neighbours[t]) listed += n == sharing[0];
      EXPECT_EQ(listed, 1) << "triangle " << t << " edge " << k;
    }
  }
  for (std::size_t v = 0; v < mesh.vertices.size(); ++v)
    for (std::uint32_t c = mesh.cornerOffsets[v]; c < mesh.cornerOffsets[v + 1]; ++c)
      EXPECT_TRUE(hasVertex(mesh.triangles[mesh.cornerTriangles[c]], std::uint32_t(v)));
}

TEST(Adjacency, BoxIsClosedAndItsCornersAddUpToThreeRightAngles) {
  const TriangleMesh mesh = loadMesh(clod_test::testData("box_4x2x1.obj"));
  expectClosedManifoldAdjacency(mesh);
  for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
    double sum = 0.0;
    for (std::uint32_t c = mesh.cornerOffsets[v]; c < mesh.cornerOffsets[v + 1]; ++c) sum += mesh.cornerAngles[c];
    EXPECT_NEAR(sum, 1.5 * M_PI, 1e-6) << "vertex " << v;
  }
}

TEST(Adjacency, TorusIsClosed) { expectClosedManifoldAdjacency(loadMesh(CLOD_PACKAGE_DATA_DIR "/meshes/torus.obj")); }

// Two apexes (vertices 0 and 1, the lowest ids, so each holds the edges to all 100 rim vertices) over a 100-gon:
// a vertex with hundreds of edges, which the edges' sort orders apart from the few of an ordinary vertex.
TEST(Adjacency, BipyramidWithHundredsOfEdgesAtEachApexIsClosed) {
  const std::uint32_t rim = 100;
  std::vector<Vec3> vertices{Vec3(0, 0, 1), Vec3(0, 0, -1)};
  std::vector<Triangle> triangles;
  for (std::uint32_t i = 0; i < rim; ++i) {
    const double a = 2.0 * M_PI * i / rim;
    vertices.push_back(Vec3(std::cos(a), std::sin(a), 0.0));
    const std::uint32_t v = 2 + i, w = 2 + (i + 1) % rim;
    triangles.push_back({0, v, w});
    triangles.push_back({1, w, v});
  }
  expectClosedManifoldAdjacency(makeMesh(vertices, triangles, "bipyramid"));
}

TEST(Adjacency, BoundaryNonManifoldAndInconsistentEdgesHaveNoNeighbour) {
  // Two triangles sharing edge (1, 2), wound consistently: linked; their outer edges are a boundary.
  TriangleMesh m = makeMesh({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(1, 1, 0)}, {{0, 1, 2}, {2, 1, 3}});
  EXPECT_EQ(m.neighbours[0], (std::array<std::int32_t, 3>{1, -1, -1}));
  EXPECT_EQ(m.neighbours[1], (std::array<std::int32_t, 3>{0, -1, -1}));
  // The same pair wound inconsistently: no inside to speak of, no neighbour.
  m = makeMesh({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(1, 1, 0)}, {{0, 1, 2}, {1, 2, 3}});
  EXPECT_EQ(m.neighbours[0], (std::array<std::int32_t, 3>{-1, -1, -1}));
  // Three triangles on one edge (non-manifold): none of them is linked across it.
  m = makeMesh({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, -1, 0), Vec3(0, 0, 1)},
               {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}});
  for (const auto& n : m.neighbours) EXPECT_EQ(n, (std::array<std::int32_t, 3>{-1, -1, -1}));
  // There the edge's pseudo-normal is the face's own normal.
  EXPECT_EQ(pseudoNormal(m, 0, {TriangleFeature::Edge, 0}), m.normals[0]);
  // A repeated index is no edge; the corners still list the triangle.
  m = makeMesh({Vec3(0, 0, 0), Vec3(1, 0, 0)}, {{0, 1, 1}});
  EXPECT_EQ(m.neighbours[0], (std::array<std::int32_t, 3>{-1, -1, -1}));
  EXPECT_EQ(m.cornerOffsets, (std::vector<std::uint32_t>{0, 1, 3}));
}

// The loader builds the mesh, then normalises it and reverses every winding of an inside-out file: the
// adjacency, made before, must still give the right side everywhere.
TEST(Adjacency, SurvivesTheLoadersNormalisingAndFlip) {
  const std::string path =
      (std::filesystem::temp_directory_path() / ("clod_inside_out_box_" + std::to_string(::getpid()) + ".obj")).string();
  {
    std::ifstream in(clod_test::testData("box_4x2x1.obj"));
    std::ofstream out(path);
    std::string line;
    while (std::getline(in, line)) {
      if (line.rfind("f ", 0) == 0) {  // reverse the winding: inside out
        std::istringstream f(line.substr(2));
        std::string a, b, c;
        f >> a >> b >> c;
        line = "f " + a + " " + c + " " + b;
      }
      out << line << "\n";
    }
  }
  MeshLoadOptions options;
  options.normalize = true;
  const TriangleMesh mesh = loadMesh(path, options);
  std::filesystem::remove(path);
  ASSERT_TRUE(mesh.flipped);
  expectClosedManifoldAdjacency(mesh);
  // Normalised: x 0..1, y 0.25..0.75, z 0.375..0.625. Probes near every edge and corner and inside.
  const Eigen::AlignedBox3d box = mesh.bounds();
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-0.1, 1.1);
  int inside = 0;
  for (int k = 0; k < 4000; ++k) {
    const Vec3 p(u(rng), 0.2 + 0.6 * (u(rng) + 0.1) / 1.2, 0.3 + 0.4 * (u(rng) + 0.1) / 1.2);
    const ContactResult c = bruteForceQuery(mesh, p, 10.0);
    ASSERT_TRUE(c.contact);
    const bool truth = (p.array() > box.min().array()).all() && (p.array() < box.max().array()).all();
    ASSERT_EQ(c.inside, truth) << p.transpose();
    inside += truth;
  }
  EXPECT_GT(inside, 500);
}

}  // namespace
