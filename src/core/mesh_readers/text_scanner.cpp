#include "text_scanner.h"

#include <cerrno>
#include <clocale>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>

#include <locale.h>

namespace clod_haptics {
namespace detail {
namespace {

bool isSpace(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; }

// strtod reads the decimal point of the current locale; mesh files always write '.'.
locale_t cLocale() {
  static const locale_t c = newlocale(LC_ALL_MASK, "C", static_cast<locale_t>(nullptr));
  return c;
}

// Clinger's fast path: a decimal m x 10^e with m < 2^53 and |e| <= 22 is one exact integer and one exact power
// of ten, so a single IEEE multiplication or division rounds it exactly as strtod does. False (nothing decided)
// for any other token: strtod reads those.
bool parseSimpleDecimal(std::string_view t, double& value) {
  static const double kPow10[] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,  1e10, 1e11,
                                  1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};
  std::size_t i = 0;
  const bool negative = i < t.size() && t[i] == '-';
  if (i < t.size() && (t[i] == '-' || t[i] == '+')) ++i;
  std::uint64_t m = 0;
  int digits = 0, exponent = 0;
  bool any = false, dot = false;
  for (; i < t.size(); ++i) {
    const char c = t[i];
    if (c == '.' && !dot) {
      dot = true;
      continue;
    }
    if (c < '0' || c > '9') break;
    any = true;
    if (m == 0 && c == '0') {
      if (dot) --exponent;
      continue;
    }
    if (++digits > 15) return false;
    m = m * 10 + static_cast<std::uint64_t>(c - '0');
    if (dot) --exponent;
  }
  if (!any) return false;
  if (i < t.size()) {
    if (t[i] != 'e' && t[i] != 'E') return false;
    std::int64_t e = 0;
    if (!parseInteger(t.substr(i + 1), e) || e > 400 || e < -400) return false;
    exponent += static_cast<int>(e);
  }
  if (m == 0) exponent = 0;
  if (exponent > 22 || exponent < -22) return false;
  const double x = static_cast<double>(m);
  value = exponent >= 0 ? x * kPow10[exponent] : x / kPow10[-exponent];
  if (negative) value = -value;
  return true;
}

}  // namespace

std::string readWholeFile(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw MeshLoadError(path, "not a regular file");
  const std::uintmax_t size = std::filesystem::file_size(path, ec);
  if (ec) throw MeshLoadError(path, "cannot read the file size: " + ec.message());
  std::ifstream in(path, std::ios::binary);
  std::string bytes(static_cast<std::size_t>(size), '\0');
  if (!in.read(&bytes[0], static_cast<std::streamsize>(size)) && size > 0)
    throw MeshLoadError(path, "read error after " + std::to_string(in.gcount()) + " of " + std::to_string(size) +
                                  " bytes");
  return bytes;
}

std::string_view TextScanner::tokenInLine() {
  while (pos_ < text_.size() && isSpace(text_[pos_])) ++pos_;
  if (pos_ == text_.size() || text_[pos_] == '\n') return {};
  if (comment_ != 0 && text_[pos_] == comment_) {
    while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
    return {};
  }
  const std::size_t start = pos_;
  while (pos_ < text_.size() && text_[pos_] != '\n' && !isSpace(text_[pos_])) ++pos_;
  return text_.substr(start, pos_ - start);
}

bool TextScanner::nextLine() {
  while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
  if (pos_ == text_.size()) return false;
  ++pos_;
  ++line_;
  return pos_ < text_.size();
}

std::string_view TextScanner::token() {
  for (;;) {
    const std::string_view t = tokenInLine();
    if (!t.empty()) return t;
    if (!nextLine()) return {};
  }
}

bool parseDouble(std::string_view token, double& value) {
  if (parseSimpleDecimal(token, value)) return true;
  // The token ends at white space, a '/' or the text's end; copy it so strtod cannot read past it.
  char buffer[128];
  if (token.empty() || token.size() >= sizeof buffer) return false;
  token.copy(buffer, token.size());
  buffer[token.size()] = '\0';
  char* end = nullptr;
  value = strtod_l(buffer, &end, cLocale());
  return end == buffer + token.size();
}

bool parseInteger(std::string_view token, std::int64_t& value) {
  std::size_t i = 0;
  const bool negative = !token.empty() && token[0] == '-';
  if (!token.empty() && (token[0] == '-' || token[0] == '+')) i = 1;
  if (i == token.size()) return false;
  std::uint64_t magnitude = 0;
  for (; i < token.size(); ++i) {
    const char c = token[i];
    if (c < '0' || c > '9') return false;
    if (magnitude > (std::uint64_t{1} << 62)) return false;
    magnitude = magnitude * 10 + static_cast<std::uint64_t>(c - '0');
  }
  if (magnitude > (std::uint64_t{1} << 62)) return false;
  value = negative ? -static_cast<std::int64_t>(magnitude) : static_cast<std::int64_t>(magnitude);
  return true;
}

std::string atLine(std::size_t line) { return "line " + std::to_string(line) + ": "; }

std::string quoted(std::string_view token) {
  if (token.size() > 40) return "'" + std::string(token.substr(0, 37)) + "...'";
  return "'" + std::string(token) + "'";
}

std::string badCoordinate(int axis, std::size_t vertex, std::string_view token, bool parsed) {
  static const char* kAxis[] = {"x", "y", "z"};
  std::string what = token.empty() ? std::string("missing") : "is " + quoted(token) + ", not a";
  if (!token.empty()) what += parsed ? " finite number" : " number";
  return "coordinate " + std::string(kAxis[axis]) + " of vertex " + std::to_string(vertex) + " " + what;
}

std::string containerKind(const std::string& bytes) {
  auto starts = [&](const char* magic, std::size_t n) { return bytes.size() >= n && bytes.compare(0, n, magic, n) == 0; };
  if (starts("\x1f\x8b", 2)) return "gzip-compressed data";
  if (starts("PK\x03\x04", 4)) return "a zip archive";
  if (starts("BZh", 3)) return "bzip2-compressed data";
  if (starts("\xfd" "7zXZ", 5)) return "xz-compressed data";
  if (starts("\x28\xb5\x2f\xfd", 4)) return "zstd-compressed data";
  return "";
}

void requireText(const std::string& path, const std::string& bytes, const char* format) {
  const std::string article = (format[0] == 'O' || format[0] == 'S') ? "an " : "a ";
  const std::string kind = containerKind(bytes);
  if (!kind.empty()) throw MeshLoadError(path, "not " + article + format + " file: it is " + kind);
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    const auto c = static_cast<unsigned char>(bytes[i]);
    if (c < 0x20 && c != '\n' && c != '\r' && c != '\t' && c != '\f' && c != '\v') {
      char hex[8];
      std::snprintf(hex, sizeof hex, "0x%02x", c);
      throw MeshLoadError(path, "not " + article + format + " file: byte " + hex + " at offset " + std::to_string(i) +
                                    " is binary data, not text");
    }
  }
}

void requireRoom(const std::string& path, std::uint64_t count, const std::string& what, std::uint64_t minBytes,
                 std::uint64_t available) {
  if (minBytes == 0 || count <= available / minBytes) return;
  throw MeshLoadError(path, "header says " + std::to_string(count) + " " + what + ", but the " +
                                std::to_string(available) + " bytes after the header hold at most " +
                                std::to_string(available / minBytes) + " (each takes at least " +
                                std::to_string(minBytes) + " bytes)");
}

void throwEndsEarly(const std::string& path, std::uint64_t declared, const std::string& what, std::uint64_t read) {
  throw MeshLoadError(path, "header says " + std::to_string(declared) + " " + what + ", the file ends after " +
                                std::to_string(read));
}

}  // namespace detail
}  // namespace clod_haptics
