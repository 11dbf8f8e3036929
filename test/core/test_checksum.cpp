// The hashes of raw bytes (checksum.h): the cache files' checksum sees every single-bit flip at every position of
// buffers whose lengths cover every tail (0 to 31 bytes past the 32-byte blocks) and every lane, and tells apart
// buffers that differ only in length; the key hash continues from its seed.

#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <set>
#include <vector>

#include "clod_haptics/core/checksum.h"

namespace {

using namespace clod_haptics;

TEST(Checksum, EverySingleBitFlipChangesTheChecksum) {
  std::mt19937_64 rng(3);
  for (std::size_t length : {1u, 7u, 8u, 31u, 32u, 33u, 63u, 64u, 95u, 100u, 257u}) {
    std::vector<unsigned char> bytes(length);
    for (unsigned char& b : bytes) b = static_cast<unsigned char>(rng());
    const std::uint64_t base = cacheChecksum(bytes.data(), bytes.size());
    EXPECT_EQ(cacheChecksum(bytes.data(), bytes.size()), base) << "deterministic";
    std::set<std::uint64_t> seen{base};
    for (std::size_t i = 0; i < length; ++i)
      for (int bit = 0; bit < 8; ++bit) {
        bytes[i] ^= static_cast<unsigned char>(1u << bit);
        const std::uint64_t flipped = cacheChecksum(bytes.data(), bytes.size());
        bytes[i] ^= static_cast<unsigned char>(1u << bit);
        EXPECT_NE(flipped, base) << "length " << length << " byte " << i << " bit " << bit;
        seen.insert(flipped);
      }
    EXPECT_EQ(seen.size(), 8 * length + 1) << "length " << length << ": two flips collided";
  }
}

TEST(Checksum, LengthAndOrderCount) {
  const std::vector<unsigned char> zeros(96, 0);
  std::set<std::uint64_t> sums;
  for (std::size_t length = 0; length <= zeros.size(); ++length) sums.insert(cacheChecksum(zeros.data(), length));
  EXPECT_EQ(sums.size(), zeros.size() + 1) << "zero buffers of different lengths";
  // Two 8-byte words swapped between lanes, and within a lane across blocks.
  std::vector<std::uint64_t> words(16);
  for (std::size_t i = 0; i < words.size(); ++i) words[i] = 0x9e3779b97f4a7c15ull * (i + 1);
  const std::uint64_t base = cacheChecksum(words.data(), words.size() * 8);
  for (std::size_t j : {1u, 4u, 5u}) {
    std::vector<std::uint64_t> swapped = words;
    std::swap(swapped[0], swapped[j]);
    EXPECT_NE(cacheChecksum(swapped.data(), swapped.size() * 8), base) << "word 0 swapped with " << j;
  }
}

TEST(Checksum, KeyHashContinuesFromItsSeed) {
  const char text[] = "clod_haptics mesh content";
  const std::size_t n = sizeof(text) - 1;
  EXPECT_EQ(fnv1a64(text + 8, n - 8, fnv1a64(text, 8)), fnv1a64(text, n)) << "split at a word boundary";
  EXPECT_NE(fnv1a64(text, n, 1), fnv1a64(text, n));
}

}  // namespace
