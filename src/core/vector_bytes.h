#pragma once
// Internal to the core's .cpp files (not API): the memory a vector holds, for the bytes() of what a detector keeps.

#include <cstddef>
#include <vector>

namespace clod_haptics {
namespace detail {

/** \brief The bytes v holds (its capacity, not its size). */
template <class T>
std::size_t bytesOf(const std::vector<T>& v) {
  return v.capacity() * sizeof(T);
}

}  // namespace detail
}  // namespace clod_haptics
