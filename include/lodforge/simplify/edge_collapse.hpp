// Machinery shared by the collapse engines (edge_collapse.cpp: greedy QEM; multiple_choice.cpp: Wu-Kobbelt).
// Not a user API: call lodforge::simplify(). It is a header so that both engines and their tests can use it.
//
// The working mesh is a triangle list with per-vertex face lists (CSR-like pool; a list is rewritten in place
// or moved to the end of the pool when a collapse makes it grow), per-vertex quadrics and positions in double,
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

#include <cstdint>
#include <utility>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "lodforge/core/mesh.hpp"
#include "lodforge/metric/quadric.hpp"
#include "lodforge/simplify/simplify.hpp"

namespace lodforge::collapse {

// What a vertex may do, decided once from topology and options.
enum class VertexKind : std::uint8_t {
  interior,  // manifold, closed fan: may move and be removed
  border,    // manifold, open fan (on one boundary loop): may move and be removed; constraint planes in preserve
  locked,    // never moves, never removed; a neighbour may collapse onto it: user locks, borders in lock mode,
             // non-manifold stars (edges with > 2 faces, several fans), inconsistent orientation around it
  frozen,    // takes part in no collapse at all: its position is NaN/Inf, so no cost or test involving it means
             // anything
};
inline constexpr int kVertexKinds = 4;

// How edge (u, v) collapses, by the kinds of its endpoints.
enum class EdgeRule : std::uint8_t {
  forbidden,  // never collapses
  optimal,    // full-edge collapse to the quadric's optimal placement
  keep_u,     // half-edge collapse v → u (u is locked: it stays where it is)
  keep_v,     // half-edge collapse u → v
};

// kEdgeRule[kind(u)][kind(v)]. Rule of thumb: locked vertices attract, frozen ones repel, the rest is free;
// topology (link condition, boundary pinch) is checked per collapse, not here.
inline constexpr EdgeRule kEdgeRule[kVertexKinds][kVertexKinds] = {
    //  v: interior          border             locked             frozen
    {EdgeRule::optimal, EdgeRule::optimal, EdgeRule::keep_v, EdgeRule::forbidden},      // u interior
    {EdgeRule::optimal, EdgeRule::optimal, EdgeRule::keep_v, EdgeRule::forbidden},      // u border
    {EdgeRule::keep_u, EdgeRule::keep_u, EdgeRule::forbidden, EdgeRule::forbidden},     // u locked
    {EdgeRule::forbidden, EdgeRule::forbidden, EdgeRule::forbidden, EdgeRule::forbidden},  // u frozen
};

// Why a candidate was refused at check time (for statistics and tests).
enum class Veto : std::uint8_t {
  none,
  not_an_edge,      // a and b share no face (stale candidate), or share more than two
  link_condition,   // a common neighbour that is not an apex: the collapse would glue two sheets together
  boundary_pinch,   // interior edge between two boundary vertices: would pinch the surface to one vertex
  dangling_face,    // the edge's face has its two other edges on the boundary: would leave a dangling edge
  tetrahedron,      // both faces c-d-a and c-d-b exist: the collapse would fold a tetrahedron flat
  fold,             // a face normal would turn by more than max_flip_angle_deg
  degenerate,       // a face would get (almost) zero area
  seam,             // wedges cannot be carried over without merging distinct attribute values
};

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

 private:
  unsigned concurrency_ = 1;
  tbb::task_arena arena_;
};

// An evaluated candidate collapse of edge (u, v), u < v.
struct Evaluation {
  double cost = 0;     // ordering key: the quadric error E(position), area-weighted (GH97)
  double error = 0;    // quadric error / accumulated area: a mean squared distance, normalised units
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
  bool ok() const { return veto == Veto::none; }
};

// Per-thread scratch of check(), ring() and apply(); reused to avoid per-collapse allocations.
struct Scratch {
  std::vector<std::uint32_t> na, nb;    // check(): stars of a and b (neighbour after / before in each face)
  std::vector<std::uint32_t> ring;      // ring() output; apply(): the survivor's merged face list
  std::vector<std::uint64_t> spokes;    // setup: neighbour << 32 | face code
  std::vector<std::uint32_t> parent;    // setup: fan union-find
};

class CollapseMesh {
 public:
  // `triangles` must hold triangles only (simplify() triangulates first). Faces with out-of-range indices or
  // a repeated vertex are dropped; they carry no surface. Throws std::invalid_argument for out-of-range
  // locked vertex ids.
  CollapseMesh(const Mesh& triangles, const SimplifyOptions& options, Parallel& parallel);

  std::size_t alive_faces() const { return alive_faces_; }
  std::size_t vertex_count() const { return vx_.size(); }
  double scale() const { return scale_; }  // normalised length × scale = model length
  double diagonal() const { return diagonal_; }  // of the input's bounding box, model units

  bool alive(std::uint32_t v) const { return (state_[v] & kDead) == 0; }
  std::uint32_t version(std::uint32_t v) const { return version_[v]; }
  VertexKind kind(std::uint32_t v) const { return kind_[v]; }
  EdgeRule rule(std::uint32_t u, std::uint32_t v) const {
    return kEdgeRule[static_cast<int>(kind_[u])][static_cast<int>(kind_[v])];
  }
  // Cost and placement of collapsing edge (u, v), u < v, rule not forbidden. Thread-safe (reads only).
  // Placement: the surface quadric's minimiser where it is well conditioned, else the minimiser with the
  // rubber band added (or the best point of the edge); a locked endpoint stays where it is.
  Evaluation evaluate(std::uint32_t u, std::uint32_t v) const;
  // Topology, fold and seam tests of collapsing (u, v) to `x`; chooses which endpoint survives. Reads only.
  Check check(std::uint32_t u, std::uint32_t v, const Vec3d& x, Scratch& scratch) const;
  // Applies a checked collapse in two steps: reserve() makes room for the survivor's merged face list (it
  // may grow the pool, so nothing else may run meanwhile); apply() then rewrites the neighbourhood. apply()
  // calls for collapses with disjoint closed neighbourhoods may run concurrently. commit() does both.
  void reserve(Check& c);
  void apply(const Check& c, const Vec3d& x, Scratch& scratch);
  void commit(Check c, const Vec3d& x, Scratch& scratch);

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
  // Calls f(w) for every vertex of every face of u and of v (with repeats): their closed neighbourhood.
  template <typename F>
  void for_each_closed_ring_vertex(std::uint32_t u, std::uint32_t v, F&& f) const {
    for (std::uint32_t s : {u, v}) {
      const std::uint32_t* fl = &pool_[begin_[s]];
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

  // The simplified mesh: alive faces in input order, referenced wedges and vertices compacted in id order,
  // unmoved vertices bit-identical to the input.
  Mesh output() const;

 private:
  static constexpr std::uint8_t kDead = 1, kMoved = 2, kSeam = 4;

  bool flip_ok(const Vec3d& old_p, const Vec3d& x, const Vec3d& p, const Vec3d& q) const;
  bool wedges_carry_over(std::uint32_t a, std::uint32_t b, const Check& c) const;
  void setup(Parallel& parallel);

  const Mesh& src_;
  SimplifyOptions options_;
  Vec3d origin_{};
  double scale_ = 1.0;
  double diagonal_ = 0.0;
  double cos_max_flip_ = 0.5;
  double weight_floor_ = 1e-30;  // keeps cost = E / W finite where all faces are degenerate
  double reg_weight_ = 0.0;      // rubber-band weight per anchor

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
  std::vector<Vertex> vx_;
  // Small per-vertex arrays read by staleness tests and edge rules: dense, so they stay in cache.
  std::vector<std::uint32_t> version_;
  std::vector<VertexKind> kind_;
  std::vector<std::uint8_t> state_;
  std::vector<std::uint32_t> tri_;        // 3 vertices per face; tri_[3f] == kInvalidIndex: dead
  std::vector<std::uint32_t> tri_wedge_;  // 3 wedges per face
  std::vector<std::uint32_t> tri_source_; // input face of each working face
  std::vector<std::uint32_t> begin_, size_, capacity_;  // per-vertex face lists in pool_
  std::vector<std::uint32_t> pool_;
  std::size_t alive_faces_ = 0;
};

// Engines. `triangles` holds triangles only; the result's triangles_before is filled in by simplify().
SimplifyResult run_edge_collapse(const Mesh& triangles, const SimplifyOptions& options);
SimplifyResult run_multiple_choice(const Mesh& triangles, const SimplifyOptions& options);

// Error budget in normalised units (squared, to compare with costs); +inf when unlimited.
double normalised_budget_squared(const SimplifyOptions& options, double scale, double diagonal);
// Triangle count to stop at.
std::size_t target_triangle_count(const SimplifyOptions& options, std::size_t input_triangles);

}  // namespace lodforge::collapse
