// Terrain patches: walls simplified once per level, conservative fix-up of the kept wall samples, each patch
// simplified with its outline locked, skirts (docs/terrain.md).
#include "lodforge/tiling/terrain.hpp"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>
#include <unordered_map>
#include <utility>

namespace lodforge::terrain {

namespace {

constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();

// The map as the patches see it: float heights (what the meshes store), holes, cell validity.
struct Grid {
  std::size_t w = 0, h = 0;
  double sx = 1, sz = 1;
  std::vector<float> y;            // per sample
  std::vector<std::uint8_t> hole;  // per sample
  std::vector<std::uint8_t> cell;  // per cell ((w - 1) x (h - 1)): all four corners present

  std::uint32_t id(std::size_t c, std::size_t r) const { return static_cast<std::uint32_t>(r * w + c); }
  std::size_t col(std::uint32_t v) const { return v % w; }
  std::size_t row(std::uint32_t v) const { return v / w; }
  bool cell_ok(std::ptrdiff_t c, std::ptrdiff_t r) const {
    return c >= 0 && r >= 0 && static_cast<std::size_t>(c) + 1 < w && static_cast<std::size_t>(r) + 1 < h &&
           cell[static_cast<std::size_t>(r) * (w - 1) + static_cast<std::size_t>(c)] != 0;
  }
  // Whether every cell around sample (c, r) inside the map is present.
  bool all_cells_around(std::size_t c, std::size_t r) const {
    for (std::ptrdiff_t dr = -1; dr <= 0; ++dr) {
      for (std::ptrdiff_t dc = -1; dc <= 0; ++dc) {
        const std::ptrdiff_t cc = static_cast<std::ptrdiff_t>(c) + dc, rr = static_cast<std::ptrdiff_t>(r) + dr;
        if (cc < 0 || rr < 0 || static_cast<std::size_t>(cc) + 1 >= w || static_cast<std::size_t>(rr) + 1 >= h)
          continue;
        if (!cell_ok(cc, rr)) return false;
      }
    }
    return true;
  }
  // The height-map surface at (x, z) in sample units, inside the map, on a present cell.
  double surface(double x, double z) const {
    std::size_t c = static_cast<std::size_t>(std::clamp(std::floor(x), 0.0, static_cast<double>(w - 2)));
    std::size_t r = static_cast<std::size_t>(std::clamp(std::floor(z), 0.0, static_cast<double>(h - 2)));
    const double fx = x - static_cast<double>(c), fz = z - static_cast<double>(r);
    const double h00 = y[id(c, r)], h10 = y[id(c + 1, r)], h01 = y[id(c, r + 1)], h11 = y[id(c + 1, r + 1)];
    // Cells are split along the diagonal from (c, r) to (c + 1, r + 1).
    if (fx >= fz) return h00 + fx * (h10 - h00) + fz * (h11 - h10);
    return h00 + fz * (h01 - h00) + fx * (h11 - h01);
  }
};

Grid make_grid(const io::HeightMap& map) {
  Grid g;
  g.w = map.width;
  g.h = map.height;
  g.sx = map.layout.spacing_x;
  g.sz = map.layout.spacing_z;
  g.y.resize(g.w * g.h);
  g.hole.resize(g.w * g.h);
  for (std::size_t r = 0; r < g.h; ++r) {
    for (std::size_t c = 0; c < g.w; ++c) {
      g.y[g.id(c, r)] = static_cast<float>(map.y(c, r));
      g.hole[g.id(c, r)] = map.hole(c, r) ? 1 : 0;
    }
  }
  g.cell.assign((g.w - 1) * (g.h - 1), 0);
  for (std::size_t r = 0; r + 1 < g.h; ++r) {
    for (std::size_t c = 0; c + 1 < g.w; ++c) {
      g.cell[r * (g.w - 1) + c] =
          !g.hole[g.id(c, r)] && !g.hole[g.id(c + 1, r)] && !g.hole[g.id(c, r + 1)] && !g.hole[g.id(c + 1, r + 1)];
    }
  }
  return g;
}

// One side of a patch: samples `count` long from (c0, r0), along columns (horizontal) or rows.
struct Wall {
  std::size_t c0 = 0, r0 = 0, count = 0;
  bool horizontal = true;
  std::uint32_t at(const Grid& g, std::size_t i) const { return horizontal ? g.id(c0 + i, r0) : g.id(c0, r0 + i); }
};

// The patch grid: patch (px, pz) spans cells [cx0, cx1) x [cz0, cz1).
struct Layout {
  std::size_t cells = 64, nx = 0, nz = 0;
  std::size_t cx0(std::size_t px, const Grid&) const { return px * cells; }
  std::size_t cx1(std::size_t px, const Grid& g) const { return std::min((px + 1) * cells, g.w - 1); }
  std::size_t cz0(std::size_t pz, const Grid&) const { return pz * cells; }
  std::size_t cz1(std::size_t pz, const Grid& g) const { return std::min((pz + 1) * cells, g.h - 1); }
  // Walls: horizontal ones at row pz * cells (pz = 0..nz, the last at the map's last row) for patch column px,
  // vertical ones likewise.
  Wall horizontal(std::size_t px, std::size_t pz, const Grid& g) const {
    const std::size_t r = std::min(pz * cells, g.h - 1);
    return {cx0(px, g), r, cx1(px, g) - cx0(px, g) + 1, true};
  }
  Wall vertical(std::size_t px, std::size_t pz, const Grid& g) const {
    const std::size_t c = std::min(px * cells, g.w - 1);
    return {c, cz0(pz, g), cz1(pz, g) - cz0(pz, g) + 1, false};
  }
};

// Which samples of a wall a level keeps: the removal cost of a kept sample is the largest height difference,
// over the samples between its kept neighbours, between the map and the chord that would replace them.
std::vector<std::uint8_t> keep_on_wall(const Grid& g, const Wall& wall, const LevelSpec& level) {
  const std::size_t n = wall.count;
  std::vector<std::uint8_t> keep(n, 1), forced(n, 0);
  std::vector<double> height(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t v = wall.at(g, i);
    height[i] = g.y[v];
    // Ends, their neighbours (a corner then never absorbs a sample: it stays as the map has it, and no patch
    // depends on walls it does not touch), samples next to a hole, and missing samples stay.
    forced[i] = i <= 1 || i + 2 >= n || g.hole[v] || !g.all_cells_around(g.col(v), g.row(v));
  }
  const auto target =
      static_cast<std::size_t>(std::max(2.0, std::round(static_cast<double>(n - 1) * std::sqrt(level.ratio)) + 1.0));
  std::vector<std::size_t> prev(n), next(n);
  for (std::size_t i = 0; i < n; ++i) {
    prev[i] = i == 0 ? 0 : i - 1;
    next[i] = i + 1;
  }
  const auto cost = [&](std::size_t j) {
    const std::size_t a = prev[j], b = next[j];
    double worst = 0;
    for (std::size_t m = a + 1; m < b; ++m) {
      const double t = static_cast<double>(m - a) / static_cast<double>(b - a);
      worst = std::max(worst, std::abs(height[m] - (height[a] + t * (height[b] - height[a]))));
    }
    return worst;
  };
  std::vector<double> costs(n, std::numeric_limits<double>::infinity());
  for (std::size_t i = 0; i < n; ++i) {
    if (!forced[i]) costs[i] = cost(i);
  }
  std::size_t kept = n;
  while (kept > target) {
    std::size_t best = n;
    for (std::size_t i = 0; i < n; ++i) {
      if (keep[i] && !forced[i] && (best == n || costs[i] < costs[best])) best = i;
    }
    if (best == n || !std::isfinite(costs[best])) break;
    if (level.max_error >= 0 && costs[best] > level.max_error) break;
    keep[best] = 0;
    --kept;
    const std::size_t a = prev[best], b = next[best];
    next[a] = b;
    prev[b] = a;
    if (!forced[a]) costs[a] = cost(a);
    if (!forced[b]) costs[b] = cost(b);
  }
  return keep;
}

// One level's walls: every wall sample that moved onto a kept one, and the kept samples' heights.
struct LevelWalls {
  std::unordered_map<std::uint32_t, std::uint32_t> moved;  // wall sample -> kept sample it moved onto
  std::unordered_map<std::uint32_t, float> height;         // kept wall samples whose height changed
  std::vector<std::uint8_t> on_wall;                       // per sample: a kept wall sample (may adjust)
};

std::uint32_t rep(const LevelWalls& lw, std::uint32_t v) {
  const auto it = lw.moved.find(v);
  return it == lw.moved.end() ? v : it->second;
}

// The two triangles of cell (c, r), counter-clockwise seen from above (+y).
std::array<std::array<std::uint32_t, 3>, 2> cell_triangles(const Grid& g, std::size_t c, std::size_t r) {
  const std::uint32_t a = g.id(c, r), b = g.id(c + 1, r), d = g.id(c, r + 1), e = g.id(c + 1, r + 1);
  return {{{a, d, e}, {a, e, b}}};
}

// Cell-unit position of sample v.
std::array<double, 2> at(const Grid& g, std::uint32_t v) {
  return {static_cast<double>(g.col(v)), static_cast<double>(g.row(v))};
}

// For a triangle the wall moves made (corners after the moves), the lowest (occluder) or highest (bounding)
// height each adjustable corner may have so that the triangle stays on its side of the map everywhere, with
// the other corners where the map has them: checked at every grid sample inside it and every crossing of its
// edges with the grid's lines, the points where the difference of two piecewise-linear surfaces peaks.
void constrain(const Grid& g, const std::array<std::uint32_t, 3>& t, const std::vector<std::uint8_t>& adjustable,
               bool below, std::unordered_map<std::uint32_t, double>& bound) {
  const std::array<std::array<double, 2>, 3> p{at(g, t[0]), at(g, t[1]), at(g, t[2])};
  const double area = (p[1][0] - p[0][0]) * (p[2][1] - p[0][1]) - (p[2][0] - p[0][0]) * (p[1][1] - p[0][1]);
  if (std::abs(area) < 1e-12) return;
  const auto check = [&](double x, double z) {
    std::array<double, 3> l{};
    for (int i = 0; i < 3; ++i) {
      const auto& a = p[(i + 1) % 3];
      const auto& b = p[(i + 2) % 3];
      l[i] = ((a[0] - x) * (b[1] - z) - (b[0] - x) * (a[1] - z)) / area;
    }
    if (l[0] < -1e-9 || l[1] < -1e-9 || l[2] < -1e-9) return;
    double lod = 0;
    for (int i = 0; i < 3; ++i) lod += l[i] * static_cast<double>(g.y[t[i]]);
    const double map = g.surface(x, z);
    const double excess = below ? lod - map : map - lod;
    if (excess <= 0) return;
    for (int i = 0; i < 3; ++i) {
      if (!adjustable[t[i]] || l[i] < 1e-6) continue;
      const double y = static_cast<double>(g.y[t[i]]) + (below ? -excess : excess) / l[i];
      auto [it, fresh] = bound.try_emplace(t[i], y);
      if (!fresh) it->second = below ? std::min(it->second, y) : std::max(it->second, y);
    }
  };
  for (int i = 0; i < 3; ++i) check(p[i][0], p[i][1]);
  const double x0 = std::min({p[0][0], p[1][0], p[2][0]}), x1 = std::max({p[0][0], p[1][0], p[2][0]});
  const double z0 = std::min({p[0][1], p[1][1], p[2][1]}), z1 = std::max({p[0][1], p[1][1], p[2][1]});
  for (double z = std::ceil(z0); z <= z1; z += 1) {
    for (double x = std::ceil(x0); x <= x1; x += 1) check(x, z);
  }
  for (int i = 0; i < 3; ++i) {
    const auto& a = p[i];
    const auto& b = p[(i + 1) % 3];
    const double dx = b[0] - a[0], dz = b[1] - a[1];
    // Lines x = k, z = k and the cell diagonals x - z = k.
    const auto cross_lines = [&](double s0, double ds) {
      if (std::abs(ds) < 1e-12) return;
      const double lo = std::min(s0, s0 + ds), hi = std::max(s0, s0 + ds);
      for (double k = std::ceil(lo); k <= hi; k += 1) {
        const double u = (k - s0) / ds;
        check(a[0] + u * dx, a[1] + u * dz);
      }
    };
    cross_lines(a[0], dx);
    cross_lines(a[1], dz);
    cross_lines(a[0] - a[1], dx - dz);
  }
}

float round_towards(double y, bool below) {
  float f = static_cast<float>(y);
  if (below && static_cast<double>(f) > y) f = std::nextafter(f, -std::numeric_limits<float>::infinity());
  if (!below && static_cast<double>(f) < y) f = std::nextafter(f, std::numeric_limits<float>::infinity());
  return f;
}

// The triangles of patch (px, pz) after `lw`'s moves (nullptr: as the map has them), degenerate ones dropped.
std::vector<std::array<std::uint32_t, 3>> patch_triangles(const Grid& g, const Layout& lay, std::size_t px,
                                                          std::size_t pz, const LevelWalls* lw) {
  std::vector<std::array<std::uint32_t, 3>> out;
  for (std::size_t r = lay.cz0(pz, g); r < lay.cz1(pz, g); ++r) {
    for (std::size_t c = lay.cx0(px, g); c < lay.cx1(px, g); ++c) {
      if (!g.cell_ok(static_cast<std::ptrdiff_t>(c), static_cast<std::ptrdiff_t>(r))) continue;
      for (auto t : cell_triangles(g, c, r)) {
        if (lw) {
          for (auto& v : t) v = rep(*lw, v);
          if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) continue;
        }
        out.push_back(t);
      }
    }
  }
  return out;
}

LevelWalls make_level_walls(const Grid& g, const Layout& lay, const LevelSpec& level, Conservative mode) {
  LevelWalls lw;
  lw.on_wall.assign(g.w * g.h, 0);
  std::vector<Wall> walls;
  for (std::size_t pz = 0; pz <= lay.nz; ++pz) {
    for (std::size_t px = 0; px < lay.nx; ++px) walls.push_back(lay.horizontal(px, pz, g));
  }
  for (std::size_t pz = 0; pz < lay.nz; ++pz) {
    for (std::size_t px = 0; px <= lay.nx; ++px) walls.push_back(lay.vertical(px, pz, g));
  }
  for (const Wall& wall : walls) {
    const std::vector<std::uint8_t> keep = keep_on_wall(g, wall, level);
    std::size_t last = 0;
    for (std::size_t i = 0; i < wall.count; ++i) {
      if (!keep[i]) continue;
      lw.on_wall[wall.at(g, i)] = 1;
      for (std::size_t m = last + 1; m < i; ++m) {
        lw.moved[wall.at(g, m)] = wall.at(g, m - last <= i - m ? last : i);
      }
      last = i;
    }
  }
  if (mode == Conservative::none) return lw;
  const bool below = mode == Conservative::occluder;
  std::unordered_map<std::uint32_t, double> bound;
  for (std::size_t pz = 0; pz < lay.nz; ++pz) {
    for (std::size_t px = 0; px < lay.nx; ++px) {
      for (std::size_t r = lay.cz0(pz, g); r < lay.cz1(pz, g); ++r) {
        for (std::size_t c = lay.cx0(px, g); c < lay.cx1(px, g); ++c) {
          if (!g.cell_ok(static_cast<std::ptrdiff_t>(c), static_cast<std::ptrdiff_t>(r))) continue;
          for (auto t : cell_triangles(g, c, r)) {
            bool changed = false;
            for (auto& v : t) {
              const std::uint32_t to = rep(lw, v);
              changed = changed || to != v;
              v = to;
            }
            if (!changed || t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) continue;
            constrain(g, t, lw.on_wall, below, bound);
          }
        }
      }
    }
  }
  for (const auto& [v, y] : bound) {
    const float f = round_towards(y, below);
    if (below ? f < g.y[v] : f > g.y[v]) lw.height[v] = f;
  }
  return lw;
}

float level_height(const Grid& g, const LevelWalls* lw, std::uint32_t v) {
  if (lw) {
    const auto it = lw->height.find(v);
    if (it != lw->height.end()) return it->second;
  }
  return g.y[v];
}

// Patch mesh from its triangles: vertices in ascending sample order.
Mesh build_mesh(const Grid& g, const LevelWalls* lw, const std::vector<std::array<std::uint32_t, 3>>& tris,
                std::vector<std::uint32_t>& samples) {
  samples.clear();
  for (const auto& t : tris) samples.insert(samples.end(), t.begin(), t.end());
  std::sort(samples.begin(), samples.end());
  samples.erase(std::unique(samples.begin(), samples.end()), samples.end());
  Mesh m;
  m.materials.push_back({});
  std::unordered_map<std::uint32_t, std::uint32_t> local;
  local.reserve(samples.size());
  for (const std::uint32_t v : samples) {
    local[v] =
        m.add_vertex_with_wedge(Vec3f{{static_cast<float>(static_cast<double>(g.col(v)) * g.sx), level_height(g, lw, v),
                                       static_cast<float>(static_cast<double>(g.row(v)) * g.sz)}});
  }
  for (const auto& t : tris) m.add_face({local[t[0]], local[t[1]], local[t[2]]});
  return m;
}

std::vector<std::uint32_t> boundary_vertices(const Mesh& m) {
  std::map<std::pair<std::uint32_t, std::uint32_t>, int> edges;
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    const std::uint32_t b = m.face_offsets[f], n = m.face_size(f);
    for (std::uint32_t i = 0; i < n; ++i) {
      std::uint32_t a = m.corner_vertex(b + i), c = m.corner_vertex(b + (i + 1) % n);
      if (a > c) std::swap(a, c);
      ++edges[{a, c}];
    }
  }
  std::vector<std::uint32_t> out;
  for (const auto& [e, count] : edges) {
    if (count == 1) {
      out.push_back(e.first);
      out.push_back(e.second);
    }
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

// A patch side shared with a neighbour: the wall line and the skirt's bottom.
struct SkirtSide {
  int axis = 2;    // the coordinate constant along the wall: 2 (z) for a wall along x, 0 (x) for one along z
  float line = 0;  // its value
  float bottom = 0;
};

// Appends vertical skirt triangles under every boundary edge of `m` that lies on one of `sides`.
void add_skirts(Mesh& m, const std::vector<SkirtSide>& sides) {
  std::map<std::pair<std::uint32_t, std::uint32_t>, int> count;
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    const std::uint32_t b = m.face_offsets[f];
    for (std::uint32_t i = 0; i < 3; ++i) {
      const std::uint32_t a = m.corner_vertex(b + i), c = m.corner_vertex(b + (i + 1) % 3);
      ++count[{std::min(a, c), std::max(a, c)}];
    }
  }
  std::vector<std::array<std::uint32_t, 2>> edges;  // boundary edges as wedge pairs, in face order
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    const std::uint32_t b = m.face_offsets[f];
    for (std::uint32_t i = 0; i < 3; ++i) {
      const std::uint32_t wa = m.corner_wedge[b + i], wc = m.corner_wedge[b + (i + 1) % 3];
      const std::uint32_t a = m.wedge_vertex[wa], c = m.wedge_vertex[wc];
      if (count[{std::min(a, c), std::max(a, c)}] == 1) edges.push_back({wa, wc});
    }
  }
  std::map<std::pair<std::uint32_t, std::size_t>, std::uint32_t> bottom_of;  // (wedge, side) -> bottom wedge
  for (const auto& [wa, wc] : edges) {
    const Vec3f pa = m.positions[m.wedge_vertex[wa]];
    const Vec3f pc = m.positions[m.wedge_vertex[wc]];
    for (std::size_t s = 0; s < sides.size(); ++s) {
      const SkirtSide& side = sides[s];
      if (pa[side.axis] != side.line || pc[side.axis] != side.line) continue;
      const auto bottom = [&](std::uint32_t w) {
        const auto it = bottom_of.find({w, s});
        if (it != bottom_of.end()) return it->second;
        Vec3f p = m.positions[m.wedge_vertex[w]];
        p[1] = side.bottom;
        const std::uint32_t nw = m.add_vertex_with_wedge(p);
        bottom_of.emplace(std::pair{w, s}, nw);
        return nw;
      };
      const std::uint32_t ba = bottom(wa), bc = bottom(wc);
      // The surface's boundary edge a -> c runs counter-clockwise around the patch seen from above, so the
      // quad below it, walked c -> a -> a' -> c', faces the neighbour.
      m.add_face({wc, wa, ba});
      m.add_face({wc, ba, bc});
      break;
    }
  }
}

std::string settings_text(const io::HeightMap& map, const Options& o) {
  std::ostringstream s;
  s.precision(17);
  s << map.width << 'x' << map.height << ';' << map.layout.spacing_x << ',' << map.layout.spacing_z << ','
    << map.layout.height_scale << ',' << map.layout.height_offset << ',';
  if (map.layout.nodata) {
    s << *map.layout.nodata;
  } else {
    s << '-';
  }
  s << ';' << o.patch_cells << ';' << conservative_name(o.conservative) << ';' << (o.skirts ? "skirts" : "-");
  for (const LevelSpec& l : o.levels) s << ';' << l.ratio << '/' << l.max_error;
  return s.str();
}

}  // namespace

std::vector<std::string> Options::validate() const {
  std::vector<std::string> problems;
  if (patch_cells < 2 || patch_cells > 4096) problems.push_back("patch_cells must be from 2 to 4096");
  for (std::size_t k = 0; k < levels.size(); ++k) {
    const LevelSpec& l = levels[k];
    if (!(l.ratio > 0.0 && l.ratio <= 1.0)) {
      problems.push_back("level " + std::to_string(k + 1) + ": ratio must be in (0, 1]");
    }
    if (!std::isfinite(l.max_error))
      problems.push_back("level " + std::to_string(k + 1) + ": max_error must be a number");
  }
  return problems;
}

std::array<std::uint8_t, 3> patch_colour(std::size_t surface_triangles, std::size_t patch_cells) {
  const double share = static_cast<double>(surface_triangles) /
                       (2.0 * static_cast<double>(patch_cells) * static_cast<double>(patch_cells));
  // Blue, cyan, green, yellow, red at shares 1/1024, 1/181, 1/32, 1/5.7, 1 (log2 steps of 2.5).
  static constexpr std::array<std::array<double, 3>, 5> kStops{
      {{40, 70, 200}, {40, 180, 210}, {70, 190, 80}, {235, 210, 60}, {220, 60, 40}}};
  const double t = (std::log2(std::clamp(share, 1.0 / 1024, 1.0)) + 10.0) / 2.5;  // 0 .. 4
  const std::size_t i = std::min<std::size_t>(static_cast<std::size_t>(t), 3);
  const double u = std::clamp(t - static_cast<double>(i), 0.0, 1.0);
  std::array<std::uint8_t, 3> colour{};
  for (int c = 0; c < 3; ++c) {
    colour[c] = static_cast<std::uint8_t>(std::lround(kStops[i][c] + u * (kStops[i + 1][c] - kStops[i][c])));
  }
  return colour;
}

namespace {

constexpr std::string_view kResultMagic = "lodforge-terrain-result-1\n";

class Writer {
 public:
  void u64(std::uint64_t x) { raw(&x, sizeof x); }
  void str(std::string_view t) {
    u64(t.size());
    out_.append(t);
  }
  template <typename T>
  void vec(const std::vector<T>& v) {
    u64(v.size());
    if (!v.empty()) raw(v.data(), v.size() * sizeof(T));
  }
  void raw(const void* p, std::size_t n) { out_.append(static_cast<const char*>(p), n); }
  std::string take() { return std::move(out_); }

 private:
  std::string out_;
};

class Reader {
 public:
  explicit Reader(std::string_view in) : in_(in) {}
  bool u64(std::uint64_t& x) { return raw(&x, sizeof x); }
  bool size(std::size_t& x) {
    std::uint64_t v = 0;
    if (!u64(v) || v > in_.size()) return false;  // no count exceeds the bytes left
    x = static_cast<std::size_t>(v);
    return true;
  }
  bool str(std::string& t) {
    std::size_t n = 0;
    if (!size(n) || n > in_.size() - at_) return false;
    t.assign(in_.substr(at_, n));
    at_ += n;
    return true;
  }
  template <typename T>
  bool vec(std::vector<T>& v) {
    std::size_t n = 0;
    if (!size(n) || n > (in_.size() - at_) / sizeof(T)) return false;
    v.resize(n);
    return n == 0 || raw(v.data(), n * sizeof(T));
  }
  bool raw(void* p, std::size_t n) {
    if (n > in_.size() - at_) return false;
    std::memcpy(p, in_.data() + at_, n);
    at_ += n;
    return true;
  }
  bool done() const { return at_ == in_.size(); }

 private:
  std::string_view in_;
  std::size_t at_ = 0;
};

// What a patch mesh of build() holds: positions, wedges, faces, one plain material, a name.
bool plain(const Mesh& m) {
  return m.skin.empty() && m.priority.empty() && m.normals.empty() && m.tangents.empty() && m.uvs.empty() &&
         m.colors.empty() && m.color_components.empty() && m.custom.empty() && m.morph_targets.empty() &&
         m.morph_default_weights.empty() && m.face_group.empty() && m.groups.empty() && m.formats.empty() &&
         std::all_of(m.materials.begin(), m.materials.end(), [](const MaterialSlot& s) { return s == MaterialSlot{}; });
}

}  // namespace

std::string encode_result(const Result& result) {
  Writer w;
  w.raw(kResultMagic.data(), kResultMagic.size());
  w.u64(result.patches_x);
  w.u64(result.patches_z);
  w.str(result.settings);
  w.u64(result.patches.size());
  for (const Patch& p : result.patches) {
    for (const std::size_t x : {p.column, p.row, p.first_column, p.first_row, p.columns, p.rows}) w.u64(x);
    w.vec(p.inputs);
    std::vector<std::uint64_t> surface(p.surface_triangles.begin(), p.surface_triangles.end());
    w.vec(surface);
    w.u64(p.lods.size());
    for (const Mesh& m : p.lods) {
      if (!plain(m)) return {};
      w.str(m.name);
      w.u64(m.materials.size());
      w.vec(m.positions);
      w.vec(m.wedge_vertex);
      w.vec(m.face_offsets);
      w.vec(m.corner_wedge);
      w.vec(m.face_material);
    }
  }
  return w.take();
}

std::optional<Result> decode_result(std::string_view bytes) {
  if (bytes.substr(0, kResultMagic.size()) != kResultMagic) return std::nullopt;
  Reader r(bytes.substr(kResultMagic.size()));
  Result out;
  std::size_t count = 0;
  if (!r.size(out.patches_x) || !r.size(out.patches_z) || !r.str(out.settings) || !r.size(count)) return std::nullopt;
  out.patches.resize(count);
  for (Patch& p : out.patches) {
    for (std::size_t* x : {&p.column, &p.row, &p.first_column, &p.first_row, &p.columns, &p.rows}) {
      if (!r.size(*x)) return std::nullopt;
    }
    std::vector<std::uint64_t> surface;
    std::size_t levels = 0;
    if (!r.vec(p.inputs) || !r.vec(surface) || !r.size(levels)) return std::nullopt;
    p.surface_triangles.assign(surface.begin(), surface.end());
    p.lods.resize(levels);
    for (Mesh& m : p.lods) {
      std::size_t materials = 0;
      if (!r.str(m.name) || !r.size(materials) || !r.vec(m.positions) || !r.vec(m.wedge_vertex) ||
          !r.vec(m.face_offsets) || !r.vec(m.corner_wedge) || !r.vec(m.face_material)) {
        return std::nullopt;
      }
      m.materials.assign(materials, MaterialSlot{});
    }
    p.rebuilt = false;
  }
  if (!r.done()) return std::nullopt;
  return out;
}

Mesh level_surface(const Result& result, std::size_t level, std::size_t patch_cells,
                   std::vector<std::array<std::uint8_t, 3>>* face_colours) {
  Mesh out;
  out.materials.push_back({});
  out.name = "terrain_level_" + std::to_string(level);
  if (face_colours) face_colours->clear();
  for (const Patch& p : result.patches) {
    if (level >= p.lods.size()) continue;
    const Mesh& m = p.lods[level];
    const std::uint32_t base = static_cast<std::uint32_t>(out.vertex_count());
    for (const Vec3f& q : m.positions) out.add_vertex_with_wedge(q);
    const std::array<std::uint8_t, 3> colour = patch_colour(p.surface_triangles[level], patch_cells);
    for (std::size_t f = 0; f < p.surface_triangles[level]; ++f) {
      const std::uint32_t b = m.face_offsets[f];
      out.add_face({base + m.wedge_vertex[m.corner_wedge[b]], base + m.wedge_vertex[m.corner_wedge[b + 1]],
                    base + m.wedge_vertex[m.corner_wedge[b + 2]]});
      if (face_colours) face_colours->push_back(colour);
    }
  }
  return out;
}

Mesh full_surface(const io::HeightMap& map) {
  const Grid g = make_grid(map);
  std::vector<std::array<std::uint32_t, 3>> tris;
  for (std::size_t r = 0; r + 1 < g.h; ++r) {
    for (std::size_t c = 0; c + 1 < g.w; ++c) {
      if (!g.cell_ok(static_cast<std::ptrdiff_t>(c), static_cast<std::ptrdiff_t>(r))) continue;
      for (const auto& t : cell_triangles(g, c, r)) tris.push_back(t);
    }
  }
  std::vector<std::uint32_t> samples;
  Mesh m = build_mesh(g, nullptr, tris, samples);
  m.name = "terrain";
  return m;
}

Result build(const io::HeightMap& map, const Options& options, const Result* previous) {
  if (const auto problems = options.validate(); !problems.empty()) {
    throw std::invalid_argument("terrain options: " + problems.front());
  }
  if (map.width < 2 || map.height < 2 || map.samples.size() != map.width * map.height) {
    throw std::invalid_argument("terrain: the height map's size does not match its samples");
  }
  const Grid g = make_grid(map);
  Layout lay;
  lay.cells = options.patch_cells;
  lay.nx = (g.w - 1 + lay.cells - 1) / lay.cells;
  lay.nz = (g.h - 1 + lay.cells - 1) / lay.cells;
  const std::size_t levels = options.levels.size();

  std::vector<LevelWalls> walls(levels);
  tbb::task_arena arena(options.threads == 0 ? tbb::task_arena::automatic : static_cast<int>(options.threads));
  arena.execute([&] {
    tbb::parallel_for(std::size_t{0}, levels, [&](std::size_t k) {
      walls[k] = make_level_walls(g, lay, options.levels[k], options.conservative);
    });
  });

  Result result;
  result.patches_x = lay.nx;
  result.patches_z = lay.nz;
  result.patches.resize(lay.nx * lay.nz);
  const std::string settings = settings_text(map, options);
  const bool reuse = previous && previous->patches_x == lay.nx && previous->patches_z == lay.nz &&
                     previous->patches.size() == result.patches.size() && previous->settings == settings;
  result.settings = settings;

  // The bottom of each wall's skirt: below every level's polyline on it.
  const float margin = static_cast<float>(std::max(1e-3 * std::max(g.sx, g.sz), 1e-6));
  const auto wall_bottom = [&](const Wall& wall) {
    float lowest = std::numeric_limits<float>::infinity();
    for (std::size_t i = 0; i < wall.count; ++i) {
      const std::uint32_t v = wall.at(g, i);
      if (g.hole[v]) continue;
      lowest = std::min(lowest, g.y[v]);
      for (const LevelWalls& lw : walls) lowest = std::min(lowest, level_height(g, &lw, v));
    }
    return lowest - margin;
  };

  std::vector<std::size_t> todo;
  for (std::size_t pz = 0; pz < lay.nz; ++pz) {
    for (std::size_t px = 0; px < lay.nx; ++px) {
      Patch& p = result.patches[pz * lay.nx + px];
      p.column = px;
      p.row = pz;
      p.first_column = lay.cx0(px, g);
      p.first_row = lay.cz0(pz, g);
      p.columns = lay.cx1(px, g) - p.first_column;
      p.rows = lay.cz1(pz, g) - p.first_row;
      const std::size_t c0 = p.first_column == 0 ? 0 : p.first_column - 1;
      const std::size_t r0 = p.first_row == 0 ? 0 : p.first_row - 1;
      const std::size_t c1 = std::min(p.first_column + p.columns + 1, g.w - 1);
      const std::size_t r1 = std::min(p.first_row + p.rows + 1, g.h - 1);
      for (std::size_t r = r0; r <= r1; ++r) {
        p.inputs.insert(p.inputs.end(), map.samples.begin() + static_cast<std::ptrdiff_t>(r * g.w + c0),
                        map.samples.begin() + static_cast<std::ptrdiff_t>(r * g.w + c1 + 1));
      }
      const std::size_t index = pz * lay.nx + px;
      if (reuse && previous->patches[index].inputs == p.inputs) {
        p.lods = previous->patches[index].lods;
        p.surface_triangles = previous->patches[index].surface_triangles;
        p.rebuilt = false;
      } else {
        p.lods.resize(levels + 1);
        p.surface_triangles.resize(levels + 1);
        todo.push_back(index);
      }
    }
  }
  result.rebuilt = todo.size();

  arena.execute([&] {
    tbb::parallel_for(std::size_t{0}, todo.size() * (levels + 1), [&](std::size_t task) {
      Patch& p = result.patches[todo[task / (levels + 1)]];
      const std::size_t k = task % (levels + 1);
      const LevelWalls* lw = k == 0 ? nullptr : &walls[k - 1];
      std::vector<std::uint32_t> samples;
      const auto tris = patch_triangles(g, lay, p.column, p.row, lw);
      const std::size_t full = 2 * [&] {
        std::size_t cells = 0;
        for (std::size_t r = p.first_row; r < p.first_row + p.rows; ++r) {
          for (std::size_t c = p.first_column; c < p.first_column + p.columns; ++c) {
            cells += g.cell_ok(static_cast<std::ptrdiff_t>(c), static_cast<std::ptrdiff_t>(r));
          }
        }
        return cells;
      }();
      Mesh mesh = build_mesh(g, lw, tris, samples);
      if (k > 0 && mesh.face_count() > 0) {
        const LevelSpec& level = options.levels[k - 1];
        SimplifyOptions so;
        so.target_triangles =
            std::max<std::size_t>(1, static_cast<std::size_t>(std::llround(level.ratio * static_cast<double>(full))));
        so.max_error_abs = level.max_error;
        so.border_mode = BorderMode::lock;
        so.locked_vertices = boundary_vertices(mesh);
        so.conservative = options.conservative;
        so.height_field_axis = 1;
        so.threads = 1;
        so.seams = SeamMode::keep;
        mesh = simplify(mesh, so).mesh;
      }
      p.surface_triangles[k] = mesh.triangle_count();
      if (options.skirts) {
        std::vector<SkirtSide> sides;
        // Positions on a wall are computed as build_mesh computes them, so the comparison is exact.
        const auto wall_z = [&](std::size_t r) { return static_cast<float>(static_cast<double>(r) * g.sz); };
        const auto wall_x = [&](std::size_t c) { return static_cast<float>(static_cast<double>(c) * g.sx); };
        if (p.row > 0) sides.push_back({2, wall_z(p.first_row), wall_bottom(lay.horizontal(p.column, p.row, g))});
        if (p.row + 1 < lay.nz) {
          sides.push_back({2, wall_z(p.first_row + p.rows), wall_bottom(lay.horizontal(p.column, p.row + 1, g))});
        }
        if (p.column > 0) sides.push_back({0, wall_x(p.first_column), wall_bottom(lay.vertical(p.column, p.row, g))});
        if (p.column + 1 < lay.nx) {
          sides.push_back({0, wall_x(p.first_column + p.columns), wall_bottom(lay.vertical(p.column + 1, p.row, g))});
        }
        add_skirts(mesh, sides);
      }
      mesh.name = "patch_" + std::to_string(p.column) + "_" + std::to_string(p.row);
      p.lods[k] = std::move(mesh);
    });
  });
  return result;
}

}  // namespace lodforge::terrain
