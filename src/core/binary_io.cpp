#include "binary_io.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cinttypes>
#include <cstdio>
#include <fstream>

#include "clod_haptics/core/errors.h"
#include "clod_haptics/core/sphere_cache.h"

namespace clod_haptics {
namespace detail {

ByteWriter::ByteWriter(const CacheMagic& magic, std::uint32_t version, std::size_t reserve) {
  buffer_.reserve(sizeof(CacheMagic) + sizeof(version) + reserve);
  buffer_.assign(magic, magic + sizeof(CacheMagic));
  put(version);
}

void ByteWriter::writeWithChecksum(const std::string& path, const char* kind) {
  put(cacheChecksum(buffer_.data(), buffer_.size()));
  const std::string prefix = std::string("cannot write ") + kind + " file '" + path + "': ";
  std::ofstream file(path, std::ios::binary | std::ios::trunc);
  if (!file) throw FormatError(prefix + "cannot open it");
  file.write(buffer_.data(), static_cast<std::streamsize>(buffer_.size()));
  file.close();
  if (!file) throw FormatError(prefix + "write failed");
}

void ByteReader::expectArraysIn(std::initializer_list<std::pair<std::uint64_t, std::size_t>> countsAndSizes,
                                bool whole) const {
  std::uint64_t total = 0;
  for (const auto& [count, size] : countsAndSizes) {
    if (count > remaining()) fail("array sizes do not match the file size");
    total += count * size;
    if (total > remaining()) fail("array sizes do not match the file size");
  }
  if (whole && total != remaining()) fail("array sizes do not match the file size");
}

void ByteReader::fail(const std::string& why) const {
  throw FormatError(std::string(kind_) + " file '" + path_ + "': " + why);
}

void ByteReader::failTruncated(const char* field) const {
  fail(field != nullptr ? std::string("truncated in ") + field : std::string("truncated"));
}

std::string readFileBytes(const std::string& path, std::vector<char>& bytes) {
  bytes.clear();
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) return "cannot open it";
  const std::streamoff size = in.tellg();
  if (size < 0) return "cannot read its size";
  bytes.resize(static_cast<std::size_t>(size));
  in.seekg(0);
  in.read(bytes.data(), size);
  if (!in) return "read failed";
  return {};
}

ByteReader openCacheFile(const std::vector<char>& bytes, const CacheMagic& magic, std::uint32_t version,
                         const char* kind, const std::string& path) {
  return openCacheFile(bytes.data(), bytes.size(), magic, version, kind, path);
}

ByteReader openCacheFile(const char* data, std::size_t size, const CacheMagic& magic, std::uint32_t version,
                         const char* kind, const std::string& path) {
  const ByteReader whole(data, size, kind, path);
  std::uint64_t stored;
  if (size < sizeof(CacheMagic) + sizeof(stored)) whole.fail("too short to be a cache file");
  std::memcpy(&stored, data + size - sizeof(stored), sizeof(stored));
  if (cacheChecksum(data, size - sizeof(stored)) != stored) whole.fail("checksum mismatch (corrupt file)");

  ByteReader body(data, size - sizeof(stored), kind, path);
  char found[sizeof(CacheMagic)];
  body.read(found, sizeof(found), "the magic");
  if (std::memcmp(found, magic, sizeof(CacheMagic)) != 0) {
    body.fail(std::string("not a clod_haptics ") + kind + " file");
  }
  const auto foundVersion = body.get<std::uint32_t>("the version");
  if (foundVersion != version) {
    body.fail("format version " + std::to_string(foundVersion) + ", expected " + std::to_string(version));
  }
  return body;
}

MappedFile::~MappedFile() {
  if (mapping_ != nullptr) ::munmap(mapping_, size_);
}

std::string MappedFile::map(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return "cannot open it";
  struct stat st;
  if (::fstat(fd, &st) != 0 || st.st_size < 0) {
    ::close(fd);
    return "cannot read its size";
  }
  size_ = static_cast<std::size_t>(st.st_size);
  if (size_ == 0) {  // mmap refuses an empty range; an empty file is "too short" for openCacheFile
    ::close(fd);
    data_ = "";
    return {};
  }
  void* p = ::mmap(nullptr, size_, PROT_READ, MAP_PRIVATE, fd, 0);
  ::close(fd);  // the mapping keeps the file
  if (p == MAP_FAILED) {
    size_ = 0;
    return "mmap failed";
  }
  ::madvise(p, size_, MADV_SEQUENTIAL);
  mapping_ = p;
  data_ = static_cast<const char*>(p);
  return {};
}

std::string hex64(std::uint64_t v) {
  char text[17];
  std::snprintf(text, sizeof(text), "%016" PRIx64, v);
  return text;
}

}  // namespace detail
}  // namespace clod_haptics
