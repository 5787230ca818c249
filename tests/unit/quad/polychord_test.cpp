// Polychord tracing (docs/quad-lods.md): ends, loops, self-intersection, face -> chord tables.
#include <gtest/gtest.h>

#include <algorithm>
#include <set>

#include "lodforge/core/validate.hpp"
#include "lodforge/quad/polychord.hpp"
#include "lodforge/quad/polychord_collapse.hpp"
#include "lodforge/quad/quad_mesh.hpp"
#include "quad_meshes.hpp"

namespace lodforge::quad {
namespace {

using testing::make_cylinder;
using testing::make_quad_grid;
using testing::make_spiral_strip;
using testing::make_subdivided_cube;

// Every alive quad lies on exactly one chord per direction, and the chord lists it in that direction.
void expect_consistent(const QuadMesh& qm, const PolychordSet& set) {
  for (std::uint32_t f = 0; f < qm.face_slots(); ++f) {
    for (int d = 0; d < 2; ++d) {
      const std::uint32_t id = set.face_chord[f][d];
      if (qm.face_size(f) != 4) {
        EXPECT_EQ(id, kInvalidIndex);
        continue;
      }
      ASSERT_LT(id, set.chords.size()) << "face " << f << " direction " << d;
      const Polychord& c = set.chords[id];
      bool listed = false;
      for (std::size_t k = 0; k < c.faces.size(); ++k) listed |= c.faces[k] == f && c.directions[k] == d;
      EXPECT_TRUE(listed) << "face " << f << " direction " << d;
    }
  }
}

TEST(Polychord, GridChordsRunFromBoundaryToBoundary) {
  const QuadMesh qm(make_quad_grid(4, 3));
  const PolychordSet set = trace_polychords(qm);
  ASSERT_EQ(set.chords.size(), 7u);  // 3 rows + 4 columns
  std::multiset<std::size_t> lengths;
  for (const Polychord& c : set.chords) {
    EXPECT_FALSE(c.closed);
    EXPECT_EQ(c.ends[0], ChordEnd::boundary);
    EXPECT_EQ(c.ends[1], ChordEnd::boundary);
    EXPECT_EQ(c.rungs.size(), c.faces.size() + 1);
    EXPECT_FALSE(c.self_intersecting);
    EXPECT_FALSE(c.self_touching);
    lengths.insert(c.faces.size());
  }
  EXPECT_EQ(lengths, (std::multiset<std::size_t>{3, 3, 3, 3, 4, 4, 4}));
  expect_consistent(qm, set);
  // Each quad is on two different chords.
  for (const auto& ids : set.face_chord) EXPECT_NE(ids[0], ids[1]);
}

TEST(Polychord, CylinderRingsAreClosedLoops) {
  const QuadMesh qm(make_cylinder(8, 3));
  const PolychordSet set = trace_polychords(qm);
  std::size_t loops = 0, open = 0;
  for (const Polychord& c : set.chords) {
    if (c.closed) {
      ++loops;
      EXPECT_EQ(c.faces.size(), 8u);
      EXPECT_EQ(c.rungs.size(), 8u);  // r_K is r_0
      EXPECT_EQ(c.ends[0], ChordEnd::closed);
    } else {
      ++open;
      EXPECT_EQ(c.faces.size(), 3u);
    }
  }
  EXPECT_EQ(loops, 3u);
  EXPECT_EQ(open, 8u);
  expect_consistent(qm, set);
}

TEST(Polychord, SubdividedCubeHas3nLoopsOf4nQuads) {
  for (int n : {1, 2, 3, 4, 8}) {
    const Mesh cube = make_subdivided_cube(n);
    ASSERT_EQ(cube.face_count(), static_cast<std::size_t>(6 * n * n));
    const QuadMesh qm(cube);
    const PolychordSet set = trace_polychords(qm);
    EXPECT_EQ(set.chords.size(), static_cast<std::size_t>(3 * n)) << "n = " << n;
    for (const Polychord& c : set.chords) {
      EXPECT_TRUE(c.closed);
      EXPECT_EQ(c.faces.size(), static_cast<std::size_t>(4 * n));
      EXPECT_FALSE(c.self_intersecting);
    }
    // Every quad in exactly two polychords.
    std::vector<int> count(cube.face_count(), 0);
    for (const Polychord& c : set.chords) {
      std::set<std::uint32_t> faces(c.faces.begin(), c.faces.end());
      for (std::uint32_t f : faces) ++count[f];
    }
    for (int k : count) EXPECT_EQ(k, 2) << "n = " << n;
    expect_consistent(qm, set);
  }
}

// Grid 4 x 3 whose middle row ends in a triangle at both sides (the left and right boundary rungs of row 1
// collapsed), or in a pentagon on the left.
Mesh make_row_ending_in_triangles() {
  Mesh m = make_quad_grid(4, 3);
  Mesh out = m;
  out.face_offsets.assign(1, 0);
  out.corner_wedge.clear();
  out.face_material.clear();
  auto id = [](int i, int j) { return static_cast<std::uint32_t>(j * 5 + i); };
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    std::vector<std::uint32_t> poly;
    for (std::uint32_t c = m.face_offsets[f]; c < m.face_offsets[f + 1]; ++c) {
      std::uint32_t v = m.corner_wedge[c];
      if (v == id(0, 2)) v = id(0, 1);
      if (v == id(4, 2)) v = id(4, 1);
      if (poly.empty() || poly.back() != v) poly.push_back(v);
    }
    if (poly.front() == poly.back()) poly.pop_back();
    out.add_face(poly.data(), poly.size());
  }
  return out;
}

TEST(Polychord, StopsAtTrianglesAndRecordsThem) {
  const Mesh m = make_row_ending_in_triangles();
  ASSERT_EQ(count_face_kinds(m).triangles, 2u);
  const QuadMesh qm(m);
  const PolychordSet set = trace_polychords(qm);
  expect_consistent(qm, set);
  // The chord through quad (1, 1) in its row direction ends in the two triangles (faces 4 and 7).
  const std::uint32_t quad_1_1 = 5;
  const Polychord& row = set.chords[set.face_chord[quad_1_1][1]];
  EXPECT_EQ(row.faces.size(), 2u);
  EXPECT_EQ(row.ends[0], ChordEnd::triangle);
  EXPECT_EQ(row.ends[1], ChordEnd::triangle);
  EXPECT_EQ(std::set<std::uint32_t>(row.end_faces.begin(), row.end_faces.end()), (std::set<std::uint32_t>{4, 7}));
}

TEST(Polychord, StopsAtPolygons) {
  // Two quads side by side, a pentagon glued to the right one.
  Mesh m;
  for (auto [x, y] : {std::pair{0, 0}, {1, 0}, {2, 0}, {0, 1}, {1, 1}, {2, 1}, {3, 0}, {3, 1}, {4, 0}}) {
    testing::add_point(m, x, y, 0);
  }
  m.add_face({0, 1, 4, 3});
  m.add_face({1, 2, 5, 4});
  m.add_face({2, 6, 8, 7, 5});
  const QuadMesh qm(m);
  const Polychord c = trace_polychord(qm, 0, 1);  // sides 1 and 3: the row
  EXPECT_EQ(c.faces.size(), 2u);
  const int at_polygon = c.ends[0] == ChordEnd::polygon ? 0 : 1;
  EXPECT_EQ(c.ends[at_polygon], ChordEnd::polygon);
  EXPECT_EQ(c.ends[1 - at_polygon], ChordEnd::boundary);
  EXPECT_EQ(c.end_faces[at_polygon], 2u);
  EXPECT_FALSE(qm.locked(5));  // n-gon corners may move (Polychord.NgonCornersMove)
}

TEST(Polychord, DetectsSelfIntersectionInSpiral) {
  const int arc = 9;
  const QuadMesh qm(make_spiral_strip(arc));
  const PolychordSet set = trace_polychords(qm);
  const std::uint32_t x = 1;  // the crossing quad
  ASSERT_EQ(set.face_chord[x][0], set.face_chord[x][1]);
  const Polychord& c = set.chords[set.face_chord[x][0]];
  EXPECT_TRUE(c.self_intersecting);
  EXPECT_TRUE(c.self_touching);
  EXPECT_FALSE(c.closed);
  EXPECT_EQ(c.faces.size(), static_cast<std::size_t>(6 + arc));  // A X R arc B X T
  EXPECT_EQ(std::count(c.faces.begin(), c.faces.end(), x), 2);
  expect_consistent(qm, set);
}

TEST(Polychord, SpiralWholeCollapseIsRefusedButRunsAvoidingTheCrossingAreAllowed) {
  const int arc = 9;
  const Mesh spiral = make_spiral_strip(arc);
  QuadMesh qm(spiral);
  const Polychord c = trace_polychord(qm, 1, 0);
  const std::size_t last = c.rungs.size() - 1;
  EXPECT_FALSE(run_allowed(c, 0, last));
  // Rungs of X appear at two places of the chord; find them and check that any run holding two adjacent
  // sides of X is refused.
  std::vector<std::size_t> at_x;
  for (std::size_t k = 0; k < c.faces.size(); ++k) {
    if (c.faces[k] == 1) at_x.push_back(k);
  }
  ASSERT_EQ(at_x.size(), 2u);
  EXPECT_FALSE(run_allowed(c, at_x[0], at_x[1]));
  EXPECT_TRUE(run_allowed(c, at_x[0], at_x[0] + 1));  // through X once: opposite sides only
  // A run avoiding the crossing: the free end of arm A and X's left side. A vanishes (with its far corner),
  // X becomes a triangle between B and T.
  ASSERT_EQ(at_x[0], 1u);
  ASSERT_TRUE(run_allowed(c, 0, 1));
  auto weld_run = [&](std::size_t first, std::size_t last) {
    std::vector<std::vector<std::uint32_t>> islands;
    std::vector<Vec3d> positions;
    for (std::size_t k = first; k <= last; ++k) {
      islands.push_back({c.rungs[k][0], c.rungs[k][1]});
      positions.push_back((qm.position(c.rungs[k][0]) + qm.position(c.rungs[k][1])) * 0.5);
    }
    return qm.weld(islands, positions);
  };
  // Inside the one-quad-wide arc every rung joins the two rims: a run there cuts the ribbon in two (the
  // Euler characteristic changes), which the weld refuses.
  const std::size_t arc_rung = at_x[0] + 4;
  ASSERT_TRUE(run_allowed(c, arc_rung, arc_rung + 2));
  EXPECT_EQ(weld_run(arc_rung, arc_rung + 2).failure, WeldFailure::euler);
  // Through X once (both its left and right sides) pinches R off B and T: refused as well.
  EXPECT_EQ(weld_run(0, 2).failure, WeldFailure::non_manifold_vertex);
  const WeldResult w = weld_run(0, 1);
  EXPECT_TRUE(w.ok()) << weld_failure_name(w.failure);
  EXPECT_EQ(w.triangles_removed, 3);
  EXPECT_TRUE(validate(qm.to_mesh(spiral)).ok());
}

}  // namespace
}  // namespace lodforge::quad
