#pragma once
// Internal to the core's .cpp files (not API): the byte buffers of the binary cache files (mesh_cache.cpp,
// sphere_cache.cpp). A cache file is an 8-byte magic, a 32-bit format version, the fields in the machine's
// byte order, then the checksum (cacheChecksum) of every byte before it.

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <initializer_list>
#include <string>
#include <utility>
#include <vector>

namespace clod_haptics {
namespace detail {

/** \brief The byte-order mark every binary cache file stores after its version (read back as written). */
constexpr std::uint32_t kByteOrder = 0x01020304u;

/** \brief The bits of a double, for exact comparisons and file names (-0 and +0 differ). */
inline std::uint64_t bitsOf(double d) {
  std::uint64_t bits;
  std::memcpy(&bits, &d, sizeof(bits));
  return bits;
}

/** \brief The 8-byte magic that opens a cache file. */
using CacheMagic = char[8];

/** \brief Builds a cache file in memory: the magic and version first, then raw values and arrays. */
class ByteWriter {
 public:
  /** \brief A buffer of reserve bytes' capacity, starting with magic and version. */
  ByteWriter(const CacheMagic& magic, std::uint32_t version, std::size_t reserve = 0);

  /** \brief Appends the bytes of a trivially copyable value. */
  template <class T>
  void put(const T& value) {
    append(&value, sizeof(T));
  }
  /** \brief Appends the elements of a contiguous container (vector, string) as they lie in memory. */
  template <class Container>
  void putArray(const Container& values) {
    append(values.data(), values.size() * sizeof(typename Container::value_type));
  }
  /** \brief Appends raw bytes. */
  void append(const void* data, std::size_t bytes) {
    const char* p = static_cast<const char*>(data);
    buffer_.insert(buffer_.end(), p, p + bytes);
  }

  /**
   * \brief Appends the checksum and writes the whole buffer to path.
   * \throws FormatError "cannot write <kind> file '<path>': ..." when the file cannot be opened or written.
   */
  void writeWithChecksum(const std::string& path, const char* kind);
  /** \brief The bytes so far (tests compare two writes). */
  const std::vector<char>& bytes() const { return buffer_; }

 private:
  std::vector<char> buffer_;
};

/**
 * \brief Reads raw values from a byte range. Reading past its end, or any check the caller fails with
 * fail(), throws FormatError "<kind> file '<path>': <why>".
 */
class ByteReader {
 public:
  /** \brief A reader of [data, data + size); kind and path name the file in messages and must outlive it. */
  ByteReader(const char* data, std::size_t size, const char* kind, const std::string& path)
      : data_(data), size_(size), kind_(kind), path_(path) {}

  /** \brief The next value; field names it in the message of a truncated file ("truncated in <field>"). */
  template <class T>
  T get(const char* field = nullptr) {
    T value;
    read(&value, sizeof(T), field);
    return value;
  }
  /** \brief The next bytes into out. */
  void read(void* out, std::size_t bytes, const char* field = nullptr) {
    if (bytes > size_ - pos_) failTruncated(field);
    if (bytes == 0) return;  // an empty array's data() may be null, and memcpy's pointers must be valid even for 0
    std::memcpy(out, data_ + pos_, bytes);
    pos_ += bytes;
  }
  /** \brief The next count elements into values (a vector or string), resized to count first. */
  template <class Container>
  void readArray(Container& values, std::uint64_t count, const char* field = nullptr) {
    values.resize(count);
    read(values.data(), count * sizeof(typename Container::value_type), field);
  }

  /**
   * \brief Checks that arrays of the given element counts and sizes fill the rest of the range exactly, before
   * anything is allocated from counts read in the file. No count exceeds the bytes left, so no product overflows.
   */
  void expectArrays(std::initializer_list<std::pair<std::uint64_t, std::size_t>> countsAndSizes) const {
    expectArraysIn(countsAndSizes, true);
  }
  /** \brief As expectArrays, for arrays that more sections follow: they fit in the rest of the range. */
  void expectArraysWithin(std::initializer_list<std::pair<std::uint64_t, std::size_t>> countsAndSizes) const {
    expectArraysIn(countsAndSizes, false);
  }

  /** \brief Bytes not read yet. */
  std::size_t remaining() const { return size_ - pos_; }
  /** \brief Throws the FormatError naming the file and why. */
  [[noreturn]] void fail(const std::string& why) const;

 private:
  [[noreturn]] void failTruncated(const char* field) const;
  void expectArraysIn(std::initializer_list<std::pair<std::uint64_t, std::size_t>> countsAndSizes, bool whole) const;

  const char* data_;
  std::size_t size_;
  std::size_t pos_ = 0;
  const char* kind_;
  const std::string& path_;
};

/**
 * \brief Reads the whole file at path into bytes.
 * \return empty, or why it could not: "cannot open it", "cannot read its size", "read failed".
 */
std::string readFileBytes(const std::string& path, std::vector<char>& bytes);

/**
 * \brief Checks the frame of a cache file read into bytes and returns a reader of the fields after the
 * version, which ends before the checksum. The checksum is checked first, so no field is read from a byte
 * it did not cover.
 * \throws FormatError "too short to be a cache file", "checksum mismatch (corrupt file)",
 * "not a clod_haptics <kind> file", "format version <v>, expected <version>".
 */
ByteReader openCacheFile(const std::vector<char>& bytes, const CacheMagic& magic, std::uint32_t version,
                         const char* kind, const std::string& path);
/** \brief The same over [data, data + size) (a MappedFile). */
ByteReader openCacheFile(const char* data, std::size_t size, const CacheMagic& magic, std::uint32_t version,
                         const char* kind, const std::string& path);

/**
 * \brief A whole file mapped read-only into memory (mmap), unmapped on destruction: large cache files are read
 * straight from the page cache, with no copy into a buffer first.
 */
class MappedFile {
 public:
  MappedFile() = default;
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;
  ~MappedFile();
  /** \brief Maps path; returns empty, or why it could not ("cannot open it", "cannot read its size", "mmap failed"). */
  std::string map(const std::string& path);
  const char* data() const { return data_; }
  std::size_t size() const { return size_; }

 private:
  const char* data_ = nullptr;
  std::size_t size_ = 0;
  void* mapping_ = nullptr;
};

/** \brief The 16 lower-case hex digits of v, for cache file names. */
std::string hex64(std::uint64_t v);

}  // namespace detail
}  // namespace clod_haptics
