// The benchmarks' generated terrain: a height field of side × side vertices over the unit square, heights from 8
// octaves of value noise (fBm) with a fixed seed, two triangles per grid square (2 (side - 1)² in all). The PLY
// writer stores values in the machine's byte order, and says little-endian: the benches run on x86-64.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

#include "lodforge/core/vec.hpp"

namespace lodforge::bench {

// The terrain's height at (x, y) of the unit square.
inline double fbm_height(double x, double y) {
  auto hash = [](std::uint32_t xi, std::uint32_t yi, std::uint32_t octave) {
    std::uint32_t v = xi * 0x8da6b343u ^ yi * 0xd8163841u ^ (octave + 12345u) * 0xcb1ab31fu;  // fixed seed 12345
    v ^= v >> 15;
    v *= 0x2c1b3c6du;
    v ^= v >> 12;
    v *= 0x297a2d39u;
    v ^= v >> 15;
    return static_cast<double>(v) / 4294967295.0;
  };
  auto smooth = [](double t) { return t * t * (3.0 - 2.0 * t); };
  double z = 0, amplitude = 0.08, frequency = 4.0;
  for (std::uint32_t o = 0; o < 8; ++o, amplitude *= 0.5, frequency *= 2.0) {
    const double fx = x * frequency, fy = y * frequency;
    const auto x0 = static_cast<std::uint32_t>(fx), y0 = static_cast<std::uint32_t>(fy);
    const double tx = smooth(fx - x0), ty = smooth(fy - y0);
    const double a = hash(x0, y0, o), b = hash(x0 + 1, y0, o), c = hash(x0, y0 + 1, o), d = hash(x0 + 1, y0 + 1, o);
    z += amplitude * ((a + (b - a) * tx) * (1 - ty) + (c + (d - c) * tx) * ty);
  }
  return z;
}

// Vertex (i, j) of a terrain of `side` vertices per side.
inline Vec3f fbm_vertex(std::size_t side, std::size_t i, std::size_t j) {
  const double step = 1.0 / static_cast<double>(side - 1);
  const double x = static_cast<double>(j) * step, y = static_cast<double>(i) * step;
  return {{static_cast<float>(x), static_cast<float>(y), static_cast<float>(fbm_height(x, y))}};
}

inline void make_fbm_terrain(std::size_t side, std::vector<Vec3f>& positions, std::vector<std::uint32_t>& indices) {
  // One thread on purpose: the benches fork their measured runs after generating, and a child forked from a
  // process that has started TBB's workers runs its own parallel loops on one thread.
  positions.assign(side * side, Vec3f{});
  for (std::size_t i = 0; i < side; ++i) {
    for (std::size_t j = 0; j < side; ++j) positions[i * side + j] = fbm_vertex(side, i, j);
  }
  indices.clear();
  indices.reserve(6 * (side - 1) * (side - 1));
  for (std::size_t i = 0; i + 1 < side; ++i) {
    for (std::size_t j = 0; j + 1 < side; ++j) {
      const auto a = static_cast<std::uint32_t>(i * side + j), b = a + 1, d = static_cast<std::uint32_t>(a + side), c = d + 1;
      indices.insert(indices.end(), {a, b, c, a, c, d});
    }
  }
}

// The same terrain written as a binary little-endian PLY row by row, never held in memory (inputs larger than
// memory for the out-of-core path). Returns false if the file could not be written.
inline bool write_fbm_terrain_ply(std::size_t side, const std::string& path) {
  std::ofstream out(path, std::ios::binary);
  const std::size_t faces = 2 * (side - 1) * (side - 1);
  out << "ply\nformat binary_little_endian 1.0\nelement vertex " << side * side
      << "\nproperty float x\nproperty float y\nproperty float z\nelement face " << faces
      << "\nproperty list uchar int vertex_indices\nend_header\n";
  std::vector<Vec3f> row(side);
  for (std::size_t i = 0; i < side; ++i) {
    for (std::size_t j = 0; j < side; ++j) row[j] = fbm_vertex(side, i, j);  // one thread, as above
    out.write(reinterpret_cast<const char*>(row.data()), static_cast<std::streamsize>(row.size() * sizeof(Vec3f)));
  }
  std::vector<char> record;
  for (std::size_t i = 0; i + 1 < side; ++i) {
    record.clear();
    for (std::size_t j = 0; j + 1 < side; ++j) {
      const auto a = static_cast<std::int32_t>(i * side + j), b = a + 1, d = static_cast<std::int32_t>(a + side), c = d + 1;
      for (const auto& t : {std::array<std::int32_t, 3>{a, b, c}, std::array<std::int32_t, 3>{a, c, d}}) {
        record.push_back(3);
        const char* bytes = reinterpret_cast<const char*>(t.data());
        record.insert(record.end(), bytes, bytes + sizeof t);
      }
    }
    out.write(record.data(), static_cast<std::streamsize>(record.size()));
  }
  return static_cast<bool>(out);
}

}  // namespace lodforge::bench
