// When a simplification engine stops: one rule for the triangle engines and the polychord engine.
//
//   StopRule stop = StopRule::make(input_triangles, {.target_ratio = 0.1, .max_error_rel = 0.002}, diagonal);
//   while (!stop.reached(triangles)) { ... if (!stop.allows(error)) skip; ... }
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>

namespace lodforge {

struct StopTargets {
  double target_ratio = 1.0;         // fraction of the input triangles, used when target_triangles is 0
  std::size_t target_triangles = 0;  // 0 = use target_ratio
  double max_error_abs = -1.0;       // model units; negative = no budget
  double max_error_rel = -1.0;       // fraction of the bounding-box diagonal; negative = no budget
};

struct StopRule {
  std::size_t target_triangles = 0;  // stop once the mesh has this many triangles or fewer
  // No collapse whose error (a distance, model units) exceeds this is made; +inf: no budget.
  double max_error = std::numeric_limits<double>::infinity();

  // The count clamps to the input's; of two budgets the smaller wins.
  static StopRule make(std::size_t input_triangles, const StopTargets& t, double diagonal) {
    StopRule r;
    if (t.target_triangles > 0) {
      r.target_triangles = std::min(t.target_triangles, input_triangles);
    } else {
      const double n = std::round(t.target_ratio * static_cast<double>(input_triangles));
      r.target_triangles = std::min(input_triangles, static_cast<std::size_t>(std::max(n, 0.0)));
    }
    if (t.max_error_abs >= 0.0) r.max_error = std::min(r.max_error, t.max_error_abs);
    if (t.max_error_rel >= 0.0) r.max_error = std::min(r.max_error, t.max_error_rel * diagonal);
    return r;
  }

  bool reached(std::size_t triangles) const { return triangles <= target_triangles; }
  bool allows(double error) const { return !(error > max_error); }
  bool has_budget() const { return max_error < std::numeric_limits<double>::infinity(); }
};

}  // namespace lodforge
