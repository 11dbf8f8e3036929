#include "clod_haptics/core/mesh_loader.h"

#include <cmath>
#include <cctype>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <unordered_map>
#include <utility>

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include "clod_haptics/core/errors.h"
#include "mesh_readers/polygon_soup.h"
#include "mesh_readers/text_scanner.h"

namespace clod_haptics {
namespace {

using detail::PositionHash;

// Walks the node tree so every mesh instance lands in model coordinates.
void collect(const aiScene* scene, const aiNode* node, const aiMatrix4x4& parent, std::vector<Vec3>& vertices,
             std::vector<Triangle>& triangles, std::unordered_map<Vec3, std::uint32_t, PositionHash>& ids,
             bool& nonFinite, std::string& badIndex) {
  const aiMatrix4x4 transform = parent * node->mTransformation;
  for (unsigned m = 0; m < node->mNumMeshes; ++m) {
    const aiMesh* mesh = scene->mMeshes[node->mMeshes[m]];
    std::vector<std::uint32_t> local(mesh->mNumVertices);
    for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
      const aiVector3D q = transform * mesh->mVertices[v];
      const Vec3 p(q.x, q.y, q.z);
      if (!p.allFinite()) {
        nonFinite = true;
        return;
      }
      auto it = ids.emplace(p, static_cast<std::uint32_t>(vertices.size()));
      if (it.second) vertices.push_back(p);
      local[v] = it.first->second;
    }
    for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
      const aiFace& face = mesh->mFaces[f];
      if (face.mNumIndices != 3) continue;  // points and lines carry no surface
      for (unsigned k = 0; k < 3; ++k)
        if (face.mIndices[k] >= mesh->mNumVertices) {
          badIndex = "face " + std::to_string(f) + " refers to vertex " + std::to_string(face.mIndices[k]) + " of " +
                     std::to_string(mesh->mNumVertices);
          return;
        }
      triangles.push_back({local[face.mIndices[0]], local[face.mIndices[1]], local[face.mIndices[2]]});
    }
  }
  for (unsigned c = 0; c < node->mNumChildren; ++c)
    collect(scene, node->mChildren[c], transform, vertices, triangles, ids, nonFinite, badIndex);
}

std::string lowerExtension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

using SoupReader = detail::PolygonSoup (*)(const std::string&, const std::string&);

// The double-precision reader of the file's format, or nullptr for a format left to assimp. A file that starts
// with "ply" goes to the PLY reader whatever its name: assimp 5.2's PLY reader can loop forever on a malformed
// header.
SoupReader readerFor(const std::string& path) {
  const std::string ext = lowerExtension(path);
  if (ext == ".off") return detail::readOff;
  if (ext == ".obj") return detail::readObj;
  if (ext == ".ply") return detail::readPly;
  if (ext == ".stl") return detail::readStl;
  std::ifstream in(path, std::ios::binary);
  char magic[4] = {0, 0, 0, 0};
  in.read(magic, 4);
  if (in.gcount() == 4 && std::memcmp(magic, "ply", 3) == 0 && (magic[3] == '\n' || magic[3] == '\r'))
    return detail::readPly;
  return nullptr;
}

std::pair<std::vector<Vec3>, std::vector<Triangle>> readWithSoupReader(const std::string& path, SoupReader reader) {
  const detail::PolygonSoup soup = reader(path, detail::readWholeFile(path));
  std::pair<std::vector<Vec3>, std::vector<Triangle>> mesh;
  detail::triangulateSoup(soup, mesh.first, mesh.second);
  return mesh;
}

// Every other format, through assimp: its Debian build reads coordinates as float32, hence the warning.
std::pair<std::vector<Vec3>, std::vector<Triangle>> readWithAssimp(const std::string& path) {
  std::clog << "clod_haptics: warning: '" << path << "' is read by assimp in single precision (coordinates rounded "
            << "to float32); OFF, OBJ, PLY and STL are read in double\n";
  Assimp::Importer importer;
  // Join only exact duplicates ourselves (assimp's joining also compares normals and UVs, so an STL's
  // per-face vertices would stay apart); keep degenerate triangles: they must be covered too.
  // ValidateDataStructure runs first and fails the import on out-of-range indices, which some readers
  // pass through and the later steps would read out of bounds.
  const aiScene* scene =
      importer.ReadFile(path, aiProcess_ValidateDataStructure | aiProcess_Triangulate | aiProcess_SortByPType);
  if (scene == nullptr) {
    std::string why = importer.GetErrorString();
    throw MeshLoadError(path, "unreadable format (" + (why.empty() ? std::string("assimp gave no reason") : why) + ")");
  }
  if (scene->mRootNode == nullptr) throw MeshLoadError(path, "the file holds no scene");

  std::pair<std::vector<Vec3>, std::vector<Triangle>> mesh;
  std::unordered_map<Vec3, std::uint32_t, PositionHash> ids;
  bool nonFinite = false;
  std::string badIndex;
  collect(scene, scene->mRootNode, aiMatrix4x4(), mesh.first, mesh.second, ids, nonFinite, badIndex);
  if (nonFinite) throw MeshLoadError(path, "non-finite vertex coordinates (NaN or Inf)");
  if (!badIndex.empty()) throw MeshLoadError(path, "corrupt file: " + badIndex);
  return mesh;
}

}  // namespace

double signedVolume(const TriangleMesh& mesh) {
  const Vec3 c = mesh.bounds().center();
  double v = 0.0;
  for (std::size_t t = 0; t < mesh.size(); ++t)
    v += (mesh.vertex(t, 0) - c).dot((mesh.vertex(t, 1) - c).cross(mesh.vertex(t, 2) - c));
  return v / 6.0;
}

namespace {

// Scales or normalises the file's positions into the mesh's local frame, in place; returns the local origin
// (model = local + origin) and records the transform in scale and offset (model = file * scale + offset). A
// mesh far from zero (chooseLocalOrigin of the file's bounds, o) gets the origin o * scale, and each local
// coordinate is file * scale - origin rounded once: the shape and its place keep the precision of a mesh at
// zero. Normalising puts the mesh in the unit cube (origin zero), centred from exact differences to o.
Vec3 transformVertices(std::vector<Vec3>& vertices, const std::vector<Triangle>& triangles,
                       const MeshLoadOptions& options, const std::string& name, double& scale, Vec3& offset) {
  Eigen::AlignedBox3d box;
  for (const Triangle& t : triangles)
    for (std::uint32_t v : t) box.extend(vertices[v]);
  const Vec3 o = chooseLocalOrigin(box);
  Vec3 origin = Vec3::Zero();
  if (options.normalize) {
    const double extent = box.sizes().maxCoeff();
    if (!(extent > 0.0) || !std::isfinite(extent))
      throw InvalidParameter("mesh '" + name + "' has zero extent and cannot be normalised");
    const double s = 1.0 / extent;
    // The centre relative to o from the exact differences (box.center() would round (min + max) / 2 at the
    // magnitude of the coordinates: 1e-10 off centre at 1e6).
    const Vec3 centre = ((box.min() - o) + (box.max() - o)) / 2.0;
    const Vec3 shift = Vec3::Constant(0.5) - centre * s;
    for (Vec3& v : vertices) v = (v - o) * s + shift;
    scale = s;
    offset = Vec3::Constant(0.5) - box.center() * s;
  } else {
    if (!(options.scale > 0.0) || !std::isfinite(options.scale))
      throw InvalidParameter("scale must be finite and positive, got " + std::to_string(options.scale));
    // local = v * scale - origin with one rounding (fma keeps the product exact): the model frame's vertex,
    // the file's number times the scale, is local + origin to a unit in the last place of the local value.
    origin = o * options.scale;
    for (Vec3& v : vertices)
      for (int k = 0; k < 3; ++k) v[k] = std::fma(v[k], options.scale, -origin[k]);
    scale = options.scale;
    offset.setZero();
  }
  for (const Vec3& v : vertices)
    if (!v.allFinite()) throw InvalidParameter("mesh '" + name + "': scaling overflowed to a non-finite value");
  if (!origin.allFinite()) throw InvalidParameter("mesh '" + name + "': scaling overflowed to a non-finite value");
  return origin;
}

}  // namespace

void transformMesh(TriangleMesh& mesh, const MeshLoadOptions& options) {
  std::vector<Vec3> model = mesh.vertices;
  for (Vec3& v : model) v = mesh.toModel(v);
  double scale = 1.0;
  Vec3 offset = Vec3::Zero();
  const Vec3 origin = transformVertices(model, mesh.triangles, options, mesh.name, scale, offset);
  TriangleMesh moved = makeLocalMesh(std::move(model), mesh.triangles, mesh.name, origin);
  mesh.vertices = std::move(moved.vertices);
  mesh.origin = moved.origin;
  mesh.normals = std::move(moved.normals);
  mesh.scale = scale;
  mesh.offset = offset;
}

TriangleMesh loadMesh(const std::string& path, const MeshLoadOptions& options) {
  if (!options.normalize && (!(options.scale > 0.0) || !std::isfinite(options.scale)))
    throw InvalidParameter("scale must be finite and positive, got " + std::to_string(options.scale));
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw MeshLoadError(path, "no such file");
  if (std::filesystem::is_directory(path, ec)) throw MeshLoadError(path, "is a directory, not a mesh file");
  if (!std::ifstream(path).good()) throw MeshLoadError(path, "file cannot be opened for reading");

  const SoupReader reader = readerFor(path);
  auto [vertices, triangles] = reader != nullptr ? readWithSoupReader(path, reader) : readWithAssimp(path);
  if (triangles.empty()) throw MeshLoadError(path, "no triangles");

  std::string name = std::filesystem::path(path).filename().string();
  double scale = 1.0;
  Vec3 offset = Vec3::Zero();
  const Vec3 origin = transformVertices(vertices, triangles, options, name, scale, offset);
  TriangleMesh mesh = makeLocalMesh(std::move(vertices), std::move(triangles), name, origin);
  mesh.scale = scale;
  mesh.offset = offset;
  if (options.orientOutward && signedVolume(mesh) < 0.0) {
    for (Triangle& t : mesh.triangles) std::swap(t[1], t[2]);
    for (Vec3& n : mesh.normals) n = -n;
    mesh.flipped = true;
  }
  return mesh;
}

}  // namespace clod_haptics
