// Small quad meshes made by the quad tests (one wedge per vertex, material 0), and checks the tests share.
#pragma once

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <map>
#include <numbers>
#include <string>
#include <vector>

#include "lodforge/core/mesh.hpp"
#include "lodforge/core/topology.hpp"
#include "lodforge/core/validate.hpp"

namespace lodforge::testing {

inline long long euler(const Mesh& m) { return summarize_topology(m, build_topology(m)).euler_characteristic; }

// validate() finds nothing (the first message otherwise).
inline void expect_valid(const Mesh& m) {
  const ValidationReport r = validate(m);
  EXPECT_TRUE(r.ok()) << (r.messages.empty() ? std::string() : r.messages.front());
}

// Adds a vertex with one wedge (and the default material slot the first time).
inline std::uint32_t add_point(Mesh& m, double x, double y, double z) {
  if (m.materials.empty()) m.materials.push_back(MaterialSlot{.name = "default"});
  return m.add_vertex_with_wedge({{static_cast<float>(x), static_cast<float>(y), static_cast<float>(z)}});
}

// Planar nx × ny quad grid in z = 0 over [0, nx] × [0, ny]; vertex (i, j) has id j * (nx + 1) + i; quad
// (i, j) has id j * nx + i and corners (i,j) (i+1,j) (i+1,j+1) (i,j+1), facing +z.
inline Mesh make_quad_grid(int nx, int ny) {
  Mesh m;
  for (int j = 0; j <= ny; ++j) {
    for (int i = 0; i <= nx; ++i) add_point(m, i, j, 0);
  }
  auto id = [&](int i, int j) { return static_cast<std::uint32_t>(j * (nx + 1) + i); };
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) m.add_face({id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)});
  }
  return m;
}

// Open cylinder of `around` × `rings` quads (radius 1, height `rings`), facing outwards; vertex (i, j) has id
// j * around + i.
inline Mesh make_cylinder(int around, int rings) {
  Mesh m;
  for (int j = 0; j <= rings; ++j) {
    for (int i = 0; i < around; ++i) {
      const double a = 2.0 * std::numbers::pi * i / around;
      add_point(m, std::cos(a), std::sin(a), j);
    }
  }
  auto id = [&](int i, int j) { return static_cast<std::uint32_t>(j * around + (i % around)); };
  for (int j = 0; j < rings; ++j) {
    for (int i = 0; i < around; ++i) m.add_face({id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)});
  }
  return m;
}

// Torus of `major` × `minor` quads (radii 3 and 1), facing outwards.
inline Mesh make_torus(int major, int minor) {
  Mesh m;
  for (int j = 0; j < minor; ++j) {
    for (int i = 0; i < major; ++i) {
      const double u = 2.0 * std::numbers::pi * i / major, v = 2.0 * std::numbers::pi * j / minor;
      add_point(m, (3.0 + std::cos(v)) * std::cos(u), (3.0 + std::cos(v)) * std::sin(u), std::sin(v));
    }
  }
  auto id = [&](int i, int j) { return static_cast<std::uint32_t>((j % minor) * major + (i % major)); };
  for (int j = 0; j < minor; ++j) {
    for (int i = 0; i < major; ++i) m.add_face({id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)});
  }
  return m;
}

// A cube whose faces are n × n grids, as Catmull-Clark subdivision n = 2^k times of a cube gives topologically
// (positions pushed onto the unit sphere, as subdivision rounds it); closed, facing outwards, 6 n² quads.
inline Mesh make_subdivided_cube(int n) {
  Mesh m;
  std::map<std::array<int, 3>, std::uint32_t> ids;
  auto vertex = [&](std::array<int, 3> g) {
    const auto it = ids.find(g);
    if (it != ids.end()) return it->second;
    const double x = 2.0 * g[0] / n - 1.0, y = 2.0 * g[1] / n - 1.0, z = 2.0 * g[2] / n - 1.0;
    const double l = std::sqrt(x * x + y * y + z * z);
    const std::uint32_t v = add_point(m, x / l, y / l, z / l);
    ids.emplace(g, v);
    return v;
  };
  // Each cube face: a fixed axis at 0 or n, and two running axes (u, w) ordered so that u × w points outwards.
  for (int axis = 0; axis < 3; ++axis) {
    for (int side = 0; side < 2; ++side) {
      int u = (axis + 1) % 3, w = (axis + 2) % 3;
      if (side == 0) std::swap(u, w);
      for (int a = 0; a < n; ++a) {
        for (int b = 0; b < n; ++b) {
          auto at = [&](int da, int db) {
            std::array<int, 3> g{};
            g[axis] = side * n;
            g[u] = a + da;
            g[w] = b + db;
            return vertex(g);
          };
          m.add_face({at(0, 0), at(1, 0), at(1, 1), at(0, 1)});
        }
      }
    }
  }
  return m;
}

// A planar quad ribbon whose single polychord crosses itself: it runs right through the unit square X at the
// origin, loops 270 degrees clockwise around (1.5, -1.5) in `arc_quads` quads, and comes back up through X
// (see polychord_test.cpp). Its chord starts at the left end of arm A and ends at the top of arm T.
inline Mesh make_spiral_strip(int arc_quads) {
  Mesh m;
  std::map<std::pair<long, long>, std::uint32_t> ids;  // welded by position (rounded to 1e-6)
  auto vertex = [&](double x, double y) {
    const std::pair<long, long> key{std::lround(x * 1e6), std::lround(y * 1e6)};
    const auto it = ids.find(key);
    if (it != ids.end()) return it->second;
    const std::uint32_t v = add_point(m, x, y, 0);
    ids.emplace(key, v);
    return v;
  };
  auto quad = [&](std::array<double, 8> p) {  // counter-clockwise corners x0 y0 .. x3 y3
    m.add_face({vertex(p[0], p[1]), vertex(p[2], p[3]), vertex(p[4], p[5]), vertex(p[6], p[7])});
  };
  quad({-1.5, -0.5, -0.5, -0.5, -0.5, 0.5, -1.5, 0.5});  // A
  quad({-0.5, -0.5, 0.5, -0.5, 0.5, 0.5, -0.5, 0.5});    // X
  quad({0.5, -0.5, 1.5, -0.5, 1.5, 0.5, 0.5, 0.5});      // R
  quad({-0.5, -1.5, 0.5, -1.5, 0.5, -0.5, -0.5, -0.5});  // B
  quad({-0.5, 0.5, 0.5, 0.5, 0.5, 1.5, -0.5, 1.5});      // T
  // Arc: rung k at angle phi_k = k * 270deg / arc_quads clockwise from the top of the circle around c.
  const double cx = 1.5, cy = -1.5;
  auto rung = [&](int k, double r) {
    const double phi = 1.5 * std::numbers::pi * k / arc_quads;
    return std::array<double, 2>{cx + r * std::sin(phi), cy + r * std::cos(phi)};
  };
  for (int k = 0; k < arc_quads; ++k) {
    const auto i0 = rung(k, 1.0), o0 = rung(k, 2.0), i1 = rung(k + 1, 1.0), o1 = rung(k + 1, 2.0);
    // Clockwise travel: the inner rail is on the right, so counter-clockwise order is i0, i1, o1, o0.
    quad({i0[0], i0[1], i1[0], i1[1], o1[0], o1[1], o0[0], o0[1]});
  }
  return m;
}

}  // namespace lodforge::testing
