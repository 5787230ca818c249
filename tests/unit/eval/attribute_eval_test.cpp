#include "lodforge/eval/attribute_eval.hpp"

#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <cmath>
#include <vector>

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

// A flat mesh (z = 0) from 3-D corners, one wedge per corner with the given UVs.
Mesh uv_mesh(const std::vector<Vec3f>& positions, const std::vector<std::array<std::uint32_t, 3>>& faces,
             const std::vector<std::array<Vec2f, 3>>& uvs) {
  Mesh m;
  m.positions = positions;
  m.uvs.resize(1);
  for (std::size_t f = 0; f < faces.size(); ++f) {
    std::uint32_t w[3];
    for (int i = 0; i < 3; ++i) {
      w[i] = static_cast<std::uint32_t>(m.wedge_vertex.size());
      m.wedge_vertex.push_back(faces[f][static_cast<std::size_t>(i)]);
      m.uvs[0].push_back(uvs[f][static_cast<std::size_t>(i)]);
    }
    m.add_face(w, 3);
  }
  m.materials.push_back({});
  return m;
}

TEST(AttributeEval, TrianglesOverZeroAreaUvStripsAreUnorientedNotFlipped) {
  // A quad whose UVs collapse onto the segment (0,0)-(1,0): the original has no UV orientation there.
  const std::vector<Vec3f> p = {{{0, 0, 0}}, {{1, 0, 0}}, {{1, 1, 0}}, {{0, 1, 0}}};
  const Vec2f a{{0, 0}}, b{{1, 0}};
  const Mesh strip = uv_mesh(p, {{0, 1, 2}, {0, 2, 3}}, {{a, b, b}, {a, b, a}});
  // The LOD opens the strip up slightly, one triangle each way round.
  const Vec2f c{{1, 0.01f}}, d{{0, 0.01f}};
  const Mesh opened = uv_mesh(p, {{0, 1, 2}, {0, 2, 3}}, {{a, b, c}, {a, c, d}});
  const AttributeEvalResult r = evaluate_attributes(strip, opened, kFast);
  ASSERT_EQ(r.uv_sets.size(), 1u);
  EXPECT_EQ(r.uv_sets[0].flipped, 0u);
  EXPECT_EQ(r.uv_sets[0].unoriented, 2u);
  EXPECT_EQ(r.uv_sets[0].degenerate_original, 2u);
}

TEST(AttributeEval, TrianglesBesideAFoldedChartKeepTheirSurfaceWinding) {
  // One chart folded onto itself at x = 1: the part x in [1, 1.5] maps back onto u in [0.5, 1], mirrored.
  const std::vector<Vec3f> p = {{{0, 0, 0}}, {{1, 0, 0}}, {{1, 1, 0}}, {{0, 1, 0}}, {{1.5f, 0, 0}}, {{1.5f, 1, 0}}};
  const Vec2f uv[6] = {{{0, 0}}, {{1, 0}}, {{1, 1}}, {{0, 1}}, {{0.5f, 0}}, {{0.5f, 1}}};
  auto tri = [&](std::uint32_t i, std::uint32_t j, std::uint32_t k) {
    return std::array<Vec2f, 3>{uv[i], uv[j], uv[k]};
  };
  const Mesh folded = uv_mesh(p, {{0, 1, 2}, {0, 2, 3}, {1, 4, 5}, {1, 5, 2}},
                              {tri(0, 1, 2), tri(0, 2, 3), tri(1, 4, 5), tri(1, 5, 2)});
  // The mirrored part keeps its winding on the surface, but its UVs reach past the fold's image (u < 0.5),
  // where only the other half lies in UV space.
  const Vec2f e{{0.1f, 0}}, f{{0.1f, 1}};
  const Mesh lod = uv_mesh(p, {{0, 1, 2}, {0, 2, 3}, {1, 4, 5}, {1, 5, 2}},
                           {tri(0, 1, 2), tri(0, 2, 3), {uv[1], e, f}, {uv[1], f, uv[2]}});
  const AttributeEvalResult r = evaluate_attributes(folded, lod, kFast);
  ASSERT_EQ(r.uv_sets.size(), 1u);
  EXPECT_EQ(r.uv_sets[0].flipped, 0u);
  EXPECT_EQ(r.uv_sets[0].fold, 1u);
  EXPECT_EQ(r.uv_sets[0].spanning, 0u);
  // A triangle turned over both in UV space and on the surface (where only one half lies): a flip.
  const Mesh turned = uv_mesh(p, {{0, 1, 2}, {0, 2, 3}, {1, 4, 5}, {1, 5, 2}},
                              {tri(0, 1, 2), tri(0, 3, 2), tri(1, 4, 5), tri(1, 5, 2)});
  EXPECT_EQ(evaluate_attributes(folded, turned, kFast).uv_flipped(), 1u);
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

TEST(AttributeEval, StopRequestSkipsTheRestAndSaysSo) {
  const Mesh m = attributed_grid(10);
  EXPECT_FALSE(evaluate_attributes(m, m, kFast).stopped);
  std::atomic<bool> flag{true};
  AttributeEvalOptions options = kFast;
  options.stop.flag = &flag;
  EXPECT_TRUE(evaluate_attributes(m, m, options).stopped);
}

TEST(AttributeEval, EmptyInputGivesAnEmptyResult) {
  const AttributeEvalResult r = evaluate_attributes(Mesh{}, attributed_grid(2), kFast);
  EXPECT_TRUE(r.attributes.empty());
  EXPECT_TRUE(r.uv_sets.empty());
}

}  // namespace
}  // namespace lodforge
