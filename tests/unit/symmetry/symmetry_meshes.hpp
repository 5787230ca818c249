// Synthetic meshes for the symmetry tests: bumpy closed blobs (quad bands, triangle caps at the poles) that are
// exact mirror images of themselves about x = 0, or not symmetric at all.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <random>
#include <vector>

#include "lodforge/core/mesh.hpp"

namespace lodforge::symmetry::testing {

// A bumpy radius over the unit sphere with no mirror plane of its own.
inline double bump(double x, double y, double z) {
  return 1.0 + 0.15 * std::sin(3.1 * x + 1.3) * std::cos(2.3 * y - 0.4) + 0.08 * std::sin(4.7 * z + 0.9 * y + 0.2);
}

// A closed blob of `rings` latitude bands and `segments` (a multiple of 4) around: quads between rings,
// triangle fans at the poles. mirrored: the radius depends on |x|, and the vertices at x < 0 are the exact
// (negated-x) copies of those at x > 0. Otherwise the bump plus a deterministic jitter of `jitter` (fraction of
// the radius) per vertex.
inline Mesh make_blob(int rings, int segments, bool mirrored, double jitter = 0.0) {
  Mesh m;
  const double pi = std::acos(-1.0);
  std::mt19937 rng(1234);
  std::uniform_real_distribution<double> noise(-1.0, 1.0);
  auto position = [&](double theta, double phi) {
    const double dx = std::sin(theta) * std::cos(phi), dy = std::sin(theta) * std::sin(phi), dz = std::cos(theta);
    const double r = bump(mirrored ? std::abs(dx) : dx, dy, dz) * (1.0 + jitter * noise(rng));
    return Vec3d{{r * dx, r * dy, r * dz}};
  };
  std::vector<Vec3d> p;
  p.push_back(position(0, 0));
  for (int r = 1; r < rings; ++r) {
    const double theta = pi * r / rings;
    for (int j = 0; j < segments; ++j) p.push_back(position(theta, 2 * pi * j / segments));
  }
  p.push_back(position(pi, 0));
  if (mirrored) {  // phi -> pi - phi is the mirror about x = 0: j -> segments / 2 - j
    for (int r = 1; r < rings; ++r) {
      const std::size_t base = 1 + static_cast<std::size_t>(r - 1) * segments;
      for (int j = 0; j < segments; ++j) {
        const int mj = ((segments / 2 - j) % segments + segments) % segments;
        Vec3d& q = p[base + j];
        const bool right = j < segments / 4 || j > 3 * segments / 4;
        if (j == segments / 4 || j == 3 * segments / 4) q[0] = 0.0;
        if (!right && q[0] != 0.0) {
          q = p[base + mj];
          q[0] = -q[0];
        }
      }
    }
    p.front()[0] = 0.0;
    p.back()[0] = 0.0;
  }
  for (const Vec3d& q : p) m.add_vertex_with_wedge(to_float(q));
  const auto ring = [&](int r, int j) { return static_cast<std::uint32_t>(1 + (r - 1) * segments + (j % segments)); };
  const auto south = static_cast<std::uint32_t>(p.size() - 1);
  for (int j = 0; j < segments; ++j) m.add_face({0, ring(1, j), ring(1, j + 1)});
  for (int r = 1; r + 1 < rings; ++r) {
    for (int j = 0; j < segments; ++j) m.add_face({ring(r, j), ring(r + 1, j), ring(r + 1, j + 1), ring(r, j + 1)});
  }
  for (int j = 0; j < segments; ++j) m.add_face({ring(rings - 1, j), south, ring(rings - 1, j + 1)});
  return m;
}

// `mesh` with its vertices renumbered and its faces reordered by a fixed random permutation.
inline Mesh shuffled(const Mesh& mesh, unsigned seed) {
  std::mt19937 rng(seed);
  std::vector<std::uint32_t> order(mesh.vertex_count());
  std::iota(order.begin(), order.end(), 0u);
  std::shuffle(order.begin(), order.end(), rng);
  std::vector<std::uint32_t> new_id(order.size());
  for (std::uint32_t i = 0; i < order.size(); ++i) new_id[order[i]] = i;
  Mesh out;
  for (std::uint32_t v : order) out.add_vertex_with_wedge(mesh.positions[v]);
  std::vector<std::uint32_t> faces(mesh.face_count());
  std::iota(faces.begin(), faces.end(), 0u);
  std::shuffle(faces.begin(), faces.end(), rng);
  for (std::uint32_t f : faces) {
    std::vector<std::uint32_t> corners;
    for (std::uint32_t c = mesh.face_offsets[f]; c < mesh.face_offsets[f + 1]; ++c) {
      corners.push_back(new_id[mesh.corner_vertex(c)]);
    }
    out.add_face(corners.data(), corners.size());
  }
  return out;
}

// `mesh` with every position mapped by p -> R p + t (R a fixed rotation about a skew axis).
struct Rigid {
  double r[3][3];
  Vec3d t;
  Vec3d apply(const Vec3d& p) const {
    Vec3d q = t;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) q[i] += r[i][j] * p[j];
    }
    return q;
  }
};
inline Rigid skew_rigid() {
  // Rotation by 0.7 rad about the unit axis (1, 2, 3) / sqrt(14), Rodrigues' formula.
  const double s = std::sqrt(14.0), k[3] = {1 / s, 2 / s, 3 / s}, a = 0.7, c = std::cos(a), sn = std::sin(a);
  Rigid g{};
  const double kx[3][3] = {{0, -k[2], k[1]}, {k[2], 0, -k[0]}, {-k[1], k[0], 0}};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      double kk = 0;
      for (int l = 0; l < 3; ++l) kk += kx[i][l] * kx[l][j];
      g.r[i][j] = (i == j ? 1.0 : 0.0) + sn * kx[i][j] + (1 - c) * kk;
    }
  }
  g.t = {{0.3, -1.7, 2.2}};
  return g;
}
inline Mesh transformed(Mesh mesh, const Rigid& g) {
  for (Vec3f& p : mesh.positions) p = to_float(g.apply(to_double(p)));
  return mesh;
}

inline Mesh translated_x(Mesh mesh, float dx) {
  for (Vec3f& p : mesh.positions) p[0] += dx;
  return mesh;
}

// Two copies of `part`: one moved by +offset along x, the other its mirror image about x = 0 (winding reversed).
inline Mesh mirrored_pair(const Mesh& part, double offset) {
  Mesh out;
  for (const Vec3f& p : part.positions) out.add_vertex_with_wedge({{static_cast<float>(p[0] + offset), p[1], p[2]}});
  for (const Vec3f& p : part.positions) out.add_vertex_with_wedge({{static_cast<float>(-(p[0] + offset)), p[1], p[2]}});
  const auto n = static_cast<std::uint32_t>(part.vertex_count());
  for (std::size_t f = 0; f < part.face_count(); ++f) {
    std::vector<std::uint32_t> a, b;
    for (std::uint32_t c = part.face_offsets[f]; c < part.face_offsets[f + 1]; ++c) a.push_back(part.corner_vertex(c));
    for (auto it = a.rbegin(); it != a.rend(); ++it) b.push_back(*it + n);
    out.add_face(a.data(), a.size());
    out.add_face(b.data(), b.size());
  }
  return out;
}

}  // namespace lodforge::symmetry::testing
