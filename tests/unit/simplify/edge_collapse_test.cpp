#include "collapse_mesh.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "lodforge/core/validate.hpp"
#include "lodforge/eval/eval.hpp"
#include "lodforge/simplify/simplify.hpp"
#include "simplify_fixtures.hpp"
#include "test_support.hpp"

namespace lodforge {
namespace {

using simplify_test::expect_nothing_new;
using simplify_test::make_bumpy_grid;
using simplify_test::make_bumpy_sphere;
using simplify_test::make_subdivided_cube;
using simplify_test::position_set;
using simplify_test::summary;

TEST(EdgeCollapse, SubdividedPlaneToTwoTriangles) {
  const Mesh grid = testing::make_grid(8, 8, false);
  const SimplifyResult r = simplify(grid, {.target_triangles = 2, .border_mode = BorderMode::preserve});
  EXPECT_EQ(r.triangles_before, 128u);
  EXPECT_EQ(r.triangles_after, 2u);
  EXPECT_EQ(r.stop_reason, StopReason::target_reached);
  EXPECT_LT(r.qem_error_rel, 1e-6);
  EXPECT_TRUE(validate(r.mesh).ok());
  // The four corners survive where they were: the square is covered exactly.
  const auto corners = position_set(r.mesh);
  for (const auto& c : {std::array<float, 3>{0, 0, 0}, {8, 0, 0}, {0, 8, 0}, {8, 8, 0}}) {
    bool found = false;
    for (const auto& p : corners) {
      found = found || (std::abs(p[0] - c[0]) < 1e-4f && std::abs(p[1] - c[1]) < 1e-4f && std::abs(p[2]) < 1e-6f);
    }
    EXPECT_TRUE(found) << "corner " << c[0] << "," << c[1];
  }
  EXPECT_EQ(r.mesh.vertex_count(), 4u);
}

TEST(EdgeCollapse, SubdividedCubeToTwelveTriangles) {
  const Mesh cube = make_subdivided_cube(6);
  const SimplifyResult r = simplify(cube, {.target_triangles = 12});
  EXPECT_EQ(r.triangles_after, 12u);
  EXPECT_LT(r.qem_error_rel, 1e-6);
  EXPECT_TRUE(validate(r.mesh).ok());
  ASSERT_EQ(r.mesh.vertex_count(), 8u);
  for (const Vec3f& p : r.mesh.positions) {  // the sharp corners are kept by the plane quadrics
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(std::min(std::abs(p[i]), std::abs(p[i] - 6.0f)), 0.0f, 1e-4f);
  }
  EXPECT_EQ(summary(r.mesh).euler_characteristic, 2);
}

TEST(EdgeCollapse, TetrahedronCannotCollapse) {
  const Mesh tet = testing::make_tetrahedron();
  const SimplifyResult r = simplify(tet, {.target_triangles = 1});
  EXPECT_EQ(r.triangles_after, 4u);
  EXPECT_EQ(r.collapses, 0u);
  EXPECT_EQ(r.stop_reason, StopReason::no_valid_collapse);
  EXPECT_EQ(r.mesh, tet);  // nothing moved, nothing renumbered
}

// Direct checks of one candidate on the working mesh.
collapse::Check check_edge(const Mesh& m, std::uint32_t u, std::uint32_t v, const Vec3d& x_model,
                           const SimplifyOptions& o = {}) {
  collapse::Parallel par(1);
  collapse::CollapseMesh cm(m, o, par);
  collapse::Scratch s;
  // Positions are normalised inside: map the model-space point the same way (origin = bbox min, scale = max
  // extent).
  const Bounds3 b = compute_bounds(m);
  const Vec3d x = (x_model - b.min) * (1.0 / cm.scale());
  return cm.check(std::min(u, v), std::max(u, v), x, s);
}

TEST(EdgeCollapse, RefusesBoundaryPinch) {
  // Two quads side by side; every vertex is on the border. The middle edge 1-4 is interior:
  //   3 --- 4 --- 5
  //   |   / |   / |
  //   0 --- 1 --- 2
  const Mesh strip = testing::make_grid(2, 1, false);
  const collapse::Check c = check_edge(strip, 1, 4, {{1.0, 0.5, 0.0}});
  EXPECT_EQ(c.veto, collapse::Veto::boundary_pinch);
  // A border edge of the same mesh collapses fine (to its midpoint, no fold).
  EXPECT_TRUE(check_edge(strip, 1, 2, {{1.5, 0.0, 0.0}}).ok());
}

TEST(EdgeCollapse, RefusesLinkConditionViolation) {
  // The tetrahedron's edges all fail the link condition (a collapse would glue two faces back to back).
  const Mesh tet = testing::make_tetrahedron();
  const collapse::Check c = check_edge(tet, 0, 1, {{0.5, 0.0, 0.0}});
  EXPECT_FALSE(c.ok());
  EXPECT_EQ(c.veto, collapse::Veto::tetrahedron);
}

TEST(EdgeCollapse, RefusesGluingAcrossAHandle) {
  // On the smallest torus (3 × 3), the endpoints of every edge have a third common neighbour around the
  // handle that is not an apex: collapsing would pinch the handle into a non-manifold vertex.
  const Mesh tiny = simplify_test::make_torus(3, 3);
  ASSERT_EQ(summary(tiny).euler_characteristic, 0);
  EXPECT_EQ(check_edge(tiny, 0, 3, {{tiny.positions[0][0], tiny.positions[0][1], tiny.positions[0][2]}}).veto,
            collapse::Veto::link_condition);
  const SimplifyResult r = simplify(tiny, {.target_triangles = 1});
  EXPECT_EQ(r.collapses, 0u);
  EXPECT_EQ(r.stop_reason, StopReason::no_valid_collapse);

  // A larger torus simplified as far as it goes keeps its handle.
  const Mesh torus = simplify_test::make_torus(40, 16);
  const SimplifyResult low = simplify(torus, {.target_triangles = 1});
  EXPECT_EQ(low.stop_reason, StopReason::no_valid_collapse);
  EXPECT_LT(low.triangles_after, 64u);
  const TopologySummary s = summary(low.mesh);
  EXPECT_EQ(s.euler_characteristic, 0);
  EXPECT_TRUE(s.closed_manifold());
  EXPECT_TRUE(validate(low.mesh).ok());
}

TEST(EdgeCollapse, LoneTriangleIsNotCollapsedAway) {
  // Collapsing any edge of a lone triangle would leave a dangling edge (and then nothing): the component
  // must stay.
  Mesh tri;
  tri.add_vertex_with_wedge({{0, 0, 0}});
  tri.add_vertex_with_wedge({{1, 0, 0}});
  tri.add_vertex_with_wedge({{0, 1, 0}});
  tri.add_face({0, 1, 2});
  tri.materials.push_back(MaterialSlot{});
  EXPECT_EQ(check_edge(tri, 0, 1, {{0.5, 0.0, 0.0}}).veto, collapse::Veto::dangling_face);
  const SimplifyResult r = simplify(tri, {.target_ratio = 0.01});
  EXPECT_EQ(r.triangles_after, 1u);
  EXPECT_EQ(r.stop_reason, StopReason::no_valid_collapse);
}

TEST(EdgeCollapse, RefusesFoldingPlacement) {
  // A flat 2×2 grid; collapse edge 4-5. Putting the new vertex at (-1, 1) turns face 0-4-3 over; putting it
  // on vertex 8 squashes face 4-8-7 to a line; the midpoint is fine.
  //   6 --- 7 --- 8
  //   |   / |   / |
  //   3 --- 4 --- 5
  //   |   / |   / |
  //   0 --- 1 --- 2
  const Mesh grid = testing::make_grid(2, 2, false);
  EXPECT_EQ(check_edge(grid, 4, 5, {{-1.0, 1.0, 0.0}}).veto, collapse::Veto::fold);
  EXPECT_EQ(check_edge(grid, 4, 5, {{2.0, 2.0, 0.0}}).veto, collapse::Veto::degenerate);
  EXPECT_TRUE(check_edge(grid, 4, 5, {{1.5, 1.0, 0.0}}).ok());
}

TEST(EdgeCollapse, FoldThresholdFollowsTheOption) {
  // Same grid; lift the new vertex of edge 4-5 above vertex 4 by h. The steepest face (3-4-7, whose far edge
  // is 1/sqrt(2) away) tilts by atan(sqrt(2) h): about 66 degrees for h = 1.6, 55 degrees for h = 1.
  const Mesh grid = testing::make_grid(2, 2, false);
  EXPECT_EQ(check_edge(grid, 4, 5, {{1.0, 1.0, 1.6}}).veto, collapse::Veto::fold);  // default 60 degrees
  EXPECT_TRUE(check_edge(grid, 4, 5, {{1.0, 1.0, 1.6}}, {.max_flip_angle_deg = 75.0}).ok());
  EXPECT_TRUE(check_edge(grid, 4, 5, {{1.0, 1.0, 1.0}}).ok());
  EXPECT_EQ(check_edge(grid, 4, 5, {{1.0, 1.0, 1.0}}, {.max_flip_angle_deg = 50.0}).veto, collapse::Veto::fold);
}

TEST(EdgeCollapse, LockedBorderIsBitIdentical) {
  const Mesh grid = make_bumpy_grid(20);
  const SimplifyResult r = simplify(grid, {.target_ratio = 0.1, .border_mode = BorderMode::lock});
  EXPECT_LT(r.triangles_after, grid.triangle_count() / 2);
  const auto out = position_set(r.mesh);
  std::size_t border = 0;
  for (const Vec3f& p : grid.positions) {
    if (p[0] == 0.0f || p[0] == 20.0f || p[1] == 0.0f || p[1] == 20.0f) {
      ++border;
      EXPECT_TRUE(out.count({p[0], p[1], p[2]})) << p[0] << "," << p[1];
    }
  }
  EXPECT_EQ(border, 80u);
  EXPECT_TRUE(validate(r.mesh).ok());
}

TEST(EdgeCollapse, ExplicitLockedVerticesStayPut) {
  const Mesh sphere = make_bumpy_sphere(24, 32);
  std::vector<std::uint32_t> locked;
  for (std::uint32_t v = 5; v < sphere.vertex_count(); v += 37) locked.push_back(v);
  const SimplifyResult r = simplify(sphere, {.target_ratio = 0.1, .locked_vertices = locked});
  EXPECT_EQ(r.stop_reason, StopReason::target_reached);
  const auto out = position_set(r.mesh);
  for (std::uint32_t v : locked) {
    const Vec3f& p = sphere.positions[v];
    EXPECT_TRUE(out.count({p[0], p[1], p[2]})) << "vertex " << v;
  }
  EXPECT_THROW(simplify(sphere, {.locked_vertices = {static_cast<std::uint32_t>(sphere.vertex_count())}}),
               std::invalid_argument);
}

TEST(EdgeCollapse, ClosedManifoldKeepsEulerCharacteristicAndValidity) {
  const Mesh sphere = make_bumpy_sphere(40, 60);
  for (double ratio : {0.3, 0.05, 0.01}) {
    const SimplifyResult r = simplify(sphere, {.target_ratio = ratio});
    const TopologySummary s = summary(r.mesh);
    EXPECT_TRUE(s.closed_manifold()) << ratio;
    EXPECT_EQ(s.euler_characteristic, 2) << ratio;
    EXPECT_EQ(s.inconsistent_edges, 0u) << ratio;
    const ValidationReport v = validate(r.mesh);
    EXPECT_TRUE(v.ok()) << ratio << ": " << (v.messages.empty() ? "" : v.messages.front());
    EXPECT_EQ(v.unreferenced_vertices, 0u);
  }
}

TEST(EdgeCollapse, ReachesTargetOnClosedMeshAtOnePercent) {
  const Mesh sphere = make_bumpy_sphere(50, 100);  // 9,900 triangles
  const SimplifyResult r = simplify(sphere, {.target_ratio = 0.01});
  EXPECT_EQ(r.stop_reason, StopReason::target_reached);
  const double target = std::round(0.01 * static_cast<double>(r.triangles_before));
  EXPECT_LE(std::abs(static_cast<double>(r.triangles_after) - target), 0.01 * target + 1.0);
  EXPECT_EQ(r.triangles_after, r.mesh.triangle_count());
}

TEST(EdgeCollapse, StopsAtErrorBudget) {
  const Mesh sphere = make_bumpy_sphere(40, 60);
  const double budget = 2e-3;
  const SimplifyResult r = simplify(sphere, {.target_triangles = 4, .max_error_rel = budget});
  EXPECT_EQ(r.stop_reason, StopReason::error_budget);
  EXPECT_GT(r.triangles_after, 4u);
  EXPECT_LT(r.triangles_after, r.triangles_before);
  EXPECT_LE(r.qem_error_rel, budget);
  EXPECT_GT(r.qem_error_rel, 0.0);
  // Verified by measurement: within the budget both ways (budget_test.cpp covers the back-off).
  EXPECT_TRUE(r.budget.verified);
  EXPECT_TRUE(r.budget.within);
  EXPECT_LE(evaluate(sphere, r.mesh).hausdorff_rel(), budget * 1.1);
  // The absolute budget is the same stop in model units.
  const double diag = compute_bounds(sphere).diagonal();
  const SimplifyResult a = simplify(sphere, {.target_triangles = 4, .max_error_abs = budget * diag});
  EXPECT_EQ(a.stop_reason, StopReason::error_budget);
  EXPECT_LE(a.qem_error_abs, budget * diag * (1 + 1e-9));
  // A looser budget removes more.
  const SimplifyResult loose = simplify(sphere, {.target_triangles = 4, .max_error_rel = 4 * budget});
  EXPECT_LT(loose.triangles_after, r.triangles_after);
}

TEST(EdgeCollapse, ErrorBoundGrowsWithReduction) {
  const Mesh sphere = make_bumpy_sphere(30, 40);
  double previous = -1.0;
  std::size_t previous_tris = sphere.triangle_count() + 1;
  for (double ratio : {0.5, 0.2, 0.05}) {
    const SimplifyResult r = simplify(sphere, {.target_ratio = ratio});
    EXPECT_LT(r.triangles_after, previous_tris);
    EXPECT_GE(r.qem_error_abs, previous);
    EXPECT_NEAR(r.qem_error_rel * compute_bounds(sphere).diagonal(), r.qem_error_abs, 1e-12);
    previous = r.qem_error_abs;
    previous_tris = r.triangles_after;
  }
}

TEST(EdgeCollapse, DeterministicAcrossThreadCounts) {
  const Mesh sphere = make_bumpy_sphere(60, 90);
  for (double ratio : {0.2, 0.02}) {
    const SimplifyResult r1 = simplify(sphere, {.target_ratio = ratio, .threads = 1});
    const SimplifyResult r2 = simplify(sphere, {.target_ratio = ratio, .threads = 2});
    const SimplifyResult r4 = simplify(sphere, {.target_ratio = ratio, .threads = 4});
    EXPECT_TRUE(r1.mesh == r2.mesh) << ratio;
    EXPECT_TRUE(r1.mesh == r4.mesh) << ratio;
    EXPECT_EQ(r1.qem_error_abs, r4.qem_error_abs);
    EXPECT_EQ(r1.collapses, r2.collapses);
  }
}

TEST(EdgeCollapse, BatchesKeepTheSequentialQuality) {
  // Batched rounds reorder a few collapses relative to the strictly sequential greedy order; the surface
  // distance must stay the same within a few percent.
  const Mesh sphere = make_bumpy_sphere(60, 90);
  const SimplifyResult seq = simplify(sphere, {.target_ratio = 0.05, .max_batch = 1});
  const SimplifyResult bat = simplify(sphere, {.target_ratio = 0.05});
  EXPECT_EQ(seq.triangles_after, bat.triangles_after);
  EXPECT_EQ(seq.rounds, seq.collapses + seq.vetoes.rejected());  // one candidate per round
  EXPECT_LT(bat.rounds, seq.rounds / 10);
  const EvalResult es = evaluate(sphere, seq.mesh, {.samples = 100000});
  const EvalResult eb = evaluate(sphere, bat.mesh, {.samples = 100000});
  EXPECT_LE(eb.mean, 1.05 * es.mean);
  EXPECT_LE(eb.rms, 1.05 * es.rms);
}

// A flat region aligned with the axes gives every candidate exactly the same cost. Ties must not go by
// vertex id: the lowest id would absorb one neighbour after another, growing a fan of slivers that every
// later round walks (quadratic; minutes on a 100k-triangle plate). The collapses spread evenly instead.
TEST(EdgeCollapse, FlatRegionsCollapseEvenly) {
  const Mesh grid = testing::make_grid(60, 60, false);
  const SimplifyResult r = simplify(grid, {.target_ratio = 0.1, .threads = 1});
  ASSERT_EQ(r.stop_reason, StopReason::target_reached);
  std::vector<std::uint32_t> valence(r.mesh.vertex_count(), 0);
  for (std::uint32_t w : r.mesh.corner_wedge) ++valence[r.mesh.wedge_vertex[w]];
  const std::uint32_t most = *std::max_element(valence.begin(), valence.end());
  EXPECT_LE(most, 16u);  // faces around the busiest vertex
  EXPECT_LT(r.rounds, r.collapses / 4);  // batches fill: candidates do not queue behind one vertex
}

// Packing the face lists (make_room) moves them within the pool and nothing else: the same collapses on a mesh
// packed every few steps give the same mesh, ring by ring and at the output.
TEST(EdgeCollapse, PackingTheFaceListsChangesNothing) {
  const Mesh sphere = make_bumpy_sphere(30, 40);
  const SimplifyOptions o;
  collapse::Parallel par(1);
  collapse::CollapseMesh plain(sphere, o, par), packed(sphere, o, par);
  collapse::Scratch s;
  std::vector<std::uint32_t> ring_plain, ring_packed;
  std::size_t collapses = 0;
  for (std::uint32_t u = 0; u < plain.vertex_count() && collapses < 400; u += 3) {
    if (!plain.alive(u) || plain.star_size(u) == 0) continue;
    plain.ring(u, ring_plain);
    for (std::uint32_t w : ring_plain) {
      const std::uint32_t a = std::min(u, w), b = std::max(u, w);
      if (plain.rule(a, b) == collapse::EdgeRule::forbidden) continue;
      const collapse::Evaluation ev = plain.evaluate(a, b);
      const collapse::Check c = plain.check(a, b, ev.position, s);
      ASSERT_EQ(c.veto, packed.check(a, b, ev.position, s).veto);
      if (!c.ok()) continue;
      plain.commit(c, ev.position, s);
      packed.commit(c, ev.position, s);
      if (++collapses % 25 == 0) packed.make_room(std::size_t{1} << 40);  // more than there is: packs every time
      break;
    }
  }
  EXPECT_GT(collapses, 300u);
  for (std::uint32_t v = 0; v < plain.vertex_count(); ++v) {
    ASSERT_EQ(plain.star_size(v), packed.star_size(v)) << v;
    plain.ring(v, ring_plain);
    packed.ring(v, ring_packed);
    ASSERT_EQ(ring_plain, ring_packed) << v;
  }
  EXPECT_TRUE(plain.output() == packed.output());
}

TEST(EdgeCollapse, PolygonInputIsTriangulatedFirst) {
  const Mesh cube = testing::make_cube_quads();
  const SimplifyResult r = simplify(cube, {.target_ratio = 1.0});
  EXPECT_EQ(r.triangles_before, 12u);
  EXPECT_EQ(r.triangles_after, 12u);
  EXPECT_EQ(count_face_kinds(r.mesh).triangles, 12u);
  EXPECT_EQ(r.mesh.positions, cube.positions);
  EXPECT_TRUE(validate(r.mesh).ok());
}

TEST(EdgeCollapse, SeamsStayOnTheirSide) {
  // A grid whose left and right halves have separate wedges along x = 10 (a UV seam): uv.x is 0 on the
  // left, 1 on the right. Every output face must take all its corners from one side.
  Mesh grid = make_bumpy_grid(20);
  grid.uvs.assign(1, std::vector<Vec2f>(grid.wedge_count()));
  const std::size_t nw = grid.wedge_count();
  std::vector<std::uint32_t> right_twin(grid.vertex_count(), kInvalidIndex);
  for (std::uint32_t w = 0; w < nw; ++w) {
    const Vec3f p = grid.positions[grid.wedge_vertex[w]];
    grid.uvs[0][w] = {{p[0] < 10.0f ? 0.0f : 1.0f, 0.0f}};
    if (p[0] == 10.0f) {
      grid.uvs[0][w] = {{0.0f, 0.0f}};
      right_twin[grid.wedge_vertex[w]] = static_cast<std::uint32_t>(grid.wedge_vertex.size());
      grid.wedge_vertex.push_back(grid.wedge_vertex[w]);
      grid.uvs[0].push_back({{1.0f, 0.0f}});
    }
  }
  for (std::size_t f = 0; f < grid.face_count(); ++f) {
    float cx = 0;
    for (std::uint32_t c = grid.face_offsets[f]; c < grid.face_offsets[f + 1]; ++c) cx += grid.positions[grid.corner_vertex(c)][0];
    if (cx / 3.0f <= 10.0f) continue;  // left face
    for (std::uint32_t c = grid.face_offsets[f]; c < grid.face_offsets[f + 1]; ++c) {
      const std::uint32_t v = grid.corner_vertex(c);
      if (right_twin[v] != kInvalidIndex) grid.corner_wedge[c] = right_twin[v];
    }
  }
  ASSERT_TRUE(validate(grid).ok());

  const SimplifyResult r = simplify(grid, {.target_ratio = 0.1});
  EXPECT_TRUE(validate(r.mesh).ok());
  EXPECT_LT(r.triangles_after, grid.triangle_count() / 4);
  ASSERT_EQ(r.mesh.uvs.size(), 1u);
  ASSERT_EQ(r.mesh.uvs[0].size(), r.mesh.wedge_count());
  std::size_t seam_vertices = 0;
  std::vector<int> wedges_of(r.mesh.vertex_count(), 0);
  for (std::uint32_t v : r.mesh.wedge_vertex) ++wedges_of[v];
  for (int n : wedges_of) seam_vertices += n > 1;
  EXPECT_GE(seam_vertices, 2u);  // the seam's two ends at least
  for (std::size_t f = 0; f < r.mesh.face_count(); ++f) {
    const std::uint32_t c0 = r.mesh.face_offsets[f];
    const float side = r.mesh.uvs[0][r.mesh.corner_wedge[c0]][0];
    for (std::uint32_t c = c0 + 1; c < r.mesh.face_offsets[f + 1]; ++c) {
      EXPECT_EQ(r.mesh.uvs[0][r.mesh.corner_wedge[c]][0], side) << "face " << f;
    }
  }
}

// The same mesh with its wedges numbered backwards (wedge w of vertex n - 1 - w), per-wedge normals moved with
// them.
Mesh with_reversed_wedges(const Mesh& m) {
  Mesh r = m;
  const auto nw = static_cast<std::uint32_t>(m.wedge_count());
  for (std::uint32_t w = 0; w < nw; ++w) r.wedge_vertex[nw - 1 - w] = m.wedge_vertex[w];
  for (std::uint32_t& c : r.corner_wedge) c = nw - 1 - c;
  for (std::uint32_t w = 0; w < m.normals.size(); ++w) r.normals[nw - 1 - w] = m.normals[w];
  return r;
}

std::vector<Vec3f> corner_positions(const Mesh& m) {
  std::vector<Vec3f> out;
  for (std::size_t c = 0; c < m.corner_count(); ++c) out.push_back(m.positions[m.corner_vertex(c)]);
  return out;
}

// Where each vertex is its one wedge (wedge id = vertex id) the engine keeps no per-corner wedge array and,
// with every face valid, no source-face array; numbered any other way it takes the general path. Both must
// make the same LOD: plain, with per-vertex normals, and with three materials at a target the strict seam stage
// cannot reach (the relaxed stages then start from the shortcut).
TEST(EdgeCollapse, OneWedgePerVertexNeedsNoWedgeArray) {
  Mesh plain = make_bumpy_sphere(30, 40);
  ASSERT_EQ(plain.wedge_count(), plain.vertex_count());
  for (std::uint32_t w = 0; w < plain.wedge_count(); ++w) ASSERT_EQ(plain.wedge_vertex[w], w);
  Mesh shaded = plain;
  for (const Vec3f& p : plain.positions) shaded.normals.push_back(p * (1.0f / std::sqrt(dot(p, p))));
  Mesh painted = plain;  // three materials in small patches: most vertices sit where several meet
  painted.materials.push_back(MaterialSlot{.name = "second"});
  painted.materials.push_back(MaterialSlot{.name = "third"});
  for (std::size_t f = 0; f < painted.face_count(); ++f) {
    painted.face_material[f] = static_cast<std::uint32_t>(f / 5 % 3);
  }
  struct Case {
    const Mesh* mesh;
    double ratio;
  };
  SeamStage last_stage = SeamStage::strict;
  for (const Case& c : {Case{&plain, 0.1}, Case{&shaded, 0.1}, Case{&painted, 0.1}, Case{&painted, 0.002}}) {
    const SimplifyResult own = simplify(*c.mesh, {.target_ratio = c.ratio});
    const SimplifyResult general = simplify(with_reversed_wedges(*c.mesh), {.target_ratio = c.ratio});
    ASSERT_GT(own.collapses, 0u);
    EXPECT_EQ(own.collapses, general.collapses);
    EXPECT_EQ(own.seam_stage, general.seam_stage);
    EXPECT_EQ(corner_positions(own.mesh), corner_positions(general.mesh));
    EXPECT_EQ(own.mesh.face_material, general.mesh.face_material);
    EXPECT_EQ(own.mesh.normals.size(), own.mesh.wedge_count() * !c.mesh->normals.empty());
    EXPECT_TRUE(validate(own.mesh).ok());
    last_stage = own.seam_stage;
  }
  EXPECT_GT(last_stage, SeamStage::strict);  // the last case went through the relaxed stages
}

TEST(EdgeCollapse, KeepsMaterialsAndGroupsPerFace) {
  Mesh grid = make_bumpy_grid(16);
  grid.materials.push_back(MaterialSlot{.name = "second"});
  grid.groups = {"left", "right"};
  grid.face_group.resize(grid.face_count());
  for (std::size_t f = 0; f < grid.face_count(); ++f) {
    const bool right = grid.positions[grid.corner_vertex(grid.face_offsets[f])][0] >= 8.0f;
    grid.face_material[f] = right ? 1 : 0;
    grid.face_group[f] = right ? 1 : 0;
  }
  const SimplifyResult r = simplify(grid, {.target_ratio = 0.2});
  EXPECT_EQ(r.mesh.materials, grid.materials);
  EXPECT_EQ(r.mesh.groups, grid.groups);
  ASSERT_EQ(r.mesh.face_group.size(), r.mesh.face_count());
  std::size_t per_material[2] = {0, 0};
  for (std::uint32_t m : r.mesh.face_material) ++per_material[m];
  EXPECT_GT(per_material[0], 0u);
  EXPECT_GT(per_material[1], 0u);
  for (std::size_t f = 0; f < r.mesh.face_count(); ++f) EXPECT_EQ(r.mesh.face_material[f], r.mesh.face_group[f]);
  EXPECT_TRUE(validate(r.mesh).ok());
}

TEST(EdgeCollapse, NonManifoldInputReportsNothingNew) {
  // A bumpy sphere plus a fin: three faces around one edge (non-manifold edge), and a second sphere touching
  // the first at a single vertex (non-manifold vertex).
  Mesh m = make_bumpy_sphere(20, 24);
  const std::uint32_t nv = static_cast<std::uint32_t>(m.vertex_count());
  // Fin on the edge of the first face.
  const std::uint32_t a = m.corner_vertex(0), b = m.corner_vertex(1);
  const Vec3f pa = m.positions[a], pb = m.positions[b];
  const std::uint32_t tip = m.add_vertex_with_wedge((pa + pb) * 0.5f + Vec3f{{0.0f, 0.0f, 0.3f}});
  m.add_face({a, b, tip});
  // Bowtie: a second sphere whose north pole is the first one's south pole vertex.
  Mesh second = make_bumpy_sphere(20, 24);
  const std::uint32_t south = nv - 1;
  const Vec3f offset = m.positions[south] - second.positions[0];
  std::vector<std::uint32_t> map(second.vertex_count());
  for (std::uint32_t v = 0; v < second.vertex_count(); ++v) {
    map[v] = v == 0 ? south : m.add_vertex_with_wedge(second.positions[v] + offset);
  }
  for (std::size_t f = 0; f < second.face_count(); ++f) {
    const std::uint32_t c = second.face_offsets[f];
    m.add_face({map[second.corner_vertex(c)], map[second.corner_vertex(c + 1)], map[second.corner_vertex(c + 2)]});
  }
  const ValidationReport before = validate(m);
  ASSERT_GT(before.non_manifold_edges, 0u);
  ASSERT_GT(before.non_manifold_vertices, 0u);
  for (double ratio : {0.3, 0.05}) {
    const SimplifyResult r = simplify(m, {.target_ratio = ratio});
    EXPECT_LT(r.triangles_after, m.triangle_count() / 2);
    expect_nothing_new(before, validate(r.mesh));
    // The locked non-manifold vertices keep their positions.
    const auto out = position_set(r.mesh);
    EXPECT_TRUE(out.count({m.positions[south][0], m.positions[south][1], m.positions[south][2]}));
  }
}

// Faces an exporter wrote twice make their edges non-manifold, which would lock the simplifier around them;
// simplify() drops them first and gives what the clean mesh gives, to a ratio of the input as it was.
TEST(EdgeCollapse, RepeatedFacesAreDroppedFirst) {
  const Mesh clean = make_bumpy_sphere(20, 24);
  const Mesh repeated = testing::with_repeated_faces(clean, 3);
  const std::size_t copies = repeated.face_count() - clean.face_count();
  ASSERT_EQ(repeated_faces(repeated).size(), copies);
  ASSERT_GT(validate(repeated).non_manifold_edges, 0u);
  for (Engine engine : {Engine::edge_collapse, Engine::multiple_choice}) {
    SimplifyOptions o{.target_ratio = 0.1};
    o.engine = engine;
    const SimplifyResult r = simplify(repeated, o);
    EXPECT_EQ(r.repeated_faces_removed, copies);
    EXPECT_EQ(r.triangles_before, repeated.triangle_count());
    SimplifyOptions same = o;
    same.target_triangles = static_cast<std::size_t>(std::round(0.1 * static_cast<double>(repeated.triangle_count())));
    const SimplifyResult c = simplify(clean, same);
    EXPECT_EQ(c.repeated_faces_removed, 0u);
    EXPECT_EQ(r.triangles_after, c.triangles_after);
    EXPECT_TRUE(r.mesh == c.mesh) << "engine " << static_cast<int>(engine);
    const ValidationReport v = validate(r.mesh);
    EXPECT_EQ(v.non_manifold_edges, 0u);
    EXPECT_EQ(v.duplicate_faces, 0u);
  }
}

TEST(EdgeCollapse, NonFinitePositionsAreLeftAlone) {
  Mesh m = make_bumpy_grid(10);
  m.positions[60][0] = std::numeric_limits<float>::quiet_NaN();
  const ValidationReport before = validate(m);
  ASSERT_EQ(before.nonfinite_positions, 1u);
  const SimplifyResult r = simplify(m, {.target_ratio = 0.2});
  EXPECT_LT(r.triangles_after, m.triangle_count());
  const ValidationReport after = validate(r.mesh);
  EXPECT_EQ(after.nonfinite_positions, 1u);
  EXPECT_EQ(after.duplicate_faces, 0u);
  EXPECT_EQ(after.non_manifold_edges, 0u);
  EXPECT_EQ(after.non_manifold_vertices, 0u);
}

TEST(EdgeCollapse, EmptyAndDegenerateInput) {
  Mesh empty;
  empty.materials.push_back(MaterialSlot{});
  const SimplifyResult r = simplify(empty, {});
  EXPECT_EQ(r.triangles_after, 0u);
  EXPECT_EQ(r.stop_reason, StopReason::target_reached);

  // Faces with a repeated vertex carry no surface: dropped, not crashed on.
  Mesh m = make_bumpy_grid(6);
  m.add_face({0, 0, 1});
  const SimplifyResult d = simplify(m, {.target_ratio = 0.5});
  EXPECT_EQ(validate(d.mesh).degenerate_faces, 0u);
}

TEST(SimplifyOptions, ValidateReportsEveryProblem) {
  const SimplifyOptions ok{};
  EXPECT_TRUE(ok.validate().empty());
  const SimplifyOptions bad{.target_ratio = 0.0,
                            .border_weight = -1.0,
                            .regularization_weight = std::numeric_limits<double>::infinity(),
                            .max_flip_angle_deg = 90.0,
                            .multiple_choice_k = 0};
  EXPECT_EQ(bad.validate().size(), 5u);
  EXPECT_THROW(simplify(testing::make_tetrahedron(), bad), std::invalid_argument);
  EXPECT_STREQ(stop_reason_name(StopReason::target_reached), "target_reached");
  EXPECT_STREQ(stop_reason_name(StopReason::error_budget), "error_budget");
  EXPECT_STREQ(stop_reason_name(StopReason::no_valid_collapse), "no_valid_collapse");
}

}  // namespace
}  // namespace lodforge
