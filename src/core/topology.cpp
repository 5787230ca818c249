#include "lodforge/core/topology.hpp"

#include <algorithm>
#include <numeric>

#include "lodforge/core/union_find.hpp"

namespace lodforge {
namespace {

// Corner of face f that follows corner c (cyclically).
inline std::uint32_t next_corner(const Mesh& m, std::uint32_t f, std::uint32_t c) {
  return c + 1 == m.face_offsets[f + 1] ? m.face_offsets[f] : c + 1;
}

// The face of every corner.
std::vector<std::uint32_t> corner_faces(const Mesh& mesh) {
  std::vector<std::uint32_t> corner_face(mesh.corner_count());
  for (std::uint32_t f = 0; f < mesh.face_count(); ++f) {
    for (std::uint32_t c = mesh.face_offsets[f]; c < mesh.face_offsets[f + 1]; ++c) corner_face[c] = f;
  }
  return corner_face;
}

// Corners around each vertex joined into fans across its two-face edges; `edge(e, valence, consistent)` is
// called for every edge (consistent: a two-face edge its faces traverse in opposite directions).
template <class EdgeVisitor>
UnionFind fans_of(const Mesh& mesh, const Topology& topo, const std::vector<std::uint32_t>& corner_face,
                  EdgeVisitor&& edge) {
  UnionFind fans(mesh.corner_count());
  for (std::size_t e = 0; e < topo.edge_count(); ++e) {
    const std::uint32_t val = topo.edge_valence(e);
    const std::uint32_t* cs = &topo.edge_corner[topo.edge_corner_offsets[e]];
    if (val != 2) {
      edge(e, val, false);
      continue;
    }
    const std::uint32_t c0 = cs[0], c1 = cs[1];
    const std::uint32_t n0 = next_corner(mesh, corner_face[c0], c0), n1 = next_corner(mesh, corner_face[c1], c1);
    const bool same_direction = mesh.corner_vertex(c0) == mesh.corner_vertex(c1);
    if (same_direction) {
      fans.unite(c0, c1);
      fans.unite(n0, n1);
    } else {
      fans.unite(c0, n1);
      fans.unite(n0, c1);
    }
    edge(e, val, !same_direction);
  }
  return fans;
}

// Per vertex, 1 where its corners form more than one fan.
std::vector<std::uint8_t> several_fans(const Mesh& mesh, UnionFind& fans) {
  const std::size_t nv = mesh.vertex_count();
  std::vector<std::uint32_t> fan_root(nv, kInvalidIndex);
  std::vector<std::uint8_t> several(nv, 0);
  for (std::uint32_t c = 0; c < mesh.corner_count(); ++c) {
    const std::uint32_t v = mesh.corner_vertex(c);
    const std::uint32_t r = fans.find(c);
    if (fan_root[v] == kInvalidIndex) fan_root[v] = r;
    else if (fan_root[v] != r) several[v] = 1;
  }
  return several;
}

}  // namespace

Topology build_topology(const Mesh& mesh) {
  Topology t;
  const std::size_t nc = mesh.corner_count();
  // (min vertex, max vertex) packed into 64 bits, with the corner, in (key, corner) order: that groups the
  // sides of each edge. A counting pass by the lower vertex (corners stay in order within each) and a sort
  // of each vertex's few sides give that order in linear time; ids far beyond the positions (a mesh not yet
  // validated) take a plain sort.
  std::vector<std::pair<std::uint64_t, std::uint32_t>> sides;
  sides.reserve(nc);
  t.corner_edge.assign(nc, kInvalidIndex);
  std::uint32_t highest = 0;
  for (std::uint32_t f = 0; f < mesh.face_count(); ++f) {
    for (std::uint32_t c = mesh.face_offsets[f]; c < mesh.face_offsets[f + 1]; ++c) {
      const std::uint32_t a = mesh.corner_vertex(c), b = mesh.corner_vertex(next_corner(mesh, f, c));
      if (a == b) continue;
      const std::uint32_t lo = std::min(a, b);
      highest = std::max(highest, lo);
      sides.emplace_back((std::uint64_t{lo} << 32) | std::max(a, b), c);
    }
  }
  if (highest > mesh.vertex_count() + nc) {
    std::sort(sides.begin(), sides.end());
  } else {
    std::vector<std::uint32_t> end(std::size_t{highest} + 2, 0);
    for (const auto& side : sides) ++end[(side.first >> 32) + 1];
    for (std::size_t v = 1; v < end.size(); ++v) end[v] += end[v - 1];
    std::vector<std::pair<std::uint64_t, std::uint32_t>> sorted(sides.size());
    for (const auto& side : sides) sorted[end[side.first >> 32]++] = side;  // end[v]: now the end of v's sides
    for (std::size_t v = 0, begin = 0; v + 1 < end.size(); ++v) {
      if (end[v] - begin > 1) {
        std::sort(sorted.begin() + static_cast<std::ptrdiff_t>(begin), sorted.begin() + static_cast<std::ptrdiff_t>(end[v]));
      }
      begin = end[v];
    }
    sides = std::move(sorted);
  }
  t.edge_corner.reserve(sides.size());
  t.edge_corner_offsets.reserve(sides.size() / 2 + 2);
  for (std::size_t i = 0; i < sides.size();) {
    const std::uint64_t key = sides[i].first;
    const auto e = static_cast<std::uint32_t>(t.edges.size());
    t.edges.push_back({static_cast<std::uint32_t>(key >> 32), static_cast<std::uint32_t>(key & 0xffffffffu)});
    t.edge_corner_offsets.push_back(static_cast<std::uint32_t>(t.edge_corner.size()));
    for (; i < sides.size() && sides[i].first == key; ++i) {
      t.edge_corner.push_back(sides[i].second);
      t.corner_edge[sides[i].second] = e;
    }
  }
  t.edge_corner_offsets.push_back(static_cast<std::uint32_t>(t.edge_corner.size()));
  return t;
}

TopologySummary summarize_topology(const Mesh& mesh, const Topology& topo) {
  TopologySummary s;
  const std::size_t nv = mesh.vertex_count(), nc = mesh.corner_count();
  const std::vector<std::uint32_t> corner_face = corner_faces(mesh);
  for (std::uint32_t f = 0; f < mesh.face_count(); ++f) {
    if (mesh.face_size(f) >= 3) ++s.faces;
  }
  std::vector<char> referenced(nv, 0);
  for (std::size_t c = 0; c < nc; ++c) referenced[mesh.corner_vertex(c)] = 1;
  s.referenced_vertices = static_cast<std::size_t>(std::count(referenced.begin(), referenced.end(), 1));
  s.edges = topo.edge_count();

  UnionFind boundary(nv);       // vertices joined along boundary edges
  UnionFind components(nv);     // vertices joined by faces
  std::vector<char> on_boundary(nv, 0);
  UnionFind fans = fans_of(mesh, topo, corner_face, [&](std::size_t e, std::uint32_t val, bool consistent) {
    if (val == 1) {
      ++s.boundary_edges;
      boundary.unite(topo.edges[e][0], topo.edges[e][1]);
      on_boundary[topo.edges[e][0]] = on_boundary[topo.edges[e][1]] = 1;
    } else if (val > 2) {
      ++s.non_manifold_edges;
    } else if (!consistent) {
      ++s.inconsistent_edges;
    }
  });
  // A vertex is manifold when all its corners form one fan.
  const std::vector<std::uint8_t> non_manifold = several_fans(mesh, fans);
  s.non_manifold_vertices = static_cast<std::size_t>(std::count(non_manifold.begin(), non_manifold.end(), 1));

  for (std::uint32_t f = 0; f < mesh.face_count(); ++f) {
    for (std::uint32_t c = mesh.face_offsets[f] + 1; c < mesh.face_offsets[f + 1]; ++c) {
      components.unite(mesh.corner_vertex(mesh.face_offsets[f]), mesh.corner_vertex(c));
    }
  }
  for (std::uint32_t v = 0; v < nv; ++v) {
    if (referenced[v] && components.find(v) == v) ++s.components;
    if (on_boundary[v] && boundary.find(v) == v) ++s.boundary_loops;
  }
  s.euler_characteristic = static_cast<long long>(s.referenced_vertices) - static_cast<long long>(s.edges) +
                           static_cast<long long>(s.faces);
  return s;
}

std::vector<std::uint8_t> irregular_vertices(const Mesh& mesh, const Topology& topo) {
  const std::vector<std::uint32_t> corner_face = corner_faces(mesh);
  std::vector<std::uint32_t> bad_edges;
  UnionFind fans = fans_of(mesh, topo, corner_face, [&](std::size_t e, std::uint32_t val, bool consistent) {
    if (val > 2 || (val == 2 && !consistent)) bad_edges.push_back(static_cast<std::uint32_t>(e));
  });
  std::vector<std::uint8_t> irregular = several_fans(mesh, fans);
  for (std::uint32_t e : bad_edges) irregular[topo.edges[e][0]] = irregular[topo.edges[e][1]] = 1;
  return irregular;
}

}  // namespace lodforge
