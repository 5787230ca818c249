// Error budgets held by measurement.
//
// The engines stop on their QEM error, an area-weighted RMS distance to the planes a vertex absorbed. That
// ranks collapses well but bounds nothing: at the QEM's stop the measured Hausdorff distance is typically 2-15
// times the budget (docs/budgets.md has the figures). So with a budget the engine runs with a collapse log,
// and its output is measured against the reference surface:
//   output → reference   certified upper bound (eval/distance_bound.hpp), which must be within the budget;
//   reference → output   sampled at the reference's vertices and triangle centroids.
// When either exceeds the budget, prefixes of the same collapse sequence are replayed on a fresh working mesh
// and measured, by bisection: the longest prefix found whose measurement holds is the output. (The distance is
// not monotone along the sequence, so this is a prefix that holds, not always the longest one.)
#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <utility>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>
#include <tbb/task_arena.h>

#include "engines.hpp"
#include "lodforge/eval/distance_bound.hpp"

namespace lodforge::collapse {
namespace {

// The bound stops refining once it is within this fraction of the largest distance measured; near the budget
// it refines down to the finer tolerance that decides.
constexpr double kBoundTolerance = 0.1;
constexpr double kFinestTolerance = 0.002;
// Deciding whether a prefix holds, parts of the LOD whose bound is below this fraction of the budget need no
// refinement: they cannot decide it. Flat parts lying on the input (CAD faces) have distance zero, and a
// Lipschitz bound only reaches zero by splitting without end.
constexpr double kDecisionFraction = 0.9;
// The output's reported bound is refined further, down to this fraction of the budget.
constexpr double kReportFraction = 0.25;
// Closest-point queries allowed per output triangle (plus a base) when deciding a prefix and when refining
// the reported bound: about what the evaluator spends on a LOD.
constexpr std::size_t kDecisionQueries = 4, kReportQueries = 16, kBaseQueries = 50000;
// Bisection stops when the undecided range is at most this fraction of the log (and one collapse at least).
constexpr std::size_t kResolutionDivisor = 128;

struct Measurement {
  bool within = false;
  bool certified = false;  // within by the certified bound (else by the bound's sampled maximum)
  double bound = 0;        // output → reference, an upper bound (+inf when it gave up above the budget)
  double sampled = 0;      // output → reference, the largest distance measured
  double reverse = 0;      // reference → output, sampled
};

// The reference surface, prepared once: its BVH (for the certified bound) and its sample points.
class Reference {
 public:
  Reference(const Mesh& mesh, unsigned threads) : index_(mesh), arena_(threads == 0 ? tbb::task_arena::automatic : static_cast<int>(threads)), threads_(threads) {
    std::vector<char> used(index_.positions.size(), 0);
    for (std::size_t t = 0; t + 2 < index_.indices.size(); t += 3) {
      const Vec3d& a = index_.positions[index_.indices[t]];
      const Vec3d& b = index_.positions[index_.indices[t + 1]];
      const Vec3d& c = index_.positions[index_.indices[t + 2]];
      const Vec3d g = (a + b + c) * (1.0 / 3.0);
      if (!finite3(g)) continue;
      samples_.push_back(g);
      for (std::size_t k = 0; k < 3; ++k) used[index_.indices[t + k]] = 1;
    }
    for (std::size_t v = 0; v < used.size(); ++v) {
      if (used[v]) samples_.push_back(index_.positions[v]);
    }
  }

  // A tighter bound on an output already known to hold (never looser than `known`).
  double tighter_bound(const Mesh& output, double budget, double known) const {
    const DistanceBound b = distance_bound(output, index_,
                                           {.tolerance = kBoundTolerance,
                                            .good_enough = kReportFraction * budget,
                                            .max_queries = kReportQueries * output.triangle_count() + 4 * kBaseQueries,
                                            .threads = threads_});
    return std::min(known, b.upper);
  }

  Measurement measure(const Mesh& output, double budget) {
    Measurement m;
    const std::size_t triangles = output.triangle_count();
    DistanceBoundOptions options{.tolerance = kBoundTolerance,
                                 .good_enough = kDecisionFraction * budget,
                                 .give_up_above = budget,
                                 .max_queries = kDecisionQueries * triangles + kBaseQueries,
                                 .threads = threads_};
    DistanceBound b = distance_bound(output, index_, options);
    if (b.converged && b.upper > budget && b.lower < budget) {
      // Just under the budget: refine until the bound decides (the tolerance that separates them).
      options.tolerance = std::max(kFinestTolerance, 0.5 * (budget / b.lower - 1.0));
      options.max_queries *= 4;
      b = distance_bound(output, index_, options);
    }
    m.bound = b.upper;
    m.sampled = b.lower;
    m.certified = b.converged && b.upper <= budget;
    // Where the refinement could not finish (flat parts on the input), the largest measured distance decides.
    if (b.gave_up || !(m.certified || (!b.converged && b.lower <= budget))) return m;
    const SurfaceIndex lod(output);
    if (lod.empty()) {
      m.reverse = samples_.empty() ? 0.0 : std::numeric_limits<double>::infinity();
    } else {
      // Exact maxima per chunk, combined by max: the same for any thread count.
      m.reverse = arena_.execute([&] {
        return tbb::parallel_reduce(
            tbb::blocked_range<std::size_t>(0, samples_.size(), 1024), 0.0,
            [&](const tbb::blocked_range<std::size_t>& r, double acc) {
              for (std::size_t i = r.begin(); i < r.end(); ++i) {
                acc = std::max(acc, lod.bvh.closest_point(samples_[i]).distance());
              }
              return acc;
            },
            [](double x, double y) { return std::max(x, y); });
      });
    }
    m.within = m.reverse <= budget;
    return m;
  }

 private:
  SurfaceIndex index_;
  std::vector<Vec3d> samples_;
  tbb::task_arena arena_;
  unsigned threads_;
};

}  // namespace

BudgetCheck measure_budget(const Mesh& output, const Mesh& reference_mesh, double budget, unsigned threads) {
  Reference reference(reference_mesh, threads);
  const Measurement m = reference.measure(output, budget);
  BudgetCheck check;
  check.verified = true;
  check.within = m.within;
  check.certified = m.certified;
  check.budget_abs = budget;
  check.bound_abs = m.bound;
  check.sampled_abs = m.sampled;
  check.reverse_abs = m.reverse;
  check.prefixes_measured = 1;
  return check;
}

SimplifyResult run_within_budget(LoggedEngine engine, const Mesh& triangles, const SimplifyOptions& options,
                                 const CollapsePolicies& policies) {
  std::vector<CollapseRecord> log;
  SimplifyResult result = engine(triangles, options, policies, &log);
  const auto t0 = std::chrono::steady_clock::now();
  const Mesh& reference_mesh = options.budget_reference != nullptr ? *options.budget_reference : triangles;
  const StopRule stop = stop_rule(options, triangles.triangle_count(), compute_bounds(triangles).diagonal());
  const double budget = stop.max_error;
  Reference reference(reference_mesh, options.threads);

  BudgetCheck& check = result.budget;
  check.verified = true;
  check.budget_abs = budget;
  Measurement full = reference.measure(result.mesh, budget);
  ++check.prefixes_measured;
  if (!full.within) {
    // Bisection over prefixes [lo, hi): prefix lo holds (the input itself does), prefix hi does not. The
    // working mesh at lo is kept, so each step replays only the collapses between lo and the midpoint.
    Parallel parallel(options.threads);
    SimplifyOptions replay_options = options;
    replay_options.max_error_abs = replay_options.max_error_rel = -1.0;
    std::optional<CollapseMesh> at_lo;
    at_lo.emplace(triangles, replay_options, parallel);
    Scratch scratch;
    std::size_t lo = 0, hi = log.size();
    std::size_t resolution = std::max<std::size_t>(1, log.size() / kResolutionDivisor);
    std::optional<Mesh> best;
    Measurement best_measurement;
    // Replays records [from, to) on `cm`; false if a record no longer applies (it always should).
    auto replay = [&](CollapseMesh& cm, std::size_t from, std::size_t to) {
      for (std::size_t i = from; i < to; ++i) {
        const CollapseRecord& r = log[i];
        while (cm.stage() < r.stage && cm.relax()) {
        }
        Check c = cm.check(r.u, r.v, r.position, scratch);
        if (!c.ok()) return false;
        cm.commit(c, r.position, scratch);
      }
      return true;
    };
    while (hi - lo > resolution) {
      const std::size_t mid = lo + (hi - lo) / 2;
      CollapseMesh trial = *at_lo;
      if (!replay(trial, lo, mid)) {
        hi = mid;
        continue;
      }
      Mesh out = trial.output();
      const Measurement m = reference.measure(out, budget);
      ++check.prefixes_measured;
      if (m.within) {
        lo = mid;
        at_lo.reset();
        at_lo.emplace(std::move(trial));
        best = std::move(out);
        best_measurement = m;
      } else {
        hi = mid;
      }
    }
    if (!best) {  // no prefix but the empty one held: the input as it is (within, unless a reference differs)
      best = at_lo->output();
      best_measurement = reference.measure(*best, budget);
      ++check.prefixes_measured;
    }
    check.collapses_undone = log.size() - lo;
    double qem = 0.0;
    for (std::size_t i = 0; i < lo; ++i) qem = std::max(qem, log[i].error);
    result.mesh = std::move(*best);
    result.triangles_after = at_lo->alive_faces();
    result.collapses = lo;
    result.qem_error_abs = at_lo->model_error(qem);
    result.qem_error_rel = at_lo->diagonal() > 0.0 ? result.qem_error_abs / at_lo->diagonal() : 0.0;
    result.stop_reason = StopReason::error_budget;
    full = best_measurement;
  }
  if (full.within) full.bound = reference.tighter_bound(result.mesh, budget, full.bound);
  check.within = full.within;
  check.certified = full.certified;
  check.sampled_abs = full.sampled;
  check.bound_abs = full.bound;
  check.reverse_abs = full.reverse;
  const double diagonal = compute_bounds(reference_mesh).diagonal();
  result.error_bound_abs = full.bound;
  result.error_bound_rel = diagonal > 0.0 ? full.bound / diagonal : 0.0;
  check.ms = elapsed_ms(t0);
  return result;
}

}  // namespace lodforge::collapse
