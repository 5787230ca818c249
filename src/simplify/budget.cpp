// Error budgets held by measurement.
//
// The engines stop on their QEM error, an area-weighted RMS distance to the planes a vertex absorbed. That
// ranks collapses well but bounds nothing: at the QEM's stop the measured Hausdorff distance is typically 2-15
// times the budget (docs/budgets.md has the figures). So with a budget the engine runs guarded
// (GuardReference: every collapse must keep the measurement's sample points within the budget), with a
// collapse log, and its output is measured against the reference surface, first by samples both ways (the
// screen: cheap, and it stops at the first point over the budget), then where those pass by a certified upper
// bound on output → reference (eval/distance_bound.hpp). A guarded run passes the samples by construction;
// where the bound still finds a point over the budget, prefixes of the same collapse sequence are replayed on
// a fresh working mesh by bisection: the longest prefix found whose measurement holds is the output. (The
// distance is not monotone along the sequence, so this is a prefix that holds, not always the longest one.)
#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <chrono>
#include <cmath>
#include <iterator>
#include <limits>
#include <mutex>
#include <optional>
#include <span>
#include <unordered_set>
#include <utility>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
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
// Parts of the LOD whose bound is below this fraction of the budget need no refinement: they cannot decide
// it, and the reported bound is close enough. Flat parts lying on the input (CAD faces) have distance zero,
// and a Lipschitz bound only reaches zero by splitting without end.
constexpr double kGoodEnough = 0.5;
// Output → reference settles any part bounded within the budget, however far above the distances measured
// there: the reported bound is the proof of the decision, and refining it further (down to kBoundTolerance)
// cost a third of that bound's queries on coarse LODs. Reference → output gains little from it (its
// threshold, kReverseTolerance, is already its ceiling) and keeps its tighter report.
// Closest-point queries allowed per triangle measured (plus a base) when bounding a prefix. Output → reference
// on a guarded LOD rarely converges (the guard holds every face near 0.7 of the budget, and a Lipschitz bound
// gets there only by splitting without end), so its allowance buys only a tighter reported bound; reference
// → output decides and usually converges.
constexpr std::size_t kForwardQueriesPerTriangle = 4, kReverseQueriesPerTriangle = 16, kBaseQueries = 50000;
// Output triangles are sampled on a grid of this spacing, in budgets (at most kMaxGrid steps per edge).
constexpr double kGridSpacing = 4.0;
// Searches deciding their steps by the screen before every step is measured in full.
constexpr int kScreenedSearches = 3;
// Bisection stops when the undecided range is at most this fraction of the log or of the triangles left (and
// one collapse at least).
constexpr std::size_t kResolutionDivisor = 128;
// Where the reverse bound finds reference triangles with a point over the budget, a guarded run is repeated
// (at most this often) with a lattice of this spacing (in budgets, at most kMaxLatticeSteps per edge) on each
// of them added to the guard's samples.
constexpr std::size_t kGuardReruns = 2;
// Reference → output is held to the budget at the reference's vertices and centroids (the guard's samples,
// the screen's) and certified to this multiple of it everywhere: between those samples the distance may rise
// where a long reference triangle passes over a concave crease of the output, and holding every point of it
// to the budget would take a lattice on every long triangle (tens of points per triangle at small budgets).
constexpr double kReverseTolerance = 1.1;
constexpr double kLatticeSpacing = 0.25;
constexpr int kMaxLatticeSteps = 64;

// Appends a lattice of points about `spacing` apart over triangle t of `s`, corners included.
void append_lattice(const SurfaceIndex& s, std::uint32_t t, double spacing, std::vector<Vec3d>& out) {
  const Vec3d& a = s.positions[s.indices[3 * std::size_t{t}]];
  const Vec3d& b = s.positions[s.indices[3 * std::size_t{t} + 1]];
  const Vec3d& c = s.positions[s.indices[3 * std::size_t{t} + 2]];
  const double longest = std::sqrt(std::max({dot(b - a, b - a), dot(c - b, c - b), dot(a - c, a - c)}));
  const int steps = std::clamp(static_cast<int>(std::ceil(longest / spacing)), 1, kMaxLatticeSteps);
  for (int i = 0; i <= steps; ++i) {
    for (int j = 0; i + j <= steps; ++j) {
      const double u = double(i) / steps, v = double(j) / steps;
      out.push_back(a + (b - a) * u + (c - a) * v);
    }
  }
}

struct Measurement {
  bool within = false;
  bool certified = false;  // output → reference held by the certified bound (else by its sampled maximum)
  double bound = 0;        // output → reference, an upper bound (+inf when not computed or over the budget)
  double sampled = 0;      // output → reference, the largest distance measured
  // reference → output, the largest distance measured by samples or the bound's lower end (+inf when a sample
  // exceeded the budget)
  double reverse = 0;
  double reverse_bound = 0;  // reference → output, an upper bound (+inf when not computed or over the budget)
  std::vector<char> on_target;          // per output triangle: a reference triangle bit for bit (distance 0)
  std::vector<char> reference_on_output;  // per reference triangle: an output triangle bit for bit
  std::vector<std::uint32_t> reverse_over;  // reference triangles with a point found over the budget
  // Boxes around the output triangles found with a point over the budget, a budget wider on every side.
  std::vector<Bounds3> forward_over;
};

// Sampled points visited coarse to fine: every 64th, then every 8th, then the rest, each pass in order (the BVH
// walks stay local). A budget that fails usually fails somewhere broad, so the first passes find it.
constexpr std::size_t kPassStrides[] = {64, 8, 1};

// The largest of distance(i) over the points i < n that pass `pass` visits, and `floor`; stops early, setting
// `over`, once one exceeds `limit`. distance(i, hint, known) may return `known` (the largest found so far)
// for a point it finds no farther. The value is the same for any thread count (exact maxima per chunk,
// combined by max).
template <typename Distance>
double pass_max(tbb::task_arena& arena, std::size_t pass, std::size_t n, double limit, double floor,
                std::atomic<bool>& over, Distance&& distance) {
  const std::size_t stride = kPassStrides[pass];
  const std::size_t coarser = pass == 0 ? 0 : kPassStrides[pass - 1];
  return arena.execute([&] {
    return tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, (n + stride - 1) / stride, std::max<std::size_t>(1, 1024 / stride)), 0.0,
        [&](const tbb::blocked_range<std::size_t>& r, double acc) {
          if (over.load(std::memory_order_relaxed)) return acc;
          acc = std::max(acc, floor);
          std::uint32_t hint = kInvalidIndex;  // the previous answer: neighbouring points are near each other
          for (std::size_t k = r.begin(); k < r.end(); ++k) {
            const std::size_t i = k * stride;
            if (coarser != 0 && i % coarser == 0) continue;  // measured by a coarser pass
            const double d = distance(i, hint, acc);
            acc = std::max(acc, d);
            if (d > limit) {
              over.store(true, std::memory_order_relaxed);
              break;
            }
          }
          return acc;
        },
        [](double x, double y) { return std::max(x, y); });
  });
}

// Exact positions: a LOD keeps the positions of the vertices it never moved, bit for bit, so a LOD triangle with
// the corners of a reference triangle is that triangle (distance 0 both ways) and needs no measuring.
using PointKey = std::array<std::uint32_t, 3>;
using TriangleKey = std::array<std::uint32_t, 9>;

struct KeyHash {
  template <std::size_t N>
  std::size_t operator()(const std::array<std::uint32_t, N>& key) const {
    std::uint64_t h = 0x9E3779B97F4A7C15ull;
    for (const std::uint32_t x : key) h = (h ^ x) * 0x100000001B3ull ^ (h >> 31);
    return static_cast<std::size_t>(h ^ (h >> 29));
  }
};

PointKey point_key(const Vec3d& p) {
  return {std::bit_cast<std::uint32_t>(static_cast<float>(p[0])), std::bit_cast<std::uint32_t>(static_cast<float>(p[1])),
          std::bit_cast<std::uint32_t>(static_cast<float>(p[2]))};
}

TriangleKey triangle_key(const SurfaceIndex& s, std::size_t t) {
  std::array<PointKey, 3> c = {point_key(s.positions[s.indices[3 * t]]), point_key(s.positions[s.indices[3 * t + 1]]),
                               point_key(s.positions[s.indices[3 * t + 2]])};
  std::sort(c.begin(), c.end());
  TriangleKey key;
  for (std::size_t k = 0; k < 9; ++k) key[k] = c[k / 3][k % 3];
  return key;
}

// A mesh's triangles and vertex positions as exact keys: in order (per triangle, per vertex) and as sets.
struct SurfaceKeys {
  explicit SurfaceKeys(const SurfaceIndex& s) {
    const std::size_t n = s.indices.size() / 3;
    triangle_list.reserve(n);
    triangles.reserve(n);
    for (std::size_t t = 0; t < n; ++t) {
      triangle_list.push_back(triangle_key(s, t));
      triangles.insert(triangle_list.back());
    }
    point_list.reserve(s.positions.size());
    points.reserve(s.positions.size());
    for (const Vec3d& p : s.positions) {
      point_list.push_back(point_key(p));
      points.insert(point_list.back());
    }
  }
  std::vector<TriangleKey> triangle_list;
  std::vector<PointKey> point_list;
  std::unordered_set<TriangleKey, KeyHash> triangles;
  std::unordered_set<PointKey, KeyHash> points;
};

// Sample points of a mesh `s` (its keys `own`) not found exactly in `other`: points of its triangles
// (for_each_face_sample with `spacing`), then its vertices (those of a triangle with finite corners). `on_other` flags the triangles found (in triangle order).
std::vector<Vec3d> samples_not_in(const SurfaceIndex& s, const SurfaceKeys& own, const SurfaceKeys& other,
                                  std::vector<char>& on_other, double spacing = 0.0) {
  std::vector<Vec3d> samples;
  const std::size_t n = s.indices.size() / 3;
  on_other.assign(n, 0);
  std::vector<char> used(s.positions.size(), 0);
  for (std::size_t t = 0; t < n; ++t) {
    const Vec3d& a = s.positions[s.indices[3 * t]];
    const Vec3d& b = s.positions[s.indices[3 * t + 1]];
    const Vec3d& c = s.positions[s.indices[3 * t + 2]];
    const Vec3d g = (a + b + c) * (1.0 / 3.0);
    if (!finite3(g)) continue;
    for (std::size_t k = 0; k < 3; ++k) used[s.indices[3 * t + k]] = 1;
    if (other.triangles.contains(own.triangle_list[t])) {
      on_other[t] = 1;
      continue;
    }
    for_each_face_sample(a, b, c, spacing, [&](const Vec3d& p) {
      samples.push_back(p);
      return true;
    });
  }
  for (std::size_t v = 0; v < used.size(); ++v) {
    if (used[v] && !other.points.contains(own.point_list[v])) samples.push_back(s.positions[v]);
  }
  return samples;
}

// The reference surface, prepared once: its BVH (for the certified bound) and its exact keys.
class Reference {
 public:
  Reference(const SurfaceIndex& index, unsigned threads)
      : index_(index), keys_(index_), arena_(threads == 0 ? tbb::task_arena::automatic : static_cast<int>(threads)),
        threads_(threads) {}

  // Samples both ways, stopping at the first distance over the budget: output vertices and triangle centroids
  // → reference, reference vertices and triangle centroids → output, coarse passes of both first. Points the
  // output shares exactly with the reference are at distance 0 and skipped. Cheap, and decisive wherever the
  // output fails. With `decide_only`, each point asks only whether some triangle is within the budget (about
  // one triangle per point where it is), and the largest distances are not measured (left at 0).
  Measurement screen(const Mesh& output, double budget, bool decide_only = false) {
    return screen(SurfaceIndex(output), budget, decide_only);
  }
  Measurement screen(const SurfaceIndex& lod, double budget, bool decide_only = false) {
    Measurement m;
    const SurfaceKeys lod_keys(lod);
    // The output's triangles are large and may bridge a concavity: sampled on a grid, not only at centroids.
    const std::vector<Vec3d> forward = samples_not_in(lod, lod_keys, keys_, m.on_target, kGridSpacing * budget);
    const std::vector<Vec3d> reverse = samples_not_in(index_, keys_, lod_keys, m.reference_on_output);
    m.bound = m.reverse_bound = std::numeric_limits<double>::infinity();
    if (index_.empty() || lod.empty()) {  // nothing to measure against: only nothing against nothing holds
      m.sampled = forward.empty() ? 0.0 : std::numeric_limits<double>::infinity();
      m.reverse = reverse.empty() ? 0.0 : std::numeric_limits<double>::infinity();
      m.within = m.sampled <= budget && m.reverse <= budget;
      return m;
    }
    std::atomic<bool> over{false};
    // Reference points that were over the budget in an earlier measurement (thin parts collapsed away) usually
    // are again: try them first. Which ones were recorded depends on the threads; only the time does.
    for (const Vec3d& p : suspects_) {
      if (std::uint32_t hint = kInvalidIndex; !lod.bvh.any_within(p, budget, hint)) {
        over.store(true);
        break;
      }
    }
    constexpr double kOver = std::numeric_limits<double>::infinity();
    auto distance_to = [&](const TriangleBvh& bvh, const Vec3d& p, std::uint32_t& hint, double known) {
      if (decide_only) return bvh.any_within(p, budget, hint) ? 0.0 : kOver;
      // A point within the largest distance found so far cannot raise it: only the others are measured.
      if (known > 0 && bvh.any_within(p, known, hint)) return known;
      const BvhHit h = bvh.closest_point(p, hint);
      hint = h.triangle;
      return h.distance();
    };
    for (std::size_t pass = 0; pass < std::size(kPassStrides) && !over.load(); ++pass) {
      m.sampled = pass_max(arena_, pass, forward.size(), budget, m.sampled, over,
                           [&](std::size_t i, std::uint32_t& hint, double known) {
                             return distance_to(index_.bvh, forward[i], hint, known);
                           });
      if (over.load()) break;
      m.reverse = pass_max(arena_, pass, reverse.size(), budget, m.reverse, over,
                           [&](std::size_t i, std::uint32_t& hint, double known) {
                             const double d = distance_to(lod.bvh, reverse[i], hint, known);
                             if (d > budget) suspect(reverse[i]);
                             return d;
                           });
    }
    // Which value stopped it depends on the threads: report only that it was over.
    if (over.load()) m.sampled = m.reverse = std::numeric_limits<double>::infinity();
    m.within = !over.load();
    return m;
  }

  // screen(), then where it passes the certified bounds both ways, each refined until it decides the budget
  // (as far as its query allowance goes) and down to kGoodEnough of it. Output → reference is also the bound
  // reported. Reference → output matters where a long reference triangle passes over a concave crease of
  // the output: its samples (corners, centroid) are near the output, a point between them is not.
  // `face_bounds` (may be null): per output triangle, a bound known already (a guarded run's); `sample_faces`
  // (may be null): per sample of samples(), an output triangle within the budget of it (the guard's).
  Measurement measure(const Mesh& output, double budget, const std::vector<double>* face_bounds = nullptr,
                      const std::vector<std::uint32_t>* sample_faces = nullptr) {
    const SurfaceIndex lod(output);
    Measurement m = screen(lod, budget);
    if (!m.within) return m;
    const Direction forward = bound_direction(lod, index_, budget, &m.on_target, face_bounds, false);
    m.bound = forward.bound;
    m.sampled = std::max(m.sampled, forward.lower);
    m.certified = forward.certified;
    if (!forward.within) {
      for (const std::uint32_t t : forward.over) {
        Bounds3 box;
        for (int k = 0; k < 3; ++k) box.add(lod.positions[lod.indices[3 * std::size_t{t} + k]]);
        for (int k = 0; k < 3; ++k) {
          box.min[k] -= budget;
          box.max[k] += budget;
        }
        m.forward_over.push_back(box);
      }
      m.within = false;
      return m;
    }
    // Listing every reference triangle over the tolerance, so that a rerun of the guard gets them all at once.
    const std::vector<double> known = sample_faces != nullptr ? attached_bounds(lod, *sample_faces) : std::vector<double>();
    Direction reverse = bound_direction(index_, lod, kReverseTolerance * budget, &m.reference_on_output,
                                        known.empty() ? nullptr : &known, true);
    m.reverse_bound = reverse.bound;
    m.reverse = std::max(m.reverse, reverse.lower);
    m.within = reverse.within;
    m.reverse_over = std::move(reverse.over);
    return m;
  }

  const TriangleBvh& bvh() const { return index_.bvh; }
  const SurfaceIndex& index() const { return index_; }
  tbb::task_arena& arena() { return arena_; }
  // The reference's sample points for the reverse direction, the same as screen() takes: the vertices of its
  // triangles with finite corners, then their centroids.
  const std::vector<Vec3d>& samples() {
    if (samples_.empty()) {
      std::vector<char> used(index_.positions.size(), 0);
      std::vector<Vec3d> centroids;
      std::vector<std::uint32_t> centroid_origins;
      for (std::size_t t = 0; 3 * t < index_.indices.size(); ++t) {
        const std::uint32_t* c = &index_.indices[3 * t];
        const Vec3d g = (index_.positions[c[0]] + index_.positions[c[1]] + index_.positions[c[2]]) * (1.0 / 3.0);
        if (!finite3(g)) continue;
        used[c[0]] = used[c[1]] = used[c[2]] = 1;
        centroids.push_back(g);
        centroid_origins.push_back(static_cast<std::uint32_t>(t) | kCentroidOrigin);
      }
      for (std::size_t v = 0; v < used.size(); ++v) {
        if (!used[v]) continue;
        samples_.push_back(index_.positions[v]);
        origins_.push_back(static_cast<std::uint32_t>(v));
      }
      samples_.insert(samples_.end(), centroids.begin(), centroids.end());
      origins_.insert(origins_.end(), centroid_origins.begin(), centroid_origins.end());
    }
    return samples_;
  }
  // Per sample of samples(): its vertex, or its triangle | kCentroidOrigin.
  const std::vector<std::uint32_t>& origins() {
    samples();
    return origins_;
  }

 private:
  struct Direction {
    bool within = false;     // the bound holds the budget, or where it could not converge, its largest measurement
    bool certified = false;  // the bound itself is within the budget
    double bound = 0, lower = 0;
    std::vector<std::uint32_t> over;  // triangles of `from` where a point over the budget was found
  };
  // The certified bound `from` → `to`, refined until it decides the budget where it can.
  // `reverse` (reference → output): decides only, listing every reference triangle over, and takes the known
  // bounds within the budget as they are. Output → reference is also the bound reported.
  Direction bound_direction(const SurfaceIndex& from, const SurfaceIndex& to, double budget,
                            const std::vector<char>* on_target, const std::vector<double>* known,
                            bool reverse) const {
    const std::size_t measured = static_cast<std::size_t>(std::count(on_target->begin(), on_target->end(), 0));
    DistanceBoundOptions options{.tolerance = kBoundTolerance,
                                 .good_enough = kGoodEnough * budget,
                                 .settle_below = reverse ? 0.0 : budget,
                                 .give_up_above = budget,
                                 .list_over = reverse,
                                 .max_queries = (reverse ? kReverseQueriesPerTriangle : kForwardQueriesPerTriangle) * measured +
                                                kBaseQueries,
                                 .threads = threads_,
                                 .on_target = on_target,
                                 .known_upper = known,
                                 .settle_known = reverse};
    DistanceBound b = distance_bound(from, to, options);
    if (b.converged && b.upper > budget && b.lower < budget) {
      // Just under the budget: refine until the bound decides (the tolerance that separates them).
      options.tolerance = std::max(kFinestTolerance, 0.5 * (budget / b.lower - 1.0));
      options.max_queries *= 4;
      b = distance_bound(from, to, options);
    }
    Direction d;
    d.bound = b.upper;
    d.lower = b.lower;
    d.certified = !b.gave_up && b.upper <= budget;
    // Where the refinement could not finish (flat parts on the other surface), the largest measured distance
    // decides.
    d.within = !b.gave_up && (d.certified || (!b.converged && b.lower <= budget));
    d.over = std::move(b.over);
    return d;
  }

  // Per reference triangle, an upper bound on its distance to the output from the output triangles the guard
  // attached its corners and centroid to: the distance to one triangle is convex, so over the reference
  // triangle it is at most its largest at the corners; the smallest such over those triangles (-1: none).
  std::vector<double> attached_bounds(const SurfaceIndex& lod, const std::vector<std::uint32_t>& sample_faces) {
    const std::vector<Vec3d>& smp = samples();
    const std::size_t nt = index_.indices.size() / 3, nf = lod.indices.size() / 3;
    std::vector<double> known(nt, -1.0);
    if (sample_faces.size() < smp.size()) return {};
    std::vector<std::uint32_t> vertex_face(index_.positions.size(), kInvalidIndex), centroid_face(nt, kInvalidIndex);
    for (std::size_t i = 0; i < smp.size(); ++i) {
      const std::uint32_t o = origins_[i], f = sample_faces[i];
      if (f >= nf) continue;
      if (o & kCentroidOrigin) {
        centroid_face[o & ~kCentroidOrigin] = f;
      } else {
        vertex_face[o] = f;
      }
    }
    arena_.execute([&] {
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, nt, 1024), [&](const tbb::blocked_range<std::size_t>& r) {
        for (std::size_t t = r.begin(); t < r.end(); ++t) {
          const std::uint32_t* c = &index_.indices[3 * t];
          const std::array<std::uint32_t, 4> faces{vertex_face[c[0]], vertex_face[c[1]], vertex_face[c[2]], centroid_face[t]};
          double best = std::numeric_limits<double>::infinity();
          for (std::size_t k = 0; k < faces.size(); ++k) {
            const std::uint32_t f = faces[k];
            if (f == kInvalidIndex || std::find(faces.begin(), faces.begin() + k, f) != faces.begin() + k) continue;
            const Vec3d& p = lod.positions[lod.indices[3 * std::size_t{f}]];
            const Vec3d& q = lod.positions[lod.indices[3 * std::size_t{f} + 1]];
            const Vec3d& w = lod.positions[lod.indices[3 * std::size_t{f} + 2]];
            double worst = 0.0;
            for (int j = 0; j < 3 && worst < best; ++j) {
              const Vec3d& x = index_.positions[c[j]];
              worst = std::max(worst, length(x - closest_point_on_triangle(x, p, q, w).point));
            }
            best = std::min(best, worst);
          }
          if (std::isfinite(best)) known[t] = best;
        }
      });
    });
    return known;
  }

  void suspect(const Vec3d& p) {
    const std::lock_guard<std::mutex> lock(suspects_mutex_);
    if (suspects_.size() == kMaxSuspects) suspects_.erase(suspects_.begin());
    suspects_.push_back(p);
  }
  static constexpr std::size_t kMaxSuspects = 64;

  const SurfaceIndex& index_;
  SurfaceKeys keys_;
  std::vector<Vec3d> suspects_;
  std::vector<Vec3d> samples_;
  std::vector<std::uint32_t> origins_;
  std::mutex suspects_mutex_;
  tbb::task_arena arena_;
  unsigned threads_;
};

// Screens the prefixes of one bisection incrementally. A prefix that held leaves, per reference sample, a face
// slot of the working mesh within the budget of it (its witness); all its faces' samples were within. A longer
// prefix then measures only what its extra collapses touched: the samples of the faces they changed (any
// corner collapsed or moved), and the reference samples whose witness they changed or removed. The decision
// is the decide-only screen's, at a fraction of its work; which witness a sample keeps may depend on the
// threads, the decision does not.
class PrefixScreen {
 public:
  PrefixScreen(Reference& reference, double budget) : reference_(reference), budget_(budget) {}

  // The search's start (before any record): measured in full. False if it does not hold.
  bool start(const CollapseMesh& cm, const Mesh& out) {
    const std::vector<std::uint32_t> slots = alive_slots(cm);
    const SurfaceIndex lod(out);
    std::vector<std::uint32_t> all(slots.size());
    for (std::size_t i = 0; i < all.size(); ++i) all[i] = static_cast<std::uint32_t>(i);
    if (!forward_within(lod, all)) return false;
    const std::vector<Vec3d>& points = reference_.samples();
    witness_.assign(points.size(), kInvalidIndex);
    std::vector<std::uint32_t> everyone(points.size());
    for (std::size_t i = 0; i < everyone.size(); ++i) everyone[i] = static_cast<std::uint32_t>(i);
    std::vector<std::uint32_t> found;
    if (!reverse_within(lod.bvh, everyone, found)) return false;
    for (std::size_t k = 0; k < everyone.size(); ++k) witness_[everyone[k]] = slots[found[k]];
    return true;
  }

  // Whether `trial` (the accepted prefix plus `records`, output `out`) holds; accept() then makes it the
  // accepted prefix.
  bool decide(const CollapseMesh& trial, const Mesh& out, std::span<const CollapseRecord> records) {
    pending_.clear();
    touched_.assign(trial.vertex_count(), 0);
    for (const CollapseRecord& r : records) touched_[r.u] = touched_[r.v] = 1;
    auto changed_slot = [&](std::uint32_t f) {
      return !trial.face_alive(f) || touched_[trial.face_vertex(f, 0)] || touched_[trial.face_vertex(f, 1)] ||
             touched_[trial.face_vertex(f, 2)];
    };
    // Output triangle i is the i-th alive slot; the changed ones, as output triangles.
    const std::vector<std::uint32_t> slots = alive_slots(trial);
    std::vector<std::uint32_t> changed;
    for (std::size_t i = 0; i < slots.size(); ++i) {
      if (changed_slot(slots[i])) changed.push_back(static_cast<std::uint32_t>(i));
    }
    SurfaceIndex lod;
    lod.positions.reserve(out.positions.size());
    for (const Vec3f& p : out.positions) lod.positions.push_back(to_double(p));
    lod.indices = triangle_vertex_indices(out);
    if (!forward_within(lod, changed)) return false;
    // Reference samples whose witness changed: first against the changed faces alone (most find one there),
    // then the rest against the whole output.
    std::vector<std::uint32_t> lost;
    for (std::size_t k = 0; k < witness_.size(); ++k) {
      if (witness_[k] == kInvalidIndex || changed_slot(witness_[k])) lost.push_back(static_cast<std::uint32_t>(k));
    }
    if (lost.empty()) return true;
    std::vector<std::uint32_t> changed_indices;
    changed_indices.reserve(3 * changed.size());
    for (const std::uint32_t t : changed) {
      for (int k = 0; k < 3; ++k) changed_indices.push_back(lod.indices[3 * t + k]);
    }
    const TriangleBvh near(lod.positions, changed_indices);
    std::vector<std::uint32_t> found;
    std::vector<std::uint32_t> rest;
    search(near, lost, found, &rest);
    for (std::size_t k = 0; k < lost.size(); ++k) {
      if (found[k] != kInvalidIndex) pending_.push_back({lost[k], slots[changed[found[k]]]});
    }
    if (!rest.empty()) {
      const TriangleBvh whole(lod.positions, lod.indices);
      if (!reverse_within(whole, rest, found)) return false;
      for (std::size_t k = 0; k < rest.size(); ++k) pending_.push_back({rest[k], slots[found[k]]});
    }
    return true;
  }

  void accept() {
    for (const auto& [k, slot] : pending_) witness_[k] = slot;
    pending_.clear();
  }

 private:
  static std::vector<std::uint32_t> alive_slots(const CollapseMesh& cm) {
    std::vector<std::uint32_t> slots;
    slots.reserve(cm.alive_faces());
    for (std::size_t f = 0; f < cm.face_slots(); ++f) {
      if (cm.face_alive(static_cast<std::uint32_t>(f))) slots.push_back(static_cast<std::uint32_t>(f));
    }
    return slots;
  }

  // Whether every sample of the output triangles `triangles` (corners, centroid, grid) is within the budget of
  // the reference.
  bool forward_within(const SurfaceIndex& lod, const std::vector<std::uint32_t>& triangles) {
    const TriangleBvh& target = reference_.bvh();
    const double spacing = kGridSpacing * budget_;
    std::atomic<bool> over{false};
    reference_.arena().execute([&] {
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, triangles.size(), 256), [&](const tbb::blocked_range<std::size_t>& r) {
        std::uint32_t hint = kInvalidIndex;
        auto within = [&](const Vec3d& p) { return target.any_within(p, budget_, hint); };
        for (std::size_t k = r.begin(); k < r.end() && !over.load(std::memory_order_relaxed); ++k) {
          const std::uint32_t* c = &lod.indices[3 * std::size_t{triangles[k]}];
          const Vec3d& a = lod.positions[c[0]];
          const Vec3d& b = lod.positions[c[1]];
          const Vec3d& d = lod.positions[c[2]];
          const Vec3d g = (a + b + d) * (1.0 / 3.0);
          if (!finite3(g)) continue;
          if (!(within(a) && within(b) && within(d) && for_each_face_sample(a, b, d, spacing, within))) {
            over.store(true, std::memory_order_relaxed);
          }
        }
      });
    });
    return !over.load();
  }

  // For each reference sample points[who[k]]: a triangle of `bvh` within the budget in found[k] (kInvalidIndex
  // if none). Without `rest`, stops at the first one with none and returns false; with it, those are listed
  // there instead.
  bool search(const TriangleBvh& bvh, const std::vector<std::uint32_t>& who, std::vector<std::uint32_t>& found,
              std::vector<std::uint32_t>* rest) {
    const std::vector<Vec3d>& points = reference_.samples();
    found.assign(who.size(), kInvalidIndex);
    std::atomic<bool> over{false};
    reference_.arena().execute([&] {
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, who.size(), 1024), [&](const tbb::blocked_range<std::size_t>& r) {
        std::uint32_t hint = kInvalidIndex;
        for (std::size_t k = r.begin(); k < r.end(); ++k) {
          if (over.load(std::memory_order_relaxed)) return;
          if (bvh.any_within(points[who[k]], budget_, hint)) {
            found[k] = hint;
          } else if (rest == nullptr) {
            over.store(true, std::memory_order_relaxed);
          }
        }
      });
    });
    if (rest != nullptr) {
      for (std::size_t k = 0; k < who.size(); ++k) {
        if (found[k] == kInvalidIndex) rest->push_back(who[k]);
      }
    }
    return !over.load();
  }

  bool reverse_within(const TriangleBvh& bvh, const std::vector<std::uint32_t>& who, std::vector<std::uint32_t>& found) {
    return search(bvh, who, found, nullptr);
  }

  Reference& reference_;
  double budget_;
  std::vector<std::uint32_t> witness_;                        // per reference sample: a face slot
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pending_;  // the trial's new witnesses
  std::vector<char> touched_;
};

}  // namespace

const SurfaceIndex& reference_index(const SimplifyOptions& options, const Mesh& reference,
                                    std::optional<SurfaceIndex>& local) {
  if (options.budget_reference_index != nullptr && &reference == options.budget_reference) {
    return *options.budget_reference_index;
  }
  return local.emplace(reference);
}

BudgetCheck measure_budget(const Mesh& output, const SurfaceIndex& reference_index, double budget, unsigned threads) {
  Reference reference(reference_index, threads);
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
                                 const CollapsePolicies& policies, bool incremental_screens, bool guarded,
                                 std::vector<CollapseRecord>* log_out) {
  auto t0 = std::chrono::steady_clock::now();
  const Mesh& reference_mesh = options.budget_reference != nullptr ? *options.budget_reference : triangles;
  const StopRule stop = stop_rule(options, triangles.triangle_count(), compute_bounds(triangles).diagonal());
  const double budget = stop.max_error;
  std::optional<SurfaceIndex> local_index;
  Reference reference(reference_index(options, reference_mesh, local_index), options.threads);
  std::vector<double> face_bounds;
  std::vector<std::uint32_t> sample_faces;
  GuardReference guard{.bvh = &reference.bvh(),
                       .samples = reference.samples(),
                       .origins = &reference_mesh == &triangles ? std::span<const std::uint32_t>(reference.origins())
                                                               : std::span<const std::uint32_t>(),
                       .start_faces = &reference_mesh != &triangles && options.budget_attachments != nullptr
                                          ? std::span<const std::uint32_t>(*options.budget_attachments)
                                          : std::span<const std::uint32_t>(),
                       .budget = budget,
                       .grid_spacing = kGridSpacing * budget,
                       .dense_regions = {},
                       .face_bounds = &face_bounds,
                       .sample_faces = &sample_faces};
  const double setup_ms = elapsed_ms(t0);

  // The guard holds its samples; a reference triangle whose samples pass can still rise over the budget
  // between them (over a concave crease of the output), and so can an output face between its own. Where the
  // bounds find either, the run is repeated, before any back-off, with a fine lattice on those reference
  // triangles among the samples, and a fine grid on the new faces where those output points were.
  std::vector<Vec3d> guard_samples;
  std::vector<std::uint32_t> guard_origins;
  std::vector<Bounds3> dense_regions;
  std::vector<CollapseRecord> log;
  SimplifyResult result;
  Measurement full;
  double rerun_ms = 0.0;
  std::size_t reruns = 0, measured = 0;
  for (;;) {
    const auto run_start = std::chrono::steady_clock::now();
    log.clear();
    result = engine(triangles, options, policies, &log, guarded ? &guard : nullptr);
    if (reruns > 0) rerun_ms += elapsed_ms(run_start);
    if (log_out != nullptr) *log_out = log;
    // Stopped: the engine's output as it is, unmeasured (each measurement is a pass over both surfaces).
    if (result.stop_reason == StopReason::stopped) return result;
    if (options.stop.requested()) {
      result.stop_reason = StopReason::stopped;
      return result;
    }
    t0 = std::chrono::steady_clock::now();
    const bool bounds_known = face_bounds.size() == result.mesh.triangle_count();
    full = reference.measure(result.mesh, budget, bounds_known ? &face_bounds : nullptr,
                             bounds_known ? &sample_faces : nullptr);
    ++measured;
    if (full.within || !guarded || reruns == kGuardReruns) break;
    if (full.reverse_over.empty() && full.forward_over.empty()) break;
    // Output points over the budget lie between the guard's samples of a face: where they were, the rerun
    // tests new faces on a grid fine enough to hold every point.
    dense_regions.insert(dense_regions.end(), full.forward_over.begin(), full.forward_over.end());
    guard.dense_regions = dense_regions;
    if (!full.reverse_over.empty()) {
      if (guard_samples.empty()) {
        guard_samples = reference.samples();
        guard_origins.assign(guard.origins.begin(), guard.origins.end());
      }
      for (const std::uint32_t t : full.reverse_over) {
        append_lattice(reference.index(), t, kLatticeSpacing * budget, guard_samples);
      }
      // Lattice points have no origin: the guard attaches them to their nearest face.
      if (!guard_origins.empty()) guard_origins.resize(guard_samples.size(), kInvalidIndex);
      guard.samples = guard_samples;
      guard.origins = guard_origins;
    }
    ++reruns;
    rerun_ms += elapsed_ms(t0);
  }

  BudgetCheck& check = result.budget;
  check.verified = true;
  check.budget_abs = budget;
  check.guard_reruns = reruns;
  check.prefixes_measured = measured;
  const bool engine_output = full.within;  // else backed off below
  if (!full.within) {
    // Bisection over prefixes [lo, hi): prefix lo holds (the input itself does), prefix hi does not. The
    // working mesh at lo is kept, so each step replays only the collapses between lo and the midpoint. Steps
    // are decided by the screen; the prefix found is then measured in full (the bound), and where that fails
    // the search goes on below it, after a few tries deciding each step in full.
    Parallel parallel(options.threads);
    SimplifyOptions replay_options = options;
    replay_options.max_error_abs = replay_options.max_error_rel = -1.0;
    Scratch scratch;
    std::optional<CollapseMesh> at_lo;
    std::size_t lo = 0, hi = log.size();
    // The undecided range ends at 1/128 of the log, or of the triangles the LOD keeps where that is finer (a
    // small LOD at the end of a long log: one step of the log would remove more triangles than it has).
    auto resolution = [&] {
      const std::size_t kept = at_lo ? at_lo->alive_faces() : triangles.triangle_count();
      return std::max<std::size_t>(1, std::min(log.size(), kept) / kResolutionDivisor);
    };
    std::optional<Mesh> best;
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
    bool stopped = false;
    PrefixScreen prefix(reference, budget);  // screens a search's steps incrementally where its start holds
    for (int attempt = 0;; ++attempt) {
      const bool in_full = attempt >= kScreenedSearches;
      if (!at_lo) at_lo.emplace(triangles, replay_options, parallel);
      const bool incremental = incremental_screens && !in_full && prefix.start(*at_lo, at_lo->output());
      while (hi - lo > resolution()) {
        if (options.stop.requested()) {  // one poll per prefix measured
          stopped = true;
          break;
        }
        const std::size_t mid = lo + (hi - lo) / 2;
        CollapseMesh trial = *at_lo;
        if (!replay(trial, lo, mid)) {
          hi = mid;
          continue;
        }
        Mesh out = trial.output();
        Measurement m;
        if (in_full) {
          m = reference.measure(out, budget);
        } else if (incremental) {
          m.within = prefix.decide(trial, out, std::span(log).subspan(lo, mid - lo));
          ++check.prefixes_screened_incrementally;
        } else {
          m = reference.screen(out, budget, true);
        }
        ++check.prefixes_measured;
        if (m.within) {
          if (incremental) prefix.accept();
          lo = mid;
          at_lo.reset();
          at_lo.emplace(std::move(trial));
          best = std::move(out);
          if (in_full) full = std::move(m);
        } else {
          hi = mid;
        }
      }
      if (stopped) {  // prefix lo, as far as the search got
        if (!best) best = at_lo->output();
        break;
      }
      if (!best) {  // no prefix but the empty one held: the input as it is (within, unless a reference differs)
        best = at_lo->output();
        full = reference.measure(*best, budget);
        ++check.prefixes_measured;
        break;
      }
      if (in_full) break;
      if (options.stop.requested()) {  // before the full measurement of the prefix found
        stopped = true;
        break;
      }
      full = reference.measure(*best, budget);
      ++check.prefixes_measured;
      if (full.within || lo == 0) break;
      // The screen passed but the bound found a point over the budget: search below it.
      hi = lo;
      lo = 0;
      best.reset();
      at_lo.reset();
    }
    check.collapses_undone = log.size() - lo;
    double qem = 0.0;
    for (std::size_t i = 0; i < lo; ++i) qem = std::max(qem, log[i].error);
    result.mesh = std::move(*best);
    result.triangles_after = at_lo->alive_faces();
    result.collapses = lo;
    result.qem_error_abs = at_lo->model_error(qem);
    result.qem_error_rel = at_lo->diagonal() > 0.0 ? result.qem_error_abs / at_lo->diagonal() : 0.0;
    result.stop_reason = stopped ? StopReason::stopped : StopReason::error_budget;
  }
  if (result.stop_reason == StopReason::stopped) {  // the longest prefix found to hold so far, unrefined
    check.within = false;
    check.ms = setup_ms + rerun_ms + elapsed_ms(t0);
    return result;
  }

  if (guarded && engine_output && full.within && face_bounds.size() == result.mesh.triangle_count()) {
    sample_faces.resize(std::min(sample_faces.size(), reference.samples().size()));  // lattice points dropped
    result.reference_attachments = std::move(sample_faces);
  }
  check.within = full.within;
  check.certified = full.certified;
  check.sampled_abs = full.sampled;
  check.bound_abs = full.bound;
  check.reverse_abs = full.reverse;
  check.reverse_bound_abs = full.reverse_bound;
  const double diagonal = compute_bounds(reference_mesh).diagonal();
  result.error_bound_abs = full.bound;
  result.error_bound_rel = diagonal > 0.0 ? full.bound / diagonal : 0.0;
  check.ms = setup_ms + rerun_ms + elapsed_ms(t0);
  return result;
}

}  // namespace lodforge::collapse
