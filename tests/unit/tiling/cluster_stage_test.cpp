// The tiled path's cluster stage (SimplifyOptions::cluster_stage): a vertex clustering of the whole mesh to a
// few times the target, finished by the tiled edge-collapse passes.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstdint>
#include <map>
#include <utility>

#include "lodforge/core/topology.hpp"
#include "lodforge/core/validate.hpp"
#include "lodforge/eval/eval.hpp"
#include "lodforge/simplify/simplify.hpp"
#include "lodforge/tiling/tiling.hpp"
#include "tiles.hpp"

namespace lodforge::tiling {
namespace {

// A rough height field over [0, 1]², side × side vertices: a few waves plus hashed bumps, so that clustering
// cells hold ridges and folds, as real terrain does.
Mesh make_terrain(int side) {
  Mesh m;
  auto bump = [](int i, int j) {
    std::uint32_t h = static_cast<std::uint32_t>(i) * 0x8da6b343u ^ static_cast<std::uint32_t>(j) * 0xd8163841u;
    h ^= h >> 15;
    h *= 0x2c1b3c6du;
    h ^= h >> 12;
    return static_cast<double>(h & 0xffff) / 65535.0;
  };
  for (int i = 0; i < side; ++i) {
    for (int j = 0; j < side; ++j) {
      const double x = double(j) / (side - 1), y = double(i) / (side - 1);
      const double z = 0.08 * std::sin(7 * x) * std::cos(5 * y) + 0.03 * std::sin(23 * x + 11 * y) +
                       0.004 * bump(i, j);
      m.add_vertex_with_wedge({{float(x), float(y), float(z)}});
    }
  }
  auto id = [&](int i, int j) { return static_cast<std::uint32_t>(i * side + j); };
  for (int i = 0; i + 1 < side; ++i) {
    for (int j = 0; j + 1 < side; ++j) {
      m.add_face({id(i, j), id(i, j + 1), id(i + 1, j + 1)});
      m.add_face({id(i, j), id(i + 1, j + 1), id(i + 1, j)});
    }
  }
  m.materials.push_back({.name = "default"});
  return m;
}

// A closed slab of n × n cells a side and `thickness` thick: its two big faces lie within one clustering cell
// of each other at coarse grids, where they fold onto each other back to back.
Mesh make_thin_slab(int n, float thickness) {
  Mesh m;
  std::map<std::array<int, 3>, std::uint32_t> ids;
  auto vertex = [&](int x, int y, int z) {
    const auto [it, fresh] = ids.try_emplace({x, y, z}, static_cast<std::uint32_t>(m.vertex_count()));
    if (fresh) m.add_vertex_with_wedge({{float(x) / n, float(y) / n, z * thickness}});
    return it->second;
  };
  auto quad = [&](std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint32_t d) {
    m.add_face({a, b, c});
    m.add_face({a, c, d});
  };
  for (int x = 0; x < n; ++x) {
    for (int y = 0; y < n; ++y) {
      quad(vertex(x, y, 1), vertex(x + 1, y, 1), vertex(x + 1, y + 1, 1), vertex(x, y + 1, 1));  // top, +z
      quad(vertex(x, y, 0), vertex(x, y + 1, 0), vertex(x + 1, y + 1, 0), vertex(x + 1, y, 0));  // bottom, -z
    }
  }
  for (int k = 0; k < n; ++k) {  // the four rims, one cell high
    quad(vertex(k, 0, 0), vertex(k + 1, 0, 0), vertex(k + 1, 0, 1), vertex(k, 0, 1));
    quad(vertex(n, k, 0), vertex(n, k + 1, 0), vertex(n, k + 1, 1), vertex(n, k, 1));
    quad(vertex(k + 1, n, 0), vertex(k, n, 0), vertex(k, n, 1), vertex(k + 1, n, 1));
    quad(vertex(0, k + 1, 0), vertex(0, k, 0), vertex(0, k, 1), vertex(0, k + 1, 1));
  }
  m.materials.push_back({.name = "default"});
  return m;
}

SimplifyOptions staged(double ratio, std::size_t tile, TilingMode stage = TilingMode::on) {
  SimplifyOptions o;
  o.target_ratio = ratio;
  o.tiling = TilingMode::on;
  o.tile_triangles = tile;
  o.cluster_stage = stage;
  return o;
}

TEST(ClusterStage, ClustersFirstAndLosesLittle) {
  const Mesh m = make_terrain(241);  // 115,200 triangles
  const std::size_t target = std::size_t(std::llround(0.01 * double(m.face_count())));
  const SimplifyResult r = simplify_maybe_tiled(m, staged(0.01, 20000));
  EXPECT_EQ(r.stop_reason, StopReason::target_reached);
  EXPECT_LE(r.triangles_after, target);
  EXPECT_GT(r.triangles_after, std::size_t(0.95 * double(target)));
  // The stage lands near its aim, cluster_stage_factor times the target (above it where clusters were split
  // to keep the mesh a manifold).
  const double aim = 8.0 * double(target);
  EXPECT_LE(double(r.cluster_stage_triangles), 1.25 * aim);
  EXPECT_GT(double(r.cluster_stage_triangles), 0.85 * aim);
  EXPECT_GE(r.tiling_passes, 1u);
  // The rough terrain folds inside many cells; the LOD is still a manifold with the input's topology.
  const ValidationReport v = validate(r.mesh);
  EXPECT_TRUE(v.ok()) << (v.messages.empty() ? "" : v.messages[0]);
  EXPECT_EQ(v.non_manifold_edges, 0u);
  const TopologySummary before = summarize_topology(m, build_topology(m));
  const TopologySummary after = summarize_topology(r.mesh, build_topology(r.mesh));
  EXPECT_EQ(after.non_manifold_vertices, 0u);
  EXPECT_EQ(after.boundary_loops, before.boundary_loops);
  EXPECT_EQ(after.euler_characteristic, before.euler_characteristic);

  const SimplifyResult plain = simplify_maybe_tiled(m, staged(0.01, 20000, TilingMode::off));
  EXPECT_EQ(plain.cluster_stage_triangles, 0u);
  EvalOptions eo;
  eo.samples = 200000;
  const EvalResult staged_error = evaluate(m, r.mesh, eo), plain_error = evaluate(m, plain.mesh, eo);
  // On the benchmark terrains the staged RMS is within 2% of the plain path's (docs/tiling.md); here allow 15%.
  EXPECT_LE(staged_error.rms, 1.15 * plain_error.rms);
  EXPECT_LE(staged_error.mean, 1.15 * plain_error.mean);
}

TEST(ClusterStage, SameOutputForOneAndTwoThreads) {
  const Mesh m = make_terrain(161);
  SimplifyResult one, two;
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
    SimplifyOptions o = staged(0.02, 8000);
    o.threads = 1;
    one = simplify_maybe_tiled(m, o);
  }
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
    SimplifyOptions o = staged(0.02, 8000);
    o.threads = 2;
    two = simplify_maybe_tiled(m, o);
  }
  ASSERT_GT(one.cluster_stage_triangles, 0u);
  EXPECT_EQ(one.cluster_stage_triangles, two.cluster_stage_triangles);
  EXPECT_TRUE(one.mesh == two.mesh);
}

TEST(ClusterStage, BackToBackFacesGoBeforeTheEdgeEngine) {
  // Clustered alone, the slab's two faces meet in one layer of cells back to back (non-manifold edges); the
  // stage drops such pairs, so the edge engine that finishes gets no locked non-manifold vertices from them.
  const Mesh m = make_thin_slab(120, 0.002f);
  SimplifyOptions cluster;
  cluster.engine = Engine::cluster;
  cluster.target_ratio = 0.08;
  const ValidationReport clustered = validate(simplify(m, cluster).mesh);
  ASSERT_GT(clustered.non_manifold_edges, 0u) << "the plain cluster engine keeps the folded pairs";
  SimplifyOptions o = staged(0.01, 20000);
  const SimplifyResult r = simplify_maybe_tiled(m, o);
  ASSERT_GT(r.cluster_stage_triangles, 0u);
  EXPECT_EQ(validate(r.mesh).non_manifold_edges, 0u);
}

TEST(ClusterStage, OnlyWhereItApplies) {
  SimplifyOptions o;
  ASSERT_EQ(o.cluster_stage, TilingMode::automatic);
  const std::size_t huge = kAutoClusterTriangles;
  EXPECT_EQ(detail::cluster_stage_target(o, huge, huge / 100), 8 * (huge / 100));
  EXPECT_EQ(detail::cluster_stage_target(o, huge - 1, huge / 100), 0u) << "automatic: huge meshes only";
  EXPECT_EQ(detail::cluster_stage_target(o, huge, huge / 16), 0u) << "automatic: at most a quarter of the input";
  SimplifyOptions on = o;
  on.cluster_stage = TilingMode::on;
  EXPECT_EQ(detail::cluster_stage_target(on, 1000, 50), 400u);
  EXPECT_EQ(detail::cluster_stage_target(on, 1000, 125), 0u) << "not below the input";
  SimplifyOptions off = o;
  off.cluster_stage = TilingMode::off;
  EXPECT_EQ(detail::cluster_stage_target(off, huge, huge / 100), 0u);
  for (auto change : {+[](SimplifyOptions& x) { x.locked_vertices = {0}; },
                      +[](SimplifyOptions& x) { x.max_error_rel = 0.01; },
                      +[](SimplifyOptions& x) { x.max_error_abs = 0.01; },
                      +[](SimplifyOptions& x) { x.conservative = Conservative::bounding; }}) {
    SimplifyOptions x = on;
    change(x);
    EXPECT_EQ(detail::cluster_stage_target(x, huge, huge / 100), 0u);
  }
  SimplifyOptions bad = o;
  bad.cluster_stage_factor = 0.5;
  EXPECT_FALSE(bad.validate().empty());

  // Through the whole path: locked vertices keep the stage off and stay where they were.
  const Mesh m = make_terrain(101);
  SimplifyOptions locked = staged(0.02, 4000);
  locked.locked_vertices = {0, 100, 5050};
  const SimplifyResult r = simplify_maybe_tiled(m, locked);
  EXPECT_EQ(r.cluster_stage_triangles, 0u);
  EXPECT_EQ(r.stop_reason, StopReason::target_reached);
}

}  // namespace
}  // namespace lodforge::tiling
