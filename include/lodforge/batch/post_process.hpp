// Post-processing of a finished LOD: index and vertex order for the GPU.
//
//   const Mesh gpu = optimize_for_gpu(lod);  // same triangles, fewer vertex-shader runs and cache misses
//
// Faces are grouped by material (and OBJ group), each group's triangles are reordered by meshoptimizer's
// vertex-cache optimiser (Forsyth-style, meshopt_optimizeVertexCache), and then wedges, and vertices, are
// renumbered in order of first use (what meshopt_optimizeVertexFetch does to one vertex buffer), with every
// per-vertex and per-wedge array permuted alike, so attributes, seams, skin and morph targets stay attached.
// The result holds exactly the same polygons (same corners in the same cyclic order, so the same triangles
// after fan triangulation) in a different order; unused wedges and vertices are kept, after the used ones.
#pragma once

#include "lodforge/core/mesh.hpp"

namespace lodforge::batch {

Mesh optimize_for_gpu(const Mesh& mesh);

// Average cache miss ratio (vertex-shader runs per triangle) of the mesh's fan-triangulated faces in their
// current order, for a FIFO cache of `cache_size` wedges (meshopt_analyzeVertexCache); lower is better.
double average_cache_miss_ratio(const Mesh& mesh, unsigned cache_size = 16);

}  // namespace lodforge::batch
