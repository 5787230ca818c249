// Multiple-choice edge collapse.
//
// Papers implemented here:
//  - J. Wu, L. Kobbelt, "Fast Mesh Decimation by Multiple-Choice Techniques", VMV 2002: instead of a global
//    priority queue, each step draws k random candidate edges, evaluates them now and executes the cheapest
//    valid one. No queue, no neighbour updates, costs are never stale.
//  - Garland & Heckbert 1997 for the cost and placement, the link condition of Dey et al. 1999 (both shared
//    with the greedy engine through CollapseMesh).
//
// Parallel rounds: a round runs G steps at once. Each step draws its k samples with a
// counter-based RNG keyed by (seed, round, step, sample), so what is drawn never depends on threads; the steps
// are evaluated and checked in parallel against the mesh as it was at the start of the round; then, in order
// of (cost, u, v), each step's winner is committed unless its neighbourhood touches one already committed this
// round (the check stays valid for disjoint neighbourhoods).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <vector>

#include "engines.hpp"

namespace lodforge::collapse {
namespace {

// Steps per round: a small fraction of the faces, so that the winners rarely conflict and each round still
// gives the cores enough work.
constexpr std::size_t kStepDivisor = 64;
constexpr std::size_t kMaxSteps = 2048;
// Rounds in a row without a single commit before giving up: with random samples "no valid collapse" and
// "over budget" are statistical verdicts.
constexpr int kMaxFailedRounds = 32;

std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

// Counter-based: the sample's random bits are a pure function of its coordinates.
std::uint64_t sample_bits(std::uint64_t seed, std::uint64_t round, std::uint64_t step, std::uint64_t sample) {
  return splitmix64(splitmix64(splitmix64(seed) ^ round) ^ ((step << 16) | sample));
}

struct Winner {
  bool found = false;
  VetoCounts vetoes;         // samples that failed check(), and those over the error budget
  bool over_budget = false;  // some sample was valid-looking but over the error budget
  std::uint32_t u = 0, v = 0;
  Evaluation eval;
  Check check;
};

struct Sample {
  double cost;
  std::uint32_t u, v;
  Evaluation eval;
};

}  // namespace

SimplifyResult run_multiple_choice(const Mesh& triangles, const SimplifyOptions& options,
                                   const CollapsePolicies& policies, std::vector<CollapseRecord>* log,
                                   const GuardReference* guard) {
  SimplifyResult result;
  auto t0 = std::chrono::steady_clock::now();
  Parallel parallel(options.threads);
  CollapseMesh cm(triangles, options, parallel, policies.any() ? &policies : nullptr, guard);
  const StopRule stop = stop_rule(options, triangles.triangle_count(), cm.diagonal());
  const std::size_t target = stop.target_triangles;
  const double budget2 = normalised_budget_squared(stop, cm.scale());
  const auto k = static_cast<std::size_t>(options.multiple_choice_k);
  result.timings.setup_ms = elapsed_ms(t0);

  t0 = std::chrono::steady_clock::now();
  std::vector<std::uint32_t> faces;  // alive faces to sample from; rebuilt when half of it is dead
  auto rebuild_faces = [&] {
    faces.clear();
    for (std::uint32_t f = 0; f < cm.face_slots(); ++f) {
      if (cm.face_alive(f)) faces.push_back(f);
    }
  };
  rebuild_faces();
  tbb::enumerable_thread_specific<Scratch> scratch;
  Scratch main_scratch;
  tbb::enumerable_thread_specific<std::vector<Sample>> sample_scratch;
  std::vector<Winner> winners;
  std::vector<std::uint32_t> order;
  std::vector<std::uint32_t> mark(cm.vertex_count(), 0);
  std::uint32_t stamp = 0;
  double max_error = 0.0;
  int failed_rounds = 0;
  bool over_budget = false;

  auto policy_stop = [&] {
    return policies.stop && policies.stop({.triangles = cm.alive_faces(),
                                           .collapses = result.collapses,
                                           .rounds = result.rounds,
                                           .max_error = cm.model_error(max_error)});
  };
  bool stopped = false;  // options.stop was requested (polled once a round)
  const double volume_limit = collapse::volume_limit(options, cm);
  double volume_used = 0.0;
  bool volume_stop = false;
  for (std::uint64_t round = 0; !stop.reached(cm.alive_faces()) && !volume_stop && !policy_stop(); ++round) {
    if (options.stop.requested()) {
      stopped = true;
      break;
    }
    if (faces.size() > 2 * cm.alive_faces() + 64) rebuild_faces();
    const std::size_t remaining = cm.alive_faces() - target;
    const std::size_t steps =
        std::min(std::clamp<std::size_t>(cm.alive_faces() / kStepDivisor, 1, kMaxSteps), (remaining + 1) / 2);
    winners.assign(steps, Winner{});
    parallel.for_ranges(steps, 4, [&](std::size_t b, std::size_t e) {
      Scratch& s = scratch.local();
      std::vector<Sample>& samples = sample_scratch.local();
      for (std::size_t g = b; g < e; ++g) {
        samples.clear();
        Winner& w = winners[g];
        for (std::size_t i = 0; i < k; ++i) {
          const std::uint64_t r = sample_bits(options.seed, round, g, i);
          const std::uint32_t f = faces[(r & 0xffffffffu) % faces.size()];
          if (!cm.face_alive(f)) continue;
          const int j = static_cast<int>((r >> 32) % 3);
          std::uint32_t u = cm.face_vertex(f, j), v = cm.face_vertex(f, (j + 1) % 3);
          if (u > v) std::swap(u, v);
          if (cm.rule(u, v) == EdgeRule::forbidden) continue;
          const Evaluation ev = cm.evaluate(u, v);
          if (ev.error > budget2) {
            w.over_budget = true;
            ++w.vetoes[Veto::error_budget];
            continue;
          }
          samples.push_back({ev.cost, u, v, ev});
        }
        std::sort(samples.begin(), samples.end(), [](const Sample& x, const Sample& y) {
          return x.cost < y.cost || (x.cost == y.cost && (x.u < y.u || (x.u == y.u && x.v < y.v)));
        });
        // Cheapest valid sample wins (duplicates of a refused edge are refused again, cheaply enough).
        for (const Sample& smp : samples) {
          const Check c = cm.check(smp.u, smp.v, smp.eval.position, s);
          if (!c.ok()) ++w.vetoes[c.veto];
          if (c.veto == Veto::error_budget) w.over_budget = true;  // a guarded budget refused it
          if (c.ok()) {
            w.found = true;
            w.u = smp.u;
            w.v = smp.v;
            w.eval = smp.eval;
            w.check = c;
            break;
          }
        }
      }
    });
    ++result.rounds;

    order.clear();
    bool round_over_budget = false;
    for (std::uint32_t g = 0; g < steps; ++g) {
      if (winners[g].found) order.push_back(g);
      result.vetoes += winners[g].vetoes;
      round_over_budget = round_over_budget || winners[g].over_budget;
    }
    std::sort(order.begin(), order.end(), [&](std::uint32_t x, std::uint32_t y) {
      const Winner& a = winners[x];
      const Winner& b = winners[y];
      if (a.eval.cost != b.eval.cost) return a.eval.cost < b.eval.cost;
      if (a.u != b.u) return a.u < b.u;
      if (a.v != b.v) return a.v < b.v;
      return x < y;
    });
    ++stamp;
    std::size_t committed = 0;
    for (std::uint32_t g : order) {
      if (stop.reached(cm.alive_faces())) break;
      const Winner& w = winners[g];
      bool conflict = false;
      cm.for_each_closed_ring_vertex(w.u, w.v, [&](std::uint32_t x) { conflict = conflict || mark[x] == stamp; });
      if (conflict) continue;
      if (cm.removes_last_material(w.check)) {  // counts only fall: never valid again
        ++result.vetoes[Veto::seam];
        continue;
      }
      if (volume_limit < std::numeric_limits<double>::infinity()) {
        // The round's commits touch disjoint neighbourhoods: the change is that of the checked mesh.
        const double dv = volume_sign(options) * cm.volume_change(w.check.victim, w.check.survivor, w.eval.position);
        if (volume_used + dv > volume_limit) {  // stop before the budget is exceeded
          volume_stop = over_budget = true;
          break;
        }
        volume_used += dv;
      }
      cm.for_each_closed_ring_vertex(w.u, w.v, [&](std::uint32_t x) { mark[x] = stamp; });
      cm.commit(w.check, w.eval.position, main_scratch);
      max_error = std::max(max_error, w.eval.error);
      ++result.collapses;
      if (log != nullptr) log->push_back({w.u, w.v, w.eval.position, w.eval.error, cm.stage()});
      if (policies.on_collapse) {
        policies.on_collapse({.victim = w.check.victim,
                              .survivor = w.check.survivor,
                              .position = cm.model_position(w.eval.position),
                              .error = cm.model_error(w.eval.error),
                              .triangles = cm.alive_faces()});
      }
      ++committed;
    }
    if (committed == 0) {
      over_budget = round_over_budget || volume_stop;
      if (++failed_rounds >= kMaxFailedRounds) {
        // Out of valid collapses (as far as sampling tells) and not stopped by the budget: the next seam stage.
        if (over_budget || !cm.relax()) break;
        result.seam_stage = cm.stage();
        failed_rounds = 0;
      }
    } else {
      failed_rounds = 0;
    }
  }
  result.timings.collapse_ms = elapsed_ms(t0);
  if (!stop.reached(cm.alive_faces())) {
    result.floors = volume_stop   ? std::vector<std::string>{"volume_budget"}
                    : over_budget ? std::vector<std::string>{"error_budget"}
                                  : diagnose_floors(cm, budget2);
  }

  finish_result(cm, max_error, stop, over_budget, result, stopped);
  return result;
}

}  // namespace lodforge::collapse
