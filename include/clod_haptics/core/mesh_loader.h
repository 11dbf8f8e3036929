#pragma once

#include <string>

#include "clod_haptics/core/mesh.h"

namespace clod_haptics {

/** \brief How a mesh file is turned into model coordinates. */
struct MeshLoadOptions {
  /** \brief Uniform factor applied to the file's coordinates (ignored when normalize is set). */
  double scale = 1.0;
  /**
   * \brief Fit the model into the unit cube [0, 1]^3: centred, its largest extent scaled to 1, aspect
   * kept. The paper's clustering distances 0 to 0.08 assume a model of about that size.
   */
  bool normalize = false;
  /**
   * \brief Reverse every triangle's winding when the mesh's signed volume is negative, so normals
   * point outward: the paper's rays go inward along -n and the contact normal pushes the stylus out.
   * The test is global (one decision for the whole mesh); it is meaningful for closed or nearly
   * closed meshes and harmless for open ones.
   */
  bool orientOutward = true;
};

/** \brief Signed volume of the mesh relative to its bounds' centre (negative: normals point inward). */
double signedVolume(const TriangleMesh& mesh);

/**
 * \brief Loads a triangle mesh: OFF, OBJ, PLY (ASCII and binary) and STL (ASCII and binary) in double
 * precision, exactly the file's numbers, by strict readers; any other format assimp reads (DAE, ...) through
 * assimp, in single precision, with a one-line warning on std::clog. Polygons are triangulated (quads as assimp
 * splits them; larger polygons by ear clipping in their plane, so a non-convex one stays inside its outline, and
 * beyond 1024 corners, or without a plane, as a fan), node transforms applied, all meshes merged and vertices
 * at identical positions joined. The model frame is the file's frame times options.scale (or the unit cube when
 * normalising); a mesh far from its frame's zero is stored relative to its centre (TriangleMesh::origin,
 * chooseLocalOrigin), subtracted from the file's numbers before scaling, so it keeps the precision of a mesh
 * at zero: at scale 1, local + origin gives back the file's numbers exactly.
 * \throws MeshLoadError for a missing file, a file that is not in its format, a header that does not match the
 * data (counts, sizes), a face index outside the vertices, a coordinate that is not a finite number, or no
 * triangles; the message names the file, and the line or byte and the problem.
 * \throws InvalidParameter for a scale that is not finite and positive.
 */
TriangleMesh loadMesh(const std::string& path, const MeshLoadOptions& options = {});

/** \brief Applies a uniform scale, or the unit-cube normalisation, in place (used by loadMesh). */
void transformMesh(TriangleMesh& mesh, const MeshLoadOptions& options);

}  // namespace clod_haptics
