#include "clod_haptics/core/mesh_cache.h"

#include <chrono>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <vector>


#include "clod_haptics/core/atomic_file.h"
#include "clod_haptics/core/errors.h"

namespace clod_haptics {

namespace {

constexpr char kMagic[8] = {'C', 'L', 'O', 'D', 'M', 'S', 'H', '\0'};

std::vector<char> readAll(const std::string& path, bool& ok) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  ok = static_cast<bool>(in);
  if (!ok) return {};
  const std::streamoff size = in.tellg();
  std::vector<char> bytes(size > 0 ? static_cast<std::size_t>(size) : 0);
  in.seekg(0);
  in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  ok = static_cast<bool>(in) || bytes.empty();
  return bytes;
}

template <class T>
void put(std::vector<char>& out, const T& value) {
  const char* p = reinterpret_cast<const char*>(&value);
  out.insert(out.end(), p, p + sizeof(T));
}

void putBytes(std::vector<char>& out, const void* data, std::size_t bytes) {
  const char* p = static_cast<const char*>(data);
  out.insert(out.end(), p, p + bytes);
}

class Reader {
 public:
  Reader(const std::vector<char>& bytes, std::size_t end, const std::string& path)
      : bytes_(bytes), end_(end), path_(path) {}
  template <class T>
  T get() {
    T value;
    read(&value, sizeof(T));
    return value;
  }
  void read(void* out, std::size_t n) {
    if (n > end_ - pos_) fail("truncated");
    std::memcpy(out, bytes_.data() + pos_, n);
    pos_ += n;
  }
  std::size_t remaining() const { return end_ - pos_; }
  [[noreturn]] void fail(const std::string& why) const { throw FormatError("mesh cache file '" + path_ + "': " + why); }

 private:
  const std::vector<char>& bytes_;
  std::size_t end_;
  std::size_t pos_ = 0;
  const std::string& path_;
};

}  // namespace

std::uint64_t meshSourceKey(const std::string& path, const MeshLoadOptions& options) {
  bool ok = false;
  const std::vector<char> bytes = readAll(path, ok);
  if (!ok) throw MeshLoadError(path, "cannot read the file");
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
  if (mesh.normals.size() != mesh.triangles.size()) {
    throw FormatError("cannot write mesh cache file '" + path + "': normals do not match the triangles");
  }
  std::vector<char> out;
  out.reserve(64 + mesh.vertices.size() * sizeof(Vec3) + mesh.triangles.size() * (sizeof(Triangle) + sizeof(Vec3)));
  putBytes(out, kMagic, sizeof(kMagic));
  put(out, kMeshCacheFormatVersion);
  put(out, static_cast<std::uint32_t>(mesh.flipped));
  put(out, sourceKey);
  put(out, mesh.scale);
  putBytes(out, mesh.offset.data(), sizeof(double) * 3);
  put(out, static_cast<std::uint64_t>(mesh.vertices.size()));
  put(out, static_cast<std::uint64_t>(mesh.triangles.size()));
  put(out, static_cast<std::uint64_t>(mesh.name.size()));
  putBytes(out, mesh.vertices.data(), mesh.vertices.size() * sizeof(Vec3));
  putBytes(out, mesh.triangles.data(), mesh.triangles.size() * sizeof(Triangle));
  putBytes(out, mesh.normals.data(), mesh.normals.size() * sizeof(Vec3));
  putBytes(out, mesh.name.data(), mesh.name.size());
  put(out, fnv1a64(out.data(), out.size()));
  std::ofstream file(path, std::ios::binary | std::ios::trunc);
  if (!file) throw FormatError("cannot write mesh cache file '" + path + "': cannot open it");
  file.write(out.data(), static_cast<std::streamsize>(out.size()));
  file.close();
  if (!file) throw FormatError("cannot write mesh cache file '" + path + "': write failed");
}

TriangleMesh readMeshBinary(const std::string& path, std::uint64_t sourceKey) {
  bool ok = false;
  const std::vector<char> bytes = readAll(path, ok);
  Reader whole(bytes, bytes.size(), path);
  if (!ok) whole.fail("cannot read it");
  if (bytes.size() < sizeof(kMagic) + sizeof(std::uint64_t)) whole.fail("too short to be a cache file");
  std::uint64_t stored;
  std::memcpy(&stored, bytes.data() + bytes.size() - sizeof(stored), sizeof(stored));
  if (fnv1a64(bytes.data(), bytes.size() - sizeof(stored)) != stored) whole.fail("checksum mismatch (corrupt file)");
  Reader r(bytes, bytes.size() - sizeof(stored), path);
  char magic[sizeof(kMagic)];
  r.read(magic, sizeof(magic));
  if (std::memcmp(magic, kMagic, sizeof(kMagic)) != 0) r.fail("not a clod_haptics mesh cache file");
  const auto version = r.get<std::uint32_t>();
  if (version != kMeshCacheFormatVersion) r.fail("format version " + std::to_string(version));
  const auto flipped = r.get<std::uint32_t>();
  if (r.get<std::uint64_t>() != sourceKey) r.fail("written for another source file or load options");
  TriangleMesh mesh;
  mesh.flipped = flipped != 0;
  mesh.scale = r.get<double>();
  r.read(mesh.offset.data(), sizeof(double) * 3);
  const auto nv = r.get<std::uint64_t>();
  const auto nt = r.get<std::uint64_t>();
  const auto nameLength = r.get<std::uint64_t>();
  if (nv > bytes.size() || nt > bytes.size() || nameLength > bytes.size() ||
      nv * sizeof(Vec3) + nt * (sizeof(Triangle) + sizeof(Vec3)) + nameLength != r.remaining()) {
    r.fail("array sizes do not match the file size");
  }
  if (nt == 0) r.fail("no triangles");
  mesh.vertices.resize(nv);
  mesh.triangles.resize(nt);
  mesh.normals.resize(nt);
  mesh.name.resize(nameLength);
  r.read(mesh.vertices.data(), nv * sizeof(Vec3));
  r.read(mesh.triangles.data(), nt * sizeof(Triangle));
  r.read(mesh.normals.data(), nt * sizeof(Vec3));
  r.read(mesh.name.data(), nameLength);
  // The same validity makeMesh guarantees: indices in range, coordinates finite.
  for (const Vec3& v : mesh.vertices)
    if (!v.allFinite()) r.fail("a vertex is not finite");
  for (const Triangle& t : mesh.triangles)
    for (std::uint32_t v : t)
      if (v >= nv) r.fail("a vertex index is out of range");
  for (const Vec3& n : mesh.normals)
    if (!n.allFinite()) r.fail("a normal is not finite");
  if (!std::isfinite(mesh.scale) || !mesh.offset.allFinite()) r.fail("scale or offset not finite");
  // The adjacency is not stored (the file layout is unchanged): it is rebuilt as makeMesh builds it.
  computeAdjacency(mesh);
  return mesh;
}

MeshCache::MeshCache(std::string directory)
    : directory_(directory.empty() ? defaultSphereCacheDirectory() : std::move(directory)) {}

std::string MeshCache::pathFor(std::uint64_t sourceKey) const {
  char hex[17];
  std::snprintf(hex, sizeof(hex), "%016" PRIx64, sourceKey);
  return directory_ + "/source-" + hex + "-v" + std::to_string(kMeshCacheFormatVersion) + ".clodmesh";
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
  auto elapsed = [&] {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  };
  std::error_code ec;
  if (std::filesystem::exists(out.path, ec)) {
    try {
      TriangleMesh mesh = readMeshBinary(out.path, key);
      mesh.name = std::filesystem::path(path).filename().string();  // as loadMesh names it
      hits_.fetch_add(1);
      out.source = CacheSource::Hit;
      out.ms = elapsed();
      return mesh;
    } catch (const FormatError& e) {
      rejected_.fetch_add(1);
      out.source = CacheSource::Rebuilt;
      out.problem = e.what();
      std::filesystem::remove(out.path, ec);
    }
  } else {
    out.source = CacheSource::Built;
  }
  TriangleMesh mesh = loadMesh(path, options);
  parsed_.fetch_add(1);
  storeAtomically(
      directory_, out.path, [&](const std::string& tmp) { writeMeshBinary(mesh, key, tmp); }, out.problem);
  out.ms = elapsed();
  return mesh;
}

}  // namespace clod_haptics
