// How polygons become triangles: one rule (Mesh::triangulated, triangle_vertex_indices, the glTF writer and
// the evaluator all follow for_each_face_triangle).
#include "lodforge/core/mesh.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <vector>

namespace lodforge {
namespace {

// One face over fresh vertices at `corners`, in that order.
Mesh single_face(const std::vector<Vec3f>& corners) {
  Mesh m;
  std::vector<std::uint32_t> w;
  for (const Vec3f& p : corners) w.push_back(m.add_vertex_with_wedge(p));
  m.add_face(w.data(), w.size());
  return m;
}

std::vector<std::array<std::uint32_t, 3>> triangles_of(const Mesh& m) {
  const std::vector<std::uint32_t> idx = triangle_vertex_indices(m);
  std::vector<std::array<std::uint32_t, 3>> out;
  for (std::size_t i = 0; i + 2 < idx.size(); i += 3) out.push_back({idx[i], idx[i + 1], idx[i + 2]});
  return out;
}

using Tris = std::vector<std::array<std::uint32_t, 3>>;

TEST(Triangulation, QuadSplitsAlongItsShorterDiagonal) {
  // A rhombus long along x: corners 1 and 3 are the close pair, so the split is 1-3.
  const Mesh rhombus = single_face({{{-2, 0, 0}}, {{0, -1, 0}}, {{2, 0, 0}}, {{0, 1, 0}}});
  EXPECT_EQ(triangulation_start(rhombus, 0), 1u);
  EXPECT_EQ(triangles_of(rhombus), (Tris{{1, 2, 3}, {1, 3, 0}}));
  // The same rhombus listed from another corner: the same diagonal, so the same fold.
  const Mesh rotated = single_face({{{0, -1, 0}}, {{2, 0, 0}}, {{0, 1, 0}}, {{-2, 0, 0}}});
  EXPECT_EQ(triangulation_start(rotated, 0), 0u);
  EXPECT_EQ(triangles_of(rotated), (Tris{{0, 1, 2}, {0, 2, 3}}));
}

TEST(Triangulation, SquareTiesAndPolygonsFanFromTheFirstCorner) {
  const Mesh square = single_face({{{0, 0, 0}}, {{1, 0, 0}}, {{1, 1, 0}}, {{0, 1, 0}}});
  EXPECT_EQ(triangles_of(square), (Tris{{0, 1, 2}, {0, 2, 3}}));
  // A pentagon whose 1-3 chord is short still fans from corner 0: only quads choose.
  const Mesh pentagon = single_face({{{-2, 0, 0}}, {{0, -1, 0}}, {{2, 0, 0}}, {{0, 1, 0}}, {{-1, 1, 0}}});
  EXPECT_EQ(triangulation_start(pentagon, 0), 0u);
  EXPECT_EQ(triangles_of(pentagon), (Tris{{0, 1, 2}, {0, 2, 3}, {0, 3, 4}}));
  const Mesh triangle = single_face({{{0, 0, 0}}, {{1, 0, 0}}, {{0, 1, 0}}});
  EXPECT_EQ(triangles_of(triangle), (Tris{{0, 1, 2}}));
}

TEST(Triangulation, NonFinitePositionsKeepTheFirstCorner) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const Mesh m = single_face({{{nan, 0, 0}}, {{0, -1, 0}}, {{2, 0, 0}}, {{0, 1, 0}}});
  EXPECT_EQ(triangulation_start(m, 0), 0u);
}

TEST(Triangulation, TriangulatedMeshUsesTheSameTrianglesAndKeepsWinding) {
  // A bent quad (a fold along 1-3) next to a flat one; both keep the +z winding of their corners.
  Mesh m;
  const Vec3f p[6] = {{{-2, 0, 0}}, {{0, -1, 0}}, {{2, 0, 1}}, {{0, 1, 0}}, {{4, -1, 0}}, {{4, 1, 0}}};
  std::uint32_t w[6];
  for (int i = 0; i < 6; ++i) w[i] = m.add_vertex_with_wedge(p[i]);
  m.add_face({w[0], w[1], w[2], w[3]});
  m.add_face({w[1], w[4], w[5], w[2]});
  std::vector<std::uint32_t> source;
  const Mesh t = triangulated(m, &source);
  ASSERT_EQ(t.face_count(), 4u);
  EXPECT_EQ(source, (std::vector<std::uint32_t>{0, 0, 1, 1}));
  const std::vector<std::uint32_t> idx = triangle_vertex_indices(m);
  ASSERT_EQ(idx.size(), 12u);
  for (std::size_t f = 0; f < t.face_count(); ++f) {
    for (int k = 0; k < 3; ++k) EXPECT_EQ(t.corner_vertex(t.face_offsets[f] + k), idx[3 * f + k]);
    const Vec3d a = to_double(t.positions[idx[3 * f]]), b = to_double(t.positions[idx[3 * f + 1]]),
                c = to_double(t.positions[idx[3 * f + 2]]);
    EXPECT_GT(cross(b - a, c - a)[2], 0.0) << "triangle " << f;
  }
  EXPECT_EQ(t.triangle_count(), m.triangle_count());
}

// Faces repeating an earlier one: same corner cycle (from any corner), same winding, same material.
TEST(RepeatedFaces, ListsLaterCopiesOfTheSameFaceOnly) {
  Mesh m;
  m.materials.resize(2);
  std::uint32_t w[6];
  for (int i = 0; i < 6; ++i) w[i] = m.add_vertex_with_wedge({{static_cast<float>(i % 3), static_cast<float>(i / 3), 0}});
  const std::uint32_t extra = static_cast<std::uint32_t>(m.wedge_vertex.size());
  m.wedge_vertex.push_back(1);  // a second wedge of vertex 1 (a seam): repeats compare vertices, not wedges
  m.add_face({w[0], w[1], w[4], w[3]});      // 0
  m.add_face({w[1], w[2], w[5], w[4]});      // 1
  m.add_face({w[4], w[3], w[0], extra});     // 2: face 0 from another corner, through the other wedge
  m.add_face({w[3], w[4], w[1], w[0]});      // 3: face 0 wound the other way (a back face): kept
  m.add_face({w[1], w[2], w[5], w[4]}, 1);   // 4: face 1 in another material: kept
  m.add_face({w[2], w[5], w[4], w[1]});      // 5: face 1 again
  m.add_face({w[0], w[1], w[4], w[3]});      // 6: face 0 a third time
  m.add_face({w[0], w[1], w[1]});            // 7: degenerate
  m.add_face({w[0], w[1], w[1]});            // 8: degenerate, never listed
  m.add_face({w[0], w[1], 99});              // 9: an out-of-range wedge, never read
  m.add_face({w[0], w[1], 99});              // 10
  EXPECT_EQ(repeated_faces(m), (std::vector<std::uint32_t>{2, 5, 6}));

  m.face_group = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10};
  m.groups.resize(11);
  const std::vector<std::uint32_t> drop = repeated_faces(m);
  const Mesh kept = without_faces(m, drop);
  ASSERT_EQ(kept.face_count(), 8u);
  EXPECT_EQ(kept.face_group, (std::vector<std::uint32_t>{0, 1, 3, 4, 7, 8, 9, 10}));
  EXPECT_EQ(kept.face_material, (std::vector<std::uint32_t>{0, 0, 0, 1, 0, 0, 0, 0}));
  EXPECT_EQ(kept.positions, m.positions);
  EXPECT_EQ(kept.wedge_vertex, m.wedge_vertex);
  for (std::size_t f = 0; f < 2; ++f) {
    EXPECT_EQ(kept.face_size(f), 4u);
    for (std::uint32_t c = 0; c < 4; ++c) EXPECT_EQ(kept.corner_wedge[kept.face_offsets[f] + c], m.corner_wedge[m.face_offsets[f] + c]);
  }
  EXPECT_TRUE(repeated_faces(kept).empty());
  EXPECT_EQ(without_faces(m, {}), m);
}

// Enough faces for many partitions and the parallel path: every face's answer against a brute-force one (a map
// from the canonical corner cycle and material to the first face with it), on any thread count.
TEST(RepeatedFaces, ALargeMeshGetsTheBruteForceAnswerOnAnyThreadCount) {
  Mesh m;
  m.materials.resize(3);
  constexpr std::uint32_t kVertices = 3000;
  for (std::uint32_t v = 0; v < kVertices; ++v) m.add_vertex_with_wedge({{static_cast<float>(v), 0, 0}});
  std::mt19937 rng(7);
  std::vector<std::vector<std::uint32_t>> made;
  for (int f = 0; f < 200000; ++f) {
    std::vector<std::uint32_t> face;
    if (!made.empty() && rng() % 8 == 0) {  // a copy of an earlier face, from another corner or wound back
      face = made[rng() % made.size()];
      std::rotate(face.begin(), face.begin() + static_cast<std::ptrdiff_t>(rng() % face.size()), face.end());
      if (rng() % 4 == 0) std::reverse(face.begin(), face.end());
    } else {
      const std::size_t k = 3 + rng() % 3;
      for (std::size_t c = 0; c < k; ++c) face.push_back(rng() % (rng() % 16 == 0 ? 4 : kVertices));
    }
    made.push_back(face);
    m.add_face(face.data(), face.size(), static_cast<std::uint32_t>(rng() % 4 == 0 ? 1 + rng() % 2 : 0));
  }
  std::vector<std::uint32_t> expected;
  std::map<std::pair<std::vector<std::uint32_t>, std::uint32_t>, std::uint32_t> first;
  for (std::uint32_t f = 0; f < m.face_count(); ++f) {
    std::vector<std::uint32_t> cycle(made[f]);
    std::vector<std::uint32_t> sorted(cycle);
    std::sort(sorted.begin(), sorted.end());
    if (std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end()) continue;  // a repeated corner
    std::rotate(cycle.begin(), std::min_element(cycle.begin(), cycle.end()), cycle.end());
    if (!first.try_emplace({cycle, m.face_material[f]}, f).second) expected.push_back(f);
  }
  ASSERT_GT(expected.size(), 10000u);
  EXPECT_EQ(repeated_faces(m, 1), expected);
  EXPECT_EQ(repeated_faces(m, 2), expected);
  EXPECT_EQ(repeated_faces(m), expected);
}

}  // namespace
}  // namespace lodforge
