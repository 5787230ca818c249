// The simplifier entry point: engines behind one function.
//
//   SimplifyResult r = simplify(mesh, {.target_ratio = 0.1});
//
// Works on triangles: polygon input is fan-triangulated first. The input is never modified.
//
// What the output keeps (this issue is geometry; attribute-aware collapse comes later):
//  - vertices: survivors keep their input id order; a vertex that never moved (locked, or only ever the
//    target of half-edge collapses) keeps its exact input position, bit for bit;
//  - wedges: a survivor keeps its own wedges with their attributes unchanged. A collapse is only made when
//    the victim's wedges map one-to-one onto the survivor's across the collapsed edge: seam vertices move
//    along their seam, never across it. Meshes whose every vertex is a seam (flat-shaded normals, per-face
//    UV islands) therefore barely simplify yet; stop_reason says no_valid_collapse;
//  - faces: input order, each with its material and group;
//  - topology: no new non-manifold, duplicate, degenerate or inconsistently oriented elements (validate());
//    vertices on non-manifold edges, several fans or inconsistently oriented edges are locked; closed
//    components keep their Euler characteristic.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "lodforge/core/mesh.hpp"

namespace lodforge {

enum class Engine {
  edge_collapse,    // greedy QEM edge collapse, versioned queue, parallel batched re-evaluation (default)
  multiple_choice,  // Wu-Kobbelt: best of k sampled candidates per step (fast preset)
};

enum class BorderMode {
  free,      // borders collapse like interior edges (no constraint planes)
  preserve,  // borders may collapse along themselves, held by perpendicular constraint planes (default)
  lock,      // border vertices never move and are never removed
};

struct SimplifyOptions {
  // Target triangle count: target_triangles when it is non-zero, else round(target_ratio × input triangles);
  // ratio in (0, 1]. The error budgets below may stop earlier (stop_reason says so).
  double target_ratio = 0.5;
  std::size_t target_triangles = 0;  // 0 = use target_ratio
  // Error budget: no collapse whose error (as in SimplifyResult::error_bound_abs) exceeds it is made; when
  // only such collapses are left, stop_reason is error_budget. The smaller of the two wins. Negative =
  // unlimited.
  double max_error_abs = -1.0;       // in model units
  double max_error_rel = -1.0;       // as a fraction of the bounding-box diagonal
  BorderMode border_mode = BorderMode::preserve;
  double border_weight = 10.0;       // weight of boundary constraint planes relative to face quadrics
  std::vector<std::uint32_t> locked_vertices{};  // vertex ids that never move
  double regularization_weight = 1e-3;  // rubber-band point quadric weight × mean face area (0 = off)
  double max_flip_angle_deg = 60.0;  // reject collapses that turn a face normal by more than this (< 90)
  unsigned threads = 0;              // 0 = all cores
  std::uint64_t seed = 1;            // multiple_choice sampling
  Engine engine = Engine::edge_collapse;
  int multiple_choice_k = 8;
  // Most collapses the edge_collapse engine commits per round (its parallel unit); 0 = automatic (small
  // relative to the queue, see edge_collapse.cpp), 1 = strictly sequential greedy. Output depends on this
  // value but never on `threads`.
  std::size_t max_batch = 0;

  // Every problem at once, one line each; empty = valid.
  std::vector<std::string> validate() const;
};

enum class StopReason { target_reached, error_budget, no_valid_collapse };
const char* stop_reason_name(StopReason r);

struct SimplifyResult {
  Mesh mesh;
  std::size_t triangles_before = 0;
  std::size_t triangles_after = 0;
  // Running maximum over committed collapses of sqrt(E / W): E the surface quadric error at the new vertex
  // (face planes and boundary constraint planes, not the rubber band), W the surface area the vertex stands
  // for. An area-weighted RMS distance to the original planes, in model units.
  double error_bound_abs = 0.0;
  double error_bound_rel = 0.0;  // error_bound_abs / bounding-box diagonal of the input
  StopReason stop_reason = StopReason::target_reached;
  struct Timings {
    double setup_ms = 0, initial_costs_ms = 0, collapse_ms = 0, output_ms = 0;
  } timings;
  std::size_t collapses = 0;
  std::size_t rounds = 0;           // parallel rounds (edge_collapse batches, multiple_choice sample rounds)
  std::size_t rejected = 0;         // candidates refused at check time (link, pinch, fold, seam, ...)
};

// Throws std::invalid_argument listing every problem when options.validate() is not empty, and when a
// locked vertex id is out of range for `mesh`.
SimplifyResult simplify(const Mesh& mesh, const SimplifyOptions& options);

}  // namespace lodforge
