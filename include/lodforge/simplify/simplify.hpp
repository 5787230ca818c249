// The simplifier entry point: engines behind one function.
//
//   SimplifyResult r = simplify(mesh, {.target_ratio = 0.1});
//
// Works on triangles: polygon input is fan-triangulated first. The input is never modified.
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
  // Target: the smallest of these that is set wins; ratio of input triangles in (0, 1].
  double target_ratio = 0.5;
  std::size_t target_triangles = 0;  // 0 = use target_ratio
  // Error budget: stop before a collapse whose error exceeds it. Negative = unlimited.
  double max_error_abs = -1.0;       // in model units
  double max_error_rel = -1.0;       // as a fraction of the bounding-box diagonal
  BorderMode border_mode = BorderMode::preserve;
  double border_weight = 10.0;       // weight of boundary constraint planes relative to face quadrics
  std::vector<std::uint32_t> locked_vertices;  // vertex ids that never move
  double regularization_weight = 1e-3;  // rubber-band point quadric weight × mean face area (0 = off)
  double max_flip_angle_deg = 60.0;  // reject collapses that turn a face normal by more than this (< 90)
  unsigned threads = 0;              // 0 = all cores
  std::uint64_t seed = 1;            // multiple_choice sampling
  Engine engine = Engine::edge_collapse;
  int multiple_choice_k = 8;

  // Every problem at once, one line each; empty = valid.
  std::vector<std::string> validate() const;
};

enum class StopReason { target_reached, error_budget, no_valid_collapse };
const char* stop_reason_name(StopReason r);

struct SimplifyResult {
  Mesh mesh;
  std::size_t triangles_before = 0;
  std::size_t triangles_after = 0;
  double error_bound_abs = 0.0;  // running maximum of sqrt(quadric error) of committed collapses
  double error_bound_rel = 0.0;  // error_bound_abs / bounding-box diagonal of the input
  StopReason stop_reason = StopReason::target_reached;
  struct Timings {
    double setup_ms = 0, initial_costs_ms = 0, collapse_ms = 0, output_ms = 0;
  } timings;
  std::size_t collapses = 0;
};

// Throws std::invalid_argument listing every problem when options.validate() is not empty.
SimplifyResult simplify(const Mesh& mesh, const SimplifyOptions& options);

}  // namespace lodforge
