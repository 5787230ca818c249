// Property tests on real meshes from ../shared/corpus (skipped with a message when it is absent). Kept to a
// few meshes of at most ~100k triangles so the whole file runs in seconds.
#include <gtest/gtest.h>

#include <string>

#include "lodforge/core/validate.hpp"
#include "lodforge/eval/eval.hpp"
#include "lodforge/io/asset.hpp"
#include "lodforge/simplify/simplify.hpp"
#include "simplify_fixtures.hpp"
#include "test_support.hpp"

namespace lodforge {
namespace {

using simplify_test::expect_nothing_new;

TEST(SimplifyCorpus, BunnyMeetsTheQualityTargets) {
  LODFORGE_REQUIRE_CORPUS(path, "scanned/stanford-bunny.obj");
  const Mesh bunny = io::load_asset(path).meshes.at(0);
  // Textbook Garland-Heckbert reaches about 0.0190% / 0.144% mean error (of the diagonal) at 10% / 1%.
  struct Case {
    double ratio, max_mean_rel;
  };
  for (const Case c : {Case{0.1, 0.00020}, Case{0.01, 0.00150}}) {
    const SimplifyResult r = simplify(bunny, {.target_ratio = c.ratio});
    EXPECT_EQ(r.stop_reason, StopReason::target_reached);
    const EvalResult e = evaluate(bunny, r.mesh);
    EXPECT_LE(e.mean_rel(), c.max_mean_rel) << "ratio " << c.ratio;
    EXPECT_GT(e.mean_rel(), 0.0);
    expect_nothing_new(validate(bunny), validate(r.mesh));
  }
}

TEST(SimplifyCorpus, BunnyIsIdenticalForOneAndTwoThreads) {
  LODFORGE_REQUIRE_CORPUS(path, "scanned/stanford-bunny.obj");
  const Mesh bunny = io::load_asset(path).meshes.at(0);
  const SimplifyResult a = simplify(bunny, {.target_ratio = 0.05, .threads = 1});
  const SimplifyResult b = simplify(bunny, {.target_ratio = 0.05, .threads = 2});
  EXPECT_TRUE(a.mesh == b.mesh);
}

// Validity never gets worse than the input's, and lower ratios give fewer triangles.
void check_chain(const std::string& rel, Engine engine) {
  const auto path = testing::corpus_path(rel);
  if (path.empty()) GTEST_SKIP() << "corpus file " << rel << " absent (../shared/corpus)";
  const io::Asset asset = io::load_asset(path);
  for (const Mesh& mesh : asset.meshes) {
    const ValidationReport before = validate(triangulated(mesh));
    std::size_t previous = mesh.triangle_count() + 1;
    for (double ratio : {0.5, 0.2, 0.05}) {
      SCOPED_TRACE(rel + " ratio " + std::to_string(ratio));
      const SimplifyResult r = simplify(mesh, {.target_ratio = ratio, .engine = engine});
      expect_nothing_new(before, validate(r.mesh));
      EXPECT_LE(r.triangles_after, previous);
      EXPECT_EQ(r.triangles_after, r.mesh.triangle_count());
      if (r.stop_reason == StopReason::target_reached) {
        EXPECT_LE(r.triangles_after, static_cast<std::size_t>(std::round(ratio * double(r.triangles_before))) + 1);
      }
      previous = r.triangles_after;
    }
  }
}

TEST(SimplifyCorpus, NonManifoldScanKeepsItsTopologyFindings) {
  check_chain("scanned/happy-buddha-100k.obj", Engine::edge_collapse);
}

TEST(SimplifyCorpus, OpenAndPolygonMeshesStayValid) {
  check_chain("topology/blub_open.obj", Engine::edge_collapse);
  check_chain("quad/hexaSphere_polygons.obj", Engine::edge_collapse);
  check_chain("quad/makehuman_hair_bob01.obj", Engine::edge_collapse);  // duplicates, non-manifold cards
}

TEST(SimplifyCorpus, GltfWithSeamsAndNonManifoldEdgesStaysValid) {
  check_chain("hardsurface/kenney_cakeBirthday.glb", Engine::edge_collapse);
  check_chain("gltf/Duck.glb", Engine::edge_collapse);
}

TEST(SimplifyCorpus, MultipleChoiceStaysValid) {
  check_chain("scanned/demosthenes-17k.obj", Engine::multiple_choice);
  check_chain("hardsurface/kenney_cakeBirthday.glb", Engine::multiple_choice);
}

}  // namespace
}  // namespace lodforge
