#include "clod_haptics/core/mesh.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "clod_haptics/core/errors.h"

namespace clod_haptics {

Eigen::AlignedBox3d TriangleMesh::bounds() const {
  Eigen::AlignedBox3d box;
  for (const Triangle& t : triangles)
    for (std::uint32_t v : t) box.extend(vertices[v]);
  return box;
}

Vec3 chooseLocalOrigin(const Eigen::AlignedBox3d& box) {
  Vec3 origin = Vec3::Zero();
  if (box.isEmpty()) return origin;
  const double side = box.sizes().maxCoeff();
  const Vec3 centre = box.center();
  for (int k = 0; k < 3; ++k)
    if (std::abs(centre[k]) > 4.0 * side) origin[k] = centre[k];
  return origin;
}

Vec3 faceNormal(const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 e0 = b - a, e1 = c - a, e2 = c - b;
  const Vec3 n = e0.cross(e1);
  const double len = n.norm();
  // Area relative to the longest edge squared: below this the direction is rounding noise.
  const double scale = std::max({e0.squaredNorm(), e1.squaredNorm(), e2.squaredNorm()});
  if (!(len > 1e-12 * scale) || !std::isfinite(len)) return Vec3::Zero();
  return n / len;
}

void computeAdjacency(TriangleMesh& mesh) {
  const std::size_t nt = mesh.triangles.size(), nv = mesh.vertices.size();
  // Edges as (lower id, higher id, triangle, direction); sorted, the triangles of one edge are adjacent.
  struct HalfEdge {
    std::uint32_t lo, hi, triangle;
    bool forward;  // the triangle runs lo -> hi
  };
  // Sorted by (lo, hi, triangle): a counting sort by lo (triangles ascending within each lo, as they are met),
  // then each lo's few edges by hi by insertion, which keeps the triangles' order: linear in the edges, where a
  // comparison sort of the millions of a large mesh was most of its adjacency's cost.
  std::vector<std::uint32_t> start(nv + 1, 0);
  for (std::size_t t = 0; t < nt; ++t)
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = mesh.triangles[t][k], b = mesh.triangles[t][(k + 1) % 3];
      if (a != b) ++start[std::min(a, b) + 1];
    }
  for (std::size_t v = 0; v < nv; ++v) start[v + 1] += start[v];
  std::vector<HalfEdge> edges(start[nv]);
  {
    std::vector<std::uint32_t> next(start.begin(), start.end() - 1);
    for (std::size_t t = 0; t < nt; ++t)
      for (int k = 0; k < 3; ++k) {
        const std::uint32_t a = mesh.triangles[t][k], b = mesh.triangles[t][(k + 1) % 3];
        if (a == b) continue;  // a repeated index is no edge
        edges[next[std::min(a, b)]++] = {std::min(a, b), std::max(a, b), static_cast<std::uint32_t>(t), a < b};
      }
  }
  for (std::size_t v = 0; v < nv; ++v) {
    if (start[v + 1] - start[v] > 32) {  // a fan's centre (thousands of edges): no quadratic insertion
      std::sort(edges.begin() + start[v], edges.begin() + start[v + 1], [](const HalfEdge& x, const HalfEdge& y) {
        return x.hi != y.hi ? x.hi < y.hi : x.triangle < y.triangle;
      });
      continue;
    }
    for (std::uint32_t i = start[v] + 1; i < start[v + 1]; ++i) {
      const HalfEdge e = edges[i];
      std::uint32_t j = i;
      for (; j > start[v] && edges[j - 1].hi > e.hi; --j) edges[j] = edges[j - 1];
      edges[j] = e;
    }
  }
  mesh.neighbours.assign(nt, {-1, -1, -1});
  auto link = [&](std::uint32_t t, std::uint32_t other) {
    for (std::int32_t& slot : mesh.neighbours[t])
      if (slot < 0) {
        slot = static_cast<std::int32_t>(other);
        return;
      }
  };
  for (std::size_t i = 0; i < edges.size();) {
    std::size_t j = i + 1;
    while (j < edges.size() && edges[j].lo == edges[i].lo && edges[j].hi == edges[i].hi) ++j;
    // Manifold: exactly two distinct triangles, traversing the edge in opposite directions.
    if (j - i == 2 && edges[i].triangle != edges[i + 1].triangle && edges[i].forward != edges[i + 1].forward) {
      link(edges[i].triangle, edges[i + 1].triangle);
      link(edges[i + 1].triangle, edges[i].triangle);
    }
    i = j;
  }

  // Corners per vertex (counting sort: triangles ascending within each vertex), with their angles.
  mesh.cornerOffsets.assign(nv + 1, 0);
  for (const Triangle& t : mesh.triangles)
    for (std::uint32_t v : t) ++mesh.cornerOffsets[v + 1];
  for (std::size_t v = 0; v < nv; ++v) mesh.cornerOffsets[v + 1] += mesh.cornerOffsets[v];
  mesh.cornerTriangles.assign(3 * nt, 0);
  mesh.cornerAngles.assign(3 * nt, 0.0f);
  std::vector<std::uint32_t> fill(mesh.cornerOffsets.begin(), mesh.cornerOffsets.end() - 1);
  for (std::size_t t = 0; t < nt; ++t)
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t v = mesh.triangles[t][k];
      const Vec3 e1 = mesh.vertex(t, (k + 1) % 3) - mesh.vertices[v],
                 e2 = mesh.vertex(t, (k + 2) % 3) - mesh.vertices[v];
      // atan2 of |cross| and dot: accurate for every angle, 0 for a zero-length edge.
      const double angle = std::atan2(e1.cross(e2).norm(), e1.dot(e2));
      const std::uint32_t slot = fill[v]++;
      mesh.cornerTriangles[slot] = static_cast<std::uint32_t>(t);
      mesh.cornerAngles[slot] = std::isfinite(angle) ? static_cast<float>(angle) : 0.0f;
    }
}

namespace {

TriangleMesh validatedMesh(std::vector<Vec3> vertices, std::vector<Triangle> triangles, std::string name) {
  if (triangles.empty()) throw InvalidParameter("mesh '" + name + "' has no triangles");
  for (std::size_t i = 0; i < vertices.size(); ++i)
    if (!vertices[i].allFinite())
      throw InvalidParameter("mesh '" + name + "': vertex " + std::to_string(i) + " has a non-finite coordinate");
  for (std::size_t t = 0; t < triangles.size(); ++t)
    for (std::uint32_t v : triangles[t])
      if (v >= vertices.size())
        throw InvalidParameter("mesh '" + name + "': triangle " + std::to_string(t) + " refers to vertex " +
                               std::to_string(v) + " of " + std::to_string(vertices.size()));
  TriangleMesh mesh;
  mesh.name = std::move(name);
  mesh.vertices = std::move(vertices);
  mesh.triangles = std::move(triangles);
  return mesh;
}

void finishMesh(TriangleMesh& mesh) {
  mesh.normals.resize(mesh.triangles.size());
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t)
    mesh.normals[t] = faceNormal(mesh.vertex(t, 0), mesh.vertex(t, 1), mesh.vertex(t, 2));
  computeAdjacency(mesh);
}

}  // namespace

TriangleMesh makeMesh(std::vector<Vec3> vertices, std::vector<Triangle> triangles, std::string name) {
  TriangleMesh mesh = validatedMesh(std::move(vertices), std::move(triangles), std::move(name));
  mesh.origin = chooseLocalOrigin(mesh.bounds());
  if (!mesh.origin.isZero(0.0))
    for (Vec3& v : mesh.vertices) v -= mesh.origin;  // exact: see chooseLocalOrigin
  finishMesh(mesh);
  return mesh;
}

TriangleMesh makeLocalMesh(std::vector<Vec3> localVertices, std::vector<Triangle> triangles, std::string name,
                           const Vec3& origin) {
  if (!origin.allFinite()) throw InvalidParameter("mesh '" + name + "': the local origin is not finite");
  TriangleMesh mesh = validatedMesh(std::move(localVertices), std::move(triangles), std::move(name));
  mesh.origin = origin;
  finishMesh(mesh);
  return mesh;
}

}  // namespace clod_haptics
