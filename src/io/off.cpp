// Geomview OFF reader and writer (text form).
//
// Header keyword [ST][C][N]OFF (texture coordinates, colour, normal per vertex), then "vertices faces edges"
// (possibly on the keyword's line), then one vertex per line: x y z [nx ny nz] [colour] [s t], then one face
// per line: n i0 .. i(n-1) [colour]. The body is read line by line because the optional colours have no
// declared size (3 or 4 values, integers 0..255 or floats 0..1). Face colours are ignored (with a warning):
// lodforge has no per-face attribute stream. '#' starts a comment anywhere. Binary OFF is not supported.
// Reference: the OFF page of the Geomview manual (geomview.org/docs/html/OFF.html).

#include <algorithm>
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

struct OffHeader {
  bool texcoords = false, colors = false, normals = false;
};

// Next line with its comment removed and trimmed, skipping lines left empty.
bool next_content_line(parse::LineCursor& lines, ErrorContext& ctx, std::string_view& line) {
  while (lines.next(line)) {
    ctx.line = lines.line_number();
    const std::size_t hash = line.find('#');
    if (hash != std::string_view::npos) line = line.substr(0, hash);
    line = parse::trim(line);
    if (!line.empty()) return true;
  }
  return false;
}

bool parse_keyword(std::string_view k, OffHeader& h) {
  if (k.size() < 3 || k.substr(k.size() - 3) != "OFF") return false;
  k.remove_suffix(3);
  if (k.starts_with("ST")) {
    h.texcoords = true;
    k.remove_prefix(2);
  }
  if (k.starts_with("C")) {
    h.colors = true;
    k.remove_prefix(1);
  }
  if (k.starts_with("N")) {
    h.normals = true;
    k.remove_prefix(1);
  }
  return k.empty();  // 4OFF (4D) and nOFF (n-D) are not surfaces lodforge handles
}

// Integer tokens ("255") may be 0..255 channels; reals ("1.0", "0.5") are 0..1 already.
bool looks_integral(std::string_view token) { return token.find_first_of(".eEnN") == std::string_view::npos; }

}  // namespace

Asset read_off(const std::filesystem::path& path, std::string_view bytes, const LoadOptions& options) {
  ErrorContext ctx{path};
  if (bytes.empty()) ctx.fail("file is empty");
  parse::LineCursor lines(bytes);
  std::string_view line;
  if (!next_content_line(lines, ctx, line)) ctx.fail("file has no content");

  OffHeader h;
  std::string_view rest = line;
  const std::string_view keyword = parse::next_token(rest);
  if (!parse_keyword(keyword, h)) ctx.fail("not an OFF file (header " + parse::quote(keyword) + ")");
  if (parse::trim(rest).starts_with("BINARY")) ctx.fail("binary OFF is not supported");
  // The counts may follow the keyword on the same line.
  if (parse::trim(rest).empty()) {
    if (!next_content_line(lines, ctx, line)) ctx.fail("file ends before the counts line");
    rest = line;
  }
  std::uint64_t counts[3] = {0, 0, 0};
  for (int i = 0; i < 3; ++i) {
    const std::string_view token = parse::next_token(rest);
    if (token.empty() && i == 2) break;  // the edge count is often left out
    if (!parse::parse_int(token, counts[i])) ctx.fail("malformed counts line (expected 'vertices faces edges')");
  }
  const std::uint64_t nv = counts[0], nf = counts[1];
  // Each vertex line has at least "x y z" (5 characters), each face line at least "3 a b c" (7 characters).
  constexpr std::uint64_t kMinVertexBytes = 5, kMinFaceBytes = 7;
  const std::uint64_t remaining = bytes.size() - lines.offset();
  parse::check_declared_count(ctx, "vertices", nv, kMinVertexBytes, remaining, options);
  parse::check_declared_count(ctx, "faces", nf, kMinFaceBytes, remaining - nv * kMinVertexBytes, options);

  Mesh mesh;
  mesh.positions.resize(nv);
  mesh.wedge_vertex.resize(nv);
  if (h.normals) mesh.normals.resize(nv);
  if (h.texcoords) mesh.uvs.emplace_back(nv);
  // Colours are 0..255 integers when every colour token of the file is an integer and one exceeds 1; else 0..1.
  bool all_integral = true, above_one = false, alpha = false;
  if (h.colors) mesh.colors.emplace_back(nv, Vec4f{{1, 1, 1, 1}});
  for (std::uint64_t v = 0; v < nv; ++v) {
    if (!next_content_line(lines, ctx, line)) ctx.fail("file ends after " + std::to_string(v) + " of " + std::to_string(nv) + " vertices");
    float x[13] = {};
    std::string_view tokens[13];
    std::string_view r = line;
    int n = 0;
    for (std::string_view t = parse::next_token(r); !t.empty(); t = parse::next_token(r)) {
      if (n == 13) ctx.fail("too many values on vertex line " + std::to_string(v));
      if (!parse::parse_real(t, x[n])) ctx.fail("malformed number " + parse::quote(t) + " on vertex line " + std::to_string(v));
      tokens[n++] = t;
    }
    const int needed = 3 + (h.normals ? 3 : 0) + (h.texcoords ? 2 : 0);
    const int color_values = n - needed;
    if (color_values < 0 || (h.colors ? (color_values != 3 && color_values != 4) : color_values != 0)) {
      ctx.fail("vertex line " + std::to_string(v) + " has " + std::to_string(n) + " values, which does not match the header " +
               parse::quote(keyword));
    }
    mesh.positions[v] = Vec3f{{x[0], x[1], x[2]}};
    parse::check_finite_position(ctx, mesh.positions[v], v);
    mesh.wedge_vertex[v] = static_cast<std::uint32_t>(v);
    int k = 3;
    if (h.normals) {
      mesh.normals[v] = Vec3f{{x[3], x[4], x[5]}};
      k = 6;
    }
    if (h.colors) {
      alpha |= color_values == 4;
      for (int c = 0; c < color_values; ++c) {
        all_integral &= looks_integral(tokens[k + c]);
        above_one |= x[k + c] > 1.0f;
        mesh.colors[0][v][c] = x[k + c];
      }
      k += color_values;
    }
    if (h.texcoords) mesh.uvs[0][v] = Vec2f{{x[k], x[k + 1]}};
  }
  if (h.colors) {
    mesh.color_components.push_back(alpha ? 4 : 3);
    if (all_integral && above_one) {
      mesh.formats["COLOR_0"] = AttributeFormat{5121, true};
      for (Vec4f& c : mesh.colors[0]) {
        for (int i = 0; i < 4; ++i) {
          // Alpha left out of a 3-channel file stays 1.
          if (i < 3 || alpha) c[i] /= 255.0f;
        }
      }
    }
  }

  mesh.face_offsets.reserve(nf + 1);
  mesh.corner_wedge.reserve(nf * 3);
  std::uint64_t colored_faces = 0;
  for (std::uint64_t f = 0; f < nf; ++f) {
    if (!next_content_line(lines, ctx, line)) ctx.fail("file ends after " + std::to_string(f) + " of " + std::to_string(nf) + " faces");
    std::string_view r = line;
    std::uint64_t count = 0;
    const std::string_view first = parse::next_token(r);
    if (!parse::parse_int(first, count)) ctx.fail("malformed vertex count " + parse::quote(first) + " of face " + std::to_string(f));
    if (count < 3) ctx.fail("face " + std::to_string(f) + " has " + std::to_string(count) + " vertices (at least 3 needed)");
    for (std::uint64_t c = 0; c < count; ++c) {
      const std::string_view t = parse::next_token(r);
      if (t.empty()) ctx.fail("face " + std::to_string(f) + " declares " + std::to_string(count) + " vertices but lists " + std::to_string(c));
      std::int64_t index = 0;
      if (!parse::parse_int(t, index)) ctx.fail("malformed vertex index " + parse::quote(t) + " in face " + std::to_string(f));
      if (index < 0 || static_cast<std::uint64_t>(index) >= nv) {
        ctx.fail("face " + std::to_string(f) + " uses vertex " + std::to_string(index) + " but the file has " + std::to_string(nv) + " vertices");
      }
      mesh.corner_wedge.push_back(static_cast<std::uint32_t>(index));
    }
    if (!parse::trim(r).empty()) ++colored_faces;
    parse::check_element_cap(ctx, "face corners", mesh.corner_wedge.size(), options);
    mesh.face_offsets.push_back(static_cast<std::uint32_t>(mesh.corner_wedge.size()));
  }

  parse::finish_mesh(mesh);
  Asset asset = parse::make_asset(path, Format::off, std::move(mesh));
  if (colored_faces > 0) asset.warnings.push_back("ignored the colours of " + std::to_string(colored_faces) + " faces");
  return asset;
}

// Writes [C]OFF: one vertex per vertex (OFF attributes are per vertex; a seam vertex takes its first wedge's
// colour), faces as they are. Colours as 0..255 integers when the source stored them so, else floats.
std::string write_off(const Asset& asset) {
  Mesh storage;
  const Mesh& m = parse::single_mesh(asset, storage);
  parse::check_writable(m, asset.source);
  const std::size_t nv = m.vertex_count();
  const bool colors = parse::has_colors(m);
  const bool alpha = colors && !m.color_components.empty() && m.color_components[0] == 4;
  const auto fmt = m.formats.find("COLOR_0");
  const bool uchar_colors = colors && fmt != m.formats.end() && fmt->second.component_type == 5121;
  const std::vector<std::uint32_t> first_wedge = colors ? parse::first_wedge_of_vertex(m) : std::vector<std::uint32_t>{};

  std::string out;
  out.reserve(nv * 40 + m.corner_count() * 8 + m.face_count() * 4);
  out += colors ? "COFF\n" : "OFF\n";
  out += std::to_string(nv) + " " + std::to_string(m.face_count()) + " 0\n";
  for (std::size_t v = 0; v < nv; ++v) {
    for (int i = 0; i < 3; ++i) {
      if (i) out += ' ';
      parse::append_real(out, m.positions[v][i]);
    }
    if (colors) {
      const Vec4f c = first_wedge[v] == kInvalidIndex ? Vec4f{{1, 1, 1, 1}} : m.colors[0][first_wedge[v]];
      for (int i = 0; i < (alpha ? 4 : 3); ++i) {
        out += ' ';
        if (uchar_colors) parse::append_uint(out, parse::to_unorm8(c[i]));
        else parse::append_real(out, c[i]);
      }
    }
    out += '\n';
  }
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    parse::append_uint(out, m.face_size(f));
    for (std::uint32_t c = m.face_offsets[f]; c < m.face_offsets[f + 1]; ++c) {
      out += ' ';
      parse::append_uint(out, m.wedge_vertex[m.corner_wedge[c]]);
    }
    out += '\n';
  }
  return out;
}

}  // namespace lodforge::io
