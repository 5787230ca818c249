// Greedy quadric edge collapse: the driver.
//
// Papers and sources implemented here:
//  - M. Garland, P. Heckbert, "Surface Simplification Using Quadric Error Metrics", SIGGRAPH 1997: the greedy
//    order (cost, placement and checks are CollapseMesh's).
//  - Independent-set batches as in meshoptimizer's pass structure and Wu & Kobbelt 2002: the batch is chosen
//    sequentially in cost order, so the result does not depend on the thread count.
//
//   run()       collect(); then, until the stop rule holds or nothing is left:
//   collect()   every allowed edge evaluated in parallel and queued (bucketed heap of (cost, u, v, version sum);
//               stale entries are skipped when they surface)
//   select()    the cheapest candidates whose closed neighbourhoods are disjoint, in cost order (the
//               neighbourhoods are gathered in parallel)
//   check()     the batch's placements and topology/fold/seam checks, in parallel
//   commit()    in selection order: over-budget candidates dropped, refused ones parked on their endpoints,
//               list space reserved for the rest; then, in parallel, each collapse applied and the edges
//               around its survivor re-evaluated (its closed neighbourhood is its own)
//   requeue()   the fresh candidates pushed in survivor order
//   release()   candidates parked around the survivors evaluated again and pushed
//   output      compact alive faces, wedges and vertices (finish_result)
// Every parallel step writes per-item outputs; everything that orders (pops, pushes, reservations) is
// sequential, so the output is byte-identical for any thread count.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "candidate_queue.hpp"
#include "engines.hpp"

namespace lodforge::collapse {
namespace {

// Batch sizing (automatic max_batch): at most 1/kBatchDivisor of the live edges (under 1% of the queue) and at
// most kMaxBatch. Measured on the bunny, mean error (% of the diagonal) at 10% / 1%: strictly sequential
// 0.0191 / 0.141; batches of 1/256 (max 512) 0.0191 / 0.138; 1/128 (max 1024) 0.0191 / 0.142; 1/64 (max 2048)
// 0.0192 / 0.143; 1/32 0.0193 / 0.142. Quality is flat, so the larger batches win: fewer rounds, and each
// round gives the cores more to do.
constexpr std::size_t kBatchDivisor = 128;
constexpr std::size_t kMaxBatch = 1024;

// Heap entries superseded by newer ones stay in the heap until popped; when the heap is this many times the
// live edge count, drop them all at once (bounds memory; O(n) rebuild).
constexpr std::size_t kPurgeFactor = 3;

// select(): candidates whose endpoints' stars together exceed this many faces are not gathered ahead in
// parallel; their conflict test looks at the endpoints first (a high-valence vertex is in every neighbouring
// candidate's neighbourhood, and its star would be walked once per such candidate popped).
constexpr std::size_t kLargeStars = 64;

class GreedyEngine {
 public:
  GreedyEngine(const Mesh& triangles, const SimplifyOptions& options, const CollapsePolicies& policies,
               std::vector<CollapseRecord>* log, const GuardReference* guard)
      : options_(options),
        policies_(policies),
        log_(log),
        parallel_(options.threads),
        cm_(triangles, options, parallel_, policies.any() ? &policies : nullptr, guard),
        stop_(stop_rule(options, triangles.triangle_count(), cm_.diagonal())),
        budget2_(normalised_budget_squared(stop_, cm_.scale())),
        parked_(cm_.vertex_count()),
        volume_limit_(volume_limit(options, cm_)),
        mark_(cm_.vertex_count(), 0) {}

  SimplifyResult run(std::chrono::steady_clock::time_point start) {
    result_.timings.setup_ms = elapsed_ms(start);
    auto t0 = std::chrono::steady_clock::now();
    if (options_.stop.requested()) {  // before the first full pass over the edges
      stopped_ = true;
      finish_result(cm_, max_error_, stop_, over_budget_, result_, stopped_);
      return std::move(result_);
    }
    collect();
    result_.timings.initial_costs_ms = elapsed_ms(t0);

    t0 = std::chrono::steady_clock::now();
    for (;;) {
      while (!stop()) {
        select();
        if (selected_.empty()) {
          requeue_deferred();
          break;
        }
        ++result_.rounds;
        check();
        commit();
        requeue();
        release();
        requeue_deferred();
        purge();
      }
      // Out of valid collapses before the target (not stopped by the error budget): the next seam stage, with
      // every edge evaluated again (the queue is empty; what was parked is collected anew).
      if (stop() || over_budget_ || !cm_.relax()) break;
      result_.seam_stage = cm_.stage();
      parked_ = ParkingLot(cm_.vertex_count());
      collect();
    }
    result_.timings.collapse_ms = elapsed_ms(t0);
    // An error budget stops most of its runs short of their (nominal) triangle target: no pass over the edges.
    if (!stop_.reached(cm_.alive_faces()) && !stopped_) {
      result_.floors = volume_stop_  ? std::vector<std::string>{"volume_budget"}
                       : over_budget_ ? std::vector<std::string>{"error_budget"}
                                      : diagnose_floors(cm_, budget2_);
    }
    finish_result(cm_, max_error_, stop_, over_budget_, result_, stopped_);
    return std::move(result_);
  }

 private:
  bool current(const QueueEntry& e) const { return cm_.version(e.u()) + cm_.version(e.v) == e.vsum; }
  QueueEntry entry(std::uint32_t u, std::uint32_t v) const {
    return make_entry(cost_bits(cm_.evaluate(u, v).cost), u, v, cm_.version(u) + cm_.version(v));
  }

  // Whether to stop before the next round: the target, a stop request (one poll a round: a round is a batch of
  // collapses), or the caller's stop policy.
  bool stop() {
    if (stop_.reached(cm_.alive_faces()) || volume_stop_) return true;
    if (options_.stop.requested()) return stopped_ = true;
    return policies_.stop && policies_.stop({.triangles = cm_.alive_faces(),
                                             .collapses = result_.collapses,
                                             .rounds = result_.rounds,
                                             .max_error = cm_.model_error(max_error_)});
  }

  // Every allowed edge once (u < v), evaluated in parallel over fixed chunks of vertices (not per thread) and
  // queued in chunk order: deterministic.
  void collect() {
    constexpr std::size_t kChunk = 4096;
    const std::size_t nv = cm_.vertex_count();
    std::vector<std::vector<QueueEntry>> chunks((nv + kChunk - 1) / kChunk);
    parallel_.for_ranges(chunks.size(), 1, [&](std::size_t cb, std::size_t ce) {
      Scratch& s = scratch_.local();
      for (std::size_t c = cb; c < ce; ++c) {
        std::vector<QueueEntry>& out = chunks[c];
        const std::size_t vend = std::min(nv, (c + 1) * kChunk);
        out.reserve(3 * (vend - c * kChunk) + 64);  // about 3 edges per vertex on a closed surface
        for (std::size_t v = c * kChunk; v < vend; ++v) {
          const auto u = static_cast<std::uint32_t>(v);
          cm_.ring(u, s.ring);
          for (std::uint32_t w : s.ring) cm_.prefetch(w);
          for (std::uint32_t w : s.ring) {
            if (w <= u || cm_.rule(u, w) == EdgeRule::forbidden) continue;
            out.push_back(entry(u, w));
          }
        }
      }
    });
    for (std::vector<QueueEntry>& chunk : chunks) {
      for (const QueueEntry& e : chunk) queue_.push(e);
      std::vector<QueueEntry>().swap(chunk);
    }
  }

  // Cheapest first; candidates whose closed neighbourhood touches an already selected one are deferred.
  // Candidates are popped a window at a time and their closed neighbourhoods gathered in parallel (the mesh
  // does not change during selection); the conflict tests then run in pop order, and whatever the window
  // popped beyond the end of the selection goes back into the queue, so the batch is the one a one-at-a-time
  // selection makes.
  void select() {
    const std::size_t remaining = cm_.alive_faces() - stop_.target_triangles;
    std::size_t batch = options_.max_batch > 0
                            ? options_.max_batch
                            : std::clamp<std::size_t>(cm_.alive_faces() * 3 / 2 / kBatchDivisor, 1, kMaxBatch);
    batch = std::min(batch, (remaining + 1) / 2);  // an interior collapse removes two triangles

    selected_.clear();
    deferred_.clear();
    ++stamp_;
    bool full = false;
    auto is_current = [this](const QueueEntry& e) { return current(e); };
    while (!full && selected_.size() < batch) {
      window_.clear();
      // A quarter more than the batch still needs: some will conflict (fewer windows, fewer parallel loops).
      const std::size_t want = std::max<std::size_t>((batch - selected_.size()) * 5 / 4, 32);
      while (window_.size() < want && queue_.refill(parallel_, is_current)) {
        const QueueEntry e = queue_.top();
        queue_.pop();
        if (current(e)) window_.push_back(e);
      }
      if (window_.empty()) break;
      const std::size_t nwin = window_.size();
      window_first_.resize(nwin + 1);
      window_large_.assign(nwin, 0);
      std::size_t span = 0;
      for (std::size_t i = 0; i < nwin; ++i) {
        window_first_[i] = span;
        const std::size_t stars = std::size_t{cm_.star_size(window_[i].u())} + cm_.star_size(window_[i].v);
        if (stars > kLargeStars) {
          window_large_[i] = 1;
        } else {
          span += 3 * stars;
        }
      }
      window_first_[nwin] = span;
      if (closed_ring_.size() < span) closed_ring_.resize(span);
      parallel_.for_ranges(nwin, 32, [&](std::size_t b, std::size_t e) {
        for (std::size_t i = b; i < e; ++i) {
          if (window_large_[i]) continue;
          if (i + 1 < e) {
            cm_.prefetch_star(window_[i + 1].u());
            cm_.prefetch_star(window_[i + 1].v);
          }
          std::uint32_t* out = &closed_ring_[window_first_[i]];
          cm_.for_each_closed_ring_vertex(window_[i].u(), window_[i].v, [&](std::uint32_t w) { *out++ = w; });
        }
      });
      std::size_t i = 0;
      for (; i < nwin && !full && selected_.size() < batch; ++i) {
        const std::uint32_t* ring_begin = closed_ring_.data() + window_first_[i];
        const std::uint32_t* ring_end = closed_ring_.data() + window_first_[i + 1];
        bool conflict = false;
        if (window_large_[i]) {
          conflict = large_conflict(window_[i].u(), window_[i].v);
        } else {
          for (const std::uint32_t* w = ring_begin; w != ring_end; ++w) conflict |= mark_[*w] == stamp_;
        }
        if (conflict) {
          deferred_.push_back(window_[i]);
          full = deferred_.size() >= 2 * batch;
          continue;
        }
        if (window_large_[i]) {
          cm_.for_each_closed_ring_vertex(window_[i].u(), window_[i].v, [&](std::uint32_t w) { mark_[w] = stamp_; });
        } else {
          for (const std::uint32_t* w = ring_begin; w != ring_end; ++w) mark_[*w] = stamp_;
        }
        selected_.push_back(window_[i]);
      }
      for (; i < nwin; ++i) queue_.push(window_[i]);  // popped beyond the selection: not looked at
    }
  }

  // Whether the closed neighbourhood of (u, v), a large one, touches a claimed vertex: the endpoints first (each
  // lies on its own faces), so that a conflict at a high-valence vertex costs O(1), not a walk of its star.
  bool large_conflict(std::uint32_t u, std::uint32_t v) const {
    for (std::uint32_t w : {u, v}) {
      if (cm_.star_size(w) > 0 && mark_[w] == stamp_) return true;
    }
    bool conflict = false;
    cm_.for_each_closed_ring_vertex(u, v, [&](std::uint32_t w) { conflict |= mark_[w] == stamp_; });
    return conflict;
  }

  // The neighbourhoods are disjoint, so checking before any commit equals checking just before each commit.
  void check() {
    const std::size_t ns = selected_.size();
    evals_.resize(ns);
    checks_.resize(ns);
    parallel_.for_ranges(ns, 8, [&](std::size_t b, std::size_t e) {
      Scratch& s = scratch_.local();
      for (std::size_t i = b; i < e; ++i) {
        const std::uint32_t u = selected_[i].u(), v = selected_[i].v;
        if (i + 1 < e) {
          cm_.prefetch(selected_[i + 1].u());
          cm_.prefetch(selected_[i + 1].v);
        }
        evals_[i] = cm_.evaluate(u, v, /*with_cost=*/false);  // the queue had the cost; here where and how far
        if (evals_[i].error <= budget2_) checks_[i] = cm_.check(u, v, evals_[i].position, s);
      }
    });
  }

  // In selection order, room for the merged face lists is reserved sequentially (it may grow the pool); then
  // the collapses apply in parallel (their neighbourhoods are disjoint), each followed by the re-evaluation of
  // the edges around its survivor: a survivor's ring and the quadrics its edges read lie in its own closed
  // neighbourhood, which no other collapse of the batch touches. Each survivor writes its ring and its fresh
  // candidates into its own region (sized by its merged list: two neighbours per face), so the result is in
  // survivor order whatever the threads do; no edge appears twice.
  void commit() {
    const std::size_t ns = selected_.size();
    survivors_.clear();
    committed_.clear();
    ring_first_.clear();
    std::uint32_t total = 0;
    std::size_t room = 0;
    for (std::size_t i = 0; i < ns; ++i) {
      if (evals_[i].error <= budget2_ && checks_[i].ok()) room += cm_.list_room(checks_[i]);
    }
    cm_.make_room(room);
    for (std::size_t i = 0; i < ns; ++i) {
      if (evals_[i].error > budget2_) {
        over_budget_ = true;  // not parked: its cost only changes when an endpoint does
        ++result_.vetoes[Veto::error_budget];
        continue;
      }
      if (!checks_[i].ok()) {
        parked_.park(selected_[i].u(), selected_[i].v);
        ++result_.vetoes[checks_[i].veto];
        over_budget_ = over_budget_ || checks_[i].veto == Veto::error_budget;  // a guarded budget refused it
        continue;
      }
      if (cm_.removes_last_material(checks_[i])) {  // counts only fall: never valid again
        ++result_.vetoes[Veto::seam];
        continue;
      }
      const Check& c = checks_[i];
      if (volume_limit_ < std::numeric_limits<double>::infinity()) {
        // The neighbourhoods of a batch are disjoint and none is applied yet: the change is exact.
        const double dv = volume_sign(options_) * cm_.volume_change(c.victim, c.survivor, evals_[i].position);
        if (volume_used_ + dv > volume_limit_) {  // stop before the budget is exceeded
          volume_stop_ = over_budget_ = true;
          break;
        }
        volume_used_ += dv;
      }
      ring_first_.push_back(total);
      total += 2 * (cm_.star_size(c.victim) + cm_.star_size(c.survivor) - 2 * c.edge_face_count);
      cm_.reserve(checks_[i]);
      max_error_ = std::max(max_error_, evals_[i].error);
      committed_.push_back(static_cast<std::uint32_t>(i));
      survivors_.push_back(c.survivor);
      ++result_.collapses;
      if (log_ != nullptr) {
        log_->push_back({selected_[i].u(), selected_[i].v, evals_[i].position, evals_[i].error, cm_.stage()});
      }
      if (policies_.on_collapse) {
        policies_.on_collapse({.victim = c.victim,
                               .survivor = c.survivor,
                               .position = cm_.model_position(evals_[i].position),
                               .error = cm_.model_error(evals_[i].error),
                               .triangles = cm_.alive_faces()});
      }
    }
    const std::size_t nsurv = survivors_.size();
    ring_first_.push_back(total);
    ring_buf_.resize(total);
    ring_size_.resize(nsurv);
    fresh_.resize(total);

    parallel_.for_ranges(nsurv, 8, [&](std::size_t b, std::size_t e) {
      Scratch& s = scratch_.local();
      for (std::size_t i = b; i < e; ++i) {
        if (i + 1 < e) {  // the next collapse's records, while this one is applied
          const Check& next = checks_[committed_[i + 1]];
          for (std::uint32_t w : {next.victim, next.survivor}) {
            cm_.prefetch(w);
            cm_.prefetch_star(w);
          }
        }
        cm_.apply(checks_[committed_[i]], evals_[committed_[i]].position, s);
        reevaluate_ring(i, s);
      }
    });
  }

  // Survivor i's ring into its region of ring_buf_, and a fresh candidate for every allowed edge of it.
  void reevaluate_ring(std::size_t i, Scratch& s) {
    const std::uint32_t sv = survivors_[i];
    cm_.ring(sv, s.ring);
    for (std::uint32_t w : s.ring) cm_.prefetch(w);
    const std::uint32_t base = ring_first_[i];
    ring_size_[i] = static_cast<std::uint32_t>(s.ring.size());
    for (std::size_t r = 0; r < s.ring.size(); ++r) {
      const std::uint32_t w = s.ring[r];
      ring_buf_[base + r] = w;
      if (cm_.rule(sv, w) == EdgeRule::forbidden) {
        fresh_[base + r].vsum = kInvalidIndex;
        continue;
      }
      fresh_[base + r] = entry(std::min(sv, w), std::max(sv, w));
    }
  }

  void requeue() {
    for (std::size_t i = 0; i < survivors_.size(); ++i) {
      for (std::uint32_t r = 0; r < ring_size_[i]; ++r) {
        const QueueEntry& e = fresh_[ring_first_[i] + r];
        if (e.vsum != kInvalidIndex) queue_.push(e);
      }
    }
  }

  // Candidates parked anywhere in a survivor's new neighbourhood may have become valid: evaluate them again.
  // Pairs with a survivor endpoint were just re-evaluated by commit().
  void release() {
    if (!parked_.any()) return;
    ++stamp_;
    for (std::uint32_t sv : survivors_) mark_[sv] = stamp_;
    released_.clear();
    for (std::size_t i = 0; i < survivors_.size(); ++i) {
      parked_.release(survivors_[i], released_);
      for (std::uint32_t r = 0; r < ring_size_[i]; ++r) parked_.release(ring_buf_[ring_first_[i] + r], released_);
    }
    std::sort(released_.begin(), released_.end());
    released_.erase(std::unique(released_.begin(), released_.end()), released_.end());
    for (const auto& [u, v] : released_) {
      if (!cm_.alive(u) || !cm_.alive(v) || mark_[u] == stamp_ || mark_[v] == stamp_) continue;
      queue_.push(entry(u, v));
    }
  }

  // Deferred candidates were not looked at: back into the queue as they were.
  void requeue_deferred() {
    for (const QueueEntry& e : deferred_) queue_.push(e);
  }

  // Superseded entries: drop them in one sweep when they dominate the queue.
  void purge() {
    if (queue_.size() > kPurgeFactor * (cm_.alive_faces() * 3 / 2) + 4096) {
      queue_.purge(parallel_, [this](const QueueEntry& e) { return current(e); });
    }
  }

  const SimplifyOptions& options_;
  const CollapsePolicies& policies_;
  std::vector<CollapseRecord>* log_;  // null: no log
  Parallel parallel_;
  CollapseMesh cm_;
  const StopRule stop_;
  const double budget2_;  // the stop rule's budget as Evaluation::error

  SimplifyResult result_;
  CandidateQueue queue_;
  ParkingLot parked_;
  tbb::enumerable_thread_specific<Scratch> scratch_;
  bool over_budget_ = false;
  bool stopped_ = false;    // options_.stop was requested
  const double volume_limit_;  // max_volume_growth in model units³ (+inf: none)
  double volume_used_ = 0.0;   // volume gained (bounding) or lost (occluder) so far
  bool volume_stop_ = false;   // the volume budget stopped the run
  double max_error_ = 0.0;  // largest committed Evaluation::error

  // Per-round buffers, kept across rounds to avoid reallocation.
  std::vector<std::uint32_t> mark_;  // mark_[v] == stamp_: v is in the current round's claimed set
  std::uint32_t stamp_ = 0;
  std::vector<QueueEntry> selected_, deferred_, window_;
  std::vector<std::size_t> window_first_;
  std::vector<char> window_large_;  // closed neighbourhood over kLargeStars: walked in the sequential pass, when needed
  std::vector<std::uint32_t> closed_ring_;
  std::vector<Evaluation> evals_;
  std::vector<Check> checks_;
  std::vector<std::uint32_t> survivors_, committed_, ring_first_, ring_buf_, ring_size_;
  std::vector<QueueEntry> fresh_;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> released_;
};

}  // namespace

// ---- shared by the engines -------------------------------------------------------------------------------------

std::vector<std::string> diagnose_floors(const CollapseMesh& cm, double budget2) {
  std::map<std::string, std::size_t> count;
  Scratch s;
  std::vector<std::uint32_t> ring;
  for (std::uint32_t u = 0; u < cm.vertex_count(); ++u) {
    if (!cm.alive(u) || cm.star_size(u) == 0) continue;
    cm.ring(u, ring);
    for (std::uint32_t w : ring) {
      if (w <= u) continue;
      if (cm.rule(u, w) == EdgeRule::forbidden) {
        ++count[cm.forbidden_reason(u, w)];
        continue;
      }
      const Evaluation ev = cm.evaluate(u, w, /*with_cost=*/false);
      if (ev.error > budget2) {
        ++count["error_budget"];
        continue;
      }
      const Check c = cm.check(u, w, ev.position, s);
      switch (c.veto) {
        case Veto::none: ++count[cm.removes_last_material(c) ? "material_slot" : "topology"]; break;
        case Veto::seam:
          ++count[cm.stage() == SeamStage::strict ? "seams_kept"
                  : cm.stage() < SeamStage::materials ? "materials_kept"
                                                       : "topology"];
          break;
        case Veto::skin: ++count["skin"]; break;
        case Veto::uv_flip: ++count["uv_checks"]; break;
        case Veto::error_budget: ++count["error_budget"]; break;
        default: ++count["topology"]; break;
      }
    }
  }
  std::vector<std::pair<std::size_t, std::string>> order;
  for (const auto& [name, n] : count) order.emplace_back(n, name);
  // The named floors first, most refusals first; topology (link condition, folds) last: every mesh has some.
  std::stable_sort(order.begin(), order.end(), [](const auto& x, const auto& y) {
    const bool tx = x.second == "topology", ty = y.second == "topology";
    return tx != ty ? ty : x.first > y.first;
  });
  std::vector<std::string> out;
  for (const auto& o : order) out.push_back(o.second);
  if (out.empty()) out.push_back("topology");  // no edge left at all
  return out;
}


double volume_limit(const SimplifyOptions& o, const CollapseMesh& cm) {
  if (o.conservative == Conservative::none || !(o.max_volume_growth >= 0.0)) {
    return std::numeric_limits<double>::infinity();
  }
  return o.max_volume_growth * std::abs(cm.input_volume());
}

double volume_sign(const SimplifyOptions& o) { return o.conservative == Conservative::occluder ? -1.0 : 1.0; }

StopRule stop_rule(const SimplifyOptions& o, std::size_t input_triangles, double diagonal) {
  return StopRule::make(input_triangles,
                        {.target_ratio = o.target_ratio,
                         .target_triangles = o.target_triangles,
                         .max_error_abs = o.max_error_abs,
                         .max_error_rel = o.max_error_rel},
                        diagonal);
}

double normalised_budget_squared(const StopRule& stop, double scale) {
  const double b = stop.max_error / scale;
  return b * b;
}

void finish_result(const CollapseMesh& cm, double max_error, const StopRule& stop, bool over_budget,
                   SimplifyResult& result, bool stopped) {
  const auto t0 = std::chrono::steady_clock::now();
  result.mesh = cm.output();
  cm.store_face_bounds();
  result.triangles_after = cm.alive_faces();
  result.qem_error_abs = cm.model_error(max_error);
  result.qem_error_rel = cm.diagonal() > 0.0 ? result.qem_error_abs / cm.diagonal() : 0.0;
  result.stop_reason = stop.reached(cm.alive_faces()) ? StopReason::target_reached
                       : stopped                       ? StopReason::stopped
                       : over_budget                   ? StopReason::error_budget
                                                       : StopReason::no_valid_collapse;
  result.timings.output_ms = elapsed_ms(t0);
}

SimplifyResult run_edge_collapse(const Mesh& triangles, const SimplifyOptions& options,
                                 const CollapsePolicies& policies, std::vector<CollapseRecord>* log,
                                 const GuardReference* guard) {
  const auto start = std::chrono::steady_clock::now();
  GreedyEngine engine(triangles, options, policies, log, guard);
  return engine.run(start);
}

}  // namespace lodforge::collapse
