#include "lodforge/core/volume.hpp"

namespace lodforge {

double signed_volume(const Mesh& mesh) {
  double v = 0.0;
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    const std::uint32_t c = mesh.face_offsets[f];
    const Vec3d p0 = to_double(mesh.positions[mesh.corner_vertex(c)]);
    for (std::uint32_t k = 1; k + 1 < mesh.face_size(f); ++k) {
      const Vec3d p1 = to_double(mesh.positions[mesh.corner_vertex(c + k)]);
      const Vec3d p2 = to_double(mesh.positions[mesh.corner_vertex(c + k + 1)]);
      v += dot(cross(p0, p1), p2);
    }
  }
  return v / 6.0;
}

}  // namespace lodforge
