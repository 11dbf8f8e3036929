// PLY: a text header (format, elements with their counts and properties, end_header), then the elements in
// order, as text or binary of either byte order. The "vertex" element's x, y, z and the "face" element's
// vertex_indices (or vertex_index) list make the mesh; every other element and property is read and skipped.

#include <algorithm>
#include <cmath>
#include <cstring>

#include "polygon_soup.h"
#include "text_scanner.h"

namespace clod_haptics {
namespace detail {
namespace {

enum class PlyFormat { Ascii, BinaryLittle, BinaryBig };

struct PlyType {
  const char* names[2];
  int bytes;
  bool isInteger, isSigned;
};
const PlyType kTypes[] = {
    {{"char", "int8"}, 1, true, true},      {{"uchar", "uint8"}, 1, true, false},
    {{"short", "int16"}, 2, true, true},    {{"ushort", "uint16"}, 2, true, false},
    {{"int", "int32"}, 4, true, true},      {{"uint", "uint32"}, 4, true, false},
    {{"float", "float32"}, 4, false, true}, {{"double", "float64"}, 8, false, true},
};

const PlyType* typeNamed(std::string_view name) {
  for (const PlyType& t : kTypes)
    if (name == t.names[0] || name == t.names[1]) return &t;
  return nullptr;
}

struct PlyProperty {
  std::string name;
  const PlyType* type = nullptr;
  const PlyType* countType = nullptr;  // set for a list
};

struct PlyElement {
  std::string name;
  std::uint64_t count = 0;
  std::vector<PlyProperty> properties;
  std::string plural() const {
    return name == "vertex" ? "vertices" : name == "face" ? "faces" : "'" + name + "' elements";
  }
  // The fewest bytes one element can take: binary sizes (a list's count only), or one character and a separator
  // per value in text.
  std::uint64_t minBytes(PlyFormat format) const {
    std::uint64_t n = 0;
    for (const PlyProperty& p : properties)
      n += format == PlyFormat::Ascii ? 2 : (p.countType != nullptr ? p.countType : p.type)->bytes;
    return n;
  }
};

struct PlyHeader {
  PlyFormat format = PlyFormat::Ascii;
  std::vector<PlyElement> elements;
  std::size_t bodyOffset = 0, bodyLine = 0;
};

class HeaderParser {
 public:
  HeaderParser(const std::string& path, const std::string& bytes) : path_(path), bytes_(bytes) {}

  PlyHeader parse() {
    if (bytes_.compare(0, 3, "ply") != 0 || (bytes_.size() > 3 && bytes_[3] != '\n' && bytes_[3] != '\r'))
      throw MeshLoadError(path_, "not a PLY file: it does not start with the line 'ply'");
    TextScanner in(bytes_, '\0');
    bool format = false, ended = false;
    while (!ended && in.nextLine()) {
      line_ = in.line();
      const std::string_view word = in.tokenInLine();
      if (word == "end_header")
        ended = true;
      else if (word == "format")
        format = (readFormat(in), true);
      else if (word == "element")
        readElement(in);
      else if (word == "property")
        readProperty(in);
      else if (!word.empty() && word != "comment" && word != "obj_info")
        fail("unexpected " + quoted(word));
    }
    if (!ended) fail("no end_header");
    if (!format) fail("no format line before end_header");
    in.nextLine();
    header_.bodyOffset = bytes_.size() - in.remaining();
    header_.bodyLine = in.line();
    return std::move(header_);
  }

 private:
  [[noreturn]] void fail(const std::string& what) {
    throw MeshLoadError(path_, "malformed PLY header: " + atLine(line_) + what);
  }

  void readFormat(TextScanner& in) {
    const std::string_view kind = in.tokenInLine(), version = in.tokenInLine();
    if (kind == "ascii")
      header_.format = PlyFormat::Ascii;
    else if (kind == "binary_little_endian")
      header_.format = PlyFormat::BinaryLittle;
    else if (kind == "binary_big_endian")
      header_.format = PlyFormat::BinaryBig;
    else
      fail("unknown format " + quoted(kind));
    if (version != "1.0") fail("unknown version " + quoted(version));
  }

  void readElement(TextScanner& in) {
    PlyElement e;
    e.name = std::string(in.tokenInLine());
    const std::string_view count = in.tokenInLine();
    std::int64_t n = 0;
    if (e.name.empty() || !parseInteger(count, n) || n < 0 || n > std::int64_t{0xffffffff})
      fail("element line needs a name and a count from 0 to 4294967295, found " + quoted(count));
    e.count = static_cast<std::uint64_t>(n);
    header_.elements.push_back(std::move(e));
  }

  void readProperty(TextScanner& in) {
    if (header_.elements.empty()) fail("a property before any element");
    PlyProperty p;
    std::string_view type = in.tokenInLine();
    if (type == "list") {
      const std::string_view countType = in.tokenInLine();
      p.countType = typeNamed(countType);
      if (p.countType == nullptr || !p.countType->isInteger) fail("list count type " + quoted(countType) + " is not an integer type");
      type = in.tokenInLine();
    }
    p.type = typeNamed(type);
    p.name = std::string(in.tokenInLine());
    if (p.type == nullptr) fail("unknown property type " + quoted(type));
    if (p.name.empty()) fail("property without a name");
    header_.elements.back().properties.push_back(std::move(p));
  }

  const std::string& path_;
  const std::string& bytes_;
  PlyHeader header_;
  std::size_t line_ = 1;
};

// Values of a text body, one token each.
class AsciiValues {
 public:
  AsciiValues(const std::string& path, std::string_view body, std::size_t line)
      : path_(path), in_(body, '\0', line) {}
  // False at the end of the body.
  bool read(const PlyType& type, double& value) {
    const std::string_view t = in_.token();
    if (t.empty()) return false;
    std::int64_t n = 0;
    const bool ok = type.isInteger ? parseInteger(t, n) : parseDouble(t, value);
    if (!ok) throw MeshLoadError(path_, atLine(in_.line()) + quoted(t) + " is not a" + (type.isInteger ? "n integer" : " number") + " (" + type.names[0] + ")");
    if (type.isInteger) value = static_cast<double>(n);
    return true;
  }
  std::uint64_t remaining() const { return in_.remaining(); }
  std::string where() const { return atLine(in_.line()); }
  std::string leftover() {
    const std::string_view t = in_.token();
    return t.empty() ? std::string() : where() + "unexpected " + quoted(t) + " after the last element";
  }

 private:
  const std::string& path_;
  TextScanner in_;
};

// Values of a binary body, in the file's byte order.
class BinaryValues {
 public:
  BinaryValues(std::string_view body, bool bigEndian) : body_(body), bigEndian_(bigEndian) {}
  bool read(const PlyType& type, double& value) {
    if (body_.size() - pos_ < static_cast<std::size_t>(type.bytes)) return false;
    unsigned char b[8];
    std::memcpy(b, body_.data() + pos_, static_cast<std::size_t>(type.bytes));
    pos_ += static_cast<std::size_t>(type.bytes);
    if (bigEndian_) std::reverse(b, b + type.bytes);
    value = decode(type, b);
    return true;
  }
  std::uint64_t remaining() const { return body_.size() - pos_; }
  std::string where() const { return "byte " + std::to_string(pos_) + " after the header: "; }
  std::string leftover() const {
    return pos_ == body_.size() ? std::string()
                                : std::to_string(body_.size() - pos_) + " bytes after the last element (the header's "
                                                                        "counts do not match the data)";
  }

 private:
  static double decode(const PlyType& type, const unsigned char* b) {
    std::uint64_t u = 0;
    for (int i = type.bytes - 1; i >= 0; --i) u = u << 8 | b[i];  // little endian
    if (!type.isInteger) {
      if (type.bytes == 4) {
        float f;
        const auto bits = static_cast<std::uint32_t>(u);
        std::memcpy(&f, &bits, sizeof f);
        return f;
      }
      double d;
      std::memcpy(&d, &u, sizeof d);
      return d;
    }
    if (type.isSigned && type.bytes < 8 && (u >> (8 * type.bytes - 1)) != 0) return static_cast<double>(u) - std::ldexp(1.0, 8 * type.bytes);
    return static_cast<double>(u);
  }

  std::string_view body_;
  bool bigEndian_;
  std::size_t pos_ = 0;
};

template <class Values>
class BodyReader {
 public:
  BodyReader(const std::string& path, const PlyHeader& header, Values values)
      : path_(path), header_(header), values_(std::move(values)) {}

  PolygonSoup read() {
    for (const PlyElement& e : header_.elements) {
      if (e.name == "vertex") soup_.positions.reserve(e.count);
      for (std::uint64_t i = 0; i < e.count; ++i) readElement(e, i);
    }
    const std::string left = values_.leftover();
    if (!left.empty()) throw MeshLoadError(path_, left);
    soup_.fileOrder = true;
    return std::move(soup_);
  }

 private:
  [[noreturn]] void fail(const std::string& what) { throw MeshLoadError(path_, values_.where() + what); }

  double value(const PlyElement& e, std::uint64_t i, const PlyType& type) {
    double v = 0.0;
    if (!values_.read(type, v)) throwEndsEarly(path_, e.count, e.plural(), i);
    return v;
  }

  void readElement(const PlyElement& e, std::uint64_t i) {
    const bool vertex = e.name == "vertex", face = e.name == "face";
    Vec3 p = Vec3::Zero();
    for (const PlyProperty& prop : e.properties) {
      if (prop.countType != nullptr) {
        readList(e, i, prop, face && (prop.name == "vertex_indices" || prop.name == "vertex_index"));
        continue;
      }
      const double v = value(e, i, *prop.type);
      const int axis = prop.name == "x" ? 0 : prop.name == "y" ? 1 : prop.name == "z" ? 2 : -1;
      if (!vertex || axis < 0) continue;
      if (!std::isfinite(v)) fail(badCoordinate(axis, i, std::to_string(v), true));
      p[axis] = v;
    }
    if (vertex) soup_.positions.push_back(p);
  }

  void readList(const PlyElement& e, std::uint64_t i, const PlyProperty& prop, bool indices) {
    const double n = value(e, i, *prop.countType);
    if (n < 0 || n > static_cast<double>(values_.remaining()))
      fail(e.name + " " + std::to_string(i) + ": a list of " + std::to_string(static_cast<std::int64_t>(n)) +
           " values does not fit in the rest of the file");
    const std::size_t start = soup_.corners.size();
    for (std::uint64_t k = 0; k < static_cast<std::uint64_t>(n); ++k) {
      const double v = value(e, i, *prop.type);
      if (!indices) continue;
      if (!(v >= 0.0 && v < static_cast<double>(soup_.positions.size())) || v != std::floor(v))
        fail("face " + std::to_string(i) + " uses vertex " + number(v) + " but the file has " +
             std::to_string(soup_.positions.size()) + " vertices");
      soup_.corners.push_back(static_cast<std::uint32_t>(v));
    }
    if (indices) soup_.closePolygon(start);
  }

  static std::string number(double v) {
    return v == std::floor(v) && std::abs(v) < 1e18 ? std::to_string(static_cast<std::int64_t>(v)) : std::to_string(v);
  }

  const std::string& path_;
  const PlyHeader& header_;
  Values values_;
  PolygonSoup soup_;
};

void checkHeader(const std::string& path, const PlyHeader& header, std::uint64_t bodyBytes) {
  bool hasVertex = false, hasFace = false;
  for (const PlyElement& e : header.elements) {
    if (e.name == "vertex") {
      for (const char* axis : {"x", "y", "z"}) {
        bool found = false;
        for (const PlyProperty& p : e.properties) found = found || (p.name == axis && p.countType == nullptr);
        if (!found) throw MeshLoadError(path, std::string("malformed PLY header: the vertex element has no property ") + axis);
      }
      hasVertex = true;
    }
    hasFace = hasFace || e.name == "face";
  }
  if (!hasVertex) throw MeshLoadError(path, "malformed PLY header: no vertex element");
  if (!hasFace) throw MeshLoadError(path, "no triangles: the PLY header declares no face element");
  // Every element's count against the bytes that follow the header, before anything is reserved.
  std::uint64_t room = bodyBytes + (header.format == PlyFormat::Ascii ? 1 : 0);
  for (const PlyElement& e : header.elements) {
    const std::uint64_t each = e.minBytes(header.format);
    requireRoom(path, e.count, e.plural(), each, room);
    room -= e.count * each;
  }
}

}  // namespace

PolygonSoup readPly(const std::string& path, const std::string& bytes) {
  const std::string kind = containerKind(bytes);
  if (!kind.empty()) throw MeshLoadError(path, "not a PLY file: it is " + kind);
  const PlyHeader header = HeaderParser(path, bytes).parse();
  const std::string_view body = std::string_view(bytes).substr(header.bodyOffset);
  checkHeader(path, header, body.size());
  if (header.format == PlyFormat::Ascii) {
    requireText(path, bytes, "PLY");
    return BodyReader<AsciiValues>(path, header, AsciiValues(path, body, header.bodyLine)).read();
  }
  return BodyReader<BinaryValues>(path, header, BinaryValues(body, header.format == PlyFormat::BinaryBig)).read();
}

}  // namespace detail
}  // namespace clod_haptics
