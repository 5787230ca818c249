// Post-processing reorders faces, wedges and vertices for the GPU and changes nothing else.
#include "lodforge/batch/post_process.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <numeric>
#include <random>
#include <tuple>
#include <vector>

#include "lodforge/core/validate.hpp"
#include "test_support.hpp"

namespace lodforge::batch {
namespace {

// A corner as what it means, independent of any numbering: position, normal, UV, colour, custom value, skin.
using Corner = std::tuple<std::array<float, 3>, std::array<float, 3>, std::array<float, 2>, std::array<float, 4>, float,
                          std::uint16_t>;
// A polygon as its corners from the smallest one on (same cyclic order), plus its material.
using Polygon = std::pair<std::vector<Corner>, std::uint32_t>;

std::vector<Polygon> polygons(const Mesh& m) {
  std::vector<Polygon> out;
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    std::vector<Corner> corners;
    for (std::uint32_t c = m.face_offsets[f]; c < m.face_offsets[f + 1]; ++c) {
      const std::uint32_t w = m.corner_wedge[c], v = m.wedge_vertex[w];
      corners.emplace_back(m.positions[v].v, m.normals[w].v, m.uvs[0][w].v, m.colors[0][w].v, m.custom[0].values[w],
                           m.skin[v].joints[0]);
    }
    std::rotate(corners.begin(), std::min_element(corners.begin(), corners.end()), corners.end());
    out.emplace_back(std::move(corners), m.face_material[f]);
  }
  std::sort(out.begin(), out.end());
  return out;
}

// A sphere and a quad grid in one mesh, two materials, faces shuffled (the worst order for a vertex cache),
// every wedge stream set to something that identifies its wedge, and UV seams (several wedges per vertex).
Mesh shuffled_test_mesh() {
  Mesh m = testing::make_uv_sphere(24, 32);
  const Mesh grid = testing::make_grid(12, 12, true);
  const auto base = static_cast<std::uint32_t>(m.vertex_count());
  for (const Vec3f& p : grid.positions) m.add_vertex_with_wedge({{p[0] + 3, p[1], p[2]}});
  for (std::size_t f = 0; f < grid.face_count(); ++f) {
    std::vector<std::uint32_t> w;
    for (std::uint32_t c = grid.face_offsets[f]; c < grid.face_offsets[f + 1]; ++c)
      w.push_back(base + grid.corner_wedge[c]);
    m.add_face(w.data(), w.size(), 1);
  }
  m.materials.resize(2);
  // Seams: the first 50 faces get their own wedges for their first corner.
  for (std::size_t f = 0; f < 50; ++f) {
    const std::uint32_t c = m.face_offsets[f];
    m.wedge_vertex.push_back(m.wedge_vertex[m.corner_wedge[c]]);
    m.corner_wedge[c] = static_cast<std::uint32_t>(m.wedge_vertex.size() - 1);
  }
  const std::size_t nw = m.wedge_count();
  m.normals.resize(nw);
  m.uvs.assign(1, std::vector<Vec2f>(nw));
  m.colors.assign(1, std::vector<Vec4f>(nw));
  m.color_components = {4};
  m.custom.push_back(CustomAttribute{.name = "_ID", .components = 1, .format = {}, .values = std::vector<float>(nw)});
  for (std::size_t w = 0; w < nw; ++w) {
    const float x = static_cast<float>(w);
    m.normals[w] = {{0, 0, 1}};
    m.uvs[0][w] = {{x, -x}};
    m.colors[0][w] = {{x, 0, 0, 1}};
    m.custom[0].values[w] = x;
  }
  m.skin.resize(m.vertex_count());
  for (std::size_t v = 0; v < m.vertex_count(); ++v) {
    m.skin[v].joints[0] = static_cast<std::uint16_t>(v % 7);
    m.skin[v].weights[0] = 1;
  }

  std::vector<std::uint32_t> order(m.face_count());
  std::iota(order.begin(), order.end(), 0u);
  std::shuffle(order.begin(), order.end(), std::mt19937(42));
  Mesh s = m;
  s.face_offsets.assign(1, 0);
  s.corner_wedge.clear();
  s.face_material.clear();
  for (const std::uint32_t f : order) {
    s.corner_wedge.insert(s.corner_wedge.end(), m.corner_wedge.begin() + m.face_offsets[f],
                          m.corner_wedge.begin() + m.face_offsets[f + 1]);
    s.face_offsets.push_back(static_cast<std::uint32_t>(s.corner_wedge.size()));
    s.face_material.push_back(m.face_material[f]);
  }
  return s;
}

TEST(PostProcess, KeepsTheSamePolygonsAndAttributes) {
  const Mesh in = shuffled_test_mesh();
  const Mesh out = optimize_for_gpu(in);
  EXPECT_TRUE(validate(out).ok());
  EXPECT_EQ(out.face_count(), in.face_count());
  EXPECT_EQ(out.wedge_count(), in.wedge_count());
  EXPECT_EQ(out.vertex_count(), in.vertex_count());
  EXPECT_EQ(count_face_kinds(out).quads, count_face_kinds(in).quads) << "quads stay quads";
  EXPECT_TRUE(polygons(out) == polygons(in));
  EXPECT_NE(out.corner_wedge, in.corner_wedge) << "something was reordered";
}

TEST(PostProcess, ImprovesVertexCacheEfficiency) {
  const Mesh in = shuffled_test_mesh();
  const Mesh out = optimize_for_gpu(in);
  const double before = average_cache_miss_ratio(in), after = average_cache_miss_ratio(out);
  EXPECT_LT(after, 0.8 * before) << before << " -> " << after;
  EXPECT_LT(after, 1.0);
}

TEST(PostProcess, GroupsFacesByMaterialAndOrdersWedgesByFirstUse) {
  const Mesh out = optimize_for_gpu(shuffled_test_mesh());
  EXPECT_TRUE(std::is_sorted(out.face_material.begin(), out.face_material.end()));
  std::uint32_t next = 0;
  for (const std::uint32_t w : out.corner_wedge) {
    ASSERT_LE(w, next) << "wedges are numbered in order of first use";
    if (w == next) ++next;
  }
  std::uint32_t next_vertex = 0;
  for (const std::uint32_t v : out.wedge_vertex) {
    ASSERT_LE(v, next_vertex);
    if (v == next_vertex) ++next_vertex;
  }
}

TEST(PostProcess, IsDeterministicAndIdempotentInShape) {
  const Mesh in = shuffled_test_mesh();
  EXPECT_EQ(optimize_for_gpu(in), optimize_for_gpu(in));
  const Mesh twice = optimize_for_gpu(optimize_for_gpu(in));
  EXPECT_TRUE(polygons(twice) == polygons(in));
}

TEST(PostProcess, KeepsUnusedWedgesAndVerticesAtTheEnd) {
  Mesh m = testing::make_tetrahedron();
  m.add_vertex_with_wedge({{5, 5, 5}});  // referenced by no face
  const Mesh out = optimize_for_gpu(m);
  EXPECT_EQ(out.vertex_count(), 5u);
  EXPECT_EQ(out.positions.back(), (Vec3f{{5, 5, 5}}));
  EXPECT_EQ(optimize_for_gpu(Mesh{}), Mesh{});
}

}  // namespace
}  // namespace lodforge::batch
