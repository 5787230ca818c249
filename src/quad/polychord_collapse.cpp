// Sub-polychord collapse: the quad-dominant LOD method A. Mason described in "Quad
// Mesh Simplification in Frostbite" (GDC 2020), built on the polychord collapse of Daniels, Silva, Shepherd &
// Cohen, "Quadrilateral mesh simplification" (SIGGRAPH Asia 2008), with Garland-Heckbert quadrics (1997) for
// cost and placement. The guide-plane re-simplification pass of EA's US patent 10,043,310 is not part of it.
//
// Driver: setup (quadrics, chords) -> queue of per-chord best runs -> pop, weld, re-trace around the touched
// vertices -> output.
#include "lodforge/quad/polychord_collapse.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <queue>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>

#include "lodforge/metric/attribute_quadric.hpp"
#include "lodforge/metric/quadric.hpp"
#include "lodforge/metric/skin.hpp"
#include "lodforge/metric/stop_rule.hpp"
#include "lodforge/quad/polychord.hpp"
#include "lodforge/quad/quad_mesh.hpp"
#include "lodforge/quad/quad_recovery.hpp"
#include "lodforge/quad/surface_fit.hpp"

#include <tbb/task_group.h>

namespace lodforge::quad {
namespace {

// Steps of the collapse loop between polls of PolychordOptions::stop: a clock read per step would cost more
// than the cheap steps (stale entries) it interleaves.
constexpr std::size_t kStopPollSteps = 256;

// conflict[k]: the last rung before k that shares a vertex with rung k, or -1. A run [i, j] is allowed when
// every conflict[k] for k in [i, j] is below i. `last_rung` is scratch indexed by vertex (grown as needed,
// every entry -1 between calls).
void rung_conflicts(const Polychord& p, std::vector<long long>& conflict, std::vector<long long>& last_rung) {
  conflict.assign(p.rungs.size(), -1);
  for (std::size_t k = 0; k < p.rungs.size(); ++k) {
    for (std::uint32_t v : p.rungs[k]) {
      if (v >= last_rung.size()) last_rung.resize(std::size_t{v} + 1, -1);
      conflict[k] = std::max(conflict[k], last_rung[v]);
      last_rung[v] = static_cast<long long>(k);
    }
  }
  for (const auto& r : p.rungs) last_rung[r[0]] = last_rung[r[1]] = -1;
}

// A contiguous run of rungs [first, last] of one chord (all rungs when whole).
struct Candidate {
  std::uint32_t first = 0, last = 0;
  double cost = 0;        // summed island cost plus the triangle penalty (never negative)
  long long removed = 0;  // triangles the collapse removes
  long long left = 0;     // triangles it leaves behind (open ends in quads) minus those it deletes
  double key = 0;         // cost per removed triangle, no better than the worst rung's: lower is better
  double base_key = 0;    // the key before the triangle budget's factor
  bool over_budget = false;  // leaves more triangles than the budget has left (its key carries the penalty)
};

// The queue orders by key, then prefers more removed triangles, then the lower chord id (determinism).
struct Entry {
  double key;
  long long removed;
  std::uint32_t chord, version;
  bool operator>(const Entry& o) const {
    if (key != o.key) return key > o.key;
    if (removed != o.removed) return removed < o.removed;
    return chord > o.chord;
  }
};

// A traced chord and its queue state. After a collapse nearby, a chord goes stale: its trace may be wrong,
// but it keeps its queue entry (with the old key) and is re-traced only when that entry pops (lazy
// invalidation), since most stale chords never reach the top before they change again.
struct Chord {
  enum class State : std::uint8_t { alive, stale, dead };
  Polychord trace;
  State state = State::alive;
  std::uint32_t version = 0;
  bool queued = false;  // an entry with this version is in the queue
  Candidate best;       // what that entry stands for (alive chords)
  // Retry limits after the weld refused a run: the whole chord, then runs of at most max_run rungs.
  bool whole_allowed = true;
  std::size_t max_run = std::numeric_limits<std::size_t>::max();
  // Rungs the weld refused on their own (an attribute seam, a pinched fan, a flip): runs avoid them, so one
  // bad rung does not take the rest of the chord out of play. Halving max_run alone starved the UV-seamed
  // MakeHuman proxy741 of runs (597 seam refusals at 50%): its quad fraction at 25% went from 0.82 to 0.90.
  std::vector<std::uint8_t> blocked;
  // Symmetry: the version whose entry pair_up() sent back into the queue at its symmetric key (kInvalidIndex:
  // none), and whether that was because its mirror could not go with it (then it goes alone next time).
  std::uint32_t rekeyed = kInvalidIndex;
  bool alone = false;
};

// A diagonal collapse candidate: corners `diagonal` and `diagonal + 2` of quad `face`, scored while the face
// had `version`.
struct DiagonalEntry {
  double key;
  std::uint32_t face, diagonal, version;
  bool operator>(const DiagonalEntry& o) const {
    if (key != o.key) return key > o.key;
    if (face != o.face) return face > o.face;
    return diagonal > o.diagonal;
  }
};

// A run's mirror image: rungs [first, last] of `chord` (the same chord where the run is its own image).
struct MirrorRun {
  std::uint32_t chord = kInvalidIndex, first = 0, last = 0;
  bool wraps = false;  // past the start of a closed chord: its lowest and highest index are first and last
  bool covers = false;  // a run of the run's own chord that holds the run and its image (then it is the move)
  std::vector<std::uint32_t> index;  // the image of the run's k-th rung is rung index[k] of `chord` (unless covers)
  std::vector<std::array<std::uint32_t, 2>> rungs;  // those rungs
  long long removed = 0;
  double key = 0;
};

// A run goes back into the queue when its symmetric key (the mean of its and its mirror's, or its own times
// 1 + symmetry_weight) exceeds its queued key by more than this factor; within it, it is taken as it is.
constexpr double kRekeySlack = 1.01;

struct IslandPlan {
  std::vector<std::vector<std::uint32_t>> islands;
  std::vector<Vec3d> positions;
  std::vector<Quadric> quadrics;
  double max_error = 0;  // sqrt(E / area), model units
};

class Engine {
 public:
  Engine(const Mesh& mesh, const PolychordOptions& options, const StopRule& stop)
      : mesh_(mesh), options_(options), stop_(stop), target_(stop.target_triangles), qm_(mesh) {
    for (std::uint32_t v : options.locked_vertices) qm_.lock(v);
    if (mesh.priority.size() == mesh.vertex_count()) {
      for (std::uint32_t v = 0; v < mesh.vertex_count(); ++v) {
        if (mesh.priority[v] >= options.priority_lock) qm_.lock(v);
      }
    }
    if (options.lock_boundary) {
      for (std::uint32_t v = 0; v < qm_.vertex_count(); ++v) {
        if (qm_.on_boundary(v)) qm_.lock(v);
      }
    }
    weld_options_.max_flip_angle_deg = options.max_flip_angle_deg;
    // A small overshoot lets the last collapses be whole runs rather than single rungs that leave triangles.
    slack_ = std::max<long long>(2, static_cast<long long>(target_ / 100));
    // At the target a quad-dominant mesh has about target / 2 faces.
    triangle_budget_ = options.max_triangle_fraction >= 1.0
                           ? kUnlimited
                           : std::llround(options.max_triangle_fraction * static_cast<double>(target_) / 2.0);
    setup_quadrics();
    setup_attributes();
    if (options.symmetry_weight > 0.0) setup_symmetry();
  }

  PolychordResult run();  // collapse(), then the surface fit and the output mesh
  PolychordResult collapse();

 private:
  void setup_quadrics();
  void setup_attributes();
  // Cost of merging rung (a, b) at its best point: surface plus attribute error. A diagonal collapse names its
  // quad (whose corners a and b become one, so their wedges there merge).
  double rung_cost(const std::array<std::uint32_t, 2>& r, std::uint32_t diagonal_quad = kInvalidIndex) const;
  // The attribute error at x of the wedge classes that merging a and b makes (0 without attributes).
  double attribute_cost(std::uint32_t a, std::uint32_t b, std::uint32_t diagonal_quad, const Vec3d& x) const;
  // After a weld: merged wedges' attribute quadrics join, and moved classes take new values.
  void carry_attributes(const WeldResult& w);
  bool skin_allows(const std::vector<std::vector<std::uint32_t>>& islands) const;
  // held_key: the best key among the runs looked at that only the hard triangle budget kept out (+inf: none).
  std::optional<Candidate> best_candidate(const Chord& chord, long long cap, double& held_key) const;
  // How many more triangles runs may leave behind (the triangle budget minus the triangles there are).
  long long triangles_left_allowed() const {
    return triangle_budget_ - static_cast<long long>(qm_.triangle_faces());
  }
  // Past the hard limit, a multiple of the budget, runs that leave triangles are not made at all (until nothing
  // else is left and the budget is raised); between the budget and it they rank over_budget_factor worse.
  long long hard_triangles_left() const {
    if (triangle_budget_ >= kUnlimited) return kUnlimited;
    const long long hard = std::llround(options_.hard_budget_factor * static_cast<double>(triangle_budget_));
    return std::max(0LL, hard - static_cast<long long>(qm_.triangle_faces()));
  }
  IslandPlan plan(const Chord& chord, const Candidate& c) const;
  // Islands of a set of rungs (of one run or of a run and its mirror image).
  IslandPlan plan_rungs(const std::vector<std::array<std::uint32_t, 2>>& rungs) const;
  // (removed, triangles left) of rungs [i, j] of p: see best_candidate().
  std::pair<long long, long long> run_counts(const Polychord& p, std::size_t i, std::size_t j) const;
  // Triangles one run may remove: what is left to the target plus the slack, halved where runs go in mirror
  // pairs (so that a pair does not overshoot).
  long long run_cap() const {
    const long long cap = static_cast<long long>(qm_.triangle_count()) - static_cast<long long>(target_) + slack_;
    return mirror_.empty() ? cap : (cap + 1) / 2;
  }

  // ---- symmetry (options_.symmetry_weight > 0) ----
  enum class Pairing { single, pair, requeued };
  void setup_symmetry();
  // The mirror image of run c of chord `id`, when it is a run too (nullopt otherwise, `outside` set where some
  // rung end has no mirror at all). May re-trace the stale chord holding it (chords_ grows).
  std::optional<MirrorRun> mirror_run(std::uint32_t id, const Candidate& c, bool& outside);
  // How chord `id`'s best run goes: with its mirror image (`mirror`), alone, or back into the queue once at the
  // key of the way it will go.
  Pairing pair_up(std::uint32_t id, MirrorRun& mirror);
  void requeue_alone(std::uint32_t id);
  // Islands that are each other's mirror image get mirrored places: the one holding the popped run's
  // vertices (`own`, sorted) keeps its optimum; an island that is its own image goes onto the plane.
  void mirror_places(IslandPlan& plan, const std::vector<std::uint32_t>& own) const;
  // Per island, the island that is its mirror image (every member's mirror in it, the same size; itself for
  // an island on the plane), or kInvalidIndex.
  std::vector<std::uint32_t> island_images(const std::vector<std::vector<std::uint32_t>>& islands) const;
  // After a weld: survivors of islands that mirror each other mirror each other; every other island vertex
  // and its partner lose their mirror.
  void update_mirror(const std::vector<std::vector<std::uint32_t>>& islands,
                     const std::vector<std::uint32_t>& survivors);
  // The surface fit moves each vertex by its own least-squares step, which mirrored vertices take alike only
  // up to what differs around them: mirrored moved vertices meet halfway (one at the other's mirror image),
  // moved ones on the plane go onto it.
  void symmetrize_fit();
  void place(const std::vector<std::uint32_t>& island, IslandPlan& out) const;
  void push_diagonals(std::uint32_t face);
  // Pops the best diagonal collapse and makes it if still valid.
  void try_diagonal();
  // A candidate's rank: its cost per removed triangle, no better than its worst rung's cost scaled by
  // worst_rung_weight (before any triangle-budget factor). Lower is better.
  double rank(double cost, long long removed, double worst_rung) const {
    const double per_triangle =
        removed > 0 ? cost / static_cast<double>(removed) : std::numeric_limits<double>::infinity();
    return std::max(per_triangle, options_.worst_rung_weight * 0.5 * worst_rung);
  }
  double diagonal_top();  // key of the best live diagonal entry (stale ones dropped), +inf when none
  bool block_failing_rungs(Chord& chord, const Candidate& c);
  // Whether the weld (a dry run) or the skin rule refuses these rungs collapsed as one run.
  bool refused_alone(const std::vector<std::array<std::uint32_t, 2>>& rungs);
  void refuse(std::uint32_t id, const Candidate& c);
  // A run and its mirror image refused together, where at least one half fails alone too: each failing
  // half's failing rungs are blocked (or its whole chord, or its run length halved) and the same is done to
  // the other half's images of them, so that the two sides keep leaving the same rungs out.
  void refuse_pair(std::uint32_t id, const Candidate& c, const MirrorRun& m, bool run_fails, bool mirror_fails);
  void trace_from(std::uint32_t face, int direction);
  void push(std::uint32_t id);
  void mark_stale(std::uint32_t id);
  void retrace(std::uint32_t id);
  void invalidate_around(const WeldResult& w);

  const Mesh& mesh_;
  const PolychordOptions& options_;
  const StopRule stop_;  // the triangle engines' stop rule: target count and error budget
  std::size_t target_;   // stop_.target_triangles
  QuadMesh qm_;
  WeldOptions weld_options_;
  long long slack_ = 2;
  double penalty_ = 0;  // cost of one triangle left behind
  static constexpr long long kUnlimited = std::numeric_limits<long long>::max() / 4;
  long long triangle_budget_ = 0;
  std::vector<Quadric> quadric_;
  // Attribute metric: layout (empty: geometry only), per-wedge Hoppe quadrics (wg_: dims gradients per
  // wedge), and the wedges' values now (copies of the input's, written by carry_attributes()).
  AttributeLayout layout_;
  std::vector<AttributeQuadric> wq_;
  std::vector<AttributeGradient> wg_;
  bool write_values_ = false;
  std::vector<Vec3f> normals_;
  std::vector<std::vector<Vec2f>> uvs_;
  std::vector<std::vector<Vec4f>> colors_;
  std::vector<Chord> chords_;
  std::vector<std::array<std::uint32_t, 2>> face_chord_;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> queue_;
  std::vector<std::uint32_t> face_version_;
  std::vector<std::uint32_t> face_stamp_;  // invalidate_around()'s marks
  std::uint32_t stamp_ = 0;
  std::priority_queue<DiagonalEntry, std::vector<DiagonalEntry>, std::greater<DiagonalEntry>> diagonals_;
  std::size_t diagonal_collapses_ = 0;
  bool diagonals_scored_ = false;  // diagonals_ holds every quad's diagonals (see run())
  // Runs the hard triangle budget holds back, by key (lazy: entries of changed chords are dropped on top).
  std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> held_;
  double held_top();
  double error_bound_ = 0;
  std::size_t collapses_ = 0, rejected_ = 0, over_budget_ = 0;
  struct Scratch {
    std::vector<double> cost, prefix;
    std::vector<std::uint8_t> usable, in_run;
    std::vector<long long> conflict, last_rung;
  };
  mutable Scratch scratch_;  // best_candidate()'s arrays
  TraceScratch trace_scratch_;
  std::vector<std::uint32_t> mirror_;     // per vertex (empty: no symmetry term)
  std::optional<symmetry::Plane> plane_;  // model coordinates, set with mirror_
  std::size_t paired_ = 0;
};

void Engine::setup_quadrics() {
  const std::size_t nv = qm_.vertex_count();
  quadric_.assign(nv, Quadric{});
  double area = 0, edge_sq = 0;
  std::size_t faces = 0, edges = 0;
  for (std::uint32_t f = 0; f < qm_.face_slots(); ++f) {
    const std::uint32_t n = qm_.face_size(f);
    if (n == 0) continue;
    // The face's plane quadric: its fan triangles, added to every corner (GH97 per-face planes).
    Quadric q;
    const Vec3d& p0 = qm_.position(qm_.face_vertex(f, 0));
    for (std::uint32_t i = 1; i + 1 < n; ++i) {
      q += Quadric::from_triangle(p0, qm_.position(qm_.face_vertex(f, i)), qm_.position(qm_.face_vertex(f, i + 1)));
    }
    for (std::uint32_t i = 0; i < n; ++i) quadric_[qm_.face_vertex(f, i)] += q;
    area += q.weight;
    ++faces;
    const Vec3d normal = qm_.face_normal(f);
    for (std::uint32_t i = 0; i < n; ++i) {
      const std::uint32_t a = qm_.face_vertex(f, i), b = qm_.face_vertex(f, (i + 1) % n);
      const Vec3d d = qm_.position(b) - qm_.position(a);
      edge_sq += dot(d, d);
      ++edges;
      if (qm_.across(f, i).kind != QuadMesh::Across::boundary) continue;
      const Quadric border =
          Quadric::from_boundary_edge(qm_.position(a), qm_.position(b), normal, options_.border_weight);
      quadric_[a] += border;
      quadric_[b] += border;
    }
  }
  // Painted priority scales a vertex's whole quadric by its square (as the triangle engine does): a weight acts
  // on distances, so a region painted 10 keeps about a tenth of the error.
  if (mesh_.priority.size() == nv) {
    for (std::size_t v = 0; v < nv; ++v) {
      const double p = mesh_.priority[v];
      if (std::isfinite(p) && p >= 0.0) quadric_[v] *= p * p;
    }
  }
  const double mean_area = faces > 0 ? area / static_cast<double>(faces) : 0.0;
  const double mean_edge_sq = edges > 0 ? edge_sq / static_cast<double>(edges) : 0.0;
  penalty_ = options_.triangle_penalty * mean_area * mean_edge_sq;
}

// Attribute quadrics of every wedge (Hoppe 1999, in the triangle engine's units: metric/attribute_quadric.hpp
// attribute_layout()): each triangle the output draws (a quad split along its shorter diagonal) adds its
// linear attribute functions, weighted by its area times the corner vertex's painted priority squared (as
// the surface quadric), to the wedge at each corner.
void Engine::setup_attributes() {
  const Mesh& m = mesh_;
  const std::size_t nw = m.wedge_count(), nv = m.vertex_count();
  write_values_ = options_.optimal_attributes;
  const bool normals = m.normals.size() == nw && nw > 0;
  std::vector<double> uv_area(m.uvs.size(), 0.0);
  std::vector<std::uint8_t> color_sets(m.colors.size(), 0);
  for (std::size_t set = 0; set < m.colors.size(); ++set) color_sets[set] = m.colors[set].size() == nw && nw > 0;
  bool any = normals;
  for (std::size_t set = 0; set < m.uvs.size(); ++set) any |= m.uvs[set].size() == nw && nw > 0;
  for (std::uint8_t c : color_sets) any |= c != 0;
  if (!any) return;
  // The triangles, as corner offsets, of the faces QuadMesh keeps (in-range indices).
  std::vector<std::array<std::uint32_t, 3>> triangles;
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    if (!face_indices_in_range(m, f)) continue;
    for_each_face_triangle(m, f, [&](std::uint32_t c0, std::uint32_t c1, std::uint32_t c2) {
      triangles.push_back({c0, c1, c2});
    });
  }
  auto point = [&](std::uint32_t c) { return to_double(m.positions[m.corner_vertex(c)]); };
  double area = 0.0;
  std::vector<double> tri_area(triangles.size(), 0.0);
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    const auto& c = triangles[t];
    const Vec3d p0 = point(c[0]);
    const double a = 0.5 * length(cross(point(c[1]) - p0, point(c[2]) - p0));
    if (!std::isfinite(a)) continue;
    tri_area[t] = a;
    area += a;
    for (std::size_t set = 0; set < m.uvs.size(); ++set) {
      if (m.uvs[set].size() != nw) continue;
      const std::vector<Vec2f>& uv = m.uvs[set];
      const double ua = uv_triangle_area(uv[m.corner_wedge[c[0]]], uv[m.corner_wedge[c[1]]], uv[m.corner_wedge[c[2]]]);
      if (std::isfinite(ua)) uv_area[set] += ua;
    }
  }
  const double length_unit = attribute_length_unit(area, triangles.size());
  layout_ = attribute_layout({.normals = normals,
                              .uv_area = uv_area,
                              .color_sets = color_sets,
                              .area = area,
                              .length_unit = length_unit,
                              .normal_weight = options_.normal_weight,
                              .uv_weight = options_.uv_weight,
                              .color_weight = options_.color_weight});
  if (write_values_) {
    if (normals) normals_ = m.normals;
    uvs_ = m.uvs;
    colors_ = m.colors;
  }
  if (layout_.dims == 0) return;
  const auto dims = static_cast<std::size_t>(layout_.dims);
  wq_.assign(nw, {});
  wg_.assign(nw * dims, {});
  std::vector<double> values(3 * dims);
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    if (!(tri_area[t] > 0.0)) continue;
    const auto& c = triangles[t];
    const Vec3d p0 = point(c[0]), p1 = point(c[1]), p2 = point(c[2]);
    for (int k = 0; k < 3; ++k) layout_.scaled(m.normals, m.uvs, m.colors, m.corner_wedge[c[k]], &values[k * dims]);
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t w = m.corner_wedge[c[k]], v = m.wedge_vertex[w];
      double weight = tri_area[t];
      if (m.priority.size() == nv && std::isfinite(m.priority[v]) && m.priority[v] >= 0.0f) {
        weight *= static_cast<double>(m.priority[v]) * m.priority[v];
      }
      if (!(weight > 0.0)) continue;
      bool used = false;
      for (std::size_t d = 0; d < dims; ++d) {
        AttributeGradient fn;
        if (!fit_attribute_gradient(p0, p1, p2, values[d], values[dims + d], values[2 * dims + d], fn)) continue;
        accumulate_attribute(wq_[w], wg_[w * dims + d], fn, weight);
        used = true;
      }
      if (used) wq_[w].alpha += weight;
    }
  }
}

// Whether every island joins only vertices that may merge by their skin weights (every pair: an island's
// vertices end as one, whichever survives).
bool Engine::skin_allows(const std::vector<std::vector<std::uint32_t>>& islands) const {
  if (mesh_.skin.size() != mesh_.vertex_count()) return true;
  for (const std::vector<std::uint32_t>& island : islands) {
    for (std::size_t i = 0; i < island.size(); ++i) {
      for (std::size_t j = i + 1; j < island.size(); ++j) {
        if (!skin_mergeable(mesh_.skin[island[i]], mesh_.skin[island[j]], options_.skin_weight_threshold,
                            options_.skin_max_distance)) {
          return false;
        }
      }
    }
  }
  return true;
}

// +inf when both ends are locked (neither may move).
double Engine::rung_cost(const std::array<std::uint32_t, 2>& r, std::uint32_t diagonal_quad) const {
  const auto [a, b] = r;
  if (qm_.locked(a) && qm_.locked(b)) return std::numeric_limits<double>::infinity();
  const Quadric q = quadric_[a] + quadric_[b];
  Placement p;
  if (qm_.locked(a) || qm_.locked(b)) {
    p.position = qm_.position(qm_.locked(a) ? a : b);
    p.error = q.evaluate(p.position);
  } else {
    p = place_on_edge(q, qm_.position(a), qm_.position(b));
  }
  if (layout_.dims == 0 || options_.attribute_cost_weight == 0.0) return p.error;
  return p.error + options_.attribute_cost_weight * attribute_cost(a, b, diagonal_quad, p.position);
}

// The classes QuadMesh::weld makes for the island {a, b}: a's and b's wedges that meet across a face side
// a-b (or are the two corners of the dissolved quad) merge, every other wedge of a and b counts alone
// (as the triangle engine's add_attribute_quadrics). A wedge paired twice means a seam the weld refuses.
double Engine::attribute_cost(std::uint32_t a, std::uint32_t b, std::uint32_t diagonal_quad, const Vec3d& x) const {
  const auto dims = static_cast<std::size_t>(layout_.dims);
  auto grads = [&](std::uint32_t w) { return std::span<const AttributeGradient>(&wg_[w * dims], dims); };
  constexpr int kMax = 8;  // more distinct wedges make a vertex the weld refuses anyway
  std::array<std::uint32_t, kMax> wa{}, wb{};
  std::array<std::pair<std::uint32_t, std::uint32_t>, kMax> pairs{};
  int na = 0, nb = 0, np = 0;
  auto note = [](std::array<std::uint32_t, kMax>& list, int& n, std::uint32_t w) {
    if (n < kMax && std::find(list.begin(), list.begin() + n, w) == list.begin() + n) list[n++] = w;
  };
  for (std::uint32_t f : qm_.vertex_faces(a)) {
    const std::uint32_t n = qm_.face_size(f), i = qm_.corner_of(f, a), j = qm_.corner_of(f, b);
    note(wa, na, qm_.face_wedge(f, i));
    if (j == kInvalidIndex || !(j == (i + 1) % n || i == (j + 1) % n || f == diagonal_quad)) continue;
    const std::pair<std::uint32_t, std::uint32_t> pair{qm_.face_wedge(f, i), qm_.face_wedge(f, j)};
    if (np < kMax && std::find(pairs.begin(), pairs.begin() + np, pair) == pairs.begin() + np) pairs[np++] = pair;
  }
  for (std::uint32_t f : qm_.vertex_faces(b)) note(wb, nb, qm_.face_wedge(f, qm_.corner_of(f, b)));
  double cost = 0.0;
  for (int i = 0; i < np; ++i) {
    const auto [u, v] = pairs[i];
    cost += reduce_merged_attributes(wq_[u], grads(u), wq_[v], grads(v)).evaluate(x);
  }
  auto paired = [&](std::uint32_t w) {
    for (int i = 0; i < np; ++i) {
      if (pairs[i].first == w || pairs[i].second == w) return true;
    }
    return false;
  };
  for (int i = 0; i < na; ++i) {
    if (!paired(wa[i])) cost += reduce_attributes(wq_[wa[i]], grads(wa[i])).evaluate(x);
  }
  for (int i = 0; i < nb; ++i) {
    if (!paired(wb[i])) cost += reduce_attributes(wq_[wb[i]], grads(wb[i])).evaluate(x);
  }
  return std::max(0.0, cost);
}

// Seed-and-grow search over one chord: the cheapest seed window, grown one rung at either
// end while cost per removed triangle improves (stopping once it is clearly worse), against the whole chord.
// Runs never hold two rungs that share a vertex (self-touching or self-intersecting strips), and remove at
// most `cap` triangles.
std::optional<Candidate> Engine::best_candidate(const Chord& chord, long long cap, double& held_key) const {
  held_key = std::numeric_limits<double>::infinity();
  const Polychord& p = chord.trace;
  const std::size_t rungs = p.rungs.size();
  if (rungs == 0) return std::nullopt;
  // Scratch reused across calls (the engine is sequential): allocating these per chord was a tenth of the
  // engine's time on the 100k-quad torus.
  std::vector<double>& cost = scratch_.cost;
  std::vector<double>& prefix = scratch_.prefix;
  std::vector<std::uint8_t>& usable = scratch_.usable;  // finite cost
  std::vector<std::uint8_t>& in_run = scratch_.in_run;  // usable and not blocked
  cost.resize(rungs);
  prefix.assign(rungs + 1, 0.0);
  usable.resize(rungs);
  in_run.resize(rungs);
  for (std::size_t k = 0; k < rungs; ++k) {
    cost[k] = rung_cost(p.rungs[k]);
    usable[k] = std::isfinite(cost[k]);
    in_run[k] = usable[k] && (chord.blocked.empty() || chord.blocked[k] == 0);
    prefix[k + 1] = prefix[k] + (usable[k] ? cost[k] : 0.0);
  }
  std::vector<long long>& conflict = scratch_.conflict;
  rung_conflicts(p, conflict, scratch_.last_rung);
  const long long max_left = std::max(0LL, triangles_left_allowed());
  auto evaluate = [&](std::size_t i, std::size_t j, double worst) {
    Candidate c{static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(j), 0, 0, 0};
    std::tie(c.removed, c.left) = run_counts(p, i, j);
    c.cost = std::max(0.0, prefix[j + 1] - prefix[i] + penalty_ * static_cast<double>(c.left));
    // A long cheap run must not carry one expensive rung along: rank it no better than its worst rung.
    c.key = c.base_key = rank(c.cost, c.removed, worst);
    // Once the budget is spent, runs that leave triangles rank worse and runs that delete some rank better
    // (freeing budget): on the bench this kept the quad fraction near 0.9 rather than 0.87 at equal error.
    if (c.left > max_left) {
      c.over_budget = true;
      c.key *= options_.over_budget_factor;
    } else if (c.left < 0 && max_left == 0) {
      c.key /= options_.over_budget_factor;
    }
    return c;
  };
  const long long hard_left = hard_triangles_left();
  auto fits = [&](const Candidate& c) {
    if (c.removed <= 0 || c.removed > cap) return false;
    if (c.left <= hard_left) return true;
    held_key = std::min(held_key, c.key);
    return false;
  };
  auto better = [](const Candidate& a, const Candidate& b) {
    return a.key < b.key || (a.key == b.key && a.removed > b.removed);
  };

  std::optional<Candidate> best;
  // Whole chord: every rung usable and no two sharing a vertex.
  const bool whole_valid = chord.whole_allowed && !p.self_touching &&
                           std::all_of(usable.begin(), usable.end(), [](std::uint8_t u) { return u != 0; });
  if (whole_valid) {
    const Candidate whole = evaluate(0, rungs - 1, *std::max_element(cost.begin(), cost.end()));
    if (fits(whole)) best = whole;
  }

  const std::size_t max_run = std::min(chord.max_run, rungs);
  if (max_run == 0) return best;
  // Seed: the cheapest valid window of seed_rungs rungs (fewer if no such window exists).
  std::optional<Candidate> seed;
  for (std::size_t len = std::min<std::size_t>(std::max(options_.seed_rungs, 1), max_run); len >= 1 && !seed; --len) {
    for (std::size_t i = 0; i + len <= rungs; ++i) {
      const std::size_t j = i + len - 1;
      bool ok = true;
      for (std::size_t k = i; k <= j && ok; ++k) ok = in_run[k] && conflict[k] < static_cast<long long>(i);
      if (!ok) continue;
      const Candidate c = evaluate(i, j, *std::max_element(cost.begin() + i, cost.begin() + j + 1));
      if (fits(c) && (!seed || better(c, *seed))) seed = c;
    }
  }
  if (!seed) return best;
  Candidate run = *seed, best_run = *seed;
  double run_worst = *std::max_element(cost.begin() + run.first, cost.begin() + run.last + 1);
  long long max_conflict = -1;
  for (std::size_t k = run.first; k <= run.last; ++k) max_conflict = std::max(max_conflict, conflict[k]);
  // Growth stops once the ratio is this much worse than the best seen ("clearly worse").
  constexpr double kGiveUpFactor = 2.0;
  while (run.last - run.first + 1 < max_run) {
    std::optional<Candidate> option;
    bool grow_right = false;
    if (run.first > 0 && in_run[run.first - 1] && max_conflict < static_cast<long long>(run.first) - 1) {
      const Candidate c = evaluate(run.first - 1, run.last, std::max(run_worst, cost[run.first - 1]));
      if (fits(c)) option = c;
    }
    if (run.last + 1 < rungs && in_run[run.last + 1] && conflict[run.last + 1] < static_cast<long long>(run.first)) {
      const Candidate c = evaluate(run.first, run.last + 1, std::max(run_worst, cost[run.last + 1]));
      if (fits(c) && (!option || !better(*option, c))) {
        option = c;
        grow_right = true;
      }
    }
    if (!option) break;
    if (grow_right) max_conflict = std::max(max_conflict, conflict[run.last + 1]);
    run_worst = std::max(run_worst, cost[grow_right ? run.last + 1 : run.first - 1]);
    run = *option;
    if (better(run, best_run)) best_run = run;
    if (run.key > kGiveUpFactor * best_run.key && run.key > 0.0) break;
  }
  if (!best || better(best_run, *best)) best = best_run;
  return best;
}

std::pair<long long, long long> Engine::run_counts(const Polychord& p, std::size_t i, std::size_t j) const {
  const std::size_t rungs = p.rungs.size(), quads = p.faces.size();
  if (p.closed && j - i + 1 == rungs) return {2 * static_cast<long long>(quads), 0};
  if (p.closed) return {2 * static_cast<long long>(j - i) + 2, 2};
  // What an open end of a run does: in a quad, turns it into a triangle (removes 1, leaves 1); at a triangle
  // the chord ends in, deletes it (removes 1, closes 1); at a boundary, nothing.
  auto end_effect = [&](bool inner, int side) -> std::pair<int, int> {
    if (inner) return {1, 1};
    if (p.ends[side] == ChordEnd::triangle) return {1, -1};
    return {0, 0};
  };
  const auto [r0, t0] = end_effect(i > 0, 0);
  const auto [r1, t1] = end_effect(j < quads, 1);
  return {2 * static_cast<long long>(j - i) + r0 + r1, t0 + t1};
}

// Islands of a run: its rungs, joined where they share a vertex (union-find), each placed by its summed
// quadric.
IslandPlan Engine::plan(const Chord& chord, const Candidate& c) const {
  const Polychord& p = chord.trace;
  return plan_rungs({p.rungs.begin() + c.first, p.rungs.begin() + c.last + 1});
}

IslandPlan Engine::plan_rungs(const std::vector<std::array<std::uint32_t, 2>>& rungs) const {
  IslandPlan out;
  std::vector<std::uint32_t> verts;
  for (const auto& r : rungs) verts.insert(verts.end(), r.begin(), r.end());
  std::sort(verts.begin(), verts.end());
  verts.erase(std::unique(verts.begin(), verts.end()), verts.end());
  std::vector<std::uint32_t> parent(verts.size());
  for (std::uint32_t i = 0; i < parent.size(); ++i) parent[i] = i;
  auto index = [&](std::uint32_t v) {
    return static_cast<std::uint32_t>(std::lower_bound(verts.begin(), verts.end(), v) - verts.begin());
  };
  auto root = [&](std::uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (const auto& r : rungs) {
    const std::uint32_t a = root(index(r[0])), b = root(index(r[1]));
    if (a != b) parent[std::max(a, b)] = std::min(a, b);
  }
  std::vector<std::uint32_t> island_of(verts.size(), kInvalidIndex);
  for (std::uint32_t i = 0; i < verts.size(); ++i) {
    const std::uint32_t r = root(i);
    if (island_of[r] == kInvalidIndex) {
      island_of[r] = static_cast<std::uint32_t>(out.islands.size());
      out.islands.emplace_back();
    }
    out.islands[island_of[r]].push_back(verts[i]);
  }
  for (const auto& island : out.islands) place(island, out);
  return out;
}

// Places one island at its summed quadric's best point (the locked member's position when it has one) and
// appends position, quadric and error to `out`.
void Engine::place(const std::vector<std::uint32_t>& island, IslandPlan& out) const {
  Quadric q;
  std::uint32_t locked = kInvalidIndex;
  Vec3d centroid{};
  for (std::uint32_t v : island) {
    q += quadric_[v];
    centroid = centroid + qm_.position(v);
    if (qm_.locked(v)) locked = v;
  }
  centroid = centroid * (1.0 / static_cast<double>(island.size()));
  Vec3d x;
  if (locked != kInvalidIndex) {
    x = qm_.position(locked);
  } else if (island.size() == 2) {
    x = place_on_edge(q, qm_.position(island[0]), qm_.position(island[1])).position;
  } else {
    // Larger islands: the minimiser when well conditioned, else the best of the centroid and the members.
    x = centroid;
    double best = q.evaluate(centroid);
    for (std::uint32_t v : island) {
      if (q.evaluate(qm_.position(v)) < best) {
        best = q.evaluate(qm_.position(v));
        x = qm_.position(v);
      }
    }
    if (const auto m = q.minimizer(kMinPivotRelative)) x = *m;
  }
  const double e = q.evaluate(x);
  out.max_error = std::max(out.max_error, q.weight > 0.0 ? std::sqrt(e / q.weight) : 0.0);
  out.positions.push_back(x);
  out.quadrics.push_back(q);
}

// Wedges of one class (the same `into`) merge their attribute quadrics into the representative; when the
// island moved, the representative takes the merged quadric's minimiser at the new position, clamped into
// what the merged values allow (see PolychordOptions::optimal_attributes). A class of one keeps its values.
void Engine::carry_attributes(const WeldResult& w) {
  if (layout_.dims == 0) return;
  const auto dims = static_cast<std::size_t>(layout_.dims);
  // weld() lists each class's wedges together (one `into` each); they merge in wedge order.
  const std::vector<WeldResult::Wedge>& list = w.wedges;
  std::vector<double> opt(dims);
  std::vector<std::uint32_t> members;
  for (std::size_t b = 0, e = 0; b < list.size(); b = e) {
    const std::uint32_t t = list[b].into, s = list[b].survivor;
    members.clear();
    for (e = b; e < list.size() && list[e].into == t; ++e) members.push_back(list[e].wedge);
    if (members.size() < 2) continue;
    std::sort(members.begin(), members.end());
    for (std::uint32_t m : members) {
      if (m != t) {
        merge_attribute_quadrics(wq_[t], std::span(&wg_[t * dims], dims), wq_[m],
                                 std::span<const AttributeGradient>(&wg_[m * dims], dims));
      }
    }
    if (!write_values_ || qm_.locked(s)) continue;
    if (!optimal_attributes(wq_[t], std::span<const AttributeGradient>(&wg_[t * dims], dims), qm_.position(s), opt)) {
      continue;
    }
    if (const AttributeGroup* g = layout_.find(AttributeGroup::Type::normal, 0)) {
      Vec3d n{};
      for (int i = 0; i < 3; ++i) n[i] = opt[static_cast<std::size_t>(g->dim + i)] / g->scale;
      const double len = length(n);
      if (len > 1e-6 && std::isfinite(len)) normals_[t] = to_float(n * (1.0 / len));
    }
    // A seam vertex (two or more wedges) snaps its UVs to one of the merged values: a point between them
    // may lie outside the chart (see the triangle engine's new_uv).
    std::size_t survivor_wedges = 0;
    {
      std::array<std::uint32_t, 2> seen{kInvalidIndex, kInvalidIndex};
      for (std::uint32_t f : qm_.vertex_faces(s)) {
        const std::uint32_t x = qm_.face_wedge(f, qm_.corner_of(f, s));
        if (x != seen[0] && x != seen[1] && survivor_wedges < 2) seen[survivor_wedges++] = x;
      }
    }
    for (std::size_t set = 0; set < uvs_.size(); ++set) {
      const AttributeGroup* g = layout_.find(AttributeGroup::Type::uv, static_cast<int>(set));
      if (g == nullptr) continue;
      std::vector<Vec2f>& uv = uvs_[set];
      const double ox = opt[static_cast<std::size_t>(g->dim)] / g->scale, oy = opt[static_cast<std::size_t>(g->dim + 1)] / g->scale;
      if (!std::isfinite(ox) || !std::isfinite(oy)) continue;
      // The nearest point to the optimum on the segments between the merged wedges' UVs (or the nearest
      // of those UVs at a seam vertex).
      double best = std::numeric_limits<double>::infinity(), bx = uv[t][0], by = uv[t][1];
      auto consider = [&](double x, double y) {
        const double d = (x - ox) * (x - ox) + (y - oy) * (y - oy);
        if (d < best) {
          best = d;
          bx = x;
          by = y;
        }
      };
      for (std::size_t i = 0; i < members.size(); ++i) {
        const Vec2f p = uv[members[i]];
        consider(p[0], p[1]);
        if (survivor_wedges > 1) continue;
        for (std::size_t j = i + 1; j < members.size(); ++j) {
          const Vec2f q = uv[members[j]];
          const double ex = double{q[0]} - p[0], ey = double{q[1]} - p[1], len2 = ex * ex + ey * ey;
          if (!(len2 > 0.0)) continue;
          const double u = std::clamp(((ox - p[0]) * ex + (oy - p[1]) * ey) / len2, 0.0, 1.0);
          consider(p[0] + u * ex, p[1] + u * ey);
        }
      }
      uv[t] = Vec2f{{static_cast<float>(bx), static_cast<float>(by)}};
    }
    for (std::size_t set = 0; set < colors_.size(); ++set) {
      const AttributeGroup* g = layout_.find(AttributeGroup::Type::color, static_cast<int>(set));
      if (g == nullptr) continue;
      std::vector<Vec4f>& col = colors_[set];
      Vec4f c = col[t];
      for (int i = 0; i < 4; ++i) {
        // [0, 1], widened to the merged values' own range (HDR colours stay HDR).
        float lo = 0.0f, hi = 1.0f;
        for (std::uint32_t m : members) {
          lo = std::min(lo, col[m][i]);
          hi = std::max(hi, col[m][i]);
        }
        const double v = opt[static_cast<std::size_t>(g->dim + i)] / g->scale;
        if (std::isfinite(v)) c[i] = std::clamp(static_cast<float>(v), lo, hi);
      }
      col[t] = c;
    }
  }
}

// Scores both diagonals of quad f (nothing for other faces, or with diagonal collapses off).
void Engine::push_diagonals(std::uint32_t f) {
  if (options_.diagonal_factor <= 0.0 || qm_.face_size(f) != 4) return;
  for (std::uint32_t d = 0; d < 2; ++d) {
    const double cost = rung_cost({qm_.face_vertex(f, d), qm_.face_vertex(f, d + 2)}, f);
    if (!std::isfinite(cost)) continue;
    // The rank of a one-rung run of this cost that removes two triangles and leaves none, times the factor.
    const double key = options_.diagonal_factor * rank(cost, 2, cost);
    diagonals_.push({key, f, d, face_version_[f]});
  }
}

double Engine::held_top() {
  while (!held_.empty()) {
    const Entry& e = held_.top();
    if (chords_[e.chord].state == Chord::State::alive && chords_[e.chord].version == e.version) return e.key;
    held_.pop();
  }
  return std::numeric_limits<double>::infinity();
}

double Engine::diagonal_top() {
  while (!diagonals_.empty()) {
    const DiagonalEntry& e = diagonals_.top();
    if (qm_.face_size(e.face) == 4 && face_version_[e.face] == e.version) return e.key;
    diagonals_.pop();
  }
  return std::numeric_limits<double>::infinity();
}

void Engine::try_diagonal() {
  const DiagonalEntry e = diagonals_.top();
  diagonals_.pop();
  // The two other corners each lose a face: an interior one left with two faces would be a doublet (two
  // faces sharing two sides), which folds.
  for (std::uint32_t k : {e.diagonal + 1, (e.diagonal + 3) % 4}) {
    const std::uint32_t v = qm_.face_vertex(e.face, k);
    if (qm_.vertex_faces(v).size() <= 3 && !qm_.on_boundary(v)) return;
  }
  // Nor may the merged vertex get more than diagonal_max_faces faces (a pole).
  const std::size_t merged_faces = qm_.vertex_faces(qm_.face_vertex(e.face, e.diagonal)).size() +
                                   qm_.vertex_faces(qm_.face_vertex(e.face, e.diagonal + 2)).size() - 2;
  if (merged_faces > options_.diagonal_max_faces) return;
  IslandPlan plan;
  plan.islands = {{qm_.face_vertex(e.face, e.diagonal), qm_.face_vertex(e.face, e.diagonal + 2)}};
  place(plan.islands[0], plan);
  if (!stop_.allows(plan.max_error)) {
    ++over_budget_;
    return;
  }
  if (!skin_allows(plan.islands)) return;
  WeldOptions dissolve = weld_options_;
  dissolve.dissolve_diagonal_quads = true;
  const WeldResult w = qm_.weld(plan.islands, plan.positions, dissolve);
  if (!w.ok()) {
    ++rejected_;
    return;
  }
  quadric_[w.survivors[0]] = plan.quadrics[0];
  carry_attributes(w);
  if (!mirror_.empty()) update_mirror(plan.islands, w.survivors);
  error_bound_ = std::max(error_bound_, plan.max_error);
  ++diagonal_collapses_;
  invalidate_around(w);
}

// After the weld refused run c: blocks the rungs of c that the weld would refuse on their own (checked with
// dry runs), and says whether there were any. None means the rungs fail only together.
bool Engine::block_failing_rungs(Chord& chord, const Candidate& c) {
  chord.blocked.resize(chord.trace.rungs.size(), 0);
  if (c.first == c.last) {
    chord.blocked[c.first] = 1;
    return true;
  }
  bool any = false;
  for (std::uint32_t k = c.first; k <= c.last; ++k) {
    if (refused_alone({chord.trace.rungs[k]})) {
      chord.blocked[k] = 1;
      any = true;
    }
  }
  return any;
}

bool Engine::refused_alone(const std::vector<std::array<std::uint32_t, 2>>& rungs) {
  WeldOptions check = weld_options_;
  check.dry_run = true;
  const IslandPlan p = plan_rungs(rungs);
  return !skin_allows(p.islands) || !qm_.weld(p.islands, p.positions, check).ok();
}

// After the weld refused run c of chord `id`: the whole chord is not tried again, or the rungs that fail on
// their own are blocked (or, where none does, runs are halved); then the chord is queued afresh.
void Engine::refuse(std::uint32_t id, const Candidate& c) {
  Chord& chord = chords_[id];
  ++chord.version;
  const bool whole = c.first == 0 && c.last + 1 == chord.trace.rungs.size();
  if (whole && chord.whole_allowed) chord.whole_allowed = false;
  else if (!block_failing_rungs(chord, c)) chord.max_run = (c.last - c.first + 1) / 2;
  push(id);
}

void Engine::refuse_pair(std::uint32_t id, const Candidate& c, const MirrorRun& m, bool run_fails, bool mirror_fails) {
  Chord& a = chords_[id];
  Chord& b = chords_[m.chord];
  const std::size_t n = c.last - c.first + 1;
  const bool whole_a = n == a.trace.rungs.size(), whole_b = m.index.size() == b.trace.rungs.size();
  a.blocked.resize(a.trace.rungs.size(), 0);
  b.blocked.resize(b.trace.rungs.size(), 0);
  bool halve = false;
  if ((run_fails && whole_a && a.whole_allowed) || (mirror_fails && whole_b && b.whole_allowed)) {
    a.whole_allowed = b.whole_allowed = false;
  } else {
    bool any = false;
    if (run_fails) any |= block_failing_rungs(a, c);
    if (mirror_fails) {
      // block_failing_rungs() takes a range; the image's rungs are tested one by one instead (it may wrap).
      for (std::uint32_t k : m.index) {
        if (refused_alone({b.trace.rungs[k]})) {
          b.blocked[k] = 1;
          any = true;
        }
      }
    }
    halve = !any;
  }
  for (std::size_t t = 0; t < n; ++t) {
    std::uint8_t& x = a.blocked[c.first + t];
    std::uint8_t& y = b.blocked[m.index[t]];
    x = y = static_cast<std::uint8_t>(x | y);
  }
  if (halve) a.max_run = b.max_run = std::max<std::size_t>(1, n / 2);
  ++a.version;
  push(id);
  if (m.chord != id) {
    ++b.version;
    push(m.chord);
  }
}

void Engine::push(std::uint32_t id) {
  Chord& chord = chords_[id];
  double held = 0;
  if (const auto c = best_candidate(chord, run_cap(), held)) {
    chord.best = *c;
    chord.queued = true;
    queue_.push({c->key, c->removed, id, chord.version});
  }
  if (std::isfinite(held) && options_.diagonal_factor > 0.0) held_.push({held, 0, id, chord.version});
}

void Engine::trace_from(std::uint32_t face, int direction) {
  const auto id = static_cast<std::uint32_t>(chords_.size());
  Chord chord;
  chord.trace = trace_polychord(qm_, face, direction, trace_scratch_);
  for (std::size_t k = 0; k < chord.trace.faces.size(); ++k) {
    face_chord_[chord.trace.faces[k]][chord.trace.directions[k]] = id;
  }
  chords_.push_back(std::move(chord));
  push(id);
}

void Engine::mark_stale(std::uint32_t id) {
  Chord& chord = chords_[id];
  if (chord.state != Chord::State::alive) return;
  chord.state = Chord::State::stale;
  // A chord without an entry (nothing valid last time) gets one, so that it is looked at again.
  if (!chord.queued) {
    chord.queued = true;
    queue_.push({0.0, 0, id, chord.version});
  }
}

// Re-traces a stale chord through those of its quads (and directions) no newer chord has claimed yet: the
// old strip may have been cut in several, or joined to another.
void Engine::retrace(std::uint32_t id) {
  const Polychord old = std::move(chords_[id].trace);
  chords_[id].state = Chord::State::dead;
  for (std::size_t k = 0; k < old.faces.size(); ++k) {
    const std::uint32_t f = old.faces[k], d = old.directions[k];
    if (qm_.face_size(f) == 4 && face_chord_[f][d] == id) trace_from(f, static_cast<int>(d));
  }
}

// After a weld: every chord through a face around a touched vertex may have changed (its rungs' quadrics, its
// length, its ends, its validity): those go stale. Faces that stopped being quads leave their chords; faces
// that became quads (an n-gon losing a corner) start new ones.
void Engine::invalidate_around(const WeldResult& w) {
  // The faces, each once (a stamp per face instead of sorting the duplicates away), in ascending order.
  std::vector<std::uint32_t> faces;
  ++stamp_;
  auto add = [&](std::uint32_t f) {
    if (face_stamp_[f] == stamp_) return;
    face_stamp_[f] = stamp_;
    faces.push_back(f);
  };
  for (std::uint32_t f : w.faces) add(f);
  for (std::uint32_t f : w.faces) {
    for (std::uint32_t i = 0; i < qm_.face_size(f); ++i) {
      for (std::uint32_t g : qm_.vertex_faces(qm_.face_vertex(f, i))) add(g);
    }
  }
  std::sort(faces.begin(), faces.end());
  for (std::uint32_t f : faces) {
    for (std::uint32_t& id : face_chord_[f]) {
      if (id == kInvalidIndex) continue;
      mark_stale(id);
      if (qm_.face_size(f) != 4) id = kInvalidIndex;
    }
  }
  for (std::uint32_t f : faces) {
    ++face_version_[f];
    if (diagonals_scored_) push_diagonals(f);
    if (qm_.face_size(f) != 4) continue;
    for (int d = 0; d < 2; ++d) {
      if (face_chord_[f][d] == kInvalidIndex) trace_from(f, d);
    }
  }
}

// ---- symmetry ---------------------------------------------------------------------------------------------

void Engine::setup_symmetry() {
  const std::size_t nv = qm_.vertex_count();
  if (options_.vertex_mirror != nullptr) {
    if (options_.vertex_mirror->size() != nv) return;
    mirror_ = *options_.vertex_mirror;
    for (std::uint32_t& m : mirror_) {
      if (m >= nv) m = kInvalidIndex;
    }
    plane_ = symmetry::plane_of_pairs(mesh_, mirror_);
  } else {
    symmetry::SymmetryMap map = symmetry::detect_symmetry(mesh_, {.plane = options_.symmetry_plane});
    if (map.found() && map.vertex_mirror.size() == nv) {
      mirror_ = std::move(map.vertex_mirror);
      plane_ = map.plane;
    }
  }
  if (!plane_) mirror_.clear();
}

std::optional<MirrorRun> Engine::mirror_run(std::uint32_t id, const Candidate& c, bool& outside) {
  outside = false;
  using Rung = std::array<std::uint32_t, 2>;
  auto sorted = [](Rung r) {
    if (r[0] > r[1]) std::swap(r[0], r[1]);
    return r;
  };
  // The run's rungs and their images (copies: re-tracing below grows chords_).
  const bool run_closed = chords_[id].trace.closed;
  const bool whole = c.first == 0 && c.last + 1 == chords_[id].trace.rungs.size();
  std::vector<Rung> own, image;
  std::size_t ends = 0;  // rung ends with a mirror
  for (std::uint32_t k = c.first; k <= c.last; ++k) {
    const Rung r = chords_[id].trace.rungs[k];
    ends += (mirror_[r[0]] != kInvalidIndex) + (mirror_[r[1]] != kInvalidIndex);
    own.push_back(sorted(r));
    image.push_back(sorted({mirror_[r[0]], mirror_[r[1]]}));
  }
  // Wholly outside the symmetric part: nothing to keep. Partly: the run has no image, and going alone
  // would take the symmetry of its mirrored vertices' partners with it.
  if (ends == 0) {
    outside = true;
    return std::nullopt;
  }
  if (ends < 2 * own.size()) return std::nullopt;
  {
    std::vector<Rung> a = own, b = image;
    std::sort(a.begin(), a.end());
    std::sort(b.begin(), b.end());
    if (a == b) return MirrorRun{.chord = id, .first = c.first, .last = c.last, .removed = c.removed, .key = c.key};
  }
  // The chord through the image of the first rung: a quad with that side, in one of its two directions.
  const auto [ma, mb] = image[0];
  std::uint32_t other = kInvalidIndex;
  std::size_t at = 0;
  for (std::uint32_t f : std::vector<std::uint32_t>(qm_.vertex_faces(ma))) {
    if (qm_.face_size(f) != 4 || qm_.corner_of(f, mb) == kInvalidIndex) continue;
    for (int d = 0; d < 2 && other == kInvalidIndex; ++d) {
      std::uint32_t cid = face_chord_[f][d];
      if (cid == kInvalidIndex) continue;
      if (chords_[cid].state == Chord::State::stale) {
        retrace(cid);
        cid = face_chord_[f][d];
        if (cid == kInvalidIndex) continue;
      }
      if (chords_[cid].state != Chord::State::alive) continue;
      const std::vector<Rung>& rs = chords_[cid].trace.rungs;
      for (std::size_t k = 0; k < rs.size(); ++k) {
        if (sorted(rs[k]) == image[0]) {
          other = cid;
          at = k;
          break;
        }
      }
    }
    if (other != kInvalidIndex) break;
  }
  if (other == kInvalidIndex) return std::nullopt;
  const Chord& o = chords_[other];
  const std::vector<Rung>& rs = o.trace.rungs;
  const std::size_t n = image.size(), size = rs.size();
  // The image's rung indices in `other`, in the run's order (on a closed chord they may wrap past its start).
  std::vector<std::uint32_t> index;
  if (whole && run_closed && o.trace.closed && size == n) {
    // A whole closed chord's image is a whole closed chord, traced from wherever: each image rung's index.
    std::vector<std::pair<Rung, std::uint32_t>> where;
    for (std::uint32_t k = 0; k < size; ++k) where.emplace_back(sorted(rs[k]), k);
    std::sort(where.begin(), where.end());
    for (const Rung& r : image) {
      const auto it = std::lower_bound(where.begin(), where.end(), std::pair{r, 0u});
      if (it == where.end() || it->first != r) break;
      index.push_back(it->second);
    }
    std::vector<std::uint32_t> distinct = index;
    std::sort(distinct.begin(), distinct.end());
    if (index.size() != n || std::adjacent_find(distinct.begin(), distinct.end()) != distinct.end()) index.clear();
  } else if (n <= size) {
    for (int step : {1, -1}) {
      index.clear();
      for (std::size_t t = 0; t < n; ++t) {
        long long k = static_cast<long long>(at) + step * static_cast<long long>(t);
        const auto wrap = static_cast<long long>(size);
        if (o.trace.closed) k = (k % wrap + wrap) % wrap;
        if (k < 0 || k >= static_cast<long long>(size) || sorted(rs[static_cast<std::size_t>(k)]) != image[t]) break;
        index.push_back(static_cast<std::uint32_t>(k));
      }
      if (index.size() == n) break;
    }
    if (index.size() != n) index.clear();
  }
  if (index.empty()) return std::nullopt;
  const auto [lo, hi] = std::minmax_element(index.begin(), index.end());
  MirrorRun m{.chord = other, .first = *lo, .last = *hi};
  m.wraps = m.last - m.first + 1 != n;
  // Within one chord, a run overlapping its image (it crosses the plane off centre) grows to the run that
  // covers both, its own image.
  const auto in_run = [&](std::uint32_t k) { return k >= c.first && k <= c.last; };
  if (other == id && std::any_of(index.begin(), index.end(), in_run)) {
    if (m.wraps) return std::nullopt;
    m.covers = true;
    m.first = std::min(m.first, c.first);
    m.last = std::max(m.last, c.last);
    index.clear();
    for (std::uint32_t k = m.first; k <= m.last; ++k) index.push_back(k);
  }
  // The image must be a run the weld may make: usable, unblocked rungs without a shared vertex, the whole
  // chord only where allowed.
  if (index.size() == size && (!o.whole_allowed || o.trace.self_touching)) return std::nullopt;
  std::vector<std::uint32_t> verts;
  double cost = 0, worst = 0;
  for (std::uint32_t k : index) {
    if (!o.blocked.empty() && o.blocked[k] != 0) return std::nullopt;
    const double rc = rung_cost(rs[k]);
    if (!std::isfinite(rc)) return std::nullopt;
    cost += rc;
    worst = std::max(worst, rc);
    verts.insert(verts.end(), rs[k].begin(), rs[k].end());
    m.rungs.push_back(rs[k]);
  }
  m.index = index;
  std::sort(verts.begin(), verts.end());
  if (std::adjacent_find(verts.begin(), verts.end()) != verts.end()) return std::nullopt;
  long long left = 0;
  // A wrapped run of a closed chord counts as any partial run of it.
  std::tie(m.removed, left) = m.wraps ? run_counts(o.trace, 0, n - 1) : run_counts(o.trace, m.first, m.last);
  if (m.covers && m.removed > run_cap() * 2) return std::nullopt;  // as large as a pair may be
  // The triangle budget's factor is the run's own (set when it was queued): a run and its image in the same
  // state rank alike.
  m.key = rank(std::max(0.0, cost + penalty_ * static_cast<double>(left)), m.removed, worst);
  if (c.base_key > 0.0 && std::isfinite(c.base_key)) m.key *= c.key / c.base_key;
  return m;
}

Engine::Pairing Engine::pair_up(std::uint32_t id, MirrorRun& mirror) {
  const Candidate c = chords_[id].best;
  const bool tagged = chords_[id].rekeyed == chords_[id].version;
  const bool alone = tagged && chords_[id].alone;
  bool outside = false;
  const std::optional<MirrorRun> m = mirror_run(id, c, outside);
  if (outside) return Pairing::single;  // outside the symmetric region
  if (m && m->chord == id && m->first == c.first && m->last == c.last) return Pairing::single;  // its own image
  double pair_key = std::numeric_limits<double>::infinity();
  if (m && !alone) pair_key = m->covers ? m->key : 0.5 * (c.key + m->key);
  const double alone_key = c.key * (1.0 + options_.symmetry_weight);
  const double best = std::min(pair_key, alone_key);
  Chord& chord = chords_[id];
  if (!tagged && best > c.key * kRekeySlack) {
    chord.rekeyed = chord.version;
    chord.alone = false;
    chord.queued = true;
    queue_.push({best, c.removed, id, chord.version});
    return Pairing::requeued;
  }
  if (pair_key <= alone_key) {
    mirror = *m;
    return Pairing::pair;
  }
  return Pairing::single;
}

void Engine::requeue_alone(std::uint32_t id) {
  Chord& chord = chords_[id];
  chord.rekeyed = chord.version;
  chord.alone = true;
  chord.queued = true;
  queue_.push({chord.best.key * (1.0 + options_.symmetry_weight), chord.best.removed, id, chord.version});
}

void Engine::mirror_places(IslandPlan& plan, const std::vector<std::uint32_t>& own) const {
  const std::size_t n = plan.islands.size();
  const std::vector<std::uint32_t> image = island_images(plan.islands);
  auto holds_own = [&](std::uint32_t i) {
    return std::any_of(plan.islands[i].begin(), plan.islands[i].end(),
                       [&](std::uint32_t v) { return std::binary_search(own.begin(), own.end(), v); });
  };
  auto has_locked = [&](std::uint32_t i) {
    return std::any_of(plan.islands[i].begin(), plan.islands[i].end(), [&](std::uint32_t v) { return qm_.locked(v); });
  };
  bool changed = false;
  for (std::uint32_t i = 0; i < n; ++i) {
    const std::uint32_t j = image[i];
    if (j == kInvalidIndex) continue;
    if (j == i) {
      if (has_locked(i)) continue;
      const Vec3d& x = plan.positions[i];
      plan.positions[i] = x - plane_->normal * plane_->signed_distance(x);
      changed = true;
      continue;
    }
    // The pair's island that keeps its optimum: the popped run's, else the lower index.
    const bool keep = holds_own(i) != holds_own(j) ? holds_own(i) : i < j;
    if (!keep || has_locked(j)) continue;
    plan.positions[j] = plane_->reflect(plan.positions[i]);
    changed = true;
  }
  if (!changed) return;
  plan.max_error = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Quadric& q = plan.quadrics[i];
    const double e = q.evaluate(plan.positions[i]);
    plan.max_error = std::max(plan.max_error, q.weight > 0.0 ? std::sqrt(std::max(0.0, e) / q.weight) : 0.0);
  }
}

std::vector<std::uint32_t> Engine::island_images(const std::vector<std::vector<std::uint32_t>>& islands) const {
  const std::size_t n = islands.size();
  std::vector<std::pair<std::uint32_t, std::uint32_t>> member;  // (vertex, island), sorted
  for (std::uint32_t i = 0; i < n; ++i) {
    for (std::uint32_t v : islands[i]) member.emplace_back(v, i);
  }
  std::sort(member.begin(), member.end());
  auto island_of = [&](std::uint32_t v) {
    const auto it = std::lower_bound(member.begin(), member.end(), std::pair{v, 0u});
    return it != member.end() && it->first == v ? it->second : kInvalidIndex;
  };
  std::vector<std::uint32_t> image(n, kInvalidIndex);
  for (std::uint32_t i = 0; i < n; ++i) {
    const std::uint32_t m = mirror_[islands[i][0]];
    const std::uint32_t j = m == kInvalidIndex ? kInvalidIndex : island_of(m);
    if (j == kInvalidIndex || islands[j].size() != islands[i].size()) continue;
    if (std::all_of(islands[i].begin(), islands[i].end(),
                    [&](std::uint32_t v) { return mirror_[v] != kInvalidIndex && island_of(mirror_[v]) == j; })) {
      image[i] = j;
    }
  }
  return image;
}

void Engine::update_mirror(const std::vector<std::vector<std::uint32_t>>& islands,
                           const std::vector<std::uint32_t>& survivors) {
  const std::vector<std::uint32_t> image = island_images(islands);
  std::vector<std::uint32_t> members;
  for (const auto& island : islands) members.insert(members.end(), island.begin(), island.end());
  std::sort(members.begin(), members.end());
  for (std::uint32_t v : members) {
    const std::uint32_t m = mirror_[v];
    if (m != kInvalidIndex && !std::binary_search(members.begin(), members.end(), m) && mirror_[m] == v) {
      mirror_[m] = kInvalidIndex;
    }
  }
  for (std::uint32_t v : members) mirror_[v] = kInvalidIndex;
  for (std::uint32_t i = 0; i < islands.size(); ++i) {
    if (image[i] != kInvalidIndex) mirror_[survivors[i]] = survivors[image[i]];
  }
}

void Engine::symmetrize_fit() {
  for (std::uint32_t v = 0; v < mirror_.size(); ++v) {
    const std::uint32_t m = mirror_[v];
    if (m == kInvalidIndex || m < v || !qm_.vertex_alive(v) || !qm_.vertex_alive(m)) continue;
    if (!qm_.moved(v) || !qm_.moved(m) || qm_.locked(v) || qm_.locked(m)) continue;
    if (m == v) {
      const Vec3d& x = qm_.position(v);
      qm_.set_position(v, x - plane_->normal * plane_->signed_distance(x));
      continue;
    }
    const Vec3d x = (qm_.position(v) + plane_->reflect(qm_.position(m))) * 0.5;
    qm_.set_position(v, x);
    qm_.set_position(m, plane_->reflect(x));
  }
}

PolychordResult Engine::run() {
  // The surface fit's BVH of the input is built on another core while the (sequential) collapses run.
  TriangleBvh input_bvh;
  tbb::task_group fit_setup;
  if (options_.fit_surface) fit_setup.run([&] { input_bvh = input_surface_bvh(mesh_); });
  try {
    PolychordResult result = collapse();
    fit_setup.wait();
    // Quadric placement bounds the distance to the absorbed faces' planes, not to the surface between them;
    // on the bench, fitting the moved vertices to the input took the mean distance of the MakeHuman casual
    // suit at 25% from 1.68x the triangle engine's to 1.42x.
    if (options_.fit_surface && !result.stopped) {
      refit_to_surface(qm_, mesh_, input_bvh, {});
      if (!mirror_.empty()) symmetrize_fit();
    }
    AttributeOverrides values;
    if (write_values_) {
      if (!normals_.empty()) values.normals = &normals_;
      values.uvs = &uvs_;
      values.colors = &colors_;
    }
    result.mesh = qm_.to_mesh(mesh_, values);
    return result;
  } catch (...) {
    fit_setup.wait();
    throw;
  }
}

PolychordResult Engine::collapse() {
  PolychordResult result;
  result.triangles_before = qm_.triangle_count();
  result.quads_before = qm_.face_kinds().quads;
  face_chord_.assign(qm_.face_slots(), {kInvalidIndex, kInvalidIndex});
  face_version_.assign(qm_.face_slots(), 0);
  face_stamp_.assign(qm_.face_slots(), 0);
  for (std::uint32_t f = 0; f < qm_.face_slots(); ++f) {
    if (qm_.face_size(f) != 4) continue;
    for (int d = 0; d < 2; ++d) {
      if (face_chord_[f][d] == kInvalidIndex) trace_from(f, d);
    }
  }

  for (std::size_t step = 0; !stop_.reached(qm_.triangle_count()); ++step) {
    if (step % kStopPollSteps == 0 && options_.stop.requested()) {
      result.stopped = true;
      break;
    }
    // While the hard triangle budget forces runs much dearer than those it holds back (PolychordOptions::
    // diagonal_gate), a diagonal collapse that ranks better than the best run goes first. Diagonals are
    // scored from the first time the gate opens (most meshes never open it).
    const double run_key = queue_.empty() ? std::numeric_limits<double>::infinity() : queue_.top().key;
    if (options_.diagonal_factor > 0.0 && run_key > options_.diagonal_gate * held_top()) {
      if (!diagonals_scored_) {
        diagonals_scored_ = true;
        for (std::uint32_t f = 0; f < qm_.face_slots(); ++f) push_diagonals(f);
      }
      if (const double diagonal = diagonal_top(); diagonal < run_key) {
        try_diagonal();
        continue;
      }
    }
    if (queue_.empty()) {
      // The triangle budget is a preference, not a limit: when only runs that leave triangles are left,
      // double it (up to no limit) and score every chord again rather than hand the rest to the triangle
      // engine.
      if (triangle_budget_ == kUnlimited) break;
      triangle_budget_ = triangle_budget_ > static_cast<long long>(target_) ? kUnlimited
                                                                            : std::max(2 * triangle_budget_, 16LL);
      for (std::uint32_t id = 0; id < chords_.size(); ++id) {
        if (chords_[id].state == Chord::State::dead) continue;
        ++chords_[id].version;
        chords_[id].queued = false;
        if (chords_[id].state == Chord::State::stale) {
          chords_[id].queued = true;
          queue_.push({0.0, 0, id, chords_[id].version});
        } else {
          push(id);
        }
      }
      continue;
    }
    const Entry e = queue_.top();
    queue_.pop();
    Chord& chord = chords_[e.chord];
    if (chord.version != e.version) continue;
    chord.queued = false;
    // A stale chord is re-traced into new chords (queued afresh) and dies; retrace() grows chords_, so
    // `chord` must not be used after it.
    if (chord.state == Chord::State::stale) {
      retrace(e.chord);
      continue;
    }
    if (chord.state != Chord::State::alive) continue;
    // The cap tightened, or the run's standing against the triangle budget changed, since it was queued.
    const bool over_now = chord.best.left > std::max(0LL, triangles_left_allowed());
    if (chord.best.removed > run_cap() ||
        (chord.best.left > 0 && (over_now != chord.best.over_budget || chord.best.left > hard_triangles_left()))) {
      ++chord.version;
      push(e.chord);
      continue;
    }
    const Candidate candidate = chord.best;
    MirrorRun mirror;
    const Pairing pairing = mirror_.empty() ? Pairing::single : pair_up(e.chord, mirror);
    if (pairing == Pairing::requeued) continue;
    // pair_up() may have re-traced the mirror's chord, which grows chords_.
    Chord& run_chord = chords_[e.chord];
    const Polychord& trace = run_chord.trace;
    std::vector<std::array<std::uint32_t, 2>> rungs(trace.rungs.begin() + candidate.first,
                                                    trace.rungs.begin() + candidate.last + 1);
    std::vector<std::uint32_t> own;
    if (!mirror_.empty()) {
      for (const auto& r : rungs) own.insert(own.end(), r.begin(), r.end());
      std::sort(own.begin(), own.end());
      own.erase(std::unique(own.begin(), own.end()), own.end());
    }
    if (pairing == Pairing::pair) {
      if (mirror.covers) rungs.clear();
      rungs.insert(rungs.end(), mirror.rungs.begin(), mirror.rungs.end());
    }
    IslandPlan islands = plan_rungs(rungs);
    if (!mirror_.empty()) mirror_places(islands, own);
    if (!stop_.allows(islands.max_error)) {  // stays out until its neighbourhood changes
      if (pairing == Pairing::pair) {
        requeue_alone(e.chord);
      } else {
        ++over_budget_;
      }
      continue;
    }
    WeldResult w;
    if (skin_allows(islands.islands)) {
      w = qm_.weld(islands.islands, islands.positions, weld_options_);
    } else {
      w.failure = WeldFailure::skin;
    }
    if (!w.ok()) {
      ++rejected_;
      if (pairing == Pairing::pair) {
        // The pair failed together. Each half the weld refuses on its own is refused as a single run would
        // be (its failing rungs blocked, so both sides leave the same rungs out); where neither is, they fail
        // only together, and the run goes alone later.
        const Polychord& trace_now = chords_[e.chord].trace;
        const bool run_fails =
            refused_alone({trace_now.rungs.begin() + candidate.first, trace_now.rungs.begin() + candidate.last + 1});
        const bool mirror_fails = !mirror.covers && refused_alone(mirror.rungs);
        if (mirror.covers && run_fails) {
          refuse(e.chord, candidate);
        } else if (run_fails || mirror_fails) {
          refuse_pair(e.chord, candidate, mirror, run_fails, mirror_fails);
        } else {
          requeue_alone(e.chord);
        }
        continue;
      }
      refuse(e.chord, candidate);
      continue;
    }
    for (std::size_t k = 0; k < w.survivors.size(); ++k) quadric_[w.survivors[k]] = islands.quadrics[k];
    carry_attributes(w);
    if (!mirror_.empty()) update_mirror(islands.islands, w.survivors);
    error_bound_ = std::max(error_bound_, islands.max_error);
    ++collapses_;
    if (pairing == Pairing::pair && mirror.covers) {
      ++paired_;  // one run that holds its image
    } else if (pairing == Pairing::pair) {
      ++collapses_;
      paired_ += 2;
    }
    invalidate_around(w);
  }

  result.triangles_after = qm_.triangle_count();
  result.quads_after = qm_.face_kinds().quads;
  result.target_reached = stop_.reached(result.triangles_after);
  result.error_bound_abs = error_bound_;
  result.collapses = collapses_;
  result.paired_collapses = paired_;
  result.rejected = rejected_;
  result.over_budget = over_budget_;
  result.diagonal_collapses = diagonal_collapses_;
  return result;
}

}  // namespace

bool run_allowed(const Polychord& chord, std::size_t first, std::size_t last) {
  if (first > last || last >= chord.rungs.size()) return false;
  std::vector<long long> conflict, last_rung;
  rung_conflicts(chord, conflict, last_rung);
  for (std::size_t k = first; k <= last; ++k) {
    if (conflict[k] >= static_cast<long long>(first)) return false;
  }
  return true;
}

PolychordResult simplify_polychord(const Mesh& mesh, const PolychordOptions& options) {
  if (!(options.target_ratio > 0.0 && options.target_ratio <= 1.0)) {
    throw std::invalid_argument("polychord: target_ratio must be in (0, 1], got " + std::to_string(options.target_ratio));
  }
  if (!(options.max_flip_angle_deg > 0.0 && options.max_flip_angle_deg < 90.0)) {
    throw std::invalid_argument("polychord: max_flip_angle_deg must be in (0, 90)");
  }
  auto finite_non_negative = [](double x) { return x >= 0.0 && std::isfinite(x); };
  if (!finite_non_negative(options.triangle_penalty) || !finite_non_negative(options.worst_rung_weight) ||
      !(options.max_triangle_fraction >= 0.0) || !(options.over_budget_factor >= 1.0) ||
      !(options.hard_budget_factor >= 1.0) || options.seed_rungs < 1 || std::isnan(options.max_error_abs) ||
      !finite_non_negative(options.diagonal_factor) || !finite_non_negative(options.diagonal_gate) ||
      !finite_non_negative(options.normal_weight) || !finite_non_negative(options.uv_weight) ||
      !finite_non_negative(options.color_weight) || !finite_non_negative(options.attribute_cost_weight)) {
    throw std::invalid_argument(
        "polychord: triangle_penalty, worst_rung_weight, diagonal_factor, diagonal_gate and the attribute weights "
        "must be finite and "
        ">= 0, max_triangle_fraction >= 0, over_budget_factor and hard_budget_factor >= 1, seed_rungs >= 1, "
        "max_error_abs not NaN");
  }
  for (std::uint32_t v : options.locked_vertices) {
    if (v >= mesh.vertex_count()) {
      throw std::invalid_argument("polychord: locked vertex " + std::to_string(v) + " out of range (" +
                                  std::to_string(mesh.vertex_count()) + " vertices)");
    }
  }
  const FaceKindCounts kinds = count_face_kinds(mesh);
  Mesh recovered;
  std::size_t made = 0;
  const bool recover = options.recover_quads && kinds.quads == 0 && kinds.triangles > 0;
  if (recover) recovered = recover_quads(mesh, {}, &made);
  const Mesh& input = recover ? recovered : mesh;
  const std::size_t input_triangles = mesh.triangle_count();
  const StopRule stop = StopRule::make(input_triangles,
                                      {.target_ratio = options.target_ratio,
                                       .target_triangles = options.target_triangles,
                                       .max_error_abs = options.max_error_abs},
                                      0.0);
  Engine engine(input, options, stop);
  PolychordResult r = engine.run();
  r.recovered_quads = made;
  // Triangles left by neighbouring runs often pair up into quads without moving anything (quad_recovery.hpp:
  // nearly coplanar pairs whose shared edge is the longest side and the quad's shorter diagonal, so that it
  // splits back into the same triangles, and whose other diagonal is not an edge).
  if (count_face_kinds(r.mesh).triangles >= 2) {
    r.mesh = recover_quads(r.mesh, {.keep_triangles = true}, &r.paired_triangles);
    r.quads_after += r.paired_triangles;
  }
  r.quads_before = kinds.quads;
  return r;
}

}  // namespace lodforge::quad
