#include "clod_haptics/core/mesh_cache.h"

#include <chrono>
#include <cmath>
#include <filesystem>
#include <vector>

#include "binary_io.h"
#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/mesh_box_tree.h"

namespace clod_haptics {

namespace {

using detail::ByteReader;

constexpr detail::CacheMagic kMagic = {'C', 'L', 'O', 'D', 'M', 'S', 'H', '\0'};
constexpr const char* kKind = "mesh cache";

/** The same validity makeMesh guarantees: indices in range, coordinates finite. */
void checkMesh(const ByteReader& r, const TriangleMesh& mesh) {
  for (const Vec3& v : mesh.vertices)
    if (!v.allFinite()) r.fail("a vertex is not finite");
  for (const Triangle& t : mesh.triangles)
    for (std::uint32_t v : t)
      if (v >= mesh.vertices.size()) r.fail("a vertex index is out of range");
  // faceNormal's: unit, or zero for a triangle of no area. Placement and the inside test take them as unit vectors.
  for (const Vec3& n : mesh.normals)
    if (!n.allFinite() || !(n.isZero(0.0) || std::abs(n.squaredNorm() - 1.0) < 1e-9))
      r.fail("a normal is neither a unit vector nor zero");
  if (!std::isfinite(mesh.scale) || !mesh.offset.allFinite() || !mesh.origin.allFinite())
    r.fail("scale, offset or origin not finite");
  // The adjacency as computeAdjacency leaves it: whatever a query indexes with it stays in range.
  const auto nt = static_cast<std::int64_t>(mesh.triangles.size());
  for (const auto& n : mesh.neighbours)
    for (std::int32_t t : n)
      if (t < -1 || t >= nt) r.fail("a neighbour index is out of range");
  const std::vector<std::uint32_t>& offsets = mesh.cornerOffsets;
  if (offsets.front() != 0 || offsets.back() != mesh.cornerTriangles.size())
    r.fail("the corner offsets do not span the corners");
  for (std::size_t v = 0; v + 1 < offsets.size(); ++v)
    if (offsets[v] > offsets[v + 1]) r.fail("the corner offsets are not ascending");
  for (std::uint32_t t : mesh.cornerTriangles)
    if (t >= mesh.triangles.size()) r.fail("a corner's triangle is out of range");
  for (float a : mesh.cornerAngles)
    if (!std::isfinite(a)) r.fail("a corner angle is not finite");
}

}  // namespace

std::uint64_t meshSourceKey(const std::string& path, const MeshLoadOptions& options) {
  std::vector<char> bytes;
  if (!detail::readFileBytes(path, bytes).empty()) throw MeshLoadError(path, "cannot read the file");
  const std::uint64_t header[2] = {bytes.size(), kMeshCacheFormatVersion};
  std::uint64_t h = fnv1a64(header, sizeof(header));
  h = fnv1a64(bytes.data(), bytes.size(), h);
  const double scale = options.scale;
  const unsigned char flags[2] = {static_cast<unsigned char>(options.normalize),
                                  static_cast<unsigned char>(options.orientOutward)};
  h = fnv1a64(&scale, sizeof(scale), h);
  return fnv1a64(flags, sizeof(flags), h);
}

void writeMeshBinary(const TriangleMesh& mesh, std::uint64_t sourceKey, const std::string& path) {
  if (mesh.normals.size() != mesh.triangles.size() || mesh.neighbours.size() != mesh.triangles.size() ||
      mesh.cornerOffsets.size() != mesh.vertices.size() + 1 ||
      mesh.cornerAngles.size() != mesh.cornerTriangles.size()) {
    throw FormatError("cannot write mesh cache file '" + path +
                      "': normals, adjacency or corners do not match the triangles (not built by makeMesh)");
  }
  const std::size_t corners = mesh.cornerTriangles.size();
  const std::shared_ptr<const MeshBoxTree> tree = meshBoxTreeOf(mesh);
  detail::ByteWriter w(kMagic, kMeshCacheFormatVersion,
                       96 + mesh.vertices.size() * (sizeof(Vec3) + 4) +
                           mesh.triangles.size() * (sizeof(Triangle) + sizeof(Vec3) + 16) + corners * 8 +
                           tree->nodes.size() * (sizeof(BoxNode) + sizeof(NodeSlab)) + mesh.name.size());
  w.put(static_cast<std::uint32_t>(mesh.flipped));
  w.put(sourceKey);
  w.put(mesh.scale);
  w.append(mesh.offset.data(), sizeof(Vec3));
  w.append(mesh.origin.data(), sizeof(Vec3));
  w.put(static_cast<std::uint64_t>(mesh.vertices.size()));
  w.put(static_cast<std::uint64_t>(mesh.triangles.size()));
  w.put(static_cast<std::uint64_t>(mesh.name.size()));
  w.put(static_cast<std::uint64_t>(corners));
  w.put(static_cast<std::uint64_t>(tree->nodes.size()));
  w.putArray(mesh.vertices);
  w.putArray(mesh.triangles);
  w.putArray(mesh.normals);
  w.putArray(mesh.neighbours);
  w.putArray(mesh.cornerOffsets);
  w.putArray(mesh.cornerTriangles);
  w.putArray(mesh.cornerAngles);
  static_assert(sizeof(NodeSlab) == 64, "slabs are written as they lie in memory: no padding bytes");
  w.putArray(tree->nodes);
  w.putArray(tree->order);
  w.putArray(tree->slabs);
  w.putArray(mesh.name);
  w.writeWithChecksum(path, kKind);
}

TriangleMesh readMeshBinary(const std::string& path, std::uint64_t sourceKey) {
  detail::MappedFile file;  // mapped, not read into a buffer: the arrays are copied once, from the mapping
  const std::string unmapped = file.map(path);
  if (!unmapped.empty()) throw FormatError(std::string(kKind) + " file '" + path + "': " + unmapped);
  ByteReader r = detail::openCacheFile(file.data(), file.size(), kMagic, kMeshCacheFormatVersion, kKind, path);
  const auto flipped = r.get<std::uint32_t>();
  if (r.get<std::uint64_t>() != sourceKey) r.fail("written for another source file or load options");
  TriangleMesh mesh;
  mesh.flipped = flipped != 0;
  mesh.scale = r.get<double>();
  r.read(mesh.offset.data(), sizeof(Vec3));
  r.read(mesh.origin.data(), sizeof(Vec3));
  const auto nv = r.get<std::uint64_t>();
  const auto nt = r.get<std::uint64_t>();
  const auto nameLength = r.get<std::uint64_t>();
  const auto corners = r.get<std::uint64_t>();
  const auto treeNodes = r.get<std::uint64_t>();
  r.expectArrays({{nv, sizeof(Vec3)},
                  {nt, sizeof(Triangle)},
                  {nt, sizeof(Vec3)},
                  {nt, sizeof(mesh.neighbours[0])},
                  {nv + 1, sizeof(std::uint32_t)},
                  {corners, sizeof(std::uint32_t)},
                  {corners, sizeof(float)},
                  {treeNodes, sizeof(BoxNode)},
                  {nt, sizeof(std::uint32_t)},
                  {treeNodes, sizeof(NodeSlab)},
                  {nameLength, 1}});
  if (nt == 0) r.fail("no triangles");
  r.readArray(mesh.vertices, nv);
  r.readArray(mesh.triangles, nt);
  r.readArray(mesh.normals, nt);
  r.readArray(mesh.neighbours, nt);
  r.readArray(mesh.cornerOffsets, nv + 1);
  r.readArray(mesh.cornerTriangles, corners);
  r.readArray(mesh.cornerAngles, corners);
  auto tree = std::make_shared<MeshBoxTree>();
  r.readArray(tree->nodes, treeNodes);
  r.readArray(tree->order, nt);
  r.readArray(tree->slabs, treeNodes);
  r.readArray(mesh.name, nameLength);
  checkMesh(r, mesh);
  const std::string treeProblem = meshBoxTreeProblem(*tree, mesh);
  if (!treeProblem.empty()) r.fail("box tree: " + treeProblem);
  // The slabs: their shape here; what they bound rests on the checksum, as the grid's candidates do (checking it is
  // as dear as computing them).
  for (const NodeSlab& s : tree->slabs) {
    const bool zeroNormal = s.normal.isZero(0.0);  // no slab, or a ball alone (triangles of no area)
    const bool none = zeroNormal && std::isinf(s.thick) && std::isinf(s.radius);
    const bool bound = s.centre.allFinite() && (zeroNormal || std::abs(s.normal.norm() - 1.0) < 1e-9) &&
                       std::isfinite(s.thick) && std::isfinite(s.radius) && s.thick >= 0.0 && s.radius >= 0.0;
    if (!none && !bound) r.fail("box tree: a node's slab is neither a bound nor none");
  }
  tree->servesFingerprint = meshFingerprint(mesh);
  mesh.boxTree = std::move(tree);
  return mesh;
}

MeshCache::MeshCache(std::string directory) : DiskCache(std::move(directory)) {}

std::string MeshCache::pathFor(std::uint64_t sourceKey) const {
  return directory() + "/source-" + detail::hex64(sourceKey) + "-v" + std::to_string(kMeshCacheFormatVersion) +
         ".clodmesh";
}

TriangleMesh MeshCache::load(const std::string& path, const MeshLoadOptions& options, CacheOutcome* outcome) {
  const auto start = std::chrono::steady_clock::now();
  CacheOutcome local;
  CacheOutcome& out = outcome ? *outcome : local;
  out = CacheOutcome();
  std::uint64_t key;
  try {
    key = meshSourceKey(path, options);
  } catch (const MeshLoadError&) {
    return loadMesh(path, options);  // the loader gives the precise error (missing file, ...)
  }
  out.path = pathFor(key);
  TriangleMesh mesh;
  lookUp(
      out, start,
      [&] {
        mesh = readMeshBinary(out.path, key);
        mesh.name = std::filesystem::path(path).filename().string();  // as loadMesh names it
      },
      [&] {
        mesh = loadMesh(path, options);
        mesh.boxTree = buildMeshBoxTree(mesh);  // stored with it, and shared by its detectors from now on
        parsed_.fetch_add(1);
      },
      [&](const std::string& tmp) { writeMeshBinary(mesh, key, tmp); });
  return mesh;
}

}  // namespace clod_haptics
