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

void transformMesh(TriangleMesh& mesh, const MeshLoadOptions& options) {
  if (options.normalize) {
    const Eigen::AlignedBox3d box = mesh.bounds();
    const double extent = box.sizes().maxCoeff();
    if (!(extent > 0.0) || !std::isfinite(extent))
      throw InvalidParameter("mesh '" + mesh.name + "' has zero extent and cannot be normalised");
    const double s = 1.0 / extent;
    const Vec3 offset = Vec3::Constant(0.5) - box.center() * s;
    for (Vec3& v : mesh.vertices) v = v * s + offset;
    mesh.scale = s;
    mesh.offset = offset;
  } else {
    if (!(options.scale > 0.0) || !std::isfinite(options.scale))
      throw InvalidParameter("scale must be finite and positive, got " + std::to_string(options.scale));
    if (options.scale != 1.0)
      for (Vec3& v : mesh.vertices) v *= options.scale;
    mesh.scale = options.scale;
    mesh.offset.setZero();
  }
  for (const Vec3& v : mesh.vertices)
    if (!v.allFinite()) throw InvalidParameter("mesh '" + mesh.name + "': scaling overflowed to a non-finite value");
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t)
    mesh.normals[t] = faceNormal(mesh.vertex(t, 0), mesh.vertex(t, 1), mesh.vertex(t, 2));
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
  TriangleMesh mesh = makeMesh(std::move(vertices), std::move(triangles), name);
  transformMesh(mesh, options);
  if (options.orientOutward && signedVolume(mesh) < 0.0) {
    for (Triangle& t : mesh.triangles) std::swap(t[1], t[2]);
    for (Vec3& n : mesh.normals) n = -n;
    mesh.flipped = true;
  }
  return mesh;
}

}  // namespace clod_haptics
