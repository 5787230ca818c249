#include "lodforge/metric/quadric.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace lodforge {
namespace {

Vec3d v3(double x, double y, double z) { return {{x, y, z}}; }

TEST(Quadric, PlaneEvaluatesToWeightedSquaredDistance) {
  // Plane z = 2 (n = +z, d = -2), weight 3.
  const Quadric q = Quadric::from_plane(v3(0, 0, 1), -2.0, 3.0);
  EXPECT_DOUBLE_EQ(q.evaluate(v3(5, -7, 2)), 0.0);
  EXPECT_DOUBLE_EQ(q.evaluate(v3(1, 1, 5)), 3.0 * 9.0);
  EXPECT_DOUBLE_EQ(q.evaluate(v3(0, 0, 0)), 3.0 * 4.0);
  EXPECT_DOUBLE_EQ(q.weight, 0.0);  // a bare plane adds no surface
}

TEST(Quadric, TriangleQuadricIsAreaWeighted) {
  // Right triangle with legs 2 and 3 in the plane z = 1: area 3.
  const Quadric q = Quadric::from_triangle(v3(0, 0, 1), v3(2, 0, 1), v3(0, 3, 1));
  EXPECT_DOUBLE_EQ(q.weight, 3.0);
  EXPECT_NEAR(q.evaluate(v3(10, -4, 1)), 0.0, 1e-12);
  EXPECT_NEAR(q.evaluate(v3(0, 0, 3)), 3.0 * 4.0, 1e-12);
}

TEST(Quadric, DegenerateTriangleGivesZeroQuadric) {
  const Quadric q = Quadric::from_triangle(v3(0, 0, 0), v3(1, 1, 1), v3(2, 2, 2));
  EXPECT_EQ(q.weight, 0.0);
  EXPECT_EQ(q.evaluate(v3(3, -1, 7)), 0.0);
}

TEST(Quadric, AdditionIsComponentwise) {
  const Quadric a = Quadric::from_plane(v3(1, 0, 0), -1.0, 2.0);
  const Quadric b = Quadric::from_plane(v3(0, 1, 0), 0.5, 0.25);
  const Vec3d x = v3(0.3, -0.7, 4.0);
  EXPECT_NEAR((a + b).evaluate(x), a.evaluate(x) + b.evaluate(x), 1e-12);
}

TEST(Quadric, ThreeOrthogonalPlanesMeetAtTheMinimiser) {
  Quadric q = Quadric::from_plane(v3(1, 0, 0), -1.0, 1.0);  // x = 1
  q += Quadric::from_plane(v3(0, 1, 0), 2.0, 1.0);          // y = -2
  q += Quadric::from_plane(v3(0, 0, 1), -3.0, 1.0);         // z = 3
  const auto x = q.minimizer();
  ASSERT_TRUE(x.has_value());
  EXPECT_NEAR((*x)[0], 1.0, 1e-12);
  EXPECT_NEAR((*x)[1], -2.0, 1e-12);
  EXPECT_NEAR((*x)[2], 3.0, 1e-12);
  EXPECT_NEAR(q.evaluate(*x), 0.0, 1e-12);
}

TEST(Quadric, FlatQuadricHasNoMinimiserAndPlacementStaysOnTheEdge) {
  // Rank 1: every point of z = 0 is optimal. The solve must refuse, and the placement must fall back to
  // the edge with zero error and finite coordinates.
  const Quadric q = Quadric::from_triangle(v3(0, 0, 0), v3(1, 0, 0), v3(0, 1, 0));
  EXPECT_FALSE(q.minimizer().has_value());
  const Placement p = place_on_edge(q, v3(0, 0, 0), v3(1, 0, 0));
  EXPECT_FALSE(p.optimal);
  EXPECT_TRUE(std::isfinite(p.position[0]) && std::isfinite(p.position[1]) && std::isfinite(p.position[2]));
  EXPECT_NEAR(p.position[1], 0.0, 1e-12);
  EXPECT_NEAR(p.position[2], 0.0, 1e-12);
  EXPECT_GE(p.position[0], 0.0);
  EXPECT_LE(p.position[0], 1.0);
  EXPECT_NEAR(p.error, 0.0, 1e-12);
}

TEST(Quadric, RubberBandMakesFlatQuadricSolvableAtTheCentroid) {
  // Flat patch plus equal point quadrics at the two endpoints: the minimiser is their midpoint, on the plane.
  Quadric q = Quadric::from_triangle(v3(0, 0, 0), v3(2, 0, 0), v3(0, 2, 0));
  q += Quadric::from_point(v3(0, 0, 0), 1e-3);
  q += Quadric::from_point(v3(2, 0, 0), 1e-3);
  const auto x = q.minimizer();
  ASSERT_TRUE(x.has_value());
  EXPECT_NEAR((*x)[0], 1.0, 1e-9);
  EXPECT_NEAR((*x)[1], 0.0, 1e-9);
  EXPECT_NEAR((*x)[2], 0.0, 1e-9);
}

TEST(Quadric, CreaseMinimiserLiesOnTheCreaseLine) {
  // Two planes meeting along the line y = 0, z = 0 (a crease, rank 2), regularised by a tiny point quadric
  // at (0.4, 1, 1): the minimiser sits on the crease, at the point's x.
  Quadric q = Quadric::from_plane(v3(0, 1, 0), 0.0, 1.0);
  q += Quadric::from_plane(v3(0, 0, 1), 0.0, 1.0);
  q += Quadric::from_point(v3(0.4, 1.0, 1.0), 1e-4);
  const Placement p = place_on_edge(q, v3(0, 0, 0), v3(1, 0, 0));
  EXPECT_TRUE(p.optimal);
  EXPECT_NEAR(p.position[0], 0.4, 1e-6);
  EXPECT_NEAR(p.position[1], 0.0, 1e-3);
  EXPECT_NEAR(p.position[2], 0.0, 1e-3);
}

TEST(Quadric, UnregularisedCreaseFallsBackToTheBestPointOfTheEdge) {
  // Crease along x through (0, 0, 0); the edge runs across it from (0, -1, 0) to (0, 1, 0): the best point of
  // the segment is where it crosses the crease, at zero error.
  Quadric q = Quadric::from_plane(v3(0, 1, 0), 0.0, 1.0);
  q += Quadric::from_plane(v3(0, 0, 1), 0.0, 1.0);
  EXPECT_FALSE(q.minimizer().has_value());
  const Placement p = place_on_edge(q, v3(0, -1, 0), v3(0, 1, 0));
  EXPECT_NEAR(p.position[1], 0.0, 1e-12);
  EXPECT_NEAR(p.error, 0.0, 1e-12);
}

TEST(Quadric, FarMinimiserIsRejectedForTheEdge) {
  // Three planes meeting far from the edge (at x = 100): the unconstrained optimum would drag the vertex
  // across the model; the placement stays on the edge instead.
  Quadric q = Quadric::from_plane(v3(1, 0, 0), -100.0, 1.0);
  q += Quadric::from_plane(v3(0, 1, 0), 0.0, 1.0);
  q += Quadric::from_plane(v3(0, 0, 1), 0.0, 1.0);
  ASSERT_TRUE(q.minimizer().has_value());
  const Placement p = place_on_edge(q, v3(0, 0, 0), v3(1, 0, 0));
  EXPECT_FALSE(p.optimal);
  EXPECT_NEAR(p.position[0], 1.0, 1e-12);  // the end nearest the optimum
}

TEST(Quadric, BoundaryPlaneIsPerpendicularToTheFaceThroughTheEdge) {
  // Face in z = 0 with normal +z; boundary edge along x. The constraint plane is y = 0, weight w |e|².
  const Quadric q = Quadric::from_boundary_edge(v3(0, 0, 0), v3(2, 0, 0), v3(0, 0, 1), 10.0);
  EXPECT_NEAR(q.evaluate(v3(5, 0, 3)), 0.0, 1e-12);           // anywhere in the plane y = 0
  EXPECT_NEAR(q.evaluate(v3(0, 1, 0)), 10.0 * 4.0, 1e-12);    // unit distance, weight 10 × |e|² = 40
  EXPECT_EQ(q.weight, 0.0);
  const Quadric none = Quadric::from_boundary_edge(v3(1, 1, 1), v3(1, 1, 1), v3(0, 0, 1), 10.0);
  EXPECT_EQ(none.evaluate(v3(3, 4, 5)), 0.0);
}

TEST(Quadric, PointQuadricIsWeightedSquaredDistance) {
  const Quadric q = Quadric::from_point(v3(1, 2, 3), 0.5);
  EXPECT_NEAR(q.evaluate(v3(1, 2, 3)), 0.0, 1e-12);
  EXPECT_NEAR(q.evaluate(v3(1, 2, 5)), 0.5 * 4.0, 1e-12);
}

}  // namespace
}  // namespace lodforge
