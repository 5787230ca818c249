// meshoptimizer as the benchmarks' peer: meshopt_simplify on a triangle index list, back as a lodforge Mesh.
#pragma once

#include <meshoptimizer.h>

#include <cstddef>
#include <cstdint>
#include <vector>

#include "lodforge/core/mesh.hpp"

namespace lodforge::bench {

// meshopt_simplify of `indices` (triangles over `mesh`'s positions) down to about `target_triangles`; target
// error 1 (the whole diagonal), so only the count stops it. One material, one wedge per vertex.
inline Mesh meshopt_lod(const Mesh& mesh, const std::vector<std::uint32_t>& indices, std::size_t target_triangles) {
  std::vector<std::uint32_t> dst(indices.size());
  float result_error = 0;
  const std::size_t n = meshopt_simplify(dst.data(), indices.data(), indices.size(), &mesh.positions[0][0],
                                         mesh.positions.size(), sizeof(Vec3f), 3 * target_triangles,
                                         /*target_error=*/1.0f, /*options=*/0, &result_error);
  Mesh out;
  out.materials.push_back(MaterialSlot{.name = "default"});
  out.positions = mesh.positions;
  for (std::uint32_t v = 0; v < mesh.positions.size(); ++v) out.wedge_vertex.push_back(v);
  for (std::size_t i = 0; i + 2 < n; i += 3) out.add_face({dst[i], dst[i + 1], dst[i + 2]});
  return out;
}

}  // namespace lodforge::bench
