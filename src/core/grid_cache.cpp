#include "clod_haptics/core/grid_cache.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <vector>

#include "binary_io.h"
#include "clod_haptics/core/errors.h"

namespace clod_haptics {

namespace {

using detail::ByteReader;
using detail::ByteWriter;

constexpr detail::CacheMagic kMagic = {'C', 'L', 'O', 'D', 'G', 'R', 'I', 'D'};
constexpr const char* kKind = "grid cache";
using detail::bitsOf;
using detail::kByteOrder;

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

void CellGrid::writeTo(detail::ByteWriter& out) const {
  static_assert(sizeof(Entry) == 8 && sizeof(Word) == 16 && sizeof(CellRef) == 8 && sizeof(Slot) == 24,
                "the grid's arrays are written as they lie in memory: no padding bytes");
  for (double v : {radius_, cell_, inv_, slack_, unit_, distanceUnit_, slabPad_, origin_.x(), origin_.y(), origin_.z()})
    out.put(v);
  for (std::int64_t d : dims_) out.put(d);
  out.put(static_cast<std::uint64_t>(cellCount_));
  for (std::size_t n : {entries_.size(), words_.size(), refs_.size(), headers_.size(), slots_.size()})
    out.put(static_cast<std::uint64_t>(n));
  out.putArray(entries_);
  out.putArray(words_);
  out.putArray(refs_);
  out.putArray(headers_);
  out.putArray(slots_);
}

CellGrid CellGrid::readFrom(detail::ByteReader& in, std::size_t triangles) {
  CellGrid g;
  double* const scalars[] = {&g.radius_, &g.cell_, &g.inv_, &g.slack_, &g.unit_, &g.distanceUnit_, &g.slabPad_};
  for (double* v : scalars) *v = in.get<double>("the grid's scalars");
  for (int k = 0; k < 3; ++k) g.origin_[k] = in.get<double>("the grid's origin");
  for (std::int64_t& d : g.dims_) d = in.get<std::int64_t>("the grid's dimensions");
  const auto cells = in.get<std::uint64_t>("the cell count");
  std::uint64_t counts[5];
  for (std::uint64_t& c : counts) c = in.get<std::uint64_t>("the array sizes");

  for (double* v : scalars)
    if (!std::isfinite(*v)) in.fail("a grid scalar is not finite");
  if (!g.origin_.allFinite()) in.fail("the grid's origin is not finite");
  if (!(g.radius_ > 0.0 && g.cell_ > 0.0 && g.inv_ > 0.0 && g.unit_ > 0.0 && g.distanceUnit_ > 0.0 && g.slack_ >= 0.0 &&
        g.slabPad_ >= 0.0))
    in.fail("grid scalars out of range");
  for (std::int64_t d : g.dims_)
    if (d < 1 || d > (1 << kBits) - 1) in.fail("grid dimensions out of range");
  in.expectArraysWithin({{counts[0], sizeof(Entry)},  // the trees over the spheres follow (writeTrees)
                         {counts[1], sizeof(Word)},
                         {counts[2], sizeof(CellRef)},
                         {counts[3], sizeof(std::uint32_t)},
                         {counts[4], sizeof(Slot)}});
  in.readArray(g.entries_, counts[0], "the entries");
  in.readArray(g.words_, counts[1], "the dense index");
  in.readArray(g.refs_, counts[2], "the cell proofs");
  in.readArray(g.headers_, counts[3], "the cell headers");
  in.readArray(g.slots_, counts[4], "the hash table");
  g.cellCount_ = cells;

  // The cells: consecutive runs of a header and its candidates filling the entries exactly.
  const std::size_t n = g.entries_.size();
  const bool dense = !g.words_.empty();
  if (n == 0 || cells == 0) in.fail("empty grid");
  if (dense ? (g.refs_.size() != cells || g.headers_.size() != cells || !g.slots_.empty())
            : (!g.refs_.empty() || !g.headers_.empty() || g.slots_.empty()))
    in.fail("index sizes do not match the cell count");
  std::vector<std::uint64_t> isHeader(dense ? 0 : (n + 63) / 64, 0);  // hashed: which entries start a cell
  std::uint64_t cell = 0;
  for (std::size_t at = 0; at < n; ++cell) {
    const std::uint32_t count = g.entries_[at].triangle;
    std::uint32_t spheres;
    std::memcpy(&spheres, reinterpret_cast<const unsigned char*>(&g.entries_[at]) + 4, sizeof spheres);
    if (cell >= cells) in.fail("more cells in the entries than the cell count");
    if (count == 0 || count > n - at - 1 || spheres == 0 || spheres > count)
      in.fail("cell " + std::to_string(cell) + ": header out of range");
    g.largest_ = std::max(g.largest_, count);
    if (dense) {
      if (g.headers_[cell] != at) in.fail("cell " + std::to_string(cell) + ": index header does not match the entries");
    } else {
      isHeader[at >> 6] |= 1ull << (at & 63);
    }
    for (std::size_t i = at + 1; i <= at + count; ++i)
      if (g.entries_[i].triangle >= triangles)
        in.fail("cell " + std::to_string(cell) + ": triangle " + std::to_string(g.entries_[i].triangle) +
                " out of range (" + std::to_string(triangles) + " triangles)");
    at += 1 + static_cast<std::size_t>(count);
  }
  if (cell != cells) in.fail("fewer cells in the entries than the cell count");

  if (dense) {
    // One bit per cell of the box; the ranks count the bits before each word, the bits total the cells.
    const double total =
        static_cast<double>(g.dims_[0]) * static_cast<double>(g.dims_[1]) * static_cast<double>(g.dims_[2]);
    if (!(total < 17179869184.0) || g.words_.size() != (static_cast<std::uint64_t>(total) + 63) / 64)
      in.fail("dense index size does not match the grid's dimensions");
    std::uint64_t rank = 0;
    for (const Word& w : g.words_) {
      if (w.rank != rank) in.fail("dense index ranks inconsistent");
      rank += static_cast<std::uint64_t>(__builtin_popcountll(w.bits));
    }
    const std::uint64_t tail = static_cast<std::uint64_t>(total) & 63;
    if (tail != 0 && (g.words_.back().bits >> tail) != 0) in.fail("dense index bits beyond the grid");
    if (rank != cells) in.fail("dense index bits do not match the cell count");
  } else {
    // Open addressing: a power-of-two table with a free slot, every key reachable from its hash, every header a cell's.
    const std::size_t size = g.slots_.size();
    if (size < 16 || (size & (size - 1)) != 0) in.fail("hash table size is not a power of two");
    g.mask_ = size - 1;
    std::uint64_t occupied = 0;
    for (const Slot& slot : g.slots_) occupied += slot.key != kOutside;
    if (occupied != cells || occupied >= size) in.fail("hash table does not match the cell count");
    // With a free slot every probe ends; each key must be the first of its value on its chain from its hash.
    for (const Slot& slot : g.slots_) {
      if (slot.key == kOutside) continue;
      constexpr std::uint64_t m = (1ull << kBits) - 1;
      if ((slot.key >> (3 * kBits)) != 0 || static_cast<std::int64_t>(slot.key & m) >= g.dims_[0] ||
          static_cast<std::int64_t>((slot.key >> kBits) & m) >= g.dims_[1] ||
          static_cast<std::int64_t>((slot.key >> (2 * kBits)) & m) >= g.dims_[2])
        in.fail("hash table key outside the grid");
      if (slot.header >= n || !((isHeader[slot.header >> 6] >> (slot.header & 63)) & 1))
        in.fail("hash table header is not a cell's");
      if (g.findHashed(slot.key) != &slot.ref) in.fail("hash table key not reachable from its hash");
    }
  }
  return g;
}

std::uint64_t sphereSetHash(const ClodSphereSet& set) {
  const std::uint64_t counts[2] = {set.size(), set.triangles.size()};
  std::uint64_t h = fnv1a64(counts, sizeof(counts));
  h = fnv1a64(set.offsets.data(), set.offsets.size() * sizeof(set.offsets[0]), h);
  return fnv1a64(set.triangles.data(), set.triangles.size() * sizeof(set.triangles[0]), h);
}

namespace {

/** The trees' arrays after their counts, as they lie in memory. */
void writeTrees(const SphereTrees& t, ByteWriter& out) {
  static_assert(sizeof(BoxNode) == 32, "box nodes are written as they lie in memory: no padding bytes");
  for (std::size_t n : {t.ballNodes.size(), t.ballOrder.size(), t.tightNodes.size(), t.tightOrder.size(),
                        t.gapNodes.size(), t.gapOrder.size(), t.gapRadius.size()})
    out.put(static_cast<std::uint64_t>(n));
  out.putArray(t.ballNodes);
  out.putArray(t.ballOrder);
  out.putArray(t.tightNodes);
  out.putArray(t.tightOrder);
  out.putArray(t.gapNodes);
  out.putArray(t.gapOrder);
  out.putArray(t.gapRadius);
}

/** Reads what writeTrees wrote and checks that the trees serve set over mesh (sphereTreesProblem). */
SphereTrees readTrees(ByteReader& in, const TriangleMesh& mesh, const ClodSphereSet& set) {
  std::uint64_t counts[7];
  for (std::uint64_t& c : counts) c = in.get<std::uint64_t>("the trees' sizes");
  in.expectArrays({{counts[0], sizeof(BoxNode)},
                   {counts[1], sizeof(std::uint32_t)},
                   {counts[2], sizeof(BoxNode)},
                   {counts[3], sizeof(std::uint32_t)},
                   {counts[4], sizeof(BoxNode)},
                   {counts[5], sizeof(std::uint32_t)},
                   {counts[6], sizeof(float)}});
  SphereTrees t;
  in.readArray(t.ballNodes, counts[0], "the ball tree");
  in.readArray(t.ballOrder, counts[1], "the ball tree's order");
  in.readArray(t.tightNodes, counts[2], "the tight tree");
  in.readArray(t.tightOrder, counts[3], "the tight tree's order");
  in.readArray(t.gapNodes, counts[4], "the gap tree");
  in.readArray(t.gapOrder, counts[5], "the gap tree's order");
  in.readArray(t.gapRadius, counts[6], "the gap tree's radii");
  const std::string problem = sphereTreesProblem(t, mesh, set, meshBoxTreePad(mesh));
  if (!problem.empty()) in.fail("the trees over the spheres: " + problem);
  return t;
}

}  // namespace

void writeCellGridBinary(const ClodDetector::GridParts& parts, const GridCacheKey& key, std::size_t triangles,
                         const std::string& path) {
  const CellGrid& grid = parts.grid;
  if (grid.empty()) throw FormatError("cannot write grid cache file '" + path + "': empty grid");
  ByteWriter w(kMagic, kGridCacheFormatVersion, grid.bytes() + parts.trees.bytes() + 256);
  w.put(kByteOrder);
  w.put(key.meshHash);
  w.put(key.distance);
  w.put(key.setHash);
  w.put(key.radius);
  w.put(key.entriesPerTriangle);
  w.put(static_cast<std::uint8_t>(key.index));
  w.put(static_cast<std::uint64_t>(triangles));
  grid.writeTo(w);
  writeTrees(parts.trees, w);
  w.writeWithChecksum(path, kKind);
}

ClodDetector::GridParts readCellGridBinary(const std::string& path, const GridCacheKey& key, const TriangleMesh& mesh,
                                           const ClodSphereSet& set) {
  detail::MappedFile file;
  const std::string unmapped = file.map(path);
  if (!unmapped.empty()) throw FormatError(std::string(kKind) + " file '" + path + "': " + unmapped);
  ByteReader r = detail::openCacheFile(file.data(), file.size(), kMagic, kGridCacheFormatVersion, kKind, path);
  readHeader(r, key, mesh);
  ClodDetector::GridParts parts;
  parts.grid = CellGrid::readFrom(r, mesh.size());
  if (bitsOf(parts.grid.radius()) != bitsOf(key.radius)) r.fail("the grid's radius differs from the header's");
  parts.trees = readTrees(r, mesh, set);
  return parts;
}

std::uint64_t CellGridCache::defaultMaxBytes() {
  const char* env = std::getenv("CLOD_GRID_CACHE_MAX_MB");
  if (env != nullptr && *env != '\0') {
    char* end = nullptr;
    const double mb = std::strtod(env, &end);
    if (end != env && *end == '\0' && mb >= 0.0 && mb < 1e9) return static_cast<std::uint64_t>(mb * 1024.0 * 1024.0);
  }
  return 2ull << 30;
}

CellGridCache::CellGridCache(std::string directory, std::uint64_t maxBytes)
    : DiskCache(std::move(directory)), maxBytes_(maxBytes > 0 ? maxBytes : defaultMaxBytes()) {}

void CellGridCache::prune(const std::string& keep) const {
  namespace fs = std::filesystem;
  std::error_code ec;
  struct File {
    fs::file_time_type time;
    std::uint64_t bytes;
    fs::path path;
  };
  std::vector<File> files;
  std::uint64_t total = 0;
  for (fs::directory_iterator it(directory(), ec), end; !ec && it != end; it.increment(ec)) {
    if (it->path().extension() != ".clodgrid") continue;
    std::error_code e;
    const std::uint64_t bytes = it->file_size(e);
    const fs::file_time_type time = it->last_write_time(e);
    if (e) continue;  // gone meanwhile (another process pruned it)
    total += bytes;
    files.push_back({time, bytes, it->path()});
  }
  if (total <= maxBytes_) return;
  std::sort(files.begin(), files.end(), [](const File& a, const File& b) { return a.time < b.time; });
  for (const File& f : files) {
    if (total <= maxBytes_) break;
    if (f.path == fs::path(keep)) continue;
    std::error_code e;
    if (fs::remove(f.path, e)) total -= f.bytes;
  }
}

std::string CellGridCache::pathFor(const GridCacheKey& key) const {
  return directory() + "/mesh-" + detail::hex64(key.meshHash) + "-d" + detail::hex64(bitsOf(key.distance)) + "-grid-r" +
         detail::hex64(bitsOf(key.radius)) + "-o" + detail::hex64(optionsHash(key)) + "-v" +
         std::to_string(kGridCacheFormatVersion) + ".clodgrid";
}

namespace {
GridCacheKey normalised(GridCacheKey key) {
  if (key.distance == 0.0) key.distance = 0.0;  // -0 and +0 are the same level and the same file
  return key;
}
}  // namespace

bool CellGridCache::has(const GridCacheKey& key) const {
  std::error_code ec;
  return std::filesystem::is_regular_file(pathFor(normalised(key)), ec);
}

ClodDetector::GridParts CellGridCache::getOrBuild(const TriangleMesh& mesh, const ClodSphereSet& set,
                                                  const GridCacheKey& key,
                                                  const std::function<ClodDetector::GridParts()>& build,
                                                  CacheOutcome* outcome) {
  requireNonNegative(key.distance, "clustering distance");
  if (!(key.radius > 0.0) || !std::isfinite(key.radius))
    throw InvalidParameter("cell grid radius must be finite and > 0, got " + std::to_string(key.radius));
  const GridCacheKey k = normalised(key);
  const auto start = std::chrono::steady_clock::now();
  CacheOutcome local;
  CacheOutcome& out = outcome ? *outcome : local;
  out = CacheOutcome();
  out.path = pathFor(k);
  ClodDetector::GridParts parts;
  lookUp(
      out, start, [&] { parts = readCellGridBinary(out.path, k, mesh, set); },
      [&] {
        if (out.source == CacheSource::Built) misses_.fetch_add(1);
        parts = build();
      },
      [&](const std::string& tmp) { writeCellGridBinary(parts, k, mesh.size(), tmp); });
  std::error_code ec;
  if (out.source == CacheSource::Hit)  // least recently used goes first: a hit makes the file recent
    std::filesystem::last_write_time(out.path, std::filesystem::file_time_type::clock::now(), ec);
  else
    prune(out.path);
  return parts;
}

}  // namespace clod_haptics
