#pragma once
// Writes a triangle soup in each format the double-precision loader reads, with numbers that round-trip:
// OFF, OBJ, PLY (ASCII, binary little and big endian, double properties), STL (ASCII with 17 digits; binary,
// float32 by the format's definition). For tests that load the same numbers through every reader.

#include <array>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

namespace clod_test {

using Soup3 = std::vector<std::array<double, 3>>;
using Faces3 = std::vector<std::array<std::uint32_t, 3>>;

/** \brief The formats writeMeshAs writes; the file name's extension follows. */
inline const std::vector<std::string>& meshFormats() {
  static const std::vector<std::string> formats = {"off",      "obj",       "ascii.ply", "binary_le.ply",
                                                   "binary_be.ply", "ascii.stl", "binary.stl"};
  return formats;
}

namespace detail_writers {
inline void putBytes(std::FILE* f, const void* data, std::size_t n, bool bigEndian) {
  unsigned char b[8];
  std::memcpy(b, data, n);
  if (bigEndian)
    for (std::size_t i = 0; i < n / 2; ++i) std::swap(b[i], b[n - 1 - i]);
  std::fwrite(b, 1, n, f);
}
inline std::array<double, 3> normalOf(const Soup3& v, const std::array<std::uint32_t, 3>& t) {
  const auto &a = v[t[0]], &b = v[t[1]], &c = v[t[2]];
  const double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  return {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
}
}  // namespace detail_writers

/** \brief Writes the soup as `format` (one of meshFormats()) to path; returns false when the file cannot be written. */
inline bool writeMeshAs(const std::string& format, const Soup3& v, const Faces3& faces, const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) return false;
  if (format == "off") {
    std::fprintf(f, "OFF\n%zu %zu 0\n", v.size(), faces.size());
    for (const auto& p : v) std::fprintf(f, "%.17g %.17g %.17g\n", p[0], p[1], p[2]);
    for (const auto& t : faces) std::fprintf(f, "3 %u %u %u\n", t[0], t[1], t[2]);
  } else if (format == "obj") {
    for (const auto& p : v) std::fprintf(f, "v %.17g %.17g %.17g\n", p[0], p[1], p[2]);
    for (const auto& t : faces) std::fprintf(f, "f %u %u %u\n", t[0] + 1, t[1] + 1, t[2] + 1);
  } else if (format.size() > 4 && format.compare(format.size() - 4, 4, ".ply") == 0) {
    const bool ascii = format == "ascii.ply", big = format == "binary_be.ply";
    std::fprintf(f, "ply\nformat %s 1.0\nelement vertex %zu\nproperty double x\nproperty double y\nproperty double z\n"
                 "element face %zu\nproperty list uchar int vertex_indices\nend_header\n",
                 ascii ? "ascii" : big ? "binary_big_endian" : "binary_little_endian", v.size(), faces.size());
    for (const auto& p : v) {
      if (ascii)
        std::fprintf(f, "%.17g %.17g %.17g\n", p[0], p[1], p[2]);
      else
        for (double c : p) detail_writers::putBytes(f, &c, 8, big);
    }
    for (const auto& t : faces) {
      if (ascii) {
        std::fprintf(f, "3 %u %u %u\n", t[0], t[1], t[2]);
        continue;
      }
      const unsigned char three = 3;
      std::fwrite(&three, 1, 1, f);
      for (std::uint32_t i : t) {
        const std::int32_t s = static_cast<std::int32_t>(i);
        detail_writers::putBytes(f, &s, 4, big);
      }
    }
  } else if (format == "ascii.stl") {
    std::fprintf(f, "solid test\n");
    for (const auto& t : faces) {
      const auto n = detail_writers::normalOf(v, t);
      std::fprintf(f, " facet normal %.9g %.9g %.9g\n  outer loop\n", n[0], n[1], n[2]);
      for (std::uint32_t i : t) std::fprintf(f, "   vertex %.17g %.17g %.17g\n", v[i][0], v[i][1], v[i][2]);
      std::fprintf(f, "  endloop\n endfacet\n");
    }
    std::fprintf(f, "endsolid test\n");
  } else if (format == "binary.stl") {
    char header[80] = "binary STL written by clod_haptics tests";
    std::fwrite(header, 1, 80, f);
    const std::uint32_t count = static_cast<std::uint32_t>(faces.size());
    detail_writers::putBytes(f, &count, 4, false);
    for (const auto& t : faces) {
      const auto n = detail_writers::normalOf(v, t);
      for (double c : n) {
        const float x = static_cast<float>(c);
        detail_writers::putBytes(f, &x, 4, false);
      }
      for (std::uint32_t i : t)
        for (double c : v[i]) {
          const float x = static_cast<float>(c);
          detail_writers::putBytes(f, &x, 4, false);
        }
      const std::uint16_t attributes = 0;
      std::fwrite(&attributes, 2, 1, f);
    }
  } else {
    std::fclose(f);
    return false;
  }
  return std::fclose(f) == 0;
}

/**
 * \brief The numbers a reader gets back from a file writeMeshAs wrote: binary STL holds float32. Rounded through
 * an array of floats: GCC 12.2 at -O3 (its SLP vectoriser) compiles the in-place `c = double(float(c))` over
 * arrays of three doubles so that the last (n % 4) points keep x and y unrounded.
 */
inline Soup3 numbersAsWritten(const std::string& format, Soup3 v) {
  if (format != "binary.stl") return v;
  std::vector<float> floats(3 * v.size());
  for (std::size_t i = 0; i < floats.size(); ++i) floats[i] = static_cast<float>(v[i / 3][i % 3]);
  for (std::size_t i = 0; i < floats.size(); ++i) v[i / 3][i % 3] = floats[i];
  return v;
}

}  // namespace clod_test
