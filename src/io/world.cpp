// The scene's view of an asset: its meshes placed by their nodes' world transforms (glTF), for measuring.
#include <algorithm>
#include <cmath>

#include "lodforge/io/asset.hpp"

namespace lodforge::io {
namespace {

using Matrix4 = std::array<double, 16>;

Vec3d apply(const Matrix4& m, const Vec3f& p) {
  Vec3d out;
  for (int r = 0; r < 3; ++r) out[r] = m[r] * p[0] + m[4 + r] * p[1] + m[8 + r] * p[2] + m[12 + r];
  return out;
}

// The instances of mesh `m`: its transforms, or one identity instance (none given).
std::vector<Matrix4> instances(const Asset& asset, std::size_t m) {
  if (m < asset.mesh_transforms.size() && !asset.mesh_transforms[m].empty()) return asset.mesh_transforms[m];
  return {Matrix4{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}};
}

}  // namespace

Mesh world_surface(const Asset& asset) {
  Mesh all;
  all.materials.push_back({});
  for (std::size_t i = 0; i < asset.meshes.size(); ++i) {
    const Mesh& m = asset.meshes[i];
    for (const Matrix4& t : instances(asset, i)) {
      const auto base = static_cast<std::uint32_t>(all.vertex_count());
      for (const Vec3f& p : m.positions) all.positions.push_back(to_float(apply(t, p)));
      std::vector<std::uint32_t> w;
      for (std::size_t f = 0; f < m.face_count(); ++f) {
        w.clear();
        for (std::uint32_t c = m.face_offsets[f]; c < m.face_offsets[f + 1]; ++c) {
          all.wedge_vertex.push_back(base + m.corner_vertex(c));
          w.push_back(static_cast<std::uint32_t>(all.wedge_vertex.size() - 1));
        }
        all.add_face(w.data(), w.size());
      }
    }
  }
  return all;
}

Bounds3 world_bounds(const Asset& asset) {
  Bounds3 b;
  for (std::size_t i = 0; i < asset.meshes.size(); ++i) {
    for (const Matrix4& t : instances(asset, i)) {
      for (const Vec3f& p : asset.meshes[i].positions) {
        if (std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2])) b.add(apply(t, p));
      }
    }
  }
  return b;
}

double world_scale(const Asset& asset, std::size_t m) {
  if (m >= asset.mesh_transforms.size() || asset.mesh_transforms[m].empty()) return 1.0;
  double scale = 0.0;
  for (const Matrix4& t : asset.mesh_transforms[m]) {
    for (int c = 0; c < 3; ++c) {
      scale = std::max(scale, std::sqrt(t[c * 4] * t[c * 4] + t[c * 4 + 1] * t[c * 4 + 1] + t[c * 4 + 2] * t[c * 4 + 2]));
    }
  }
  return scale > 0.0 && std::isfinite(scale) ? scale : 1.0;
}

}  // namespace lodforge::io
