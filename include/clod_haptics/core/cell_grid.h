#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

#include "clod_haptics/core/mesh.h"
#include "clod_haptics/core/sphere_set.h"

namespace clod_haptics {

namespace detail {

class ByteReader;
class ByteWriter;

/**
 * \brief A malloc'd array of trivially copyable items that grows and shrinks with realloc: for large
 * blocks glibc moves the pages (mremap) instead of copying, so growing or trimming never holds the old
 * and the new block resident at once (std::vector's growth does, and cannot shrink in place).
 */
template <class T>
class ReallocArray {
  static_assert(std::is_trivially_copyable<T>::value, "ReallocArray holds trivially copyable items");

 public:
  using value_type = T;

  ReallocArray() = default;
  ReallocArray(const ReallocArray& o) {
    reserve(o.size_);
    if (o.size_ > 0) std::memcpy(data_, o.data_, o.size_ * sizeof(T));
    size_ = o.size_;
  }
  ReallocArray(ReallocArray&& o) noexcept : data_(o.data_), size_(o.size_), capacity_(o.capacity_) {
    o.data_ = nullptr;
    o.size_ = o.capacity_ = 0;
  }
  ReallocArray& operator=(ReallocArray o) noexcept {
    std::swap(data_, o.data_);
    std::swap(size_, o.size_);
    std::swap(capacity_, o.capacity_);
    return *this;
  }
  ~ReallocArray() { std::free(data_); }

  T* data() noexcept { return data_; }
  const T* data() const noexcept { return data_; }
  T* begin() noexcept { return data_; }
  T* end() noexcept { return data_ + size_; }
  const T* begin() const noexcept { return data_; }
  const T* end() const noexcept { return data_ + size_; }
  T& operator[](std::size_t i) noexcept { return data_[i]; }
  const T& operator[](std::size_t i) const noexcept { return data_[i]; }
  std::size_t size() const noexcept { return size_; }
  std::size_t capacity() const noexcept { return capacity_; }
  bool empty() const noexcept { return size_ == 0; }
  void clear() noexcept { size_ = 0; }
  void reserve(std::size_t n) {
    if (n > capacity_) resizeBlock(n);
  }
  /** \brief New items are uninitialised. */
  void resize(std::size_t n) {
    if (n > capacity_) resizeBlock(std::max(n, 2 * capacity_));
    size_ = n;
  }
  void push_back(const T& v) {
    if (size_ == capacity_) resizeBlock(std::max<std::size_t>(64, 2 * capacity_));
    data_[size_++] = v;
  }
  /** \brief Releases the capacity beyond size(). */
  void shrink() {
    if (capacity_ > size_) resizeBlock(size_);
  }

 private:
  void resizeBlock(std::size_t n) {
    if (n == 0) {
      std::free(data_);
      data_ = nullptr;
      capacity_ = 0;
      return;
    }
    if (n > std::numeric_limits<std::size_t>::max() / sizeof(T)) throw std::bad_alloc();
    void* p = std::realloc(data_, n * sizeof(T));
    if (p == nullptr) throw std::bad_alloc();
    data_ = static_cast<T*>(p);
    capacity_ = n;
  }
  T* data_ = nullptr;
  std::size_t size_ = 0, capacity_ = 0;
};

}  // namespace detail

/**
 * \brief The fast level precomputed per cell of a uniform grid: for every pointer of radius up to
 * radius() inside a cell, the triangles (and the spheres listing them) that the two-level detection
 * could report. A query is one index lookup and a few exact triangle tests, O(1) in the mesh size; an
 * empty cell means no contact and no precise work at all.
 *
 * A cell of side h keeps every triangle whose distance to the cell's centre is at most
 * radius + h sqrt(3) / 2 (an exact test, so no candidate is missed), sorted by that distance (to 1/256 of
 * its 8-bit code's unit, then by triangle), so a query stops at the first candidate whose lower bound
 * (distance to the centre minus the pointer's offset from the centre) exceeds the best distance so far.
 * Immutable after construction.
 *
 * Layout, for a query bound by memory latency: one array of 8-byte entries where each non-empty cell
 * is a header (its candidate and sphere counts) followed by its candidates, so a query touches one
 * run of consecutive cache lines. Cells are found through a dense index (one bit per cell of the box
 * plus a rank per 64 cells, then the run's start: small enough to stay in cache, and an empty cell is
 * answered from the bit alone) when the box has few enough cells, otherwise through a hash table.
 *
 * Beside its index entry each cell keeps a cheap proof of "no contact", so most pointers near but not
 * on the surface are answered without reading the cell's candidates: a slab
 * |m . (p - centre) - offset| <= halfWidth holding every candidate's part within reach of the cell
 * (m, 8 bits per component: the first candidate's normal or the mean normal of the candidates nearest
 * the centre, whichever gives the narrower slab); a pointer farther than r from the slab touches nothing.
 */
class CellGrid {
 public:
  /** \brief One candidate of a cell (8 bytes). */
  struct Entry {
    std::uint32_t triangle;
    /**
     * Distance dc from the cell centre to the triangle in units of distanceUnit() (reach / 255),
     * rounded down: a lower bound. A cell's entries are nearest first (see the class comment).
     */
    std::uint8_t distance;
    /**
     * Unit direction u from the triangle's closest point q to the cell centre, times 127, rounded to
     * nearest (zero when the centre is on the triangle). The triangle lies in the half-space
     * (x - q) . u <= 0, so for a pointer at p distance(p, T) >= dc + (p - centre) . u; the rounding of
     * u (at most sqrt(3) / 254) is covered by slack().
     */
    std::int8_t direction[3];
    /** \brief Component k of the direction as stored (divided by 127). */
    float dir(int k) const { return static_cast<float>(direction[k]) * (1.0f / 127.0f); }
  };
  /** \brief A non-empty cell: its candidates and the number of distinct spheres they come from. */
  struct Cell {
    const Entry* entries;
    std::uint32_t count;
    std::uint32_t spheres;
  };
  /** \brief How cells are found. */
  enum class Index : std::uint8_t { Auto, Dense, Hashed };

  CellGrid() = default;
  /**
   * \brief Builds the grid for pointers of radius up to radius (> 0). Cell side is 2 to 3 radius, grown
   * when the grid would exceed 2^21 cells per axis or its memory budget: max(10^6, entriesPerTriangle x
   * triangles) candidates (8 bytes each), so memory stays linear in the mesh beyond 41,667 triangles. Then,
   * while the grid would take more than bytesPerTriangle, grown further (up to 2.5 times) as long as a cell keeps
   * at most 16 candidates: where triangles are large against the cells, coarser cells answer as fast and take
   * less memory and build time. The candidates, cells and index are estimated before the build from the
   * triangles' total area, perimeter and count (the volume of each triangle grown by a cell's reach), which holds
   * for small, large and long thin triangles.
   * \param index Auto: dense when its bit index takes no more than the hashed index would, or at most 16 bytes
   * per triangle, hashed otherwise; Dense or Hashed force one (Dense falls back to Hashed beyond 2^34 cells).
   * \param sliceCandidates the build collects candidates in slices of z of about half this many, two slices at a
   * time (the peak memory of the build is the entries plus about this many 20-byte candidates); the grid is the same.
   * \param bytesPerTriangle the size the grid aims at where coarser cells cost no query speed (see above).
   */
  CellGrid(const TriangleMesh& mesh, const ClodSphereSet& set, double radius, double entriesPerTriangle = 24.0,
           Index index = Index::Auto, double sliceCandidates = 1e6, double bytesPerTriangle = 192.0);

  /**
   * \brief The grid the constructor builds for set, from another level's grid of the same mesh: the candidates do not
   * depend on the sphere set, only each cell's count of distinct spheres does, so when the cells this build would
   * choose are sameMesh's (radius, side, origin, extent and index) the grid is sameMesh's with those counts made again
   * (a copy and one pass over the candidates), else it is built. Bit for bit the constructor's grid either way
   * (test_cell_grid.cpp). sameMesh must have been built for mesh (the detector and SceneAssets know it); a candidate
   * beyond the mesh's triangles makes it build instead. reused (when given): whether sameMesh's cells were taken.
   */
  static CellGrid forLevel(const CellGrid& sameMesh, const TriangleMesh& mesh, const ClodSphereSet& set, double radius,
                           double entriesPerTriangle = 24.0, Index index = Index::Auto, double sliceCandidates = 1e6,
                           double bytesPerTriangle = 192.0, bool* reused = nullptr);

  /** \brief The largest pointer radius the grid answers for; larger pointers need another descent. */
  double radius() const { return radius_; }
  /** \brief Slack to subtract from an Entry's bound for the rounding of its float and 8-bit fields. */
  double slack() const { return slack_; }
  /** \brief Unit of Entry::distance. */
  double distanceUnit() const { return distanceUnit_; }
  /** \brief An entry's distance from the cell centre (a lower bound of the true one). */
  double centreDistance(const Entry& e) const { return e.distance * distanceUnit_; }
  /** \brief Side of a cell. */
  double cellSize() const { return cell_; }
  /** \brief Whether the grid was built. */
  bool empty() const { return entries_.empty(); }
  /** \brief Whether cells are found through the dense bit index (else the hash table). */
  bool dense() const { return !words_.empty(); }
  /** \brief Number of stored cells and candidates (for statistics). */
  std::size_t cells() const { return cellCount_; }
  std::size_t entries() const { return entries_.size() - cellCount_; }
  /** \brief Candidates of the most crowded cell (derived from the cells, at the build and when read). */
  std::uint32_t largestCell() const { return largest_; }
  /** \brief Bytes held by the grid's arrays. */
  std::size_t bytes() const;

  /**
   * \brief Appends the grid to a cache file (grid_cache.h): its scalars, the array sizes, then each array as it
   * lies in memory, so readFrom copies each array in one piece.
   */
  void writeTo(detail::ByteWriter& out) const;
  /**
   * \brief Reads a grid that writeTo wrote, checked so that no lookup can leave its arrays: finite scalars,
   * sizes that fill the file, every cell header and its candidates inside the entries, every candidate's
   * triangle below triangles (the mesh's count), the dense index's ranks or every hashed slot's header and
   * probe chain consistent. A grid that passes answers exactly as the one written.
   * \throws FormatError (through in.fail) naming the first check that failed.
   */
  static CellGrid readFrom(detail::ByteReader& in, std::size_t triangles);

  /** \brief What the index keeps per non-empty cell for the proof of no contact (8 bytes). */
  struct CellRef {
    std::int8_t normal[3];  ///< slab direction m times 127 (zero: no slab)
    std::uint8_t unused;
    std::int16_t offset;      ///< slab centre along m, in units of cellSize() / 8192
    std::uint16_t halfWidth;  ///< slab half width, same units, rounded up (covers offset's rounding)
  };

  /** \brief Cell key of p, or kOutside when p is outside the grid (then no triangle is within radius()). */
  std::uint64_t keyOf(const Vec3& p) const noexcept {
    std::uint64_t key = 0;
    for (int k = 0; k < 3; ++k) {
      const double q = (p[k] - origin_[k]) * inv_;
      if (!(q >= 0.0) || q >= static_cast<double>(dims_[k])) return kOutside;
      key |= static_cast<std::uint64_t>(q) << (k * kBits);  // truncation: floor for q >= 0
    }
    return key;
  }
  /**
   * \brief Integer coordinates of the cell holding p along each axis (keyOf's floor), clamped to
   * [-1, cells on the axis]: what a walk over a box of cells needs to enumerate them with keyAt().
   */
  void cellCoordinates(const Vec3& p, std::int64_t out[3]) const noexcept {
    for (int k = 0; k < 3; ++k) {
      const double q = std::floor((p[k] - origin_[k]) * inv_);
      out[k] = q < 0.0 ? -1 : q >= static_cast<double>(dims_[k]) ? dims_[k] : static_cast<std::int64_t>(q);
    }
  }
  /** \brief Key of the cell at integer coordinates (cellCoordinates), or kOutside beyond the grid. */
  std::uint64_t keyAt(std::int64_t x, std::int64_t y, std::int64_t z) const noexcept {
    if (x < 0 || y < 0 || z < 0 || x >= dims_[0] || y >= dims_[1] || z >= dims_[2]) return kOutside;
    return static_cast<std::uint64_t>(x) | static_cast<std::uint64_t>(y) << kBits |
           static_cast<std::uint64_t>(z) << (2 * kBits);
  }
  /** \brief The index entry of the cell of a key, or null when no triangle is near it. */
  const CellRef* find(std::uint64_t key) const noexcept {
    if (words_.empty() || key == kOutside) return findHashed(key);
    const std::uint64_t linear = linearOf(key);
    const Word& w = words_[linear >> 6];
    const std::uint64_t bit = 1ull << (linear & 63);
    if (!(w.bits & bit)) return nullptr;
    return refs_.data() + w.rank + bitCount(w.bits & (bit - 1));
  }
  /** \brief The candidates of a cell. */
  Cell cell(const CellRef& ref) const noexcept {
    const Entry* header =
        entries_.data() + (words_.empty() ? reinterpret_cast<const Slot*>(reinterpret_cast<const char*>(&ref) -
                                                                          offsetof(Slot, ref))->header
                                          : headers_[static_cast<std::size_t>(&ref - refs_.data())]);
    std::uint32_t spheres;
    std::memcpy(&spheres, reinterpret_cast<const unsigned char*>(header) + 4, sizeof spheres);
    return Cell{header + 1, header->triangle, spheres};
  }
  /**
   * \brief How far from the point p = centre + rel of a cell every triangle is listed by that cell: the cell
   * lists every triangle within radius() + h sqrt(3) / 2 of its centre, so every one within that less |rel| of p
   * (less a rounding margin). Beyond radius(): a search for the nearest triangle farther than the radius (a
   * pointer pushed deeper) is answered by the cell alone when it finds one within this distance.
   */
  double listedWithin(const Vec3& rel) const noexcept {
    return radius_ + 0.8660254037844386 * cell_ - rel.norm() - slabPad_;
  }
  /**
   * \brief Whether the pointer (p = centre + rel, radius r <= radius()) in the cell certainly touches
   * no triangle: it is farther than r from the cell's slab.
   */
  bool noContact(const CellRef& ref, const Vec3& rel, double r) const noexcept {
    // |m| <= 1 + kDirection: |m . (p - q)| > |m| r proves |p - q| > r for every slab point q.
    const double along = (rel.x() * ref.normal[0] + rel.y() * ref.normal[1] + rel.z() * ref.normal[2]) * (1.0 / 127.0);
    return std::abs(along - unit_ * ref.offset) - unit_ * ref.halfWidth - slabPad_ > r * kSlabRadius;
  }
  /** \brief Centre of the cell of a key. */
  Vec3 centreOf(std::uint64_t key) const noexcept {
    constexpr std::uint64_t m = (1ull << kBits) - 1;
    return origin_ + (Vec3(static_cast<double>(key & m), static_cast<double>((key >> kBits) & m),
                           static_cast<double>((key >> (2 * kBits)) & m)) +
                      Vec3::Constant(0.5)) *
                         cell_;
  }

  static constexpr std::uint64_t kOutside = ~0ull;
  static constexpr int kBits = 21;  ///< bits per axis in a key

 private:
  struct Word {
    std::uint64_t bits;  // one bit per cell, in linear order x + nx (y + ny z)
    std::uint32_t rank;  // non-empty cells before this word
    std::uint32_t unused;
  };
  struct Slot {
    std::uint64_t key;  // kOutside marks a free slot
    std::uint64_t header;
    CellRef ref;
  };
  /**
   * Set bits of x. Without the POPCNT instruction (the generic x86-64 the package builds for) __builtin_popcountll
   * is a call into libgcc (a table of bytes); every lookup of the dense index counts once, so it is inlined here.
   */
  static std::uint32_t bitCount(std::uint64_t x) noexcept {
#if defined(__POPCNT__)
    return static_cast<std::uint32_t>(__builtin_popcountll(x));
#else
    x -= (x >> 1) & 0x5555555555555555ull;
    x = (x & 0x3333333333333333ull) + ((x >> 2) & 0x3333333333333333ull);
    x = (x + (x >> 4)) & 0x0f0f0f0f0f0f0f0full;
    return static_cast<std::uint32_t>((x * 0x0101010101010101ull) >> 56);
#endif
  }
  /** Position of a cell in the linear order x + nx (y + ny z) of the dense index. */
  std::uint64_t linearOf(std::uint64_t key) const noexcept {
    constexpr std::uint64_t m = (1ull << kBits) - 1;
    return (key & m) + static_cast<std::uint64_t>(dims_[0]) *
                           (((key >> kBits) & m) + static_cast<std::uint64_t>(dims_[1]) * ((key >> (2 * kBits)) & m));
  }
  const CellRef* findHashed(std::uint64_t key) const noexcept;
  // The index of the cells (keys in key order, headers: their positions in the entries, refs: their slabs).
  bool useDenseIndex(Index index, std::size_t triangles) const;
  /**
   * Each cell's count of distinct spheres made again for set; false (the grid half rewritten) when a candidate lies
   * beyond triangles or a header beyond the entries.
   */
  bool recountSpheres(const ClodSphereSet& set, std::size_t triangles);
  void buildDenseIndex(const std::vector<std::uint64_t>& keys, const std::vector<std::uint64_t>& headers,
                       std::vector<CellRef>& refs);
  void buildHashedIndex(const std::vector<std::uint64_t>& keys, const std::vector<std::uint64_t>& headers,
                        const std::vector<CellRef>& refs);
  static constexpr double kSlabRadius = 1.0 + 1.7320508075688772 / 254.0;  // bound of |m|
  double radius_ = 0.0;
  double cell_ = 0.0;
  double inv_ = 0.0;
  double slack_ = 0.0;
  double unit_ = 0.0;  // slab units: cell / 8192
  double distanceUnit_ = 0.0;
  double slabPad_ = 0.0;  // rounding of the slab test
  Vec3 origin_ = Vec3::Zero();
  std::int64_t dims_[3] = {0, 0, 0};
  std::size_t cellCount_ = 0;
  // Per cell: a header (triangle = count, the next 4 bytes = spheres), then its candidates.
  detail::ReallocArray<Entry> entries_;
  std::vector<Word> words_;             // dense index
  std::vector<CellRef> refs_;           // dense index: proofs of the k-th non-empty cell (read by every query)
  std::vector<std::uint32_t> headers_;  // dense index: its header in the entries (read on contact only)
  std::vector<Slot> slots_;             // hashed index: open addressing
  std::uint64_t mask_ = 0;
  std::uint32_t largest_ = 0;  // candidates of the most crowded cell (last: the members every query reads keep their
                               // places)
};

}  // namespace clod_haptics
