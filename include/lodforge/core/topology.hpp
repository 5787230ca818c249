// Connectivity built on demand from the face list: undirected edges with their incident faces.
// Works on any polygon soup, manifold or not (non-manifold edges simply have more than two faces).
#pragma once

#include <cstdint>
#include <vector>

#include "lodforge/core/mesh.hpp"

namespace lodforge {

struct Topology {
  // Undirected edges, v0 < v1, sorted lexicographically (deterministic).
  std::vector<std::array<std::uint32_t, 2>> edges;
  // Incident corners per edge in CSR form: corners of edge e are edge_corner[edge_corner_offsets[e] ..
  // edge_corner_offsets[e+1]); corner c is the start of the face side (c -> next corner of its face).
  std::vector<std::uint32_t> edge_corner_offsets;
  std::vector<std::uint32_t> edge_corner;
  // Edge of each corner's outgoing side.
  std::vector<std::uint32_t> corner_edge;

  std::size_t edge_count() const { return edges.size(); }
  std::uint32_t edge_valence(std::size_t e) const { return edge_corner_offsets[e + 1] - edge_corner_offsets[e]; }
};

// Faces with out-of-range vertex indices or fewer than 3 corners must not be passed (see validate()).
// Sides whose two corners name the same vertex (degenerate) get no edge: corner_edge is kInvalidIndex.
Topology build_topology(const Mesh& mesh);

struct TopologySummary {
  std::size_t referenced_vertices = 0;
  std::size_t edges = 0;
  std::size_t faces = 0;
  std::size_t boundary_edges = 0;       // edges with exactly one face
  std::size_t non_manifold_edges = 0;   // edges with more than two faces
  std::size_t non_manifold_vertices = 0;  // vertices whose face fan is not a single disc or half-disc
  std::size_t inconsistent_edges = 0;   // two-face edges traversed in the same direction by both faces
  std::size_t boundary_loops = 0;
  std::size_t components = 0;           // face-connected components (sharing an edge or a vertex)
  long long euler_characteristic = 0;   // V - E + F over referenced vertices
  bool closed_manifold() const {
    return boundary_edges == 0 && non_manifold_edges == 0 && non_manifold_vertices == 0;
  }
};

TopologySummary summarize_topology(const Mesh& mesh, const Topology& topo);

// Per vertex, 1 where the mesh is not a manifold there: its faces form several fans (the summary's
// non-manifold vertices), or it lies on an edge with more than two faces or on a two-face edge both faces
// traverse in the same direction.
std::vector<std::uint8_t> irregular_vertices(const Mesh& mesh, const Topology& topo);

}  // namespace lodforge
