// Attribute-aware simplification of every glTF corpus asset (../shared/corpus gltf/ and skinned/; skipped with
// a message when absent) at 50%, 25% and 10%: no UV chart merges, no new UV flips, validity no worse, skin
// intact, and the written files pass the Khronos glTF validator with no new errors (skipped when node or the
// validator is absent). The synthetic tests in attribute_collapse_test.cpp cover every feature without the
// corpus.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "attribute_fixtures.hpp"
#include "corpus_assets.hpp"
#include "lodforge/core/validate.hpp"
#include "lodforge/io/asset.hpp"
#include "lodforge/simplify/simplify.hpp"
#include "simplify_fixtures.hpp"
#include "test_support.hpp"

namespace lodforge {
namespace {

namespace fs = std::filesystem;

class AttributeCorpus : public ::testing::TestWithParam<const char*> {};

std::string case_name(const ::testing::TestParamInfo<const char*>& info) {
  return testing::test_name_of(info.param);
}

void expect_skin_intact(const Mesh& in, const Mesh& out) {
  if (in.skin.empty()) return;
  ASSERT_EQ(out.skin.size(), out.vertex_count());
  std::uint16_t max_joint = 0;
  for (const SkinInfluences& s : in.skin) {
    for (int i = 0; i < kMaxInfluences; ++i) {
      if (s.weights[i] > 0) max_joint = std::max(max_joint, s.joints[i]);
    }
  }
  for (const SkinInfluences& s : out.skin) {
    float sum = 0;
    for (int i = 0; i < kMaxInfluences; ++i) {
      sum += s.weights[i];
      if (s.weights[i] > 0) {
        EXPECT_LE(s.joints[i], max_joint);
      }
    }
    EXPECT_NEAR(sum, 1.0f, 1e-3f);
  }
}

TEST_P(AttributeCorpus, SimplifiesWithoutChartMergesOrFlips) {
  LODFORGE_REQUIRE_CORPUS(src, GetParam());
  const io::Asset asset = io::load_asset(src);
  const fs::path dir = testing::temp_dir("attribute_corpus_" + case_name({GetParam(), 0}));
  std::vector<fs::path> written;
  for (double ratio : {0.5, 0.25, 0.1}) {
    io::Asset lod = asset;
    for (std::size_t i = 0; i < asset.meshes.size(); ++i) {
      SCOPED_TRACE(std::string(GetParam()) + " mesh " + std::to_string(i) + " ratio " + std::to_string(ratio));
      Mesh tagged = triangulated(asset.meshes[i]);
      attribute_test::tag_charts(tagged);
      const auto orientation = attribute_test::chart_orientation(tagged);
      const attribute_test::ChartReport before = attribute_test::chart_report(tagged, orientation);
      const SimplifyResult r = simplify(tagged, {.target_ratio = ratio});
      const attribute_test::ChartReport after = attribute_test::chart_report(r.mesh, orientation);
      EXPECT_EQ(after.spanning, 0u);
      EXPECT_LE(after.flipped, before.flipped);
      simplify_test::expect_nothing_new(validate(tagged), validate(r.mesh));
      expect_skin_intact(asset.meshes[i], r.mesh);
      EXPECT_LT(r.triangles_after, r.triangles_before + (ratio == 1.0));
      Mesh out = r.mesh;
      out.custom.pop_back();  // the _CHART tag
      lod.meshes[i] = std::move(out);
    }
    written.push_back(dir / ("lod_" + std::to_string(static_cast<int>(ratio * 100)) + ".glb"));
    io::save_asset(lod, written.back());
  }
  if (const std::string why = testing::gltf_validator_unavailable(); !why.empty()) {
    GTEST_SKIP() << "simplified; validator skipped: " << why;
  }
  const testing::CommandResult r = testing::validate_gltf(written, src);
  EXPECT_EQ(r.exit_code, 0) << r.output;
}

INSTANTIATE_TEST_SUITE_P(Gltf, AttributeCorpus, ::testing::ValuesIn(testing::kGltfAttributeAssets), case_name);

}  // namespace
}  // namespace lodforge
