#pragma once

// Shared pieces of the mesh readers: whole-file reading, a cursor over whitespace-separated tokens with line
// numbers, number parsing that accepts a token only when all of it is the number, and the checks every reader
// makes (binary bytes in a text file, compressed files, header counts against the file's size).

#include <cstdint>
#include <string>
#include <string_view>

#include "clod_haptics/core/errors.h"

namespace clod_haptics {
namespace detail {

/** \brief The whole file; MeshLoadError if it is not a regular file or cannot be read. */
std::string readWholeFile(const std::string& path);

/** \brief A cursor over the tokens of a text, by line; `comment` (if not 0) starts a comment to the line's end. */
class TextScanner {
 public:
  TextScanner(std::string_view text, char comment, std::size_t line = 1) : text_(text), comment_(comment), line_(line) {}

  /** \brief The next token of the current line, or an empty view at the line's end (which is not left). */
  std::string_view tokenInLine();
  /** \brief Moves to the start of the next line (skipping the rest of this one); false at the end of the text. */
  bool nextLine();
  /** \brief The next token, crossing lines; empty at the end of the text. */
  std::string_view token();
  /** \brief The current line number, 1-based. */
  std::size_t line() const { return line_; }
  /** \brief Bytes not yet read. */
  std::size_t remaining() const { return text_.size() - pos_; }

 private:
  std::string_view text_;
  char comment_;
  std::size_t line_;
  std::size_t pos_ = 0;
};

/** \brief The token as the nearest double (strtod in the C locale); false unless all of the token is a number. */
bool parseDouble(std::string_view token, double& value);
/** \brief The token as a decimal integer with an optional sign; false unless all of it is one that fits. */
bool parseInteger(std::string_view token, std::int64_t& value);

/** \brief "line 12: " */
std::string atLine(std::size_t line);
/** \brief A token for a message: quoted, cut to 40 characters. */
std::string quoted(std::string_view token);
/** \brief "coordinate y of vertex 3 is '1e400', not a finite number", or "... 'abc', not a number". */
std::string badCoordinate(int axis, std::size_t vertex, std::string_view token, bool parsed);

/**
 * \brief Throws unless the bytes look like the named text format: a gzip or zip file, or a control byte other
 * than white space, is named as such ("not an OFF file: it is gzip-compressed data").
 */
void requireText(const std::string& path, const std::string& bytes, const char* format);
/** \brief "gzip-compressed data", "a zip archive" or "" for bytes that are none of the known containers. */
std::string containerKind(const std::string& bytes);

/**
 * \brief Throws unless `count` items of at least `minBytes` each fit in `available` bytes, so a header's
 * counts are checked before anything is reserved for them.
 */
void requireRoom(const std::string& path, std::uint64_t count, const std::string& what, std::uint64_t minBytes,
                 std::uint64_t available);

/** \brief "header says 12 faces, the file ends after 1" */
[[noreturn]] void throwEndsEarly(const std::string& path, std::uint64_t declared, const std::string& what,
                                 std::uint64_t read);

}  // namespace detail
}  // namespace clod_haptics
