// Closed test solids and nesting checks for conservative LODs (the conservative tests and bench share them).
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <map>
#include <numbers>
#include <random>
#include <tuple>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "lodforge/core/mesh.hpp"
#include "lodforge/core/vec.hpp"

namespace lodforge::conservative_test {

using Tri = std::array<Vec3d, 3>;

inline Mesh with_material(Mesh m) {
  m.materials.push_back(MaterialSlot{.name = "default"});
  return m;
}

// Torus around z: major radius R, minor r, outward.
inline Mesh make_torus(int nu, int nv, double R, double r) {
  Mesh m;
  for (int i = 0; i < nu; ++i) {
    const double u = 2 * std::numbers::pi * i / nu;
    for (int j = 0; j < nv; ++j) {
      const double v = 2 * std::numbers::pi * j / nv;
      m.add_vertex_with_wedge({{float((R + r * std::cos(v)) * std::cos(u)), float((R + r * std::cos(v)) * std::sin(u)),
                                float(r * std::sin(v))}});
    }
  }
  auto id = [&](int i, int j) { return static_cast<std::uint32_t>((i % nu) * nv + (j % nv)); };
  for (int i = 0; i < nu; ++i) {
    for (int j = 0; j < nv; ++j) {
      m.add_face({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      m.add_face({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
  }
  return with_material(std::move(m));
}

// The boundary of a union of cells of an nx × ny × nz grid (filled(x, y, z)), each cell `res` sub-cells a side,
// scaled by `cell` per axis: a closed, outward, welded triangle surface. No two filled cells may touch along an
// edge or corner only.
template <typename Filled>
Mesh make_voxel_solid(int nx, int ny, int nz, int res, const Vec3d& cell, Filled&& filled) {
  Mesh m;
  std::map<std::tuple<int, int, int>, std::uint32_t> ids;
  auto vid = [&](int x, int y, int z) {
    const auto key = std::make_tuple(x, y, z);
    if (auto it = ids.find(key); it != ids.end()) return it->second;
    const std::uint32_t w = m.add_vertex_with_wedge(
        {{float(x * cell[0] / res), float(y * cell[1] / res), float(z * cell[2] / res)}});
    ids.emplace(key, w);
    return w;
  };
  auto inside = [&](int x, int y, int z) {
    return x >= 0 && y >= 0 && z >= 0 && x < nx && y < ny && z < nz && filled(x, y, z);
  };
  // Each side: outward axis, and the two in-plane axes u, v with u × v outward.
  struct Side {
    int axis, dir, u, v;
  };
  const Side sides[6] = {{0, 1, 1, 2}, {0, -1, 2, 1}, {1, 1, 2, 0}, {1, -1, 0, 2}, {2, 1, 0, 1}, {2, -1, 1, 0}};
  for (int x = 0; x < nx; ++x) {
    for (int y = 0; y < ny; ++y) {
      for (int z = 0; z < nz; ++z) {
        if (!inside(x, y, z)) continue;
        for (const Side& s : sides) {
          int c[3] = {x, y, z};
          c[s.axis] += s.dir;
          if (inside(c[0], c[1], c[2])) continue;
          int base[3] = {x * res, y * res, z * res};
          if (s.dir > 0) base[s.axis] += res;
          for (int i = 0; i < res; ++i) {
            for (int j = 0; j < res; ++j) {
              auto at = [&](int a, int b) {
                int p[3] = {base[0], base[1], base[2]};
                p[s.u] += a;
                p[s.v] += b;
                return vid(p[0], p[1], p[2]);
              };
              m.add_face({at(i, j), at(i + 1, j), at(i + 1, j + 1)});
              m.add_face({at(i, j), at(i + 1, j + 1), at(i, j + 1)});
            }
          }
        }
      }
    }
  }
  return with_material(std::move(m));
}

// An extruded C: a 4 × 4 ring of cells with one side open, 1 cell deep.
inline Mesh make_c_shape(int res) {
  return make_voxel_solid(4, 4, 1, res, Vec3d{{1, 1, 1}}, [](int x, int y, int) {
    const bool ring = x == 0 || y == 0 || y == 3 || x == 3;
    return ring && !(x == 3 && (y == 1 || y == 2));
  });
}

// A 1 × 1 × 0.02 plate.
inline Mesh make_plate(int res) {
  return make_voxel_solid(1, 1, 1, res, Vec3d{{1, 1, 0.02}}, [](int, int, int) { return true; });
}

// Icosphere of `level` subdivisions; `bump` > 0 scales each vertex's radius by 1 + bump × uniform(-1, 1)
// (star-shaped blobs), drawn from `seed`.
inline Mesh make_icosphere(int level, double bump = 0.0, std::uint64_t seed = 1) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Vec3d> p = {{{-1, t, 0}}, {{1, t, 0}}, {{-1, -t, 0}}, {{1, -t, 0}}, {{0, -1, t}}, {{0, 1, t}},
                          {{0, -1, -t}}, {{0, 1, -t}}, {{t, 0, -1}}, {{t, 0, 1}}, {{-t, 0, -1}}, {{-t, 0, 1}}};
  std::vector<std::array<std::uint32_t, 3>> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                                 {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                                 {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                                 {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (Vec3d& q : p) q = q * (1.0 / length(q));
  for (int l = 0; l < level; ++l) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> mid;
    auto midpoint = [&](std::uint32_t a, std::uint32_t b) {
      const auto key = std::minmax(a, b);
      if (auto it = mid.find(key); it != mid.end()) return it->second;
      Vec3d q = (p[a] + p[b]) * 0.5;
      p.push_back(q * (1.0 / length(q)));
      const auto id = static_cast<std::uint32_t>(p.size() - 1);
      mid.emplace(key, id);
      return id;
    };
    std::vector<std::array<std::uint32_t, 3>> g;
    for (const auto& tri : f) {
      const std::uint32_t a = midpoint(tri[0], tri[1]), b = midpoint(tri[1], tri[2]), c = midpoint(tri[2], tri[0]);
      g.push_back({tri[0], a, c});
      g.push_back({tri[1], b, a});
      g.push_back({tri[2], c, b});
      g.push_back({a, b, c});
    }
    f.swap(g);
  }
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  Mesh m;
  for (const Vec3d& q : p) {
    const double s = bump > 0.0 ? 1.0 + bump * uni(rng) : 1.0;
    m.add_vertex_with_wedge(to_float(q * s));
  }
  for (const auto& tri : f) m.add_face({tri[0], tri[1], tri[2]});
  return with_material(std::move(m));
}

// Triangles of a triangle mesh in double.
inline std::vector<Tri> triangles_of(const Mesh& m) {
  std::vector<Tri> out;
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    const std::uint32_t c = m.face_offsets[f];
    if (m.face_size(f) != 3) continue;
    out.push_back({to_double(m.positions[m.corner_vertex(c)]), to_double(m.positions[m.corner_vertex(c + 1)]),
                   to_double(m.positions[m.corner_vertex(c + 2)])});
  }
  return out;
}

inline double signed_volume(const std::vector<Tri>& t) {
  double v = 0.0;
  for (const Tri& x : t) v += dot(cross(x[0], x[1]), x[2]);
  return v / 6.0;
}

inline double diagonal_of(const std::vector<Tri>& t) {
  Vec3d lo{{1e300, 1e300, 1e300}}, hi{{-1e300, -1e300, -1e300}};
  for (const Tri& x : t) {
    for (const Vec3d& p : x) {
      for (int i = 0; i < 3; ++i) {
        lo[i] = std::min(lo[i], p[i]);
        hi[i] = std::max(hi[i], p[i]);
      }
    }
  }
  return length(hi - lo);
}

// Generalised winding number of p with respect to the triangles (solid angles, Van Oosterom and Strackee).
inline double winding_number(const std::vector<Tri>& tris, const Vec3d& p) {
  double sum = 0.0;
  for (const Tri& t : tris) {
    const Vec3d a = t[0] - p, b = t[1] - p, c = t[2] - p;
    const double la = length(a), lb = length(b), lc = length(c);
    const double num = dot(a, cross(b, c));
    const double den = la * lb * lc + dot(a, b) * lc + dot(b, c) * la + dot(c, a) * lb;
    sum += 2.0 * std::atan2(num, den);
  }
  return sum / (4.0 * std::numbers::pi);
}

inline double distance_to_triangle(const Vec3d& p, const Tri& t) {
  // Closest point on triangle (Ericson 5.1.5).
  const Vec3d& a = t[0];
  const Vec3d& b = t[1];
  const Vec3d& c = t[2];
  const Vec3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return length(p - a);
  const Vec3d bp = p - b;
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return length(p - b);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return length(p - (a + ab * (d1 / (d1 - d3))));
  const Vec3d cp = p - c;
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return length(p - c);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return length(p - (a + ac * (d2 / (d2 - d6))));
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    return length(p - (b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)))));
  }
  const double denom = 1.0 / (va + vb + vc);
  return length(p - (a + ab * (vb * denom) + ac * (vc * denom)));
}

inline double distance_to_mesh(const std::vector<Tri>& tris, const Vec3d& p) {
  double best = 1e300;
  for (const Tri& t : tris) best = std::min(best, distance_to_triangle(p, t));
  return best;
}

// Whether triangles s and t cross by more than `tol` (a length): each has corners farther than tol on both
// sides of the other's plane, and the two segments where they meet the other's plane overlap by more than tol.
// Touching (shared corners and edges, coplanar contact) does not count.
inline bool triangles_cross(const Tri& s, const Tri& t, double tol) {
  auto side = [&](const Tri& x, const Tri& y, double (&d)[3]) {
    Vec3d n = cross(y[1] - y[0], y[2] - y[0]);
    const double len = length(n);
    if (!(len > 0.0)) return false;
    n = n * (1.0 / len);
    bool below = false, above = false;
    for (int i = 0; i < 3; ++i) {
      d[i] = dot(n, x[i] - y[0]);
      below |= d[i] < -tol;
      above |= d[i] > tol;
    }
    return below && above;
  };
  double ds[3], dt[3];
  if (!side(s, t, ds) || !side(t, s, dt)) return false;
  const Vec3d dir = cross(cross(s[1] - s[0], s[2] - s[0]), cross(t[1] - t[0], t[2] - t[0]));
  const double dl = length(dir);
  if (!(dl > 0.0)) return false;
  const Vec3d axis = dir * (1.0 / dl);
  auto interval = [&](const Tri& x, const double (&d)[3], double& lo, double& hi) {
    lo = 1e300;
    hi = -1e300;
    for (int i = 0; i < 3; ++i) {
      const int j = (i + 1) % 3;
      if (d[i] == 0.0) {
        lo = std::min(lo, dot(axis, x[i]));
        hi = std::max(hi, dot(axis, x[i]));
      }
      if ((d[i] < 0.0 && d[j] > 0.0) || (d[i] > 0.0 && d[j] < 0.0)) {
        const Vec3d q = x[i] + (x[j] - x[i]) * (d[i] / (d[i] - d[j]));
        lo = std::min(lo, dot(axis, q));
        hi = std::max(hi, dot(axis, q));
      }
    }
  };
  double slo, shi, tlo, thi;
  interval(s, ds, slo, shi);
  interval(t, dt, tlo, thi);
  return std::min(shi, thi) - std::max(slo, tlo) > tol;
}

// Pairs (lod triangle, source triangle) that cross (triangles_cross), found through a uniform grid.
inline std::size_t count_crossings(const std::vector<Tri>& lod, const std::vector<Tri>& src, double tol) {
  Vec3d lo{{1e300, 1e300, 1e300}}, hi{{-1e300, -1e300, -1e300}};
  for (const Tri& x : src) {
    for (const Vec3d& p : x) {
      for (int i = 0; i < 3; ++i) {
        lo[i] = std::min(lo[i], p[i]);
        hi[i] = std::max(hi[i], p[i]);
      }
    }
  }
  const int n = std::clamp(static_cast<int>(std::cbrt(double(src.size()) / 4.0)), 1, 64);
  Vec3d size = hi - lo;
  for (int i = 0; i < 3; ++i) size[i] = std::max(size[i], 1e-12);
  auto cell = [&](double v, int axis) {
    return std::clamp(static_cast<int>((v - lo[axis]) / size[axis] * n), 0, n - 1);
  };
  std::vector<std::vector<std::uint32_t>> grid(std::size_t(n) * n * n);
  auto for_cells = [&](const Tri& x, double pad, auto&& f) {
    int a[3], b[3];
    for (int i = 0; i < 3; ++i) {
      const double mn = std::min({x[0][i], x[1][i], x[2][i]}) - pad, mx = std::max({x[0][i], x[1][i], x[2][i]}) + pad;
      if (mx < lo[i] || mn > hi[i]) return;
      a[i] = cell(mn, i);
      b[i] = cell(mx, i);
    }
    for (int x0 = a[0]; x0 <= b[0]; ++x0)
      for (int y0 = a[1]; y0 <= b[1]; ++y0)
        for (int z0 = a[2]; z0 <= b[2]; ++z0) f(std::size_t(x0) * n * n + std::size_t(y0) * n + z0);
  };
  for (std::uint32_t i = 0; i < src.size(); ++i) for_cells(src[i], 0.0, [&](std::size_t c) { grid[c].push_back(i); });
  std::vector<std::uint32_t> seen(src.size(), 0);
  std::uint32_t stamp = 0;
  std::size_t crossings = 0;
  for (const Tri& x : lod) {
    ++stamp;
    for_cells(x, tol, [&](std::size_t c) {
      for (std::uint32_t i : grid[c]) {
        if (seen[i] == stamp) continue;
        seen[i] = stamp;
        crossings += triangles_cross(x, src[i], tol);
      }
    });
  }
  return crossings;
}

// `count` points spread over the triangles by area (fixed seed).
inline std::vector<Vec3d> surface_samples(const std::vector<Tri>& tris, std::size_t count, std::uint64_t seed) {
  std::vector<double> cum;
  double total = 0.0;
  for (const Tri& t : tris) {
    total += 0.5 * length(cross(t[1] - t[0], t[2] - t[0]));
    cum.push_back(total);
  }
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  std::vector<Vec3d> out;
  if (tris.empty() || !(total > 0.0)) return out;
  for (std::size_t i = 0; i < count; ++i) {
    const double r = uni(rng) * total;
    const std::size_t f = std::min<std::size_t>(std::lower_bound(cum.begin(), cum.end(), r) - cum.begin(), tris.size() - 1);
    double a = uni(rng), b = uni(rng);
    if (a + b > 1.0) {
      a = 1.0 - a;
      b = 1.0 - b;
    }
    const Tri& t = tris[f];
    out.push_back(t[0] + (t[1] - t[0]) * a + (t[2] - t[0]) * b);
  }
  return out;
}

// The vertices a mesh's faces use, and `samples` points on its surface.
inline std::vector<Vec3d> test_points(const Mesh& m, std::size_t samples, std::uint64_t seed = 7) {
  std::vector<Vec3d> pts = surface_samples(triangles_of(m), samples, seed);
  std::vector<char> used(m.vertex_count(), 0);
  for (std::uint32_t w : m.corner_wedge) used[m.wedge_vertex[w]] = 1;
  for (std::size_t v = 0; v < used.size(); ++v) {
    if (used[v]) pts.push_back(to_double(m.positions[v]));
  }
  return pts;
}

// How many of `points` are not inside or on `outer`: winding number below 0.5 and farther than `tol` from its
// surface. Parallel over the points.
inline std::size_t points_outside(const std::vector<Vec3d>& points, const std::vector<Tri>& outer, double tol) {
  std::atomic<std::size_t> bad{0};
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points.size(), 64), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t i = r.begin(); i < r.end(); ++i) {
      if (winding_number(outer, points[i]) >= 0.5) continue;
      if (distance_to_mesh(outer, points[i]) <= tol) continue;
      ++bad;
    }
  });
  return bad.load();
}

}  // namespace lodforge::conservative_test
