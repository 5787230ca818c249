// The polychord engine on real quad meshes from ../shared/corpus/quad (skipped with a message when absent):
// at 50% and 25% of the input triangles the result stays quad-dominant (quad fraction >= 0.85), validate()
// is clean, and the mean surface distance is within 1.5x of the triangle engine's at the same triangle count.
// The larger quad meshes (MakeHuman base, sword) are measured by lodforge_bench_quad instead. Not here
// because it misses the mean-distance target (see the benchmark and docs/quad-lods.md): the small Suzanne (968
// triangles, open eye components, 32 triangles to start with), 2.8x the triangle engine's mean at 50% and
// 2.3x at 25%. Its closed loops each take a tenth of the mesh, and the fitted quad surface has no more
// vertices than the triangle engine's but cannot place them where the curvature is.
#include <gtest/gtest.h>

#include <string>

#include "lodforge/core/validate.hpp"
#include "lodforge/eval/eval.hpp"
#include "lodforge/io/asset.hpp"
#include "lodforge/quad/polychord_collapse.hpp"
#include "lodforge/quad/quad_stats.hpp"
#include "lodforge/simplify/simplify.hpp"
#include "test_support.hpp"

namespace lodforge::quad {
namespace {

void expect_quad_lods_meet_targets(const std::string& relative) {
  LODFORGE_REQUIRE_CORPUS(path, relative);
  const Mesh mesh = io::load_asset(path).meshes.at(0);
  for (double ratio : {0.5, 0.25}) {
    SCOPED_TRACE(relative + " at " + std::to_string(ratio));
    SimplifyOptions quad_options{.target_ratio = ratio};
    quad_options.engine = Engine::polychord;
    const SimplifyResult q = simplify(mesh, quad_options);
    EXPECT_EQ(q.stop_reason, StopReason::target_reached);
    EXPECT_GE(quad_stats(q.mesh).quad_fraction, 0.85);
    const ValidationReport report = validate(q.mesh);
    EXPECT_TRUE(report.ok()) << (report.messages.empty() ? std::string() : report.messages.front());
    // glTF output and the evaluator split the quads along a diagonal: that must stay clean too.
    const ValidationReport split = validate(triangulated(q.mesh));
    EXPECT_TRUE(split.ok()) << (split.messages.empty() ? std::string() : split.messages.front());

    const SimplifyResult t = simplify(mesh, {.target_triangles = q.triangles_after});
    // The same count, or one collapse fewer (a collapse removes two triangles, one at a border): never more.
    ASSERT_LE(t.triangles_after, q.triangles_after) << "the triangle engine must reach the count to compare";
    ASSERT_GE(t.triangles_after + 2, q.triangles_after) << "the triangle engine must reach the count to compare";
    const double quad_mean = evaluate(mesh, q.mesh).mean, triangle_mean = evaluate(mesh, t.mesh).mean;
    EXPECT_LE(quad_mean, 1.5 * triangle_mean) << "polychord mean " << quad_mean << ", edge_collapse mean "
                                              << triangle_mean;
  }
}

// Mean distance of the polychord engine's LOD at `ratio` of the input with the surface fit, and without it.
struct FitEffect {
  double fitted = 0, unfitted = 0;
};
FitEffect fit_effect(const Mesh& mesh, double ratio) {
  PolychordOptions options{.target_ratio = ratio};
  FitEffect e;
  e.fitted = evaluate(mesh, simplify_polychord(mesh, options).mesh).mean;
  options.fit_surface = false;
  e.unfitted = evaluate(mesh, simplify_polychord(mesh, options).mesh).mean;
  return e;
}

// Collapses place vertices by quadrics, which leaves the new faces cutting under curved regions; fitting the
// moved vertices to the input surface must bring the result measurably closer on a real character mesh.
TEST(PolychordCorpus, SurfaceFitBringsACharacterCloser) {
  LODFORGE_REQUIRE_CORPUS(path, "quad/makehuman_male_casualsuit01.obj");
  const FitEffect e = fit_effect(io::load_asset(path).meshes.at(0), 0.25);
  EXPECT_LT(e.fitted, 0.9 * e.unfitted) << "fitted " << e.fitted << ", unfitted " << e.unfitted;
}

// On coarse subdivision cages a collapse moves a vertex across much of the shape: the least-squares fit (every
// moved vertex free in 3D, edge midpoints and input vertices as samples) brings their quarter LODs at least a
// quarter closer. Measured: spot 0.69, blub 0.63, penguin 0.66 of the unfitted mean distance; the
// normal-direction step it replaced reached 0.86, 0.82 and 0.88.
TEST(PolychordCorpus, SurfaceFitBringsCoarseCagesCloser) {
  for (const char* relative :
       {"quad/spot_control_mesh.obj", "quad/blub_control_mesh.obj", "quad/penguin_control_mesh.obj"}) {
    SCOPED_TRACE(relative);
    LODFORGE_REQUIRE_CORPUS(path, relative);
    const FitEffect e = fit_effect(io::load_asset(path).meshes.at(0), 0.25);
    EXPECT_LT(e.fitted, 0.75 * e.unfitted) << "fitted " << e.fitted << ", unfitted " << e.unfitted;
  }
}

TEST(PolychordCorpus, SpotStaysQuadDominantAndClose) {
  expect_quad_lods_meet_targets("quad/spot_quadrangulated.obj");
}

TEST(PolychordCorpus, BlubStaysQuadDominantAndClose) {
  expect_quad_lods_meet_targets("quad/blub_quadrangulated.obj");
}

TEST(PolychordCorpus, MakeHumanBodyStaysQuadDominantAndClose) {
  expect_quad_lods_meet_targets("quad/makehuman_male_generic.obj");
}

// A MakeHuman proxy (1460 triangles, UV seams runs may not cross): at 25% the triangle budget forced loops
// across the face until diagonal collapses stood in for them (2.07x the triangle engine's mean, now 1.45x).
TEST(PolychordCorpus, MakeHumanProxyStaysQuadDominantAndClose) {
  expect_quad_lods_meet_targets("quad/makehuman_proxy741.obj");
}

}  // namespace
}  // namespace lodforge::quad
