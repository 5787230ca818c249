#include "lodforge/core/mesh.hpp"

#include <cassert>

namespace lodforge {

std::size_t Mesh::triangle_count() const {
  std::size_t n = 0;
  for (std::size_t f = 0; f < face_count(); ++f) {
    const std::uint32_t k = face_size(f);
    if (k >= 3) n += k - 2;
  }
  return n;
}

std::uint32_t Mesh::add_face(const std::uint32_t* wedges, std::size_t n, std::uint32_t material) {
  if (face_offsets.empty()) face_offsets.push_back(0);
  corner_wedge.insert(corner_wedge.end(), wedges, wedges + n);
  face_offsets.push_back(static_cast<std::uint32_t>(corner_wedge.size()));
  face_material.push_back(material);
  return static_cast<std::uint32_t>(face_offsets.size() - 2);
}

std::uint32_t Mesh::add_face(std::initializer_list<std::uint32_t> wedges, std::uint32_t material) {
  return add_face(wedges.begin(), wedges.size(), material);
}

std::uint32_t Mesh::add_vertex_with_wedge(const Vec3f& p) {
  positions.push_back(p);
  wedge_vertex.push_back(static_cast<std::uint32_t>(positions.size() - 1));
  return static_cast<std::uint32_t>(wedge_vertex.size() - 1);
}

FaceKindCounts count_face_kinds(const Mesh& mesh) {
  FaceKindCounts c;
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    const std::uint32_t k = mesh.face_size(f);
    if (k == 3) ++c.triangles;
    else if (k == 4) ++c.quads;
    else if (k > 4) ++c.polygons;
  }
  return c;
}

Bounds3 compute_bounds(const Mesh& mesh) {
  Bounds3 b;
  for (const Vec3f& p : mesh.positions) {
    if (std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2])) b.add(to_double(p));
  }
  return b;
}

Vec3d face_normal_newell(const Mesh& mesh, std::size_t f) {
  Vec3d n{};
  const std::uint32_t begin = mesh.face_offsets[f], end = mesh.face_offsets[f + 1];
  for (std::uint32_t c = begin; c < end; ++c) {
    const std::uint32_t cn = (c + 1 == end) ? begin : c + 1;
    const Vec3d a = to_double(mesh.positions[mesh.corner_vertex(c)]);
    const Vec3d b = to_double(mesh.positions[mesh.corner_vertex(cn)]);
    n[0] += (a[1] - b[1]) * (a[2] + b[2]);
    n[1] += (a[2] - b[2]) * (a[0] + b[0]);
    n[2] += (a[0] - b[0]) * (a[1] + b[1]);
  }
  return n;
}

Mesh triangulated(const Mesh& mesh, std::vector<std::uint32_t>* triangle_face) {
  Mesh out = mesh;
  out.face_offsets.assign(1, 0);
  out.corner_wedge.clear();
  out.face_material.clear();
  out.face_group.clear();
  const std::size_t tris = mesh.triangle_count();
  out.face_offsets.reserve(tris + 1);
  out.corner_wedge.reserve(tris * 3);
  out.face_material.reserve(tris);
  if (!mesh.face_group.empty()) out.face_group.reserve(tris);
  if (triangle_face) {
    triangle_face->clear();
    triangle_face->reserve(tris);
  }
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    for_each_face_triangle(mesh, f, [&](std::uint32_t c0, std::uint32_t c1, std::uint32_t c2) {
      const std::uint32_t tri[3] = {mesh.corner_wedge[c0], mesh.corner_wedge[c1], mesh.corner_wedge[c2]};
      out.add_face(tri, 3, mesh.face_material.empty() ? 0 : mesh.face_material[f]);
      if (!mesh.face_group.empty()) out.face_group.push_back(mesh.face_group[f]);
      if (triangle_face) triangle_face->push_back(static_cast<std::uint32_t>(f));
    });
  }
  return out;
}

std::vector<std::uint32_t> triangle_vertex_indices(const Mesh& mesh) {
  std::vector<std::uint32_t> indices;
  indices.reserve(3 * mesh.triangle_count());
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    for_each_face_triangle(mesh, f, [&](std::uint32_t c0, std::uint32_t c1, std::uint32_t c2) {
      indices.push_back(mesh.corner_vertex(c0));
      indices.push_back(mesh.corner_vertex(c1));
      indices.push_back(mesh.corner_vertex(c2));
    });
  }
  return indices;
}

std::uint32_t triangulation_start(const Mesh& mesh, std::size_t f) {
  if (mesh.face_size(f) != 4) return 0;
  const std::uint32_t c = mesh.face_offsets[f];
  auto at = [&](std::uint32_t i) { return to_double(mesh.positions[mesh.corner_vertex(c + i)]); };
  return quad_triangulation_start(at(0), at(1), at(2), at(3));
}

}  // namespace lodforge
