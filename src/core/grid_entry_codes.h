#pragma once
// Internal to the core (not API): how the cell grid's build stores a triangle's distance and direction from a cell's
// centre in an entry's bytes (CellGrid::Entry), in one place for the scalar build and its AVX2 form
// (simd/grid_entry_avx2.h), which must agree with it bit for bit.

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace clod_haptics {
namespace detail {

/** \brief u (finite) times 127, rounded half away from zero as std::lround would, without its library call. */
inline std::int8_t quantiseDirection(double u) {
  const double v = std::clamp(u, -1.0, 1.0) * 127.0;
  const auto whole = static_cast<int>(v);  // toward zero; v - whole is exact
  const double part = v - whole;
  return static_cast<std::int8_t>(whole + (part >= 0.5) - (part <= -0.5));
}

/** \brief The 8-bit distance of an entry, rounded down (q * unit <= d, exactly as the query computes it). */
inline std::uint8_t distanceCode(float distance, double unit) {
  const double d = static_cast<double>(distance);
  double q = std::min(255.0, std::floor(d / unit));
  while (q > 0.0 && q * unit > d) q -= 1.0;
  return static_cast<std::uint8_t>(q);
}

/** \brief The finer byte: where the rounded distance lies within its code, in 256ths of the unit (scale 256 / unit). */
inline std::uint8_t finerCode(float rounded, std::uint8_t code, double unit, double scale) {
  const double within = (static_cast<double>(rounded) - code * unit) * scale;  // monotone in the distance
  return static_cast<std::uint8_t>(std::clamp(within, 0.0, 255.0));
}

}  // namespace detail
}  // namespace clod_haptics
