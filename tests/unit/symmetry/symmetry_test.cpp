#include "lodforge/symmetry/symmetry.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <random>
#include <set>

#include "symmetry_meshes.hpp"

namespace lodforge::symmetry {
namespace {

using testing::make_blob;

// Every map is an involution, and an edge's mirror joins the mirrors of its ends.
void expect_consistent(const Mesh& mesh, const Topology& topo, const SymmetryMap& s) {
  ASSERT_EQ(s.edge_mirror.size(), topo.edge_count());
  ASSERT_EQ(s.vertex_mirror.size(), mesh.vertex_count());
  ASSERT_EQ(s.face_mirror.size(), mesh.face_count());
  for (std::uint32_t v = 0; v < s.vertex_mirror.size(); ++v) {
    if (s.vertex_mirror[v] != kInvalidIndex) {
      EXPECT_EQ(s.vertex_mirror[s.vertex_mirror[v]], v);
    }
  }
  for (std::uint32_t f = 0; f < s.face_mirror.size(); ++f) {
    if (s.face_mirror[f] != kInvalidIndex) {
      EXPECT_EQ(s.face_mirror[s.face_mirror[f]], f);
    }
  }
  for (std::uint32_t e = 0; e < topo.edge_count(); ++e) {
    const std::uint32_t m = s.edge_mirror[e];
    if (m == kInvalidIndex) continue;
    EXPECT_EQ(s.edge_mirror[m], e);
    const std::set<std::uint32_t> ends = {s.vertex_mirror[topo.edges[e][0]], s.vertex_mirror[topo.edges[e][1]]};
    EXPECT_EQ(ends, (std::set<std::uint32_t>{topo.edges[m][0], topo.edges[m][1]}));
  }
}

void expect_plane(const Plane& got, const Vec3d& normal, double offset, double tol) {
  const double sign = dot(got.normal, normal) < 0 ? -1.0 : 1.0;
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(sign * got.normal[i], normal[i], tol);
  EXPECT_NEAR(sign * got.offset, offset, tol);
}

TEST(Symmetry, PlaneModeNamesRoundTrip) {
  for (PlaneMode m : {PlaneMode::automatic, PlaneMode::x, PlaneMode::y, PlaneMode::z, PlaneMode::none}) {
    EXPECT_EQ(parse_plane_mode(plane_mode_name(m)), m);
  }
  EXPECT_FALSE(parse_plane_mode("X").has_value());
  EXPECT_FALSE(parse_plane_mode("").has_value());
}

TEST(Symmetry, MirroredMeshIsFoundWhole) {
  const Mesh mesh = make_blob(16, 32, true);
  const Topology topo = build_topology(mesh);
  const SymmetryMap s = detect_symmetry(mesh, topo);
  expect_consistent(mesh, topo, s);
  EXPECT_EQ(s.symmetric_edges, topo.edge_count());
  EXPECT_DOUBLE_EQ(s.symmetric_fraction(), 1.0);
  expect_plane(s.plane, {{1, 0, 0}}, 0.0, 1e-6);
  // Vertices on the plane are their own mirror; the others are not.
  for (std::uint32_t v = 0; v < mesh.vertex_count(); ++v) {
    EXPECT_EQ(s.vertex_mirror[v] == v, mesh.positions[v][0] == 0.0f) << v;
  }
}

TEST(Symmetry, ShuffledAndMovedMirrorIsFoundWhole) {
  const testing::Rigid g = testing::skew_rigid();
  const Mesh mesh = testing::transformed(testing::shuffled(make_blob(16, 32, true), 7), g);
  const Topology topo = build_topology(mesh);
  const SymmetryMap s = detect_symmetry(mesh, topo);
  expect_consistent(mesh, topo, s);
  EXPECT_EQ(s.symmetric_edges, topo.edge_count());
  const Vec3d n = testing::Rigid{{{g.r[0][0], g.r[0][1], g.r[0][2]}, {g.r[1][0], g.r[1][1], g.r[1][2]},
                                  {g.r[2][0], g.r[2][1], g.r[2][2]}},
                                 {}}
                      .apply({{1, 0, 0}});
  // Positions are floats: the plane is as exact as they are (a few 1e-7 of the size here).
  expect_plane(s.plane, n, -dot(n, g.t), 1e-6);
}

TEST(Symmetry, AxisModesFixTheNormal) {
  const Mesh mesh = testing::translated_x(make_blob(12, 24, true), 0.25f);
  const SymmetryMap x = detect_symmetry(mesh, {.plane = PlaneMode::x});
  EXPECT_DOUBLE_EQ(x.symmetric_fraction(), 1.0);
  expect_plane(x.plane, {{1, 0, 0}}, -0.25, 1e-6);
  // The blob has no mirror plane across y or z.
  EXPECT_LT(detect_symmetry(mesh, {.plane = PlaneMode::y}).symmetric_fraction(), 0.05);
  EXPECT_LT(detect_symmetry(mesh, {.plane = PlaneMode::z}).symmetric_fraction(), 0.05);
  const SymmetryMap none = detect_symmetry(mesh, {.plane = PlaneMode::none});
  EXPECT_FALSE(none.found());
  EXPECT_EQ(none.edges, build_topology(mesh).edge_count());
}

TEST(Symmetry, EditedSideIsExcludedAndTheRestFound) {
  const Mesh clean = make_blob(16, 32, true);
  const SymmetryMap before = detect_symmetry(clean);
  ASSERT_DOUBLE_EQ(before.symmetric_fraction(), 1.0);
  // Push a patch on the +x side outwards by 5% of the radius (several times the tolerance).
  Mesh mesh = clean;
  const Vec3d centre{{0.7, 0.4, 0.5}};
  std::set<std::uint32_t> edited;
  for (std::uint32_t v = 0; v < mesh.vertex_count(); ++v) {
    const Vec3d p = to_double(mesh.positions[v]);
    if (p[0] > 0.2 && length(p * (1.0 / length(p)) - centre * (1.0 / length(centre))) < 0.35) {
      mesh.positions[v] = to_float(p * 1.05);
      edited.insert(v);
    }
  }
  ASSERT_GT(edited.size(), 10u);
  std::set<std::uint32_t> affected = edited;  // the edited vertices and the ones they used to mirror
  for (std::uint32_t v : edited) affected.insert(before.vertex_mirror[v]);
  std::set<std::uint32_t> near = affected;  // and every vertex sharing a face with them
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    bool touches = false;
    for (std::uint32_t c = mesh.face_offsets[f]; c < mesh.face_offsets[f + 1]; ++c) {
      touches = touches || affected.count(mesh.corner_vertex(c)) > 0;
    }
    if (!touches) continue;
    for (std::uint32_t c = mesh.face_offsets[f]; c < mesh.face_offsets[f + 1]; ++c) near.insert(mesh.corner_vertex(c));
  }

  const Topology topo = build_topology(mesh);
  const SymmetryMap s = detect_symmetry(mesh, topo);
  expect_consistent(mesh, topo, s);
  expect_plane(s.plane, {{1, 0, 0}}, 0.0, 1e-6);
  for (std::uint32_t v : affected) EXPECT_EQ(s.vertex_mirror[v], kInvalidIndex) << v;
  std::size_t away = 0;
  for (std::uint32_t e = 0; e < topo.edge_count(); ++e) {
    const auto [a, b] = topo.edges[e];
    if (affected.count(a) || affected.count(b)) {
      EXPECT_EQ(s.edge_mirror[e], kInvalidIndex) << "edited edge " << a << "-" << b;
    } else if (!near.count(a) || !near.count(b)) {
      EXPECT_NE(s.edge_mirror[e], kInvalidIndex) << "untouched edge " << a << "-" << b;
      ++away;
    }
  }
  EXPECT_GT(away, topo.edge_count() / 2);
  EXPECT_LT(s.symmetric_fraction(), 1.0);
  EXPECT_GT(s.symmetric_fraction(), 0.8);
}

// Real assets are never mirrors bit for bit: noise of 1e-6 of the diagonal changes nothing.
TEST(Symmetry, NoiseOfAMillionthIsStillSymmetric) {
  Mesh mesh = testing::shuffled(make_blob(16, 32, true), 9);
  const double diagonal = compute_bounds(mesh).diagonal();
  std::mt19937 rng(77);
  std::uniform_real_distribution<double> noise(-1.0, 1.0);
  for (Vec3f& p : mesh.positions) {
    for (int i = 0; i < 3; ++i) p[i] = static_cast<float>(p[i] + 1e-6 * diagonal * noise(rng) / std::sqrt(3.0));
  }
  const SymmetryMap s = detect_symmetry(mesh);
  EXPECT_DOUBLE_EQ(s.symmetric_fraction(), 1.0);
  expect_plane(s.plane, {{1, 0, 0}}, 0.0, 1e-5 * diagonal);
}

// A topological edit (quads split into triangles on one side) leaves those faces and their counterparts
// unmatched and keeps the rest.
TEST(Symmetry, SplitFacesOnOneSideAreExcluded) {
  const Mesh clean = make_blob(16, 32, true);
  Mesh mesh;
  mesh.positions = clean.positions;
  mesh.wedge_vertex = clean.wedge_vertex;
  std::set<std::uint32_t> split_vertices;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> diagonals;
  std::size_t split = 0;
  for (std::size_t f = 0; f < clean.face_count(); ++f) {
    const std::uint32_t* c = &clean.corner_wedge[clean.face_offsets[f]];
    Vec3d centre{};
    for (std::uint32_t i = 0; i < clean.face_size(f); ++i) centre = centre + to_double(clean.positions[c[i]]);
    centre = centre * (1.0 / clean.face_size(f));
    if (clean.face_size(f) == 4 && centre[0] > 0.3 && centre[2] > 0.2 && centre[2] < 0.6) {
      mesh.add_face({c[0], c[1], c[2]});
      mesh.add_face({c[0], c[2], c[3]});
      diagonals.emplace_back(c[0], c[2]);
      for (int i = 0; i < 4; ++i) split_vertices.insert(c[i]);
      ++split;
    } else {
      mesh.add_face(c, clean.face_size(f));
    }
  }
  ASSERT_GT(split, 5u);
  const Topology topo = build_topology(mesh);
  const SymmetryMap s = detect_symmetry(mesh, topo);
  expect_consistent(mesh, topo, s);
  expect_plane(s.plane, {{1, 0, 0}}, 0.0, 1e-6);
  // The new diagonals have no counterpart on the other side.
  for (const auto& [a, b] : diagonals) {
    const auto it = std::find(topo.edges.begin(), topo.edges.end(), std::array{std::min(a, b), std::max(a, b)});
    ASSERT_NE(it, topo.edges.end());
    EXPECT_EQ(s.edge_mirror[static_cast<std::size_t>(it - topo.edges.begin())], kInvalidIndex);
  }
  // Every face away from the split region (no vertex in it or its mirror image) is matched.
  const SymmetryMap before = detect_symmetry(clean);
  std::set<std::uint32_t> touched = split_vertices;
  for (std::uint32_t v : split_vertices) touched.insert(before.vertex_mirror[v]);
  for (std::uint32_t f = 0; f < mesh.face_count(); ++f) {
    bool away = true;
    for (std::uint32_t c = mesh.face_offsets[f]; c < mesh.face_offsets[f + 1]; ++c) {
      away = away && !touched.count(mesh.corner_vertex(c));
    }
    if (away) {
      EXPECT_NE(s.face_mirror[f], kInvalidIndex) << f;
    }
  }
  EXPECT_LT(s.symmetric_fraction(), 1.0);
  EXPECT_GT(s.symmetric_fraction(), 0.8);
}

TEST(Symmetry, SeparateMirroredPartsAreFound) {
  const Mesh part = make_blob(10, 20, false);
  const Mesh mesh = testing::shuffled(testing::mirrored_pair(part, 2.5), 11);
  const Topology topo = build_topology(mesh);
  const SymmetryMap s = detect_symmetry(mesh, topo);
  expect_consistent(mesh, topo, s);
  EXPECT_DOUBLE_EQ(s.symmetric_fraction(), 1.0);
  expect_plane(s.plane, {{1, 0, 0}}, 0.0, 1e-6);
  for (std::uint32_t v = 0; v < mesh.vertex_count(); ++v) {
    ASSERT_NE(s.vertex_mirror[v], kInvalidIndex);
    // Each vertex's mirror lies in the other part.
    EXPECT_LT(mesh.positions[v][0] * mesh.positions[s.vertex_mirror[v]][0], 0.0f);
  }
}

TEST(Symmetry, AsymmetricMeshHasNone) {
  for (double jitter : {0.0, 0.03}) {
    const Mesh mesh = make_blob(16, 32, false, jitter);
    const Topology topo = build_topology(mesh);
    const SymmetryMap s = detect_symmetry(mesh, topo);
    expect_consistent(mesh, topo, s);
    EXPECT_EQ(s.symmetric_edges, 0u) << "jitter " << jitter;
    EXPECT_FALSE(s.found());
  }
}

TEST(Symmetry, IsDeterministic) {
  const Mesh mesh = testing::shuffled(make_blob(16, 32, true), 3);
  const SymmetryMap a = detect_symmetry(mesh), b = detect_symmetry(mesh);
  EXPECT_EQ(a.edge_mirror, b.edge_mirror);
  EXPECT_EQ(a.vertex_mirror, b.vertex_mirror);
  EXPECT_EQ(a.face_mirror, b.face_mirror);
  EXPECT_EQ(a.plane.normal, b.plane.normal);
  EXPECT_EQ(a.plane.offset, b.plane.offset);
  // One thread gives the same maps as many.
  {
    const tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    const SymmetryMap d = detect_symmetry(mesh);
    EXPECT_EQ(d.edge_mirror, a.edge_mirror);
    EXPECT_EQ(d.plane.normal, a.plane.normal);
    EXPECT_EQ(d.plane.offset, a.plane.offset);
  }
  // Another numbering of the same mesh finds the same symmetry.
  const SymmetryMap c = detect_symmetry(testing::shuffled(mesh, 5));
  EXPECT_EQ(c.symmetric_edges, a.symmetric_edges);
}

TEST(Symmetry, EmptyAndBrokenMeshesFindNothing) {
  EXPECT_FALSE(detect_symmetry(Mesh{}).found());
  Mesh broken = make_blob(6, 8, true);
  broken.corner_wedge[0] = 9999;  // out of range
  const SymmetryMap s = detect_symmetry(broken);
  EXPECT_FALSE(s.found());
  EXPECT_EQ(s.vertex_mirror.size(), broken.vertex_count());
}

}  // namespace
}  // namespace lodforge::symmetry
