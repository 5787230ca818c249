// Seam relaxation (SimplifyOptions::seams, SeamStage): each stage on a small mesh made here whose strict run
// stops before the target, the floors that remain named, and what relaxation must not change (a LOD the strict
// rules reach, thread-count independence, UV charts and materials). Corpus cases at the end skip with a message
// when ../shared/corpus is absent.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <string>
#include <vector>

#include "attribute_fixtures.hpp"
#include "lodforge/core/validate.hpp"
#include "lodforge/io/asset.hpp"
#include "lodforge/simplify/simplify.hpp"
#include "simplify_fixtures.hpp"
#include "test_support.hpp"

namespace lodforge {
namespace {

using attribute_test::chart_orientation;
using attribute_test::chart_report;
using attribute_test::make_charted_cube;
using attribute_test::tag_charts;
using simplify_test::expect_nothing_new;

bool reached(const SimplifyResult& r, std::size_t target) {
  return static_cast<double>(r.triangles_after) <= std::ceil(1.02 * static_cast<double>(target));
}

bool names(const SimplifyResult& r, const std::string& floor) {
  return std::find(r.floors.begin(), r.floors.end(), floor) != r.floors.end();
}

// A UV sphere with one wedge per corner: the face's own normal (neighbouring faces differ by about 11 degrees:
// soft creases) and a UV continuous across faces.
Mesh make_faceted_sphere(int rings, int segments) {
  const Mesh smooth = testing::make_uv_sphere(rings, segments);
  Mesh m;
  m.positions = smooth.positions;
  m.uvs.resize(1);
  for (std::size_t f = 0; f < smooth.face_count(); ++f) {
    const Vec3d n = face_normal_newell(smooth, f);
    const Vec3f un = to_float(n * (1.0 / std::max(length(n), 1e-12)));
    std::uint32_t w[3];
    for (int i = 0; i < 3; ++i) {
      const std::uint32_t v = smooth.corner_vertex(smooth.face_offsets[f] + static_cast<std::uint32_t>(i));
      w[i] = static_cast<std::uint32_t>(m.wedge_vertex.size());
      m.wedge_vertex.push_back(v);
      m.normals.push_back(un);
      const Vec3f p = m.positions[v];
      m.uvs[0].push_back({{0.5f + 0.4f * p[0], 0.5f + 0.4f * p[2]}});
    }
    m.add_face(w, 3);
  }
  m.materials.push_back(MaterialSlot{.name = "default"});
  return m;
}

// The charted cube with UVs continuous over its edges (a projection of the position): its corners are where
// three hard-normal seams meet, and nothing else splits a vertex.
Mesh make_hard_edged_cube(int n) {
  Mesh m = make_charted_cube(n);
  for (std::size_t w = 0; w < m.wedge_count(); ++w) {
    const Vec3f p = m.positions[m.wedge_vertex[w]];
    m.uvs[0][w] = {{(p[0] + 0.31f * p[1]) / float(2 * n), (p[2] + 0.73f * p[1]) / float(2 * n)}};
  }
  return m;
}

TEST(SeamRelax, SoftCreasesReachTheTargetAtTheCornersStage) {
  const Mesh sphere = make_faceted_sphere(16, 32);
  const std::size_t target = sphere.triangle_count() / 4;
  const SimplifyResult keep = simplify(sphere, {.target_ratio = 0.25, .seams = SeamMode::keep});
  EXPECT_FALSE(reached(keep, target));
  ASSERT_FALSE(keep.floors.empty());
  EXPECT_EQ(keep.floors.front(), "seams_kept");
  EXPECT_EQ(keep.seam_stage, SeamStage::strict);

  const SimplifyResult r = simplify(sphere, {.target_ratio = 0.25});
  EXPECT_TRUE(reached(r, target)) << r.triangles_after << " for " << target;
  EXPECT_EQ(r.stop_reason, StopReason::target_reached);
  EXPECT_EQ(r.seam_stage, SeamStage::corners);
  EXPECT_TRUE(r.floors.empty());
  expect_nothing_new(validate(sphere), validate(r.mesh));
}

// Facets 36 to 45 degrees apart are hard edges, beyond the corners stage: the normals stage merges them.
TEST(SeamRelax, HardNormalSeamsNeedTheNormalsStage) {
  const Mesh sphere = make_faceted_sphere(5, 8);
  const std::size_t target = sphere.triangle_count() / 4;
  const SimplifyResult keep = simplify(sphere, {.target_ratio = 0.25, .seams = SeamMode::keep});
  EXPECT_FALSE(reached(keep, target));
  const SimplifyResult r = simplify(sphere, {.target_ratio = 0.25});
  EXPECT_TRUE(reached(r, target)) << r.triangles_after << " for " << target;
  EXPECT_EQ(r.seam_stage, SeamStage::normals);
  expect_nothing_new(validate(sphere), validate(r.mesh));

  // Cube corners where three hard edges meet: the 12-triangle cube keeps the input's corners exactly.
  const Mesh cube = make_hard_edged_cube(6);
  const SimplifyResult c = simplify(cube, {.target_triangles = 12});
  EXPECT_EQ(c.triangles_after, 12u);
  const Bounds3 in = compute_bounds(cube), out = compute_bounds(c.mesh);
  EXPECT_EQ(in.min, out.min);
  EXPECT_EQ(in.max, out.max);
}

// UV-seam corners move by half-edge collapse; every face keeps the wedges of its own chart (no chart-spanning
// triangle), no UV triangle flips, charts stay.
TEST(SeamRelax, UvSeamCornersMoveWithoutSpanningOrFlippingCharts) {
  Mesh cube = make_charted_cube(6);
  tag_charts(cube);
  const auto orientation = chart_orientation(cube);
  for (std::size_t target : {12u, 8u}) {
    SCOPED_TRACE(target);
    const SimplifyResult r = simplify(cube, {.target_triangles = target});
    const auto c = chart_report(r.mesh, orientation);
    EXPECT_EQ(c.spanning, 0u);
    EXPECT_EQ(c.flipped, 0u);
    EXPECT_TRUE(reached(r, target) || !r.floors.empty()) << r.triangles_after;
    expect_nothing_new(validate(cube), validate(r.mesh));
    if (target == 8u) {
      EXPECT_EQ(r.seam_stage, SeamStage::uv);  // 8 triangles: a cube corner must move
      EXPECT_LT(r.triangles_after, 12u);
    }
  }
}

// Material boundaries hold with seams = relax (the floor is named) and move with relax_materials, which
// still leaves every material at least one triangle.
TEST(SeamRelax, MaterialBoundariesHoldUnlessAllowed) {
  Mesh cube = make_hard_edged_cube(4);
  cube.materials.clear();
  for (int i = 0; i < 6; ++i) cube.materials.push_back(MaterialSlot{.name = "side" + std::to_string(i)});
  cube.face_material.resize(cube.face_count());
  for (std::size_t f = 0; f < cube.face_count(); ++f) cube.face_material[f] = static_cast<std::uint32_t>(f / 32);
  auto materials_of = [](const Mesh& m) {
    return std::set<std::uint32_t>(m.face_material.begin(), m.face_material.end());
  };

  const SimplifyResult relax = simplify(cube, {.target_triangles = 6});
  EXPECT_GT(relax.triangles_after, 6u);
  EXPECT_TRUE(names(relax, "materials_kept")) << ::testing::PrintToString(relax.floors);
  EXPECT_EQ(materials_of(relax.mesh).size(), 6u);

  const SimplifyResult loose = simplify(cube, {.target_triangles = 6, .seams = SeamMode::relax_materials});
  EXPECT_LT(loose.triangles_after, relax.triangles_after);
  EXPECT_EQ(loose.seam_stage, SeamStage::materials);
  EXPECT_EQ(materials_of(loose.mesh).size(), 6u);  // one triangle per material slot at least
  expect_nothing_new(validate(cube), validate(loose.mesh));
}

TEST(SeamRelax, LockedVerticesAreANamedFloor) {
  Mesh sphere = make_faceted_sphere(8, 16);
  SimplifyOptions o{.target_ratio = 0.1};
  for (std::uint32_t v = 0; v < sphere.vertex_count(); ++v) o.locked_vertices.push_back(v);
  const SimplifyResult r = simplify(sphere, o);
  EXPECT_EQ(r.triangles_after, sphere.triangle_count());
  ASSERT_FALSE(r.floors.empty());
  EXPECT_EQ(r.floors.front(), "locked");
}

// Relaxation starts only when the strict rules run out: a target they reach gives the same LOD in every mode.
TEST(SeamRelax, ReachableTargetsAreTheStrictResult) {
  const Mesh cube = make_charted_cube(8);
  const SimplifyResult keep = simplify(cube, {.target_ratio = 0.2, .seams = SeamMode::keep});
  ASSERT_EQ(keep.stop_reason, StopReason::target_reached);
  for (SeamMode mode : {SeamMode::relax, SeamMode::relax_materials}) {
    const SimplifyResult r = simplify(cube, {.target_ratio = 0.2, .seams = mode});
    EXPECT_EQ(r.seam_stage, SeamStage::strict);
    EXPECT_EQ(r.mesh.positions, keep.mesh.positions);
    EXPECT_EQ(r.mesh.corner_wedge, keep.mesh.corner_wedge);
    EXPECT_EQ(r.mesh.normals, keep.mesh.normals);
    EXPECT_EQ(r.mesh.uvs, keep.mesh.uvs);
  }
}

TEST(SeamRelax, RelaxedOutputDoesNotDependOnThreads) {
  Mesh cube = make_charted_cube(24);
  const SimplifyResult one = simplify(cube, {.target_triangles = 8, .threads = 1});
  const SimplifyResult two = simplify(cube, {.target_triangles = 8, .threads = 2});
  ASSERT_EQ(one.seam_stage, SeamStage::uv);
  EXPECT_EQ(one.mesh.positions, two.mesh.positions);
  EXPECT_EQ(one.mesh.corner_wedge, two.mesh.corner_wedge);
  EXPECT_EQ(one.mesh.wedge_vertex, two.mesh.wedge_vertex);
  EXPECT_EQ(one.mesh.uvs, two.mesh.uvs);
  EXPECT_EQ(one.mesh.normals, two.mesh.normals);
}

// The multiple-choice engine relaxes the same way once its samples find nothing valid; still deterministic.
TEST(SeamRelax, MultipleChoiceRelaxesToo) {
  const Mesh sphere = make_faceted_sphere(16, 32);
  const std::size_t target = sphere.triangle_count() / 4;
  const SimplifyOptions keep{.target_ratio = 0.25, .engine = Engine::multiple_choice, .seams = SeamMode::keep};
  EXPECT_FALSE(reached(simplify(sphere, keep), target));
  const SimplifyResult one = simplify(sphere, {.target_ratio = 0.25, .threads = 1, .engine = Engine::multiple_choice});
  const SimplifyResult two = simplify(sphere, {.target_ratio = 0.25, .threads = 2, .engine = Engine::multiple_choice});
  EXPECT_TRUE(reached(one, target)) << one.triangles_after << " for " << target;
  EXPECT_GE(one.seam_stage, SeamStage::corners);
  EXPECT_EQ(one.mesh.positions, two.mesh.positions);
  EXPECT_EQ(one.mesh.corner_wedge, two.mesh.corner_wedge);
  expect_nothing_new(validate(sphere), validate(one.mesh));
}

// The deprecated flag means relax, also over an explicit keep.
TEST(SeamRelax, PermissiveIsAnAliasOfRelax) {
  const Mesh sphere = make_faceted_sphere(16, 32);
  const SimplifyResult a = simplify(sphere, {.target_ratio = 0.25, .seams = SeamMode::keep, .permissive = true});
  const SimplifyResult b = simplify(sphere, {.target_ratio = 0.25});
  EXPECT_EQ(a.mesh.positions, b.mesh.positions);
  EXPECT_EQ(a.mesh.corner_wedge, b.mesh.corner_wedge);
}

// An error budget verified by measurement replays the relaxed collapses in their stages.
TEST(SeamRelax, BudgetBackOffReplaysRelaxedStages) {
  const Mesh sphere = make_faceted_sphere(16, 32);
  const SimplifyResult r = simplify(sphere, {.target_ratio = 0.05, .max_error_rel = 0.02});
  EXPECT_TRUE(r.budget.verified);
  EXPECT_TRUE(r.budget.within);
  expect_nothing_new(validate(sphere), validate(r.mesh));
}

// ---- corpus ------------------------------------------------------------------------------------------------

struct CorpusCase {
  const char* path;
  double ratio;
  bool must_reach;  // no hard floor on this asset at this ratio: the target is reached within 2%
};

class SeamRelaxCorpus : public ::testing::TestWithParam<CorpusCase> {};

TEST_P(SeamRelaxCorpus, ReachesTheTargetOrNamesTheFloor) {
  const CorpusCase& c = GetParam();
  LODFORGE_REQUIRE_CORPUS(src, c.path);
  const io::Asset asset = io::load_asset(src);
  std::size_t total = 0, target = 0;
  bool floors = false;
  for (const Mesh& m : asset.meshes) {
    const Mesh tris = triangulated(m);
    const SimplifyResult r = simplify(tris, {.target_ratio = c.ratio});
    const std::size_t t =
        std::max<std::size_t>(1, static_cast<std::size_t>(std::llround(c.ratio * double(tris.triangle_count()))));
    total += r.triangles_after;
    target += t;
    const bool mesh_reached = static_cast<double>(r.triangles_after) <= std::ceil(1.02 * static_cast<double>(t));
    EXPECT_TRUE(mesh_reached || !r.floors.empty()) << c.path << ": " << r.triangles_after << " for " << t;
    floors |= !r.floors.empty();
    expect_nothing_new(validate(tris), validate(r.mesh));
  }
  if (c.must_reach) {
    EXPECT_LE(static_cast<double>(total), std::ceil(1.02 * static_cast<double>(target))) << c.path;
    EXPECT_FALSE(floors);
  }
}

std::string corpus_case_name(const ::testing::TestParamInfo<CorpusCase>& info) {
  return testing::test_name_of(info.param.path) + "_" + std::to_string(static_cast<int>(info.param.ratio * 100));
}

INSTANTIATE_TEST_SUITE_P(Corpus, SeamRelaxCorpus,
                         ::testing::Values(CorpusCase{"gltf/CesiumMilkTruck.glb", 0.25, true},
                                           CorpusCase{"gltf/armor-knight.gltf", 0.1, true},
                                           CorpusCase{"gltf/FlightHelmet/FlightHelmet.gltf", 0.1, true},
                                           CorpusCase{"skinned/Fox.glb", 0.1, false},
                                           CorpusCase{"skinned/RiggedFigure.glb", 0.25, false},
                                           CorpusCase{"hardsurface/kenney_alien.glb", 0.1, false},
                                           CorpusCase{"hardsurface/kenney_cakeBirthday.glb", 0.25, false}),
                         corpus_case_name);

}  // namespace
}  // namespace lodforge
