// The mirror-plane estimate behind detect_symmetry(): candidate planes, scored by how close the mirror images
// of the vertices come to other vertices, the best refined by iterated closest-vertex fitting. Private.
#pragma once

#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "lodforge/core/mesh.hpp"
#include "lodforge/core/topology.hpp"
#include "lodforge/symmetry/symmetry.hpp"
#include "point_tree.hpp"

namespace lodforge::symmetry::detail {

// What the estimate and the walk share about the mesh.
struct MeshGeometry {
  std::vector<Vec3d> position;           // per vertex, in double
  std::vector<double> edge_length;       // per vertex: mean length of its edges, 0 without edges
  std::vector<std::uint32_t> vertices;   // vertices on an edge, ascending: the ones that can be matched
  std::vector<std::uint32_t> neighbour_offsets, neighbours;  // CSR: edge neighbours of each vertex, ascending
  Bounds3 bounds;                        // of `vertices`
};
MeshGeometry analyse_geometry(const Mesh& mesh, const Topology& topo);

// The plane to grow the correspondence from: the best candidate under `mode` (not none), refined.
Plane estimate_plane(const Mesh& mesh, const MeshGeometry& g, const PointTree& tree, PlaneMode mode);

// The least-squares plane of mirrored vertex pairs (a, b): its normal the principal direction of the
// differences (oriented like `previous`), through the mean of the midpoints; a pair a == b (a vertex on the
// plane) counts for the offset only. With `fixed_normal` only the offset moves. `previous` without pairs.
Plane fit_plane(const MeshGeometry& g, std::span<const std::pair<std::uint32_t, std::uint32_t>> pairs,
                const Plane& previous, bool fixed_normal);

}  // namespace lodforge::symmetry::detail
