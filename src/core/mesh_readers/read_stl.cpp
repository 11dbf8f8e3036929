// STL: binary (an 80-byte header, a little-endian triangle count, 50 bytes per triangle: normal, three float
// corners, two attribute bytes) when the size says so, else ASCII ("solid name", facets of "vertex x y z").

#include <cmath>
#include <cstring>

#include "polygon_soup.h"
#include "text_scanner.h"

namespace clod_haptics {
namespace detail {
namespace {

constexpr std::size_t kBinaryHeader = 84, kBinaryTriangle = 50;

std::uint32_t littleEndian32(const char* p) {
  const auto* b = reinterpret_cast<const unsigned char*>(p);
  return std::uint32_t{b[0]} | std::uint32_t{b[1]} << 8 | std::uint32_t{b[2]} << 16 | std::uint32_t{b[3]} << 24;
}

float littleEndianFloat(const char* p) {
  const std::uint32_t bits = littleEndian32(p);
  float f;
  std::memcpy(&f, &bits, sizeof f);
  return f;
}

PolygonSoup readBinaryStl(const std::string& path, const std::string& bytes, std::uint32_t count) {
  PolygonSoup soup;
  soup.positions.reserve(3 * std::size_t{count});
  for (std::uint32_t t = 0; t < count; ++t) {
    const char* corner = bytes.data() + kBinaryHeader + kBinaryTriangle * t + 12;
    const std::size_t start = soup.corners.size();
    for (int c = 0; c < 3; ++c, corner += 12) {
      Vec3 p;
      for (int k = 0; k < 3; ++k) {
        p[k] = littleEndianFloat(corner + 4 * k);
        if (!std::isfinite(p[k]))
          throw MeshLoadError(path, "triangle " + std::to_string(t) + ": " +
                                        badCoordinate(k, soup.positions.size(), std::to_string(p[k]), true));
      }
      soup.corners.push_back(static_cast<std::uint32_t>(soup.positions.size()));
      soup.positions.push_back(p);
    }
    soup.closePolygon(start);
  }
  return soup;
}

struct AsciiStlReader {
  const std::string& path;
  TextScanner in;
  PolygonSoup soup;
  std::size_t facets = 0;

  [[noreturn]] void fail(const std::string& what) { throw MeshLoadError(path, atLine(in.line()) + what); }

  std::string_view expect(const char* a, const char* b = nullptr) {
    const std::string_view t = in.token();
    if (t == a || (b != nullptr && t == b)) return t;
    if (t.empty()) fail(std::string("the file ends where '") + a + "' was expected (in facet " +
                        std::to_string(facets) + ")");
    fail(std::string("expected '") + a + (b != nullptr ? std::string("' or '") + b : std::string()) + "', found " +
         quoted(t));
  }

  void readFacet() {
    expect("normal");
    for (int k = 0; k < 3; ++k) {
      double n;
      const std::string_view t = in.token();
      if (!parseDouble(t, n)) fail("facet " + std::to_string(facets) + ": normal component " + quoted(t) + " is not a number");
    }
    expect("outer");
    expect("loop");
    const std::size_t start = soup.corners.size();
    while (expect("vertex", "endloop") == "vertex") {
      Vec3 p;
      for (int k = 0; k < 3; ++k) {
        const std::string_view t = in.token();
        const bool parsed = parseDouble(t, p[k]);
        if (!parsed || !std::isfinite(p[k])) fail(badCoordinate(k, soup.positions.size(), t, parsed));
      }
      soup.corners.push_back(static_cast<std::uint32_t>(soup.positions.size()));
      soup.positions.push_back(p);
    }
    soup.closePolygon(start);
    expect("endfacet");
    ++facets;
  }

  PolygonSoup read() {
    for (std::string_view t = in.token(); !t.empty(); t = in.token()) {
      if (t != "solid") fail("expected 'solid', found " + quoted(t));
      in.nextLine();  // the solid's name
      while (expect("facet", "endsolid") == "facet") readFacet();
      in.nextLine();
    }
    return std::move(soup);
  }
};

}  // namespace

PolygonSoup readStl(const std::string& path, const std::string& bytes) {
  const std::string kind = containerKind(bytes);
  if (!kind.empty()) throw MeshLoadError(path, "not an STL file: it is " + kind);
  if (bytes.size() >= kBinaryHeader) {
    const std::uint32_t count = littleEndian32(bytes.data() + 80);
    if (bytes.size() == kBinaryHeader + kBinaryTriangle * std::uint64_t{count}) return readBinaryStl(path, bytes, count);
  }
  const std::size_t first = bytes.find_first_not_of(" \t\r\n");
  if (first == std::string::npos || bytes.compare(first, 5, "solid") != 0) {
    std::string why = "not an STL file: it does not start with 'solid' (ASCII STL)";
    if (bytes.size() >= kBinaryHeader)
      why += ", and its " + std::to_string(bytes.size()) + " bytes are not the 84 + 50 x " +
             std::to_string(littleEndian32(bytes.data() + 80)) + " of a binary STL with the triangle count it gives";
    else
      why += " and is shorter than the 84 bytes of a binary STL's header";
    throw MeshLoadError(path, why);
  }
  requireText(path, bytes, "STL");
  return AsciiStlReader{path, TextScanner(bytes, '\0'), {}}.read();
}

}  // namespace detail
}  // namespace clod_haptics
