#pragma once

// The double-precision readers of OFF, OBJ, PLY and STL, and what they hand the loader: positions as the file
// writes them (parsed with strtod, so every decimal text rounds once, to the nearest double) and polygons
// indexing them. Each reader is strict: a file that does not say exactly one mesh is a MeshLoadError naming
// the line or byte and the problem, never a clamped index, a padded face list or a guess.
//
// Why hand-written and not a library: CGAL's polygon-soup readers (read_OFF / read_PLY / read_STL), OpenMesh's
// readers and tinyobjloader report failure as a bool or a log line, not as a reason the caller can show; CGAL
// resizes to the header's counts before reading (a header claiming 2e9 vertices allocates gigabytes) and does
// not check face indices of a soup; OpenMesh joins faces into a half-edge structure that drops non-manifold
// faces (a different mesh). Each reader here checks the header's counts against the file's size before it
// reserves anything.

#include <cstdint>
#include <string>
#include <vector>

#include "clod_haptics/core/mesh.h"

namespace clod_haptics {
namespace detail {

/** \brief Positions and polygons of a mesh file, before triangulation and joining. */
struct PolygonSoup {
  std::vector<Vec3> positions;
  std::vector<std::uint32_t> corners;  ///< every polygon's position indices, one polygon after the other
  std::vector<std::size_t> ends;       ///< polygon p is corners[ends[p-1] (0 for p = 0), ends[p])
  /**
   * \brief Join positions in file order and keep unused ones (OFF, PLY), rather than in the order faces first
   * use them (OBJ, STL): the order the meshes' vertices had when assimp read these formats.
   */
  bool fileOrder = false;

  /** \brief Ends the polygon whose corners were pushed since the last one; fewer than 3 carry no surface. */
  void closePolygon(std::size_t start) {
    if (corners.size() - start < 3)
      corners.resize(start);
    else
      ends.push_back(corners.size());
  }
};

/** \brief Hash of a position for joining identical vertices (+0 and -0 hash alike, as they compare equal). */
struct PositionHash {
  std::size_t operator()(const Vec3& v) const;
};

/**
 * \brief Triangles and joined vertices of a soup: quads split as assimp did; polygons of 5 to 1024 corners ear
 * clipped in their Newell plane, keeping their winding, so a non-convex one stays inside its outline (a fan
 * would not); larger ones, and those with no plane (corners on a line), fanned from corner 0. The cap bounds
 * the O(n^2) ear clipping: one million-corner polygon in a hostile file would otherwise never finish.
 */
void triangulateSoup(const PolygonSoup& soup, std::vector<Vec3>& vertices, std::vector<Triangle>& triangles);

/** \brief Reads an ASCII OFF file (also COFF, NOFF, STOFF: the extra per-vertex values are skipped). */
PolygonSoup readOff(const std::string& path, const std::string& bytes);
/** \brief Reads an OBJ file's vertices and faces (v, v/vt, v//vn, v/vt/vn, negative relative indices). */
PolygonSoup readObj(const std::string& path, const std::string& bytes);
/** \brief Reads a PLY file, ASCII or binary of either byte order. */
PolygonSoup readPly(const std::string& path, const std::string& bytes);
/** \brief Reads an STL file, ASCII or binary (told apart by the binary size rule, then by "solid"). */
PolygonSoup readStl(const std::string& path, const std::string& bytes);

}  // namespace detail
}  // namespace clod_haptics
