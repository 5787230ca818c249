// The triangle engines and what they share besides the working mesh. Engine-internal: call
// lodforge::simplify().
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "collapse_mesh.hpp"
#include "lodforge/core/mesh.hpp"
#include "lodforge/eval/distance_bound.hpp"
#include "lodforge/metric/stop_rule.hpp"
#include "lodforge/simplify/policies.hpp"
#include "lodforge/simplify/simplify.hpp"

namespace lodforge::collapse {

// One committed collapse as the engines log it: replaying a prefix of the log on a fresh working mesh (same
// input, same options) rebuilds the engine's mesh after that many collapses exactly.
struct CollapseRecord {
  std::uint32_t u = 0, v = 0;  // the candidate edge, u < v
  Vec3d position{};            // normalised (CollapseMesh) coordinates
  double error = 0;            // Evaluation::error
  SeamStage stage = SeamStage::strict;  // the seam stage it was made in (replay relaxes the mesh as far first)
};

// Engines. `triangles` holds triangles only; the result's triangles_before is filled in by simplify().
// `log`, when given, receives every committed collapse in commit order; `guard`, when given, holds an error
// budget during the run (collapses that would break it are refused).
SimplifyResult run_edge_collapse(const Mesh& triangles, const SimplifyOptions& options,
                                 const CollapsePolicies& policies = {}, std::vector<CollapseRecord>* log = nullptr,
                                 const GuardReference* guard = nullptr);
SimplifyResult run_multiple_choice(const Mesh& triangles, const SimplifyOptions& options,
                                   const CollapsePolicies& policies = {}, std::vector<CollapseRecord>* log = nullptr,
                                   const GuardReference* guard = nullptr);
// Vertex clustering (clustering.cpp): any face kinds (polygons are triangulated first), no collapse log; an
// error budget is held by measuring the output per grid resolution. Fills the whole result. `stage`: the
// output feeds another engine (the tiled path's cluster stage), which locks the vertices where a mesh is not
// a manifold: vertices merge only where they are connected within their cell, back-to-back face pairs are
// dropped, and the clusters of vertices that are still not manifold are taken apart again (each member its
// own vertex) until none is left; the count is not corrected for the faces the build drops or splits add.
SimplifyResult run_cluster(const Mesh& mesh, const SimplifyOptions& options, bool stage = false);

// simplify() with verify_budget and an error budget: runs `engine` with a log, measures its output against the
// reference and backs off along the log where it exceeds the budget (budget.cpp).
using LoggedEngine = SimplifyResult (*)(const Mesh&, const SimplifyOptions&, const CollapsePolicies&,
                                        std::vector<CollapseRecord>*, const GuardReference*);
// `guarded` holds the budget during the engine's run (GuardReference: the measurement then passes by
// construction and no back-off is needed); off, the engine stops on its QEM error alone and the back-off finds
// the prefix. `incremental` screens the bisection's steps by what each changed (the default); off, each step
// is screened in full: the same decisions at more work, for tests. `log`, when given, receives the engine's
// collapse log (the sequence the back-off replays).
SimplifyResult run_within_budget(LoggedEngine engine, const Mesh& triangles, const SimplifyOptions& options,
                                 const CollapsePolicies& policies, bool incremental = true, bool guarded = true,
                                 std::vector<CollapseRecord>* log = nullptr);
// The same measurement of one output (no back-off).
BudgetCheck measure_budget(const Mesh& output, const SurfaceIndex& reference, double budget, unsigned threads);
// The surface index of `reference` for measurements against it: the options' budget_reference_index where
// `reference` is their budget_reference and they carry one, else `local`, built here.
const SurfaceIndex& reference_index(const SimplifyOptions& options, const Mesh& reference,
                                    std::optional<SurfaceIndex>& local);

// Conservative modes: the most volume the run may add (bounding) or remove (occluder), model units³; +inf
// without a volume budget. volume_sign() turns CollapseMesh::volume_change() into that direction's amount.
double volume_limit(const SimplifyOptions& options, const CollapseMesh& cm);
double volume_sign(const SimplifyOptions& options);

// The options' targets and budgets as the one stop rule of every engine; `diagonal` that of the mesh's
// bounding box.
StopRule stop_rule(const SimplifyOptions& options, std::size_t input_triangles, double diagonal);
// The stop rule's budget in the working mesh's normalised units, squared (as Evaluation::error); +inf when
// there is none.
double normalised_budget_squared(const StopRule& stop, double scale);

// The end of an engine run: the output mesh and its triangle count, the error bound (from the largest committed
// error, normalised and squared), why it stopped (`stopped`: SimplifyOptions::stop was requested), and the
// output time.
void finish_result(const CollapseMesh& cm, double max_error, const StopRule& stop, bool over_budget,
                   SimplifyResult& result, bool stopped = false);

// What holds a mesh above its target (SimplifyResult::floors): every edge left, sorted by why it may not
// collapse; `budget2` as normalised_budget_squared().
std::vector<std::string> diagnose_floors(const CollapseMesh& cm, double budget2);

// Recomputes the tangents of `mesh` from its normals and UV set 0; no-op without them.
void recompute_tangents(Mesh& mesh);

}  // namespace lodforge::collapse
