// Attribute-aware simplification on small meshes made here (docs/simplifier.md, docs/seams.md): UV charts,
// seams, materials, attribute quadrics, painted priority, skinning, morph targets, tangents, permissive mode.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <vector>

#include "attribute_fixtures.hpp"
#include "lodforge/core/validate.hpp"
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

constexpr AttributeWeights kNoAttributes{.normal = 0, .uv = 0, .color = 0, .skin = 0};

// Smooth per-vertex normals of a triangle mesh with one wedge per vertex.
void add_vertex_normals(Mesh& m) {
  std::vector<Vec3d> n(m.vertex_count(), Vec3d{});
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    const Vec3d fn = face_normal_newell(m, f);
    for (std::uint32_t c = m.face_offsets[f]; c < m.face_offsets[f + 1]; ++c) {
      n[m.corner_vertex(c)] = n[m.corner_vertex(c)] + fn;
    }
  }
  m.normals.resize(m.wedge_count());
  for (std::size_t w = 0; w < m.wedge_count(); ++w) {
    const Vec3d v = n[m.wedge_vertex[w]];
    const double len = std::max(length(v), 1e-12);
    m.normals[w] = to_float(v * (1.0 / len));
  }
}

TEST(AttributeCollapse, CubeWithSixChartsKeepsThemAtTheMinimum) {
  Mesh cube = make_charted_cube(6);
  tag_charts(cube);
  const auto orientation = chart_orientation(cube);
  for (AttributePlacement placement : {AttributePlacement::optimal, AttributePlacement::keep}) {
    const SimplifyResult r = simplify(cube, {.target_triangles = 12, .attribute_placement = placement});
    const attribute_test::ChartReport c = chart_report(r.mesh, orientation);
    EXPECT_EQ(c.charts, 6u);
    EXPECT_EQ(c.spanning, 0u);
    EXPECT_EQ(c.flipped, 0u);
    // Seams move only along themselves: every side is still flat, so the cube stays a cube, and it gets far.
    EXPECT_LE(r.triangles_after, 24u);
    for (const Vec3f& p : r.mesh.positions) {
      const int on_faces = (p[0] == 0.0f || p[0] == 6.0f) + (p[1] == 0.0f || p[1] == 6.0f) + (p[2] == 0.0f || p[2] == 6.0f);
      EXPECT_GE(on_faces, 1);
    }
    expect_nothing_new(validate(cube), validate(r.mesh));
    // The seams are still seams: the output's own UV charts are six.
    const std::vector<std::uint32_t> out_charts = attribute_test::uv_charts(r.mesh);
    EXPECT_EQ(std::set<std::uint32_t>(out_charts.begin(), out_charts.end()).size(), 6u);
  }
}

// Attribute weights 0 give exactly the geometry-only result (the same mesh with its
// wedge structure but no attribute values).
TEST(AttributeCollapse, ZeroWeightsReproduceTheGeometryOnlyResult) {
  Mesh m = simplify_test::make_bumpy_grid(24);
  add_vertex_normals(m);
  const std::size_t nw = m.wedge_count();
  m.uvs.assign(1, std::vector<Vec2f>(nw));
  m.colors.assign(1, std::vector<Vec4f>(nw));
  m.color_components = {4};
  for (std::size_t w = 0; w < nw; ++w) {
    const Vec3f p = m.positions[m.wedge_vertex[w]];
    m.uvs[0][w] = {{p[0] / 24.0f, p[1] / 24.0f}};
    m.colors[0][w] = {{0.5f + 0.5f * std::sin(p[0]), 0.5f + 0.5f * std::cos(0.7f * p[1]), 0.2f, 1.0f}};
  }
  Mesh bare = m;
  bare.normals.clear();
  bare.uvs.clear();
  bare.colors.clear();
  bare.color_components.clear();
  for (double ratio : {0.5, 0.1}) {
    const SimplifyResult geometry = simplify(bare, {.target_ratio = ratio});
    const SimplifyResult zero = simplify(m, {.target_ratio = ratio, .attribute_weights = kNoAttributes});
    EXPECT_EQ(zero.mesh.positions, geometry.mesh.positions) << ratio;
    EXPECT_EQ(zero.mesh.corner_wedge, geometry.mesh.corner_wedge) << ratio;
    EXPECT_EQ(zero.mesh.wedge_vertex, geometry.mesh.wedge_vertex) << ratio;
    EXPECT_EQ(zero.qem_error_abs, geometry.qem_error_abs) << ratio;
    // And the weights do change something when they are not zero (so the comparison above can fail).
    const SimplifyResult with = simplify(m, {.target_ratio = ratio});
    EXPECT_NE(with.mesh.positions, geometry.mesh.positions) << ratio;
  }
}

// With attributes in the metric, vertices gather where the colour changes quickly.
TEST(AttributeCollapse, ColourGradientKeepsVerticesWhereColourChanges) {
  Mesh m = testing::make_grid(40, 40, false);  // flat: geometry alone does not care where vertices go
  const std::size_t nw = m.wedge_count();
  m.colors.assign(1, std::vector<Vec4f>(nw));
  m.color_components = {4};
  auto colour = [](float x) { return 1.0f / (1.0f + std::exp(-(x - 12.0f) * 1.5f)); };  // a step near x = 12
  for (std::size_t w = 0; w < nw; ++w) {
    const float c = colour(m.positions[m.wedge_vertex[w]][0]);
    m.colors[0][w] = {{c, c, c, 1.0f}};
  }
  auto near_step = [](const Mesh& out) {
    std::size_t n = 0, interior = 0;
    for (const Vec3f& p : out.positions) {
      if (p[0] <= 0.0f || p[0] >= 40.0f || p[1] <= 0.0f || p[1] >= 40.0f) continue;  // border vertices
      ++interior;
      n += std::abs(p[0] - 12.0f) < 4.0f;
    }
    return interior > 0 ? double(n) / double(interior) : 0.0;
  };
  const SimplifyResult plain = simplify(m, {.target_ratio = 0.1, .attribute_weights = kNoAttributes});
  const SimplifyResult aware = simplify(m, {.target_ratio = 0.1, .attribute_weights = {.color = 4.0}});
  EXPECT_EQ(aware.stop_reason, StopReason::target_reached);
  EXPECT_GT(near_step(aware.mesh), near_step(plain.mesh) + 0.1);
  // The colours stay colours.
  for (const Vec4f& c : aware.mesh.colors[0]) {
    for (int i = 0; i < 4; ++i) EXPECT_TRUE(c[i] >= 0.0f && c[i] <= 1.0f);
  }
}

TEST(AttributeCollapse, PaintedHemisphereKeepsMostVertices) {
  Mesh sphere = testing::make_uv_sphere(40, 80);
  sphere.priority.resize(sphere.vertex_count());
  for (std::size_t v = 0; v < sphere.vertex_count(); ++v) sphere.priority[v] = sphere.positions[v][2] > 0 ? 10.0f : 1.0f;
  for (const char* channel : {"_LOD_PRIORITY", "none"}) {
    const SimplifyResult r = simplify(sphere, {.target_ratio = 0.1, .priority_channel = channel});
    std::size_t top = 0, bottom = 0;
    for (const Vec3f& p : r.mesh.positions) {
      top += p[2] > 1e-4f;
      bottom += p[2] < -1e-4f;
    }
    const double share = double(top) / double(top + bottom);
    if (std::string(channel) == "none") {
      EXPECT_LT(share, 0.6);  // unpainted: about half, so the painted run below is the paint's doing
    } else {
      EXPECT_GT(share, 0.7);
    }
  }
}

TEST(AttributeCollapse, PriorityFromAColourChannelAndLockAtTheMaximum) {
  Mesh sphere = testing::make_uv_sphere(20, 40);
  const std::size_t nw = sphere.wedge_count();
  sphere.colors.assign(1, std::vector<Vec4f>(nw, Vec4f{{0.0f, 1.0f, 1.0f, 1.0f}}));
  sphere.color_components = {4};
  std::set<std::array<float, 3>> locked;
  for (std::size_t w = 0; w < nw; ++w) {
    const Vec3f p = sphere.positions[sphere.wedge_vertex[w]];
    if (p[0] > 0.5f) {
      sphere.colors[0][w][0] = 1.0f;  // red = 1 = priority_lock below: locked
      locked.insert({p[0], p[1], p[2]});
    }
  }
  const SimplifyResult r = simplify(sphere, {.target_ratio = 0.2,
                                             .attribute_weights = kNoAttributes,
                                             .priority_channel = "COLOR_0.r",
                                             .priority_lock = 1.0});
  const auto kept = simplify_test::position_set(r.mesh);
  for (const auto& p : locked) EXPECT_TRUE(kept.count(p)) << p[0] << " " << p[1] << " " << p[2];
  // Red 0 elsewhere means "don't care": that region goes first.
  EXPECT_LT(r.mesh.vertex_count(), sphere.vertex_count() / 2);
}

int dominant(const SkinInfluences& s) {
  int best = 0;
  for (int i = 1; i < kMaxInfluences; ++i) best = s.weights[i] > s.weights[best] ? i : best;
  return s.joints[best];
}

TEST(AttributeCollapse, TwoBoneCylinderKeepsBonesApart) {
  // Bone 0 below z = 1.6, bone 1 above z = 2.4, a linear blend band between.
  const Mesh cyl = testing::make_two_bone_cylinder(40, 24, 1.6f, 0.8f);
  for (double ratio : {0.2, 0.05}) {
    const SimplifyResult r = simplify(cyl, {.target_ratio = ratio});
    ASSERT_EQ(r.mesh.skin.size(), r.mesh.vertex_count());
    auto outside_band = [&](std::uint32_t v) {
      const SkinInfluences& s = r.mesh.skin[v];
      return *std::max_element(s.weights.begin(), s.weights.end()) >= 0.9f;
    };
    std::size_t joins = 0;
    for (std::size_t f = 0; f < r.mesh.face_count(); ++f) {
      for (int i = 0; i < 3; ++i) {
        const std::uint32_t p = r.mesh.corner_vertex(r.mesh.face_offsets[f] + i);
        const std::uint32_t q = r.mesh.corner_vertex(r.mesh.face_offsets[f] + (i + 1) % 3);
        joins += outside_band(p) && outside_band(q) && dominant(r.mesh.skin[p]) != dominant(r.mesh.skin[q]);
      }
    }
    EXPECT_EQ(joins, 0u) << ratio;
    for (std::size_t v = 0; v < r.mesh.vertex_count(); ++v) {
      const SkinInfluences& s = r.mesh.skin[v];
      float sum = 0.0f;
      int both = 0;
      for (float w : s.weights) {
        sum += w;
        both += w > 0.1f;
      }
      EXPECT_NEAR(sum, 1.0f, 1e-5f);
      const float z = r.mesh.positions[v][2];
      if (z < 1.5f || z > 2.5f) {
        EXPECT_LT(both, 2) << "z " << z;  // outside the band (plus a ring's margin)
      }
    }
    EXPECT_LE(r.triangles_after, static_cast<std::size_t>(std::round(ratio * double(r.triangles_before))) + 16);
  }
  // The rule is what keeps them apart: a copy with one bone everywhere collapses through the band freely.
}

TEST(AttributeCollapse, MaterialBoundariesStayPut) {
  Mesh m = simplify_test::make_bumpy_grid(30);
  m.materials.push_back(MaterialSlot{.name = "right"});
  m.face_material.assign(m.face_count(), 0);
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    double cx = 0;
    for (std::uint32_t c = m.face_offsets[f]; c < m.face_offsets[f + 1]; ++c) cx += m.positions[m.corner_vertex(c)][0];
    m.face_material[f] = cx / 3.0 > 15.0 ? 1 : 0;  // shared wedges across the boundary (as in OBJ usemtl runs)
  }
  const SimplifyResult r = simplify(m, {.target_ratio = 0.1});
  std::size_t per[2] = {0, 0};
  for (std::size_t f = 0; f < r.mesh.face_count(); ++f) {
    const std::uint32_t mat = r.mesh.face_material[f];
    ++per[mat];
    for (std::uint32_t c = r.mesh.face_offsets[f]; c < r.mesh.face_offsets[f + 1]; ++c) {
      const float x = r.mesh.positions[r.mesh.corner_vertex(c)][0];
      // Seam constraint planes hold the boundary within 1% of an edge length of its line.
      if (mat == 0) {
        EXPECT_LE(x, 15.0f + 0.01f);
      } else {
        EXPECT_GE(x, 15.0f - 0.01f);
      }
    }
  }
  EXPECT_GT(per[0], 0u);
  EXPECT_GT(per[1], 0u);
  EXPECT_LE(r.triangles_after, static_cast<std::size_t>(0.1 * double(r.triangles_before)) + 2);
}

// A sphere with flat shading (one wedge per face corner, normals of the face) and one UV chart per hemisphere.
Mesh make_flat_shaded_sphere() {
  const Mesh smooth = testing::make_uv_sphere(16, 32);
  Mesh m;
  m.positions = smooth.positions;
  m.uvs.resize(1);
  for (std::size_t f = 0; f < smooth.face_count(); ++f) {
    const Vec3d n = face_normal_newell(smooth, f);
    const Vec3f un = to_float(n * (1.0 / length(n)));
    std::uint32_t w[3];
    for (int i = 0; i < 3; ++i) {
      const std::uint32_t v = smooth.corner_vertex(smooth.face_offsets[f] + i);
      w[i] = static_cast<std::uint32_t>(m.wedge_vertex.size());
      m.wedge_vertex.push_back(v);
      m.normals.push_back(un);
      const Vec3f p = m.positions[v];
      m.uvs[0].push_back({{0.5f + 0.4f * p[0], 0.5f + 0.4f * p[1]}});  // planar projection: overlapping halves
    }
    m.add_face(w, 3);
  }
  m.materials.push_back(MaterialSlot{.name = "default"});
  return m;
}

TEST(AttributeCollapse, PermissiveCrossesHardEdgesButNotUvSeams) {
  Mesh sphere = make_flat_shaded_sphere();
  // UVs continuous across hard edges: UV value per vertex, so only normals differ between a vertex's wedges.
  const SimplifyResult strict = simplify(sphere, {.target_ratio = 0.25, .seams = SeamMode::keep});
  const SimplifyResult loose = simplify(sphere, {.target_ratio = 0.25, .seams = SeamMode::keep, .permissive = true});
  EXPECT_EQ(strict.stop_reason, StopReason::no_valid_collapse);  // every vertex is a seam
  EXPECT_FALSE(strict.floors.empty());
  EXPECT_EQ(strict.floors.front(), "seams_kept");
  EXPECT_EQ(loose.stop_reason, StopReason::target_reached);
  expect_nothing_new(validate(sphere), validate(loose.mesh));

  // UV seams still hold in permissive mode: the six-chart cube keeps its charts.
  Mesh cube = make_charted_cube(6);
  tag_charts(cube);
  const SimplifyResult r = simplify(cube, {.target_triangles = 12, .permissive = true});
  const auto c = chart_report(r.mesh, chart_orientation(cube));
  EXPECT_EQ(c.charts, 6u);
  EXPECT_EQ(c.spanning, 0u);
  EXPECT_EQ(c.flipped, 0u);
}

// Exporters round the normal of one smooth vertex differently per render vertex: such wedges are one wedge,
// no hard edge, so the mesh simplifies as if it had one wedge per vertex; a real hard edge still holds.
TEST(AttributeCollapse, NormalsEqualUpToRoundingAreNoSeam) {
  Mesh smooth = simplify_test::make_bumpy_sphere(24, 48);
  add_vertex_normals(smooth);
  // One wedge per corner, normals nudged by about 1e-6 rad, differently at each corner.
  Mesh split;
  split.positions = smooth.positions;
  split.materials = smooth.materials;
  for (std::size_t f = 0; f < smooth.face_count(); ++f) {
    std::uint32_t w[3];
    for (int i = 0; i < 3; ++i) {
      const std::uint32_t c = smooth.face_offsets[f] + static_cast<std::uint32_t>(i);
      split.wedge_vertex.push_back(smooth.corner_vertex(c));
      Vec3f n = smooth.normals[smooth.corner_wedge[c]];
      n[i] += 1e-6f * static_cast<float>(1 + (f + static_cast<std::size_t>(i)) % 3);
      split.normals.push_back(n);
      w[i] = static_cast<std::uint32_t>(split.wedge_vertex.size() - 1);
    }
    split.add_face(w, 3);
  }
  const SimplifyResult a = simplify(smooth, {.target_ratio = 0.1});
  const SimplifyResult b = simplify(split, {.target_ratio = 0.1});
  EXPECT_EQ(b.stop_reason, StopReason::target_reached);
  EXPECT_EQ(b.triangles_after, a.triangles_after);
  EXPECT_NEAR(b.qem_error_rel, a.qem_error_rel, 0.05 * a.qem_error_rel);
  EXPECT_EQ(b.mesh.wedge_count(), b.mesh.vertex_count());  // one wedge per vertex left

  // Face normals several degrees apart are hard edges: every vertex of the flat-shaded sphere stays a seam.
  const SimplifyResult hard = simplify(make_flat_shaded_sphere(), {.target_ratio = 0.25, .seams = SeamMode::keep});
  EXPECT_EQ(hard.stop_reason, StopReason::no_valid_collapse);
}

TEST(AttributeCollapse, KeepModeCopiesSurvivorAttributes) {
  Mesh m = simplify_test::make_bumpy_sphere(24, 48);
  add_vertex_normals(m);
  const std::size_t nw = m.wedge_count();
  m.uvs.assign(1, std::vector<Vec2f>(nw));
  for (std::size_t w = 0; w < nw; ++w) {
    const Vec3f p = m.positions[m.wedge_vertex[w]];
    m.uvs[0][w] = {{std::atan2(p[1], p[0]), p[2]}};
  }
  std::set<std::array<float, 5>> input;
  for (std::size_t w = 0; w < nw; ++w) {
    input.insert({m.normals[w][0], m.normals[w][1], m.normals[w][2], m.uvs[0][w][0], m.uvs[0][w][1]});
  }
  const SimplifyResult keep = simplify(m, {.target_ratio = 0.2, .attribute_placement = AttributePlacement::keep});
  for (std::size_t w = 0; w < keep.mesh.wedge_count(); ++w) {
    const auto& n = keep.mesh.normals[w];
    const auto& uv = keep.mesh.uvs[0][w];
    EXPECT_TRUE(input.count({n[0], n[1], n[2], uv[0], uv[1]}));
  }
  // Optimal placement makes new, clamped values: unit normals.
  const SimplifyResult optimal = simplify(m, {.target_ratio = 0.2});
  std::size_t fresh = 0;
  for (std::size_t w = 0; w < optimal.mesh.wedge_count(); ++w) {
    const auto& n = optimal.mesh.normals[w];
    EXPECT_NEAR(std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]), 1.0f, 1e-4f);
    fresh += !input.count({n[0], n[1], n[2], optimal.mesh.uvs[0][w][0], optimal.mesh.uvs[0][w][1]});
  }
  EXPECT_GT(fresh, 0u);
}

TEST(AttributeCollapse, TangentsAreRecomputed) {
  Mesh m = simplify_test::make_bumpy_grid(20);
  add_vertex_normals(m);
  const std::size_t nw = m.wedge_count();
  m.uvs.assign(1, std::vector<Vec2f>(nw));
  m.tangents.assign(nw, Vec4f{{0.0f, 0.0f, 1.0f, 1.0f}});  // deliberately wrong
  for (std::size_t w = 0; w < nw; ++w) {
    const Vec3f p = m.positions[m.wedge_vertex[w]];
    m.uvs[0][w] = {{p[0] / 20.0f, p[1] / 20.0f}};
  }
  const SimplifyResult r = simplify(m, {.target_ratio = 0.2});
  ASSERT_EQ(r.mesh.tangents.size(), r.mesh.wedge_count());
  for (std::size_t w = 0; w < r.mesh.wedge_count(); ++w) {
    const Vec4f t = r.mesh.tangents[w];
    const Vec3f n = r.mesh.normals[w];
    EXPECT_NEAR(t[0] * t[0] + t[1] * t[1] + t[2] * t[2], 1.0f, 1e-4f);
    EXPECT_NEAR(t[0] * n[0] + t[1] * n[1] + t[2] * n[2], 0.0f, 1e-4f);
    EXPECT_GT(t[0], 0.8f);  // u runs along +x
    EXPECT_EQ(t[3], 1.0f);
  }
}

TEST(AttributeCollapse, MorphDeltasFollowTheCollapses) {
  Mesh m = simplify_test::make_bumpy_grid(20);
  MorphTarget t{"lift", {}, {}, {}};
  for (std::size_t w = 0; w < m.wedge_count(); ++w) {
    const Vec3f p = m.positions[m.wedge_vertex[w]];
    t.position_deltas.push_back({{0.0f, 0.0f, 0.05f * p[0]}});  // linear: blending along edges is exact
  }
  m.morph_targets.push_back(t);
  const SimplifyResult r = simplify(m, {.target_ratio = 0.2});
  ASSERT_EQ(r.mesh.morph_targets.size(), 1u);
  ASSERT_EQ(r.mesh.morph_targets[0].position_deltas.size(), r.mesh.wedge_count());
  for (std::size_t w = 0; w < r.mesh.wedge_count(); ++w) {
    const Vec3f p = r.mesh.positions[r.mesh.wedge_vertex[w]];
    // Within two input edge lengths of the delta field at the vertex's new place.
    EXPECT_NEAR(r.mesh.morph_targets[0].position_deltas[w][2], 0.05f * p[0], 0.1f);
  }
}

TEST(AttributeCollapse, DeterministicForAnyThreadCount) {
  Mesh cube = make_charted_cube(12);
  cube.colors.assign(1, std::vector<Vec4f>(cube.wedge_count()));
  cube.color_components = {4};
  for (std::size_t w = 0; w < cube.wedge_count(); ++w) {
    const Vec3f p = cube.positions[cube.wedge_vertex[w]];
    cube.colors[0][w] = {{p[0] / 12.0f, p[1] / 12.0f, p[2] / 12.0f, 1.0f}};
  }
  const SimplifyResult a = simplify(cube, {.target_ratio = 0.1, .threads = 1});
  const SimplifyResult b = simplify(cube, {.target_ratio = 0.1, .threads = 2});
  const SimplifyResult c = simplify(cube, {.target_ratio = 0.1, .threads = 4});
  EXPECT_TRUE(a.mesh == b.mesh);
  EXPECT_TRUE(a.mesh == c.mesh);
}

// Bad attribute data never crashes and never makes the output invalid: NaN/Inf values, a stream of the wrong
// length, all-zero skin weights, negative and NaN priorities.
TEST(AttributeCollapse, HostileAttributesAreSurvived) {
  Mesh m = simplify_test::make_bumpy_sphere(16, 32);
  const std::size_t nw = m.wedge_count();
  add_vertex_normals(m);
  m.normals[3] = {{NAN, 0.0f, 1.0f}};
  m.uvs.assign(2, std::vector<Vec2f>(nw, Vec2f{{0.5f, 0.5f}}));
  for (std::size_t w = 0; w < nw; ++w) m.uvs[0][w] = {{float(w % 7) / 7.0f, float(w % 5) / 5.0f}};
  m.uvs[0][5] = {{INFINITY, 0.0f}};
  m.uvs[1].resize(nw / 2);  // wrong length: ignored
  m.colors.assign(1, std::vector<Vec4f>(nw, Vec4f{{0.2f, 0.4f, 0.6f, 1.0f}}));
  m.colors[0][7] = {{NAN, INFINITY, -INFINITY, 1.0f}};
  m.color_components = {4};
  m.skin.assign(m.vertex_count(), SkinInfluences{});  // all weights zero
  m.priority.assign(m.vertex_count(), 1.0f);
  m.priority[0] = -3.0f;
  m.priority[1] = NAN;
  for (AttributePlacement placement : {AttributePlacement::optimal, AttributePlacement::keep}) {
    for (bool permissive : {false, true}) {
      const SimplifyResult r =
          simplify(m, {.target_ratio = 0.2, .attribute_placement = placement, .permissive = permissive});
      // The wrong-length stream stays wrong (empty), no worse than the input; everything else as usual.
      ValidationReport after = validate(r.mesh);
      EXPECT_LE(after.attribute_size_errors, validate(m).attribute_size_errors);
      after.attribute_size_errors = 0;
      expect_nothing_new(validate(m), after);
      EXPECT_LT(r.triangles_after, r.triangles_before);
      for (const Vec3f& n : r.mesh.normals) EXPECT_FALSE(std::isinf(n[0]) || std::isinf(n[1]) || std::isinf(n[2]));
    }
  }
}

TEST(AttributeCollapse, OptionsAreValidated) {
  SimplifyOptions o;
  o.attribute_weights.uv = -1;
  o.skin_weight_threshold = 2;
  o.priority_lock = 0;
  const auto problems = o.validate();
  EXPECT_EQ(problems.size(), 3u);
  EXPECT_THROW(simplify(testing::make_tetrahedron(), o), std::invalid_argument);
}

TEST(AttributeCollapse, PriorityChannelMustNameAnAttribute) {
  for (const char* ok : {"none", "_LOD_PRIORITY", "_PAINT.x", "_PAINT.a", "COLOR_0.r", "COLOR_12.a"}) {
    EXPECT_TRUE(SimplifyOptions{.priority_channel = ok}.validate().empty()) << ok;
  }
  for (const char* bad : {"", "bogus", "_", "_PAINT.q", "COLOR_0", "COLOR_x.r", "COLOR_0.x", "_A B"}) {
    const auto problems = SimplifyOptions{.priority_channel = bad}.validate();
    ASSERT_EQ(problems.size(), 1u) << bad;
    EXPECT_NE(problems[0].find("priority_channel"), std::string::npos) << problems[0];
  }
}

}  // namespace
}  // namespace lodforge
