// Quad fraction and irregular (valence != 4) interior vertices, the two numbers that say whether an LOD still
// has an artist's edge flow: a regular quad grid has valence 4 everywhere inside.
#include "lodforge/quad/quad_stats.hpp"

#include <algorithm>
#include <utility>
#include <vector>

namespace lodforge::quad {

QuadStats quad_stats(const Mesh& mesh) {
  QuadStats s;
  const FaceKindCounts kinds = count_face_kinds(mesh);
  s.faces = mesh.face_count();
  s.quads = kinds.quads;
  s.triangles = kinds.triangles;
  s.polygons = kinds.polygons;
  s.quad_fraction = s.faces > 0 ? static_cast<double>(s.quads) / static_cast<double>(s.faces) : 0.0;

  // Undirected edges with their face counts; a vertex on an edge with other than two faces is not interior.
  const std::size_t nv = mesh.vertex_count();
  std::vector<std::pair<std::uint32_t, std::uint32_t>> sides;
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    const std::uint32_t b = mesh.face_offsets[f], n = mesh.face_size(f);
    if (n < 3) continue;
    bool ok = true;
    for (std::uint32_t i = 0; i < n && ok; ++i) {
      ok = mesh.corner_wedge[b + i] < mesh.wedge_count() && mesh.corner_vertex(b + i) < nv;
    }
    if (!ok) continue;
    for (std::uint32_t i = 0; i < n; ++i) {
      std::uint32_t a = mesh.corner_vertex(b + i), c = mesh.corner_vertex(b + (i + 1) % n);
      if (a == c) continue;
      sides.emplace_back(std::min(a, c), std::max(a, c));
    }
  }
  std::sort(sides.begin(), sides.end());
  std::vector<std::uint32_t> valence(nv, 0);
  std::vector<std::uint8_t> referenced(nv, 0), border(nv, 0);
  for (std::size_t i = 0; i < sides.size();) {
    std::size_t j = i;
    while (j < sides.size() && sides[j] == sides[i]) ++j;
    const auto [a, c] = sides[i];
    ++valence[a];
    ++valence[c];
    referenced[a] = referenced[c] = 1;
    if (j - i != 2) border[a] = border[c] = 1;
    i = j;
  }
  for (std::size_t v = 0; v < nv; ++v) {
    if (!referenced[v] || border[v]) continue;
    ++s.interior_vertices;
    if (valence[v] != 4) ++s.irregular_vertices;
  }
  return s;
}

}  // namespace lodforge::quad
