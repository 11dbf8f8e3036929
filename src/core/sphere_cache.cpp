#include "clod_haptics/core/sphere_cache.h"

#include <chrono>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <vector>


#include "clod_haptics/core/atomic_file.h"
#include "clod_haptics/core/errors.h"

namespace clod_haptics {

namespace {

constexpr char kMagic[8] = {'C', 'L', 'O', 'D', 'S', 'P', 'H', '\0'};
constexpr std::uint32_t kByteOrder = 0x01020304u;
constexpr std::uint64_t kFnvPrime = 0x100000001b3ull;

/** Appends raw values to a byte buffer. */
class Writer {
 public:
  template <class T>
  void put(const T& value) {
    append(&value, sizeof(T));
  }
  void append(const void* data, std::size_t bytes) {
    const char* p = static_cast<const char*>(data);
    buffer_.insert(buffer_.end(), p, p + bytes);
  }
  std::vector<char>& buffer() { return buffer_; }

 private:
  std::vector<char> buffer_;
};

/** Reads raw values from a byte buffer; running past its end is a FormatError. */
class Reader {
 public:
  Reader(const char* data, std::size_t size, const std::string& path) : data_(data), size_(size), path_(path) {}
  template <class T>
  T get(const char* what) {
    T value;
    read(&value, sizeof(T), what);
    return value;
  }
  void read(void* out, std::size_t bytes, const char* what) {
    if (bytes > size_ - pos_) fail(std::string("truncated in ") + what);
    std::memcpy(out, data_ + pos_, bytes);
    pos_ += bytes;
  }
  std::size_t remaining() const { return size_ - pos_; }
  [[noreturn]] void fail(const std::string& why) const {
    throw FormatError("sphere cache file '" + path_ + "': " + why);
  }

 private:
  const char* data_;
  std::size_t size_;
  std::size_t pos_ = 0;
  const std::string& path_;
};

std::string hex64(std::uint64_t v) {
  char text[17];
  std::snprintf(text, sizeof(text), "%016" PRIx64, v);
  return text;
}

std::uint64_t bitsOf(double d) {
  std::uint64_t bits;
  std::memcpy(&bits, &d, sizeof(bits));
  return bits;
}

}  // namespace

std::uint64_t fnv1a64(const void* data, std::size_t bytes, std::uint64_t seed) {
  // FNV-1a over 64-bit words (then the tail byte by byte): the same mixing as the byte-wise
  // original, eight times fewer multiplications, which matters for meshes of millions of triangles.
  const auto* p = static_cast<const unsigned char*>(data);
  std::uint64_t h = seed;
  std::size_t i = 0;
  for (; i + 8 <= bytes; i += 8) {
    std::uint64_t word;
    std::memcpy(&word, p + i, 8);
    h ^= word;
    h *= kFnvPrime;
    h ^= h >> 29;  // fold high bits down: a word-wide xor would otherwise only reach upward
  }
  for (; i < bytes; ++i) {
    h ^= p[i];
    h *= kFnvPrime;
  }
  return h;
}

std::uint64_t meshContentHash(const TriangleMesh& mesh) {
  const std::uint64_t counts[2] = {mesh.vertices.size(), mesh.triangles.size()};
  std::uint64_t h = fnv1a64(counts, sizeof(counts));
  // Vec3 is three packed doubles (Eigen::Vector3d is not padded): hash the array in one pass.
  static_assert(sizeof(Vec3) == 3 * sizeof(double), "Vec3 must be three packed doubles");
  static_assert(sizeof(Triangle) == 3 * sizeof(std::uint32_t), "Triangle must be three packed indices");
  h = fnv1a64(mesh.vertices.data(), mesh.vertices.size() * sizeof(Vec3), h);
  h = fnv1a64(mesh.triangles.data(), mesh.triangles.size() * sizeof(Triangle), h);
  return h;
}

void writeSphereSetBinary(const ClodSphereSet& set, std::uint64_t meshHash, const std::string& path) {
  const std::uint64_t n = set.size();
  const std::uint64_t m = set.triangles.size();
  if (set.radii.size() != n || set.offsets.size() != n + 1 || set.offsets.back() != m) {
    throw FormatError("cannot write sphere cache file '" + path + "': malformed sphere set");
  }
  Writer w;
  w.append(kMagic, sizeof(kMagic));
  w.put(kSphereCacheFormatVersion);
  w.put(kByteOrder);
  w.put(meshHash);
  w.put(set.distance);
  w.put(set.scale);
  w.put(static_cast<std::uint64_t>(set.stats.triangles));
  w.put(n);
  w.put(m);
  w.put(static_cast<std::uint64_t>(set.meshName.size()));
  const BuildStats& s = set.stats;
  for (std::size_t v : {s.centres, s.spheres, s.unpaired, s.degenerate, s.maxTrianglesPerSphere})
    w.put(static_cast<std::uint64_t>(v));
  for (double v : {s.meanTrianglesPerSphere, s.placementMs, s.clusteringMs}) w.put(v);
  w.append(set.centres.data(), n * sizeof(Vec3));
  w.append(set.radii.data(), n * sizeof(double));
  w.append(set.offsets.data(), (n + 1) * sizeof(std::uint32_t));
  w.append(set.triangles.data(), m * sizeof(std::uint32_t));
  w.append(set.meshName.data(), set.meshName.size());
  const std::uint64_t checksum = fnv1a64(w.buffer().data(), w.buffer().size());
  w.put(checksum);

  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw FormatError("cannot write sphere cache file '" + path + "': cannot open it");
  out.write(w.buffer().data(), static_cast<std::streamsize>(w.buffer().size()));
  out.close();
  if (!out) throw FormatError("cannot write sphere cache file '" + path + "': write failed");
}

ClodSphereSet readSphereSetBinary(const std::string& path, std::uint64_t meshHash, double distance,
                                  const TriangleMesh& mesh) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) throw FormatError("sphere cache file '" + path + "': cannot open it");
  const std::streamoff size = in.tellg();
  if (size < 0) throw FormatError("sphere cache file '" + path + "': cannot read its size");
  std::vector<char> bytes(static_cast<std::size_t>(size));
  in.seekg(0);
  in.read(bytes.data(), size);
  if (!in) throw FormatError("sphere cache file '" + path + "': read failed");

  Reader r(bytes.data(), bytes.size(), path);
  if (bytes.size() < sizeof(kMagic) + sizeof(std::uint64_t)) r.fail("too short to be a cache file");
  // Checksum first: nothing below reads a byte the checksum did not cover.
  std::uint64_t stored;
  std::memcpy(&stored, bytes.data() + bytes.size() - sizeof(stored), sizeof(stored));
  if (fnv1a64(bytes.data(), bytes.size() - sizeof(stored)) != stored) r.fail("checksum mismatch (corrupt file)");
  Reader body(bytes.data(), bytes.size() - sizeof(stored), path);

  char magic[sizeof(kMagic)];
  body.read(magic, sizeof(magic), "the magic");
  if (std::memcmp(magic, kMagic, sizeof(kMagic)) != 0) r.fail("not a clod_haptics sphere cache file");
  const auto version = body.get<std::uint32_t>("the version");
  if (version != kSphereCacheFormatVersion) {
    r.fail("format version " + std::to_string(version) + ", expected " + std::to_string(kSphereCacheFormatVersion));
  }
  if (body.get<std::uint32_t>("the byte order") != kByteOrder) r.fail("written on a machine of another byte order");
  if (body.get<std::uint64_t>("the mesh hash") != meshHash) r.fail("written for another mesh (content hash differs)");
  ClodSphereSet set;
  set.distance = body.get<double>("the distance");
  if (bitsOf(set.distance) != bitsOf(distance)) {
    r.fail("written for clustering distance " + std::to_string(set.distance) + ", expected " +
           std::to_string(distance));
  }
  set.scale = body.get<double>("the scale");
  const auto meshTriangles = body.get<std::uint64_t>("the triangle count");
  if (meshTriangles != mesh.size()) r.fail("written for a mesh of " + std::to_string(meshTriangles) + " triangles");
  const auto n = body.get<std::uint64_t>("the sphere count");
  const auto m = body.get<std::uint64_t>("the listing count");
  const auto nameLength = body.get<std::uint64_t>("the name length");
  set.stats.triangles = meshTriangles;
  set.stats.centres = body.get<std::uint64_t>("stats");
  set.stats.spheres = body.get<std::uint64_t>("stats");
  set.stats.unpaired = body.get<std::uint64_t>("stats");
  set.stats.degenerate = body.get<std::uint64_t>("stats");
  set.stats.maxTrianglesPerSphere = body.get<std::uint64_t>("stats");
  set.stats.meanTrianglesPerSphere = body.get<double>("stats");
  set.stats.placementMs = body.get<double>("stats");
  set.stats.clusteringMs = body.get<double>("stats");
  // Sizes must add up to the file exactly before anything is allocated from them.
  const std::uint64_t expected = n * (sizeof(Vec3) + sizeof(double) + sizeof(std::uint32_t)) +
                                 sizeof(std::uint32_t) + m * sizeof(std::uint32_t) + nameLength;
  if (n > bytes.size() || m > bytes.size() || nameLength > bytes.size() || expected != body.remaining()) {
    r.fail("array sizes do not match the file size");
  }
  set.centres.resize(n);
  set.radii.resize(n);
  set.offsets.resize(n + 1);
  set.triangles.resize(m);
  set.meshName.resize(nameLength);
  body.read(set.centres.data(), n * sizeof(Vec3), "centres");
  body.read(set.radii.data(), n * sizeof(double), "radii");
  body.read(set.offsets.data(), (n + 1) * sizeof(std::uint32_t), "offsets");
  body.read(set.triangles.data(), m * sizeof(std::uint32_t), "triangles");
  body.read(set.meshName.data(), nameLength, "the mesh name");

  // The set must fit the mesh: the detector relies on coverage to miss no contact.
  const std::string misfit = fitProblem(mesh, set);
  if (!misfit.empty()) r.fail(misfit);
  return set;
}

std::string defaultSphereCacheDirectory() {
  if (const char* dir = std::getenv("CLOD_CACHE_DIR"); dir != nullptr && *dir != '\0') return dir;
  if (const char* ros = std::getenv("ROS_HOME"); ros != nullptr && *ros != '\0') {
    return std::string(ros) + "/clod_haptics_cache";
  }
  if (const char* home = std::getenv("HOME"); home != nullptr && *home != '\0') {
    return std::string(home) + "/.ros/clod_haptics_cache";
  }
  return (std::filesystem::temp_directory_path() / "clod_haptics_cache").string();
}

const char* toString(CacheSource source) {
  switch (source) {
    case CacheSource::Hit:
      return "hit";
    case CacheSource::Built:
      return "built";
    case CacheSource::Rebuilt:
      return "rebuilt";
  }
  return "?";
}

SphereSetCache::SphereSetCache(std::string directory)
    : directory_(directory.empty() ? defaultSphereCacheDirectory() : std::move(directory)) {}

std::string SphereSetCache::pathFor(std::uint64_t meshHash, double distance) const {
  return directory_ + "/mesh-" + hex64(meshHash) + "-d" + hex64(bitsOf(distance)) + "-v" +
         std::to_string(kSphereCacheFormatVersion) + ".clodsph";
}

std::shared_ptr<const ClodSphereSet> SphereSetCache::getOrBuild(const TriangleMesh& mesh, std::uint64_t meshHash,
                                                                double distance,
                                                                const std::function<ClodSphereSet()>& build,
                                                                CacheOutcome* outcome) {
  requireNonNegative(distance, "clustering distance");
  if (distance == 0.0) distance = 0.0;  // -0 and +0 are the same level and the same file
  const auto start = std::chrono::steady_clock::now();
  CacheOutcome local;
  CacheOutcome& out = outcome ? *outcome : local;
  out = CacheOutcome();
  out.path = pathFor(meshHash, distance);
  auto elapsed = [&] {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  };

  std::error_code ec;
  if (std::filesystem::exists(out.path, ec)) {
    try {
      auto set = std::make_shared<const ClodSphereSet>(readSphereSetBinary(out.path, meshHash, distance, mesh));
      hits_.fetch_add(1);
      out.source = CacheSource::Hit;
      out.ms = elapsed();
      return set;
    } catch (const FormatError& e) {
      rejected_.fetch_add(1);
      out.source = CacheSource::Rebuilt;
      out.problem = e.what();
      std::filesystem::remove(out.path, ec);  // never trusted again, even if the rebuild below fails
    }
  } else {
    misses_.fetch_add(1);
    out.source = CacheSource::Built;
  }

  auto set = std::make_shared<const ClodSphereSet>(build());
  storeAtomically(
      directory_, out.path, [&](const std::string& tmp) { writeSphereSetBinary(*set, meshHash, tmp); }, out.problem);
  out.ms = elapsed();
  return set;
}

}  // namespace clod_haptics
