// OBJ: "v x y z [w | r g b]" and "f" with corners "i", "i/t", "i//n" or "i/t/n" (1-based, negative counts back
// from the last vertex defined so far). Other statements (vt, vn, g, o, usemtl, l, p, ...) carry no surface.

#include <cctype>
#include <cmath>

#include "polygon_soup.h"
#include "text_scanner.h"

namespace clod_haptics {
namespace detail {
namespace {

struct ObjReader {
  const std::string& path;
  TextScanner in;
  PolygonSoup soup;
  std::size_t faces = 0;
  // The largest positive index and where it is: checked once every vertex is known.
  std::int64_t maxIndex = 0;
  std::size_t maxIndexLine = 0, maxIndexFace = 0;

  [[noreturn]] void fail(const std::string& what) { throw MeshLoadError(path, atLine(in.line()) + what); }

  void readVertex() {
    Vec3 p;
    for (int k = 0; k < 3; ++k) {
      const std::string_view t = in.tokenInLine();
      const bool parsed = parseDouble(t, p[k]);
      if (!parsed || !std::isfinite(p[k])) fail(badCoordinate(k, soup.positions.size() + 1, t, parsed));
    }
    soup.positions.push_back(p);
  }

  std::uint32_t cornerIndex(std::string_view corner) {
    const std::string_view text = corner.substr(0, corner.find('/'));
    std::int64_t index = 0;
    if (!parseInteger(text, index) || index == 0)
      fail("face " + std::to_string(faces) + ": vertex index " + quoted(text) + " is not a nonzero integer");
    const auto defined = static_cast<std::int64_t>(soup.positions.size());
    if (index < 0) {
      if (-index > defined)
        fail("face " + std::to_string(faces) + " uses relative vertex " + std::string(text) + " but only " +
             std::to_string(defined) + " vertices are defined before it");
      return static_cast<std::uint32_t>(defined + index);
    }
    if (index > std::int64_t{0xffffffff})
      fail("face " + std::to_string(faces) + " uses vertex " + std::string(text) + ", beyond any vertex count");
    if (index > maxIndex) {
      maxIndex = index;
      maxIndexLine = in.line();
      maxIndexFace = faces;
    }
    return static_cast<std::uint32_t>(index - 1);
  }

  void readFace() {
    ++faces;
    const std::size_t start = soup.corners.size();
    for (std::string_view t = in.tokenInLine(); !t.empty(); t = in.tokenInLine()) soup.corners.push_back(cornerIndex(t));
    soup.closePolygon(start);
  }

  void readStatement(std::string_view keyword) {
    if (keyword == "v")
      readVertex();
    else if (keyword == "f" || keyword == "fo")
      readFace();
    else if (!std::isalpha(static_cast<unsigned char>(keyword[0])))
      fail(quoted(keyword) + " is not an OBJ statement");
    // Any other statement (vt, vn, g, o, s, usemtl, mtllib, l, p, ...) carries no surface.
  }

  PolygonSoup read() {
    do {
      const std::string_view keyword = in.tokenInLine();
      if (!keyword.empty()) readStatement(keyword);
    } while (in.nextLine());
    if (maxIndex > static_cast<std::int64_t>(soup.positions.size()))
      throw MeshLoadError(path, atLine(maxIndexLine) + "face " + std::to_string(maxIndexFace) + " uses vertex " +
                                    std::to_string(maxIndex) + " but the file has " +
                                    std::to_string(soup.positions.size()) + " vertices");
    return std::move(soup);
  }
};

}  // namespace

PolygonSoup readObj(const std::string& path, const std::string& bytes) {
  requireText(path, bytes, "OBJ");
  return ObjReader{path, TextScanner(bytes, '#'), {}}.read();
}

}  // namespace detail
}  // namespace clod_haptics
