// The engines' seams: the shared stop rule, caller policies (placement, cost, filter, stop, observer) and the
// per-rule veto counts.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "lodforge/core/validate.hpp"
#include "lodforge/metric/stop_rule.hpp"
#include "lodforge/simplify/policies.hpp"
#include "lodforge/simplify/simplify.hpp"
#include "simplify_fixtures.hpp"
#include "test_support.hpp"

namespace lodforge {
namespace {

using simplify_test::make_bumpy_grid;
using simplify_test::make_bumpy_sphere;

// Whether `mesh` still has a vertex exactly at `p` (unmoved vertices keep their input position bit for bit).
bool has_position(const Mesh& mesh, const Vec3f& p) {
  return std::any_of(mesh.positions.begin(), mesh.positions.end(), [&](const Vec3f& x) { return x == p; });
}

TEST(StopRule, CountRatioAndBudgets) {
  const StopRule ratio = StopRule::make(1000, {.target_ratio = 0.25}, 10.0);
  EXPECT_EQ(ratio.target_triangles, 250u);
  EXPECT_FALSE(ratio.has_budget());
  EXPECT_TRUE(ratio.allows(1e300));
  EXPECT_TRUE(ratio.reached(250));
  EXPECT_FALSE(ratio.reached(251));

  // A count wins over the ratio and is clamped to the input.
  EXPECT_EQ(StopRule::make(1000, {.target_ratio = 0.25, .target_triangles = 40}, 1.0).target_triangles, 40u);
  EXPECT_EQ(StopRule::make(100, {.target_triangles = 400}, 1.0).target_triangles, 100u);

  // Of two budgets the smaller wins; the relative one is a fraction of the diagonal.
  const StopRule both = StopRule::make(10, {.max_error_abs = 0.5, .max_error_rel = 0.01}, 20.0);
  EXPECT_DOUBLE_EQ(both.max_error, 0.2);
  EXPECT_TRUE(both.has_budget());
  EXPECT_TRUE(both.allows(0.2));
  EXPECT_FALSE(both.allows(0.2000001));
  EXPECT_DOUBLE_EQ(StopRule::make(10, {.max_error_abs = 0.1, .max_error_rel = 0.01}, 20.0).max_error, 0.1);
}

TEST(CollapsePolicies, EmptyPoliciesChangeNothing) {
  const Mesh sphere = make_bumpy_sphere(24, 32);
  for (Engine engine : {Engine::edge_collapse, Engine::multiple_choice}) {
    const SimplifyOptions o{.target_ratio = 0.2, .engine = engine};
    EXPECT_EQ(simplify(sphere, o).mesh, simplify(sphere, o, CollapsePolicies{}).mesh);
  }
}

TEST(CollapsePolicies, StopPolicyEndsTheRunBetweenRounds) {
  const Mesh sphere = make_bumpy_sphere(24, 32);
  std::size_t calls = 0;
  const CollapsePolicies p{.stop = [&](const StopState& s) {
    ++calls;
    return s.collapses >= 10;
  }};
  // One collapse per round: the stop predicate sees every collapse.
  const SimplifyResult r = simplify(sphere, {.target_ratio = 0.1, .max_batch = 1}, p);
  EXPECT_EQ(r.collapses, 10u);
  EXPECT_GE(calls, 11u);
  EXPECT_EQ(r.stop_reason, StopReason::no_valid_collapse);  // neither the target nor the budget stopped it
  EXPECT_TRUE(validate(r.mesh).ok());

  const SimplifyResult mc = simplify(sphere, {.target_ratio = 0.1, .engine = Engine::multiple_choice}, p);
  EXPECT_GE(mc.collapses, 10u);
  EXPECT_LT(mc.collapses, sphere.triangle_count() / 2);  // stopped after the round that reached 10
}

TEST(CollapsePolicies, ObserverSeesEveryCollapseInOrder) {
  const Mesh sphere = make_bumpy_sphere(24, 32);
  for (Engine engine : {Engine::edge_collapse, Engine::multiple_choice}) {
    std::vector<CollapseEvent> events;
    const CollapsePolicies p{.on_collapse = [&](const CollapseEvent& e) { events.push_back(e); }};
    const SimplifyResult r = simplify(sphere, {.target_ratio = 0.2, .engine = engine}, p);
    ASSERT_EQ(events.size(), r.collapses);
    double max_error = 0.0;
    for (std::size_t i = 0; i < events.size(); ++i) {
      EXPECT_NE(events[i].victim, events[i].survivor);
      if (i > 0) {
        EXPECT_LT(events[i].triangles, events[i - 1].triangles);
      }
      max_error = std::max(max_error, events[i].error);
    }
    EXPECT_EQ(events.back().triangles, r.triangles_after);
    EXPECT_DOUBLE_EQ(max_error, r.qem_error_abs);  // the QEM error is the largest committed one
  }
}

TEST(CollapsePolicies, FilterKeepsARegionUntouched) {
  const Mesh grid = make_bumpy_grid(20);
  auto in_kept = [](const Vec3d& p) { return p[0] < 10.5; };
  const CollapsePolicies p{.filter = [&](const CollapseCandidate& c) {
    return !in_kept(c.position_u) && !in_kept(c.position_v);
  }};
  const SimplifyResult r = simplify(grid, {.target_ratio = 0.1}, p);
  EXPECT_GT(r.vetoes[Veto::filter], 0u);
  // Every vertex of the kept half is still there, where it was.
  std::size_t kept = 0;
  for (const Vec3f& q : grid.positions) {
    if (q[0] >= 10.5f) continue;
    ++kept;
    EXPECT_TRUE(has_position(r.mesh, q)) << q[0] << "," << q[1];
  }
  EXPECT_EQ(kept, 11u * 21u);
  EXPECT_TRUE(validate(r.mesh).ok());
  // Without the filter the same target takes vertices of that half too.
  const SimplifyResult free = simplify(grid, {.target_ratio = 0.1});
  std::size_t left = 0;
  for (const Vec3f& x : free.mesh.positions) left += x[0] < 10.5f;
  EXPECT_LT(left, kept);
}

TEST(CollapsePolicies, CostPolicyOrdersTheCollapses) {
  // Collapses with an endpoint left of x = 10.5 cost a million more: the engine spends the reduction right of
  // it first, and that part alone can remove a quarter of the triangles.
  const Mesh grid = make_bumpy_grid(20);
  const CollapsePolicies p{.cost = [](const CollapseCandidate& c) {
    return (c.position_u[0] < 10.5 || c.position_v[0] < 10.5) ? 1e6 + c.cost : c.cost;
  }};
  const SimplifyResult r = simplify(grid, {.target_ratio = 0.75, .max_batch = 1}, p);
  EXPECT_EQ(r.triangles_after, 600u);
  std::size_t kept = 0;
  for (const Vec3f& q : grid.positions) {
    if (q[0] >= 10.5f) continue;
    ++kept;
    EXPECT_TRUE(has_position(r.mesh, q)) << q[0] << "," << q[1];
  }
  EXPECT_EQ(kept, 11u * 21u);
  const SimplifyResult plain = simplify(grid, {.target_ratio = 0.75, .max_batch = 1});
  std::size_t left = 0;
  for (const Vec3f& q : grid.positions) {
    if (q[0] >= 10.5f) continue;
    left += has_position(plain.mesh, q);
  }
  EXPECT_LT(left, kept);
}

TEST(CollapsePolicies, PlacementPolicyPlacesTheSurvivor) {
  // Every free collapse goes to the midpoint of its edge: the first collapse's survivor lies there.
  const Mesh sphere = make_bumpy_sphere(16, 24);
  std::vector<CollapseEvent> events;
  std::vector<Vec3d> midpoints;
  const CollapsePolicies p{
      .placement = [](const CollapseCandidate& c) -> std::optional<Vec3d> {
        return (c.position_u + c.position_v) * 0.5;
      },
      .on_collapse = [&](const CollapseEvent& e) { events.push_back(e); }};
  const SimplifyResult r = simplify(sphere, {.target_ratio = 0.5, .max_batch = 1}, p);
  ASSERT_FALSE(events.empty());
  const Vec3f a = sphere.positions[events[0].victim], b = sphere.positions[events[0].survivor];
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(events[0].position[i], 0.5 * (double{a[i]} + b[i]), 1e-6);
  // The default placement (the quadric's minimiser) puts it elsewhere on a curved surface.
  std::vector<CollapseEvent> plain_events;
  simplify(sphere, {.target_ratio = 0.5, .max_batch = 1},
           {.on_collapse = [&](const CollapseEvent& e) { plain_events.push_back(e); }});
  ASSERT_FALSE(plain_events.empty());
  const Vec3f pa = sphere.positions[plain_events[0].victim], pb = sphere.positions[plain_events[0].survivor];
  double off = 0.0;
  for (int i = 0; i < 3; ++i) off += std::abs(plain_events[0].position[i] - 0.5 * (double{pa[i]} + pb[i]));
  EXPECT_GT(off, 1e-6);
  EXPECT_TRUE(validate(r.mesh).ok());
}

TEST(Vetoes, CountedPerRule) {
  // A closed sphere to 1%: folds and link-condition refusals happen; the budget run counts its drops.
  const Mesh sphere = make_bumpy_sphere(24, 32);
  const SimplifyResult r = simplify(sphere, {.target_ratio = 0.01, .max_batch = 1});
  std::size_t sum = 0;
  for (int i = 1; i < kVetoKinds; ++i) {
    if (static_cast<Veto>(i) != Veto::error_budget) sum += r.vetoes.count[i];
  }
  EXPECT_EQ(sum, r.vetoes.rejected());
  EXPECT_EQ(r.rounds, r.collapses + r.vetoes.rejected());  // one candidate per round, sequentially
  EXPECT_EQ(r.vetoes[Veto::error_budget], 0u);

  const SimplifyResult budget = simplify(sphere, {.target_ratio = 0.01, .max_error_rel = 0.001});
  EXPECT_EQ(budget.stop_reason, StopReason::error_budget);
  EXPECT_GT(budget.vetoes[Veto::error_budget], 0u);
  EXPECT_STREQ(veto_name(Veto::uv_flip), "uv_flip");
  EXPECT_STREQ(veto_name(Veto::error_budget), "error_budget");
}

// Meshes with vertices but no usable faces (vertices only; faces whose corners weld into one vertex): every
// engine returns an empty LOD instead of reading an empty face pool.
TEST(EdgeCollapse, MeshesWithoutUsableFaces) {
  Mesh points;
  for (int i = 0; i < 5; ++i) points.add_vertex_with_wedge({{float(i), 0.0f, 0.0f}});
  Mesh welded = points;
  welded.add_face({0, 0, 0});
  welded.add_face({1, 1, 2});
  for (const Mesh* m : {&points, &welded}) {
    for (Engine engine : {Engine::edge_collapse, Engine::multiple_choice, Engine::polychord}) {
      const SimplifyResult r = simplify(*m, {.target_ratio = 0.5, .engine = engine});
      EXPECT_EQ(r.triangles_after, 0u) << static_cast<int>(engine);
      EXPECT_EQ(r.collapses, 0u);
    }
  }
}

}  // namespace
}  // namespace lodforge
