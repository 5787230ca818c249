// Greedy quadric edge collapse: the driver.
//
// Papers and sources implemented here:
//  - M. Garland, P. Heckbert, "Surface Simplification Using Quadric Error Metrics", SIGGRAPH 1997: the greedy
//    order (cost, placement and checks are CollapseMesh's).
//  - Independent-set batches as in meshoptimizer's pass structure and Wu & Kobbelt 2002: the batch is chosen
//    sequentially in cost order, so the result does not depend on the thread count.
//
//   run()       collect(); then, until the stop rule holds or nothing is left:
//   collect()   every allowed edge evaluated in parallel and queued (cost buckets of (cost, u, v, version sum);
//               stale entries are skipped when they surface)
//   select()    the cheapest candidates whose closed neighbourhoods are disjoint, in cost order (the
//               neighbourhoods are gathered in parallel)
//   check()     the batch's placements and topology/fold/seam checks, in parallel
//   commit()    in selection order: over-budget candidates dropped, refused ones parked on their endpoints,
//               list space reserved for the rest; then, in parallel, each collapse applied and the edges
//               around its survivor re-evaluated (its closed neighbourhood is its own)
//               With symmetry_weight, a candidate whose mirror image is an edge too is selected with it (the
//               pair at its mean cost); one whose mirror is gone goes back at (1 + weight) times its cost first
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
#include <optional>
#include <string>
#include <unordered_map>
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

// Queue entries superseded by newer ones stay queued until popped; when the queue holds kPurgeFactor times the
// live edge count, drop them all at once (bounds the work of skipping them). Over kPurgeFactorAtLimit times,
// the same once the queue has no free block left, so that its memory stays near its first fill's: a purge
// costs a pass over the queue, so only where it saves memory.
constexpr double kPurgeFactor = 3.0;
constexpr double kPurgeFactorAtLimit = 1.5;

// select(): candidates whose endpoints' stars together exceed this many faces are not gathered ahead in
// parallel; their conflict test looks at the endpoints first (a high-valence vertex is in every neighbouring
// candidate's neighbourhood, and its star would be walked once per such candidate popped).
constexpr std::size_t kLargeStars = 64;

// A candidate goes back into the queue when its symmetric cost (the pair's mean, or its own cost times
// 1 + symmetry_weight) exceeds its queued cost by more than this factor; within it, it is taken as it is.
constexpr double kRekeySlack = 1.01;

// How many candidates ahead the sequential passes of select() and commit() prefetch what they will read.
constexpr std::size_t kLookahead = 8;

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
        mark_(cm_.vertex_count(), 0) {
    if (options.symmetry_weight > 0.0) setup_symmetry(triangles);
  }

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
      while (!stop() || completing()) {
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

  // The target is reached with the mirror halves of last round's overlapping pairs still to go: one more round
  // for those alone (select() takes nothing else once the target is reached), so that the LOD ends symmetric.
  bool completing() const {
    return !pending_.empty() && stop_.reached(cm_.alive_faces()) && !stopped_ && !volume_stop_;
  }

  // Every allowed edge once (u < v), evaluated in parallel over fixed chunks of vertices (not per thread) and
  // queued in chunk order: deterministic.
  void collect() {
    constexpr std::size_t kChunk = 4096, kChunksAtOnce = 16;
    const std::size_t nv = cm_.vertex_count();
    const std::size_t nchunks = (nv + kChunk - 1) / kChunk;
    // A few chunks at a time, their buffers reused: the queue is the only full-size copy of the entries.
    std::vector<std::vector<QueueEntry>> chunks(std::min(nchunks, kChunksAtOnce));
    for (std::size_t first = 0; first < nchunks; first += chunks.size()) {
      const std::size_t n = std::min(chunks.size(), nchunks - first);
      parallel_.for_ranges(n, 1, [&](std::size_t cb, std::size_t ce) {
        Scratch& s = scratch_.local();
        for (std::size_t c = cb; c < ce; ++c) {
          std::vector<QueueEntry>& out = chunks[c];
          out.clear();
          const std::size_t vbegin = (first + c) * kChunk, vend = std::min(nv, vbegin + kChunk);
          out.reserve(3 * (vend - vbegin) + 64);  // about 3 edges per vertex on a closed surface
          for (std::size_t v = vbegin; v < vend; ++v) {
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
      for (std::size_t c = 0; c < n; ++c) {
        for (const QueueEntry& e : chunks[c]) queue_.push(e);
      }
    }
  }

  // Cheapest first; candidates whose closed neighbourhood touches an already selected one are deferred.
  // Candidates are popped a window at a time and their closed neighbourhoods gathered in parallel (the mesh
  // does not change during selection); the conflict tests then run in pop order, and whatever the window
  // popped beyond the end of the selection goes back into the queue, so the batch is the one a one-at-a-time
  // selection makes.
  void select() {
    const std::size_t remaining =
        cm_.alive_faces() > stop_.target_triangles ? cm_.alive_faces() - stop_.target_triangles : 0;
    std::size_t batch = options_.max_batch > 0
                            ? options_.max_batch
                            : std::clamp<std::size_t>(cm_.alive_faces() * 3 / 2 / kBatchDivisor, 1, kMaxBatch);
    batch = std::min(batch, (remaining + 1) / 2);  // an interior collapse removes two triangles

    selected_.clear();
    role_.clear();
    link_.clear();
    deferred_.clear();
    ++stamp_;
    if (!pending_.empty()) take_pending();
    bool full = false;
    auto is_current = [this](const QueueEntry& e) { return current(e); };
    while (!full && selected_.size() < batch) {
      window_.clear();
      // A quarter more than the batch still needs: some will conflict (fewer windows, fewer parallel loops).
      const std::size_t want = std::max<std::size_t>((batch - selected_.size()) * 5 / 4, 32);
      // Popped in runs and then tested for staleness with the version reads prefetched ahead: the same
      // entries in the same order as testing each as it is popped, without a cache miss per pop in between.
      while (window_.size() < want) {
        popped_.clear();
        while (popped_.size() < want - window_.size() && queue_.refill(parallel_, is_current)) {
          popped_.push_back(queue_.top());
          queue_.pop();
        }
        if (popped_.empty()) break;
        for (std::size_t k = 0; k < popped_.size(); ++k) {
          if (k + kLookahead < popped_.size()) {
            cm_.prefetch_version(popped_[k + kLookahead].u());
            cm_.prefetch_version(popped_[k + kLookahead].v);
          }
          if (current(popped_[k])) window_.push_back(popped_[k]);
        }
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
        if (i + kLookahead < nwin) {  // the marks a later candidate will test, while this one is tested
          const std::size_t j = i + kLookahead;
          for (std::size_t k = window_first_[j]; k < window_first_[j + 1]; ++k) {
            __builtin_prefetch(&mark_[closed_ring_[k]]);
          }
        }
        const std::uint32_t* ring_begin = closed_ring_.data() + window_first_[i];
        const std::uint32_t* ring_end = closed_ring_.data() + window_first_[i + 1];
        bool conflict = false;
        if (window_large_[i]) {
          conflict = large_conflict(window_[i].u(), window_[i].v);
        } else {
          for (const std::uint32_t* w = ring_begin; w != ring_end; ++w) conflict |= mark_[*w] == stamp_;
        }
        QueueEntry partner{};
        Pairing pairing = Pairing::single;
        if (!conflict && !mirror_.empty()) {
          pairing = pair_up(window_[i], partner);
          if (pairing == Pairing::requeued) continue;
          // The pair goes in one batch or waits: its mirror must not touch what is claimed already.
          if (pairing == Pairing::pair && claimed(partner)) conflict = true;
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
        role_.push_back(kAlone);
        link_.push_back({});
        if (pairing == Pairing::pair) {
          if (!claimed(partner)) {
            cm_.for_each_closed_ring_vertex(partner.u(), partner.v, [&](std::uint32_t w) { mark_[w] = stamp_; });
            role_.back() = kPairHead;
            selected_.push_back(partner);
            role_.push_back(kAlone);
            link_.push_back({});
          } else {  // its mirror overlaps its own neighbourhood (near the plane): it follows next round
            role_.back() = kLeads;
            link_.back() = {partner.u(), partner.v};
          }
        }
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
        if (evals_[i].error > budget2_) continue;
        const bool own_mirror = plane_ && own_mirror_edge(u, v);
        if (plane_ && ((i > 0 && role_[i - 1] == kPairHead) || role_[i] == kCompletes || own_mirror)) {
          // The second of a pair goes to the mirror image of the first's place where that passes its checks,
          // so that the pair stays a mirror image in spite of the sides' small differences; the second half of
          // three vertices merged across the plane goes onto the plane.
          Vec3d x;
          if (own_mirror) {  // an edge that is its own mirror image: its survivor on the plane
            x = onto_plane(evals_[i].position);
          } else if (role_[i] == kCompletes) {
            const bool merged = u == link_[i].a || v == link_[i].a;
            x = merged ? onto_plane(evals_[i].position) : plane_->reflect(link_[i].position);
          } else {
            x = plane_->reflect(cm_.evaluate(selected_[i - 1].u(), selected_[i - 1].v, false).position);
          }
          checks_[i] = cm_.check(u, v, x, s);
          if (checks_[i].ok()) {
            evals_[i].position = x;
            continue;
          }
        }
        checks_[i] = cm_.check(u, v, evals_[i].position, s);
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
    total_ = 0;
    std::size_t room = 0;
    for (std::size_t i = 0; i < ns; ++i) {
      if (i + kLookahead < ns && checks_[i + kLookahead].ok()) {
        cm_.prefetch_list(checks_[i + kLookahead].victim);
        cm_.prefetch_list(checks_[i + kLookahead].survivor);
      }
      if (evals_[i].error <= budget2_ && checks_[i].ok()) room += cm_.list_room(checks_[i]);
    }
    cm_.make_room(room);
    for (std::size_t i = 0; i < ns; ++i) {
      if (role_[i] == kPairHead) {  // selected_[i] and selected_[i + 1] mirror each other: both or neither
        const bool a = acceptable(i), b = acceptable(i + 1);
        if (!(a && b)) {
          for (const std::size_t k : {i, i + 1}) {
            if (acceptable(k)) {
              requeue_alone(selected_[k]);
            } else {
              refuse(k);
            }
          }
          ++i;
          continue;
        }
        if (!within_volume(volume_change(i) + volume_change(i + 1))) break;
        accept(i);
        accept(i + 1);
        mirror_collapsed(checks_[i], checks_[i + 1]);
        result_.paired_collapses += 2;
        ++i;
        continue;
      }
      if (!acceptable(i)) {
        refuse(i);
        if (role_[i] == kCompletes) forget_victim(link_[i].b);  // the first half stays alone
        continue;
      }
      if (!within_volume(volume_change(i))) break;
      accept(i);
      if (role_[i] == kLeads) {
        pending_.push_back({link_[i].a, link_[i].b, checks_[i].survivor, checks_[i].victim, evals_[i].position});
      } else if (role_[i] == kCompletes) {
        completed(link_[i].a, link_[i].b, checks_[i]);
        result_.paired_collapses += 2;
      } else if (!mirror_.empty()) {
        collapsed_alone(selected_[i], checks_[i]);
      }
    }
    const std::size_t nsurv = survivors_.size();
    ring_first_.push_back(total_);
    ring_buf_.resize(total_);
    ring_size_.resize(nsurv);
    parked_near_.resize(nsurv);
    fresh_.resize(total_);

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

  // Whether selected candidate i may commit: within the budget, its checks passed, not the last face of a material.
  bool acceptable(std::size_t i) const {
    return evals_[i].error <= budget2_ && checks_[i].ok() && !cm_.removes_last_material(checks_[i]);
  }

  // Candidate i may not commit: counted by why, and parked where a change around it may make it valid.
  void refuse(std::size_t i) {
    if (evals_[i].error > budget2_) {
      over_budget_ = true;  // not parked: its cost only changes when an endpoint does
      ++result_.vetoes[Veto::error_budget];
    } else if (!checks_[i].ok()) {
      parked_.park(selected_[i].u(), selected_[i].v);
      ++result_.vetoes[checks_[i].veto];
      over_budget_ = over_budget_ || checks_[i].veto == Veto::error_budget;  // a guarded budget refused it
    } else {  // removes_last_material: counts only fall, never valid again
      ++result_.vetoes[Veto::seam];
    }
  }

  // The volume candidate i adds (bounding) or removes (occluder); 0 without a volume budget. The
  // neighbourhoods of a batch are disjoint and none is applied yet: the change is exact.
  double volume_change(std::size_t i) const {
    if (!(volume_limit_ < std::numeric_limits<double>::infinity())) return 0.0;
    return volume_sign(options_) * cm_.volume_change(checks_[i].victim, checks_[i].survivor, evals_[i].position);
  }

  // Whether `dv` more fits the volume budget (then it is spent); false stops the run before it is exceeded.
  bool within_volume(double dv) {
    if (!(volume_limit_ < std::numeric_limits<double>::infinity())) return true;
    if (volume_used_ + dv > volume_limit_) {
      volume_stop_ = over_budget_ = true;
      return false;
    }
    volume_used_ += dv;
    return true;
  }

  // Commits selected candidate i: list room, survivor, log and callback (applied in parallel afterwards).
  void accept(std::size_t i) {
    const Check& c = checks_[i];
    ring_first_.push_back(total_);
    total_ += 2 * (cm_.star_size(c.victim) + cm_.star_size(c.survivor) - 2 * c.edge_face_count);
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

  // ---- symmetry -----------------------------------------------------------------------------------------------

  enum class Pairing { single, pair, requeued };

  // A candidate re-queued at its symmetric cost: its version sum then, its own cost, and whether it was sent
  // back because its mirror could not go with it (then it goes alone when it surfaces again).
  struct Rekeyed {
    std::uint32_t vsum = 0;
    float cost = 0;
    bool alone = false;
  };

  void setup_symmetry(const Mesh& triangles) {
    if (options_.vertex_mirror != nullptr) {
      if (options_.vertex_mirror->size() == cm_.vertex_count()) mirror_ = *options_.vertex_mirror;
      for (std::uint32_t& m : mirror_) {
        if (m >= cm_.vertex_count()) m = kInvalidIndex;
      }
      if (const std::optional<symmetry::Plane> plane = symmetry::plane_of_pairs(triangles, mirror_)) use_plane(*plane);
    } else {
      symmetry::SymmetryMap map = symmetry::detect_symmetry(triangles, {.plane = options_.symmetry_plane});
      if (map.found()) {
        mirror_ = std::move(map.vertex_mirror);
        use_plane(map.plane);
      }
    }
  }

  // The plane in the working mesh's normalised coordinates (model = origin + scale × normalised).
  void use_plane(const symmetry::Plane& plane) {
    plane_ = symmetry::Plane{plane.normal, (dot(plane.normal, cm_.model_position(Vec3d{})) + plane.offset) / cm_.scale()};
  }

  Vec3d onto_plane(const Vec3d& x) const { return x - plane_->normal * plane_->signed_distance(x); }

  // Whether (u, v) is its own mirror image: both ends on the plane, or each the other's mirror.
  bool own_mirror_edge(std::uint32_t u, std::uint32_t v) const {
    return mirror_[u] != kInvalidIndex &&
           ((mirror_[u] == u && mirror_[v] == v) || (mirror_[u] == v && mirror_[v] == u));
  }

  static std::uint64_t edge_id(std::uint32_t u, std::uint32_t v) { return (std::uint64_t{u} << 32) | v; }

  // What pair_up() recorded when it re-queued this very entry (same version sum); null if it did not.
  const Rekeyed* settled(const QueueEntry& e) const {
    const auto it = rekeyed_.find(edge_id(e.u(), e.v));
    return it != rekeyed_.end() && it->second.vsum == e.vsum ? &it->second : nullptr;
  }

  // The candidate's own cost: its key, or what it was before pair_up() raised it.
  float own_cost(const QueueEntry& e) const {
    const Rekeyed* tag = settled(e);
    return tag != nullptr ? tag->cost : std::bit_cast<float>(e.bits());
  }

  // Whether the closed neighbourhood of `e` touches what this round has claimed.
  bool claimed(const QueueEntry& e) const {
    bool hit = false;
    cm_.for_each_closed_ring_vertex(e.u(), e.v, [&](std::uint32_t w) { hit |= mark_[w] == stamp_; });
    return hit;
  }

  // How a candidate about to be selected goes: with its mirror image (`partner`) when that is an edge too and
  // the pair's mean cost is the cheaper way, alone when it has no mirror or is its own (on the plane), or back
  // into the queue (once) at the cost of the way it will go, when that is higher than its queued cost.
  Pairing pair_up(const QueueEntry& e, QueueEntry& partner) {
    const std::uint32_t u = e.u(), v = e.v;
    const std::uint32_t mu = mirror_[u], mv = mirror_[v];
    if (mu == kInvalidIndex || mv == kInvalidIndex) return Pairing::single;  // outside the symmetric part
    if (own_mirror_edge(u, v)) return Pairing::single;
    const Rekeyed* tag = settled(e);
    const double cost = own_cost(e);
    double pair_cost = std::numeric_limits<double>::infinity();
    if (!(tag != nullptr && tag->alone) && cm_.adjacent(mu, mv) && cm_.rule(mu, mv) != EdgeRule::forbidden) {
      partner = entry(std::min(mu, mv), std::max(mu, mv));
      pair_cost = 0.5 * (cost + std::bit_cast<float>(partner.bits()));
    }
    const double alone_cost = cost * (1.0 + options_.symmetry_weight);
    const double best = std::min(pair_cost, alone_cost);
    if (tag == nullptr && best > cost * kRekeySlack) {
      rekeyed_[edge_id(u, v)] = {e.vsum, static_cast<float>(cost), false};
      queue_.push(make_entry(cost_bits(best), u, v, e.vsum));
      return Pairing::requeued;
    }
    return pair_cost <= alone_cost ? Pairing::pair : Pairing::single;
  }

  // A paired candidate that may commit while its mirror may not: back into the queue at the cost of going
  // alone.
  void requeue_alone(const QueueEntry& e) {
    const float cost = own_cost(e);
    rekeyed_[edge_id(e.u(), e.v)] = {e.vsum, cost, true};
    queue_.push(make_entry(cost_bits(cost * (1.0 + options_.symmetry_weight)), e.u(), e.v, e.vsum));
  }

  // A mirror pair committed: the survivors mirror each other.
  void mirror_collapsed(const Check& a, const Check& b) {
    mirror_[a.victim] = mirror_[b.victim] = kInvalidIndex;
    mirror_[a.survivor] = b.survivor;
    mirror_[b.survivor] = a.survivor;
  }

  // A collapse made alone: the victim's mirror loses its partner; the survivor of an edge that was its own
  // mirror image lies on the plane.
  void collapsed_alone(const QueueEntry& e, const Check& c) {
    const bool own = own_mirror_edge(e.u(), e.v);
    forget_victim(c.victim);
    if (own) mirror_[c.survivor] = c.survivor;
  }

  void forget_victim(std::uint32_t x) {
    const std::uint32_t m = mirror_[x];
    if (m != kInvalidIndex && m != x && mirror_[m] == x) mirror_[m] = kInvalidIndex;
    mirror_[x] = kInvalidIndex;
  }

  // The second half of a pair that overlapped near the plane committed: `survivor` and `victim` are the
  // first half's. Where both kept the same vertex (three merged into one), it lies on the plane.
  void completed(std::uint32_t survivor, std::uint32_t victim, const Check& c) {
    mirror_[victim] = mirror_[c.victim] = kInvalidIndex;
    if (c.survivor == survivor) {
      mirror_[survivor] = survivor;
    } else {
      mirror_[survivor] = c.survivor;
      mirror_[c.survivor] = survivor;
    }
  }

  // At the start of a round, the mirror halves of last round's overlapping pairs, ahead of everything else (the
  // first half's victim now reads as its survivor). One that is no longer an edge leaves its first half alone.
  void take_pending() {
    std::vector<Pending> keep;
    for (const Pending& p : pending_) {
      std::uint32_t u = p.u == p.victim ? p.survivor : p.u;
      std::uint32_t v = p.v == p.victim ? p.survivor : p.v;
      if (u > v) std::swap(u, v);
      if (u == v || !cm_.adjacent(u, v) || cm_.rule(u, v) == EdgeRule::forbidden) {
        forget_victim(p.victim);
        continue;
      }
      const QueueEntry e = entry(u, v);
      if (claimed(e)) {  // beside another pending half: next round
        keep.push_back(p);
        continue;
      }
      cm_.for_each_closed_ring_vertex(u, v, [&](std::uint32_t w) { mark_[w] = stamp_; });
      selected_.push_back(e);
      role_.push_back(kCompletes);
      link_.push_back({p.survivor, p.victim, p.position});
    }
    pending_.swap(keep);
  }

  // Survivor i's ring into its region of ring_buf_, and a fresh candidate for every allowed edge of it.
  void reevaluate_ring(std::size_t i, Scratch& s) {
    const std::uint32_t sv = survivors_[i];
    cm_.ring(sv, s.ring);
    for (std::uint32_t w : s.ring) cm_.prefetch(w);
    const std::uint32_t base = ring_first_[i];
    ring_size_[i] = static_cast<std::uint32_t>(s.ring.size());
    // Whether release() has anything to look at here (read-only in the parallel phase; release() runs after).
    parked_near_[i] = parked_.any() && (parked_.at(sv) || std::any_of(s.ring.begin(), s.ring.end(),
                                                                       [&](std::uint32_t w) { return parked_.at(w); }));
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
      if (!parked_near_[i]) continue;
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
    const double live = static_cast<double>(cm_.alive_faces() * 3 / 2) + 4096.0;
    const auto queued = static_cast<double>(queue_.size());
    if (queued > kPurgeFactor * live || (queued > kPurgeFactorAtLimit * live && queue_.spare_entries() == 0)) {
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
  std::vector<QueueEntry> selected_, deferred_, window_, popped_;
  // Per selected_: how it relates to its mirror image, and (kLeads) the mirror edge or (kCompletes) the first
  // half's survivor and victim.
  enum Role : std::uint8_t {
    kAlone,      // no mirror to go with (or the second of a pair)
    kPairHead,   // the next selected is its mirror image: they commit together
    kLeads,      // its mirror overlaps its neighbourhood: it goes now, the mirror first thing next round
    kCompletes,  // the mirror half of last round's kLeads
  };
  struct Link {
    std::uint32_t a = kInvalidIndex, b = kInvalidIndex;
    Vec3d position{};  // kCompletes: where the first half put its survivor
  };
  struct Pending {
    std::uint32_t u, v, survivor, victim;  // the mirror edge, and the first half's survivor and victim
    Vec3d position;                        // and where the first half put it
  };
  std::vector<std::uint8_t> role_;
  std::vector<Link> link_;
  std::vector<Pending> pending_;
  std::uint32_t total_ = 0;   // commit(): list room handed out so far
  std::vector<std::size_t> window_first_;
  std::vector<char> window_large_;  // closed neighbourhood over kLargeStars: walked in the sequential pass, when needed
  std::vector<std::uint32_t> closed_ring_;
  std::vector<Evaluation> evals_;
  std::vector<Check> checks_;
  std::vector<std::uint32_t> survivors_, committed_, ring_first_, ring_buf_, ring_size_;
  std::vector<QueueEntry> fresh_;
  std::vector<std::uint8_t> parked_near_;  // per survivor: a candidate is parked on it or on its ring
  std::vector<std::pair<std::uint32_t, std::uint32_t>> released_;

  // Symmetry (empty: off): per vertex its mirror image (itself on the plane, kInvalidIndex: none), kept
  // through the collapses; candidates re-queued at their symmetric cost, by edge.
  std::vector<std::uint32_t> mirror_;
  std::unordered_map<std::uint64_t, Rekeyed> rekeyed_;
  std::optional<symmetry::Plane> plane_;  // normalised coordinates; where known, the pairs' places mirror
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
  cm.store_guard_outputs();
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
