// Stanford PLY reader and writer: ascii, binary_little_endian and binary_big_endian.
//
// The header declares elements (name, count) and their properties (scalar or list); the body stores the
// elements in header order. The reader takes positions, normals, one UV set and one colour set from the
// `vertex` element and polygons from the `face` element's `vertex_indices` (or `vertex_index`) list; every
// other element and property is skipped by its declared type, so files with extra data still load. Every
// declared count is checked against the bytes that remain before anything is allocated for it.
// Reference: Greg Turk, "The PLY Polygon File Format" (1994).

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "lodforge/io/formats.hpp"
#include "stream_internal.hpp"
#include "text_parse.hpp"

namespace lodforge::io {
namespace {

using parse::ErrorContext;

enum class Type { i8, u8, i16, u16, i32, u32, f32, f64 };
enum class Encoding { ascii, binary_le, binary_be };

std::size_t size_of(Type t) {
  switch (t) {
    case Type::i8:
    case Type::u8: return 1;
    case Type::i16:
    case Type::u16: return 2;
    case Type::i32:
    case Type::u32:
    case Type::f32: return 4;
    case Type::f64: return 8;
  }
  return 1;
}

bool is_integral(Type t) { return t != Type::f32 && t != Type::f64; }

bool parse_type(std::string_view s, Type& t) {
  // Both the original names and the sized aliases (int8, float32, ...) are in use.
  struct Name {
    std::string_view name;
    Type type;
  };
  static constexpr Name kNames[] = {
      {"char", Type::i8},    {"int8", Type::i8},     {"uchar", Type::u8},    {"uint8", Type::u8},
      {"short", Type::i16},  {"int16", Type::i16},   {"ushort", Type::u16},  {"uint16", Type::u16},
      {"int", Type::i32},    {"int32", Type::i32},   {"uint", Type::u32},    {"uint32", Type::u32},
      {"float", Type::f32},  {"float32", Type::f32}, {"double", Type::f64},  {"float64", Type::f64},
  };
  for (const Name& n : kNames) {
    if (n.name == s) {
      t = n.type;
      return true;
    }
  }
  return false;
}

struct Property {
  std::string name;
  Type type = Type::f32;        // scalar type, or the item type of a list
  bool list = false;
  Type count_type = Type::u8;   // lists only
};

struct Element {
  std::string name;
  std::uint64_t count = 0;
  std::vector<Property> properties;
};

struct Header {
  Encoding encoding = Encoding::ascii;
  std::vector<Element> elements;
  std::size_t data_offset = 0;  // first byte after "end_header\n"
  std::size_t data_line = 0;    // line number of the first data line (ASCII error messages)
};

// Header lines that old exporters wrote without the "comment" keyword, read as comments.
constexpr std::string_view kBareComments[] = {
    "Created by Blender3D",  // Blender's exporter up to 2.47 (the keyword was added in August 2008)
};

bool is_bare_comment(std::string_view line) {
  return std::any_of(std::begin(kBareComments), std::end(kBareComments),
                     [&](std::string_view prefix) { return line.substr(0, prefix.size()) == prefix; });
}

Header parse_header(const std::filesystem::path& path, std::string_view bytes) {
  Header h;
  parse::LineCursor lines(bytes);
  ErrorContext ctx{path};
  std::string_view line;
  if (!lines.next(line) || parse::trim(line) != "ply") ctx.fail("not a PLY file (the first line is not 'ply')");
  bool have_format = false;
  for (;;) {
    if (!lines.next(line)) ctx.fail("the header has no 'end_header' line (truncated file?)");
    ctx.line = lines.line_number();
    std::string_view rest = line;
    const std::string_view keyword = parse::next_token(rest);
    if (keyword.empty() || keyword == "comment" || keyword == "obj_info" || is_bare_comment(parse::trim(line))) {
      continue;
    }
    if (keyword == "end_header") break;
    if (keyword == "format") {
      const std::string_view enc = parse::next_token(rest);
      if (enc == "ascii") h.encoding = Encoding::ascii;
      else if (enc == "binary_little_endian") h.encoding = Encoding::binary_le;
      else if (enc == "binary_big_endian") h.encoding = Encoding::binary_be;
      else ctx.fail("unknown PLY format " + parse::quote(enc));
      have_format = true;
    } else if (keyword == "element") {
      Element e;
      e.name = std::string(parse::next_token(rest));
      const std::string_view count = parse::next_token(rest);
      if (e.name.empty() || !parse::parse_int(count, e.count)) ctx.fail("malformed element line " + parse::quote(line));
      h.elements.push_back(std::move(e));
    } else if (keyword == "property") {
      if (h.elements.empty()) ctx.fail("property declared before any element");
      Property p;
      std::string_view type = parse::next_token(rest);
      if (type == "list") {
        p.list = true;
        if (!parse_type(parse::next_token(rest), p.count_type) || !is_integral(p.count_type)) {
          ctx.fail("bad list count type in " + parse::quote(line));
        }
        type = parse::next_token(rest);
      }
      if (!parse_type(type, p.type)) ctx.fail("unknown property type in " + parse::quote(line));
      p.name = std::string(parse::next_token(rest));
      if (p.name.empty()) ctx.fail("property without a name: " + parse::quote(line));
      h.elements.back().properties.push_back(std::move(p));
    } else {
      ctx.fail("unknown header line " + parse::quote(line));
    }
  }
  if (!have_format) ctx.fail("the header has no 'format' line");
  h.data_offset = lines.offset();
  h.data_line = lines.line_number() + 1;
  return h;
}

// One binary value at p (size_of(t) bytes), in the file's byte order, as T (integers are read as integers, so
// a 64-bit T holds every index exactly).
template <typename T>
T decode(const char* p, Type t, bool big) {
  switch (t) {
    case Type::i8: return static_cast<T>(static_cast<std::int8_t>(*p));
    case Type::u8: return static_cast<T>(static_cast<std::uint8_t>(*p));
    case Type::i16: return static_cast<T>(parse::load<std::int16_t>(p, big));
    case Type::u16: return static_cast<T>(parse::load<std::uint16_t>(p, big));
    case Type::i32: return static_cast<T>(parse::load<std::int32_t>(p, big));
    case Type::u32: return static_cast<T>(parse::load<std::uint32_t>(p, big));
    case Type::f32: return static_cast<T>(parse::load<float>(p, big));
    case Type::f64: return static_cast<T>(parse::load<double>(p, big));
  }
  return 0;
}

// Where BinarySource's bytes come from: the body held in memory, or a file read front to back (out of core).
// take(n) gives the next n bytes or nullptr where the data ends first; skip(n) is checked by the caller.
class MemoryBytes {
 public:
  explicit MemoryBytes(std::string_view data) : p_(data.data()), end_(data.data() + data.size()) {}
  const char* take(std::size_t n) {
    if (static_cast<std::size_t>(end_ - p_) < n) return nullptr;
    const char* p = p_;
    p_ += n;
    return p;
  }
  void skip(std::uint64_t n) { p_ += n; }
  std::uint64_t remaining() const { return static_cast<std::uint64_t>(end_ - p_); }

 private:
  const char* p_;
  const char* end_;
};

class FileBytes {
 public:
  explicit FileBytes(FileReader& reader) : reader_(reader) {}
  const char* take(std::size_t n) { return reader_.take(n); }
  void skip(std::uint64_t n) {
    for (std::uint64_t left = n; left > 0;) {
      const std::size_t step = static_cast<std::size_t>(std::min<std::uint64_t>(left, kStreamBufferBytes));
      reader_.take(step);
      left -= step;
    }
  }
  std::uint64_t remaining() const { return reader_.remaining(); }

 private:
  FileReader& reader_;
};

// Reads values from the binary body with a bounds check on every read (a truncated file is an error, not UB).
template <typename Bytes>
class BinarySource {
 public:
  BinarySource(const ErrorContext& ctx, Bytes bytes, bool big_endian) : ctx_(ctx), bytes_(bytes), big_(big_endian) {}

  double real(Type t) { return decode<double>(take(size_of(t)), t, big_); }
  // Integral types only (checked in the header).
  std::int64_t integer(Type t) { return decode<std::int64_t>(take(size_of(t)), t, big_); }
  std::int64_t list_count(const Property& p) { return integer(p.count_type); }
  void skip(Type t, std::uint64_t n) {
    if (n > remaining() / size_of(t)) truncated();
    bytes_.skip(n * size_of(t));
  }
  std::uint64_t remaining() const { return bytes_.remaining(); }
  // Smallest encoding of one list item (bytes), for checking a list's count before reading it.
  static std::uint64_t min_item_bytes(Type t) { return size_of(t); }
  // The record being read ("face", 12), set by the caller for messages; formatted only on failure.
  void at(const std::string* element, std::uint64_t index) {
    element_ = element;
    index_ = index;
  }

 private:
  const char* take(std::size_t n) {
    const char* p = bytes_.take(n);
    if (p == nullptr) truncated();
    return p;
  }
  [[noreturn]] void truncated() const {
    ctx_.fail("binary data ends inside " + *element_ + " " + std::to_string(index_) + " (truncated file)");
  }

  const ErrorContext& ctx_;
  Bytes bytes_;
  const std::string* element_ = nullptr;
  std::uint64_t index_ = 0;
  bool big_;
};

// The header of a PLY file read by `reader`, which is left at the first byte of the body.
Header read_streamed_header(const std::filesystem::path& path, FileReader& reader) {
  constexpr std::size_t kMaxHeaderBytes = std::size_t{1} << 24;
  std::string text;
  std::string_view line;
  while (reader.next_line(line)) {
    text.append(line);
    text.push_back('\n');
    if (parse::trim(line) == "end_header") break;
    if (text.size() > kMaxHeaderBytes) break;  // parse_header reports the missing end_header
  }
  return parse_header(path, text);
}

// Reads whitespace-separated values of the ASCII body.
class AsciiSource {
 public:
  AsciiSource(ErrorContext& ctx, std::string_view data, std::size_t first_line)
      : ctx_(ctx), tokens_(data, first_line) {}

  double real(Type t) {
    const std::string_view token = take();
    double x = 0;
    if (is_integral(t)) {
      std::int64_t i = 0;
      if (!parse::parse_int(token, i)) bad(token);
      return static_cast<double>(i);
    }
    if (!parse::parse_real(token, x)) bad(token);
    return x;
  }
  std::int64_t integer(Type) {
    const std::string_view token = take();
    std::int64_t i = 0;
    if (!parse::parse_int(token, i)) bad(token);
    return i;
  }
  // A list's item count; a token that is no integer means the data does not hold the list the header declares.
  std::int64_t list_count(const Property& p) {
    const std::string_view token = take();
    std::int64_t i = 0;
    if (!parse::parse_int(token, i)) {
      ctx_.fail("list property '" + p.name + "' of " + where() + ": the count " + parse::quote(token) +
                " is not an integer (does the header match the data?)");
    }
    return i;
  }
  void skip(Type, std::uint64_t n) {
    for (std::uint64_t i = 0; i < n; ++i) take();
  }
  std::uint64_t remaining() const { return tokens_.remaining(); }
  static std::uint64_t min_item_bytes(Type) { return 1; }  // a one-digit token (plus a separator)
  void at(const std::string* element, std::uint64_t index) {
    element_ = element;
    index_ = index;
  }

 private:
  std::string_view take() {
    const std::string_view token = tokens_.next();
    ctx_.line = tokens_.line_number();
    if (token.empty()) ctx_.fail("data ends inside " + where() + " (truncated file)");
    return token;
  }
  [[noreturn]] void bad(std::string_view token) const {
    ctx_.fail("malformed number " + parse::quote(token) + " in " + where());
  }
  std::string where() const { return *element_ + " " + std::to_string(index_); }

  ErrorContext& ctx_;
  const std::string* element_ = nullptr;
  std::uint64_t index_ = 0;
  parse::TokenCursor tokens_;
};

// What each vertex property is for.
enum class Role { skip, x, y, z, nx, ny, nz, u, v, red, green, blue, alpha };

// The vertex attribute a property name stands for (Role::skip for none), whatever the property's type.
Role role_named(std::string_view name) {
  struct Name {
    std::string_view name;
    Role role;
  };
  static constexpr Name kNames[] = {
      {"x", Role::x},           {"y", Role::y},           {"z", Role::z},
      {"nx", Role::nx},         {"ny", Role::ny},         {"nz", Role::nz},
      {"u", Role::u},           {"s", Role::u},           {"texture_u", Role::u},   {"texture_s", Role::u},
      {"v", Role::v},           {"t", Role::v},           {"texture_v", Role::v},   {"texture_t", Role::v},
      {"red", Role::red},       {"green", Role::green},   {"blue", Role::blue},     {"alpha", Role::alpha},
      {"diffuse_red", Role::red}, {"diffuse_green", Role::green}, {"diffuse_blue", Role::blue},
  };
  for (const Name& n : kNames) {
    if (n.name == name) return n.role;
  }
  return Role::skip;
}

// Colour channels stored as integers are normalised by their type's maximum (uchar 255 -> 1.0); floats are
// taken as they are. Dividing in float keeps k / 255 correctly rounded, so the writer's round(c * 255) gives k.
float color_divisor(Type t) {
  switch (t) {
    case Type::u8: return 255.0f;
    case Type::u16: return 65535.0f;
    case Type::i8: return 127.0f;
    case Type::i16: return 32767.0f;
    case Type::u32: return 4294967295.0f;
    case Type::i32: return 2147483647.0f;
    default: return 1.0f;
  }
}

int gltf_component_type(Type t) {
  switch (t) {
    case Type::i8: return 5120;
    case Type::u8: return 5121;
    case Type::i16: return 5122;
    case Type::u16: return 5123;
    case Type::u32: return 5125;
    default: return 5126;
  }
}

bool is_face_list(const Property& p) { return p.list && (p.name == "vertex_indices" || p.name == "vertex_index"); }

struct BodyResult {
  Mesh mesh;
  bool double_positions = false;
  std::uint64_t skipped_elements = 0;
};

template <typename Source>
void skip_property(Source& src, const Property& p) {
  if (!p.list) {
    src.skip(p.type, 1);
    return;
  }
  const std::int64_t n = src.list_count(p);
  // A negative count is reported as running past the data (skip checks the bounds before moving).
  src.skip(p.type, n < 0 ? ~0ull : static_cast<std::uint64_t>(n));
}

template <typename Source>
void read_vertices(Source& src, const Element& e, Mesh& mesh, const ErrorContext& ctx, BodyResult& r) {
  std::vector<Role> roles;
  bool has[13] = {};
  Type color_type = Type::f32;
  for (const Property& p : e.properties) {
    // Other lists are extra data and skipped; one named like an attribute is a header that disagrees with
    // what a vertex holds (read on, its data would fail later as a malformed list count).
    if (p.list && role_named(p.name) != Role::skip) {
      ctx.fail("vertex property '" + p.name + "' is declared as a list where a scalar is expected");
    }
    roles.push_back(p.list ? Role::skip : role_named(p.name));
    has[static_cast<int>(roles.back())] = true;
    if (roles.back() == Role::red) color_type = p.type;
    if (roles.back() == Role::x && p.type == Type::f64) r.double_positions = true;
  }
  if (!has[int(Role::x)] || !has[int(Role::y)] || !has[int(Role::z)]) {
    ctx.fail("the vertex element has no x, y and z properties");
  }
  const bool normals = has[int(Role::nx)] && has[int(Role::ny)] && has[int(Role::nz)];
  const bool uvs = has[int(Role::u)] && has[int(Role::v)];
  const bool colors = has[int(Role::red)] && has[int(Role::green)] && has[int(Role::blue)];
  const auto n = static_cast<std::size_t>(e.count);  // checked against the file size by the caller
  mesh.positions.resize(n);
  mesh.wedge_vertex.resize(n);
  if (normals) mesh.normals.resize(n);
  if (uvs) mesh.uvs.emplace_back(n);
  if (colors) {
    mesh.colors.emplace_back(n, Vec4f{{0, 0, 0, 1}});
    mesh.color_components.push_back(has[int(Role::alpha)] ? 4 : 3);
    mesh.formats["COLOR_0"] = AttributeFormat{gltf_component_type(color_type), is_integral(color_type)};
  }
  for (std::size_t i = 0; i < n; ++i) {
    src.at(&e.name, i);
    for (std::size_t k = 0; k < e.properties.size(); ++k) {
      const Property& p = e.properties[k];
      if (roles[k] == Role::skip) {
        skip_property(src, p);
        continue;
      }
      const double x = src.real(p.type);
      switch (roles[k]) {
        case Role::x: mesh.positions[i][0] = static_cast<float>(x); break;
        case Role::y: mesh.positions[i][1] = static_cast<float>(x); break;
        case Role::z: mesh.positions[i][2] = static_cast<float>(x); break;
        case Role::nx: if (normals) mesh.normals[i][0] = static_cast<float>(x); break;
        case Role::ny: if (normals) mesh.normals[i][1] = static_cast<float>(x); break;
        case Role::nz: if (normals) mesh.normals[i][2] = static_cast<float>(x); break;
        case Role::u: if (uvs) mesh.uvs[0][i][0] = static_cast<float>(x); break;
        case Role::v: if (uvs) mesh.uvs[0][i][1] = static_cast<float>(x); break;
        case Role::red: if (colors) mesh.colors[0][i][0] = static_cast<float>(x) / color_divisor(p.type); break;
        case Role::green: if (colors) mesh.colors[0][i][1] = static_cast<float>(x) / color_divisor(p.type); break;
        case Role::blue: if (colors) mesh.colors[0][i][2] = static_cast<float>(x) / color_divisor(p.type); break;
        case Role::alpha: if (colors) mesh.colors[0][i][3] = static_cast<float>(x) / color_divisor(p.type); break;
        case Role::skip: break;
      }
    }
    parse::check_finite_position(ctx, mesh.positions[i], i);
    mesh.wedge_vertex[i] = static_cast<std::uint32_t>(i);
  }
}

// The face element's polygons: per face, its index list's count is checked (at least 3, no more than the data
// left holds) and `face(f, count, type)` reads the `count` indices (src.integer(type)).
template <typename Source, typename Face>
void for_each_face(Source& src, const Element& e, const ErrorContext& ctx, Face&& face) {
  const Property* list = nullptr;
  for (const Property& p : e.properties) {
    if (is_face_list(p)) list = &p;
  }
  if (!list) ctx.fail("the face element has no vertex_indices list");
  if (!is_integral(list->type)) ctx.fail("the face vertex_indices list has a non-integer item type");
  for (std::uint64_t f = 0; f < e.count; ++f) {
    src.at(&e.name, f);
    for (const Property& p : e.properties) {
      if (&p != list) {
        skip_property(src, p);
        continue;
      }
      const std::int64_t count = src.list_count(p);
      if (count < 3) ctx.fail("face " + std::to_string(f) + " has " + std::to_string(count) + " vertices (at least 3 needed)");
      if (static_cast<std::uint64_t>(count) > src.remaining() / Source::min_item_bytes(p.type)) {
        ctx.fail("face " + std::to_string(f) + " declares " + std::to_string(count) +
                 " vertices, more than the remaining data holds");
      }
      face(f, count, p.type);
    }
  }
}

template <typename Source>
void read_faces(Source& src, const Element& e, Mesh& mesh, const ErrorContext& ctx, const LoadOptions& options) {
  const auto n = static_cast<std::size_t>(e.count);  // checked against the file size by the caller
  mesh.face_offsets.reserve(n + 1);
  mesh.corner_wedge.reserve(n * 3);
  for_each_face(src, e, ctx, [&](std::uint64_t f, std::int64_t count, Type type) {
    for (std::int64_t c = 0; c < count; ++c) {
      const std::int64_t index = src.integer(type);
      // The vertex element may come after the faces, so the upper bound is checked once all is read.
      if (index < 0 || index >= std::int64_t{0xffffffff}) {
        ctx.fail("face " + std::to_string(f) + " uses vertex index " + std::to_string(index) + ", out of range");
      }
      mesh.corner_wedge.push_back(static_cast<std::uint32_t>(index));
    }
    parse::check_element_cap(ctx, "face corners", mesh.corner_wedge.size(), options);
    mesh.face_offsets.push_back(static_cast<std::uint32_t>(mesh.corner_wedge.size()));
  });
}

template <typename Source>
BodyResult read_body(Source& src, const Header& h, const ErrorContext& ctx, const LoadOptions& options) {
  BodyResult r;
  bool have_vertices = false, have_faces = false;
  for (const Element& e : h.elements) {
    if (e.name == "vertex" && !have_vertices) {
      read_vertices(src, e, r.mesh, ctx, r);
      have_vertices = true;
    } else if (e.name == "face" && !have_faces) {
      read_faces(src, e, r.mesh, ctx, options);
      have_faces = true;
    } else if (!e.properties.empty()) {
      r.skipped_elements += e.count;
      for (std::uint64_t i = 0; i < e.count; ++i) {
        src.at(&e.name, i);
        for (const Property& p : e.properties) skip_property(src, p);
      }
    }
  }
  if (!have_vertices) ctx.fail("the file has no vertex element");
  return r;
}

}  // namespace

StreamCounts ply_counts(const std::filesystem::path& path) {
  FileReader reader(path);
  const Header h = read_streamed_header(path, reader);
  StreamCounts c;
  c.readable = h.encoding != Encoding::ascii;
  for (const Element& e : h.elements) {
    if (e.name == "vertex") c.vertices = e.count;
    if (e.name == "face") c.triangles = e.count;
  }
  return c;
}

void stream_ply(const std::filesystem::path& path, const StreamSinks& sinks) {
  FileReader reader(path);
  ErrorContext ctx{path};
  if (reader.size() == 0) ctx.fail("file is empty");
  const Header h = read_streamed_header(path, reader);
  if (h.encoding == Encoding::ascii) ctx.fail("an ASCII PLY file cannot be read out of core (binary only)");
  BinarySource<FileBytes> src(ctx, FileBytes(reader), h.encoding == Encoding::binary_be);
  std::uint64_t vertices = 0;
  bool have_vertices = false, have_faces = false;
  std::vector<std::uint32_t> face;
  for (const Element& e : h.elements) {
    if (e.name == "vertex" && !have_vertices) {
      std::vector<int> axis(e.properties.size(), -1);  // per property: the coordinate it holds, or -1
      bool have[3] = {false, false, false};
      for (std::size_t k = 0; k < e.properties.size(); ++k) {
        const Property& p = e.properties[k];
        const Role role = role_named(p.name);
        if (p.list && role != Role::skip) ctx.fail("vertex property '" + p.name + "' is declared as a list where a scalar is expected");
        if (role == Role::x || role == Role::y || role == Role::z) {
          axis[k] = static_cast<int>(role) - static_cast<int>(Role::x);
          have[axis[k]] = true;
        } else if (role != Role::skip) {
          refuse_out_of_core(ctx, "vertex property '" + p.name + "'");
        }
      }
      if (!have[0] || !have[1] || !have[2]) ctx.fail("the vertex element has no x, y and z properties");
      parse::check_declared_count(ctx, "vertices", e.count, 1, src.remaining(), {});
      for (std::uint64_t i = 0; i < e.count; ++i) {
        src.at(&e.name, i);
        Vec3f p{};
        for (std::size_t k = 0; k < e.properties.size(); ++k) {
          const Property& q = e.properties[k];
          if (axis[k] < 0) {
            skip_property(src, q);
          } else {
            p[axis[k]] = static_cast<float>(src.real(q.type));
          }
        }
        parse::check_finite_position(ctx, p, i);
        sinks.vertex(p);
      }
      vertices = e.count;
      have_vertices = true;
    } else if (e.name == "face" && !have_faces) {
      if (!have_vertices) ctx.fail("the face element comes before the vertex element (out of core, vertices must come first)");
      for_each_face(src, e, ctx, [&](std::uint64_t f, std::int64_t count, Type type) {
        face.clear();
        for (std::int64_t c = 0; c < count; ++c) {
          const std::int64_t index = src.integer(type);
          if (index < 0 || static_cast<std::uint64_t>(index) >= vertices) {
            ctx.fail("face " + std::to_string(f) + " uses vertex " + std::to_string(index) + " but the file has " +
                     std::to_string(vertices) + " vertices");
          }
          face.push_back(static_cast<std::uint32_t>(index));
        }
        sinks.face(face);
      });
      have_faces = true;
    } else {
      for (std::uint64_t i = 0; i < e.count; ++i) {
        src.at(&e.name, i);
        for (const Property& p : e.properties) skip_property(src, p);
      }
    }
  }
  if (!have_vertices) ctx.fail("the file has no vertex element");
}

Asset read_ply(const std::filesystem::path& path, std::string_view bytes, const LoadOptions& options) {
  ErrorContext ctx{path};
  if (bytes.empty()) ctx.fail("file is empty");
  const Header h = parse_header(path, bytes);
  const std::string_view data = bytes.substr(h.data_offset);
  const bool binary = h.encoding != Encoding::ascii;

  // Every declared count against the bytes that remain, before anything is allocated: a record needs at least
  // its fixed-size fields (binary) or one character per value (ASCII); a face list at least 3 indices.
  std::uint64_t remaining = data.size();
  for (const Element& e : h.elements) {
    std::uint64_t min_bytes = 0;
    for (const Property& p : e.properties) {
      const std::uint64_t min_items = e.name == "face" && is_face_list(p) ? 3 : 0;
      min_bytes += binary ? size_of(p.list ? p.count_type : p.type) + min_items * size_of(p.type) : 1 + min_items;
    }
    parse::check_declared_count(ctx, e.name == "vertex" ? "vertices" : e.name == "face" ? "faces" : e.name + " elements",
                                e.count, min_bytes, remaining, options);
    remaining -= e.count * min_bytes;
  }

  BodyResult r;
  if (binary) {
    BinarySource<MemoryBytes> src(ctx, MemoryBytes(data), h.encoding == Encoding::binary_be);
    r = read_body(src, h, ctx, options);
  } else {
    ErrorContext text_ctx{path};
    AsciiSource src(text_ctx, data, h.data_line);
    r = read_body(src, h, text_ctx, options);
  }
  Mesh& mesh = r.mesh;
  for (std::size_t f = 0; f + 1 < mesh.face_offsets.size(); ++f) {
    for (std::uint32_t c = mesh.face_offsets[f]; c < mesh.face_offsets[f + 1]; ++c) {
      if (mesh.corner_wedge[c] >= mesh.vertex_count()) {
        ctx.fail("face " + std::to_string(f) + " uses vertex " + std::to_string(mesh.corner_wedge[c]) +
                 " but the file has " + std::to_string(mesh.vertex_count()) + " vertices");
      }
    }
  }
  parse::finish_mesh(mesh);
  Asset asset = parse::make_asset(path, Format::ply, std::move(mesh));
  asset.binary = binary;
  if (r.double_positions) asset.warnings.push_back("double-precision positions were rounded to float");
  if (r.skipped_elements > 0) {
    asset.warnings.push_back("skipped " + std::to_string(r.skipped_elements) + " records of elements other than vertex and face");
  }
  return asset;
}

// Writes one PLY vertex per wedge (then any vertex no wedge uses), so per-corner attributes survive; the reader
// welds them back by position. Positions, normals and UVs as float; colours as uchar when the source stored
// them so (mesh.formats["COLOR_0"]), else float; faces as a uchar count (int when a polygon has more than 255
// corners) and int indices. Polygons are written as they are.
std::string write_ply(const Asset& asset, bool binary) {
  Mesh storage;
  const Mesh& m = parse::single_mesh(asset, storage);
  parse::check_writable(m, asset.source);
  const std::vector<std::uint32_t> order = parse::per_wedge_vertex_order(m);
  const bool normals = parse::has_normals(m), uvs = parse::has_uvs(m), colors = parse::has_colors(m);
  const bool alpha = colors && !m.color_components.empty() && m.color_components[0] == 4;
  const auto fmt = m.formats.find("COLOR_0");
  const bool uchar_colors = colors && fmt != m.formats.end() && fmt->second.component_type == 5121;
  std::uint32_t max_face = 0;
  for (std::size_t f = 0; f < m.face_count(); ++f) max_face = std::max(max_face, m.face_size(f));
  const bool wide_count = max_face > 255;

  std::string out;
  out += "ply\nformat ";
  out += binary ? "binary_little_endian 1.0\n" : "ascii 1.0\n";
  out += "comment written by lodforge\n";
  out += "element vertex " + std::to_string(order.size()) + "\n";
  out += "property float x\nproperty float y\nproperty float z\n";
  if (normals) out += "property float nx\nproperty float ny\nproperty float nz\n";
  if (uvs) out += "property float s\nproperty float t\n";
  if (colors) {
    const char* t = uchar_colors ? "uchar" : "float";
    for (const char* c : {"red", "green", "blue", "alpha"}) {
      if (c[0] == 'a' && !alpha) break;
      out += std::string("property ") + t + " " + c + "\n";
    }
  }
  out += "element face " + std::to_string(m.face_count()) + "\n";
  out += wide_count ? "property list int int vertex_indices\n" : "property list uchar int vertex_indices\n";
  out += "end_header\n";
  out.reserve(out.size() + order.size() * (binary ? 40 : 80) + m.corner_count() * (binary ? 5 : 8));

  auto put_real = [&](float x, bool last) {
    if (binary) {
      parse::append_le(out, x);
    } else {
      parse::append_real(out, x);
      out += last ? '\n' : ' ';
    }
  };
  auto put_uint = [&](std::uint32_t x, int bytes, bool last) {
    if (binary) {
      if (bytes == 1) out += static_cast<char>(x);
      else parse::append_le(out, x);
    } else {
      parse::append_uint(out, x);
      out += last ? '\n' : ' ';
    }
  };
  const std::size_t nw = m.wedge_count();
  for (std::size_t i = 0; i < order.size(); ++i) {
    const bool wedge = i < nw;  // the tail holds vertices without a wedge: neutral attributes
    const Vec3f& p = m.positions[order[i]];
    bool more = normals || uvs || colors;
    put_real(p[0], false);
    put_real(p[1], false);
    put_real(p[2], !more);
    if (normals) {
      const Vec3f n = wedge ? m.normals[i] : Vec3f{};
      more = uvs || colors;
      put_real(n[0], false);
      put_real(n[1], false);
      put_real(n[2], !more);
    }
    if (uvs) {
      const Vec2f t = wedge ? m.uvs[0][i] : Vec2f{};
      put_real(t[0], false);
      put_real(t[1], !colors);
    }
    if (colors) {
      const Vec4f c = wedge ? m.colors[0][i] : Vec4f{{1, 1, 1, 1}};
      const int channels = alpha ? 4 : 3;
      for (int k = 0; k < channels; ++k) {
        const bool last = k + 1 == channels;
        if (uchar_colors) {
          put_uint(parse::to_unorm8(c[k]), 1, last);
        } else {
          put_real(c[k], last);
        }
      }
    }
  }
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    const std::uint32_t n = m.face_size(f);
    put_uint(n, wide_count ? 4 : 1, n == 0);
    for (std::uint32_t c = m.face_offsets[f]; c < m.face_offsets[f + 1]; ++c) {
      put_uint(m.corner_wedge[c], 4, c + 1 == m.face_offsets[f + 1]);
    }
  }
  return out;
}

}  // namespace lodforge::io
