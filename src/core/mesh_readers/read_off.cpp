// OFF: a keyword line ([ST][C][N]OFF), "vertices faces edges", one vertex per line (x y z, then any per-vertex
// values the keyword announces), one face per line (n, n indices, then an optional colour).

#include <cmath>

#include "polygon_soup.h"
#include "text_scanner.h"

namespace clod_haptics {
namespace detail {
namespace {

// Smallest vertex line "0 0 0\n" and face line "0\n": the bound that checks a header against the file size.
constexpr std::uint64_t kMinVertexBytes = 6, kMinFaceBytes = 2;

struct OffReader {
  const std::string& path;
  TextScanner in;
  PolygonSoup soup;

  [[noreturn]] void fail(const std::string& what) { throw MeshLoadError(path, atLine(in.line()) + what); }

  // The first token of the next line that has one; empty at the end of the file.
  std::string_view nextContentLine() {
    while (in.nextLine()) {
      const std::string_view t = in.tokenInLine();
      if (!t.empty()) return t;
    }
    return {};
  }

  void readKeyword() {
    const std::string_view keyword = in.tokenInLine();
    const std::size_t at = keyword.rfind("OFF");
    if (at == std::string_view::npos || at + 3 != keyword.size() ||
        keyword.substr(0, at).find_first_not_of("STCN") != std::string_view::npos)
      throw MeshLoadError(path, "not an OFF file: it does not start with the keyword OFF (found " + quoted(keyword) +
                                    ")");
  }

  std::uint64_t count(std::string_view token, const char* what) {
    std::int64_t n = 0;
    if (!parseInteger(token, n) || n < 0 || n > std::int64_t{0xffffffff})
      fail("the " + std::string(what) + " count " + quoted(token) + " is not a number from 0 to 4294967295");
    return static_cast<std::uint64_t>(n);
  }

  void readVertex(std::size_t v, std::string_view first) {
    Vec3 p;
    for (int k = 0; k < 3; ++k) {
      const std::string_view t = k == 0 ? first : in.tokenInLine();
      const bool parsed = parseDouble(t, p[k]);
      if (!parsed || !std::isfinite(p[k])) fail(badCoordinate(k, v, t, parsed));
    }
    soup.positions.push_back(p);
  }

  void readFace(std::size_t f, std::string_view first) {
    const std::uint64_t n = count(first, "face's vertex");
    const std::size_t start = soup.corners.size();
    for (std::uint64_t k = 0; k < n; ++k) {
      const std::string_view t = in.tokenInLine();
      if (t.empty()) fail("face " + std::to_string(f) + " has " + std::to_string(n) + " vertices but lists " +
                          std::to_string(k));
      std::int64_t index = 0;
      if (!parseInteger(t, index)) fail("face " + std::to_string(f) + ": vertex index " + quoted(t) + " is not a number");
      if (index < 0 || static_cast<std::uint64_t>(index) >= soup.positions.size())
        fail("face " + std::to_string(f) + " uses vertex " + std::string(t) + " but the file has " +
             std::to_string(soup.positions.size()) + " vertices");
      soup.corners.push_back(static_cast<std::uint32_t>(index));
    }
    soup.closePolygon(start);
  }

  PolygonSoup read() {
    readKeyword();
    std::string_view t = in.tokenInLine();
    if (t == "BINARY") fail("binary OFF is not supported");
    if (t.empty()) t = nextContentLine();
    if (t.empty()) fail("the file ends before the vertex and face counts");
    const std::uint64_t vertices = count(t, "vertex");
    const std::uint64_t faces = count(in.tokenInLine(), "face");
    const std::uint64_t room = in.remaining() + 1;  // the last line needs no newline
    requireRoom(path, vertices, "vertices", kMinVertexBytes, room);
    requireRoom(path, faces, "faces", kMinFaceBytes, room - vertices * kMinVertexBytes);
    soup.positions.reserve(vertices);
    for (std::uint64_t v = 0; v < vertices; ++v) {
      t = nextContentLine();
      if (t.empty()) throwEndsEarly(path, vertices, "vertices", v);
      readVertex(v, t);
    }
    for (std::uint64_t f = 0; f < faces; ++f) {
      t = nextContentLine();
      if (t.empty()) throwEndsEarly(path, faces, "faces", f);
      readFace(f, t);
    }
    t = nextContentLine();
    if (!t.empty()) fail("unexpected " + quoted(t) + " after the last of the header's " + std::to_string(faces) + " faces");
    return std::move(soup);
  }
};

}  // namespace

PolygonSoup readOff(const std::string& path, const std::string& bytes) {
  requireText(path, bytes, "OFF");
  PolygonSoup soup;
  soup.fileOrder = true;
  return OffReader{path, TextScanner(bytes, '#'), std::move(soup)}.read();
}

}  // namespace detail
}  // namespace clod_haptics
