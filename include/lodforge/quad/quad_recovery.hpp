// Quad recovery: pairs triangles across "soft" diagonals back into quads, so that quad-authored assets exported
// as triangles (glTF always is) get their edge flow back before polychord simplification.
//
// Two triangles a-b-c and b-a-d that share edge a-b become the quad a-d-b-c when
//  - planarity: their normals differ by at most max_dihedral_deg;
//  - angle: every corner of the quad lies within [min_corner_deg, 180 - min_corner_deg];
//  - flow: a-b is the longest side of both triangles (a quad's diagonal is longer than its sides, so the edge
//    being removed is a diagonal, not an edge of the artist's flow);
//  - the triangles share material and group, are consistently oriented, and use the same wedges at a and b
//    (an attribute seam along a-b is a real edge).
// Pairs are taken greedily, best first (planarity + deviation of the corners from 90 degrees), ties by edge id.
#pragma once

#include <cstddef>

#include "lodforge/core/mesh.hpp"

namespace lodforge::quad {

struct QuadRecoveryOptions {
  double max_dihedral_deg = 20.0;
  double min_corner_deg = 45.0;
  // Pair only where the quad splits back into the same two triangles (a-b its shorter diagonal, as
  // for_each_face_triangle() splits it): the surface is unchanged. For outputs, whose triangles are final.
  bool keep_triangles = false;
};

// Returns the mesh with paired triangles replaced by quads (each quad takes the place of the first of its two
// triangles; other faces keep their order). Vertices and wedges are unchanged. `quads_made` (optional)
// receives the number of pairs.
Mesh recover_quads(const Mesh& mesh, const QuadRecoveryOptions& options = {}, std::size_t* quads_made = nullptr);

}  // namespace lodforge::quad
