// Meshes and checks shared by the simplifier tests.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <tuple>
#include <vector>

#include "lodforge/core/mesh.hpp"
#include "lodforge/core/topology.hpp"
#include "lodforge/core/validate.hpp"
#include "test_support.hpp"

namespace lodforge::simplify_test {

// A cube [0, n]³ whose six faces are n×n grids of triangle pairs, welded, outward.
inline Mesh make_subdivided_cube(int n) {
  Mesh m;
  std::map<std::tuple<int, int, int>, std::uint32_t> ids;
  auto vid = [&](int x, int y, int z) {
    const auto key = std::make_tuple(x, y, z);
    auto it = ids.find(key);
    if (it != ids.end()) return it->second;
    const std::uint32_t w = m.add_vertex_with_wedge({{float(x), float(y), float(z)}});
    ids.emplace(key, w);
    return w;
  };
  // Each face: origin o, in-plane axes u and v with u × v pointing outward.
  struct Side {
    int o[3], u[3], v[3];
  };
  const Side sides[6] = {
      {{0, 0, 0}, {0, 1, 0}, {1, 0, 0}},  // z = 0, normal -z
      {{0, 0, n}, {1, 0, 0}, {0, 1, 0}},  // z = n, +z
      {{0, 0, 0}, {1, 0, 0}, {0, 0, 1}},  // y = 0, -y
      {{0, n, 0}, {0, 0, 1}, {1, 0, 0}},  // y = n, +y
      {{0, 0, 0}, {0, 0, 1}, {0, 1, 0}},  // x = 0, -x
      {{n, 0, 0}, {0, 1, 0}, {0, 0, 1}},  // x = n, +x
  };
  for (const Side& s : sides) {
    auto at = [&](int i, int j) {
      return vid(s.o[0] + i * s.u[0] + j * s.v[0], s.o[1] + i * s.u[1] + j * s.v[1],
                 s.o[2] + i * s.u[2] + j * s.v[2]);
    };
    for (int i = 0; i < n; ++i) {
      for (int j = 0; j < n; ++j) {
        m.add_face({at(i, j), at(i + 1, j), at(i + 1, j + 1)});
        m.add_face({at(i, j), at(i + 1, j + 1), at(i, j + 1)});
      }
    }
  }
  m.materials.push_back(MaterialSlot{.name = "default"});
  return m;
}

// A closed sphere with a deterministic bumpy radius, so that every collapse costs something different.
inline Mesh make_bumpy_sphere(int rings, int segments) {
  Mesh m = testing::make_uv_sphere(rings, segments, 1.0f);
  for (Vec3f& p : m.positions) {
    const double r = 1.0 + 0.05 * std::sin(7.0 * p[0]) * std::cos(5.0 * p[1]) + 0.03 * std::sin(11.0 * p[2]);
    p = p * static_cast<float>(r);
  }
  return m;
}

// An open grid over [0, n]² with a smooth deterministic height field.
inline Mesh make_bumpy_grid(int n) {
  Mesh m = testing::make_grid(n, n, false);
  for (Vec3f& p : m.positions) {
    p[2] = static_cast<float>(0.5 * std::sin(0.7 * p[0]) * std::cos(0.5 * p[1]));
  }
  return m;
}

// A torus of n × k quads split into triangles (closed, genus 1, Euler characteristic 0).
inline Mesh make_torus(int n, int k, double major = 2.0, double minor = 0.7) {
  Mesh m;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < k; ++j) {
      const double u = 2 * 3.14159265358979 * i / n, v = 2 * 3.14159265358979 * j / k;
      const double r = major + minor * std::cos(v);
      m.add_vertex_with_wedge({{float(r * std::cos(u)), float(r * std::sin(u)), float(minor * std::sin(v))}});
    }
  }
  auto id = [&](int i, int j) { return static_cast<std::uint32_t>(((i + n) % n) * k + (j + k) % k); };
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < k; ++j) {
      m.add_face({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      m.add_face({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
  }
  m.materials.push_back(MaterialSlot{.name = "default"});
  return m;
}

inline TopologySummary summary(const Mesh& m) { return summarize_topology(m, build_topology(m)); }

// Every topology/validity finding of `after` is no worse than that of `before`.
inline void expect_nothing_new(const ValidationReport& before, const ValidationReport& after) {
  EXPECT_EQ(after.nonfinite_positions, before.nonfinite_positions);
  EXPECT_EQ(after.out_of_range_indices, 0u);
  EXPECT_EQ(after.short_faces, 0u);
  EXPECT_LE(after.degenerate_faces, before.degenerate_faces);
  EXPECT_LE(after.duplicate_faces, before.duplicate_faces);
  EXPECT_LE(after.non_manifold_edges, before.non_manifold_edges);
  EXPECT_LE(after.non_manifold_vertices, before.non_manifold_vertices);
  EXPECT_LE(after.inconsistent_orientation, before.inconsistent_orientation);
  EXPECT_EQ(after.attribute_size_errors, 0u);
}

inline std::set<std::array<float, 3>> position_set(const Mesh& m) {
  std::set<std::array<float, 3>> s;
  for (const Vec3f& p : m.positions) s.insert({p[0], p[1], p[2]});
  return s;
}

}  // namespace lodforge::simplify_test
