#include "clod_haptics/core/sphere_cache.h"

#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <vector>

#include "binary_io.h"
#include "clod_haptics/core/atomic_file.h"
#include "clod_haptics/core/errors.h"
#include "enum_names.h"

namespace clod_haptics {

namespace {

using detail::ByteReader;
using detail::ByteWriter;

constexpr detail::CacheMagic kMagic = {'C', 'L', 'O', 'D', 'S', 'P', 'H', '\0'};
constexpr const char* kKind = "sphere cache";
using detail::bitsOf;
using detail::kByteOrder;

void writeStats(ByteWriter& w, const BuildStats& s) {
  for (std::size_t v : {s.centres, s.spheres, s.unpaired, s.degenerate, s.maxTrianglesPerSphere})
    w.put(static_cast<std::uint64_t>(v));
  for (double v : {s.meanTrianglesPerSphere, s.placementMs, s.clusteringMs}) w.put(v);
}

void readStats(ByteReader& r, BuildStats& s) {
  for (std::size_t* v : {&s.centres, &s.spheres, &s.unpaired, &s.degenerate, &s.maxTrianglesPerSphere})
    *v = r.get<std::uint64_t>("stats");
  for (double* v : {&s.meanTrianglesPerSphere, &s.placementMs, &s.clusteringMs}) *v = r.get<double>("stats");
}

/** The counts of the arrays that follow the header. */
struct ArrayCounts {
  std::uint64_t spheres = 0, listings = 0, nameLength = 0;
};

/** Reads the header after the version into set, checked against what the caller expects. */
ArrayCounts readHeader(ByteReader& r, std::uint64_t meshHash, double distance, const TriangleMesh& mesh,
                       ClodSphereSet& set) {
  if (r.get<std::uint32_t>("the byte order") != kByteOrder) r.fail("written on a machine of another byte order");
  if (r.get<std::uint64_t>("the mesh hash") != meshHash) r.fail("written for another mesh (content hash differs)");
  set.distance = r.get<double>("the distance");
  if (bitsOf(set.distance) != bitsOf(distance)) {
    r.fail("written for clustering distance " + std::to_string(set.distance) + ", expected " +
           std::to_string(distance));
  }
  set.scale = r.get<double>("the scale");
  set.origin = mesh.origin;  // the hash covers the local vertices; the origin is the mesh's
  const auto meshTriangles = r.get<std::uint64_t>("the triangle count");
  if (meshTriangles != mesh.size()) r.fail("written for a mesh of " + std::to_string(meshTriangles) + " triangles");
  set.stats.triangles = meshTriangles;
  ArrayCounts counts;
  counts.spheres = r.get<std::uint64_t>("the sphere count");
  counts.listings = r.get<std::uint64_t>("the listing count");
  counts.nameLength = r.get<std::uint64_t>("the name length");
  readStats(r, set.stats);
  return counts;
}

void readArrays(ByteReader& r, const ArrayCounts& c, ClodSphereSet& set) {
  r.expectArrays({{c.spheres, sizeof(Vec3)},
                  {c.spheres, sizeof(double)},
                  {c.spheres + 1, sizeof(std::uint32_t)},
                  {c.listings, sizeof(std::uint32_t)},
                  {c.nameLength, 1}});
  r.readArray(set.centres, c.spheres, "centres");
  r.readArray(set.radii, c.spheres, "radii");
  r.readArray(set.offsets, c.spheres + 1, "offsets");
  r.readArray(set.triangles, c.listings, "triangles");
  r.readArray(set.meshName, c.nameLength, "the mesh name");
}

}  // namespace

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
  ByteWriter w(kMagic, kSphereCacheFormatVersion);
  w.put(kByteOrder);
  w.put(meshHash);
  w.put(set.distance);
  w.put(set.scale);
  w.put(static_cast<std::uint64_t>(set.stats.triangles));
  w.put(n);
  w.put(m);
  w.put(static_cast<std::uint64_t>(set.meshName.size()));
  writeStats(w, set.stats);
  w.putArray(set.centres);
  w.putArray(set.radii);
  w.putArray(set.offsets);
  w.putArray(set.triangles);
  w.putArray(set.meshName);
  w.writeWithChecksum(path, kKind);
}

ClodSphereSet readSphereSetBinary(const std::string& path, std::uint64_t meshHash, double distance,
                                  const TriangleMesh& mesh) {
  std::vector<char> bytes;
  const std::string unreadable = detail::readFileBytes(path, bytes);
  if (!unreadable.empty()) throw FormatError(std::string(kKind) + " file '" + path + "': " + unreadable);
  ByteReader r = detail::openCacheFile(bytes, kMagic, kSphereCacheFormatVersion, kKind, path);
  ClodSphereSet set;
  const ArrayCounts counts = readHeader(r, meshHash, distance, mesh, set);
  readArrays(r, counts, set);
  // The set must fit the mesh: the detector relies on coverage to miss no contact.
  const std::string misfit = fitProblem(mesh, set);
  if (!misfit.empty()) r.fail(misfit);
  return set;
}

std::string sphereCacheDirectoryFor(const std::string& directory, const std::string& clustering) {
  const std::string base = directory.empty() ? defaultSphereCacheDirectory() : directory;
  return clustering == "single-link" ? base : base + "/" + clustering;
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
  static const detail::EnumNames<CacheSource, 3> kNames = {
      {CacheSource::Hit, "hit"}, {CacheSource::Built, "built"}, {CacheSource::Rebuilt, "rebuilt"}};
  return detail::nameOf(source, kNames);
}

DiskCache::DiskCache(std::string directory)
    : directory_(directory.empty() ? defaultSphereCacheDirectory() : std::move(directory)) {}

void DiskCache::lookUp(CacheOutcome& out, std::chrono::steady_clock::time_point start,
                       const std::function<void()>& read, const std::function<void()>& build,
                       const std::function<void(const std::string& tmp)>& write) {
  auto elapsed = [&] {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  };
  std::error_code ec;
  if (std::filesystem::exists(out.path, ec)) {
    try {
      read();
      hits_.fetch_add(1);
      out.source = CacheSource::Hit;
      out.ms = elapsed();
      return;
    } catch (const FormatError& e) {
      rejected_.fetch_add(1);
      out.source = CacheSource::Rebuilt;
      out.problem = e.what();
      std::filesystem::remove(out.path, ec);  // never trusted again, even if the rebuild below fails
    }
  } else {
    out.source = CacheSource::Built;
  }
  build();
  storeAtomically(directory_, out.path, write, out.problem);
  out.ms = elapsed();
}

SphereSetCache::SphereSetCache(std::string directory) : DiskCache(std::move(directory)) {}

std::string SphereSetCache::pathFor(std::uint64_t meshHash, double distance) const {
  return directory() + "/mesh-" + detail::hex64(meshHash) + "-d" + detail::hex64(bitsOf(distance)) + "-v" +
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
  std::shared_ptr<const ClodSphereSet> set;
  lookUp(
      out, start,
      [&] { set = std::make_shared<const ClodSphereSet>(readSphereSetBinary(out.path, meshHash, distance, mesh)); },
      [&] {
        if (out.source == CacheSource::Built) misses_.fetch_add(1);
        set = std::make_shared<const ClodSphereSet>(build());
      },
      [&](const std::string& tmp) { writeSphereSetBinary(*set, meshHash, tmp); });
  return set;
}

}  // namespace clod_haptics
