// The simplifier entry point: option checks and dispatch to the engines (edge_collapse.cpp: greedy QEM after
// Garland & Heckbert 1997; multiple_choice.cpp: Wu & Kobbelt 2002). Polygon input is fan-triangulated first.
#include "lodforge/simplify/simplify.hpp"

#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>

#include "lodforge/simplify/edge_collapse.hpp"

namespace lodforge {

std::vector<std::string> SimplifyOptions::validate() const {
  std::vector<std::string> problems;
  if (!(target_ratio > 0.0 && target_ratio <= 1.0)) {
    problems.push_back("target_ratio must be in (0, 1], got " + std::to_string(target_ratio));
  }
  if (std::isnan(max_error_abs)) problems.push_back("max_error_abs is NaN (negative = unlimited)");
  if (std::isnan(max_error_rel)) problems.push_back("max_error_rel is NaN (negative = unlimited)");
  if (!(border_weight >= 0.0 && std::isfinite(border_weight))) {
    problems.push_back("border_weight must be finite and >= 0, got " + std::to_string(border_weight));
  }
  if (!(regularization_weight >= 0.0 && std::isfinite(regularization_weight))) {
    problems.push_back("regularization_weight must be finite and >= 0, got " + std::to_string(regularization_weight));
  }
  // 90 degrees or more would let a face turn edge-on or over in one collapse, and a series of them fold.
  if (!(max_flip_angle_deg > 0.0 && max_flip_angle_deg < 90.0)) {
    problems.push_back("max_flip_angle_deg must be in (0, 90), got " + std::to_string(max_flip_angle_deg));
  }
  if (multiple_choice_k < 1 || multiple_choice_k > 256) {
    problems.push_back("multiple_choice_k must be in [1, 256], got " + std::to_string(multiple_choice_k));
  }
  return problems;
}

const char* stop_reason_name(StopReason r) {
  switch (r) {
    case StopReason::target_reached: return "target_reached";
    case StopReason::error_budget: return "error_budget";
    case StopReason::no_valid_collapse: return "no_valid_collapse";
  }
  return "unknown";
}

SimplifyResult simplify(const Mesh& mesh, const SimplifyOptions& options) {
  const std::vector<std::string> problems = options.validate();
  if (!problems.empty()) {
    std::string msg = "invalid simplify options:";
    for (const std::string& p : problems) msg += "\n  " + p;
    throw std::invalid_argument(msg);
  }
  const auto t0 = std::chrono::steady_clock::now();
  const FaceKindCounts kinds = count_face_kinds(mesh);
  const bool all_triangles = kinds.quads == 0 && kinds.polygons == 0;
  // Copy only when there is something to triangulate: the input is often the largest thing in memory.
  Mesh triangulated_copy;
  if (!all_triangles) triangulated_copy = triangulated(mesh);
  const Mesh& tris = all_triangles ? mesh : triangulated_copy;
  const double triangulate_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();

  SimplifyResult r = options.engine == Engine::multiple_choice ? collapse::run_multiple_choice(tris, options)
                                                               : collapse::run_edge_collapse(tris, options);
  r.triangles_before = mesh.triangle_count();
  r.timings.setup_ms += triangulate_ms;
  return r;
}

}  // namespace lodforge
