// Wavefront OBJ reader and writer.
//
// Own code rather than OpenMesh IO: OpenMesh's OBJ reader drops faces that would make its halfedge structure
// non-manifold (real scans have them; see happy-buddha in the corpus), loses per-corner UVs of n-gons, and
// forgets `g`/`o` groups and `usemtl` material names. A lossless load -> save -> load, quads and n-gons kept
// as they are, needs all of that, so this file parses OBJ directly (std::from_chars on the bytes in memory)
// and writes it back with shortest round-trip float formatting.
//
// Model: every `v` line is a vertex (unreferenced ones are kept); a wedge is a distinct (v, vt, vn) triple of
// face corners in first-use order; then vertices are welded by position and identical wedges merged
// (text_parse.hpp, finish_mesh). Groups (`g`, `o`) and material slots (`usemtl`) are created in the order faces
// first use them. Reference: the "Object Files (.obj)" chapter of the Wavefront Advanced Visualizer manual.

#include <array>
#include <cstdint>
#include <limits>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "lodforge/io/formats.hpp"
#include "text_parse.hpp"

namespace lodforge::io {
namespace {

using parse::ErrorContext;

constexpr std::int32_t kAbsent = -1;

// One face corner as written: 0-based indices into the v/vt/vn lists, kAbsent where the corner has none.
struct RawCorner {
  std::int32_t v, vt, vn;
};

// Everything the line pass collects; turned into a Mesh afterwards (indices may point forward, so they are
// range-checked only once all lines are read).
struct ObjData {
  std::vector<Vec3f> positions;
  std::vector<Vec4f> vertex_colors;  // per `v` line that had colours (kept only when some line had them)
  std::size_t colored_vertices = 0;
  std::vector<Vec2f> uvs;
  std::vector<Vec3f> normals;
  std::vector<RawCorner> corners;
  std::vector<std::uint32_t> face_offsets{0};
  std::vector<std::uint32_t> face_line;  // source line of each face, for error messages
  std::vector<std::uint32_t> face_material;
  std::vector<std::uint32_t> face_group;
  std::vector<std::string> materials, groups;
  std::map<std::string, std::uint32_t, std::less<>> material_ids, group_ids;
  std::vector<std::string> mtllibs;
  std::string current_material, current_group;
  // Slot ids of the current names, resolved at the next face (kInvalidIndex until then): a name lookup per
  // `usemtl`/`g` run rather than per face.
  std::uint32_t current_material_id = kInvalidIndex, current_group_id = kInvalidIndex;
  bool any_group_statement = false;
  std::size_t corners_without_vt = 0, corners_with_vt = 0, corners_without_vn = 0, corners_with_vn = 0;
  std::map<std::string, std::size_t> ignored;  // unsupported statement -> count, reported as one warning each
};

std::uint32_t slot_id(std::map<std::string, std::uint32_t, std::less<>>& ids, std::vector<std::string>& names,
                      const std::string& name) {
  auto it = ids.find(name);
  if (it != ids.end()) return it->second;
  const auto id = static_cast<std::uint32_t>(names.size());
  names.push_back(name);
  ids.emplace(name, id);
  return id;
}

// Resolves one OBJ index (1-based, or negative = relative to the elements defined so far) to 0-based.
// Positive indices may point forward; they are checked against the final counts later.
std::int32_t resolve_index(const ErrorContext& ctx, std::int64_t index, std::size_t defined, const char* what) {
  if (index == 0) ctx.fail(std::string("face uses ") + what + " index 0 (OBJ indices start at 1)");
  if (index < 0) {
    const std::int64_t resolved = static_cast<std::int64_t>(defined) + index;
    if (resolved < 0) {
      ctx.fail(std::string("face uses relative ") + what + " index " + std::to_string(index) + " but only " +
               std::to_string(defined) + " " + what + "s are defined before it");
    }
    if (resolved > std::numeric_limits<std::int32_t>::max()) ctx.fail(std::string("too many ") + what + "s for 32-bit indices");
    return static_cast<std::int32_t>(resolved);
  }
  if (index > std::numeric_limits<std::int32_t>::max()) {
    ctx.fail(std::string("face uses ") + what + " index " + std::to_string(index) + ", beyond any file's size");
  }
  return static_cast<std::int32_t>(index - 1);
}

void parse_face(const ErrorContext& ctx, std::string_view rest, ObjData& d, const LoadOptions& options) {
  std::size_t count = 0;
  for (std::string_view token = parse::next_token(rest); !token.empty(); token = parse::next_token(rest)) {
    const char* p = token.data();
    const char* end = p + token.size();
    std::int64_t index = 0;
    RawCorner c{kAbsent, kAbsent, kAbsent};
    // v, v/vt, v//vn or v/vt/vn
    p = parse::parse_int_prefix(p, end, index);
    if (!p) ctx.fail("malformed face corner " + parse::quote(token));
    c.v = resolve_index(ctx, index, d.positions.size(), "vertex");
    if (p < end && *p == '/') {
      ++p;
      if (p < end && *p != '/') {
        p = parse::parse_int_prefix(p, end, index);
        if (!p) ctx.fail("malformed face corner " + parse::quote(token));
        c.vt = resolve_index(ctx, index, d.uvs.size(), "texture coordinate");
      }
      if (p < end && *p == '/') {
        ++p;
        p = parse::parse_int_prefix(p, end, index);
        if (!p) ctx.fail("malformed face corner " + parse::quote(token));
        c.vn = resolve_index(ctx, index, d.normals.size(), "normal");
      }
    }
    if (p != end) ctx.fail("malformed face corner " + parse::quote(token));
    (c.vt == kAbsent ? d.corners_without_vt : d.corners_with_vt)++;
    (c.vn == kAbsent ? d.corners_without_vn : d.corners_with_vn)++;
    d.corners.push_back(c);
    ++count;
  }
  if (count < 3) ctx.fail("face has " + std::to_string(count) + " vertices (at least 3 needed)");
  parse::check_element_cap(ctx, "faces", d.face_line.size() + 1, options);
  parse::check_element_cap(ctx, "face corners", d.corners.size(), options);
  d.face_offsets.push_back(static_cast<std::uint32_t>(d.corners.size()));
  d.face_line.push_back(static_cast<std::uint32_t>(ctx.line));
  if (d.current_material_id == kInvalidIndex) d.current_material_id = slot_id(d.material_ids, d.materials, d.current_material);
  if (d.current_group_id == kInvalidIndex) d.current_group_id = slot_id(d.group_ids, d.groups, d.current_group);
  d.face_material.push_back(d.current_material_id);
  d.face_group.push_back(d.current_group_id);
}

void parse_vertex(const ErrorContext& ctx, std::string_view rest, ObjData& d, const LoadOptions& options) {
  // x y z, x y z w (w ignored), x y z r g b, or x y z r g b a (a widespread extension for vertex colours).
  std::array<float, 7> x{};
  const int n = parse::parse_reals(ctx, rest, x.data(), 7, "a 'v' statement");
  if (n < 3 || n == 5) {
    ctx.fail("'v' statement has " + std::to_string(n) + " values (x y z, x y z w, x y z r g b or x y z r g b a expected)");
  }
  const Vec3f p{{x[0], x[1], x[2]}};
  parse::check_finite_position(ctx, p, d.positions.size());
  parse::check_element_cap(ctx, "vertices", d.positions.size() + 1, options);
  if (n >= 6) {
    // Colours were absent on earlier lines: those vertices get white (a warning says so later).
    d.vertex_colors.resize(d.positions.size(), Vec4f{{1, 1, 1, 1}});
    d.vertex_colors.push_back(Vec4f{{x[3], x[4], x[5], n == 7 ? x[6] : 1.0f}});
    ++d.colored_vertices;
  } else if (!d.vertex_colors.empty()) {
    d.vertex_colors.push_back(Vec4f{{1, 1, 1, 1}});
  }
  d.positions.push_back(p);
}

// A statement keyword: letters, digits and '_' only. Anything else (control bytes, binary data) means the file
// is not an OBJ text file, which is reported instead of being silently skipped.
bool is_keyword(std::string_view s) {
  for (char c : s) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_';
    if (!ok) return false;
  }
  return !s.empty();
}

void parse_statement(const ErrorContext& ctx, std::string_view line, ObjData& d, const LoadOptions& options) {
  std::string_view rest = line;
  const std::string_view keyword = parse::next_token(rest);
  if (keyword.empty() || keyword[0] == '#') return;
  if (keyword == "v") {
    parse_vertex(ctx, rest, d, options);
  } else if (keyword == "f") {
    parse_face(ctx, rest, d, options);
  } else if (keyword == "vt") {
    std::array<float, 3> t{};
    const int n = parse::parse_reals(ctx, rest, t.data(), 3, "a 'vt' statement");
    if (n < 1) ctx.fail("'vt' statement has no coordinates");
    parse::check_element_cap(ctx, "texture coordinates", d.uvs.size() + 1, options);
    d.uvs.push_back(Vec2f{{t[0], t[1]}});  // w (3D textures) is not modelled
  } else if (keyword == "vn") {
    std::array<float, 3> n3{};
    const int n = parse::parse_reals(ctx, rest, n3.data(), 3, "a 'vn' statement");
    if (n != 3) ctx.fail("'vn' statement has " + std::to_string(n) + " coordinates (3 needed)");
    parse::check_element_cap(ctx, "normals", d.normals.size() + 1, options);
    d.normals.push_back(Vec3f{{n3[0], n3[1], n3[2]}});
  } else if (keyword == "g" || keyword == "o") {
    // The whole rest of the line is the name (several group names are kept together as one).
    d.current_group = std::string(parse::trim(rest));
    d.current_group_id = kInvalidIndex;
    d.any_group_statement = true;
  } else if (keyword == "usemtl") {
    d.current_material = std::string(parse::trim(rest));
    d.current_material_id = kInvalidIndex;
  } else if (keyword == "mtllib") {
    d.mtllibs.emplace_back(parse::trim(rest));
  } else if (keyword == "s") {
    // Smoothing groups: normals carry the shading here.
  } else if (is_keyword(keyword)) {
    ++d.ignored[std::string(keyword)];  // l, p, vp, curves and surfaces, ...
  } else {
    ctx.fail("not an OBJ statement: " + parse::quote(line));
  }
}

// Builds the mesh: range-checks indices, makes one wedge per distinct (v, vt, vn), fills the wedge streams.
Mesh build_mesh(const std::filesystem::path& path, ObjData& d, std::vector<std::string>& warnings) {
  Mesh mesh;
  const std::size_t nv = d.positions.size();
  const std::size_t nf = d.face_line.size();
  // Indices may point forward, so the range check waits until all elements are known.
  for (std::size_t f = 0; f < nf; ++f) {
    for (std::uint32_t c = d.face_offsets[f]; c < d.face_offsets[f + 1]; ++c) {
      const RawCorner& rc = d.corners[c];
      const ErrorContext ctx{path, d.face_line[f]};
      if (static_cast<std::size_t>(rc.v) >= nv) {
        ctx.fail("face uses vertex " + std::to_string(rc.v + 1) + " but the file has " + std::to_string(nv) + " vertices");
      }
      if (rc.vt != kAbsent && static_cast<std::size_t>(rc.vt) >= d.uvs.size()) {
        ctx.fail("face uses texture coordinate " + std::to_string(rc.vt + 1) + " but the file has " +
                 std::to_string(d.uvs.size()));
      }
      if (rc.vn != kAbsent && static_cast<std::size_t>(rc.vn) >= d.normals.size()) {
        ctx.fail("face uses normal " + std::to_string(rc.vn + 1) + " but the file has " + std::to_string(d.normals.size()));
      }
    }
  }

  // Wedges: distinct (v, vt, vn) in first-use order. The wedges of one vertex form a short chain, so the lookup
  // needs no hashing and the numbering is deterministic.
  const bool with_uv = d.corners_with_vt > 0, with_normal = d.corners_with_vn > 0;
  std::vector<std::uint32_t> head(nv, kInvalidIndex), next;
  std::vector<RawCorner> wedge_key;
  wedge_key.reserve(nv);
  next.reserve(nv);
  mesh.corner_wedge.resize(d.corners.size());
  for (std::size_t c = 0; c < d.corners.size(); ++c) {
    const RawCorner& rc = d.corners[c];
    std::uint32_t w = head[rc.v];
    while (w != kInvalidIndex && (wedge_key[w].vt != rc.vt || wedge_key[w].vn != rc.vn)) w = next[w];
    if (w == kInvalidIndex) {
      w = static_cast<std::uint32_t>(wedge_key.size());
      wedge_key.push_back(rc);
      next.push_back(head[rc.v]);
      head[rc.v] = w;
    }
    mesh.corner_wedge[c] = w;
  }

  const std::size_t nw = wedge_key.size();
  mesh.positions = std::move(d.positions);
  mesh.wedge_vertex.resize(nw);
  for (std::size_t w = 0; w < nw; ++w) mesh.wedge_vertex[w] = static_cast<std::uint32_t>(wedge_key[w].v);
  if (with_uv) {
    mesh.uvs.emplace_back(nw);
    for (std::size_t w = 0; w < nw; ++w) {
      if (wedge_key[w].vt != kAbsent) mesh.uvs[0][w] = d.uvs[static_cast<std::size_t>(wedge_key[w].vt)];
    }
    if (d.corners_without_vt > 0) {
      warnings.push_back(std::to_string(d.corners_without_vt) +
                         " face corners have no texture coordinate while others do; they get UV (0, 0)");
    }
  }
  if (with_normal) {
    mesh.normals.resize(nw);
    for (std::size_t w = 0; w < nw; ++w) {
      if (wedge_key[w].vn != kAbsent) mesh.normals[w] = d.normals[static_cast<std::size_t>(wedge_key[w].vn)];
    }
    if (d.corners_without_vn > 0) {
      warnings.push_back(std::to_string(d.corners_without_vn) +
                         " face corners have no normal while others do; they get a zero normal");
    }
  }
  if (!d.vertex_colors.empty()) {
    d.vertex_colors.resize(mesh.positions.size(), Vec4f{{1, 1, 1, 1}});
    mesh.colors.emplace_back(nw);
    bool alpha = false;
    for (std::size_t w = 0; w < nw; ++w) {
      mesh.colors[0][w] = d.vertex_colors[static_cast<std::size_t>(wedge_key[w].v)];
      alpha |= mesh.colors[0][w][3] != 1.0f;
    }
    mesh.color_components.push_back(alpha ? 4 : 3);
    if (d.colored_vertices < mesh.positions.size()) {
      warnings.push_back(std::to_string(mesh.positions.size() - d.colored_vertices) +
                         " vertices have no colour while others do; they get white");
    }
  }

  mesh.face_offsets = std::move(d.face_offsets);
  mesh.face_material = std::move(d.face_material);
  for (const std::string& name : d.materials) mesh.materials.push_back(MaterialSlot{.name = name});
  if (d.any_group_statement) {
    mesh.face_group = std::move(d.face_group);
    mesh.groups = std::move(d.groups);
  }
  return mesh;
}

bool uses_groups(const Mesh& m) { return m.face_count() > 0 && m.face_group.size() == m.face_count(); }

}  // namespace

Asset read_obj(const std::filesystem::path& path, std::string_view bytes, const LoadOptions& options) {
  ErrorContext ctx{path};
  if (bytes.empty()) ctx.fail("file is empty");
  ObjData d;
  // Rough reservations from the file size (never from anything the file claims): ~30 bytes per `v` line.
  d.positions.reserve(bytes.size() / 64);
  d.corners.reserve(bytes.size() / 16);

  parse::LineCursor lines(bytes);
  std::string_view line;
  std::string joined;  // a statement continued over several lines with a trailing backslash
  while (lines.next(line)) {
    ctx.line = lines.line_number();
    std::string_view statement = parse::trim(line);
    if (!statement.empty() && statement.back() == '\\') {
      joined.assign(statement.substr(0, statement.size() - 1));
      std::string_view more;
      bool continued = true;
      while (continued && lines.next(more)) {
        more = parse::trim(more);
        continued = !more.empty() && more.back() == '\\';
        joined.push_back(' ');
        joined.append(continued ? more.substr(0, more.size() - 1) : more);
      }
      statement = joined;
    }
    parse_statement(ctx, statement, d, options);
  }
  ctx.line = 0;
  if (d.positions.empty() && d.face_line.empty()) ctx.fail("no vertices or faces found (not an OBJ file?)");

  std::vector<std::string> warnings;
  Mesh mesh = build_mesh(path, d, warnings);
  for (const auto& [keyword, count] : d.ignored) {
    warnings.push_back("ignored " + std::to_string(count) + " unsupported '" + keyword + "' statement(s)");
  }
  parse::finish_mesh(mesh);
  Asset asset = parse::make_asset(path, Format::obj, std::move(mesh));
  asset.warnings = std::move(warnings);
  asset.obj_mtllibs = std::move(d.mtllibs);
  return asset;
}

// Writes positions (one `v` per vertex, with colours when the mesh has them), one `vt`/`vn` per wedge when the
// mesh has UVs/normals, and faces as v/vt/vn corners; `g` and `usemtl` where a face's group or material
// differs from the previous face's. Reading this back gives the same vertices, corners and attributes.
// Only UV set 0 and colour set 0 are written (OBJ has one of each); a vertex's colour is its first wedge's.
std::string write_obj(const Asset& asset, const std::filesystem::path& path) {
  Mesh storage;
  const Mesh& m = parse::single_mesh(asset, storage);
  parse::check_writable(m, path);
  const std::size_t nv = m.vertex_count(), nw = m.wedge_count();
  const bool uv = parse::has_uvs(m), normal = parse::has_normals(m), color = parse::has_colors(m);

  std::string out;
  out.reserve(nv * 40 + (uv ? nw * 24 : 0) + (normal ? nw * 36 : 0) + m.corner_count() * 20);
  out += "# written by lodforge\n";
  for (const std::string& lib : asset.obj_mtllibs) out += "mtllib " + lib + "\n";

  const std::vector<std::uint32_t> first_wedge = color ? parse::first_wedge_of_vertex(m) : std::vector<std::uint32_t>{};
  const bool alpha = color && !m.color_components.empty() && m.color_components[0] == 4;
  for (std::size_t v = 0; v < nv; ++v) {
    out += "v ";
    for (int i = 0; i < 3; ++i) {
      if (i) out += ' ';
      parse::append_real(out, m.positions[v][i]);
    }
    if (color) {
      const Vec4f c = first_wedge[v] == kInvalidIndex ? Vec4f{{1, 1, 1, 1}} : m.colors[0][first_wedge[v]];
      for (int i = 0; i < (alpha ? 4 : 3); ++i) {
        out += ' ';
        parse::append_real(out, c[i]);
      }
    }
    out += '\n';
  }
  for (std::size_t w = 0; uv && w < nw; ++w) {
    out += "vt ";
    parse::append_real(out, m.uvs[0][w][0]);
    out += ' ';
    parse::append_real(out, m.uvs[0][w][1]);
    out += '\n';
  }
  for (std::size_t w = 0; normal && w < nw; ++w) {
    out += "vn ";
    for (int i = 0; i < 3; ++i) {
      if (i) out += ' ';
      parse::append_real(out, m.normals[w][i]);
    }
    out += '\n';
  }

  const bool groups = uses_groups(m);
  std::uint32_t group = kInvalidIndex, material = kInvalidIndex;
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    if (groups && m.face_group[f] != group) {
      group = m.face_group[f];
      const std::string& name = group < m.groups.size() ? m.groups[group] : std::string();
      out += name.empty() ? "g\n" : "g " + name + "\n";
    }
    const std::uint32_t mat = f < m.face_material.size() ? m.face_material[f] : 0;
    if (mat != material) {
      const std::string& name = mat < m.materials.size() ? m.materials[mat].name : std::string();
      // The reader starts in the unnamed default slot, so a leading unnamed run needs no statement.
      if (!(material == kInvalidIndex && name.empty())) out += name.empty() ? "usemtl\n" : "usemtl " + name + "\n";
      material = mat;
    }
    out += 'f';
    for (std::uint32_t c = m.face_offsets[f]; c < m.face_offsets[f + 1]; ++c) {
      const std::uint32_t w = m.corner_wedge[c];
      out += ' ';
      parse::append_uint(out, m.wedge_vertex[w] + 1ull);
      if (uv || normal) {
        out += '/';
        if (uv) parse::append_uint(out, w + 1ull);
        if (normal) {
          out += '/';
          parse::append_uint(out, w + 1ull);
        }
      }
    }
    out += '\n';
  }
  return out;
}

}  // namespace lodforge::io
