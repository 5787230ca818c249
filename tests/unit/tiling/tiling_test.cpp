// Tiled simplification: the cut, the shifted re-cut, crack-free stitching, determinism and attributes.
#include "lodforge/tiling/tiling.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <numbers>
#include <set>
#include <utility>

#include "lodforge/core/validate.hpp"
#include "lodforge/io/asset.hpp"
#include "lodforge/simplify/simplify.hpp"
#include "lodforge/tiling/stream.hpp"
#include "test_support.hpp"

namespace lodforge::tiling {
namespace {

// A closed torus (Euler characteristic 0), one wedge per vertex, material 0.
Mesh make_torus(int rings, int segments, float major = 2.0f, float minor = 0.7f) {
  Mesh m;
  const double pi = std::numbers::pi;
  for (int i = 0; i < rings; ++i) {
    const double a = 2 * pi * i / rings;
    for (int j = 0; j < segments; ++j) {
      const double b = 2 * pi * j / segments;
      const double r = major + minor * std::cos(b);
      m.add_vertex_with_wedge({{static_cast<float>(r * std::cos(a)), static_cast<float>(r * std::sin(a)),
                                static_cast<float>(minor * std::sin(b))}});
    }
  }
  auto id = [&](int i, int j) { return static_cast<std::uint32_t>((i % rings) * segments + (j % segments)); };
  for (int i = 0; i < rings; ++i) {
    for (int j = 0; j < segments; ++j) {
      m.add_face({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      m.add_face({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
  }
  m.materials.push_back({.name = "default"});
  return m;
}

// A planar grid of n x n cells over [0, n]^2 with two UV charts: faces left of x = n/2 map to u in [0, 0.5],
// faces right of it to u in [1.5, 2] (the seam column has two wedges per vertex); normals +z on every wedge.
Mesh make_two_chart_grid(int n) {
  Mesh m;
  m.uvs.resize(1);
  auto vid = [&](int x, int y) { return static_cast<std::uint32_t>(y * (n + 1) + x); };
  for (int y = 0; y <= n; ++y) {
    for (int x = 0; x <= n; ++x) m.positions.push_back({{float(x), float(y), 0.0f}});
  }
  std::map<std::pair<std::uint32_t, int>, std::uint32_t> wedge;  // (vertex, chart) -> wedge
  auto w = [&](int x, int y, int chart) {
    const auto key = std::pair{vid(x, y), chart};
    if (auto it = wedge.find(key); it != wedge.end()) return it->second;
    const auto id = static_cast<std::uint32_t>(m.wedge_vertex.size());
    m.wedge_vertex.push_back(vid(x, y));
    m.normals.push_back({{0, 0, 1}});
    m.uvs[0].push_back({{float(x) / float(2 * n) + (chart ? 1.0f : 0.0f), float(y) / float(n)}});
    wedge[key] = id;
    return id;
  };
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      const int c = 2 * x < n ? 0 : 1;
      m.add_face({w(x, y, c), w(x + 1, y, c), w(x + 1, y + 1, c)});
      m.add_face({w(x, y, c), w(x + 1, y + 1, c), w(x, y + 1, c)});
    }
  }
  m.materials.push_back({.name = "default"});
  return m;
}

// Undirected edges with the number of faces on each.
std::map<std::pair<std::uint32_t, std::uint32_t>, int> edge_faces(const Mesh& m) {
  std::map<std::pair<std::uint32_t, std::uint32_t>, int> e;
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    const std::uint32_t k = m.face_offsets[f], n = m.face_size(f);
    for (std::uint32_t i = 0; i < n; ++i) {
      std::uint32_t a = m.corner_vertex(k + i), b = m.corner_vertex(k + (i + 1) % n);
      if (a > b) std::swap(a, b);
      ++e[{a, b}];
    }
  }
  return e;
}

std::size_t duplicate_positions(const Mesh& m) {
  std::set<std::array<float, 3>> seen;
  std::size_t used = 0;
  std::vector<std::uint8_t> referenced(m.vertex_count(), 0);
  for (std::size_t c = 0; c < m.corner_count(); ++c) referenced[m.corner_vertex(c)] = 1;
  for (std::size_t v = 0; v < m.vertex_count(); ++v) {
    if (!referenced[v]) continue;
    ++used;
    seen.insert(m.positions[v].v);
  }
  return used - seen.size();
}

// Cut edges: edges whose two faces lie in different tiles.
std::set<std::pair<std::uint32_t, std::uint32_t>> cut_edges(const Mesh& m, const TileCut& c) {
  std::vector<std::uint32_t> tile_of(m.face_count());
  for (std::size_t t = 0; t < c.tiles.size(); ++t) {
    for (std::uint32_t f : c.tiles[t]) tile_of[f] = static_cast<std::uint32_t>(t);
  }
  std::map<std::pair<std::uint32_t, std::uint32_t>, std::set<std::uint32_t>> tiles;
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    for (std::uint32_t i = 0; i < 3; ++i) {
      std::uint32_t a = m.corner_vertex(m.face_offsets[f] + i), b = m.corner_vertex(m.face_offsets[f] + (i + 1) % 3);
      if (a > b) std::swap(a, b);
      tiles[{a, b}].insert(tile_of[f]);
    }
  }
  std::set<std::pair<std::uint32_t, std::uint32_t>> out;
  for (const auto& [e, t] : tiles) {
    if (t.size() > 1) out.insert(e);
  }
  return out;
}

SimplifyOptions tiled(double ratio, std::size_t tile) {
  SimplifyOptions o;
  o.target_ratio = ratio;
  o.tiling = TilingMode::on;
  o.tile_triangles = tile;
  return o;
}

TEST(TilingCut, EveryTriangleInExactlyOneTile) {
  const Mesh m = make_torus(120, 80);
  const TileCut c = cut(m, 2000, 0.0);
  ASSERT_GT(c.tiles.size(), 4u);
  std::vector<int> seen(m.face_count(), 0);
  for (const auto& tile : c.tiles) {
    EXPECT_FALSE(tile.empty());
    EXPECT_TRUE(std::is_sorted(tile.begin(), tile.end()));
    for (std::uint32_t f : tile) ++seen[f];
  }
  for (std::size_t f = 0; f < m.face_count(); ++f) ASSERT_EQ(seen[f], 1) << "face " << f;
  // Border vertices are exactly those used by faces of two or more tiles.
  std::vector<std::set<std::size_t>> tiles_of(m.vertex_count());
  for (std::size_t t = 0; t < c.tiles.size(); ++t) {
    for (std::uint32_t f : c.tiles[t]) {
      for (int i = 0; i < 3; ++i) tiles_of[m.corner_vertex(m.face_offsets[f] + i)].insert(t);
    }
  }
  for (std::size_t v = 0; v < m.vertex_count(); ++v) EXPECT_EQ(c.border[v] != 0, tiles_of[v].size() > 1) << v;
}

TEST(TilingCut, ShiftedCutMakesOldBordersInterior) {
  const Mesh m = make_torus(160, 100);
  const TileCut first = cut(m, 3000, pass_shift(0));
  const TileCut second = cut(m, 3000, pass_shift(1));
  EXPECT_NE(pass_shift(0), pass_shift(1));
  const auto a = cut_edges(m, first), b = cut_edges(m, second);
  ASSERT_FALSE(a.empty());
  std::size_t still = 0;
  for (const auto& e : a) still += b.count(e);
  // Only where a new cut plane crosses an old one (a point per pair of planes) may an old cut edge stay cut.
  EXPECT_LT(double(still), 0.05 * double(a.size())) << still << " of " << a.size();
}

TEST(TilingCut, ExtractKeepsTheFacesAndAttributes) {
  const Mesh m = make_two_chart_grid(40);
  const TileCut c = cut(m, 400, 0.0);
  ASSERT_GT(c.tiles.size(), 2u);
  std::vector<std::uint32_t> vertices;
  const Mesh sub = extract(m, c.tiles[1], vertices);
  ASSERT_TRUE(validate(m).ok());
  // A tile may touch itself at a vertex (a bow tie of cells): such a vertex is on the cut, and locked.
  const ValidationReport v = validate(sub);
  EXPECT_EQ(v.non_manifold_edges + v.out_of_range_indices + v.attribute_size_errors + v.degenerate_faces, 0u);
  ASSERT_EQ(sub.face_count(), c.tiles[1].size());
  ASSERT_EQ(sub.normals.size(), sub.wedge_count());
  ASSERT_EQ(sub.uvs[0].size(), sub.wedge_count());
  for (std::size_t i = 0; i < c.tiles[1].size(); ++i) {
    const std::uint32_t f = c.tiles[1][i];
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t ws = sub.corner_wedge[3 * i + k], wm = m.corner_wedge[m.face_offsets[f] + k];
      EXPECT_EQ(sub.positions[sub.wedge_vertex[ws]], m.positions[m.wedge_vertex[wm]]);
      EXPECT_EQ(sub.uvs[0][ws], m.uvs[0][wm]);
      EXPECT_EQ(vertices[sub.wedge_vertex[ws]], m.wedge_vertex[wm]);
    }
  }
}

TEST(TilingSimplify, ClosedMeshStaysCrackFree) {
  for (const Mesh& m : {make_torus(160, 100), testing::make_uv_sphere(100, 160)}) {
    const long euler_before = [&] {
      const auto e = edge_faces(m);
      return long(m.vertex_count()) - long(e.size()) + long(m.face_count());
    }();
    ASSERT_EQ(duplicate_positions(m), 0u);
    // 10% in tiles of 3000: one tiled pass, then an untiled run; 20% in tiles of 500: the locked cuts hold the
    // first pass above the target, and further passes on shifted grids go on in tiles.
    for (const auto& [ratio, tile] : {std::pair{0.1, 3000}, std::pair{0.2, 500}}) {
      const SimplifyResult r = simplify_maybe_tiled(m, tiled(ratio, std::size_t(tile)));
      SCOPED_TRACE(::testing::Message() << m.face_count() << " triangles to " << ratio);
      EXPECT_EQ(r.stop_reason, StopReason::target_reached);
      EXPECT_LE(r.triangles_after, std::size_t(std::llround(ratio * double(m.face_count()))));
      EXPECT_GT(r.triangles_after, std::size_t(0.9 * ratio * double(m.face_count())));
      EXPECT_GE(r.tiling_passes, 2u);
      EXPECT_GT(r.tile_runs, r.tiling_passes);
      const ValidationReport v = validate(r.mesh);
      EXPECT_TRUE(v.ok()) << (v.messages.empty() ? "" : v.messages[0]);
      EXPECT_EQ(v.non_manifold_edges, 0u);
      EXPECT_EQ(v.unreferenced_vertices, 0u);
      const auto e = edge_faces(r.mesh);
      std::size_t open = 0;
      for (const auto& [edge, n] : e) open += n != 2;
      EXPECT_EQ(open, 0u) << "watertight: every edge has two faces (no crack, no T-junction)";
      EXPECT_EQ(long(r.mesh.vertex_count()) - long(e.size()) + long(r.mesh.face_count()), euler_before);
      EXPECT_EQ(duplicate_positions(r.mesh), 0u) << "border vertices welded";
    }
  }
}

TEST(TilingSimplify, SameOutputForOneAndTwoThreads) {
  const Mesh m = make_torus(160, 100);
  SimplifyResult one, two;
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
    SimplifyOptions o = tiled(0.05, 2000);
    o.threads = 1;
    one = simplify_maybe_tiled(m, o);
  }
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
    SimplifyOptions o = tiled(0.05, 2000);
    o.threads = 2;
    two = simplify_maybe_tiled(m, o);
  }
  EXPECT_TRUE(one.mesh == two.mesh);
  EXPECT_EQ(one.collapses, two.collapses);
  const SimplifyResult all = simplify_maybe_tiled(m, tiled(0.05, 2000));
  EXPECT_TRUE(all.mesh == one.mesh);
}

TEST(TilingSimplify, AutomaticLeavesSmallMeshesToTheEngine) {
  const Mesh m = make_torus(60, 40);
  SimplifyOptions o;
  o.target_ratio = 0.2;
  ASSERT_EQ(o.tiling, TilingMode::automatic);
  SimplifyOptions off = o;
  off.tiling = TilingMode::off;
  EXPECT_TRUE(simplify_maybe_tiled(m, o).mesh == simplify(m, off).mesh);
  EXPECT_FALSE(applies(m, o));
  EXPECT_TRUE(applies(m, tiled(0.2, 1000)));
  SimplifyOptions budget = tiled(0.2, 1000);
  budget.max_error_rel = 0.01;
  EXPECT_FALSE(applies(m, budget)) << "budgets are verified on the untiled path";
  SimplifyOptions cluster = tiled(0.2, 1000);
  cluster.engine = Engine::cluster;
  EXPECT_FALSE(applies(m, cluster));
}

// simplify() itself never tiles, whatever the options say; the tiled entry point drops repeated faces first and
// keeps a ratio target relative to the input as given, as simplify() does.
TEST(TilingSimplify, PlainSimplifyNeverTiles) {
  const Mesh m = make_torus(160, 100);
  const SimplifyOptions o = tiled(0.05, 2000);
  const SimplifyResult plain = simplify(m, o);
  EXPECT_EQ(plain.tiling_passes, 0u);
  EXPECT_EQ(plain.tile_runs, 0u);
  SimplifyOptions off = o;
  off.tiling = TilingMode::off;
  EXPECT_TRUE(plain.mesh == simplify(m, off).mesh);
  const SimplifyResult t = simplify_maybe_tiled(m, o);
  EXPECT_GE(t.tiling_passes, 2u);

  Mesh repeated = m;
  for (std::size_t f = 0; f < 100; ++f) {
    const std::uint32_t c = repeated.face_offsets[f];
    const std::uint32_t w[3] = {repeated.corner_wedge[c], repeated.corner_wedge[c + 1], repeated.corner_wedge[c + 2]};
    repeated.add_face(w, 3, 0);
  }
  const SimplifyResult r = simplify_maybe_tiled(repeated, o);
  EXPECT_EQ(r.repeated_faces_removed, 100u);
  EXPECT_EQ(r.triangles_before, repeated.face_count());
  EXPECT_GE(r.tiling_passes, 2u);
  EXPECT_EQ(r.stop_reason, StopReason::target_reached);
  EXPECT_LE(r.triangles_after, std::size_t(std::llround(0.05 * double(repeated.face_count()))));
  EXPECT_GT(r.triangles_after, t.triangles_after) << "5% of the input as given, repeats included";
  EXPECT_TRUE(validate(r.mesh).ok());
}

// Without verification an error budget is only the engines' QEM cap: the tiles apply it (relative to the whole
// mesh), and the run says the budget stopped it.
TEST(TilingSimplify, UnverifiedBudgetCapsTheTiles) {
  const Mesh m = make_torus(160, 100);
  SimplifyOptions o = tiled(0.01, 2000);
  o.max_error_rel = 1e-4;
  o.verify_budget = false;
  ASSERT_TRUE(applies(m, o));
  const SimplifyResult r = simplify_maybe_tiled(m, o);
  EXPECT_GE(r.tiling_passes, 1u);
  EXPECT_EQ(r.stop_reason, StopReason::error_budget);
  EXPECT_GT(r.triangles_after, m.face_count() / 100);
  EXPECT_LT(r.triangles_after, m.face_count());
  EXPECT_LE(r.qem_error_rel, 1e-4 * (1 + 1e-9));
}

TEST(TilingSimplify, RejectsTinyTiles) {
  SimplifyOptions o = tiled(0.5, 10);
  EXPECT_FALSE(o.validate().empty());
  EXPECT_THROW(simplify_maybe_tiled(make_torus(10, 10), o), std::invalid_argument);
}

TEST(TilingSimplify, UserLocksHoldThroughThePasses) {
  const Mesh m = make_torus(160, 100);
  SimplifyOptions o = tiled(0.05, 2000);
  for (std::uint32_t v = 0; v < m.vertex_count(); v += 997) o.locked_vertices.push_back(v);
  const SimplifyResult r = simplify_maybe_tiled(m, o);
  std::set<std::array<float, 3>> out;
  for (const Vec3f& p : r.mesh.positions) out.insert(p.v);
  for (std::uint32_t v : o.locked_vertices) EXPECT_TRUE(out.count(m.positions[v].v)) << "locked vertex " << v;
}

// UV charts stay apart across the cuts: no output triangle has corners in both charts, the seam's wedges are
// carried, and the grid's outline and normals are kept.
TEST(TilingSimplify, UvSeamsAndAttributesCarriedThroughCutAndStitch) {
  const Mesh m = make_two_chart_grid(120);
  for (AttributePlacement placement : {AttributePlacement::optimal, AttributePlacement::keep}) {
    SimplifyOptions o = tiled(0.1, 1500);
    o.attribute_placement = placement;
    const SimplifyResult r = simplify_maybe_tiled(m, o);
    ASSERT_TRUE(validate(r.mesh).ok());
    ASSERT_EQ(r.mesh.uvs.size(), 1u);
    ASSERT_EQ(r.mesh.uvs[0].size(), r.mesh.wedge_count());
    ASSERT_EQ(r.mesh.normals.size(), r.mesh.wedge_count());
    EXPECT_LE(r.triangles_after, m.face_count() / 10 + 1);
    std::size_t spanning = 0;
    for (std::size_t f = 0; f < r.mesh.face_count(); ++f) {
      int right = 0;
      for (int k = 0; k < 3; ++k) right += r.mesh.uvs[0][r.mesh.corner_wedge[3 * f + k]][0] > 1.0f;
      spanning += right != 0 && right != 3;
    }
    EXPECT_EQ(spanning, 0u);
    std::size_t seam_vertices = 0;
    std::vector<int> wedges(r.mesh.vertex_count(), 0);
    for (std::uint32_t v : r.mesh.wedge_vertex) ++wedges[v];
    for (int n : wedges) seam_vertices += n == 2;
    EXPECT_GE(seam_vertices, 2u);
    for (int n : wedges) EXPECT_LE(n, 2) << "a stitched vertex got a wedge twice";
    EXPECT_EQ(duplicate_positions(r.mesh), 0u);
    for (const Vec3f& n : r.mesh.normals) EXPECT_NEAR(n[2], 1.0f, 1e-5f);
  }
}

TEST(TilingMemory, ParsesSizesAndRefusesSmallOrMalformedOnes) {
  EXPECT_EQ(parse_memory_size("16M"), std::size_t{16} << 20);
  EXPECT_EQ(parse_memory_size("512m"), std::size_t{512} << 20);
  EXPECT_EQ(parse_memory_size("4G"), std::size_t{4} << 30);
  EXPECT_EQ(parse_memory_size("4GiB"), std::size_t{4} << 30);
  EXPECT_EQ(parse_memory_size("20000K"), std::size_t{20000} << 10);
  EXPECT_EQ(parse_memory_size("16777216"), std::size_t{16} << 20);
  for (const char* bad : {"", "M", "12X", "1.5G", "-4G", "4 G", "4GB5", "99999999999999999999T"}) {
    EXPECT_THROW(parse_memory_size(bad), std::invalid_argument) << bad;
  }
  for (const char* small : {"15M", "16777215", "1K", "0"}) {
    try {
      parse_memory_size(small);
      ADD_FAILURE() << small << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("16M"), std::string::npos) << e.what();
    }
  }
}

// Untiled where the estimate fits; tiles small enough where it does not; nothing where the mesh itself with the
// tiled path's arrays is over the limit, or where the engine cannot tile.
TEST(TilingMemory, PlansTilesThatFit) {
  const Mesh m = make_torus(300, 200);  // 120,000 triangles: over 16M untiled, under it tiled
  const SimplifyOptions o;
  const std::size_t untiled = mesh_bytes(m) + kUntiledBytesPerTriangle * m.face_count();
  const MemoryPlan roomy = plan_memory(m, o, untiled + untiled / 7 + 8, 2);  // 7/8 of the limit are planned
  EXPECT_TRUE(roomy.fits);
  EXPECT_FALSE(roomy.force_tiling);
  EXPECT_EQ(roomy.untiled_bytes, untiled);
  const MemoryPlan tight = plan_memory(m, o, kMinMemoryLimit, 2);
  ASSERT_GT(untiled, kMinMemoryLimit);
  EXPECT_TRUE(tight.fits);
  EXPECT_TRUE(tight.force_tiling);
  EXPECT_GE(tight.tile_triangles, 100u);
  EXPECT_LT(tight.tile_triangles, m.face_count() / 4);
  EXPECT_LE(tight.tiled_bytes, kMinMemoryLimit - kMinMemoryLimit / 8);
  EXPECT_TRUE(plan_memory(m, o, untiled + untiled / 8, 2).force_tiling) << "the margin";
  EXPECT_LT(plan_memory(m, o, kMinMemoryLimit, 8).tile_triangles, tight.tile_triangles) << "more tiles at once";
  SimplifyOptions cluster = o;
  cluster.engine = Engine::cluster;
  EXPECT_FALSE(plan_memory(m, cluster, kMinMemoryLimit, 2).fits);
  SimplifyOptions budget = o;
  budget.max_error_rel = 0.01;
  EXPECT_FALSE(plan_memory(m, budget, kMinMemoryLimit, 2).fits);
  const Mesh huge = make_torus(1000, 400);  // 800,000 triangles, over 16M held in memory
  ASSERT_GT(mesh_bytes(huge) + kTiledBytesPerTriangle * huge.face_count(), kMinMemoryLimit);
  EXPECT_FALSE(plan_memory(huge, o, kMinMemoryLimit, 2).fits);
}

// A glTF asset with UV charts and tangents, tiled small: no triangle spans two UV charts of the input (UV
// values are kept exactly with AttributePlacement::keep, so each output corner's chart is known).
TEST(TilingCorpus, FlightHelmetKeepsUvCharts) {
  LODFORGE_REQUIRE_CORPUS(path, "gltf/FlightHelmet/FlightHelmet.gltf");
  const io::Asset asset = io::load_asset(path);
  std::size_t checked = 0;
  for (const Mesh& m : asset.meshes) {
    if (m.uvs.empty() || m.face_count() < 6000) continue;
    const Mesh tris = triangulated(m);
    // Charts: faces joined through shared wedges; a UV value maps to the charts it occurs in.
    std::vector<std::uint32_t> parent(tris.wedge_count());
    for (std::uint32_t i = 0; i < parent.size(); ++i) parent[i] = i;
    auto find = [&](std::uint32_t x) {
      while (parent[x] != x) x = parent[x] = parent[parent[x]];
      return x;
    };
    // Wedges of one vertex with the same UV are one point of a chart (files often repeat them).
    std::map<std::pair<std::uint32_t, std::array<float, 2>>, std::uint32_t> first_wedge;
    for (std::uint32_t w = 0; w < tris.wedge_count(); ++w) {
      const auto [it, added] = first_wedge.emplace(std::pair{tris.wedge_vertex[w], tris.uvs[0][w].v}, w);
      if (!added) parent[find(w)] = find(it->second);
    }
    for (std::size_t f = 0; f < tris.face_count(); ++f) {
      const std::uint32_t a = find(tris.corner_wedge[3 * f]);
      for (int k = 1; k < 3; ++k) parent[find(tris.corner_wedge[3 * f + k])] = a;
    }
    std::map<std::array<float, 2>, std::set<std::uint32_t>> charts_of;
    for (std::uint32_t w = 0; w < tris.wedge_count(); ++w) charts_of[tris.uvs[0][w].v].insert(find(w));
    SimplifyOptions o = tiled(0.25, 1000);
    o.attribute_placement = AttributePlacement::keep;
    const SimplifyResult r = simplify_maybe_tiled(tris, o);
    SimplifyOptions untiled_options = o;
    untiled_options.tiling = TilingMode::off;
    const SimplifyResult untiled = simplify(tris, untiled_options);
    // Nothing new that is non-manifold, degenerate or out of range (RubberWood_low has two non-manifold
    // vertices of its own).
    const ValidationReport in = validate(tris), out = validate(r.mesh);
    EXPECT_LE(out.non_manifold_vertices, in.non_manifold_vertices) << m.name;
    EXPECT_LE(out.non_manifold_edges, in.non_manifold_edges) << m.name;
    EXPECT_EQ(out.out_of_range_indices + out.attribute_size_errors + out.degenerate_faces, 0u) << m.name;
    EXPECT_LE(r.triangles_after, untiled.triangles_after + untiled.triangles_after / 20) << m.name;
    auto spanning = [&](const Mesh& lod) {
      std::size_t n = 0;
      for (std::size_t f = 0; f < lod.face_count(); ++f) {
        std::set<std::uint32_t> common;
        for (int k = 0; k < 3; ++k) {
          const auto it = charts_of.find(lod.uvs[0][lod.corner_wedge[3 * f + k]].v);
          if (it == charts_of.end()) return std::size_t{999999};  // an output UV the input does not have
          if (k == 0) {
            common = it->second;
          } else {
            std::set<std::uint32_t> both;
            std::set_intersection(common.begin(), common.end(), it->second.begin(), it->second.end(),
                                  std::inserter(both, both.end()));
            common = std::move(both);
          }
        }
        n += common.empty();
      }
      return n;
    };
    EXPECT_EQ(spanning(untiled.mesh), 0u) << m.name << " (the measure itself, on the untiled engine)";
    EXPECT_EQ(spanning(r.mesh), 0u) << m.name;
    ++checked;
  }
  EXPECT_GT(checked, 0u);
}

// ---- out of core ----

// The torus written as a binary PLY and as an OBJ (the same float positions).
std::filesystem::path saved_torus(const std::filesystem::path& dir, const std::string& file, int rings, int segments) {
  io::Asset a;
  a.format = io::format_from_path(file);
  a.binary = true;
  a.meshes.push_back(make_torus(rings, segments));
  const std::filesystem::path path = dir / file;
  io::save_asset(a, path);
  return path;
}

TEST(TilingStream, ClosedMeshStaysCrackFreeTheSameOnAnyThreadCountAndFormat) {
  const Mesh m = make_torus(160, 100);
  const long euler_before = long(m.vertex_count()) - long(edge_faces(m).size()) + long(m.face_count());
  const std::filesystem::path dir = testing::temp_dir("tiling_stream_torus");
  const std::filesystem::path ply = saved_torus(dir, "torus.ply", 160, 100), obj = saved_torus(dir, "torus.obj", 160, 100);
  const std::filesystem::path scratch = dir / "tiles";
  SimplifyOptions o;
  o.target_ratio = 0.1;
  StreamedRun one, two;
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
    o.threads = 1;
    one = simplify_streamed(ply, o, 3000, scratch);
  }
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
    o.threads = 2;
    two = simplify_streamed(ply, o, 3000, scratch);
  }
  o.threads = 0;
  const StreamedRun from_obj = simplify_streamed(obj, o, 3000, scratch);
  const SimplifyResult& r = one.result;
  EXPECT_TRUE(r.mesh == two.result.mesh);
  EXPECT_EQ(r.mesh.positions, from_obj.result.mesh.positions) << "the same surface read from an OBJ";
  EXPECT_EQ(r.mesh.corner_wedge, from_obj.result.mesh.corner_wedge);
  ASSERT_EQ(from_obj.result.mesh.materials.size(), 1u);
  EXPECT_EQ(from_obj.result.mesh.materials[0].name, "default") << "the OBJ's one usemtl slot";
  EXPECT_EQ(one.input_vertices, m.vertex_count());
  EXPECT_GT(one.tiles, 4u);
  EXPECT_EQ(r.triangles_before, m.face_count());
  EXPECT_EQ(r.stop_reason, StopReason::target_reached);
  EXPECT_LE(r.triangles_after, m.face_count() / 10);
  EXPECT_GT(r.triangles_after, m.face_count() / 10 * 9 / 10);
  const auto e = edge_faces(r.mesh);
  std::size_t open = 0;
  for (const auto& [edge, n] : e) open += n != 2;
  EXPECT_EQ(open, 0u) << "watertight: no crack, no T-junction along the tiles' cuts";
  EXPECT_EQ(long(r.mesh.vertex_count()) - long(e.size()) + long(r.mesh.face_count()), euler_before);
  EXPECT_EQ(duplicate_positions(r.mesh), 0u);
  EXPECT_TRUE(validate(r.mesh).ok());
  EXPECT_TRUE(std::filesystem::is_empty(scratch)) << "tile files are removed once read";
  // Close to what the in-memory tiled path makes from the same mesh (the same cut of the first pass, cells of
  // half the size).
  const SimplifyResult in_memory = simplify_maybe_tiled(m, tiled(0.1, 3000));
  EXPECT_EQ(in_memory.triangles_after, r.triangles_after);
}

TEST(TilingStream, WeldsRepeatedPositionsAndDropsWhatCollapses) {
  // The torus with every vertex written twice (faces use the copies in alternation; the second copy writes a
  // zero coordinate as -0): welded back as loading whole does, so the cuts still weld and the mesh stays closed.
  const Mesh m = make_torus(60, 40);
  std::string text;
  for (int copy = 0; copy < 2; ++copy) {
    for (const Vec3f& p : m.positions) {
      text += "v";
      for (int a = 0; a < 3; ++a) text += " " + std::string(copy == 1 && p[a] == 0.0f ? "-0" : std::to_string(p[a]));
      text += "\n";
    }
  }
  const std::uint32_t n = static_cast<std::uint32_t>(m.vertex_count());
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    text += "f";
    for (std::uint32_t k = 0; k < 3; ++k) text += " " + std::to_string(m.corner_vertex(3 * f + k) + 1 + (f % 2) * n);
    text += "\n";
  }
  text += "f 1 1 2\n";  // degenerate: dropped, and said
  const std::filesystem::path dir = testing::temp_dir("tiling_stream_twice");
  const std::filesystem::path path = dir / "twice.obj";
  std::ofstream(path) << text;
  SimplifyOptions o;
  o.target_ratio = 0.25;
  const StreamedRun r = simplify_streamed(path, o, 500, dir / "tiles");
  EXPECT_EQ(r.degenerate_dropped, 1u);
  ASSERT_FALSE(r.warnings.empty());
  EXPECT_NE(r.warnings.back().find("repeated corner"), std::string::npos);
  std::size_t open = 0;
  for (const auto& [edge, k] : edge_faces(r.result.mesh)) open += k != 2;
  EXPECT_EQ(open, 0u);
  EXPECT_EQ(duplicate_positions(r.result.mesh), 0u);
}

TEST(TilingStream, PlansToStreamOnlyWhatCannotLoadWhole) {
  const std::filesystem::path dir = testing::temp_dir("tiling_stream_plan");
  const std::filesystem::path ply = saved_torus(dir, "plan.ply", 500, 400);  // 400k triangles, 200k vertices
  SimplifyOptions o;
  o.target_ratio = 0.01;
  const StreamPlan roomy = plan_stream(ply, o, std::size_t{1} << 30, 2);
  EXPECT_FALSE(roomy.stream);
  EXPECT_EQ(roomy.counts.vertices, 200000u);
  EXPECT_EQ(roomy.counts.triangles, 400000u);
  const StreamPlan tight = plan_stream(ply, o, std::size_t{32} << 20, 2);
  EXPECT_TRUE(tight.stream);
  EXPECT_TRUE(tight.fits);
  EXPECT_GE(tight.tile_triangles, kMinStreamTile);
  EXPECT_LE(tight.stream_bytes, (std::size_t{32} << 20) - (std::size_t{32} << 17));
  EXPECT_FALSE(plan_stream(ply, o, std::size_t{16} << 20, 2).fits);
  // An engine that cannot tile cannot stream, nor can vertex ids of a mesh never loaded.
  SimplifyOptions locked = o;
  locked.locked_vertices = {0};
  EXPECT_THROW(simplify_streamed(ply, locked, 3000, dir / "tiles"), std::invalid_argument);
  o.engine = Engine::polychord;
  EXPECT_THROW(simplify_streamed(ply, o, 3000, dir / "tiles"), std::invalid_argument);
}

}  // namespace
}  // namespace lodforge::tiling
