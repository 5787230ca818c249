// The simplifier entry point: engines behind one function.
//
//   SimplifyResult r = simplify(mesh, {.target_ratio = 0.1});
//
// Works on triangles: polygon input is fan-triangulated first. The input is never modified.
//
// What the output keeps (geometry, and the attributes):
//  - vertices: survivors keep their input id order; a vertex that never moved (locked, or only ever the
//    target of half-edge collapses) keeps its exact input position, bit for bit;
//  - wedges: a collapse is only made when the victim's wedges map one-to-one onto the survivor's across the
//    collapsed edge (material boundaries count as seams): seam vertices move along their seam, never across
//    it, UV charts never merge and no UV triangle flips. A survivor's wedges get attributes per
//    attribute_placement (optimal: the Hoppe 1999 minimiser, clamped; keep: unchanged); tangents are
//    recomputed from normals and UV set 0 when the input had them (optimal placement). Where these rules
//    stop the engine before its target, `seams` relaxes them in stages (SeamStage), each used only when the
//    one before runs out of collapses, so a LOD the strict rules reach is exactly the strict rules' LOD;
//  - skin: weights of a moved vertex blend its two sources (top influences, renormalised); morph deltas
//    blend the same way;
//  - faces: input order, each with its material and group;
//  - topology: no new non-manifold, duplicate, degenerate or inconsistently oriented elements (validate());
//    vertices on non-manifold edges, several fans or inconsistently oriented edges are locked; closed
//    components keep their Euler characteristic.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "lodforge/core/mesh.hpp"
#include "lodforge/core/stop.hpp"
#include "lodforge/simplify/policies.hpp"
#include "lodforge/symmetry/symmetry.hpp"

namespace lodforge {

struct SurfaceIndex;

enum class Engine {
  edge_collapse,    // greedy QEM edge collapse, versioned queue, parallel batched re-evaluation (default)
  multiple_choice,  // Wu-Kobbelt: best of k sampled candidates per step (fast preset)
  polychord,        // quad-preserving sub-polychord collapse (quad/polychord_collapse.hpp); keeps quads, then
                    // continues with edge_collapse (triangulating) if it stops before the target
  cluster,          // vertex clustering on a grid (Lindstrom's quadric per cell, attribute classes per cell):
                    // fastest, for far LODs and huge inputs; no collapses, so collapse policies do not apply
};

// Multipliers of the attribute error terms against the geometric error; 0 leaves that
// attribute out of the metric; all 0 gives exactly the geometry-only result. Units: a normal or colour change
// of 1 across a face costs like moving that face by one mean input edge length (times the weight); UVs are
// first scaled by the mesh's UV density (sqrt of 3-D area over UV area, per UV set), so a UV shift costs like
// moving the surface by the distance the texture slides (times the weight): independent of texture resolution.
// Skin: a weight-vector change of 1 (L2) between two merged vertices costs like a normal change of 1.
struct AttributeWeights {
  double normal = 1.0;
  double uv = 1.0;
  double color = 1.0;
  double skin = 1.0;
  friend bool operator==(const AttributeWeights&, const AttributeWeights&) = default;
};

// Where the attributes of a moved vertex come from.
enum class AttributePlacement {
  optimal,  // the attribute quadric's minimiser at the new position, clamped (unit normals, colours in [0, 1],
            // UVs on the collapsed edge's UV segment, inside the chart; at a seam vertex, where that segment
            // may be a chord of the chart's outline, the nearer end's UV); tangents recomputed
  keep,     // the surviving wedges' values unchanged (all LODs can share one vertex buffer)
};

// What the triangle engines may do to seams when the strict rules (seam vertices move only along their seam,
// vertices where seams meet never move) run out of collapses before the target.
enum class SeamMode {
  keep,             // never relax: the LOD may stop above its target (hero assets, baked normal maps)
  relax,            // relax in stages (SeamStage) until the target is reached; material boundaries hold (default)
  relax_materials,  // relax, and as a last stage let material boundaries move too
};
const char* seam_mode_name(SeamMode m);

// The relaxation stages, in the order they are tried. A stage starts only when the stages before it found no
// valid collapse left before the target; it keeps every check of the stages before it but the seam rule it
// relaxes.
enum class SeamStage : std::uint8_t {
  strict,     // the wedge rule: no two distinct wedges of a vertex merge, seam corners never move
  corners,    // wedges of a vertex whose normals differ by a soft crease (at most 30 degrees) count as one
              // (their attribute quadrics join): corners of soft seams slide along or merge across them
  normals,    // hard-normal seams: wedges that differ only in normals and tangents count as one
  uv,         // UV-seam corners move by half-edge collapse; wedges the survivor lacks go with the corner and
              // keep their values (no chart-spanning triangle, no UV flip: the UV checks hold)
  materials,  // as uv, and material boundaries may move (SeamMode::relax_materials only); a material never
              // loses its last triangle
};
const char* seam_stage_name(SeamStage s);

// Tiled simplification of huge meshes (docs/tiling.md). Plain option data: simplify() never tiles and ignores
// it; the tiled entry point in the tiling part (simplify_maybe_tiled(), tiling/tiling.hpp) reads it.
enum class TilingMode {
  off,        // one engine run over the whole mesh
  automatic,  // tiled from 1,000,000 triangles on (default)
  on,         // tiled whatever the size
};
const char* tiling_mode_name(TilingMode m);

enum class BorderMode {
  free,      // borders collapse like interior edges (no constraint planes)
  preserve,  // borders may collapse along themselves, held by perpendicular constraint planes (default)
  lock,      // border vertices never move and are never removed
};

// Conservative LODs (docs/conservative.md): every collapse puts its new vertex on one side of the planes of all
// the faces around the collapsed edge, so the LOD nests with the input.
enum class Conservative {
  none,      // no nesting constraint (default)
  bounding,  // the LOD contains the input (collision hulls): new vertices in front of or on the old faces
  occluder,  // the LOD lies inside the input (occluders): new vertices behind or on the old faces
};
const char* conservative_name(Conservative c);

struct SimplifyOptions {
  // Target triangle count: target_triangles when it is non-zero, else round(target_ratio × input triangles);
  // ratio in (0, 1]. The error budgets below may stop earlier (stop_reason says so).
  double target_ratio = 0.5;
  std::size_t target_triangles = 0;  // 0 = use target_ratio
  // Error budget, a distance: the output stays within it of the input (measured both ways, see
  // verify_budget); the engine also makes no collapse whose QEM error (SimplifyResult::qem_error_abs) exceeds
  // it. When it stops the run, stop_reason is error_budget. The smaller of the two wins. Negative = unlimited.
  double max_error_abs = -1.0;       // in model units
  double max_error_rel = -1.0;       // as a fraction of the bounding-box diagonal
  BorderMode border_mode = BorderMode::preserve;
  double border_weight = 10.0;       // weight of boundary constraint planes relative to face quadrics
  std::vector<std::uint32_t> locked_vertices{};  // vertex ids that never move
  double regularization_weight = 1e-3;  // rubber-band point quadric weight × mean face area (0 = off)
  double max_flip_angle_deg = 60.0;  // reject collapses that turn a face normal by more than this (< 90)
  // Height fields (terrain): 0, 1 or 2 refuses every collapse after which a face around it would not face
  // +that axis, so a mesh that is a height field over the other two axes stays one (no overhangs, no vertex
  // sliding past its neighbours); -1 = off. Triangle engines.
  int height_field_axis = -1;
  unsigned threads = 0;              // 0 = all cores
  std::uint64_t seed = 1;            // multiple_choice sampling
  Engine engine = Engine::edge_collapse;
  int multiple_choice_k = 8;
  // Most collapses the edge_collapse engine commits per round (its parallel unit); 0 = automatic (small
  // relative to the queue, see edge_collapse.cpp), 1 = strictly sequential greedy. Output depends on this
  // value but never on `threads`.
  std::size_t max_batch = 0;
  // Nesting with the input (Conservative). Triangle engines only (edge_collapse, multiple_choice). On open
  // meshes rim vertices never move; one whose two rim edges are collinear seen along the mesh's dominant axis
  // may be removed onto a rim neighbour (a terrain tile's straight sides thin out, its outline stays).
  Conservative conservative = Conservative::none;
  // Conservative modes: the run stops before the LOD's volume differs from the input's by more than this
  // fraction of the input's volume (bounding: growth; occluder: loss). Negative = unlimited.
  double max_volume_growth = -1.0;
  // Read by simplify_maybe_tiled() only (tiling/tiling.hpp); simplify() runs untiled whatever they say.
  TilingMode tiling = TilingMode::automatic;
  std::size_t tile_triangles = 200'000;  // triangles per tile on the tiled path, at least 100
  // The tiled path's cluster stage: the whole mesh vertex-clustered to cluster_stage_factor × the target
  // first (engine cluster), the tiled edge-collapse passes finishing from there; never with locked vertices,
  // an error budget or a conservative mode. automatic: from tiling::kAutoClusterTriangles triangles, where
  // that count is at most a quarter of the input; on: wherever it is below the input's.
  TilingMode cluster_stage = TilingMode::automatic;
  double cluster_stage_factor = 8.0;

  // --- attributes, seams, skinning, painted priority (edge_collapse.hpp has the vertex kinds and rules) ---
  AttributeWeights attribute_weights{};
  AttributePlacement attribute_placement = AttributePlacement::optimal;
  // Seam relaxation when the strict rules stop before the target (SeamMode, SeamStage).
  SeamMode seams = SeamMode::relax;
  // Deprecated alias of seams = relax (it used to let hard-normal seams merge from the start); true wins over
  // seams = keep.
  bool permissive = false;
  // Per-vertex painted weight scaling that vertex's quadrics: "_LOD_PRIORITY" (Mesh::priority), another custom
  // attribute ("_PAINT", "_PAINT.y"), a colour channel ("COLOR_0.r"), or "none". Used when the mesh has it.
  // 1 is neutral, 0 "don't care", priority_lock and above lock the vertex. The quadrics are scaled by the
  // weight squared, so a weight acts on distances: a region painted 10 keeps about a tenth of the error.
  // The QEM error (qem_error_abs) is that of the unpainted surface.
  std::string priority_channel = "_LOD_PRIORITY";
  double priority_lock = 1000.0;
  // Skinning: influences below this weight are ignored when finding a vertex's dominant joint and comparing
  // weight vectors. Two vertices whose dominant joints differ never merge unless the L1 distance of their
  // weight vectors is below skin_max_distance (the blend band of a joint).
  double skin_weight_threshold = 0.1;
  double skin_max_distance = 0.5;

  // --- symmetry (edge_collapse and polychord engines) ---
  // How strongly mirror pairs are favoured; 0 = off. Above 0 the mesh's mirror symmetry is found
  // (symmetry/symmetry.hpp) and an edge whose mirror image is also an edge collapses together with it, as one
  // candidate costing the pair's mean (the polychord engine: a run of rungs and its mirror run, see
  // quad::PolychordOptions::symmetry_weight; its triangle phase pairs edges); a collapse that would break the
  // symmetry (its mirror is gone or refused) costs (1 + symmetry_weight) times its own error. Soft: painted
  // priority on one side still keeps that side, and asymmetric regions simplify as without it. multiple_choice, cluster and tiled runs ignore it.
  double symmetry_weight = 0.0;
  symmetry::PlaneMode symmetry_plane = symmetry::PlaneMode::automatic;
  // The mirror vertex of each input vertex (itself on the plane, kInvalidIndex: none), where the caller found
  // it already; null: found by the engine when symmetry_weight > 0.
  const std::vector<std::uint32_t>* vertex_mirror = nullptr;

  // Error budgets are verified by measurement (SimplifyResult::budget): the output's distance to
  // budget_reference (null: the input) must stay within the budget both ways, and where the engine's run
  // exceeds it, fewer collapses are made. Set budget_reference to the original when simplifying from a
  // previous LOD, so that errors along a chain do not add up. false: the engine's QEM error alone stops it.
  bool verify_budget = true;
  const Mesh* budget_reference = nullptr;
  // budget_reference's surface index (eval/distance_bound.hpp), where the caller builds it once for several
  // simplify() calls against the same reference (the LODs of a chain); null: each call builds its own.
  const SurfaceIndex* budget_reference_index = nullptr;
  // A previous LOD's SimplifyResult::reference_attachments, where this call simplifies that LOD against the
  // same budget_reference: where the engine holds the budget as it runs, it starts from them instead of
  // searching every reference sample's nearest face (each is checked, and searched for where not within).
  const std::vector<std::uint32_t>* budget_attachments = nullptr;
  // Whether simplify() holds an error budget by measurement (verify_budget, and a budget set).
  bool verifies_budget() const { return verify_budget && (max_error_abs >= 0.0 || max_error_rel >= 0.0); }

  // A deadline or cancel flag (core/stop.hpp) polled between rounds of collapses (every engine) and between
  // the budget's measurements; once requested, simplify() returns the mesh as far as it got with stop_reason
  // stopped (no budget check or back-off is finished). The default never stops and costs nothing.
  StopRequest stop{};

  // Every problem at once, one line each; empty = valid.
  std::vector<std::string> validate() const;
};

// Whether `channel` names a place a painted priority can live in: "none", a custom attribute ("_LOD_PRIORITY")
// or one component of it ("_PAINT.x"), or a colour channel ("COLOR_0.r"). The grammar of configs/schema.json.
bool is_priority_channel(std::string_view channel);

// stopped: SimplifyOptions::stop was requested before the target was reached (the output is incomplete).
enum class StopReason { target_reached, error_budget, no_valid_collapse, stopped };
const char* stop_reason_name(StopReason r);

// Why a candidate collapse was refused. The first ten are the triangle engines' check-time rules
// (CollapseMesh::check, which draws the local configurations).
enum class Veto : std::uint8_t {
  none,
  not_an_edge,      // the endpoints share no face (stale candidate), or more than two
  link_condition,   // a common neighbour that is not an apex: the collapse would glue two sheets together
  boundary_pinch,   // interior edge between two boundary vertices: would pinch the surface to one vertex
  dangling_face,    // the edge's face has its two other edges on the boundary: would leave a dangling edge
  tetrahedron,      // both faces c-d-a and c-d-b exist: the collapse would fold a tetrahedron flat
  fold,             // a face normal would turn by more than max_flip_angle_deg
  degenerate,       // a face would get (almost) zero area
  seam,             // wedges cannot be carried over without merging distinct attribute values (or materials)
  uv_flip,          // a face's UV triangle would turn over (or collapse to zero area) in some UV set
  skin,             // a face would join vertices with different dominant joints and distant weight vectors
  weld,             // polychord engine: the weld of a run refused it (topology, fold, seam or skin)
  filter,           // a caller's filter policy refused it (CollapsePolicies::filter)
  error_budget,     // its error exceeds the error budget (not a refusal of the topology: counted apart)
  conservative,     // conservative modes: the new vertex would cross the plane of a face around the edge
};
inline constexpr int kVetoKinds = 15;
const char* veto_name(Veto v);

// How many candidates each rule refused.
struct VetoCounts {
  std::size_t count[kVetoKinds] = {};
  std::size_t& operator[](Veto v) { return count[static_cast<int>(v)]; }
  std::size_t operator[](Veto v) const { return count[static_cast<int>(v)]; }
  // Refusals at check time: every rule but the error budget.
  std::size_t rejected() const {
    std::size_t n = 0;
    for (int i = 1; i < kVetoKinds; ++i) n += i == static_cast<int>(Veto::error_budget) ? 0 : count[i];
    return n;
  }
  VetoCounts& operator+=(const VetoCounts& o) {
    for (int i = 0; i < kVetoKinds; ++i) count[i] += o.count[i];
    return *this;
  }
};

// How an error budget was held (SimplifyOptions::verify_budget): the engine's run is measured against the
// input (or budget_reference), and where it exceeds the budget a shorter prefix of the same collapse sequence
// is taken (bisection over prefixes), so the output never exceeds the budget by measurement.
struct BudgetCheck {
  bool verified = false;       // a budget was set and the output measured against it
  bool within = false;         // the output meets the budget by that measurement (verified only)
  double budget_abs = 0;       // the budget, model units
  // Output → reference: bound_abs is an upper bound (no point of the output is farther), refined until it
  // decides the budget; where flat parts of the output lie on the reference across several of its triangles
  // the refinement may stop first, and then the largest distance measured decides (certified false).
  // Reference → output is bounded the same way (a long reference triangle over a concave crease of the output
  // is near it at its corners and centroid, not between them), and decided the same way where its refinement
  // cannot converge.
  bool certified = false;      // output → reference held by the bound, not by samples
  double bound_abs = 0;        // upper bound, output → reference
  double sampled_abs = 0;      // largest distance measured, output → reference
  double reverse_abs = 0;      // largest distance measured, reference → output
  double reverse_bound_abs = 0;  // upper bound, reference → output
  // Guarded runs repeated with extra reference samples where the reverse bound found a point over the budget.
  std::size_t guard_reruns = 0;
  std::size_t collapses_undone = 0;  // collapses of the engine's run left out to meet the budget
  std::size_t prefixes_measured = 0;
  std::size_t prefixes_screened_incrementally = 0;  // of those: measured only where their collapses reached
  bool backed_off() const { return collapses_undone > 0; }
  double ms = 0;               // time spent verifying and backing off
};

struct SimplifyResult {
  Mesh mesh;
  std::size_t triangles_before = 0;
  std::size_t triangles_after = 0;
  // Running maximum over committed collapses of sqrt(E / W): E the surface quadric error at the new vertex
  // (face planes and boundary constraint planes, not the rubber band), W the surface area the vertex stands
  // for. An area-weighted RMS distance to the original planes, in model units: a ranking, not a bound (the
  // real distance is often several times larger).
  double qem_error_abs = 0.0;
  double qem_error_rel = 0.0;  // qem_error_abs / bounding-box diagonal of the input
  // A certified upper bound on the distance from any point of the output to the input's surface (one-sided
  // Hausdorff, eval/distance_bound.hpp), measured when an error budget is verified (budget.verified); -1 when
  // not measured.
  double error_bound_abs = -1.0;
  double error_bound_rel = -1.0;
  BudgetCheck budget;
  // Where an error budget was held by the engine as it ran and the output is its own (nothing backed off): per
  // sample point of the reference (its vertices, then its triangles' centroids), the output triangle kept
  // within the budget of it (kInvalidIndex: none). For the next LOD of a chain (budget_attachments).
  std::vector<std::uint32_t> reference_attachments;
  StopReason stop_reason = StopReason::target_reached;
  struct Timings {
    double setup_ms = 0, initial_costs_ms = 0, collapse_ms = 0, output_ms = 0;
  } timings;
  std::size_t collapses = 0;
  std::size_t paired_collapses = 0;  // collapses made together with their mirror image (symmetry_weight)
  std::size_t rounds = 0;           // parallel rounds (edge_collapse batches, multiple_choice sample rounds)
  VetoCounts vetoes;                // candidates refused, per rule (vetoes.rejected(): at check time)
  // Faces that are quads before (input) and after; only the polychord engine outputs quads.
  std::size_t quads_before = 0;
  std::size_t quads_after = 0;
  // Faces of the input that repeated an earlier face (repeated_faces(), core/mesh.hpp): dropped first.
  std::size_t repeated_faces_removed = 0;
  // Engine::polychord only: the quad engine made less than half of the reduction, so the triangle engine
  // simplified the input itself.
  bool quad_engine_handed_over = false;
  // The tiled path (simplify_maybe_tiled()): passes made (the last may be one untiled run over the stitched
  // mesh) and tiles simplified over all of them; 0 and 0 when the mesh ran untiled.
  std::size_t tiling_passes = 0;
  std::size_t tile_runs = 0;
  // The tiled path's cluster stage: its output (0: none was made) and its time (also in timings.setup_ms).
  std::size_t cluster_stage_triangles = 0;
  double cluster_stage_ms = 0;
  // The last seam stage the engine used (strict: none was needed or allowed).
  SeamStage seam_stage = SeamStage::strict;
  // When the target was not reached: what held the rest, most refused candidates first, each one of
  // "locked" (locked and painted-locked vertices), "non_manifold" (vertices locked on non-manifold or
  // inconsistently oriented edges), "skin" (the skinning rule), "material_slot" (a material's last triangle),
  // "materials_kept" (material boundaries, seams relax), "seams_kept" (seams = keep), "uv_checks" (a UV
  // triangle would flip or become a sliver), "topology" (the link condition, folds: closed parts at their
  // smallest), "error_budget". Empty when the target was reached.
  std::vector<std::string> floors;
};

// Throws std::invalid_argument listing every problem when options.validate() is not empty, and when a
// locked vertex id is out of range for `mesh`. Faces repeating an earlier face are dropped before anything
// else (SimplifyResult::repeated_faces_removed).
SimplifyResult simplify(const Mesh& mesh, const SimplifyOptions& options);
// The same with caller policies (placement, cost, filter, stop, observer: simplify/policies.hpp).
SimplifyResult simplify(const Mesh& mesh, const SimplifyOptions& options, const CollapsePolicies& policies);

}  // namespace lodforge
