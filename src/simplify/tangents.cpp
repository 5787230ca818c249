// Tangents of a LOD, recomputed from its normals and UV set 0.
#include <cmath>
#include <vector>

#include "engines.hpp"

namespace lodforge::collapse {

// Tangents of the LOD from its normals and UV set 0 (tangents are not simplified):
// per-triangle UV-space derivatives accumulated per wedge (area-weighted, as MikkTSpace does before its
// splitting rules), Gram-Schmidt against the wedge normal, handedness from the bitangent. A wedge without
// usable UVs keeps its carried tangent.
void recompute_tangents(Mesh& mesh) {
  const std::size_t nw = mesh.wedge_count();
  if (mesh.tangents.size() != nw || mesh.normals.size() != nw || mesh.uvs.empty() || mesh.uvs[0].size() != nw) return;
  const std::vector<Vec2f>& uv = mesh.uvs[0];
  std::vector<Vec3d> tan(nw, Vec3d{}), bit(nw, Vec3d{});
  // Polygons (the polychord engine's quads) count as the triangles they are drawn as.
  auto add = [&](std::uint32_t c0, std::uint32_t c1, std::uint32_t c2) {
    const std::uint32_t w[3] = {mesh.corner_wedge[c0], mesh.corner_wedge[c1], mesh.corner_wedge[c2]};
    const Vec3d p0 = to_double(mesh.positions[mesh.wedge_vertex[w[0]]]);
    const Vec3d e1 = to_double(mesh.positions[mesh.wedge_vertex[w[1]]]) - p0;
    const Vec3d e2 = to_double(mesh.positions[mesh.wedge_vertex[w[2]]]) - p0;
    const double s1 = double{uv[w[1]][0]} - uv[w[0]][0], t1 = double{uv[w[1]][1]} - uv[w[0]][1];
    const double s2 = double{uv[w[2]][0]} - uv[w[0]][0], t2 = double{uv[w[2]][1]} - uv[w[0]][1];
    const double det = s1 * t2 - s2 * t1;
    if (!(std::abs(det) > 0.0) || !std::isfinite(det)) return;
    // Unnormalised (× det² / |det|): each face contributes in proportion to its 3-D area.
    const double sign = det > 0.0 ? 1.0 : -1.0;
    const Vec3d tf = (e1 * t2 - e2 * t1) * sign;
    const Vec3d bf = (e2 * s1 - e1 * s2) * sign;
    for (int j = 0; j < 3; ++j) {
      tan[w[j]] = tan[w[j]] + tf;
      bit[w[j]] = bit[w[j]] + bf;
    }
  };
  for (std::size_t f = 0; f < mesh.face_count(); ++f) for_each_face_triangle(mesh, f, add);
  for (std::size_t w = 0; w < nw; ++w) {
    const Vec3d n = to_double(mesh.normals[w]);
    const Vec3d t = tan[w] - n * dot(n, tan[w]);
    const double len = length(t);
    if (!(len > 0.0) || !std::isfinite(len)) continue;
    const Vec3d unit = t * (1.0 / len);
    const double hand = dot(cross(n, unit), bit[w]) < 0.0 ? -1.0 : 1.0;
    mesh.tangents[w] = {{static_cast<float>(unit[0]), static_cast<float>(unit[1]), static_cast<float>(unit[2]),
                         static_cast<float>(hand)}};
  }
}

}  // namespace lodforge::collapse
