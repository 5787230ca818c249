// The benchmarks' view of an asset as geometry: every mesh fan-triangulated, attributes dropped, concatenated.
#pragma once

#include <cstdint>
#include <vector>

#include "lodforge/io/asset.hpp"

namespace lodforge::bench {

inline void asset_triangles(const io::Asset& asset, std::vector<Vec3f>& positions, std::vector<std::uint32_t>& indices) {
  for (const Mesh& m : asset.meshes) {
    const auto base = static_cast<std::uint32_t>(positions.size());
    positions.insert(positions.end(), m.positions.begin(), m.positions.end());
    for (std::size_t f = 0; f < m.face_count(); ++f) {
      const std::uint32_t begin = m.face_offsets[f], k = m.face_size(f);
      for (std::uint32_t i = 1; i + 1 < k; ++i) {
        indices.insert(indices.end(), {base + m.corner_vertex(begin), base + m.corner_vertex(begin + i),
                                       base + m.corner_vertex(begin + i + 1)});
      }
    }
  }
}

}  // namespace lodforge::bench
