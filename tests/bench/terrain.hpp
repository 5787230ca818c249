// The benchmarks' generated terrain: a height field of side × side vertices over the unit square, heights from 8
// octaves of value noise (fBm) with a fixed seed, two triangles per grid square (2 (side - 1)² in all).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include <tbb/parallel_for.h>

#include "lodforge/core/vec.hpp"

namespace lodforge::bench {

inline void make_fbm_terrain(std::size_t side, std::vector<Vec3f>& positions, std::vector<std::uint32_t>& indices) {
  auto hash = [](std::uint32_t x, std::uint32_t y, std::uint32_t octave) {
    std::uint32_t v = x * 0x8da6b343u ^ y * 0xd8163841u ^ (octave + 12345u) * 0xcb1ab31fu;  // fixed seed 12345
    v ^= v >> 15;
    v *= 0x2c1b3c6du;
    v ^= v >> 12;
    v *= 0x297a2d39u;
    v ^= v >> 15;
    return static_cast<double>(v) / 4294967295.0;
  };
  auto smooth = [](double t) { return t * t * (3.0 - 2.0 * t); };
  const double step = 1.0 / static_cast<double>(side - 1);
  positions.assign(side * side, Vec3f{});
  tbb::parallel_for(std::size_t{0}, side, [&](std::size_t i) {
    for (std::size_t j = 0; j < side; ++j) {
      const double x = static_cast<double>(j) * step, y = static_cast<double>(i) * step;
      double z = 0, amplitude = 0.08, frequency = 4.0;
      for (std::uint32_t o = 0; o < 8; ++o, amplitude *= 0.5, frequency *= 2.0) {
        const double fx = x * frequency, fy = y * frequency;
        const auto x0 = static_cast<std::uint32_t>(fx), y0 = static_cast<std::uint32_t>(fy);
        const double tx = smooth(fx - x0), ty = smooth(fy - y0);
        const double a = hash(x0, y0, o), b = hash(x0 + 1, y0, o), c = hash(x0, y0 + 1, o), d = hash(x0 + 1, y0 + 1, o);
        z += amplitude * ((a + (b - a) * tx) * (1 - ty) + (c + (d - c) * tx) * ty);
      }
      positions[i * side + j] = {{static_cast<float>(x), static_cast<float>(y), static_cast<float>(z)}};
    }
  });
  indices.clear();
  indices.reserve(6 * (side - 1) * (side - 1));
  for (std::size_t i = 0; i + 1 < side; ++i) {
    for (std::size_t j = 0; j + 1 < side; ++j) {
      const auto a = static_cast<std::uint32_t>(i * side + j), b = a + 1, d = static_cast<std::uint32_t>(a + side), c = d + 1;
      indices.insert(indices.end(), {a, b, c, a, c, d});
    }
  }
}

}  // namespace lodforge::bench
