#include "clod_haptics/core/grid_cache.h"

#include <chrono>
#include <cmath>
#include <cstring>

#include "clod_haptics/core/errors.h"
#include "binary_io.h"

namespace clod_haptics {

namespace {

using detail::ByteReader;
using detail::ByteWriter;

constexpr detail::CacheMagic kMagic = {'C', 'L', 'O', 'D', 'G', 'R', 'I', 'D'};
constexpr const char* kKind = "grid cache";
constexpr std::uint32_t kByteOrder = 0x01020304u;

std::uint64_t bitsOf(double d) {
  std::uint64_t bits;
  std::memcpy(&bits, &d, sizeof(bits));
  return bits;
}

/** The CellGrid options of a key, for the file name. */
std::uint64_t optionsHash(const GridCacheKey& key) {
  const std::uint64_t options[2] = {bitsOf(key.entriesPerTriangle), static_cast<std::uint64_t>(key.index)};
  return fnv1a64(options, sizeof(options));
}

/** Reads the header after the version and checks it against key and the mesh. */
void readHeader(ByteReader& r, const GridCacheKey& key, const TriangleMesh& mesh) {
  if (r.get<std::uint32_t>("the byte order") != kByteOrder) r.fail("written on a machine of another byte order");
  if (r.get<std::uint64_t>("the mesh hash") != key.meshHash) r.fail("written for another mesh (content hash differs)");
  const auto distance = r.get<double>("the distance");
  if (bitsOf(distance) != bitsOf(key.distance))
    r.fail("written for clustering distance " + std::to_string(distance) + ", expected " +
           std::to_string(key.distance));
  if (r.get<std::uint64_t>("the sphere set hash") != key.setHash) r.fail("written for another sphere set");
  const auto radius = r.get<double>("the radius");
  if (bitsOf(radius) != bitsOf(key.radius))
    r.fail("written for grid radius " + std::to_string(radius) + ", expected " + std::to_string(key.radius));
  if (bitsOf(r.get<double>("the options")) != bitsOf(key.entriesPerTriangle) ||
      r.get<std::uint8_t>("the options") != static_cast<std::uint8_t>(key.index))
    r.fail("written with other grid options");
  const auto triangles = r.get<std::uint64_t>("the triangle count");
  if (triangles != mesh.size()) r.fail("written for a mesh of " + std::to_string(triangles) + " triangles");
}

}  // namespace

std::uint64_t sphereSetHash(const ClodSphereSet& set) {
  const std::uint64_t counts[2] = {set.size(), set.triangles.size()};
  std::uint64_t h = fnv1a64(counts, sizeof(counts));
  h = fnv1a64(set.offsets.data(), set.offsets.size() * sizeof(set.offsets[0]), h);
  return fnv1a64(set.triangles.data(), set.triangles.size() * sizeof(set.triangles[0]), h);
}

void writeCellGridBinary(const CellGrid& grid, const GridCacheKey& key, std::size_t triangles,
                         const std::string& path) {
  if (grid.empty()) throw FormatError("cannot write grid cache file '" + path + "': empty grid");
  ByteWriter w(kMagic, kGridCacheFormatVersion, grid.bytes() + 256);
  w.put(kByteOrder);
  w.put(key.meshHash);
  w.put(key.distance);
  w.put(key.setHash);
  w.put(key.radius);
  w.put(key.entriesPerTriangle);
  w.put(static_cast<std::uint8_t>(key.index));
  w.put(static_cast<std::uint64_t>(triangles));
  grid.writeTo(w);
  w.writeWithChecksum(path, kKind);
}

CellGrid readCellGridBinary(const std::string& path, const GridCacheKey& key, const TriangleMesh& mesh) {
  detail::MappedFile file;
  const std::string unmapped = file.map(path);
  if (!unmapped.empty()) throw FormatError(std::string(kKind) + " file '" + path + "': " + unmapped);
  ByteReader r = detail::openCacheFile(file.data(), file.size(), kMagic, kGridCacheFormatVersion, kKind, path);
  readHeader(r, key, mesh);
  CellGrid grid = CellGrid::readFrom(r, mesh.size());
  if (bitsOf(grid.radius()) != bitsOf(key.radius)) r.fail("the grid's radius differs from the header's");
  return grid;
}

CellGridCache::CellGridCache(std::string directory) : DiskCache(std::move(directory)) {}

std::string CellGridCache::pathFor(const GridCacheKey& key) const {
  return directory() + "/mesh-" + detail::hex64(key.meshHash) + "-d" + detail::hex64(bitsOf(key.distance)) +
         "-grid-r" + detail::hex64(bitsOf(key.radius)) + "-o" + detail::hex64(optionsHash(key)) + "-v" +
         std::to_string(kGridCacheFormatVersion) + ".clodgrid";
}

CellGrid CellGridCache::getOrBuild(const TriangleMesh& mesh, const GridCacheKey& key,
                                   const std::function<CellGrid()>& build, CacheOutcome* outcome) {
  requireNonNegative(key.distance, "clustering distance");
  if (!(key.radius > 0.0) || !std::isfinite(key.radius))
    throw InvalidParameter("cell grid radius must be finite and > 0, got " + std::to_string(key.radius));
  GridCacheKey k = key;
  if (k.distance == 0.0) k.distance = 0.0;  // -0 and +0 are the same level and the same file
  const auto start = std::chrono::steady_clock::now();
  CacheOutcome local;
  CacheOutcome& out = outcome ? *outcome : local;
  out = CacheOutcome();
  out.path = pathFor(k);
  CellGrid grid;
  lookUp(
      out, start, [&] { grid = readCellGridBinary(out.path, k, mesh); },
      [&] {
        if (out.source == CacheSource::Built) misses_.fetch_add(1);
        grid = build();
      },
      [&](const std::string& tmp) { writeCellGridBinary(grid, k, mesh.size(), tmp); });
  return grid;
}

}  // namespace clod_haptics
