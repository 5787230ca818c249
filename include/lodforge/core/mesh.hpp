// The lodforge mesh model: struct-of-arrays geometry with explicit attribute seams.
//
//   vertex  – a welded position (plus what must move with it: skin, morph position deltas, priority).
//   wedge   – one render vertex: a vertex plus a tuple of corner attributes (normal, tangent, UVs, colours,
//             custom attributes, morph normal/tangent deltas). A vertex with several wedges sits on a seam.
//   face    – a polygon (triangle, quad or n-gon) given as a run of corners; each corner names a wedge.
//             face_offsets has faces+1 entries; the corners of face f are [face_offsets[f], face_offsets[f+1]).
//
// Why skin, morph position deltas and the priority weight are keyed into the vertex: two render vertices at
// the same rest position but bound to different bones (or moved by a morph target) separate when animated, so
// they are not the same point of the surface and must not be welded. Everything else is a wedge attribute.
#pragma once

#include <array>
#include <cstdint>
#include <initializer_list>
#include <map>
#include <optional>
#include <string>
#include <span>
#include <vector>

#include "lodforge/core/vec.hpp"

namespace lodforge {

inline constexpr std::uint32_t kInvalidIndex = 0xffffffffu;
inline constexpr int kMaxInfluences = 8;

// How an attribute was stored in its source file, so writers can store it the same way (lossless round trip).
// component_type uses the glTF codes: 5120 int8, 5121 uint8, 5122 int16, 5123 uint16, 5125 uint32, 5126 float.
struct AttributeFormat {
  int component_type = 5126;
  bool normalized = false;
  friend bool operator==(const AttributeFormat&, const AttributeFormat&) = default;
};

// A per-wedge attribute lodforge has no special meaning for (glTF `_FOO`, extra TEXCOORD sets beyond the
// modelled ones are *not* here: every TEXCOORD_n is a UV set). Carried through unchanged.
struct CustomAttribute {
  std::string name;      // glTF semantic, e.g. "_BATCHID"
  int components = 1;    // 1..4 (SCALAR..VEC4) or 16 (MAT4)
  AttributeFormat format;
  std::vector<float> values;  // wedge_count() * components
  friend bool operator==(const CustomAttribute&, const CustomAttribute&) = default;
};

struct MorphTarget {
  std::string name;
  std::vector<Vec3f> position_deltas;  // per wedge, or empty (identical for all wedges of a vertex)
  std::vector<Vec3f> normal_deltas;    // per wedge, or empty
  std::vector<Vec3f> tangent_deltas;   // per wedge, or empty
  friend bool operator==(const MorphTarget&, const MorphTarget&) = default;
};

// Up to kMaxInfluences joint influences of one vertex. Unused slots have weight 0.
struct SkinInfluences {
  std::array<std::uint16_t, kMaxInfluences> joints{};
  std::array<float, kMaxInfluences> weights{};
  friend bool operator==(const SkinInfluences&, const SkinInfluences&) = default;
};

// A face group with one material (a glTF primitive, an OBJ `usemtl` run, ...).
struct MaterialSlot {
  std::string name;         // OBJ material name or glTF material name
  int gltf_material = -1;   // index into the glTF document's materials, -1 if none
  int source_primitive = -1;  // glTF primitive index inside its mesh, -1 for other formats
  // Which wedge streams this slot's faces really carry (glTF primitives of one mesh may differ).
  bool has_normals = true;
  bool has_tangents = true;
  int uv_sets = -1;         // -1 = all of the mesh's UV sets
  int color_sets = -1;      // -1 = all of the mesh's colour sets
  bool has_custom = true;
  bool has_morphs = true;
  friend bool operator==(const MaterialSlot&, const MaterialSlot&) = default;
};

struct Mesh {
  // --- vertices (welded) ---
  std::vector<Vec3f> positions;
  std::vector<SkinInfluences> skin;  // per vertex, or empty
  std::vector<float> priority;       // per vertex painted LOD priority (glTF _LOD_PRIORITY), or empty

  // --- wedges (render vertices) ---
  std::vector<std::uint32_t> wedge_vertex;      // vertex of each wedge
  std::vector<Vec3f> normals;                   // per wedge, or empty
  std::vector<Vec4f> tangents;                  // per wedge (xyz, w = handedness), or empty
  std::vector<std::vector<Vec2f>> uvs;          // uvs[set][wedge]
  std::vector<std::vector<Vec4f>> colors;       // colors[set][wedge], RGBA (alpha 1 when stored as RGB)
  std::vector<int> color_components;            // 3 or 4 per colour set
  std::vector<CustomAttribute> custom;
  std::vector<MorphTarget> morph_targets;
  std::vector<double> morph_default_weights;

  // --- faces ---
  std::vector<std::uint32_t> face_offsets{0};  // faces + 1 entries
  std::vector<std::uint32_t> corner_wedge;     // wedge of each corner
  std::vector<std::uint32_t> face_material;    // per face index into materials
  std::vector<std::uint32_t> face_group;       // per face index into groups (OBJ g/o), or empty
  std::vector<MaterialSlot> materials;
  std::vector<std::string> groups;

  // Source formats of attribute streams by glTF semantic ("NORMAL", "TEXCOORD_1", "COLOR_0", "JOINTS_0", ...).
  std::map<std::string, AttributeFormat> formats;
  std::string name;

  // --- sizes and accessors ---
  std::size_t vertex_count() const { return positions.size(); }
  std::size_t wedge_count() const { return wedge_vertex.size(); }
  std::size_t face_count() const { return face_offsets.empty() ? 0 : face_offsets.size() - 1; }
  std::size_t corner_count() const { return corner_wedge.size(); }
  std::uint32_t face_size(std::size_t f) const { return face_offsets[f + 1] - face_offsets[f]; }
  std::uint32_t corner_vertex(std::size_t c) const { return wedge_vertex[corner_wedge[c]]; }
  // Triangles after triangulating every polygon (a k-gon gives k - 2).
  std::size_t triangle_count() const;

  // Append a face of `wedges.size()` corners; returns the new face index.
  std::uint32_t add_face(std::initializer_list<std::uint32_t> wedges, std::uint32_t material = 0);
  std::uint32_t add_face(const std::uint32_t* wedges, std::size_t n, std::uint32_t material = 0);
  // Append a vertex with one wedge (no attributes set yet); returns the wedge index.
  std::uint32_t add_vertex_with_wedge(const Vec3f& p);

  friend bool operator==(const Mesh&, const Mesh&) = default;
};

struct FaceKindCounts {
  std::size_t triangles = 0, quads = 0, polygons = 0;  // polygons = more than 4 corners
};
FaceKindCounts count_face_kinds(const Mesh& mesh);

Bounds3 compute_bounds(const Mesh& mesh);

// Area-weighted normal direction (not normalised) of a polygon of `count` corners by Newell's method, corner i
// at point(i) (a Vec3d). For polygons held in other forms (the quad part's working mesh, weld candidates).
template <class Point>
Vec3d newell_normal(std::size_t count, Point&& point) {
  Vec3d n{};
  for (std::size_t i = 0; i < count; ++i) {
    const Vec3d& a = point(i);
    const Vec3d& b = point((i + 1) % count);
    n[0] += (a[1] - b[1]) * (a[2] + b[2]);
    n[1] += (a[2] - b[2]) * (a[0] + b[0]);
    n[2] += (a[0] - b[0]) * (a[1] + b[1]);
  }
  return n;
}

// Area-weighted face normal direction (not normalised) of polygon f, by Newell's method.
Vec3d face_normal_newell(const Mesh& mesh, std::size_t f);

// How every part turns a polygon into triangles (glTF output, evaluation, the triangle engine and
// triangulated() all see the same triangles): a quad splits along its shorter diagonal, the one through its
// first corner on a tie, so a bent quad folds where a modeller expects and the fold does not depend on which
// corner a file happened to list first; larger polygons fan from their first corner. Returns the corner
// (0 or 1 for quads, else 0) that the fan of face f starts from.
std::uint32_t triangulation_start(const Mesh& mesh, std::size_t f);
// The same rule for a quad given by its corner positions (for meshes held in another form).
inline std::uint32_t quad_triangulation_start(const Vec3d& p0, const Vec3d& p1, const Vec3d& p2, const Vec3d& p3) {
  const Vec3d d02 = p2 - p0, d13 = p3 - p1;
  return dot(d13, d13) < dot(d02, d02) ? 1 : 0;  // written so that NaN lengths keep the first corner
}

// Calls emit(c0, c1, c2) with the corner offsets (into corner_wedge) of each triangle of face f, in the
// face's winding, as triangulation_start() describes.
template <class Emit>
void for_each_face_triangle(const Mesh& mesh, std::size_t f, Emit&& emit) {
  const std::uint32_t begin = mesh.face_offsets[f], k = mesh.face_size(f);
  const std::uint32_t s = triangulation_start(mesh, f);
  for (std::uint32_t i = 1; i + 1 < k; ++i) emit(begin + s, begin + (s + i) % k, begin + (s + i + 1) % k);
}

// Whether every corner of face f lies inside corner_wedge and names an existing wedge of an existing vertex
// (faces failing this carry no surface: QuadMesh drops them).
bool face_indices_in_range(const Mesh& mesh, std::size_t f);

// Three vertex indices per triangle of the whole mesh, as for_each_face_triangle() makes them.
std::vector<std::uint32_t> triangle_vertex_indices(const Mesh& mesh);

// Arrays that replace the source mesh's in compact_vertices_and_wedges(): a null pointer, or an empty UV or
// colour set, means the source's own.
struct AttributeOverrides {
  const std::vector<std::uint32_t>* wedge_vertex = nullptr;         // per wedge: its vertex now (after welds)
  const std::vector<SkinInfluences>* skin = nullptr;                // per vertex
  const std::vector<Vec3f>* normals = nullptr;                      // per wedge
  const std::vector<std::vector<Vec2f>>* uvs = nullptr;             // per set, per wedge
  const std::vector<std::vector<Vec4f>>* colors = nullptr;          // per set, per wedge
  const std::vector<MorphTarget>* morph_targets = nullptr;
};

// The vertices and wedges of `m` that a simplified face list still uses, renumbered in ascending order: what
// the engines' outputs share. On entry wedge_map (one entry per wedge of m) marks the used wedges with any
// value but kInvalidIndex; on return it holds their new ids. `vertices` receives the source vertex of each
// output vertex. The result has m's name, materials, groups, formats, morph default weights and every vertex
// and wedge array (positions as in m: callers write the moved ones), and no faces.
Mesh compact_vertices_and_wedges(const Mesh& m, std::vector<std::uint32_t>& wedge_map,
                                 std::vector<std::uint32_t>& vertices, const AttributeOverrides& overrides = {});

// Faces that repeat an earlier face: the same corner vertices in the same cyclic order (from any corner) and
// the same material. Such a face draws nothing the earlier one does not (exporters write some twice: the
// corpus's MakeHuman hair has 152), but it makes each of its edges non-manifold, which stops the simplifiers
// around it. Ascending ids; faces with a repeated vertex or an out-of-range index are never listed, nor a
// face wound the other way (a back face is drawn differently). `threads`: 0 = the current arena's, 1 = this
// thread only; the result is the same for any value.
std::vector<std::uint32_t> repeated_faces(const Mesh& mesh, unsigned threads = 0);

// A copy of `mesh` without the listed faces (ascending ids); vertices and wedges stay as they are.
Mesh without_faces(const Mesh& mesh, std::span<const std::uint32_t> faces);

// Returns a mesh whose faces are all triangles (as for_each_face_triangle() makes them); every other array
// is shared unchanged. `triangle_face` (optional) receives the source face of each triangle.
Mesh triangulated(const Mesh& mesh, std::vector<std::uint32_t>* triangle_face = nullptr);

}  // namespace lodforge
