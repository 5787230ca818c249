#include "lodforge/core/validate.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace lodforge {
namespace {

void note(std::vector<std::string>& messages, std::size_t count, const char* what) {
  if (count > 0) messages.push_back(std::to_string(count) + " " + what);
}

std::size_t check_attribute_sizes(const Mesh& m) {
  std::size_t bad = 0;
  const std::size_t nw = m.wedge_count(), nv = m.vertex_count(), nf = m.face_count();
  auto per = [&](std::size_t size, std::size_t expected, bool optional) {
    if (optional && size == 0) return;
    if (size != expected) ++bad;
  };
  per(m.normals.size(), nw, true);
  per(m.tangents.size(), nw, true);
  for (const auto& s : m.uvs) per(s.size(), nw, false);
  for (const auto& s : m.colors) per(s.size(), nw, false);
  per(m.color_components.size(), m.colors.size(), false);
  for (const auto& a : m.custom) per(a.values.size(), nw * static_cast<std::size_t>(std::max(a.components, 0)), false);
  for (const auto& t : m.morph_targets) {
    per(t.position_deltas.size(), nw, true);
    per(t.normal_deltas.size(), nw, true);
    per(t.tangent_deltas.size(), nw, true);
  }
  per(m.skin.size(), nv, true);
  per(m.priority.size(), nv, true);
  per(m.face_material.size(), nf, false);
  per(m.face_group.size(), nf, true);
  return bad;
}

}  // namespace

bool ValidationReport::ok() const {
  return nonfinite_positions == 0 && out_of_range_indices == 0 && short_faces == 0 && degenerate_faces == 0 &&
         duplicate_faces == 0 && non_manifold_edges == 0 && non_manifold_vertices == 0 &&
         inconsistent_orientation == 0 && attribute_size_errors == 0;
}

ValidationReport validate(const Mesh& m) {
  ValidationReport r;
  for (const Vec3f& p : m.positions) {
    if (!(std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]))) ++r.nonfinite_positions;
  }
  r.attribute_size_errors = check_attribute_sizes(m);

  // Structural index checks first: nothing below may index out of range.
  const std::size_t nw = m.wedge_count(), nv = m.vertex_count(), nc = m.corner_count();
  bool offsets_ok = !m.face_offsets.empty() && m.face_offsets.front() == 0 && m.face_offsets.back() == nc;
  for (std::size_t f = 0; offsets_ok && f < m.face_count(); ++f) offsets_ok = m.face_offsets[f] <= m.face_offsets[f + 1];
  if (!offsets_ok) ++r.out_of_range_indices;
  for (std::uint32_t w : m.corner_wedge) r.out_of_range_indices += w >= nw;
  for (std::uint32_t v : m.wedge_vertex) r.out_of_range_indices += v >= nv;
  if (m.face_material.size() == m.face_count()) {
    for (std::uint32_t mat : m.face_material) r.out_of_range_indices += mat >= m.materials.size();
  }
  if (m.face_group.size() == m.face_count()) {
    for (std::uint32_t g : m.face_group) r.out_of_range_indices += g >= m.groups.size();
  }
  if (r.out_of_range_indices > 0 || !offsets_ok) {
    note(r.messages, r.nonfinite_positions, "vertices with NaN/Inf positions");
    note(r.messages, r.out_of_range_indices, "out-of-range indices (topology not checked)");
    note(r.messages, r.attribute_size_errors, "attribute arrays of the wrong length");
    return r;
  }

  // Faces: short, degenerate (repeated vertex or zero area), duplicate (same vertex set).
  std::vector<std::pair<std::vector<std::uint32_t>, std::uint32_t>> keys;
  keys.reserve(m.face_count());
  std::vector<std::uint32_t> vs;
  for (std::uint32_t f = 0; f < m.face_count(); ++f) {
    const std::uint32_t k = m.face_size(f);
    if (k < 3) {
      ++r.short_faces;
      continue;
    }
    vs.clear();
    for (std::uint32_t c = m.face_offsets[f]; c < m.face_offsets[f + 1]; ++c) vs.push_back(m.corner_vertex(c));
    std::sort(vs.begin(), vs.end());
    const bool repeated = std::adjacent_find(vs.begin(), vs.end()) != vs.end();
    const Vec3d n = face_normal_newell(m, f);
    if (repeated || !(dot(n, n) > 0.0)) ++r.degenerate_faces;
    keys.emplace_back(vs, f);
  }
  std::sort(keys.begin(), keys.end());
  for (std::size_t i = 1; i < keys.size(); ++i) r.duplicate_faces += keys[i].first == keys[i - 1].first;

  const Topology topo = build_topology(m);
  const TopologySummary s = summarize_topology(m, topo);
  r.non_manifold_edges = s.non_manifold_edges;
  r.non_manifold_vertices = s.non_manifold_vertices;
  r.inconsistent_orientation = s.inconsistent_edges;
  r.unreferenced_vertices = nv - s.referenced_vertices;

  note(r.messages, r.nonfinite_positions, "vertices with NaN/Inf positions");
  note(r.messages, r.short_faces, "faces with fewer than 3 corners");
  note(r.messages, r.degenerate_faces, "degenerate faces (repeated vertex or zero area)");
  note(r.messages, r.duplicate_faces, "duplicate faces");
  note(r.messages, r.non_manifold_edges, "non-manifold edges (more than 2 faces)");
  note(r.messages, r.non_manifold_vertices, "non-manifold vertices");
  note(r.messages, r.inconsistent_orientation, "edges with inconsistent face orientation");
  note(r.messages, r.attribute_size_errors, "attribute arrays of the wrong length");
  note(r.messages, r.unreferenced_vertices, "unreferenced vertices (not an error)");
  return r;
}

}  // namespace lodforge
