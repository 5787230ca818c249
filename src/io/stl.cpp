// STL reader and writer, binary and ASCII.
//
// Binary: an 80-byte header, a uint32 triangle count, then 50 bytes per triangle (normal, three vertices as
// float32 little-endian, a uint16 attribute). ASCII: "solid name", then "facet normal nx ny nz / outer loop /
// vertex x y z (x3) / endloop / endfacet" blocks, then "endsolid". Detection: binary files whose header starts
// with "solid" are common (exporters write the solid name there), so a file whose size is exactly 84 + 50 * count
// is binary whatever its first bytes are; otherwise a file starting with "solid" is parsed as ASCII.
//
// Facet normals are ignored on read (they are often zero, unnormalised or stale, and are implied by the vertex
// order anyway) and recomputed from the vertices on write. Every corner becomes its own vertex first; the
// common finish (text_parse.hpp) then welds them by position, so the mesh is connected again.

#include <cmath>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "lodforge/io/formats.hpp"
#include "text_parse.hpp"

namespace lodforge::io {
namespace {

using parse::ErrorContext;

constexpr std::size_t kHeaderBytes = 80;
constexpr std::size_t kPreambleBytes = kHeaderBytes + 4;  // header + triangle count
constexpr std::size_t kTriangleBytes = 50;

bool iequals(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const char x = (a[i] >= 'A' && a[i] <= 'Z') ? static_cast<char>(a[i] - 'A' + 'a') : a[i];
    if (x != b[i]) return false;
  }
  return true;
}

bool starts_with_solid(std::string_view bytes) {
  std::size_t i = 0;
  while (i < bytes.size() && parse::is_space(bytes[i])) ++i;
  return bytes.size() - i >= 5 && iequals(bytes.substr(i, 5), "solid");
}

// Appends one triangle as three fresh vertices/wedges (welded later).
void add_triangle(Mesh& mesh, const Vec3f* corners) {
  std::uint32_t w[3];
  for (int k = 0; k < 3; ++k) w[k] = mesh.add_vertex_with_wedge(corners[k]);
  mesh.add_face(w, 3);
}

Mesh read_binary(const ErrorContext& ctx, std::string_view bytes, const LoadOptions& options,
                 std::vector<std::string>& warnings) {
  if (bytes.size() < kPreambleBytes) {
    ctx.fail("file is " + std::to_string(bytes.size()) +
             " bytes: too short for a binary STL (84-byte header) and it does not start with 'solid'");
  }
  const std::uint64_t count = parse::load_le<std::uint32_t>(bytes.data() + kHeaderBytes);
  const std::uint64_t needed = kPreambleBytes + count * kTriangleBytes;
  parse::check_declared_count(ctx, "triangles", count, kTriangleBytes, bytes.size() - kPreambleBytes, options);
  if (bytes.size() > needed) {
    warnings.push_back("ignored " + std::to_string(bytes.size() - needed) + " bytes after the last triangle");
  }
  Mesh mesh;
  mesh.positions.reserve(count * 3);
  mesh.wedge_vertex.reserve(count * 3);
  mesh.corner_wedge.reserve(count * 3);
  mesh.face_offsets.reserve(count + 1);
  const char* p = bytes.data() + kPreambleBytes;
  for (std::uint64_t t = 0; t < count; ++t, p += kTriangleBytes) {
    Vec3f corners[3];
    for (int k = 0; k < 3; ++k) {
      for (int i = 0; i < 3; ++i) corners[k][i] = parse::load_le<float>(p + 12 + 12 * k + 4 * i);
      parse::check_finite_position(ctx, corners[k], t * 3 + static_cast<std::uint64_t>(k));
    }
    add_triangle(mesh, corners);
  }
  return mesh;
}

Mesh read_ascii(ErrorContext& ctx, std::string_view bytes, const LoadOptions& options) {
  parse::TokenCursor tokens(bytes, 1);
  auto next = [&] {
    const std::string_view t = tokens.next();
    ctx.line = tokens.line_number();
    return t;
  };
  auto expect = [&](std::string_view word) {
    const std::string_view t = next();
    if (!iequals(t, word)) {
      ctx.fail("expected '" + std::string(word) + "', found " + (t.empty() ? std::string("the end of the file") : parse::quote(t)));
    }
  };
  Mesh mesh;
  std::size_t solids = 0;
  std::vector<Vec3f> loop;
  for (std::string_view t = next(); !t.empty(); t = next()) {
    if (!iequals(t, "solid")) ctx.fail("expected 'solid', found " + parse::quote(t));
    ++solids;
    tokens.skip_line();
    for (;;) {
      t = next();
      if (iequals(t, "endsolid")) {
        tokens.skip_line();
        break;
      }
      if (!iequals(t, "facet")) {
        ctx.fail("expected 'facet' or 'endsolid', found " + (t.empty() ? std::string("the end of the file") : parse::quote(t)));
      }
      expect("normal");
      for (int i = 0; i < 3; ++i) {
        float ignored = 0;
        const std::string_view n = next();
        if (!parse::parse_real(n, ignored)) ctx.fail("malformed number " + parse::quote(n) + " in a facet normal");
      }
      expect("outer");
      expect("loop");
      loop.clear();
      for (t = next(); iequals(t, "vertex"); t = next()) {
        Vec3f p;
        for (int i = 0; i < 3; ++i) {
          const std::string_view x = next();
          if (!parse::parse_real(x, p[i])) ctx.fail("malformed number " + parse::quote(x) + " in a vertex");
        }
        parse::check_finite_position(ctx, p, mesh.vertex_count() + loop.size());
        loop.push_back(p);
        parse::check_element_cap(ctx, "vertices", mesh.vertex_count() + loop.size(), options);
      }
      if (!iequals(t, "endloop")) {
        ctx.fail("expected 'vertex' or 'endloop', found " + (t.empty() ? std::string("the end of the file") : parse::quote(t)));
      }
      if (loop.size() < 3) ctx.fail("facet has " + std::to_string(loop.size()) + " vertices (at least 3 needed)");
      expect("endfacet");
      // Some exporters write polygons as one facet; they are kept as polygons.
      std::vector<std::uint32_t> w(loop.size());
      for (std::size_t k = 0; k < loop.size(); ++k) w[k] = mesh.add_vertex_with_wedge(loop[k]);
      mesh.add_face(w.data(), w.size());
    }
  }
  if (solids == 0) ctx.fail("no 'solid' found");
  return mesh;
}

// Unit normal of triangle (a, b, c) for the facet record; zero for a degenerate triangle.
Vec3f facet_normal(const Vec3f& a, const Vec3f& b, const Vec3f& c) {
  const Vec3d n = cross(to_double(b) - to_double(a), to_double(c) - to_double(a));
  const double len = length(n);
  return len > 0 ? to_float(n * (1.0 / len)) : Vec3f{};
}

}  // namespace

Asset read_stl(const std::filesystem::path& path, std::string_view bytes, const LoadOptions& options) {
  ErrorContext ctx{path};
  if (bytes.empty()) ctx.fail("file is empty");
  std::vector<std::string> warnings;
  bool binary = true;
  if (bytes.size() >= kPreambleBytes) {
    const std::uint64_t count = parse::load_le<std::uint32_t>(bytes.data() + kHeaderBytes);
    binary = kPreambleBytes + count * kTriangleBytes == bytes.size() || !starts_with_solid(bytes);
  } else {
    binary = !starts_with_solid(bytes);
  }
  Mesh mesh;
  try {
    mesh = binary ? read_binary(ctx, bytes, options, warnings) : read_ascii(ctx, bytes, options);
  } catch (const IoError& e) {
    // Say which reading failed: random bytes read as binary STL otherwise only complain about a count.
    throw IoError(path, std::string("not a valid STL: ") +
                            (binary ? "read as binary STL (it does not start with 'solid'): "
                                    : "read as ASCII STL (it starts with 'solid'): ") +
                            e.problem());
  }
  parse::finish_mesh(mesh);
  Asset asset = parse::make_asset(path, Format::stl, std::move(mesh));
  asset.binary = binary;
  asset.warnings = std::move(warnings);
  return asset;
}

// Triangles only (polygons are fan-triangulated from their first corner), facet normals recomputed.
std::string write_stl(const Asset& asset, bool binary) {
  Mesh storage;
  const Mesh& m = parse::single_mesh(asset, storage);
  parse::check_writable(m, asset.source);
  const std::size_t triangles = m.triangle_count();
  std::string out;
  const std::string name = m.name.empty() ? "lodforge" : m.name;
  if (binary) {
    if (triangles > 0xffffffffull) throw IoError(asset.source, "too many triangles for a binary STL");
    out.reserve(kPreambleBytes + triangles * kTriangleBytes);
    std::string header = "binary STL written by lodforge";
    header.resize(kHeaderBytes, ' ');
    out += header;
    parse::append_le(out, static_cast<std::uint32_t>(triangles));
  } else {
    out.reserve(triangles * 250);
    out += "solid " + name + "\n";
  }
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    const std::uint32_t begin = m.face_offsets[f], end = m.face_offsets[f + 1];
    if (end - begin < 3) continue;
    const Vec3f& a = m.positions[m.corner_vertex(begin)];
    for (std::uint32_t c = begin + 1; c + 1 < end; ++c) {
      const Vec3f* corners[3] = {&a, &m.positions[m.corner_vertex(c)], &m.positions[m.corner_vertex(c + 1)]};
      const Vec3f n = facet_normal(*corners[0], *corners[1], *corners[2]);
      if (binary) {
        for (int i = 0; i < 3; ++i) parse::append_le(out, n[i]);
        for (const Vec3f* p : corners) {
          for (int i = 0; i < 3; ++i) parse::append_le(out, (*p)[i]);
        }
        parse::append_le(out, std::uint16_t{0});
        continue;
      }
      out += "  facet normal ";
      for (int i = 0; i < 3; ++i) {
        if (i) out += ' ';
        parse::append_real(out, n[i]);
      }
      out += "\n    outer loop\n";
      for (const Vec3f* p : corners) {
        out += "      vertex ";
        for (int i = 0; i < 3; ++i) {
          if (i) out += ' ';
          parse::append_real(out, (*p)[i]);
        }
        out += '\n';
      }
      out += "    endloop\n  endfacet\n";
    }
  }
  if (!binary) out += "endsolid " + name + "\n";
  return out;
}

}  // namespace lodforge::io
