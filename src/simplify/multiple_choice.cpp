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
// of (cost, u, v), each step's winner is committed unless one of its endpoints is in the closed ring of a collapse
// already committed this round. That is exactly when its check and evaluation still hold: they read the faces
// around its two endpoints, and a collapse changes only faces that hold one of its own endpoints.
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
// The sampling array is compacted once this share of it is dead faces: a dead sample is a lost choice, and the
// quality of the winner depends on how many live choices a step had.
constexpr double kMaxDeadShare = 0.1;
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

// Counter-based: the sample's random bits are a pure function of (seed, round, step, sample).
std::uint64_t round_key(std::uint64_t seed, std::uint64_t round) { return splitmix64(splitmix64(seed) ^ round); }
std::uint64_t sample_bits(std::uint64_t key, std::uint64_t step, std::uint64_t sample) {
  return splitmix64(key ^ ((step << 16) | sample));
}

// Uniform in [0, n) from 32 random bits, without a division.
std::uint32_t below(std::uint64_t bits32, std::size_t n) { return static_cast<std::uint32_t>((bits32 * n) >> 32); }

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
  std::vector<std::uint32_t> faces;  // alive faces to sample from (and some dead ones), in id order
  for (std::uint32_t f = 0; f < cm.face_slots(); ++f) {
    if (cm.face_alive(f)) faces.push_back(f);
  }
  tbb::enumerable_thread_specific<Scratch> scratch;
  Scratch main_scratch;
  tbb::enumerable_thread_specific<std::vector<Sample>> sample_scratch;
  tbb::enumerable_thread_specific<std::vector<std::uint32_t>> drawn_scratch;
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
    if (static_cast<double>(faces.size()) * (1.0 - kMaxDeadShare) > static_cast<double>(cm.alive_faces()) + 64) {
      std::erase_if(faces, [&](std::uint32_t f) { return !cm.face_alive(f); });
    }
    const std::uint64_t key = round_key(options.seed, round);
    const std::size_t remaining = cm.alive_faces() - target;
    const std::size_t steps =
        std::min(std::clamp<std::size_t>(cm.alive_faces() / kStepDivisor, 1, kMaxSteps), (remaining + 1) / 2);
    winners.assign(steps, Winner{});
    parallel.for_ranges(steps, 4, [&](std::size_t b, std::size_t e) {
      Scratch& s = scratch.local();
      std::vector<Sample>& samples = sample_scratch.local();
      std::vector<std::uint32_t>& drawn = drawn_scratch.local();
      for (std::size_t g = b; g < e; ++g) {
        samples.clear();
        Winner& w = winners[g];
        // The samples are scattered over the mesh: ask for all their faces, then all their vertices, before
        // reading any, so that the cache misses overlap instead of following one another.
        drawn.clear();
        for (std::size_t i = 0; i < k; ++i) {
          const std::uint64_t r = sample_bits(key, g, i);
          const std::uint32_t at = below(r & 0xffffffffu, faces.size());
          __builtin_prefetch(&faces[at]);
          drawn.push_back(at);
          drawn.push_back(static_cast<std::uint32_t>((r >> 32) % 3));
        }
        for (std::size_t i = 0; i < k; ++i) {
          drawn[2 * i] = faces[drawn[2 * i]];
          cm.prefetch_face(drawn[2 * i]);
        }
        for (std::size_t i = 0; i < k; ++i) {
          const std::uint32_t f = drawn[2 * i];
          if (!cm.face_alive(f)) {
            drawn[2 * i] = kInvalidIndex;
            continue;
          }
          const int j = static_cast<int>(drawn[2 * i + 1]);
          cm.prefetch_vertex(cm.face_vertex(f, j));
          cm.prefetch_vertex(cm.face_vertex(f, (j + 1) % 3));
        }
        for (std::size_t i = 0; i < k; ++i) {
          const std::uint32_t f = drawn[2 * i];
          if (f == kInvalidIndex) continue;
          const int j = static_cast<int>(drawn[2 * i + 1]);
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
      if (mark[w.u] == stamp || mark[w.v] == stamp) continue;  // next to a commit: its check may be stale
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
