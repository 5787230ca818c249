// Error budgets held by measurement: verification against the input, back-off along the collapse sequence,
// a reference other than the input (LOD chains), and the comparison with the oracle prefix.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <tuple>
#include <vector>

#include "engines.hpp"
#include "lodforge/eval/bvh.hpp"
#include "lodforge/eval/distance_bound.hpp"
#include "lodforge/eval/eval.hpp"
#include "lodforge/simplify/policies.hpp"
#include "lodforge/simplify/simplify.hpp"
#include "simplify_fixtures.hpp"
#include "test_support.hpp"

namespace lodforge {
namespace {

using simplify_test::make_bumpy_grid;
using simplify_test::make_bumpy_sphere;

// The decision samples the output at many points (the bound's refinement) and the input at its vertices and
// triangle centroids; the evaluator's denser samples may find up to this much more.
constexpr double kSamplingTolerance = 0.1;

TEST(ErrorBudget, VerifiedOutputStaysWithinTheBudgetWhereTheQemAloneDoesNot) {
  const Mesh sphere = make_bumpy_sphere(40, 60);
  for (double budget : {0.001, 0.004, 0.02}) {
    const SimplifyOptions o{.target_ratio = 0.001, .max_error_rel = budget};
    SimplifyOptions unverified = o;
    unverified.verify_budget = false;
    const SimplifyResult engine = simplify(sphere, unverified);
    const SimplifyResult held = simplify(sphere, o);
    EXPECT_FALSE(engine.budget.verified);
    EXPECT_LT(engine.error_bound_abs, 0.0);  // not measured
    ASSERT_TRUE(held.budget.verified);
    EXPECT_TRUE(held.budget.within) << budget;
    const EvalResult e = evaluate(sphere, held.mesh);
    EXPECT_LE(e.hausdorff_rel(), budget * (1 + kSamplingTolerance)) << budget;
    EXPECT_GE(held.error_bound_abs, e.b_to_a.max * (1 - 1e-9)) << "the bound bounds the measured distance";
    EXPECT_LE(held.budget.sampled_abs, held.budget.bound_abs);
    // The QEM stop alone overshoots the budget (what made verification necessary), so the verified LOD keeps
    // more triangles.
    EXPECT_GT(evaluate(sphere, engine.mesh).hausdorff_rel(), budget) << budget;
    EXPECT_GT(held.vetoes[Veto::error_budget], 0u) << "the guard refused collapses the QEM allowed";
    EXPECT_GT(held.triangles_after, engine.triangles_after);
    EXPECT_EQ(held.stop_reason, StopReason::error_budget);
    EXPECT_EQ(held.triangles_after, held.mesh.triangle_count());
  }
}

TEST(ErrorBudget, AHeldRunIsTheEnginesOwnOutput) {
  // A budget the engine's run already meets: nothing is backed off and the mesh is the engine's, byte for byte.
  const Mesh sphere = make_bumpy_sphere(24, 32);
  SimplifyOptions o{.target_ratio = 0.5, .max_error_rel = 0.05};
  const SimplifyResult held = simplify(sphere, o);
  o.verify_budget = false;
  const SimplifyResult engine = simplify(sphere, o);
  EXPECT_TRUE(held.budget.within);
  EXPECT_EQ(held.budget.collapses_undone, 0u);
  EXPECT_EQ(held.budget.prefixes_measured, 1u);
  EXPECT_EQ(held.mesh, engine.mesh);
  EXPECT_EQ(held.stop_reason, StopReason::target_reached);
}

TEST(ErrorBudget, BackOffIsTheSameOnAnyThreadCountAndForBothTriangleEngines) {
  const Mesh grid = make_bumpy_grid(30);
  for (Engine engine : {Engine::edge_collapse, Engine::multiple_choice}) {
    const SimplifyOptions o1{.target_ratio = 0.01, .max_error_rel = 0.003, .threads = 1, .engine = engine};
    SimplifyOptions o2 = o1;
    o2.threads = 2;
    const SimplifyResult a = simplify(grid, o1), b = simplify(grid, o2);
    EXPECT_EQ(a.mesh, b.mesh);
    EXPECT_EQ(a.budget.bound_abs, b.budget.bound_abs);
    EXPECT_TRUE(a.budget.within);
    EXPECT_LE(evaluate(grid, a.mesh).hausdorff_rel(), 0.003 * (1 + kSamplingTolerance));
  }
}

// Budget cases over a bumpy sphere and grid: first LODs at three budgets and a chain's next LOD (measured
// against the sphere), each as the options that make it.
struct BudgetCase {
  const Mesh* input;
  double budget;
  SimplifyOptions options;
};
struct BudgetCases {
  BudgetCases()
      : sphere(make_bumpy_sphere(40, 60)),
        grid(make_bumpy_grid(40)),
        first(simplify(sphere, {.target_ratio = 0.001, .max_error_rel = 0.002})) {
    for (const auto& [input, reference, budget] : {std::tuple<const Mesh*, const Mesh*, double>{&sphere, nullptr, 0.001},
                                                   {&sphere, nullptr, 0.01},
                                                   {&grid, nullptr, 0.003},
                                                   {&first.mesh, &sphere, 0.008}}) {
      SimplifyOptions o{.target_ratio = 0.001, .max_error_rel = budget, .threads = 2};
      o.budget_reference = reference;
      cases.push_back({input, budget, o});
    }
  }
  Mesh sphere, grid;
  SimplifyResult first;
  std::vector<BudgetCase> cases;
};

// A guarded run holds the budget by itself: its output passes the measurement at once (nothing backed off,
// one measurement), stays within the budget by eval's denser sampling, and keeps no more than a quarter more
// triangles than the unguarded engine backed off along its log (on the scanned corpus it keeps far fewer,
// docs/budgets.md); on a first LOD and on a chain's next one. (simplify() guards the greedy engine only.)
TEST(ErrorBudget, AGuardedRunHoldsTheBudgetWithoutBackingOff) {
  const BudgetCases all;
  for (const BudgetCase& c : all.cases) {
    const SimplifyOptions& o = c.options;
    const SimplifyResult guarded = simplify(*c.input, o);
    const SimplifyResult unguarded =
        collapse::run_within_budget(collapse::run_edge_collapse, *c.input, o, {}, true, /*guarded=*/false);
    const Mesh& reference = o.budget_reference != nullptr ? *o.budget_reference : *c.input;
    const double diag = compute_bounds(*c.input).diagonal();
    EXPECT_TRUE(guarded.budget.within) << c.budget;
    EXPECT_EQ(guarded.budget.collapses_undone, 0u) << c.budget;
    EXPECT_EQ(guarded.budget.prefixes_measured, 1u) << c.budget;
    EXPECT_GT(guarded.vetoes[Veto::error_budget], 0u) << c.budget;
    EXPECT_LE(evaluate(reference, guarded.mesh).hausdorff, c.budget * diag * (1 + kSamplingTolerance)) << c.budget;
    EXPECT_LE(static_cast<double>(guarded.triangles_after), 1.25 * static_cast<double>(unguarded.triangles_after))
        << c.budget << ": guarded " << guarded.triangles_after << ", backed off " << unguarded.triangles_after;
  }
}

// The bisection's steps screened by what their collapses changed decide exactly as screening each step in
// full: the same prefixes measured, the same output, on a first LOD and on a chain's next one.
TEST(ErrorBudget, IncrementalScreensDecideLikeFullScreens) {
  const BudgetCases all;
  for (const BudgetCase& c : all.cases) {
    const SimplifyOptions& o = c.options;
    // Unguarded: a guarded run rarely backs off, and this is about the back-off.
    const SimplifyResult incremental =
        collapse::run_within_budget(collapse::run_edge_collapse, *c.input, o, {}, true, /*guarded=*/false);
    const SimplifyResult full =
        collapse::run_within_budget(collapse::run_edge_collapse, *c.input, o, {}, false, /*guarded=*/false);
    ASSERT_GT(incremental.budget.collapses_undone, 0u) << c.budget << ": the case must back off";
    EXPECT_GT(incremental.budget.prefixes_screened_incrementally, 0u) << c.budget;
    EXPECT_EQ(full.budget.prefixes_screened_incrementally, 0u);
    EXPECT_EQ(incremental.budget.prefixes_measured, full.budget.prefixes_measured) << c.budget;
    EXPECT_EQ(incremental.mesh, full.mesh) << c.budget;
    EXPECT_TRUE(incremental.budget.within) << c.budget;
  }
}

TEST(ErrorBudget, ChainsAreMeasuredAgainstTheReference) {
  // A LOD made from a previous LOD is held to the budget against the original, not against its input.
  const Mesh sphere = make_bumpy_sphere(40, 60);
  const SimplifyResult first = simplify(sphere, {.target_ratio = 0.001, .max_error_rel = 0.003});
  const double diag = compute_bounds(sphere).diagonal();
  SimplifyOptions next{.target_ratio = 0.001, .max_error_abs = 0.006 * diag};
  next.budget_reference = &sphere;
  const SimplifyResult second = simplify(first.mesh, next);
  EXPECT_TRUE(second.budget.within);
  EXPECT_LE(evaluate(sphere, second.mesh).hausdorff_rel(), 0.006 * (1 + kSamplingTolerance));
  EXPECT_LT(second.triangles_after, first.triangles_after);
}

// A chain's LODs may share one index of the reference: the same LOD as each building its own.
TEST(ErrorBudget, ASharedReferenceIndexGivesTheSameLod) {
  const Mesh sphere = make_bumpy_sphere(40, 60);
  const SimplifyResult first = simplify(sphere, {.target_ratio = 0.001, .max_error_rel = 0.003});
  const double diag = compute_bounds(sphere).diagonal();
  SimplifyOptions next{.target_ratio = 0.001, .max_error_abs = 0.006 * diag};
  next.budget_reference = &sphere;
  const SimplifyResult own = simplify(first.mesh, next);
  const SurfaceIndex index(sphere);
  next.budget_reference_index = &index;
  const SimplifyResult shared = simplify(first.mesh, next);
  EXPECT_EQ(shared.mesh.positions, own.mesh.positions);
  EXPECT_EQ(shared.mesh.corner_wedge, own.mesh.corner_wedge);
  EXPECT_EQ(shared.mesh.wedge_vertex, own.mesh.wedge_vertex);
  EXPECT_EQ(shared.budget.bound_abs, own.budget.bound_abs);
  EXPECT_EQ(shared.budget.reverse_abs, own.budget.reverse_abs);
  EXPECT_TRUE(shared.budget.within);
}

// A guarded LOD says which of its triangles it kept each sample of the reference near (its vertices, then its
// triangles' centroids); the chain's next LOD starts from them. Each is within the budget of its sample; the
// next LOD holds its budget with them, with none and with wrong ones (they are checked).
TEST(ErrorBudget, ReferenceAttachmentsCarryAlongAChain) {
  const Mesh sphere = make_bumpy_sphere(40, 60);
  const double diag = compute_bounds(sphere).diagonal();
  const SimplifyResult first = simplify(sphere, {.target_ratio = 0.001, .max_error_rel = 0.003});
  ASSERT_TRUE(first.budget.within);
  const std::vector<std::uint32_t> idx = triangle_vertex_indices(sphere);
  const std::size_t nv = sphere.vertex_count(), nt = idx.size() / 3;
  ASSERT_EQ(first.reference_attachments.size(), nv + nt);
  const std::vector<std::uint32_t> lod_idx = triangle_vertex_indices(first.mesh);
  auto distance_to = [&](const Vec3d& p, std::uint32_t t) {
    EXPECT_LT(t, lod_idx.size() / 3);
    if (t >= lod_idx.size() / 3) return std::numeric_limits<double>::infinity();
    const Vec3d a = to_double(first.mesh.positions[lod_idx[3 * t]]), b = to_double(first.mesh.positions[lod_idx[3 * t + 1]]),
                c = to_double(first.mesh.positions[lod_idx[3 * t + 2]]);
    return length(p - closest_point_on_triangle(p, a, b, c).point);
  };
  double worst = 0;
  for (std::size_t v = 0; v < nv; ++v) worst = std::max(worst, distance_to(to_double(sphere.positions[v]), first.reference_attachments[v]));
  for (std::size_t t = 0; t < nt; ++t) {
    const Vec3d g = (to_double(sphere.positions[idx[3 * t]]) + to_double(sphere.positions[idx[3 * t + 1]]) +
                     to_double(sphere.positions[idx[3 * t + 2]])) * (1.0 / 3.0);
    worst = std::max(worst, distance_to(g, first.reference_attachments[nv + t]));
  }
  EXPECT_LE(worst, 0.003 * diag);

  SimplifyOptions next{.target_ratio = 0.001, .max_error_abs = 0.012 * diag};
  next.budget_reference = &sphere;
  const SimplifyResult plain = simplify(first.mesh, next);
  next.budget_attachments = &first.reference_attachments;
  const SimplifyResult started = simplify(first.mesh, next);
  const std::vector<std::uint32_t> wrong(nv + nt, 0);  // all on triangle 0: within the budget of few samples
  next.budget_attachments = &wrong;
  const SimplifyResult checked = simplify(first.mesh, next);
  for (const SimplifyResult* r : {&plain, &started, &checked}) {
    EXPECT_TRUE(r->budget.within);
    EXPECT_EQ(r->budget.collapses_undone, 0u);
    EXPECT_LE(evaluate(sphere, r->mesh).hausdorff_rel(), 0.012 * (1 + kSamplingTolerance));
    EXPECT_LT(r->triangles_after, first.triangles_after);
  }
  // The attachments only change which face each sample starts on: the LODs stay close in size.
  EXPECT_NEAR(double(started.triangles_after), double(plain.triangles_after), 0.1 * double(plain.triangles_after));
}

TEST(ErrorBudget, PolychordOutputsAreMeasuredToo) {
  const Mesh grid = testing::make_grid(16, 16, true);
  Mesh bumpy = grid;
  for (Vec3f& p : bumpy.positions) p[2] = static_cast<float>(0.4 * std::sin(0.8 * p[0]) * std::cos(0.6 * p[1]));
  const double budget = 0.004;
  const SimplifyResult r = simplify(bumpy, {.target_ratio = 0.01, .max_error_rel = budget, .engine = Engine::polychord});
  ASSERT_TRUE(r.budget.verified);
  EXPECT_TRUE(r.budget.within);
  EXPECT_LE(evaluate(bumpy, r.mesh).hausdorff_rel(), budget * (1 + kSamplingTolerance));
}

// Over its budget, the quad engine backs off along its own LODs (larger targets, each with its surface fit)
// instead of handing the mesh to the triangle engine: the LOD holds and stays quads.
TEST(ErrorBudget, PolychordBacksOffAlongItsOwnLodsAndKeepsQuads) {
  Mesh bumpy = testing::make_grid(24, 24, true);
  for (Vec3f& p : bumpy.positions) p[2] = static_cast<float>(0.6 * std::sin(0.5 * p[0]) * std::cos(0.4 * p[1]));
  const double budget = 0.003;
  const SimplifyOptions options{.target_ratio = 0.01, .max_error_rel = budget, .engine = Engine::polychord};
  SimplifyOptions unverified = options;
  unverified.verify_budget = false;
  const SimplifyResult engine = simplify(bumpy, unverified);
  ASSERT_GT(evaluate(bumpy, engine.mesh).hausdorff_rel(), budget) << "the quad engine's own stop is over the budget";
  const SimplifyResult r = simplify(bumpy, options);
  ASSERT_TRUE(r.budget.within);
  EXPECT_FALSE(r.quad_engine_handed_over);
  EXPECT_LT(r.triangles_after, bumpy.triangle_count());
  EXPECT_GT(r.triangles_after, engine.triangles_after);
  EXPECT_GE(2 * r.quads_after, r.mesh.face_count()) << "mostly quads";
  EXPECT_LE(evaluate(bumpy, r.mesh).hausdorff_rel(), budget * (1 + kSamplingTolerance));
}

// The oracle: along the engine's own collapse sequence (one collapse per round), the longest prefix all of
// whose shorter prefixes meet the budget by measurement. The held LOD is not over-cautious against it.
TEST(ErrorBudget, WithinAQuarterOfTheOraclePrefix) {
  const Mesh sphere = make_bumpy_sphere(10, 14);
  const double budget = 0.01;
  const double diag = compute_bounds(sphere).diagonal();
  SimplifyOptions o{.target_ratio = 0.01, .max_error_rel = budget, .max_batch = 1};
  const SimplifyResult held = simplify(sphere, o);
  ASSERT_TRUE(held.budget.within);
  SimplifyOptions plain = o;
  plain.verify_budget = false;
  std::size_t oracle_triangles = sphere.triangle_count();
  for (std::size_t k = 1;; ++k) {
    CollapsePolicies stop_at;
    stop_at.stop = [k](const StopState& s) { return s.collapses >= k; };
    const SimplifyResult prefix = simplify(sphere, plain, stop_at);
    if (prefix.collapses < k) break;  // the engine's run ended
    if (evaluate(sphere, prefix.mesh, {.samples = 20000}).hausdorff > budget * diag) break;
    oracle_triangles = prefix.triangles_after;
  }
  EXPECT_LE(static_cast<double>(held.triangles_after), 1.25 * static_cast<double>(oracle_triangles))
      << "held " << held.triangles_after << ", oracle " << oracle_triangles << " bound " << held.budget.bound_abs / diag
      << " sampled " << held.budget.sampled_abs / diag << " reverse " << held.budget.reverse_abs / diag << " undone "
      << held.budget.collapses_undone << " measured " << held.budget.prefixes_measured << " collapses " << held.collapses;
}

// A guarded run bounds each output triangle's distance to the reference from the points it tested: every point
// of the triangle (here a lattice of 45 per triangle) is within its bound, for a first LOD (the reference is the
// input) and for a chain's next one (the reference is the source, the input a LOD of it).
TEST(ErrorBudget, GuardedFaceBoundsHoldEveryPointOfTheirTriangle) {
  const Mesh source = triangulated(make_bumpy_sphere(40, 60));
  const double diag = compute_bounds(source).diagonal();
  const TriangleBvh bvh = make_triangle_bvh(source);
  std::vector<Vec3d> samples;
  for (const Vec3f& p : source.positions) samples.push_back(to_double(p));
  const Mesh lod1 = simplify(source, {.target_ratio = 0.001, .max_error_rel = 0.002}).mesh;
  for (const Mesh* input : {&source, &lod1}) {
    for (const double budget : {0.004, 0.02}) {
      std::vector<double> bounds;
      const collapse::GuardReference guard{.bvh = &bvh,
                                           .samples = samples,
                                           .origins = {},
                                           .start_faces = {},
                                           .budget = budget * diag,
                                           .grid_spacing = 4.0 * budget * diag,
                                           .dense_regions = {},
                                           .face_bounds = &bounds,
                                           .sample_faces = nullptr};
      const SimplifyOptions o{.target_ratio = 0.001, .max_error_rel = budget};
      const SimplifyResult r = collapse::run_edge_collapse(*input, o, {}, nullptr, &guard);
      ASSERT_EQ(bounds.size(), r.mesh.triangle_count()) << budget;
      ASSERT_LT(r.mesh.triangle_count(), input->triangle_count()) << budget;
      const std::vector<std::uint32_t> idx = triangle_vertex_indices(r.mesh);
      double worst = 0;  // the largest measured distance over its bound
      std::vector<double> sorted = bounds;
      std::sort(sorted.begin(), sorted.end());
      for (std::size_t t = 0; t < bounds.size(); ++t) {
        const Vec3d a = to_double(r.mesh.positions[idx[3 * t]]), b = to_double(r.mesh.positions[idx[3 * t + 1]]),
                    c = to_double(r.mesh.positions[idx[3 * t + 2]]);
        constexpr int n = 8;
        for (int i = 0; i <= n; ++i) {
          for (int j = 0; i + j <= n; ++j) {
            const Vec3d p = a + (b - a) * (double(i) / n) + (c - a) * (double(j) / n);
            worst = std::max(worst, bvh.closest_point(p).distance() / bounds[t]);
          }
        }
      }
      EXPECT_LE(worst, 1.0) << "a point farther than its triangle's bound; budget " << budget;
      EXPECT_GT(worst, 0.1) << "bounds far above every distance; budget " << budget;
      // Tight enough to report: most triangles within a few budgets (sample reach + grid cover).
      EXPECT_LE(sorted[sorted.size() / 2], 3.0 * budget * diag) << budget;
      EXPECT_GT(sorted.back(), 0.0);
    }
  }
}

// A big reference triangle and an output that covers it only around its corners and its centroid, in its
// plane: every sample the screen takes (both ways) is at distance 0, and the reference's points between them
// are far from the output. The reverse bound finds them.
Mesh patch_around(const Vec3f& c, float r) {
  Mesh m;
  for (const Vec3f& p : {Vec3f{{c[0] - r, c[1] - r, 0}}, Vec3f{{c[0] + r, c[1] - r, 0}}, Vec3f{{c[0], c[1] + r, 0}}}) {
    m.add_vertex_with_wedge(p);
  }
  m.add_face({0, 1, 2});
  return m;
}

Mesh merged(const std::vector<Mesh>& parts) {
  Mesh out;
  for (const Mesh& part : parts) {
    const std::uint32_t base = static_cast<std::uint32_t>(out.vertex_count());
    for (const Vec3f& p : part.positions) out.add_vertex_with_wedge(p);
    const std::vector<std::uint32_t> idx = triangle_vertex_indices(part);
    for (std::size_t k = 0; k < idx.size(); k += 3) out.add_face({base + idx[k], base + idx[k + 1], base + idx[k + 2]});
  }
  return out;
}

TEST(ErrorBudget, AReferencePointBetweenItsSamplesIsMeasured) {
  Mesh big;
  for (const Vec3f& p : {Vec3f{{0, 0, 0}}, Vec3f{{30, 0, 0}}, Vec3f{{0, 30, 0}}}) big.add_vertex_with_wedge(p);
  big.add_face({0, 1, 2});
  const SurfaceIndex reference(big);
  const double budget = 1.0;
  // Patches around the corners and the centroid, clipped to the triangle's plane.
  const Mesh gapped = merged({patch_around({{0.3f, 0.3f, 0}}, 0.3f), patch_around({{29.4f, 0.3f, 0}}, 0.3f),
                              patch_around({{0.3f, 29.4f, 0}}, 0.3f), patch_around({{10, 10, 0}}, 0.3f)});
  const BudgetCheck check = collapse::measure_budget(gapped, reference, budget, 1);
  EXPECT_FALSE(check.within) << "the reference's points between the patches are up to ~7 from the output";
  // The reference itself, as four triangles: within, and both bounds under the budget.
  Mesh split;
  for (const Vec3f& p : {Vec3f{{0, 0, 0}}, Vec3f{{30, 0, 0}}, Vec3f{{0, 30, 0}}, Vec3f{{15, 0, 0}},
                         Vec3f{{15, 15, 0}}, Vec3f{{0, 15, 0}}}) {
    split.add_vertex_with_wedge(p);
  }
  split.add_face({0, 3, 5});
  split.add_face({3, 1, 4});
  split.add_face({5, 4, 2});
  split.add_face({3, 4, 5});
  const BudgetCheck same = collapse::measure_budget(split, reference, budget, 1);
  EXPECT_TRUE(same.within);
  EXPECT_LE(same.bound_abs, budget);
  EXPECT_LE(same.reverse_bound_abs, budget);
}

// A guarded run whose output the reverse bound rejects is run again, with a lattice on the reference triangles
// it named among the guard's samples, before any back-off. A stand-in engine gives the gapped output while
// its guard has only the reference's own samples, and the reference itself once it has more.
struct RerunProbe {
  static inline std::vector<std::size_t> sample_counts;
  static inline Mesh gapped, whole;
  static SimplifyResult engine(const Mesh& input, const SimplifyOptions&, const CollapsePolicies&,
                               std::vector<collapse::CollapseRecord>* log, const collapse::GuardReference* guard) {
    sample_counts.push_back(guard->samples.size());
    if (log != nullptr) log->clear();
    SimplifyResult r;
    r.triangles_before = input.triangle_count();
    r.mesh = sample_counts.size() == 1 ? gapped : whole;
    r.triangles_after = r.mesh.triangle_count();
    r.stop_reason = StopReason::error_budget;
    return r;
  }
};

TEST(ErrorBudget, AGuardedRunIsRepeatedWithSamplesWhereTheReverseBoundFails) {
  Mesh big;
  for (const Vec3f& p : {Vec3f{{0, 0, 0}}, Vec3f{{30, 0, 0}}, Vec3f{{0, 30, 0}}}) big.add_vertex_with_wedge(p);
  big.add_face({0, 1, 2});
  RerunProbe::gapped = merged({patch_around({{0.3f, 0.3f, 0}}, 0.3f), patch_around({{29.4f, 0.3f, 0}}, 0.3f),
                               patch_around({{0.3f, 29.4f, 0}}, 0.3f), patch_around({{10, 10, 0}}, 0.3f)});
  RerunProbe::whole = big;
  RerunProbe::sample_counts.clear();
  const double diag = compute_bounds(big).diagonal();
  const SimplifyOptions o{.target_ratio = 0.5, .max_error_rel = 1.0 / diag, .threads = 1};
  const SimplifyResult r = collapse::run_within_budget(&RerunProbe::engine, big, o, {});
  ASSERT_EQ(RerunProbe::sample_counts.size(), 2u);
  // The reference's 3 vertices and 1 centroid, then a lattice on its one triangle (about 4 points per budget).
  EXPECT_EQ(RerunProbe::sample_counts[0], 4u);
  EXPECT_GT(RerunProbe::sample_counts[1], 4u + 1000u);
  EXPECT_EQ(r.budget.guard_reruns, 1u);
  EXPECT_TRUE(r.budget.within);
  EXPECT_EQ(r.budget.collapses_undone, 0u);
  EXPECT_EQ(r.budget.prefixes_measured, 2u);
}

// A guard with a dense region tests the new faces there on a fine grid: every point of every such face is then
// within the budget, and so is the bound of each face no longer than the fine grid's cap (64 steps of half a
// budget).
TEST(ErrorBudget, GuardedFacesInADenseRegionAreHeldEverywhere) {
  const Mesh source = triangulated(make_bumpy_sphere(40, 60));
  const double diag = compute_bounds(source).diagonal();
  const TriangleBvh bvh = make_triangle_bvh(source);
  std::vector<Vec3d> samples;
  for (const Vec3f& p : source.positions) samples.push_back(to_double(p));
  const Bounds3 everywhere = bvh.bounds();
  for (const double budget : {0.004, 0.02}) {
    std::vector<double> bounds, plain_bounds;
    collapse::GuardReference guard{.bvh = &bvh,
                                   .samples = samples,
                                   .origins = {},
                                   .start_faces = {},
                                   .budget = budget * diag,
                                   .grid_spacing = 4.0 * budget * diag,
                                   .dense_regions = {},
                                   .face_bounds = &plain_bounds,
                                   .sample_faces = nullptr};
    const SimplifyOptions o{.target_ratio = 0.001, .max_error_rel = budget};
    const SimplifyResult plain = collapse::run_edge_collapse(source, o, {}, nullptr, &guard);
    guard.dense_regions = std::span<const Bounds3>(&everywhere, 1);
    guard.face_bounds = &bounds;
    const SimplifyResult r = collapse::run_edge_collapse(source, o, {}, nullptr, &guard);
    ASSERT_EQ(bounds.size(), r.mesh.triangle_count()) << budget;
    EXPECT_GE(r.mesh.triangle_count(), plain.mesh.triangle_count()) << "a finer test refuses more, never less";
    const std::vector<std::uint32_t> idx = triangle_vertex_indices(r.mesh);
    double worst = 0, worst_bound = 0;
    for (std::size_t t = 0; t < bounds.size(); ++t) {
      const Vec3d a = to_double(r.mesh.positions[idx[3 * t]]), b = to_double(r.mesh.positions[idx[3 * t + 1]]),
                  c = to_double(r.mesh.positions[idx[3 * t + 2]]);
      const double longest = std::max({length(b - a), length(c - b), length(a - c)});
      if (longest <= 32.0 * budget * diag) worst_bound = std::max(worst_bound, bounds[t]);
      constexpr int n = 12;
      for (int i = 0; i <= n; ++i) {
        for (int j = 0; i + j <= n; ++j) {
          const Vec3d p = a + (b - a) * (double(i) / n) + (c - a) * (double(j) / n);
          worst = std::max(worst, bvh.closest_point(p).distance());
        }
      }
    }
    EXPECT_LE(worst, budget * diag) << budget;
    EXPECT_LE(worst_bound, budget * diag) << budget;
    EXPECT_GT(*std::max_element(plain_bounds.begin(), plain_bounds.end()), budget * diag)
        << "without the region, some face's bound is over the budget (else this test shows nothing)";
  }
}

// A guarded run whose output the forward bound rejects (a point of an output face over the budget between
// the face's samples) is run again with a dense region around that face, before any back-off. The reference
// is a square with a round hole; the stand-in engine's first output covers the hole with two big triangles
// whose samples all lie on the reference, and its second, given a region over the hole, is the reference.
struct ForwardRerunProbe {
  static inline std::vector<std::vector<Bounds3>> regions;
  static inline Mesh covering, reference;
  static SimplifyResult engine(const Mesh& input, const SimplifyOptions&, const CollapsePolicies&,
                               std::vector<collapse::CollapseRecord>* log, const collapse::GuardReference* guard) {
    regions.emplace_back(guard->dense_regions.begin(), guard->dense_regions.end());
    if (log != nullptr) log->clear();
    SimplifyResult r;
    r.triangles_before = input.triangle_count();
    r.mesh = guard->dense_regions.empty() ? covering : reference;
    r.triangles_after = r.mesh.triangle_count();
    r.stop_reason = StopReason::error_budget;
    return r;
  }
};

TEST(ErrorBudget, AGuardedRunIsRepeatedWithAFineGridWhereTheForwardBoundFails) {
  // Unit cells of [0, 30]^2, less those wholly within 3 of the hole's centre; the output's grid points (every
  // 5 units along the edges of its triangles), edge midpoints and centroids are at least 3.5 from it.
  const Vec3d hole{{12.5, 12.5, 0}};
  Mesh holed;
  for (int y = 0; y <= 30; ++y) {
    for (int x = 0; x <= 30; ++x) holed.add_vertex_with_wedge(Vec3f{{float(x), float(y), 0}});
  }
  auto at = [](int x, int y) { return static_cast<std::uint32_t>(y * 31 + x); };
  for (int y = 0; y < 30; ++y) {
    for (int x = 0; x < 30; ++x) {
      bool inside = true;
      for (const auto& [dx, dy] : {std::pair{0, 0}, std::pair{1, 0}, std::pair{0, 1}, std::pair{1, 1}}) {
        inside = inside && length(Vec3d{{double(x + dx), double(y + dy), 0}} - hole) < 3.0;
      }
      if (inside) continue;
      holed.add_face({at(x, y), at(x + 1, y), at(x + 1, y + 1)});
      holed.add_face({at(x, y), at(x + 1, y + 1), at(x, y + 1)});
    }
  }
  ASSERT_LT(holed.triangle_count(), 1800u);
  Mesh covering;
  for (const Vec3f& p : {Vec3f{{0, 0, 0}}, Vec3f{{30, 0, 0}}, Vec3f{{30, 30, 0}}, Vec3f{{0, 30, 0}}}) {
    covering.add_vertex_with_wedge(p);
  }
  covering.add_face({0, 1, 3});
  covering.add_face({1, 2, 3});
  ForwardRerunProbe::covering = covering;
  ForwardRerunProbe::reference = holed;
  ForwardRerunProbe::regions.clear();
  const double diag = compute_bounds(holed).diagonal();
  const SimplifyOptions o{.target_ratio = 0.5, .max_error_rel = 1.0 / diag, .threads = 1};
  const SimplifyResult r = collapse::run_within_budget(&ForwardRerunProbe::engine, holed, o, {});
  ASSERT_EQ(ForwardRerunProbe::regions.size(), 2u);
  EXPECT_TRUE(ForwardRerunProbe::regions[0].empty());
  ASSERT_FALSE(ForwardRerunProbe::regions[1].empty());
  const bool covers_hole = std::any_of(ForwardRerunProbe::regions[1].begin(), ForwardRerunProbe::regions[1].end(),
                                       [&](const Bounds3& b) {
                                         for (int k = 0; k < 3; ++k) {
                                           if (hole[k] < b.min[k] || hole[k] > b.max[k]) return false;
                                         }
                                         return true;
                                       });
  EXPECT_TRUE(covers_hole);
  EXPECT_EQ(r.budget.guard_reruns, 1u);
  EXPECT_TRUE(r.budget.within);
  EXPECT_EQ(r.budget.collapses_undone, 0u);
  EXPECT_EQ(r.budget.prefixes_measured, 2u);
}

// The reverse bound of a guarded run takes the reference triangles whose corners the guard kept near one
// output triangle at that triangle's distance, unmeasured: it must still hold every point of the reference.
// Checked on a lattice of 28 points per reference triangle, for each budget case (first LODs and chains).
TEST(ErrorBudget, AGuardedRunsReverseBoundHoldsEveryReferencePoint) {
  const BudgetCases all;
  for (const BudgetCase& c : all.cases) {
    const SimplifyResult r = simplify(*c.input, c.options);
    ASSERT_TRUE(r.budget.within) << c.budget;
    const Mesh& reference = c.options.budget_reference != nullptr ? *c.options.budget_reference : *c.input;
    const TriangleBvh lod = make_triangle_bvh(r.mesh);
    const std::vector<std::uint32_t> idx = triangle_vertex_indices(reference);
    double worst = 0;
    for (std::size_t t = 0; t < idx.size(); t += 3) {
      const Vec3d a = to_double(reference.positions[idx[t]]), b = to_double(reference.positions[idx[t + 1]]),
                  d = to_double(reference.positions[idx[t + 2]]);
      constexpr int n = 6;
      for (int i = 0; i <= n; ++i) {
        for (int j = 0; i + j <= n; ++j) {
          worst = std::max(worst, lod.closest_point(a + (b - a) * (double(i) / n) + (d - a) * (double(j) / n)).distance());
        }
      }
    }
    EXPECT_GE(r.budget.reverse_bound_abs, worst) << c.budget;
    EXPECT_TRUE(std::isfinite(r.budget.reverse_bound_abs)) << c.budget;
  }
}

}  // namespace
}  // namespace lodforge
