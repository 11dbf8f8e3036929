#pragma once
// Internal to the core's .cpp files (not API): doubles rounded to float toward -inf / +inf, for bounds that
// must stay bounds after the cast to float (boxes, cell distances).

#include <cstdint>
#include <cstring>
#include <limits>

namespace clod_haptics {
namespace detail {

/** \brief The next float below f (f not NaN), by its bit pattern: nextafterf is a library call, and the
 * box builders run this several times per triangle. */
inline float floatBelow(float f) {
  if (f == 0.0f) return -std::numeric_limits<float>::denorm_min();
  std::uint32_t bits;
  std::memcpy(&bits, &f, sizeof bits);
  bits = f > 0.0f ? bits - 1 : bits + 1;
  std::memcpy(&f, &bits, sizeof f);
  return f;
}
/** \brief The next float above f (f not NaN). */
inline float floatAbove(float f) { return -floatBelow(-f); }

/** \brief The largest float <= x. */
inline float roundDown(double x) {
  const float f = static_cast<float>(x);
  return static_cast<double>(f) > x ? floatBelow(f) : f;
}
/** \brief The smallest float >= x. */
inline float roundUp(double x) {
  const float f = static_cast<float>(x);
  return static_cast<double>(f) < x ? floatAbove(f) : f;
}

}  // namespace detail
}  // namespace clod_haptics
