// Tiled simplification: cut by centroid cell, simplify the tiles in parallel with their borders locked,
// stitch, cut again on a shifted grid (docs/tiling.md).
#include "lodforge/tiling/tiling.hpp"

#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>

#include "../simplify/engines.hpp"
#include "tiles.hpp"

namespace lodforge::tiling {

using detail::global_target;
using detail::may_tile;
using detail::stitch;
using detail::TileRun;
using detail::track_locked;

namespace {

bool same_bits(const Vec3f& a, const Vec3f& b) {
  return std::memcmp(a.v.data(), b.v.data(), sizeof(float) * 3) == 0;
}

template <class T>
bool same_bits(const T& a, const T& b) {
  return std::memcmp(&a, &b, sizeof(T)) == 0;
}

Vec3d centroid(const Mesh& m, std::size_t f) {
  const std::uint32_t c = m.face_offsets[f];
  Vec3d s{};
  for (int i = 0; i < 3; ++i) s = s + to_double(m.positions[m.corner_vertex(c + i)]);
  return s * (1.0 / 3.0);
}

// Whether two wedges (of the same stitched vertex, one from each of two tile outputs) carry the same
// attributes. Tangents are left out: they are recomputed over the stitched faces.
bool same_wedge(const Mesh& a, std::uint32_t wa, const Mesh& b, std::uint32_t wb) {
  if (!a.normals.empty() && !same_bits(a.normals[wa], b.normals[wb])) return false;
  for (std::size_t s = 0; s < a.uvs.size(); ++s) {
    if (!a.uvs[s].empty() && !same_bits(a.uvs[s][wa], b.uvs[s][wb])) return false;
  }
  for (std::size_t s = 0; s < a.colors.size(); ++s) {
    if (!a.colors[s].empty() && !same_bits(a.colors[s][wa], b.colors[s][wb])) return false;
  }
  for (std::size_t k = 0; k < a.custom.size(); ++k) {
    const std::size_t n = static_cast<std::size_t>(a.custom[k].components);
    if (std::memcmp(&a.custom[k].values[wa * n], &b.custom[k].values[wb * n], n * sizeof(float)) != 0) return false;
  }
  for (std::size_t t = 0; t < a.morph_targets.size(); ++t) {
    const MorphTarget& ma = a.morph_targets[t];
    const MorphTarget& mb = b.morph_targets[t];
    if (!ma.position_deltas.empty() && !same_bits(ma.position_deltas[wa], mb.position_deltas[wb])) return false;
    if (!ma.normal_deltas.empty() && !same_bits(ma.normal_deltas[wa], mb.normal_deltas[wb])) return false;
    if (!ma.tangent_deltas.empty() && !same_bits(ma.tangent_deltas[wa], mb.tangent_deltas[wb])) return false;
  }
  return true;
}

// Appends wedge `w` of `src` (every per-wedge stream `dst` has) to `dst`, on vertex `vertex`.
void append_wedge(Mesh& dst, const Mesh& src, std::uint32_t w, std::uint32_t vertex) {
  dst.wedge_vertex.push_back(vertex);
  if (!src.normals.empty()) dst.normals.push_back(src.normals[w]);
  if (!src.tangents.empty()) dst.tangents.push_back(src.tangents[w]);
  for (std::size_t s = 0; s < src.uvs.size(); ++s) {
    if (!src.uvs[s].empty()) dst.uvs[s].push_back(src.uvs[s][w]);
  }
  for (std::size_t s = 0; s < src.colors.size(); ++s) {
    if (!src.colors[s].empty()) dst.colors[s].push_back(src.colors[s][w]);
  }
  for (std::size_t k = 0; k < src.custom.size(); ++k) {
    const std::size_t n = static_cast<std::size_t>(src.custom[k].components);
    const float* v = &src.custom[k].values[w * n];
    dst.custom[k].values.insert(dst.custom[k].values.end(), v, v + n);
  }
  for (std::size_t t = 0; t < src.morph_targets.size(); ++t) {
    const MorphTarget& m = src.morph_targets[t];
    MorphTarget& d = dst.morph_targets[t];
    if (!m.position_deltas.empty()) d.position_deltas.push_back(m.position_deltas[w]);
    if (!m.normal_deltas.empty()) d.normal_deltas.push_back(m.normal_deltas[w]);
    if (!m.tangent_deltas.empty()) d.tangent_deltas.push_back(m.tangent_deltas[w]);
  }
}

// `src`'s vertex-independent data (materials, groups, formats, attribute layouts) with no vertices or faces.
Mesh empty_like(const Mesh& src) {
  Mesh m;
  m.name = src.name;
  m.materials = src.materials;
  m.groups = src.groups;
  m.formats = src.formats;
  m.color_components = src.color_components;
  m.morph_default_weights = src.morph_default_weights;
  m.uvs.resize(src.uvs.size());
  m.colors.resize(src.colors.size());
  for (const CustomAttribute& c : src.custom) m.custom.push_back({c.name, c.components, c.format, {}});
  for (const MorphTarget& t : src.morph_targets) m.morph_targets.push_back({t.name, {}, {}, {}});
  return m;
}

TileRun run_tile(const Mesh& mesh, const TileCut& c, std::size_t t, const std::vector<std::uint8_t>& user_locked,
                 std::size_t global_target_triangles, std::size_t pass_triangles, const SimplifyOptions& tile_options) {
  std::vector<std::uint32_t> vertices;
  const Mesh sub = extract(mesh, c.tiles[t], vertices);
  SimplifyOptions o = tile_options;
  for (std::uint32_t i = 0; i < vertices.size(); ++i) {
    if (c.border[vertices[i]] || user_locked[vertices[i]]) o.locked_vertices.push_back(i);
  }
  o.target_triangles = detail::tile_share(global_target_triangles, c.tiles[t].size(), pass_triangles);
  TileRun run;
  run.result = simplify(sub, o);
  track_locked(run, sub, o.locked_vertices, vertices, t);
  return run;
}

}  // namespace

namespace detail {

std::size_t global_target(const SimplifyOptions& o, std::size_t n) {
  return std::max<std::size_t>(1, collapse::stop_rule(o, n, 0.0).target_triangles);
}

// applies() without the size: whether these options may tile a mesh at all.
bool may_tile(const SimplifyOptions& options) { return why_not_tileable(options) == nullptr; }

double cell_size(double area, std::size_t triangles, std::size_t tile_triangles, double diagonal) {
  const double per_tile = static_cast<double>(std::max<std::size_t>(tile_triangles, 1)) /
                          static_cast<double>(std::max<std::size_t>(triangles, 1));
  double cell = std::sqrt(area * per_tile);
  if (!(cell > 0.0) || !std::isfinite(cell)) cell = diagonal * std::cbrt(per_tile);
  if (std::isfinite(diagonal)) cell = std::max(cell, diagonal / static_cast<double>(kCellMax / 2));
  return cell;
}

SimplifyOptions tile_base_options(const SimplifyOptions& options, double diagonal) {
  SimplifyOptions base = options;
  base.tiling = TilingMode::off;
  base.symmetry_weight = 0.0;
  base.vertex_mirror = nullptr;
  base.target_ratio = 1.0;
  base.locked_vertices.clear();
  if (options.max_error_rel >= 0.0) {
    const double rel = options.max_error_rel * diagonal;
    base.max_error_abs = base.max_error_abs >= 0.0 ? std::min(base.max_error_abs, rel) : rel;
    base.max_error_rel = -1.0;
  }
  return base;
}

unsigned concurrency(const SimplifyOptions& options) {
  return options.threads ? options.threads : static_cast<unsigned>(tbb::this_task_arena::max_concurrency());
}

unsigned tile_threads(const SimplifyOptions& options, std::size_t tiles) {
  return tiles >= 2 * std::size_t{concurrency(options)} ? 1 : options.threads;
}

std::size_t first_pass_target(std::size_t target, std::size_t n) {
  const std::size_t oversampled = target * kOversample;
  return oversampled < n / 2 ? oversampled : target;
}

std::size_t cluster_stage_target(const SimplifyOptions& options, std::size_t n, std::size_t target) {
  // Clustering moves every vertex (a conservative LOD would not nest), renumbers them (locked ones would be
  // lost) and has no error budget of its own to share.
  if (options.cluster_stage == TilingMode::off || options.conservative != Conservative::none ||
      !options.locked_vertices.empty() || options.max_error_abs >= 0.0 || options.max_error_rel >= 0.0) {
    return 0;
  }
  const double wanted = options.cluster_stage_factor * static_cast<double>(target);
  if (!(wanted >= static_cast<double>(target)) || !(wanted < static_cast<double>(n))) return 0;
  const auto at = static_cast<std::size_t>(wanted);
  if (options.cluster_stage == TilingMode::automatic && (n < kAutoClusterTriangles || at > n / 4)) return 0;
  return at;
}

std::size_t tile_share(std::size_t pass_target, std::size_t tile_triangles, std::size_t pass_triangles) {
  const std::size_t total = std::max<std::size_t>(pass_triangles, 1);
  return std::max<std::size_t>(1, (pass_target * tile_triangles + total / 2) / total);
}

void add_stats(SimplifyResult& total, const SimplifyResult& r) {
  total.qem_error_abs = std::max(total.qem_error_abs, r.qem_error_abs);
  total.collapses += r.collapses;
  total.rounds += r.rounds;
  total.vetoes += r.vetoes;
  total.seam_stage = std::max(total.seam_stage, r.seam_stage);
}

void track_locked(TileRun& run, const Mesh& sub, const std::vector<std::uint32_t>& locked,
                  const std::vector<std::uint32_t>& source_of, std::size_t tile) {
  // Locked vertices never move and survivors keep their order: a merge walk over exact positions finds them.
  const Mesh& out = run.result.mesh;
  std::size_t p = 0;
  for (std::uint32_t j = 0; j < out.vertex_count() && p < locked.size(); ++j) {
    if (same_bits(out.positions[j], sub.positions[locked[p]])) {
      run.tracked_source.push_back(source_of[locked[p]]);
      run.tracked_output.push_back(j);
      ++p;
    }
  }
  if (p != locked.size()) {
    throw std::logic_error("tiling: a locked border vertex of tile " + std::to_string(tile) + " moved or vanished");
  }
}

// The tiles' outputs as one mesh, in tile order: tracked vertices (borders, user locks) weld to one vertex each,
// and their wedges with the same attributes to one wedge. `locked` (per vertex of the pass's mesh) becomes the
// user locks of the stitched mesh.
Mesh stitch(const Mesh& like, std::size_t source_vertices, const std::vector<TileRun>& runs,
            std::vector<std::uint8_t>& locked, const SimplifyOptions& options) {
  Mesh out = empty_like(like);
  std::size_t nv = 0, nw = 0, nc = 0;
  for (const TileRun& r : runs) {
    nv += r.result.mesh.vertex_count();
    nw += r.result.mesh.wedge_count();
    nc += r.result.mesh.corner_count();
  }
  out.positions.reserve(nv);
  out.wedge_vertex.reserve(nw);
  out.corner_wedge.reserve(nc);
  out.face_offsets.reserve(nc / 3 + 1);
  out.face_material.reserve(nc / 3);
  std::vector<std::uint8_t> next_locked;
  next_locked.reserve(nv);
  std::vector<std::uint32_t> global_of_source(source_vertices, kInvalidIndex);
  // Wedges made so far on each welded vertex, for the weld of equal wedges.
  struct MadeWedge {
    std::uint32_t tile, local, global;  // the tile output it came from, its id there, its id in `out`
  };
  std::unordered_map<std::uint32_t, std::vector<MadeWedge>> welded_wedges;
  std::vector<std::uint32_t> vertex_map, wedge_map;
  std::vector<std::uint8_t> tracked;
  for (std::size_t t = 0; t < runs.size(); ++t) {
    const Mesh& m = runs[t].result.mesh;
    vertex_map.assign(m.vertex_count(), kInvalidIndex);
    tracked.assign(m.vertex_count(), 0);
    for (std::size_t i = 0; i < runs[t].tracked_output.size(); ++i) {
      const std::uint32_t j = runs[t].tracked_output[i], s = runs[t].tracked_source[i];
      tracked[j] = 1;
      if (global_of_source[s] == kInvalidIndex) {
        global_of_source[s] = static_cast<std::uint32_t>(out.positions.size());
        out.positions.push_back(m.positions[j]);
        if (!m.skin.empty()) out.skin.push_back(m.skin[j]);
        if (!m.priority.empty()) out.priority.push_back(m.priority[j]);
        next_locked.push_back(locked[s]);
      }
      vertex_map[j] = global_of_source[s];
    }
    for (std::uint32_t j = 0; j < m.vertex_count(); ++j) {
      if (vertex_map[j] != kInvalidIndex) continue;
      vertex_map[j] = static_cast<std::uint32_t>(out.positions.size());
      out.positions.push_back(m.positions[j]);
      if (!m.skin.empty()) out.skin.push_back(m.skin[j]);
      if (!m.priority.empty()) out.priority.push_back(m.priority[j]);
      next_locked.push_back(0);
    }
    wedge_map.assign(m.wedge_count(), kInvalidIndex);
    for (std::uint32_t w = 0; w < m.wedge_count(); ++w) {
      const std::uint32_t v = m.wedge_vertex[w], g = vertex_map[v];
      if (tracked[v]) {
        auto& list = welded_wedges[g];
        for (const MadeWedge& made : list) {
          if (made.tile != t && same_wedge(runs[made.tile].result.mesh, made.local, m, w)) {
            wedge_map[w] = made.global;
            break;
          }
        }
        if (wedge_map[w] != kInvalidIndex) continue;
        list.push_back({static_cast<std::uint32_t>(t), w, static_cast<std::uint32_t>(out.wedge_count())});
      }
      wedge_map[w] = static_cast<std::uint32_t>(out.wedge_count());
      append_wedge(out, m, w, g);
    }
    const bool groups = m.face_group.size() == m.face_count();
    for (std::size_t f = 0; f < m.face_count(); ++f) {
      const std::uint32_t c = m.face_offsets[f];
      const std::uint32_t w[3] = {wedge_map[m.corner_wedge[c]], wedge_map[m.corner_wedge[c + 1]],
                                  wedge_map[m.corner_wedge[c + 2]]};
      out.add_face(w, 3, f < m.face_material.size() ? m.face_material[f] : 0);
      if (groups) out.face_group.push_back(m.face_group[f]);
    }
  }
  if (options.attribute_placement == AttributePlacement::optimal && !out.tangents.empty()) {
    collapse::recompute_tangents(out);
  }
  locked = std::move(next_locked);
  return out;
}

}  // namespace detail

double pass_shift(int pass) {
  static constexpr double kShifts[] = {0.0, 0.5, 0.25, 0.75};
  return kShifts[pass % 4];
}

const char* why_not_tileable(const SimplifyOptions& options) {
  if (options.tiling == TilingMode::off) return "tiling is off";
  if (options.engine != Engine::edge_collapse && options.engine != Engine::multiple_choice) {
    return "this engine cannot tile";
  }
  // A volume budget is a fraction of the whole mesh's volume: a tile (an open piece) has none of its own.
  if (options.conservative != Conservative::none && options.max_volume_growth >= 0.0) {
    return "a volume budget cannot tile";
  }
  if (options.verifies_budget()) return "a verified error budget cannot tile (--no-verify can)";
  return nullptr;
}

bool applies(const Mesh& triangles, const SimplifyOptions& options) {
  if (!may_tile(options)) return false;
  return options.tiling != TilingMode::automatic || triangles.face_count() >= kAutoThresholdTriangles;
}

TileCut cut(const Mesh& triangles, std::size_t tile_triangles, double shift) {
  TileCut c;
  c.shift = shift;
  const std::size_t n = triangles.face_count();
  c.border.assign(triangles.vertex_count(), 0);
  if (n == 0) return c;
  Bounds3 box;
  double area = 0;
  for (std::size_t f = 0; f < n; ++f) {  // sequential: the sum's order is fixed
    const Vec3d p = centroid(triangles, f);
    if (!collapse::finite3(p)) continue;
    box.add(p);
    const std::uint32_t k = triangles.face_offsets[f];
    const Vec3d a = to_double(triangles.positions[triangles.corner_vertex(k)]);
    const Vec3d e1 = to_double(triangles.positions[triangles.corner_vertex(k + 1)]) - a;
    const Vec3d e2 = to_double(triangles.positions[triangles.corner_vertex(k + 2)]) - a;
    area += 0.5 * length(cross(e1, e2));
  }
  const double cell = detail::cell_size(area, n, tile_triangles, box.diagonal());
  c.cell = cell;
  std::vector<std::uint64_t> key(n);
  const bool one_tile = !(cell > 0.0) || !std::isfinite(cell);
  const Vec3d origin = box.min - Vec3d{{shift * cell, shift * cell, shift * cell}};
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1 << 14), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t f = r.begin(); f != r.end(); ++f) {
      const Vec3d p = centroid(triangles, f);
      if (one_tile || !collapse::finite3(p)) {
        key[f] = 0;
        continue;
      }
      key[f] = detail::cell_key(p, origin, cell);
    }
  });
  std::vector<std::uint64_t> cells = key;
  tbb::parallel_sort(cells.begin(), cells.end());
  cells.erase(std::unique(cells.begin(), cells.end()), cells.end());
  std::vector<std::uint32_t> tile_of(n);
  std::vector<std::size_t> count(cells.size(), 0);
  for (std::size_t f = 0; f < n; ++f) {
    tile_of[f] = static_cast<std::uint32_t>(std::lower_bound(cells.begin(), cells.end(), key[f]) - cells.begin());
    ++count[tile_of[f]];
  }
  key = {};
  c.tiles.resize(cells.size());
  for (std::size_t t = 0; t < cells.size(); ++t) c.tiles[t].reserve(count[t]);
  std::vector<std::uint32_t> first_tile(triangles.vertex_count(), kInvalidIndex);
  for (std::size_t f = 0; f < n; ++f) {
    const std::uint32_t t = tile_of[f];
    c.tiles[t].push_back(static_cast<std::uint32_t>(f));
    for (std::uint32_t k = triangles.face_offsets[f]; k < triangles.face_offsets[f + 1]; ++k) {
      const std::uint32_t v = triangles.corner_vertex(k);
      if (first_tile[v] == kInvalidIndex) {
        first_tile[v] = t;
      } else if (first_tile[v] != t) {
        c.border[v] = 1;
      }
    }
  }
  return c;
}

Mesh extract(const Mesh& triangles, const std::vector<std::uint32_t>& faces, std::vector<std::uint32_t>& vertices) {
  std::vector<std::uint32_t> wedge_map(triangles.wedge_count(), kInvalidIndex);
  for (std::uint32_t f : faces) {
    for (std::uint32_t k = triangles.face_offsets[f]; k < triangles.face_offsets[f + 1]; ++k) {
      wedge_map[triangles.corner_wedge[k]] = 0;
    }
  }
  Mesh m = compact_vertices_and_wedges(triangles, wedge_map, vertices);
  const bool groups = triangles.face_group.size() == triangles.face_count();
  m.face_offsets.reserve(faces.size() + 1);
  m.corner_wedge.reserve(3 * faces.size());
  for (std::uint32_t f : faces) {
    std::uint32_t w[3];
    const std::uint32_t k = triangles.face_offsets[f];
    for (int i = 0; i < 3; ++i) w[i] = wedge_map[triangles.corner_wedge[k + i]];
    m.add_face(w, 3, f < triangles.face_material.size() ? triangles.face_material[f] : 0);
    if (groups) m.face_group.push_back(triangles.face_group[f]);
  }
  return m;
}

std::size_t parse_memory_size(const std::string& text) {
  auto bad = [&](const std::string& why) {
    return std::invalid_argument("memory limit '" + text + "': " + why);
  };
  std::size_t i = 0;
  std::uint64_t value = 0;
  while (i < text.size() && text[i] >= '0' && text[i] <= '9') {
    if (value > (std::uint64_t{1} << 50)) throw bad("too large");
    value = value * 10 + static_cast<std::uint64_t>(text[i] - '0');
    ++i;
  }
  if (i == 0) throw bad("expected a number of bytes with an optional K, M, G or T suffix (e.g. 512M, 4G)");
  std::string unit;
  for (; i < text.size(); ++i) unit += static_cast<char>(std::toupper(static_cast<unsigned char>(text[i])));
  int shift = 0;
  if (!unit.empty() && std::string("KMGT").find(unit[0]) != std::string::npos) {
    shift = 10 * (1 + static_cast<int>(std::string("KMGT").find(unit[0])));
    unit.erase(0, 1);
  }
  if (!unit.empty() && unit != "B" && !(shift > 0 && unit == "IB")) {
    throw bad("expected a number of bytes with an optional K, M, G or T suffix (e.g. 512M, 4G)");
  }
  if (shift > 0 && value > (std::uint64_t{1} << (62 - shift))) throw bad("too large");
  const std::uint64_t bytes = value << shift;
  if (bytes < kMinMemoryLimit) throw bad("below the smallest accepted limit, 16M");
  return static_cast<std::size_t>(bytes);
}

std::size_t mesh_bytes(const Mesh& m) {
  auto b = [](const auto& v) { return v.size() * sizeof(v[0]); };
  std::size_t n = b(m.positions) + b(m.skin) + b(m.priority) + b(m.wedge_vertex) + b(m.normals) + b(m.tangents) +
                  b(m.face_offsets) + b(m.corner_wedge) + b(m.face_material) + b(m.face_group);
  for (const auto& u : m.uvs) n += b(u);
  for (const auto& c : m.colors) n += b(c);
  for (const CustomAttribute& c : m.custom) n += b(c.values);
  for (const MorphTarget& t : m.morph_targets) n += b(t.position_deltas) + b(t.normal_deltas) + b(t.tangent_deltas);
  return n;
}

void MemoryPlan::apply(SimplifyOptions& options) const {
  if (!force_tiling) return;
  options.tiling = TilingMode::on;
  options.tile_triangles = tile_triangles;
  options.cluster_stage = TilingMode::off;
}

MemoryPlan plan_memory(const Mesh& mesh, const SimplifyOptions& options, std::size_t limit, unsigned workers) {
  MemoryPlan p;
  const std::size_t n = mesh.triangle_count();
  p.input_bytes = mesh_bytes(mesh);
  p.untiled_bytes = p.input_bytes + kUntiledBytesPerTriangle * n;
  // An eighth of the limit is kept for what the estimate leaves out: the program, allocator slack, the
  // loader's leftovers (a 2M-triangle run measured 7% over its limit without this margin).
  limit -= limit / 8;
  if (p.untiled_bytes <= limit) return p;
  if (!may_tile(options)) {
    p.fits = false;
    return p;
  }
  // Each tile is a copy of its part of the input plus its engine's working set; `workers` tiles run at once,
  // and the final untiled run takes up to kFinalTiles tiles' worth of triangles.
  const std::size_t per_tile_triangle = kUntiledBytesPerTriangle + (n > 0 ? p.input_bytes / n : 0) + 1;
  const std::size_t fixed = p.input_bytes + kTiledBytesPerTriangle * n;
  const std::size_t slots = std::max<std::size_t>(workers, 1) + kFinalTiles;
  const std::size_t tile = fixed < limit ? (limit - fixed) / (per_tile_triangle * slots) : 0;
  p.tile_triangles = std::min(tile, options.tile_triangles);
  p.tiled_bytes = fixed + per_tile_triangle * slots * p.tile_triangles;
  p.fits = p.tile_triangles >= 100;
  p.force_tiling = p.fits;
  return p;
}

SimplifyResult simplify_tiled(const Mesh& triangles, const SimplifyOptions& options) {
  const std::size_t before = triangles.face_count();
  const std::size_t target = global_target(options, before);
  const std::size_t tile_triangles = options.tile_triangles;
  const double diagonal = compute_bounds(triangles).diagonal();

  std::vector<std::uint8_t> locked(triangles.vertex_count(), 0);
  for (std::uint32_t v : options.locked_vertices) {
    if (v >= triangles.vertex_count()) {
      throw std::invalid_argument("simplify: locked vertex " + std::to_string(v) + " out of range (mesh has " +
                                  std::to_string(triangles.vertex_count()) + " vertices)");
    }
    locked[v] = 1;
  }

  const SimplifyOptions base = detail::tile_base_options(options, diagonal);
  tbb::task_arena arena(options.threads ? static_cast<int>(options.threads) : tbb::task_arena::automatic);

  SimplifyResult total;
  total.triangles_before = before;
  Mesh current;
  const Mesh* mesh = &triangles;
  double collapse_ms = 0;
  bool stopped = false, finished = false, over_budget = false;
  // The cluster stage: the whole mesh vertex-clustered to a few times the target in a few linear passes; the
  // edge engine's passes below make the LOD from that.
  if (const std::size_t cluster_target = detail::cluster_stage_target(options, before, target); cluster_target > 0) {
    const auto t0 = std::chrono::steady_clock::now();
    SimplifyOptions co = base;
    co.engine = Engine::cluster;
    co.target_triangles = cluster_target;
    SimplifyResult r = collapse::run_cluster(triangles, co, true);
    total.cluster_stage_ms = collapse::elapsed_ms(t0);
    total.timings.setup_ms += total.cluster_stage_ms;
    total.cluster_stage_triangles = r.triangles_after;
    stopped = r.stop_reason == StopReason::stopped;
    current = std::move(r.mesh);
    mesh = &current;
    locked.assign(current.vertex_count(), 0);  // the stage runs only without locked vertices
  }
  for (int pass = 0; pass < kMaxPasses && !finished && !stopped; ++pass) {
    const std::size_t n = mesh->face_count();
    if (n <= target) break;
    const auto t0 = std::chrono::steady_clock::now();
    // The first pass oversamples (tiles cut to a count alone would get the same density everywhere); later
    // passes go to the target itself.
    const std::size_t oversampled = target * kOversample;
    const std::size_t pass_target = pass == 0 ? detail::first_pass_target(target, n) : target;
    const std::size_t untiled_limit =
        std::max(tile_triangles, std::min(oversampled + oversampled / 2, kFinalTiles * tile_triangles));
    TileCut c;
    if (n > untiled_limit && pass + 1 < kMaxPasses) c = cut(*mesh, tile_triangles, pass_shift(pass));
    if (c.tiles.size() <= 1) {
      // The mesh fits in one tile (or this is the last pass): one untiled run finishes it.
      SimplifyOptions o = base;
      o.target_triangles = target;
      for (std::uint32_t v = 0; v < locked.size(); ++v) {
        if (locked[v]) o.locked_vertices.push_back(v);
      }
      SimplifyResult r = simplify(*mesh, o);
      ++total.tiling_passes;
      ++total.tile_runs;
      collapse_ms += collapse::elapsed_ms(t0);
      detail::add_stats(total, r);
      total.floors = r.floors;
      stopped = r.stop_reason == StopReason::stopped;
      over_budget = over_budget || r.stop_reason == StopReason::error_budget;
      current = std::move(r.mesh);
      mesh = &current;
      finished = true;
      break;
    }
    SimplifyOptions tile_options = base;
    tile_options.threads = detail::tile_threads(options, c.tiles.size());
    std::vector<TileRun> runs(c.tiles.size());
    const double cut_ms = collapse::elapsed_ms(t0);
    const auto t1 = std::chrono::steady_clock::now();
    arena.execute([&] {
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, c.tiles.size(), 1),
                        [&](const tbb::blocked_range<std::size_t>& r) {
                          for (std::size_t t = r.begin(); t != r.end(); ++t) {
                            runs[t] = run_tile(*mesh, c, t, locked, pass_target, n, tile_options);
                          }
                        });
    });
    collapse_ms += collapse::elapsed_ms(t1);
    ++total.tiling_passes;
    total.tile_runs += runs.size();
    const auto t2 = std::chrono::steady_clock::now();
    total.floors.clear();
    for (const TileRun& r : runs) {
      detail::add_stats(total, r.result);
      stopped = stopped || r.result.stop_reason == StopReason::stopped;
      over_budget = over_budget || r.result.stop_reason == StopReason::error_budget;
    }
    Mesh next = stitch(*mesh, mesh->vertex_count(), runs, locked, options);
    runs.clear();
    total.timings.setup_ms += cut_ms + collapse::elapsed_ms(t2);
    const bool progress = next.face_count() < n;
    current = std::move(next);
    mesh = &current;
    if (stopped || !progress) break;
  }
  total.timings.collapse_ms = collapse_ms;
  if (mesh == &triangles) current = triangles;  // already at the target
  total.mesh = std::move(current);
  total.triangles_after = total.mesh.face_count();
  total.qem_error_rel = diagonal > 0.0 ? total.qem_error_abs / diagonal : 0.0;
  total.stop_reason = total.triangles_after <= target ? StopReason::target_reached
                      : stopped                       ? StopReason::stopped
                      : over_budget                   ? StopReason::error_budget
                                                      : StopReason::no_valid_collapse;
  if (total.stop_reason == StopReason::target_reached) total.floors.clear();
  total.timings.output_ms = 0;
  return total;
}

}  // namespace lodforge::tiling

namespace lodforge {

SimplifyResult simplify_maybe_tiled(const Mesh& mesh, const SimplifyOptions& options) {
  // Fan triangulation never adds triangles to a count below the threshold: such meshes skip the checks below.
  if (!tiling::may_tile(options) ||
      (options.tiling == TilingMode::automatic && mesh.triangle_count() < tiling::kAutoThresholdTriangles)) {
    return simplify(mesh, options);
  }
  const std::vector<std::string> problems = options.validate();
  if (!problems.empty()) return simplify(mesh, options);  // throws with the full list
  // As simplify() does: repeated faces go first, and a ratio target stays a ratio of the input as given.
  const std::vector<std::uint32_t> repeats = repeated_faces(mesh, options.threads);
  if (!repeats.empty()) {
    SimplifyOptions rest = options;
    rest.target_triangles = tiling::global_target(options, mesh.triangle_count());
    SimplifyResult r = simplify_maybe_tiled(without_faces(mesh, repeats), rest);
    r.triangles_before = mesh.triangle_count();
    r.quads_before = count_face_kinds(mesh).quads;
    r.repeated_faces_removed = repeats.size();
    return r;
  }
  const auto t0 = std::chrono::steady_clock::now();
  const FaceKindCounts kinds = count_face_kinds(mesh);
  // Copy only when there is something to triangulate: the input is often the largest thing in memory.
  Mesh triangulated_copy;
  if (kinds.quads != 0 || kinds.polygons != 0) triangulated_copy = triangulated(mesh);
  const Mesh& tris = triangulated_copy.face_count() != 0 ? triangulated_copy : mesh;
  if (!tiling::applies(tris, options)) return simplify(mesh, options);
  const double triangulate_ms = collapse::elapsed_ms(t0);
  SimplifyResult r = tiling::simplify_tiled(tris, options);
  r.triangles_before = mesh.triangle_count();
  r.quads_before = kinds.quads;
  r.timings.setup_ms += triangulate_ms;
  return r;
}

}  // namespace lodforge
