// The triangle engines and what they share besides the working mesh. Engine-internal: call
// lodforge::simplify().
#pragma once

#include <cstddef>

#include "collapse_mesh.hpp"
#include "lodforge/core/mesh.hpp"
#include "lodforge/metric/stop_rule.hpp"
#include "lodforge/simplify/policies.hpp"
#include "lodforge/simplify/simplify.hpp"

namespace lodforge::collapse {

// Engines. `triangles` holds triangles only; the result's triangles_before is filled in by simplify().
SimplifyResult run_edge_collapse(const Mesh& triangles, const SimplifyOptions& options,
                                 const CollapsePolicies& policies = {});
SimplifyResult run_multiple_choice(const Mesh& triangles, const SimplifyOptions& options,
                                   const CollapsePolicies& policies = {});

// The options' targets and budgets as the one stop rule of every engine; `diagonal` that of the mesh's
// bounding box.
StopRule stop_rule(const SimplifyOptions& options, std::size_t input_triangles, double diagonal);
// The stop rule's budget in the working mesh's normalised units, squared (as Evaluation::error); +inf when
// there is none.
double normalised_budget_squared(const StopRule& stop, double scale);

// The end of an engine run: the output mesh and its triangle count, the error bound (from the largest committed
// error, normalised and squared), why it stopped, and the output time.
void finish_result(const CollapseMesh& cm, double max_error, const StopRule& stop, bool over_budget,
                   SimplifyResult& result);

// Recomputes the tangents of `mesh` from its normals and UV set 0; no-op without them.
void recompute_tangents(Mesh& mesh);

}  // namespace lodforge::collapse
