#include "lodforge/eval/distance_bound.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "lodforge/eval/eval.hpp"
#include "test_support.hpp"

namespace lodforge {
namespace {

// One triangle in z = 0 and another lifted by h at one corner: the farthest point of the lifted one is that
// corner, exactly h away.
TEST(DistanceBound, BoundsTheTrueMaximumTightly) {
  Mesh flat;
  for (const Vec3f& p : {Vec3f{{0, 0, 0}}, Vec3f{{4, 0, 0}}, Vec3f{{0, 4, 0}}}) flat.add_vertex_with_wedge(p);
  flat.add_face({0, 1, 2});
  Mesh lifted;
  for (const Vec3f& p : {Vec3f{{1, 1, 0}}, Vec3f{{2, 1, 0}}, Vec3f{{1, 2, 0.5f}}}) lifted.add_vertex_with_wedge(p);
  lifted.add_face({0, 1, 2});
  const SurfaceIndex target(flat);
  const DistanceBound b = distance_bound(lifted, target, {.tolerance = 0.05});
  EXPECT_DOUBLE_EQ(b.lower, 0.5);
  EXPECT_GE(b.upper, 0.5);
  EXPECT_LE(b.upper, 0.5 * 1.05 + 1e-12);
}

// A bump in the middle of a triangle's face, far from every vertex: corner samples see nothing, the bound
// must still cover it. The target is a tent whose apex sits above the flat triangle's interior.
TEST(DistanceBound, FindsAMaximumInsideATriangle) {
  Mesh tent;  // a square pyramid over [0,4]² with apex (2, 2, 1)
  for (const Vec3f& p : {Vec3f{{0, 0, 0}}, Vec3f{{4, 0, 0}}, Vec3f{{4, 4, 0}}, Vec3f{{0, 4, 0}}, Vec3f{{2, 2, 1}}}) {
    tent.add_vertex_with_wedge(p);
  }
  for (std::uint32_t i = 0; i < 4; ++i) tent.add_face({i, (i + 1) % 4, 4});
  Mesh square;  // its base, as two triangles: every corner lies on the tent
  for (const Vec3f& p : {Vec3f{{0, 0, 0}}, Vec3f{{4, 0, 0}}, Vec3f{{4, 4, 0}}, Vec3f{{0, 4, 0}}}) {
    square.add_vertex_with_wedge(p);
  }
  square.add_face({0, 1, 2});
  square.add_face({0, 2, 3});
  const SurfaceIndex target(tent);
  const DistanceBound b = distance_bound(square, target, {.tolerance = 0.02});
  // The base's centre (2, 2, 0) is farthest from the tent: 2/sqrt(5) from each of its faces (slope 1/2).
  const double truth = 2.0 / std::sqrt(5.0);
  EXPECT_GE(b.upper, truth);
  EXPECT_LE(b.upper, truth * 1.02 + 1e-9);
  EXPECT_GT(b.lower, 0.9 * truth);
  EXPECT_GT(b.rounds, 1);
}

TEST(DistanceBound, IsAtLeastTheSampledMaximum) {
  const Mesh sphere = testing::make_uv_sphere(12, 16, 1.0f);
  const Mesh fine = testing::make_uv_sphere(48, 64, 1.0f);
  const EvalResult e = evaluate(fine, sphere);
  const DistanceBound b = distance_bound(sphere, SurfaceIndex(fine), {.tolerance = 0.1});
  EXPECT_GE(b.upper, e.b_to_a.max);
  EXPECT_LE(b.upper, 1.1 * b.lower + 1e-12);
  EXPECT_LE(b.lower, b.upper);
}

// A caller deciding against a value needs no bound tighter than it: nodes bounded at or below it are not
// refined, so the bound costs fewer queries and still holds the true maximum.
TEST(DistanceBound, SettlesAtTheDecidingValue) {
  const Mesh sphere = testing::make_uv_sphere(12, 16, 1.0f);
  const Mesh fine = testing::make_uv_sphere(48, 64, 1.0f);
  const SurfaceIndex target(fine);
  const EvalResult e = evaluate(fine, sphere);
  const DistanceBound tight = distance_bound(sphere, target, {.tolerance = 0.02});
  ASSERT_TRUE(tight.converged);
  const double decide = 1.5 * tight.upper;
  const DistanceBound settled = distance_bound(sphere, target, {.tolerance = 0.02, .settle_below = decide});
  EXPECT_TRUE(settled.converged);
  EXPECT_LE(settled.upper, decide);
  EXPECT_GE(settled.upper, e.b_to_a.max);
  EXPECT_LE(settled.lower, settled.upper);
  EXPECT_LT(settled.queries, tight.queries);
  // Below the largest distance it changes nothing: every node over the maximum is refined as before.
  const DistanceBound under = distance_bound(sphere, target, {.tolerance = 0.02, .settle_below = 0.5 * tight.lower});
  EXPECT_EQ(under.upper, tight.upper);
  EXPECT_EQ(under.queries, tight.queries);
}

TEST(DistanceBound, GivesUpAboveAThresholdAndIsThreadIndependent) {
  const Mesh sphere = testing::make_uv_sphere(12, 16, 1.0f);
  const Mesh fine = testing::make_uv_sphere(48, 64, 1.0f);
  const SurfaceIndex target(fine);
  const DistanceBound full = distance_bound(sphere, target);
  const DistanceBound quick = distance_bound(sphere, target, {.give_up_above = 0.5 * full.lower});
  EXPECT_TRUE(quick.gave_up);
  EXPECT_TRUE(std::isinf(quick.upper));
  EXPECT_LE(quick.queries, full.queries);
  const DistanceBound one = distance_bound(sphere, target, {.threads = 1});
  const DistanceBound two = distance_bound(sphere, target, {.threads = 2});
  EXPECT_EQ(one.upper, two.upper);
  EXPECT_EQ(one.lower, two.lower);
  EXPECT_EQ(one.queries, two.queries);
}

TEST(DistanceBound, EmptyMeshesAndIdenticalSurfaces) {
  const Mesh sphere = testing::make_uv_sphere(8, 12, 1.0f);
  EXPECT_EQ(distance_bound(Mesh{}, SurfaceIndex(sphere)).upper, 0.0);
  EXPECT_TRUE(std::isinf(distance_bound(sphere, SurfaceIndex(Mesh{})).upper));
  // The same surface: zero measured; refinement stops at `good_enough`.
  const DistanceBound same = distance_bound(sphere, SurfaceIndex(sphere), {.good_enough = 1e-3});
  EXPECT_LE(same.lower, 1e-12);
  EXPECT_LE(same.upper, 1e-3);
}

// The unit square in z = 0 as `n` slivers (strips 1/n wide, 1 tall, each split in two), and the same square as
// two triangles: a LOD lying flat on a CAD face tessellated into slivers.
Mesh sliver_square(int n) {
  Mesh m;
  for (int i = 0; i <= n; ++i) m.add_vertex_with_wedge({{float(i) / float(n), 0.0f, 0.0f}});
  for (int i = 0; i <= n; ++i) m.add_vertex_with_wedge({{float(i) / float(n), 1.0f, 0.0f}});
  for (std::uint32_t i = 0; i < std::uint32_t(n); ++i) {
    const std::uint32_t top = std::uint32_t(n) + 1;
    m.add_face({i, i + 1, top + i + 1});
    m.add_face({i, top + i + 1, top + i});
  }
  return m;
}

Mesh two_triangle_square(float size) {
  Mesh m;
  for (const Vec3f& p : {Vec3f{{0, 0, 0}}, Vec3f{{size, 0, 0}}, Vec3f{{size, size, 0}}, Vec3f{{0, size, 0}}}) {
    m.add_vertex_with_wedge(p);
  }
  m.add_face({0, 1, 2});
  m.add_face({0, 2, 3});
  return m;
}

// The Lipschitz bound alone would split such a LOD without end (its centroid-to-corner radius halves per round,
// the slivers it straddles double); walking the flat region across the slivers' edges certifies it at once.
TEST(DistanceBound, ALodLyingOnAFlatFaceOfSliversConverges) {
  const SurfaceIndex target(sliver_square(400));
  const DistanceBound b = distance_bound(two_triangle_square(1.0f), target, {.tolerance = 0.1, .good_enough = 1e-3});
  EXPECT_TRUE(b.converged);
  EXPECT_LE(b.upper, 1e-3);
  EXPECT_LT(b.queries, 2000u);
}

// A hole in a flat region under a LOD triangle is a real distance: the walk stops at the hole's border. A 10 × 10
// grid without the cell [4,5]²: its centre is 0.5 from the rim.
TEST(DistanceBound, AHoleInAFlatRegionUnderALodIsMeasured) {
  const Mesh grid = testing::make_grid(10, 10, false);
  const std::uint32_t cell = 4 * 10 + 4;  // its two triangles are faces 2 cell and 2 cell + 1
  const std::uint32_t hole[] = {2 * cell, 2 * cell + 1};
  const SurfaceIndex target(without_faces(grid, hole));
  const DistanceBound b = distance_bound(two_triangle_square(10.0f), target, {.tolerance = 0.02, .good_enough = 1e-3});
  EXPECT_GE(b.upper, 0.5);
  EXPECT_GT(b.lower, 0.5 / 1.02 - 1e-9);
  EXPECT_LE(b.upper, 0.5 * 1.02 + 1e-9);
}

// Bounds known per triangle cap the result where the query allowance runs out, and are never the answer where
// refinement does better; deep refinement of the worst triangles when the allowance binds.
TEST(DistanceBound, KnownBoundsCapTheResult) {
  const Mesh sphere = testing::make_uv_sphere(12, 16, 1.0f);
  const Mesh fine = testing::make_uv_sphere(48, 64, 1.0f);
  const SurfaceIndex target(fine);
  const DistanceBound exact = distance_bound(sphere, target, {.tolerance = 0.01});
  ASSERT_TRUE(exact.converged);
  // A valid cap per triangle (the converged bound, raised a little), and a starved allowance.
  const std::vector<double> caps(sphere.triangle_count(), exact.upper * 1.2);
  const DistanceBoundOptions starved{.tolerance = 0.01, .max_queries = sphere.triangle_count() + 300, .threads = 1};
  const DistanceBound without = distance_bound(sphere, target, starved);
  DistanceBoundOptions capped = starved;
  capped.known_upper = &caps;
  const DistanceBound with = distance_bound(sphere, target, capped);
  EXPECT_FALSE(without.converged);
  EXPECT_GT(without.upper, exact.upper * 1.2) << "the starved bound alone is loose";
  EXPECT_LE(with.upper, exact.upper * 1.2 + 1e-12);
  EXPECT_GE(with.upper, exact.lower);
  // Caps far above the truth change nothing once the allowance suffices.
  const std::vector<double> loose(sphere.triangle_count(), 10.0);
  DistanceBoundOptions plenty{.tolerance = 0.01, .known_upper = &loose};
  EXPECT_DOUBLE_EQ(distance_bound(sphere, target, plenty).upper, exact.upper);
}

// Giving up names the triangles where a point over the threshold was found, and an indexed surface bounds
// as its mesh does.
TEST(DistanceBound, NamesTheTrianglesOverTheThresholdAndTakesAnIndexedSurface) {
  Mesh two;  // triangle 0 lies in z = 0, triangle 1 rises to z = 1 at its far corner
  for (const Vec3f& p : {Vec3f{{0, 0, 0}}, Vec3f{{1, 0, 0}}, Vec3f{{0, 1, 0}}, Vec3f{{5, 0, 0}}, Vec3f{{6, 0, 0}},
                         Vec3f{{5, 1, 1}}}) {
    two.add_vertex_with_wedge(p);
  }
  two.add_face({0, 1, 2});
  two.add_face({3, 4, 5});
  const SurfaceIndex target(two_triangle_square(10.0f));
  const DistanceBound over = distance_bound(two, target, {.give_up_above = 0.5, .threads = 1});
  EXPECT_TRUE(over.gave_up);
  EXPECT_EQ(over.over, std::vector<std::uint32_t>{1});
  const DistanceBound mesh = distance_bound(two, target, {.tolerance = 0.01, .threads = 1});
  const DistanceBound indexed = distance_bound(SurfaceIndex(two), target, {.tolerance = 0.01, .threads = 1});
  EXPECT_FALSE(mesh.gave_up);
  EXPECT_TRUE(mesh.over.empty());
  EXPECT_DOUBLE_EQ(mesh.upper, indexed.upper);
  EXPECT_DOUBLE_EQ(mesh.lower, indexed.lower);
  EXPECT_DOUBLE_EQ(mesh.lower, 1.0);
}

// Listing goes on past the first part over the threshold and names every triangle with one: here the tent's
// base (its corners lie on the tent, its middle 0.89 below it) and a triangle far off the tent.
TEST(DistanceBound, ListsEveryTriangleOverTheThreshold) {
  Mesh tent;
  for (const Vec3f& p : {Vec3f{{0, 0, 0}}, Vec3f{{4, 0, 0}}, Vec3f{{4, 4, 0}}, Vec3f{{0, 4, 0}}, Vec3f{{2, 2, 1}}}) {
    tent.add_vertex_with_wedge(p);
  }
  for (std::uint32_t i = 0; i < 4; ++i) tent.add_face({i, (i + 1) % 4, 4});
  Mesh m;
  for (const Vec3f& p : {Vec3f{{0, 0, 0}}, Vec3f{{4, 0, 0}}, Vec3f{{4, 4, 0}}, Vec3f{{0, 4, 0}}, Vec3f{{0.5f, 0, 0}},
                         Vec3f{{1, 0, 0}}, Vec3f{{0.5f, 0.2f, 0.2f}}, Vec3f{{8, 0, 0}}, Vec3f{{9, 0, 0}}, Vec3f{{8, 1, 1}}}) {
    m.add_vertex_with_wedge(p);
  }
  m.add_face({0, 1, 2});
  m.add_face({0, 2, 3});
  m.add_face({4, 5, 6});  // near the tent's base edge: within the threshold
  m.add_face({7, 8, 9});  // far off the tent
  const SurfaceIndex target(tent);
  // 0.7: the base's corners and centroids (0.60 away) are under it, the points near its middle over it.
  const DistanceBound listed = distance_bound(m, target, {.give_up_above = 0.7, .list_over = true, .threads = 1});
  EXPECT_TRUE(listed.gave_up);
  EXPECT_TRUE(std::isinf(listed.upper));
  EXPECT_EQ(listed.over, (std::vector<std::uint32_t>{0, 1, 3}));
  const DistanceBound first = distance_bound(m, target, {.give_up_above = 0.7, .threads = 1});
  EXPECT_TRUE(first.gave_up);
  EXPECT_TRUE(std::includes(listed.over.begin(), listed.over.end(), first.over.begin(), first.over.end()));
  EXPECT_LT(first.over.size(), listed.over.size()) << "without listing it stops at the first round over";
  // Nothing over: listing changes nothing.
  const DistanceBound none = distance_bound(m, target, {.give_up_above = 100, .list_over = true, .threads = 1});
  EXPECT_FALSE(none.gave_up);
  EXPECT_TRUE(none.over.empty());
}

// Settling known bounds: triangles whose known bound is within the threshold are taken at it and not measured;
// the others are bounded as before, and a known bound over the threshold settles nothing.
TEST(DistanceBound, SettlesKnownBoundsWithinTheThreshold) {
  const Mesh sphere = testing::make_uv_sphere(12, 16, 1.0f);
  const Mesh fine = testing::make_uv_sphere(48, 64, 1.0f);
  const SurfaceIndex target(fine);
  const DistanceBound exact = distance_bound(sphere, target, {.tolerance = 0.01, .threads = 1});
  ASSERT_TRUE(exact.converged);
  const double threshold = 2.0 * exact.upper;
  // Every triangle known within the threshold: nothing measured, the result is the largest known bound.
  std::vector<double> known(sphere.triangle_count(), 1.5 * exact.upper);
  known[3] = 1.7 * exact.upper;
  DistanceBoundOptions o{.tolerance = 0.01, .give_up_above = threshold, .threads = 1, .known_upper = &known,
                         .settle_known = true};
  const DistanceBound all = distance_bound(sphere, target, o);
  EXPECT_EQ(all.queries, 0u);
  EXPECT_DOUBLE_EQ(all.upper, 1.7 * exact.upper);
  EXPECT_FALSE(all.gave_up);
  // Half of them unknown (-1) or known over the threshold: those are measured, the rest still settled.
  for (std::size_t t = 0; t < known.size(); t += 2) known[t] = t % 4 == 0 ? -1.0 : 3.0 * exact.upper;
  const DistanceBound half = distance_bound(sphere, target, o);
  EXPECT_GT(half.queries, 0u);
  EXPECT_LT(half.queries, exact.queries);
  EXPECT_GE(half.upper, 1.7 * exact.upper);
  EXPECT_LE(half.upper, threshold);
  // Without settling, the same known bounds only cap: the result is the converged one.
  o.settle_known = false;
  EXPECT_DOUBLE_EQ(distance_bound(sphere, target, o).upper, distance_bound(sphere, target, {.tolerance = 0.01,
                   .give_up_above = threshold, .threads = 1}).upper);
}

// A triangle hovering across a crease of the target, its corners nearest to different target triangles: no
// single triangle holds it and the crease is far from flat, so a Lipschitz bound would split it round after
// round. Cut where the two triangles' distances cross, it is bounded in the first round, and truly.
TEST(DistanceBound, ANodeAcrossACreaseIsBoundedWithoutSplitting) {
  Mesh crease;  // a flat triangle and one rising at 27 degrees, sharing the edge x = 0
  for (const Vec3f& p : {Vec3f{{0, -2, 0}}, Vec3f{{0, 2, 0}}, Vec3f{{-2, 0, 0}}, Vec3f{{2, 0, 1}}}) {
    crease.add_vertex_with_wedge(p);
  }
  crease.add_face({0, 1, 2});
  crease.add_face({1, 0, 3});
  Mesh over;
  for (const Vec3f& p : {Vec3f{{-0.5f, -0.3f, 0.2f}}, Vec3f{{0.5f, -0.3f, 0.45f}}, Vec3f{{0.0f, 0.4f, 0.3f}}}) {
    over.add_vertex_with_wedge(p);
  }
  over.add_face({0, 1, 2});
  // The largest distance by brute force, on a fine lattice of the triangle.
  const SurfaceIndex target(crease);
  const Vec3d c[3] = {to_double(over.positions[0]), to_double(over.positions[1]), to_double(over.positions[2])};
  double truth = 0;
  constexpr int kSteps = 400;
  for (int i = 0; i <= kSteps; ++i) {
    for (int j = 0; i + j <= kSteps; ++j) {
      const Vec3d x = c[0] + (c[1] - c[0]) * (double(i) / kSteps) + (c[2] - c[0]) * (double(j) / kSteps);
      double d = INFINITY;
      for (std::uint32_t t = 0; t < 2; ++t) {
        const auto [a, b, e] = target.bvh.triangle(t);
        d = std::min(d, length(x - closest_point_on_triangle(x, a, b, e).point));
      }
      truth = std::max(truth, d);
    }
  }
  const DistanceBound b = distance_bound(over, target, {.tolerance = 0.0, .good_enough = 1.02 * truth});
  EXPECT_GE(b.upper, truth);
  EXPECT_LE(b.upper, 1.02 * truth);
  EXPECT_EQ(b.rounds, 1);
  EXPECT_TRUE(b.converged);
}

}  // namespace
}  // namespace lodforge
