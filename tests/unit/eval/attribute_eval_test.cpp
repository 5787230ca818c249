#include "lodforge/eval/attribute_eval.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "../simplify/attribute_fixtures.hpp"
#include "test_support.hpp"

namespace lodforge {
namespace {

constexpr AttributeEvalOptions kFast{.samples = 20000, .pose_samples = 20000};

// A flat grid with UVs = xy / n, normals +z and a colour ramp.
Mesh attributed_grid(int n) {
  Mesh m = testing::make_grid(n, n, false);
  const std::size_t nw = m.wedge_count();
  m.normals.assign(nw, Vec3f{{0.0f, 0.0f, 1.0f}});
  m.uvs.assign(1, std::vector<Vec2f>(nw));
  m.colors.assign(1, std::vector<Vec4f>(nw));
  m.color_components = {4};
  for (std::size_t w = 0; w < nw; ++w) {
    const Vec3f p = m.positions[m.wedge_vertex[w]];
    m.uvs[0][w] = {{p[0] / float(n), p[1] / float(n)}};
    m.colors[0][w] = {{p[0] / float(n), 0.5f, 0.5f, 1.0f}};
  }
  return m;
}

const AttributeError* find(const AttributeEvalResult& r, const std::string& name) {
  for (const AttributeError& a : r.attributes) {
    if (a.name == name) return &a;
  }
  return nullptr;
}

TEST(AttributeEval, IdenticalMeshesScoreZero) {
  const Mesh m = attributed_grid(10);
  const AttributeEvalResult r = evaluate_attributes(m, m, kFast);
  ASSERT_NE(find(r, "NORMAL"), nullptr);
  ASSERT_NE(find(r, "TEXCOORD_0"), nullptr);
  ASSERT_NE(find(r, "COLOR_0"), nullptr);
  for (const AttributeError& a : r.attributes) EXPECT_LT(a.rms, 1e-6) << a.name;
  EXPECT_LT(r.normal_deviation_mean_deg, 1e-3);
  ASSERT_EQ(r.uv_sets.size(), 1u);
  EXPECT_NEAR(r.uv_sets[0].stretch_ratio, 1.0, 1e-9);
  EXPECT_EQ(r.uv_flipped(), 0u);
  EXPECT_EQ(r.uv_spanning(), 0u);
  EXPECT_TRUE(r.poses.empty());
}

TEST(AttributeEval, MeasuresColourNormalAndStretch) {
  const Mesh m = attributed_grid(10);
  Mesh changed = m;
  for (Vec4f& c : changed.colors[0]) c[1] += 0.1f;  // one channel off by 0.1 everywhere
  for (Vec3f& n : changed.normals) n = {{std::sin(0.2f), 0.0f, std::cos(0.2f)}};  // tilted by 0.2 rad
  for (Vec2f& uv : changed.uvs[0]) uv[0] *= 2.0f;  // anisotropic: stretch grows
  const AttributeEvalResult r = evaluate_attributes(m, changed, kFast);
  EXPECT_NEAR(find(r, "COLOR_0")->rms, 0.1, 1e-4);
  EXPECT_NEAR(r.normal_deviation_mean_deg, 0.2 * 180.0 / 3.14159265, 0.01);
  EXPECT_GT(r.uv_sets[0].stretch_ratio, 1.05);
  EXPECT_EQ(r.uv_flipped(), 0u);
}

TEST(AttributeEval, CountsFlippedUvTriangles) {
  const Mesh m = attributed_grid(10);
  Mesh folded = m;
  // Move the UV of vertex (5, 5) far across its neighbours: the triangles around it turn over.
  for (std::size_t w = 0; w < folded.wedge_count(); ++w) {
    const Vec3f p = folded.positions[folded.wedge_vertex[w]];
    if (p[0] == 5.0f && p[1] == 5.0f) folded.uvs[0][w] = {{0.75f, 0.52f}};
  }
  const AttributeEvalResult r = evaluate_attributes(m, folded, kFast);
  EXPECT_GE(r.uv_flipped(), 1u);
  EXPECT_EQ(r.uv_spanning(), 0u);
}

TEST(AttributeEval, CountsTrianglesSpanningCharts) {
  const Mesh cube = attribute_test::make_charted_cube(3);
  Mesh broken = cube;
  // Give one corner of the first triangle the wedge another chart uses at the same vertex.
  const std::uint32_t w0 = broken.corner_wedge[0];
  for (std::uint32_t w = 0; w < broken.wedge_count(); ++w) {
    if (w != w0 && broken.wedge_vertex[w] == broken.wedge_vertex[w0]) {
      broken.corner_wedge[0] = w;
      break;
    }
  }
  const AttributeEvalResult ok = evaluate_attributes(cube, cube, kFast);
  EXPECT_EQ(ok.uv_spanning(), 0u);
  EXPECT_EQ(ok.uv_flipped(), 0u);
  const AttributeEvalResult r = evaluate_attributes(cube, broken, kFast);
  EXPECT_EQ(r.uv_spanning(), 1u);
}

TEST(AttributeEval, SkinnedPosesExposeWrongWeights) {
  // Bone 0 below z = 1.5, bone 1 above z = 2.5, blended between.
  const Mesh tube = testing::make_two_bone_cylinder(20, 12, 1.5f, 1.0f);
  const AttributeEvalResult same = evaluate_attributes(tube, tube, kFast);
  ASSERT_EQ(same.poses.size(), 3u);  // bind + both joints (only two exist)
  EXPECT_EQ(same.poses[0].name, "bind");
  for (const PoseError& p : same.poses) EXPECT_LT(p.hausdorff_rel, 1e-6) << p.name;
  Mesh wrong = tube;
  for (SkinInfluences& s : wrong.skin) s.weights = {1.0f, 0.0f};  // everything on bone 0
  const AttributeEvalResult r = evaluate_attributes(tube, wrong, kFast);
  EXPECT_LT(r.poses[0].hausdorff_rel, 1e-6);  // identical at bind pose
  EXPECT_GT(r.pose_max_hausdorff_rel, 0.05);  // but not when a joint turns
}

TEST(AttributeEval, EmptyInputGivesAnEmptyResult) {
  const AttributeEvalResult r = evaluate_attributes(Mesh{}, attributed_grid(2), kFast);
  EXPECT_TRUE(r.attributes.empty());
  EXPECT_TRUE(r.uv_sets.empty());
}

}  // namespace
}  // namespace lodforge
