// Quad-structure statistics of a mesh: what `lodforge info`, the tests and the benchmark report per LOD.
#pragma once

#include <cstddef>

#include "lodforge/core/mesh.hpp"

namespace lodforge::quad {

struct QuadStats {
  std::size_t faces = 0, quads = 0, triangles = 0, polygons = 0;  // polygons: more than 4 corners
  double quad_fraction = 0;           // quads / faces (0 for an empty mesh)
  std::size_t interior_vertices = 0;  // referenced, on no boundary or non-manifold edge
  std::size_t irregular_vertices = 0; // interior vertices whose valence (edge count) is not 4
};

// Faces with out-of-range indices or fewer than 3 corners are counted as faces but give no edges.
QuadStats quad_stats(const Mesh& mesh);

}  // namespace lodforge::quad
