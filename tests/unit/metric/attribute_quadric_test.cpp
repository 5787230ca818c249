#include "lodforge/metric/attribute_quadric.hpp"

#include <gtest/gtest.h>

#include <array>
#include <vector>

namespace lodforge {
namespace {

const Vec3d kP0{{0, 0, 0}}, kP1{{2, 0, 0}}, kP2{{0, 1, 0}};

TEST(AttributeQuadric, FitReproducesCornerValuesWithAnInPlaneGradient) {
  AttributeGradient f;
  ASSERT_TRUE(fit_attribute_gradient(kP0, kP1, kP2, 1.0, 3.0, -1.0, f));
  EXPECT_NEAR(dot(f.g, kP0) + f.d, 1.0, 1e-12);
  EXPECT_NEAR(dot(f.g, kP1) + f.d, 3.0, 1e-12);
  EXPECT_NEAR(dot(f.g, kP2) + f.d, -1.0, 1e-12);
  EXPECT_NEAR(f.g[2], 0.0, 1e-12);  // perpendicular to the normal (z)
  EXPECT_FALSE(fit_attribute_gradient(kP0, kP1, Vec3d{{4, 0, 0}}, 0, 1, 2, f));  // degenerate
}

// One face, one attribute: the error at (p, s) is the squared mismatch; minimising over s leaves zero for
// points in the plane, and s* is the face's linear function.
TEST(AttributeQuadric, ReductionAndOptimalValues) {
  AttributeGradient f;
  ASSERT_TRUE(fit_attribute_gradient(kP0, kP1, kP2, 0.0, 2.0, 5.0, f));
  AttributeQuadric q;
  std::array<AttributeGradient, 1> sums{};
  accumulate_attribute(q, sums[0], f, 0.5);
  q.alpha += 0.5;
  const Vec3d p{{0.5, 0.25, 0.0}};
  std::array<double, 1> s{};
  ASSERT_TRUE(optimal_attributes(q, sums, p, s));
  EXPECT_NEAR(s[0], dot(f.g, p) + f.d, 1e-12);
  EXPECT_NEAR(reduce_attributes(q, sums).evaluate(p), 0.0, 1e-12);

  // Two faces that disagree about the attribute: the reduced quadric is positive (their spread) and the
  // optimal value is their weighted mean.
  AttributeGradient h{{{0, 0, 0}}, 4.0};  // constant 4
  AttributeQuadric r;
  std::array<AttributeGradient, 1> rs{};
  accumulate_attribute(r, rs[0], h, 1.5);
  r.alpha += 1.5;
  merge_attribute_quadrics(q, sums, r, rs);
  ASSERT_TRUE(optimal_attributes(q, sums, p, s));
  const double a = dot(f.g, p) + f.d;
  EXPECT_NEAR(s[0], (0.5 * a + 1.5 * 4.0) / 2.0, 1e-12);
  const double spread = 0.5 * (a - s[0]) * (a - s[0]) + 1.5 * (4.0 - s[0]) * (4.0 - s[0]);
  EXPECT_NEAR(reduce_attributes(q, sums).evaluate(p), spread, 1e-9);
  EXPECT_EQ(reduce_attributes(q, sums).weight, 0.0);
}

TEST(AttributeQuadric, MergedReductionEqualsReducingTheMerge) {
  AttributeGradient f, h;
  ASSERT_TRUE(fit_attribute_gradient(kP0, kP1, kP2, 0.5, 2.0, -1.0, f));
  ASSERT_TRUE(fit_attribute_gradient(kP0, kP1, Vec3d{{1, 1, 1}}, 1.0, 0.0, 3.0, h));
  AttributeQuadric a, b;
  std::array<AttributeGradient, 1> ga{}, gb{};
  accumulate_attribute(a, ga[0], f, 0.7);
  a.alpha += 0.7;
  accumulate_attribute(b, gb[0], h, 1.3);
  b.alpha += 1.3;
  const Quadric direct = reduce_merged_attributes(a, ga, b, gb);
  merge_attribute_quadrics(a, ga, b, gb);
  const Quadric merged = reduce_attributes(a, ga);
  for (const Vec3d& p : {Vec3d{{0, 0, 0}}, Vec3d{{0.3, -0.2, 0.9}}, Vec3d{{2, 1, -1}}}) {
    EXPECT_NEAR(direct.evaluate(p), merged.evaluate(p), 1e-12);
  }
  EXPECT_GT(merged.evaluate(Vec3d{{0.3, -0.2, 0.9}}), 0.0);
}

TEST(AttributeQuadric, EmptyQuadricHasNoOptimum) {
  AttributeQuadric q;
  std::array<AttributeGradient, 2> sums{};
  std::array<double, 2> s{{7, 7}};
  EXPECT_FALSE(optimal_attributes(q, sums, Vec3d{}, s));
  EXPECT_EQ(s[0], 7);
  EXPECT_EQ(reduce_attributes(q, sums).evaluate(Vec3d{{1, 2, 3}}), 0.0);
}

}  // namespace
}  // namespace lodforge
