// Morton codes (core/morton.h) against the bit interleaving written out one bit at a time.
#include <gtest/gtest.h>

#include <cstdint>
#include <random>

#include "clod_haptics/core/morton.h"

namespace {

using namespace clod_haptics;

std::uint64_t interleaveNaive(std::uint64_t x, std::uint64_t y, std::uint64_t z) {
  std::uint64_t code = 0;
  for (int bit = 0; bit < 21; ++bit) {
    code |= ((x >> bit) & 1u) << (3 * bit);
    code |= ((y >> bit) & 1u) << (3 * bit + 1);
    code |= ((z >> bit) & 1u) << (3 * bit + 2);
  }
  return code;
}

TEST(Morton, EqualsTheInterleavingWrittenOut) {
  std::mt19937_64 rng(21);
  std::uniform_int_distribution<std::uint64_t> coord(0, (1u << 21) - 1);
  for (int i = 0; i < 20000; ++i) {
    const std::uint64_t x = coord(rng), y = coord(rng), z = coord(rng);
    ASSERT_EQ(mortonCode(Vec3(x + 0.75, y + 0.25, z)), interleaveNaive(x, y, z)) << x << " " << y << " " << z;
  }
  EXPECT_EQ(mortonCode(Vec3(0, 0, 0)), 0u);
  EXPECT_EQ(mortonCode(Vec3(kMortonMax, kMortonMax, kMortonMax)), (std::uint64_t{1} << 63) - 1);
}

TEST(Morton, SpreadKeepsOnlyTheLow21Bits) {
  EXPECT_EQ(spreadBits3(std::uint64_t{1} << 21), 0u);
  EXPECT_EQ(spreadBits3((std::uint64_t{1} << 21) | 5u), spreadBits3(5u));
  EXPECT_EQ(spreadBits3(5u), 0x41u);  // bits 0 and 2 -> bits 0 and 6
}

}  // namespace
