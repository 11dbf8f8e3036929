#include "clod_haptics/core/mesh.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "clod_haptics/core/errors.h"

namespace clod_haptics {

Eigen::AlignedBox3d TriangleMesh::bounds() const {
  Eigen::AlignedBox3d box;
  for (const Triangle& t : triangles)
    for (std::uint32_t v : t) box.extend(vertices[v]);
  return box;
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

TriangleMesh makeMesh(std::vector<Vec3> vertices, std::vector<Triangle> triangles, std::string name) {
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
  mesh.normals.resize(mesh.triangles.size());
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t)
    mesh.normals[t] = faceNormal(mesh.vertex(t, 0), mesh.vertex(t, 1), mesh.vertex(t, 2));
  return mesh;
}

}  // namespace clod_haptics
