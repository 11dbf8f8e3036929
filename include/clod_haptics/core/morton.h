#pragma once

#include <cstdint>

#include "clod_haptics/core/mesh.h"

namespace clod_haptics {

/** \brief Spreads the low 21 bits of x to every third bit (bit i goes to bit 3i). */
inline std::uint64_t spreadBits3(std::uint64_t x) {
  x &= 0x1fffff;
  x = (x | x << 32) & 0x1f00000000ffffull;
  x = (x | x << 16) & 0x1f0000ff0000ffull;
  x = (x | x << 8) & 0x100f00f00f00f00full;
  x = (x | x << 4) & 0x10c30c30c30c30c3ull;
  x = (x | x << 2) & 0x1249249249249249ull;
  return x;
}

/**
 * \brief The Morton (Z-order) code of a point given in grid units: each coordinate in [0, 2^21),
 * truncated to an integer; x takes bit 0 of each triple, y bit 1, z bit 2.
 */
inline std::uint64_t mortonCode(const Vec3& q) {
  return spreadBits3(static_cast<std::uint64_t>(q.x())) | spreadBits3(static_cast<std::uint64_t>(q.y())) << 1 |
         spreadBits3(static_cast<std::uint64_t>(q.z())) << 2;
}

/** \brief The largest coordinate mortonCode() takes (2^21 - 1). */
constexpr double kMortonMax = 2097151.0;

}  // namespace clod_haptics
