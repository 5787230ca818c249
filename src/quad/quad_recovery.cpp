// Quad recovery from triangulated input: greedy pairing of triangles across soft diagonals (the "BitQuad"
// view of Tarini et al., "Practical quad mesh simplification", EG 2010, read backwards: a quad is two
// triangles joined by a faux diagonal, and the faux diagonals are the ones to find).
#include "lodforge/quad/quad_recovery.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <tuple>
#include <vector>

#include "lodforge/core/topology.hpp"

namespace lodforge::quad {
namespace {

double angle_deg(const Vec3d& u, const Vec3d& v) {
  const double lu = length(u), lv = length(v);
  if (!(lu > 0.0 && lv > 0.0)) return 0.0;
  return std::acos(std::clamp(dot(u, v) / (lu * lv), -1.0, 1.0)) * 180.0 / std::numbers::pi;
}

struct Pair {
  double score;
  std::uint32_t edge;
  std::uint32_t f1, f2;         // triangles a-b-c (f1) and b-a-d (f2)
  std::array<std::uint32_t, 4> wedges;  // quad a-d-b-c
};

}  // namespace

Mesh recover_quads(const Mesh& mesh, const QuadRecoveryOptions& options, std::size_t* quads_made) {
  if (quads_made) *quads_made = 0;
  // build_topology needs valid indices; a mesh with bad ones is returned as it is (validate() reports it).
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    if (mesh.face_size(f) < 3) return mesh;
  }
  for (std::uint32_t w : mesh.corner_wedge) {
    if (w >= mesh.wedge_count() || mesh.wedge_vertex[w] >= mesh.vertex_count()) return mesh;
  }
  if (mesh.face_material.size() != mesh.face_count()) return mesh;
  const Topology topo = build_topology(mesh);
  const bool groups = mesh.face_group.size() == mesh.face_count();
  std::vector<std::uint32_t> corner_face(mesh.corner_count());
  for (std::uint32_t f = 0; f < mesh.face_count(); ++f) {
    for (std::uint32_t c = mesh.face_offsets[f]; c < mesh.face_offsets[f + 1]; ++c) corner_face[c] = f;
  }
  auto pos = [&](std::uint32_t corner) { return to_double(mesh.positions[mesh.corner_vertex(corner)]); };
  auto next = [&](std::uint32_t c) {
    const std::uint32_t f = corner_face[c];
    return c + 1 == mesh.face_offsets[f + 1] ? mesh.face_offsets[f] : c + 1;
  };

  std::vector<Pair> pairs;
  for (std::uint32_t e = 0; e < topo.edge_count(); ++e) {
    if (topo.edge_valence(e) != 2) continue;
    const std::uint32_t c1 = topo.edge_corner[topo.edge_corner_offsets[e]];
    const std::uint32_t c2 = topo.edge_corner[topo.edge_corner_offsets[e] + 1];
    const std::uint32_t f1 = corner_face[c1], f2 = corner_face[c2];
    if (mesh.face_size(f1) != 3 || mesh.face_size(f2) != 3 || f1 == f2) continue;
    if (mesh.face_material[f1] != mesh.face_material[f2]) continue;
    if (groups && mesh.face_group[f1] != mesh.face_group[f2]) continue;
    // c1: a -> b in f1; c2 must be b -> a in f2 (consistent orientation).
    const std::uint32_t c1b = next(c1), c1c = next(c1b), c2a = next(c2), c2d = next(c2a);
    if (mesh.corner_vertex(c2) != mesh.corner_vertex(c1b) || mesh.corner_vertex(c2a) != mesh.corner_vertex(c1)) continue;
    if (mesh.corner_wedge[c2] != mesh.corner_wedge[c1b] || mesh.corner_wedge[c2a] != mesh.corner_wedge[c1]) continue;
    if (mesh.corner_vertex(c1c) == mesh.corner_vertex(c2d)) continue;
    // The quad's other diagonal must not be an edge already: outputs split a quad along its shorter diagonal,
    // and that edge would then get three triangles.
    {
      const std::uint32_t x = mesh.corner_vertex(c1c), y = mesh.corner_vertex(c2d);
      if (std::binary_search(topo.edges.begin(), topo.edges.end(), std::array{std::min(x, y), std::max(x, y)})) continue;
    }
    const Vec3d a = pos(c1), b = pos(c1b), c = pos(c1c), d = pos(c2d);
    const Vec3d n1 = cross(b - a, c - a), n2 = cross(a - b, d - b);
    const double dihedral = angle_deg(n1, n2);
    if (!(dihedral <= options.max_dihedral_deg)) continue;
    const double diagonal = dot(b - a, b - a);
    if (diagonal < dot(c - b, c - b) || diagonal < dot(a - c, a - c) || diagonal < dot(d - a, d - a) ||
        diagonal < dot(b - d, b - d)) {
      continue;
    }
    if (options.keep_triangles && quad_triangulation_start(a, d, b, c) != 0) continue;
    // Quad a-d-b-c: corner angles.
    const std::array<Vec3d, 4> q{a, d, b, c};
    double deviation = 0.0;
    bool ok = true;
    for (int i = 0; i < 4 && ok; ++i) {
      const double ang = angle_deg(q[(i + 1) % 4] - q[i], q[(i + 3) % 4] - q[i]);
      ok = ang >= options.min_corner_deg && ang <= 180.0 - options.min_corner_deg;
      deviation += std::fabs(ang - 90.0);
    }
    // The corners must also turn the same way (a convex quad): the two triangles' normals agree (checked)
    // and each corner of the quad turns like the quad's normal.
    const Vec3d n = n1 + n2;
    for (int i = 0; i < 4 && ok; ++i) ok = dot(cross(q[(i + 1) % 4] - q[i], q[(i + 3) % 4] - q[i]), n) > 0.0;
    if (!ok) continue;
    pairs.push_back({dihedral + 0.25 * deviation, e, f1, f2,
                     {mesh.corner_wedge[c1], mesh.corner_wedge[c2d], mesh.corner_wedge[c1b], mesh.corner_wedge[c1c]}});
  }
  std::sort(pairs.begin(), pairs.end(),
            [](const Pair& x, const Pair& y) { return std::tie(x.score, x.edge) < std::tie(y.score, y.edge); });

  const std::size_t nf = mesh.face_count();
  std::vector<std::uint8_t> used(nf, 0);
  std::vector<std::uint32_t> replacement(nf, kInvalidIndex);  // pair index placed at this face
  std::vector<std::uint8_t> removed(nf, 0);
  std::size_t made = 0;
  for (std::uint32_t k = 0; k < pairs.size(); ++k) {
    const Pair& p = pairs[k];
    if (used[p.f1] || used[p.f2]) continue;
    used[p.f1] = used[p.f2] = 1;
    replacement[std::min(p.f1, p.f2)] = k;
    removed[std::max(p.f1, p.f2)] = 1;
    ++made;
  }
  if (quads_made) *quads_made = made;

  Mesh out = mesh;
  out.face_offsets.assign(1, 0);
  out.corner_wedge.clear();
  out.face_material.clear();
  out.face_group.clear();
  for (std::uint32_t f = 0; f < nf; ++f) {
    if (removed[f]) continue;
    if (replacement[f] != kInvalidIndex) {
      const auto& w = pairs[replacement[f]].wedges;
      out.corner_wedge.insert(out.corner_wedge.end(), w.begin(), w.end());
    } else {
      out.corner_wedge.insert(out.corner_wedge.end(), mesh.corner_wedge.begin() + mesh.face_offsets[f],
                              mesh.corner_wedge.begin() + mesh.face_offsets[f + 1]);
    }
    out.face_offsets.push_back(static_cast<std::uint32_t>(out.corner_wedge.size()));
    out.face_material.push_back(mesh.face_material[f]);
    if (groups) out.face_group.push_back(mesh.face_group[f]);
  }
  return out;
}

}  // namespace lodforge::quad
