#include "clod_haptics/core/mesh_loader.h"

#include <cmath>
#include <cstring>
#include <filesystem>
#include <cctype>
#include <fstream>
#include <sstream>
#include <unordered_map>

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include "clod_haptics/core/errors.h"

namespace clod_haptics {
namespace {

struct PositionHash {
  std::size_t operator()(const Vec3& v) const {
    std::size_t h = 1469598103934665603ull;
    for (int k = 0; k < 3; ++k) {
      double x = v[k] == 0.0 ? 0.0 : v[k];  // +0 and -0 are one position
      std::uint64_t bits;
      std::memcpy(&bits, &x, sizeof bits);
      h = (h ^ bits) * 1099511628211ull;
    }
    return h;
  }
};
struct PositionEqual {
  bool operator()(const Vec3& a, const Vec3& b) const { return a == b; }
};

// Walks the node tree so every mesh instance lands in model coordinates.
void collect(const aiScene* scene, const aiNode* node, const aiMatrix4x4& parent, std::vector<Vec3>& vertices,
             std::vector<Triangle>& triangles, std::unordered_map<Vec3, std::uint32_t, PositionHash, PositionEqual>& ids,
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

// assimp 5.2's PLY reader can loop forever on a malformed header, so the header is checked first:
// "ply", a format line, element lines with a count, property lines and end_header, within 64 KiB.
// Returns an empty string when it is well formed, or why it is not.
std::string plyHeaderProblem(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string line;
  std::size_t read = 0, lineNo = 0;
  bool format = false;
  while (std::getline(in, line)) {
    read += line.size() + 1;
    ++lineNo;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream words(line);
    std::string word;
    words >> word;
    if (lineNo == 1) {
      if (word != "ply") return "first line is not 'ply'";
      continue;
    }
    if (word == "end_header") return format ? "" : "no format line before end_header";
    if (word == "comment" || word == "obj_info" || word.empty()) {
    } else if (word == "format") {
      std::string kind, version;
      words >> kind >> version;
      if ((kind != "ascii" && kind != "binary_little_endian" && kind != "binary_big_endian") || version.empty())
        return "line " + std::to_string(lineNo) + ": unknown format '" + line + "'";
      format = true;
    } else if (word == "element") {
      std::string name, count;
      words >> name >> count;
      if (name.empty() || count.empty() || count.find_first_not_of("0123456789") != std::string::npos)
        return "line " + std::to_string(lineNo) + ": malformed element line '" + line + "'";
    } else if (word == "property") {
      std::string type, name;
      words >> type >> name;
      if (type.empty() || name.empty()) return "line " + std::to_string(lineNo) + ": malformed property line";
    } else {
      return "line " + std::to_string(lineNo) + ": unexpected '" + word + "' in the header";
    }
    if (read > 65536) break;
  }
  return "no end_header within the first 64 KiB";
}

bool looksLikePly(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char magic[3] = {0, 0, 0};
  in.read(magic, 3);
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext == ".ply" || (in.gcount() == 3 && magic[0] == 'p' && magic[1] == 'l' && magic[2] == 'y');
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

  if (looksLikePly(path)) {
    const std::string problem = plyHeaderProblem(path);
    if (!problem.empty()) throw MeshLoadError(path, "malformed PLY header: " + problem);
  }

  Assimp::Importer importer;
  // Join only exact duplicates ourselves (assimp's joining also compares normals and UVs, so an STL's
  // per-face vertices would stay apart); keep degenerate triangles: they must be covered too.
  // ValidateDataStructure runs first and fails the import on out-of-range indices, which the PLY
  // reader passes through and the later steps would read out of bounds.
  const aiScene* scene =
      importer.ReadFile(path, aiProcess_ValidateDataStructure | aiProcess_Triangulate | aiProcess_SortByPType);
  if (scene == nullptr) {
    std::string why = importer.GetErrorString();
    throw MeshLoadError(path, "unreadable format (" + (why.empty() ? std::string("assimp gave no reason") : why) + ")");
  }
  if (scene->mRootNode == nullptr) throw MeshLoadError(path, "the file holds no scene");

  std::vector<Vec3> vertices;
  std::vector<Triangle> triangles;
  std::unordered_map<Vec3, std::uint32_t, PositionHash, PositionEqual> ids;
  bool nonFinite = false;
  std::string badIndex;
  collect(scene, scene->mRootNode, aiMatrix4x4(), vertices, triangles, ids, nonFinite, badIndex);
  if (nonFinite) throw MeshLoadError(path, "non-finite vertex coordinates (NaN or Inf)");
  if (!badIndex.empty()) throw MeshLoadError(path, "corrupt file: " + badIndex);
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
