// The working mesh of the triangle engines (edge_collapse.cpp: greedy QEM; multiple_choice.cpp: Wu-Kobbelt):
// what a vertex may do, the cost and placement of a candidate, the checks that refuse one, and the rewrite
// that applies one. Engine-internal: call lodforge::simplify(). Its methods live in collapse_mesh.cpp (setup,
// evaluation, topology checks, commit, output) and seam_rules.cpp (seams, attributes, UVs, skin).
//
// The working mesh is a triangle list with per-vertex face lists (CSR-like pool; a list is rewritten in place
// or moved to the end of the pool when a collapse makes it grow; the lists are packed to the front when the
// pool's reserve runs out, instead of reallocating it), per-vertex quadrics and positions in double,
// normalised to the unit cube. Vertex and wedge ids are those of the input mesh throughout; only the output is
// compacted.
//
// One collapse a → b (a disappears, b survives, moved to x):
//
//          c                          c
//        /   \                        |
//   ...a  f0   b...        →     ...  b  ...      f0 = a-b-c and f1 = a-b-d die; the edges a-c and b-c
//        \ f1 /                       |          (a-d and b-d) become one; every other face of a now
//          d                          d          names b; Q_b += Q_a
//
#pragma once

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <memory>
#include <new>
#include <optional>
#include <span>
#include <type_traits>
#include <utility>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>
#include <tbb/task_arena.h>

#include "lodforge/core/mesh.hpp"
#include "lodforge/eval/bvh.hpp"
#include "lodforge/metric/attribute_quadric.hpp"
#include "lodforge/metric/quadric.hpp"
#include "lodforge/simplify/policies.hpp"
#include "lodforge/simplify/simplify.hpp"

namespace lodforge::collapse {

// What a vertex may do, decided once from topology, wedges, materials and options.
// A corner's *key* is its wedge and its face's material (from SeamStage::corners on, wedges of one vertex
// that the stage counts as one share a key, see relax()): a vertex with two keys sits on a seam (UV seam, hard
// edge or material boundary), with three or more where seams meet.
enum class VertexKind : std::uint8_t {
  interior,  // manifold, closed fan, one key: may move and be removed
  border,    // manifold, open fan (on one boundary loop), one key: may move and be removed; constraint planes
  seam,      // manifold fan (closed or open), two keys: collapses only along its seam (the wedge check), both
             // sides together; held near the seam line by constraint planes on its seam edges
  complex,   // three or more keys (seams meet: cube corners, chart corners): never moves, never removed (no
             // wedge mapping can carry it), a neighbour may collapse onto it
  locked,    // never moves, never removed; a neighbour may collapse onto it: user locks, borders in lock mode,
             // painted priority at or above priority_lock, non-manifold stars (edges with > 2 faces, several
             // fans), inconsistent orientation around it
  frozen,    // takes part in no collapse at all: its position is NaN/Inf, so no cost or test involving it means
             // anything
};
inline constexpr int kVertexKinds = 6;

// How edge (u, v) collapses, by the kinds of its endpoints.
enum class EdgeRule : std::uint8_t {
  forbidden,  // never collapses
  optimal,    // full-edge collapse to the quadric's optimal placement
  keep_u,     // half-edge collapse v → u (u is pinned: it stays where it is)
  keep_v,     // half-edge collapse u → v
  either,     // half-edge collapse onto the cheaper endpoint (SeamStage::uv on, an endpoint complex)
};

// kEdgeRule[kind(u)][kind(v)]. Rule of thumb: pinned vertices (complex, locked) attract, frozen ones repel, a
// seam vertex attracts non-seam ones (it may not leave its seam for them) and moves freely with another seam
// vertex (along their seam: the wedge check), the rest is free. Which wedges map where (and so whether
// the edge really runs along the seam), topology (link condition, boundary pinch), UV flips and skinning are
// checked per collapse, not here.
inline constexpr EdgeRule kEdgeRule[kVertexKinds][kVertexKinds] = {
    // v: interior          border             seam               complex            locked             frozen
    {EdgeRule::optimal, EdgeRule::optimal, EdgeRule::optimal, EdgeRule::keep_v, EdgeRule::keep_v,
     EdgeRule::forbidden},  // u interior
    {EdgeRule::optimal, EdgeRule::optimal, EdgeRule::optimal, EdgeRule::keep_v, EdgeRule::keep_v,
     EdgeRule::forbidden},  // u border
    {EdgeRule::optimal, EdgeRule::optimal, EdgeRule::optimal, EdgeRule::keep_v, EdgeRule::keep_v,
     EdgeRule::forbidden},  // u seam
    {EdgeRule::keep_u, EdgeRule::keep_u, EdgeRule::keep_u, EdgeRule::forbidden, EdgeRule::forbidden,
     EdgeRule::forbidden},  // u complex
    {EdgeRule::keep_u, EdgeRule::keep_u, EdgeRule::keep_u, EdgeRule::forbidden, EdgeRule::forbidden,
     EdgeRule::forbidden},  // u locked
    {EdgeRule::forbidden, EdgeRule::forbidden, EdgeRule::forbidden, EdgeRule::forbidden, EdgeRule::forbidden,
     EdgeRule::forbidden},  // u frozen
};

// Check-time refusals are the public Veto (simplify.hpp), under the engines' name too.
using lodforge::Veto;


// Small helpers shared by collapse_mesh.cpp, seam_rules.cpp and the engines.

inline bool finite3(const Vec3d& p) { return std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]); }

// Local corner of vertex v in face t (t has three vertices, one of them v).
inline int corner_of(const std::uint32_t* t, std::uint32_t v) { return t[0] == v ? 0 : (t[1] == v ? 1 : 2); }

inline constexpr int kNext[3] = {1, 2, 0};
inline constexpr int kPrev[3] = {2, 0, 1};

// Insertion sort for the short lists of one vertex star (valence ~6), std::sort beyond.
template <typename T>
void small_sort(T* p, std::size_t n) {
  if (n > 32) {
    std::sort(p, p + n);
    return;
  }
  for (std::size_t i = 1; i < n; ++i) {
    const T x = p[i];
    std::size_t j = i;
    for (; j > 0 && x < p[j - 1]; --j) p[j] = p[j - 1];
    p[j] = x;
  }
}

// The steps per edge of the grid for_each_grid_point lays on triangle abc: about `spacing` apart, at most
// `max_steps`; 0 (no grid) where the triangle is no longer than that.
inline constexpr int kMaxGrid = 6;
inline int grid_steps(const Vec3d& a, const Vec3d& b, const Vec3d& c, double spacing, int max_steps = kMaxGrid) {
  if (!(spacing > 0)) return 0;
  const double longest = std::sqrt(std::max({dot(b - a, b - a), dot(c - b, c - b), dot(a - c, a - c)}));
  if (!(longest > spacing)) return 0;  // small: its corners and centroid are close enough together
  return static_cast<int>(std::min(std::ceil(longest / spacing), double(max_steps)));
}

// Calls f(p) for the points of the grid of grid_steps() inside triangle abc (not the corners), until f returns
// false; false if it did. Points of a coarser grid of `skip_steps` steps on the same triangle (bit for bit the
// same points, already visited by the caller) are skipped.
template <typename F>
bool for_each_grid_point(const Vec3d& a, const Vec3d& b, const Vec3d& c, double spacing, F&& f, int skip_steps = 0,
                         int max_steps = kMaxGrid) {
  const int steps = grid_steps(a, b, c, spacing, max_steps);
  for (int i = 0; i <= steps; ++i) {
    for (int j = 0; i + j <= steps; ++j) {
      if (i == steps || j == steps || i + j == 0) continue;  // the corners
      if (skip_steps > 0 && (i * skip_steps) % steps == 0 && (j * skip_steps) % steps == 0) continue;
      const double u = double(i) / steps, v = double(j) / steps;
      if (!f(a + (b - a) * u + (c - a) * v)) return false;
    }
  }
  return true;
}

// The points where an error budget measures a triangle abc of an output against the reference: its centroid;
// with a `spacing`, also its edge midpoints and the grid of for_each_grid_point. Stops when f returns false;
// false if it did.
template <typename F>
bool for_each_face_sample(const Vec3d& a, const Vec3d& b, const Vec3d& c, double spacing, F&& f) {
  if (!f((a + b + c) * (1.0 / 3.0))) return false;
  if (!(spacing > 0)) return true;
  return f((a + b) * 0.5) && f((b + c) * 0.5) && f((c + a) * 0.5) && for_each_grid_point(a, b, c, spacing, f);
}

// An error budget held during the run (budget.cpp): a collapse is refused (Veto::error_budget) unless every
// sample point of the reference stays within `budget` of the faces around the collapse, and the moved vertex,
// the new faces' sample points (for_each_face_sample with `grid_spacing`) stay within `budget` of the
// reference. The samples include those the measurement after the run takes, so the output
// passes its sampled part by construction. Model units.
inline constexpr std::uint32_t kCentroidOrigin = 0x80000000u;
struct GuardReference {
  const TriangleBvh* bvh = nullptr;  // the reference surface
  std::span<const Vec3d> samples;    // its vertices and triangle centroids
  // Where the reference is the engine's input: per sample, its vertex, or its triangle | kCentroidOrigin (the
  // samples are then attached without a search). Empty otherwise.
  std::span<const std::uint32_t> origins;
  // Otherwise, optionally: per sample, a face of the input (input order) to attach it to where it is within the
  // budget of it (a previous LOD's attachments); the others are attached to their nearest face.
  std::span<const std::uint32_t> start_faces;
  double budget = 0;
  double grid_spacing = 0;
  // Boxes (model units) where an earlier run's output had a point over the budget: new faces that reach into
  // one are also tested on a fine grid there, fine enough that passing it holds every point of the face.
  std::span<const Bounds3> dense_regions;
  // Filled at the end of the run where not null: per output triangle, in output order, an upper bound on its
  // distance to the reference (model units; +inf where none is known), from the points the guard tested.
  std::vector<double>* face_bounds = nullptr;
  // Filled at the end where not null: per sample, the output triangle (output order) it is attached to, within
  // the budget of it; kInvalidIndex where none.
  std::vector<std::uint32_t>* sample_faces = nullptr;
};

inline double elapsed_ms(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - since).count();
}

// Runs loops of independent iterations inside a task arena of `threads` workers (0 = all cores); one thread
// runs them inline. Iterations write disjoint outputs, so results never depend on the thread count.
class Parallel {
 public:
  explicit Parallel(unsigned threads);
  unsigned concurrency() const { return concurrency_; }
  // f(begin, end) over [0, n) in chunks of at least `grain`.
  template <typename F>
  void for_ranges(std::size_t n, std::size_t grain, F&& f) {
    if (n == 0) return;
    if (concurrency_ <= 1 || n <= grain) {
      f(std::size_t{0}, n);
      return;
    }
    arena_.execute([&] {
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, grain),
                        [&](const tbb::blocked_range<std::size_t>& r) { f(r.begin(), r.end()); });
    });
  }

  // std::sort of [begin, end), in parallel when it is large. Only for a strict total order: the result is then
  // the one sorted sequence, whatever the threads do.
  template <typename It, typename Less>
  void sort(It begin, It end, Less&& less) {
    if (concurrency_ <= 1 || end - begin < 16384) {
      std::sort(begin, end, less);
      return;
    }
    arena_.execute([&] { tbb::parallel_sort(begin, end, less); });
  }

 private:
  unsigned concurrency_ = 1;
  tbb::task_arena arena_;
};

// std::allocator, except that resize() constructs nothing: the caller constructs each new element (placement
// new) before using it, so that a large array is first touched, page by page, by the threads that fill it rather
// than by one thread's memset. Only for trivially destructible types.
template <typename T>
struct UnconstructedAllocator : std::allocator<T> {
  template <typename U>
  struct rebind {
    using other = UnconstructedAllocator<U>;
  };
  UnconstructedAllocator() = default;
  template <typename U>
  UnconstructedAllocator(const UnconstructedAllocator<U>&) noexcept {}
  template <typename U>
  void construct(U*) noexcept {}
  template <typename U, typename... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

// An evaluated candidate collapse of edge (u, v), u < v.
struct Evaluation {
  double cost = 0;     // ordering key: the quadric error E(position), area-weighted (GH97), plus the reduced
                       // attribute quadrics of the merged wedges (Hoppe 1999) and the skinning term
  double error = 0;    // surface quadric error / accumulated area: a mean squared distance, normalised units
  Vec3d position{};    // where the survivor goes, normalised coordinates
};

// Result of checking a candidate at pop time.
struct Check {
  Veto veto = Veto::none;
  std::uint32_t victim = kInvalidIndex, survivor = kInvalidIndex;
  std::uint32_t edge_faces[2] = {kInvalidIndex, kInvalidIndex};
  std::uint32_t edge_face_count = 0;
  bool boundary = false;  // the survivor will be on the boundary
  std::uint32_t list_begin = 0, list_capacity = 0;  // where the survivor's merged face list goes (reserve())
  bool reattach = false;  // SeamStage::uv on: the victim's wedges the edge faces do not pair go to the survivor
  bool ok() const { return veto == Veto::none; }
};

// Per-thread scratch of check(), ring() and apply(); reused to avoid per-collapse allocations.
struct Scratch {
  std::vector<std::uint32_t> na, nb;    // check(): stars of a and b (neighbour after / before in each face)
  std::vector<std::uint32_t> mark;      // check() on large stars: mark[v] == stamp, v is in the list stamped
  std::uint32_t stamp = 0;
  std::uint64_t work = 0;               // check(): list entries visited and compared (tests count it)
  std::vector<std::uint32_t> ring;      // ring() output; apply(): the survivor's merged face list
  std::vector<std::uint64_t> spokes;    // setup: neighbour << 32 | face code
  std::vector<std::uint32_t> parent;    // setup: fan union-find
  std::vector<std::uint32_t> wedge_map;  // attribute mode: victim wedge, target wedge pairs (check, apply)
  std::vector<double> attr;              // attribute mode: one merged wedge's optimal attributes
  std::vector<std::array<Vec3d, 3>> fan;  // guard: the faces a collapse leaves around the new vertex
  std::vector<std::uint32_t> fan_face;    // guard: their face ids
  std::vector<std::uint32_t> moved;       // guard: samples being attached to new faces
  std::vector<std::array<double, 4>> fan_plane;  // guard: the fan faces' unit normals and offsets
};

class CollapseMesh {
 public:
  // `triangles` must hold triangles only (simplify() triangulates first). Faces with out-of-range indices or
  // a repeated vertex are dropped; they carry no surface (a mesh may be left with none). Throws
  // std::invalid_argument for out-of-range locked vertex ids. `policies` (may be null) outlives the mesh;
  // evaluate() and check() consult its placement, cost and filter.
  // `guard` (may be null) holds an error budget during the run; its surface and samples outlive the mesh.
  CollapseMesh(const Mesh& triangles, const SimplifyOptions& options, Parallel& parallel,
               const CollapsePolicies* policies = nullptr, const GuardReference* guard = nullptr);

  std::size_t alive_faces() const { return alive_faces_; }
  std::size_t vertex_count() const { return vx_.size(); }
  double scale() const { return scale_; }  // normalised length × scale = model length
  double diagonal() const { return diagonal_; }  // of the input's bounding box, model units

  bool alive(std::uint32_t v) const { return (state_[v] & kDead) == 0; }
  std::uint32_t version(std::uint32_t v) const { return version_[v]; }
  VertexKind kind(std::uint32_t v) const { return kind_[v]; }
  EdgeRule rule(std::uint32_t u, std::uint32_t v) const {
    const EdgeRule r = kEdgeRule[static_cast<int>(kind_[u])][static_cast<int>(kind_[v])];
    if (stage_ >= SeamStage::uv && movable_corner(u, v)) return EdgeRule::either;
    if (rim_.empty() || r != EdgeRule::optimal || (rim_[u] | rim_[v]) == 0) return r;
    // Conservative modes on an open mesh: rim vertices never move; a straight one may go onto a rim neighbour.
    if (rim_[u] != 0 && rim_[v] != 0) {
      return rim_[v] == kRimStraight   ? EdgeRule::keep_u
             : rim_[u] == kRimStraight ? EdgeRule::keep_v
                                       : EdgeRule::forbidden;
    }
    return rim_[u] != 0 ? EdgeRule::keep_u : EdgeRule::keep_v;
  }

  // Seam relaxation (SeamStage). stage() is the stage in force; relax() moves to the next stage the options
  // allow, recomputes the corner keys and vertex kinds, and returns false when there is none. Every candidate
  // must be evaluated again afterwards (rules and costs change).
  SeamStage stage() const { return stage_; }
  bool relax();
  // Whether a checked collapse would remove the last triangles of a material (refused from SeamStage::corners
  // on; the counts change in reserve(), so call it in commit order).
  bool removes_last_material(const Check& c) const;
  // Why edge (u, v) may never collapse, for a forbidden rule: "locked", "non_manifold", "seams_kept",
  // "materials_kept" or "topology".
  const char* forbidden_reason(std::uint32_t u, std::uint32_t v) const;
  // Cost and placement of collapsing edge (u, v), u < v, rule not forbidden. Thread-safe (reads only).
  // Placement: the surface quadric's minimiser where it is well conditioned, else the minimiser with the
  // rubber band added (or the best point of the edge); a locked endpoint stays where it is. Placement and
  // error never depend on the attribute and skin terms, so without `with_cost` they are left out (cost is
  // then the surface's alone): for callers that only need where the vertex goes and how far.
  Evaluation evaluate(std::uint32_t u, std::uint32_t v, bool with_cost = true) const;
  // evaluate() and check() as the caller's policies see them: model units.
  CollapseCandidate candidate(std::uint32_t u, std::uint32_t v, const Evaluation& ev) const;
  // A normalised squared error (Evaluation::error) as a distance in model units.
  double model_error(double error) const { return std::sqrt(error) * scale_; }
  Vec3d model_position(const Vec3d& x) const { return origin_ + x * scale_; }
  // Topology, fold and seam tests of collapsing (u, v) to `x`; chooses which endpoint survives. Reads only.
  Check check(std::uint32_t u, std::uint32_t v, const Vec3d& x, Scratch& scratch) const;
  // Applies a checked collapse in two steps: reserve() makes room for the survivor's merged face list (it
  // may grow the pool, so nothing else may run meanwhile); apply() then rewrites the neighbourhood. apply()
  // calls for collapses with disjoint closed neighbourhoods may run concurrently. commit() does both.
  void reserve(Check& c);
  void apply(const Check& c, const Vec3d& x, Scratch& scratch);
  // The most pool entries reserve(c) appends. make_room(n), called before a series of reserve() calls whose
  // list_room() add up to n, packs the face lists when the pool lacks that room, so that the pool does not
  // reallocate (twice its size, and a copy, at the peak).
  std::size_t list_room(const Check& c) const;
  void make_room(std::size_t entries);
  void commit(Check c, const Vec3d& x, Scratch& scratch);
  // Conservative modes (SimplifyOptions::conservative): whether moving the survivor of (a, b) to x keeps it on
  // the allowed side of the plane of every face around a and b, by at least a small slack (faces with a
  // corner at x itself are unchanged or vanish and are skipped). Always true in mode none. Reads only.
  bool conservative_ok(std::uint32_t a, std::uint32_t b, const Vec3d& x) const;
  // The signed volume the collapse of (a, b) to x adds to the solid (model units³): the sum of the tetrahedra
  // x makes with the faces around a and b.
  double volume_change(std::uint32_t a, std::uint32_t b, const Vec3d& x) const;
  // The input's signed volume (model units³), from the working faces at setup; 0 in mode none.
  double input_volume() const { return input_volume_; }
  // Squared distances of the input points u and v track (far_) to the fan that collapsing (u, v) to x leaves.
  // A point found within `enough` of a face is not measured further (its distance is then some value within
  // `enough`, not the least): the callers that compare against a threshold need no more.
  std::array<double, 2> far_distances(std::uint32_t u, std::uint32_t v, const Vec3d& x,
                                      double enough = -1.0) const;

  // Hints that v's record will be read soon. The greedy order jumps around the mesh, so most records are
  // cold; asking for a whole ring at once lets the memory system fetch them in parallel.
  void prefetch(std::uint32_t v) const {
    const char* p = reinterpret_cast<const char*>(&vx_[v]);
    __builtin_prefetch(p);
    __builtin_prefetch(p + 64);
  }
  // Number of faces around v; v has at most twice as many neighbours.
  std::uint32_t star_size(std::uint32_t v) const { return size_[v]; }
  // Distinct neighbours of v (not v itself), in a deterministic order.
  void ring(std::uint32_t v, std::vector<std::uint32_t>& out) const;
  // Whether u and v share a face (both alive).
  bool adjacent(std::uint32_t u, std::uint32_t v) const {
    if (!alive(u) || !alive(v) || u == v) return false;
    if (size_[v] < size_[u]) std::swap(u, v);
    const std::uint32_t* fl = star(u);
    for (std::uint32_t i = 0; i < size_[u]; ++i) {
      const std::uint32_t* t = &tri_[3 * std::size_t{fl[i]}];
      if (t[0] == v || t[1] == v || t[2] == v) return true;
    }
    return false;
  }
  // Hints that the face list of v will be read soon.
  void prefetch_star(std::uint32_t v) const { __builtin_prefetch(star(v)); }
  void prefetch_version(std::uint32_t v) const { __builtin_prefetch(&version_[v]); }
  // What reserve() and list_room() read of v's face list.
  void prefetch_list(std::uint32_t v) const {
    __builtin_prefetch(&begin_[v]);
    __builtin_prefetch(&size_[v]);
    __builtin_prefetch(&capacity_[v]);
  }
  // Calls f(w) for every vertex of every face of u and of v (with repeats): their closed neighbourhood.
  template <typename F>
  void for_each_closed_ring_vertex(std::uint32_t u, std::uint32_t v, F&& f) const {
    for (std::uint32_t s : {u, v}) {  // the faces are scattered: ask for all of them before reading one
      const std::uint32_t* fl = star(s);
      for (std::uint32_t i = 0; i < size_[s]; ++i) __builtin_prefetch(&tri_[3 * std::size_t{fl[i]}]);
    }
    for (std::uint32_t s : {u, v}) {
      const std::uint32_t* fl = star(s);
      for (std::uint32_t i = 0; i < size_[s]; ++i) {
        const std::uint32_t* t = &tri_[3 * std::size_t{fl[i]}];
        f(t[0]);
        f(t[1]);
        f(t[2]);
      }
    }
  }
  // Alive faces, for sampling (multiple choice): face ids and the corner vertices of a face.
  bool face_alive(std::uint32_t f) const { return tri_[3 * std::size_t{f}] != kInvalidIndex; }
  std::size_t face_slots() const { return tri_.size() / 3; }
  std::uint32_t face_vertex(std::uint32_t f, int corner) const { return tri_[3 * std::size_t{f} + corner]; }
  // Cache hints for sampling engines, which read scattered faces and vertices.
  void prefetch_face(std::uint32_t f) const { __builtin_prefetch(&tri_[3 * std::size_t{f}]); }
  void prefetch_vertex(std::uint32_t v) const {
    __builtin_prefetch(&vx_[v]);
    __builtin_prefetch(&kind_[v]);
  }

  // The simplified mesh: alive faces in input order, referenced wedges and vertices compacted in id order,
  // unmoved vertices bit-identical to the input.
  Mesh output() const;
  // Guarded runs whose GuardReference asked for them: writes the per-face bounds in output() order and the
  // samples' faces.
  void store_guard_outputs() const;

 private:
  // SeamStage::uv on: an edge with a complex endpoint whose other endpoint is not pinned (locked or frozen).
  bool movable_corner(std::uint32_t u, std::uint32_t v) const {
    const VertexKind ku = kind_[u], kv = kind_[v];
    auto pinned = [](VertexKind k) { return k == VertexKind::locked || k == VertexKind::frozen; };
    return (ku == VertexKind::complex || kv == VertexKind::complex) && !pinned(ku) && !pinned(kv);
  }
  bool reattach_ok(std::uint32_t a, std::uint32_t b, const Check& c) const;
  // Conservative modes: the quadric (with the rubber band) minimised over the allowed side of the face planes
  // around u and v, rounded to the output's float grid; nullopt when no allowed point is found.
  std::optional<Vec3d> conservative_place(std::uint32_t u, std::uint32_t v, const Quadric& surface) const;
  // `surface` plus the rubber band of edge (u, v): `weight` per anchor towards the anchors' positions.
  Quadric with_rubber_band(const Quadric& surface, std::uint32_t u, std::uint32_t v, double weight) const;
  // x as the output will write it (rounded to float in model units), in normalised coordinates.
  Vec3d output_rounded(const Vec3d& x) const;
  std::uint32_t face_material(std::uint32_t f) const {
    const std::uint32_t sf = source_face(f);
    return sf < src_.face_material.size() ? src_.face_material[sf] : 0u;
  }
  // Distinct keys around v, counted up to 3.
  int count_keys(std::uint32_t v) const;
  // v's kind (interior, border, seam or complex) and state bits from its key count.
  void reclassify(std::uint32_t v);
  // kFan: a single, consistently oriented manifold fan (interior, border and seam vertices), whose boundary
  // status kOpen is kept exact by apply(); check() and ring() take their fast paths on it.
  static constexpr std::uint8_t kDead = 1, kMoved = 2, kSeam = 4, kFan = 8, kOpen = 16;
  // v's face list (size_[v] entries). Pointer arithmetic, not &pool_[i]: the pool is empty on a mesh without
  // faces, and a list may start at its end.
  const std::uint32_t* star(std::uint32_t v) const { return pool_.data() + begin_[v]; }
  std::uint32_t* star(std::uint32_t v) { return pool_.data() + begin_[v]; }
  std::uint32_t key(std::size_t corner) const { return tri_key_.empty() ? corner_wedge(corner) : tri_key_[corner]; }
  // Face f's corner wedges. Empty tri_wedge_: each vertex is its one wedge (see tri_wedge_).
  const std::uint32_t* face_wedges(std::size_t f) const {
    return tri_wedge_.empty() ? &tri_[3 * f] : &tri_wedge_[3 * f];
  }
  std::uint32_t corner_wedge(std::size_t corner) const {
    return tri_wedge_.empty() ? tri_[corner] : tri_wedge_[corner];
  }
  // The input face of working face f.
  std::uint32_t source_face(std::size_t f) const {
    return tri_source_.empty() ? static_cast<std::uint32_t>(f) : tri_source_[f];
  }
  bool flip_ok(const Vec3d& old_p, const Vec3d& x, const Vec3d& p, const Vec3d& q) const;
  bool wedges_carry_over(std::uint32_t a, std::uint32_t b, const Check& c) const;
  // The keys of a's and b's corners in the edge's faces; false where the faces pair them inconsistently (a
  // seam meets the edge at one end only).
  bool edge_corner_keys(std::uint32_t a, std::uint32_t b, const Check& c, std::uint32_t (&ka)[2],
                        std::uint32_t (&kb)[2]) const;
  // Victim wedge → target wedge of every distinct wedge around a (pairs in s.wedge_map, in a's face order).
  void map_wedges(std::uint32_t a, std::uint32_t b, const Check& c, Scratch& s) const;
  bool uv_ok(std::uint32_t a, std::uint32_t b, const Check& c, const Vec3d& x, Scratch& s) const;
  bool skin_ok(std::uint32_t a, std::uint32_t b) const;
  // Where x lies on a → b: 0 at a, 1 at b (clamped).
  double edge_t(std::uint32_t a, std::uint32_t b, const Vec3d& x) const;
  bool blends(std::uint32_t b, const Vec3d& x) const { return blend_ && !(vx_[b].pos == x); }
  // The new UV of target wedge wt (merging wx) in set `set` when the survivor moves to x.
  Vec2f new_uv(int set, std::uint32_t wx, std::uint32_t wt, const Vec3d& x, double t) const;
  SkinInfluences blended_skin(std::uint32_t a, std::uint32_t b, double t) const;
  void carry_attributes(const Check& c, const Vec3d& x, Scratch& s);
  void add_attribute_quadrics(std::uint32_t u, std::uint32_t v, Quadric& q) const;
  double skin_cost(std::uint32_t u, std::uint32_t v) const;
  void setup_keys();
  void setup_priority(std::vector<float>& priority) const;
  void setup(Parallel& parallel);
  void setup_attributes(Parallel& parallel);
  void setup_conservative();
  void setup_rim();
  // Guarded budget (budget_guard.cpp): each reference sample attached to its nearest working face at the start;
  // guard_ok() is check()'s last test, guard_reattach() moves the samples of the faces apply() changed.
  void setup_guard(const GuardReference& guard, Parallel& parallel);
  bool guard_ok(std::uint32_t a, std::uint32_t b, const Check& c, const Vec3d& x, Scratch& s) const;
  // `b_moved`: the survivor moved; `kept`: how many faces at the head of its list were its own and unchanged.
  void guard_reattach(const Check& c, Scratch& s, bool b_moved, std::size_t kept);
  bool face_within(const Vec3d& p, const Vec3d& q, const Vec3d& r, std::uint32_t& hint) const;
  bool in_dense_region(const Vec3d& p, const Vec3d& q, const Vec3d& r) const;
  // The steps per edge of the densest grid face_within() tests on pqr (model units).
  int guard_steps(const Vec3d& p, const Vec3d& q, const Vec3d& r) const;
  // An upper bound on the distance of triangle pqr (model units) to the reference, given bounds on its corners'
  // distances and that its guard samples passed.
  double guarded_face_bound(const Vec3d& p, const Vec3d& q, const Vec3d& r, double corners) const;

  const Mesh& src_;
  SimplifyOptions options_;
  const CollapsePolicies* policies_ = nullptr;  // null or with no member set: built-in behaviour only
  Vec3d origin_{};
  double scale_ = 1.0;
  double diagonal_ = 0.0;
  double cos_max_flip_ = 0.5;
  int height_field_axis_ = -1;  // SimplifyOptions::height_field_axis
  double weight_floor_ = 1e-30;  // keeps cost = E / W finite where all faces are degenerate
  double reg_weight_ = 0.0;      // rubber-band weight per anchor
  double mean_area_ = 0.0;       // of the input's faces, normalised units
  // Conservative modes: +1 bounding, -1 occluder, 0 none (the side of a face plane a new vertex must be on).
  double cons_side_ = 0.0;
  double cons_slack_ = 0.0;      // normalised distance a tested point must clear a plane by
  double cons_margin_ = 0.0;     // the same for the placement solve, plus what float rounding may take away
  double cons_band_ = 0.0;       // rubber-band weight per anchor in the placement solve (> 0: A positive definite)
  double input_volume_ = 0.0;    // model units³
  double cons_volume_weight_ = 0.0;  // bounding: the added volume's weight in the ordering key
  // Conservative modes on a mesh with a boundary: per vertex, 0 (not on it), kRimStraight (its two boundary
  // edges are collinear seen along the mesh's dominant axis: it may be removed onto a boundary neighbour) or
  // kRimFixed (a corner of the rim: kept). Rim vertices never move. Empty otherwise.
  static constexpr std::uint8_t kRimStraight = 1, kRimFixed = 2;
  std::vector<std::uint8_t> rim_;

  // What a candidate evaluation reads about a vertex, in two adjacent cache lines.
  struct alignas(64) Vertex {
    Quadric quadric;  // surface: area-weighted face planes and boundary constraint planes
    Vec3d pos{};      // normalised
    // Rubber band (van den Bergen 2021): the original positions this vertex stands for, as a count and a sum
    // (float: it only steers placement in directions the surface quadric leaves free).
    float anchors = 0.0f;
    Vec3f anchor_sum{};
  };
  static_assert(sizeof(Vertex) == 128);
  static_assert(std::is_trivially_destructible_v<Vertex>);
  std::vector<Vertex, UnconstructedAllocator<Vertex>> vx_;  // constructed by the threads that first fill it
  // With an error budget: per vertex, the input point it absorbed that is farthest from its fan (normalised
  // coordinates; a proxy for the input → LOD distance, which the quadric does not see). Empty otherwise.
  std::vector<Vec3d> far_;
  // Small per-vertex arrays read by staleness tests and edge rules: dense, so they stay in cache.
  std::vector<std::uint32_t> version_;
  std::vector<VertexKind> kind_;
  std::vector<std::uint8_t> state_;
  // Written whole by the constructor's parallel pass, so left unconstructed by resize().
  using FaceArray = std::vector<std::uint32_t, UnconstructedAllocator<std::uint32_t>>;
  FaceArray tri_;         // 3 vertices per face; tri_[3f] == kInvalidIndex: dead
  // 3 wedges per face; empty while every corner's wedge is its vertex (one wedge per vertex, wedge id = vertex
  // id: meshes with positions and per-vertex attributes only), which collapses keep true until a seam stage may
  // move a wedge to another vertex (relax() then fills it). Saves 12 bytes a triangle on large scans.
  FaceArray tri_wedge_;
  FaceArray tri_source_;  // input face of each working face; empty when that is face f itself (4 bytes a face)
  std::vector<std::uint32_t> begin_, size_, capacity_;  // per-vertex face lists in pool_
  std::vector<std::uint32_t> pool_;
  std::size_t alive_faces_ = 0;

  // --- seams, attributes, skin ---
  std::vector<std::uint32_t> tri_key_;  // key of each corner when it is not simply the wedge (see VertexKind)
  AttributeLayout layout_;                 // attribute_layout() (metric/attribute_quadric.hpp); dims 0: geometry only
  std::vector<AttributeQuadric> wq_;       // per wedge
  std::vector<AttributeGradient> wg_;      // layout_.dims per wedge
  bool blend_ = false;                     // attribute_placement optimal: moved wedges get new values
  bool carry_ = false;                     // apply() has attribute work to do
  double skin_cost_scale_ = 0.0;           // λ_skin × L² (0: no skin term)
  int skin_cap_ = 0;                       // most influences any input vertex uses
  // Working copies of what collapses change (empty when the input lacks them).
  std::vector<Vec3f> normals_;
  std::vector<std::vector<Vec2f>> uvs_;
  std::vector<std::vector<Vec4f>> colors_;
  std::vector<MorphTarget> morphs_;
  std::vector<SkinInfluences> skin_;
  std::vector<float> priority_;            // painted weight per vertex, empty when none

  // --- seam relaxation ---
  SeamStage stage_ = SeamStage::strict;
  SeamStage last_stage_ = SeamStage::strict;  // the last stage the options allow
  std::vector<std::uint8_t> lock_reason_;     // per vertex: 0, kLockedByUser or kLockedTopology
  static constexpr std::uint8_t kLockedByUser = 1, kLockedTopology = 2;
  std::vector<std::size_t> material_faces_;  // alive faces per material (from SeamStage::corners on)
  std::vector<std::uint32_t> wedge_vertex_;  // each wedge's vertex now (SeamStage::uv on; empty before)
  bool reattached_ = false;                  // a wedge changed vertex (the output uses wedge_vertex_)
  // The seam constraint planes within each vertex's quadric that lie within one material (empty when seams
  // never relax or no vertex has two wedges): relax() takes them out of the quadrics at its first stage.
  std::vector<Quadric> seam_q_;

  // --- error budget held during the run (GuardReference; empty without one) ---
  const TriangleBvh* guard_bvh_ = nullptr;
  double guard_budget_ = 0.0;          // model units, less a margin for rounding the output to float
  double guard_budget2_ = 0.0;         // the same, normalised and squared
  double guard_spacing_ = 0.0;         // model units
  std::vector<Bounds3> guard_dense_;   // GuardReference::dense_regions, model units
  std::vector<Vec3d> guard_samples_;   // normalised
  std::vector<std::uint32_t> guard_head_;  // per face: its first attached sample, kInvalidIndex if none
  std::vector<std::uint32_t> guard_next_;  // per sample: the next one attached to the same face
  std::vector<std::uint32_t> guard_hint_;  // per vertex: a reference triangle near it (query start)
  std::vector<double> guard_vertex_bound_;  // per vertex: an upper bound on its distance (model units)
  std::vector<double> guard_face_bound_;    // per face: an upper bound on its distance (model units)
  double guard_rounding_ = 0.0;             // what rounding the output to float may add to a distance
  std::vector<double>* guard_bounds_out_ = nullptr;
  std::vector<std::uint32_t>* guard_sample_faces_out_ = nullptr;
};

}  // namespace lodforge::collapse
