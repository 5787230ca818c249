#include "lodforge/core/validate.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "lodforge/core/topology.hpp"
#include "lodforge/core/weld.hpp"
#include "test_support.hpp"

namespace lodforge {
namespace {

using testing::make_cube_quads;
using testing::make_grid;
using testing::make_tetrahedron;

// A cube with one UV chart per side: 24 render vertices (4 per face), welded to 8 positions.
Mesh make_cube_with_uv_seams() {
  const Mesh base = make_cube_quads();
  Mesh m;
  m.uvs.resize(1);
  const Vec2f corners[4] = {{{0, 0}}, {{1, 0}}, {{1, 1}}, {{0, 1}}};
  for (std::size_t f = 0; f < base.face_count(); ++f) {
    std::uint32_t w[4];
    for (std::uint32_t i = 0; i < 4; ++i) {
      w[i] = m.add_vertex_with_wedge(base.positions[base.corner_vertex(base.face_offsets[f] + i)]);
      m.uvs[0].push_back(corners[i]);
    }
    m.add_face(w, 4);
  }
  m.materials.push_back({});
  return m;
}

TEST(Validate, TetrahedronIsCleanClosedWithEulerTwo) {
  const Mesh m = make_tetrahedron();
  const ValidationReport r = validate(m);
  EXPECT_TRUE(r.ok()) << (r.messages.empty() ? "" : r.messages[0]);
  const TopologySummary s = summarize_topology(m, build_topology(m));
  EXPECT_EQ(s.edges, 6u);
  EXPECT_EQ(s.faces, 4u);
  EXPECT_EQ(s.euler_characteristic, 2);
  EXPECT_EQ(s.boundary_edges, 0u);
  EXPECT_EQ(s.boundary_loops, 0u);
  EXPECT_EQ(s.components, 1u);
  EXPECT_TRUE(s.closed_manifold());
}

TEST(Validate, CubeWithUvSeamsWeldsToEightVerticesAndTwentyFourWedges) {
  Mesh m = make_cube_with_uv_seams();
  EXPECT_EQ(m.vertex_count(), 24u);
  EXPECT_EQ(weld_by_position(m), 16u);
  EXPECT_EQ(m.vertex_count(), 8u);
  EXPECT_EQ(m.wedge_count(), 24u);
  const ValidationReport r = validate(m);
  EXPECT_TRUE(r.ok());
  const TopologySummary s = summarize_topology(m, build_topology(m));
  EXPECT_EQ(s.edges, 12u);
  EXPECT_EQ(s.faces, 6u);
  EXPECT_EQ(s.euler_characteristic, 2);
  EXPECT_TRUE(s.closed_manifold());
  EXPECT_EQ(count_face_kinds(m).quads, 6u);
}

TEST(Validate, BowtieHasOneNonManifoldVertex) {
  Mesh m;
  for (auto p : {Vec3f{{0, 0, 0}}, Vec3f{{1, 1, 0}}, Vec3f{{-1, 1, 0}}, Vec3f{{1, -1, 0}}, Vec3f{{-1, -1, 0}}}) {
    m.add_vertex_with_wedge(p);
  }
  m.add_face({0, 1, 2});
  m.add_face({0, 4, 3});
  m.materials.push_back({});
  const ValidationReport r = validate(m);
  EXPECT_EQ(r.non_manifold_vertices, 1u);
  EXPECT_EQ(r.non_manifold_edges, 0u);
  EXPECT_FALSE(r.ok());
  const TopologySummary s = summarize_topology(m, build_topology(m));
  EXPECT_EQ(s.boundary_edges, 6u);
  EXPECT_EQ(s.components, 1u);  // joined through the shared vertex
}

TEST(Validate, EdgeSharedByThreeFacesIsNonManifold) {
  Mesh m;
  for (auto p : {Vec3f{{0, 0, 0}}, Vec3f{{1, 0, 0}}, Vec3f{{0, 1, 0}}, Vec3f{{0, -1, 0}}, Vec3f{{0, 0, 1}}}) {
    m.add_vertex_with_wedge(p);
  }
  m.add_face({0, 1, 2});
  m.add_face({1, 0, 3});
  m.add_face({0, 1, 4});
  m.materials.push_back({});
  const ValidationReport r = validate(m);
  EXPECT_EQ(r.non_manifold_edges, 1u);
}

TEST(Validate, OpenQuadGridHasOneBoundaryLoop) {
  const Mesh m = make_grid(4, 3, /*quads=*/true);
  const ValidationReport r = validate(m);
  EXPECT_TRUE(r.ok());
  const TopologySummary s = summarize_topology(m, build_topology(m));
  EXPECT_EQ(s.faces, 12u);
  EXPECT_EQ(s.edges, 4u * 4 + 5u * 3);  // horizontal + vertical
  EXPECT_EQ(s.boundary_edges, 2u * (4 + 3));
  EXPECT_EQ(s.boundary_loops, 1u);
  EXPECT_EQ(s.euler_characteristic, 1);
  EXPECT_EQ(count_face_kinds(m).quads, 12u);
}

TEST(Validate, FlippedFaceIsInconsistentOrientation) {
  Mesh m = make_tetrahedron();
  std::swap(m.corner_wedge[0], m.corner_wedge[1]);  // reverse face 0
  const ValidationReport r = validate(m);
  EXPECT_EQ(r.inconsistent_orientation, 3u);
}

TEST(Validate, CountsNanDegenerateDuplicateAndRangeErrors) {
  Mesh m = make_tetrahedron();
  m.positions[3][1] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(validate(m).nonfinite_positions, 1u);

  m = make_tetrahedron();
  m.add_face({0, 2, 1});  // duplicate of face 0
  m.add_face({1, 1, 2});  // repeated vertex
  const ValidationReport dup = validate(m);
  EXPECT_EQ(dup.duplicate_faces, 1u);
  EXPECT_EQ(dup.degenerate_faces, 1u);

  m = make_tetrahedron();
  m.corner_wedge[5] = 99;
  EXPECT_EQ(validate(m).out_of_range_indices, 1u);

  m = make_tetrahedron();
  m.normals.resize(2);
  EXPECT_EQ(validate(m).attribute_size_errors, 1u);
}

TEST(Validate, ZeroAreaTriangleIsDegenerate) {
  Mesh m;
  m.add_vertex_with_wedge({{0, 0, 0}});
  m.add_vertex_with_wedge({{1, 0, 0}});
  m.add_vertex_with_wedge({{2, 0, 0}});
  m.add_face({0, 1, 2});
  m.materials.push_back({});
  EXPECT_EQ(validate(m).degenerate_faces, 1u);
}

TEST(Weld, KeepsVerticesWithDifferentSkinApart) {
  Mesh m;
  m.add_vertex_with_wedge({{0, 0, 0}});
  m.add_vertex_with_wedge({{0, 0, 0}});
  m.skin.resize(2);
  m.skin[0].weights[0] = 1;
  m.skin[1].joints[0] = 1;
  m.skin[1].weights[0] = 1;
  EXPECT_EQ(weld_by_position(m), 0u);
  m.skin[1] = m.skin[0];
  EXPECT_EQ(weld_by_position(m), 1u);
  EXPECT_EQ(m.wedge_vertex[1], 0u);
}

TEST(Weld, RemoveUnreferencedCompactsInOrder) {
  Mesh m = make_tetrahedron();
  m.add_vertex_with_wedge({{5, 5, 5}});
  m.corner_wedge.clear();
  m.face_offsets = {0};
  m.face_material.clear();
  m.add_face({1, 4, 3});
  const auto [rv, rw] = remove_unreferenced(m);
  EXPECT_EQ(rv, 2u);
  EXPECT_EQ(rw, 2u);
  ASSERT_EQ(m.vertex_count(), 3u);
  EXPECT_EQ(m.positions[2], (Vec3f{{5, 5, 5}}));
  EXPECT_EQ(m.corner_wedge, (std::vector<std::uint32_t>{0, 2, 1}));
  EXPECT_TRUE(validate(m).ok());
}

TEST(Mesh, TriangulatedFansPolygonsAndKeepsMaterials) {
  Mesh m = make_cube_quads();
  m.face_material[2] = 0;
  std::vector<std::uint32_t> src;
  const Mesh t = triangulated(m, &src);
  EXPECT_EQ(t.face_count(), 12u);
  EXPECT_EQ(t.triangle_count(), 12u);
  EXPECT_EQ(src[5], 2u);
  EXPECT_TRUE(validate(t).ok());
  EXPECT_EQ(summarize_topology(t, build_topology(t)).euler_characteristic, 2);
}

TEST(Mesh, UvSphereIsClosedAndOutward) {
  const Mesh m = testing::make_uv_sphere(8, 12);
  EXPECT_TRUE(validate(m).ok());
  double volume6 = 0;  // signed volume × 6; positive when faces point outward
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    const Vec3d a = to_double(m.positions[m.corner_vertex(3 * f)]);
    const Vec3d b = to_double(m.positions[m.corner_vertex(3 * f + 1)]);
    const Vec3d c = to_double(m.positions[m.corner_vertex(3 * f + 2)]);
    volume6 += dot(a, cross(b, c));
  }
  EXPECT_GT(volume6, 0.0);
  EXPECT_EQ(summarize_topology(m, build_topology(m)).euler_characteristic, 2);
}

TEST(Topology, IrregularVerticesAreWhereTheMeshIsNotAManifold) {
  const Mesh clean = testing::make_grid(3, 3, false);
  const std::vector<std::uint8_t> none = irregular_vertices(clean, build_topology(clean));
  EXPECT_EQ(std::count(none.begin(), none.end(), 1), 0);

  Mesh m;  // a bowtie at vertex 0, and a fin: edge 5-6 with three faces
  for (int i = 0; i < 10; ++i) m.add_vertex_with_wedge({{float(i), float(i * i % 5), 0.0f}});
  m.add_face({0, 1, 2});
  m.add_face({0, 3, 4});
  m.add_face({5, 6, 7});
  m.add_face({6, 5, 8});
  m.add_face({5, 6, 9});
  const std::vector<std::uint8_t> flags = irregular_vertices(m, build_topology(m));
  const std::vector<std::uint8_t> expected = {1, 0, 0, 0, 0, 1, 1, 0, 0, 0};
  EXPECT_EQ(flags, expected);
  const TopologySummary s = summarize_topology(m, build_topology(m));
  EXPECT_EQ(s.non_manifold_edges, 1u);

  Mesh flipped;  // two faces crossing their shared edge in the same direction
  for (int i = 0; i < 4; ++i) flipped.add_vertex_with_wedge({{float(i % 2), float(i / 2), 0.0f}});
  flipped.add_face({0, 1, 2});
  flipped.add_face({0, 1, 3});
  const std::vector<std::uint8_t> inconsistent = irregular_vertices(flipped, build_topology(flipped));
  EXPECT_EQ(inconsistent, (std::vector<std::uint8_t>{1, 1, 0, 0}));
}

}  // namespace
}  // namespace lodforge
