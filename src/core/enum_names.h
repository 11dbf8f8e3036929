#pragma once
// Internal to the core's .cpp files (not API): an enum's names as one table, read both ways, so the parser and
// the printer of a parameter's values cannot disagree.

#include <cstddef>
#include <cstring>
#include <utility>

namespace clod_haptics {
namespace detail {

template <class E, std::size_t N>
using EnumNames = std::pair<E, const char*>[N];

/** \brief The value named text (false for null or an unknown name). */
template <class E, std::size_t N>
bool parseName(const char* text, const EnumNames<E, N>& names, E& out) {
  if (text == nullptr) return false;
  for (const auto& entry : names) {
    if (std::strcmp(text, entry.second) == 0) {
      out = entry.first;
      return true;
    }
  }
  return false;
}

/** \brief The name of value ("unknown" when the table lacks it). */
template <class E, std::size_t N>
const char* nameOf(E value, const EnumNames<E, N>& names) {
  for (const auto& entry : names)
    if (entry.first == value) return entry.second;
  return "unknown";
}

}  // namespace detail
}  // namespace clod_haptics
