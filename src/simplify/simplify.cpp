// The simplifier entry point: option checks and dispatch to the engines (edge_collapse.cpp: greedy QEM after
// Garland & Heckbert 1997; multiple_choice.cpp: Wu & Kobbelt 2002; clustering.cpp: vertex clustering after
// Lindstrom 2000 and Willmott 2011). Polygon input is fan-triangulated first.
#include "lodforge/simplify/simplify.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>

#include "engines.hpp"
#include "lodforge/quad/polychord_collapse.hpp"
#include "lodforge/quad/quad_recovery.hpp"

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
  if (height_field_axis < -1 || height_field_axis > 2) {
    problems.push_back("height_field_axis must be -1 (off), 0, 1 or 2, got " + std::to_string(height_field_axis));
  }
  if (!(max_flip_angle_deg > 0.0 && max_flip_angle_deg < 90.0)) {
    problems.push_back("max_flip_angle_deg must be in (0, 90), got " + std::to_string(max_flip_angle_deg));
  }
  for (const auto& [name, w] : {std::pair{"normal", attribute_weights.normal}, std::pair{"uv", attribute_weights.uv},
                                 std::pair{"color", attribute_weights.color}, std::pair{"skin", attribute_weights.skin}}) {
    if (!(w >= 0.0 && std::isfinite(w))) {
      problems.push_back(std::string("attribute_weights.") + name + " must be finite and >= 0, got " + std::to_string(w));
    }
  }
  if (!is_priority_channel(priority_channel)) {
    problems.push_back("priority_channel must be \"none\", a custom attribute such as \"_LOD_PRIORITY\" or "
                       "\"_PAINT.x\", or a colour channel such as \"COLOR_0.r\"; got \"" + priority_channel + "\"");
  }
  if (!(priority_lock > 0.0)) problems.push_back("priority_lock must be > 0, got " + std::to_string(priority_lock));
  if (!(skin_weight_threshold >= 0.0 && skin_weight_threshold <= 1.0)) {
    problems.push_back("skin_weight_threshold must be in [0, 1], got " + std::to_string(skin_weight_threshold));
  }
  if (!(skin_max_distance >= 0.0 && skin_max_distance <= 2.0)) {
    problems.push_back("skin_max_distance must be in [0, 2], got " + std::to_string(skin_max_distance));
  }
  if (multiple_choice_k < 1 || multiple_choice_k > 256) {
    problems.push_back("multiple_choice_k must be in [1, 256], got " + std::to_string(multiple_choice_k));
  }
  if (std::isnan(max_volume_growth)) problems.push_back("max_volume_growth is NaN (negative = unlimited)");
  if (max_volume_growth >= 0.0 && conservative == Conservative::none) {
    problems.push_back("max_volume_growth needs conservative = bounding or occluder");
  }
  if (conservative != Conservative::none && engine != Engine::edge_collapse && engine != Engine::multiple_choice) {
    problems.push_back(std::string("conservative = ") + conservative_name(conservative) +
                       " needs the edge_collapse or multiple_choice engine");
  }
  if (!(symmetry_weight >= 0.0 && std::isfinite(symmetry_weight))) {
    problems.push_back("symmetry_weight must be finite and >= 0, got " + std::to_string(symmetry_weight));
  }
  if (!(cluster_stage_factor >= 1.0) || !std::isfinite(cluster_stage_factor)) {
    problems.push_back("cluster_stage_factor must be a finite number of at least 1, got " +
                       std::to_string(cluster_stage_factor));
  }
  if (tile_triangles < 100) {
    problems.push_back("tile_triangles must be at least 100, got " + std::to_string(tile_triangles));
  }
  return problems;
}

namespace {
bool is_ascii_word(std::string_view s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_';
  });
}

bool is_ascii_number(std::string_view s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; });
}
}  // namespace

bool is_priority_channel(std::string_view channel) {
  if (channel == "none") return true;
  const std::size_t dot = channel.find('.');
  const std::string_view name = channel.substr(0, dot);
  const std::string_view component = dot == std::string_view::npos ? std::string_view() : channel.substr(dot + 1);
  auto one_of = [&](std::string_view allowed) {
    return component.size() == 1 && allowed.find(component[0]) != std::string_view::npos;
  };
  const bool custom = name.size() > 1 && name[0] == '_' && is_ascii_word(name.substr(1)) &&
                      (dot == std::string_view::npos || one_of("xyzwrgba"));
  const bool colour = name.starts_with("COLOR_") && is_ascii_number(name.substr(6)) && one_of("rgba");
  return custom || colour;
}

const char* stop_reason_name(StopReason r) {
  switch (r) {
    case StopReason::target_reached: return "target_reached";
    case StopReason::error_budget: return "error_budget";
    case StopReason::no_valid_collapse: return "no_valid_collapse";
    case StopReason::stopped: return "stopped";
  }
  return "unknown";
}

const char* conservative_name(Conservative c) {
  switch (c) {
    case Conservative::none: return "none";
    case Conservative::bounding: return "bounding";
    case Conservative::occluder: return "occluder";
  }
  return "unknown";
}

const char* seam_mode_name(SeamMode m) {
  switch (m) {
    case SeamMode::keep: return "keep";
    case SeamMode::relax: return "relax";
    case SeamMode::relax_materials: return "relax_materials";
  }
  return "unknown";
}

const char* tiling_mode_name(TilingMode m) {
  switch (m) {
    case TilingMode::off: return "off";
    case TilingMode::automatic: return "auto";
    case TilingMode::on: return "on";
  }
  return "unknown";
}

const char* seam_stage_name(SeamStage s) {
  switch (s) {
    case SeamStage::strict: return "strict";
    case SeamStage::corners: return "corners";
    case SeamStage::normals: return "normals";
    case SeamStage::uv: return "uv";
    case SeamStage::materials: return "materials";
  }
  return "unknown";
}

const char* veto_name(Veto v) {
  switch (v) {
    case Veto::none: return "none";
    case Veto::not_an_edge: return "not_an_edge";
    case Veto::link_condition: return "link_condition";
    case Veto::boundary_pinch: return "boundary_pinch";
    case Veto::dangling_face: return "dangling_face";
    case Veto::tetrahedron: return "tetrahedron";
    case Veto::fold: return "fold";
    case Veto::degenerate: return "degenerate";
    case Veto::seam: return "seam";
    case Veto::uv_flip: return "uv_flip";
    case Veto::skin: return "skin";
    case Veto::weld: return "weld";
    case Veto::filter: return "filter";
    case Veto::error_budget: return "error_budget";
    case Veto::conservative: return "conservative";
  }
  return "unknown";
}

namespace {

// The polychord back-off stops when the undecided range of targets is this fraction of the reduction.
constexpr std::size_t kPolychordResolutionDivisor = 32;

// The result of a quad engine run taken as it is (moved from `q`; stop reason target_reached).
SimplifyResult quad_engine_result(quad::PolychordResult&& q, const SimplifyOptions& options) {
  SimplifyResult r;
  r.mesh = std::move(q.mesh);
  // Normals and UVs of merged wedges changed: tangents follow them, as the triangle engine's do.
  if (options.attribute_placement == AttributePlacement::optimal) collapse::recompute_tangents(r.mesh);
  r.triangles_after = q.triangles_after;
  r.qem_error_abs = q.error_bound_abs;
  r.collapses = q.collapses;
  r.paired_collapses = q.paired_collapses;
  r.vetoes[Veto::weld] = q.rejected;
  r.vetoes[Veto::error_budget] = q.over_budget;
  r.stop_reason = StopReason::target_reached;
  return r;
}

// The quad output is compacted, so vertex ids changed; a locked vertex never moved, so it is found again by its
// exact position.
std::vector<std::uint32_t> locked_vertices_in(const Mesh& output, const Mesh& input,
                                              const std::vector<std::uint32_t>& locked) {
  std::set<std::array<float, 3>> locked_positions;
  for (std::uint32_t v : locked) locked_positions.insert(input.positions[v].v);
  std::vector<std::uint32_t> out;
  for (std::uint32_t v = 0; v < output.vertex_count(); ++v) {
    if (locked_positions.count(output.positions[v].v)) out.push_back(v);
  }
  return out;
}

// The quad engine's output as far as it got when SimplifyOptions::stop was requested: no hand-over, no budget.
SimplifyResult stopped_quad_result(const Mesh& mesh, quad::PolychordResult&& q, double quad_ms) {
  SimplifyResult r;
  r.mesh = std::move(q.mesh);
  r.triangles_before = mesh.triangle_count();
  r.triangles_after = q.triangles_after;
  r.qem_error_abs = q.error_bound_abs;
  r.collapses = q.collapses;
  r.stop_reason = StopReason::stopped;
  r.quads_before = q.quads_before;
  r.quads_after = count_face_kinds(r.mesh).quads;
  r.timings.collapse_ms = quad_ms;
  return r;
}

// How a polychord LOD was made: by the quad engine alone, handed over to the triangle engine from the quad
// output, or by the triangle engine from the input.
enum class PolychordPath { quad_only, handed_over, restarted };

// A polychord LOD over its error budget. The quad engine keeps no replayable log, so its shorter runs are its
// LODs at larger targets, each with its surface fit: where the quad output alone held and the triangle engine
// took it further, that hand-over backs off along the triangle engine's log; where the quad output itself is
// over the budget, the largest target whose LOD holds is found by bisection; where none holds, the triangle
// engine makes the LOD from the input. `measured` counts the outputs measured.
template <typename QuadOptions>
SimplifyResult hold_polychord_budget(const Mesh& mesh, const SimplifyOptions& options, const CollapsePolicies& policies,
                                     const Mesh& reference, const SurfaceIndex& reference_index,
                                     const quad::PolychordResult& q,
                                     const QuadOptions& quad_options, PolychordPath path, std::size_t& measured) {
  const auto t0 = std::chrono::steady_clock::now();
  const StopRule stop = collapse::stop_rule(options, mesh.triangle_count(), compute_bounds(mesh).diagonal());
  auto quad_result = [&](quad::PolychordResult&& p, const BudgetCheck& check) {
    SimplifyResult r = quad_engine_result(std::move(p), options);
    r.stop_reason = StopReason::error_budget;
    r.budget = check;
    r.budget.collapses_undone = q.collapses > p.collapses ? q.collapses - p.collapses : 0;
    return r;
  };
  SimplifyOptions rest = options;
  rest.engine = Engine::edge_collapse;
  rest.vertex_mirror = nullptr;  // the quad output's vertices are not the input's
  rest.budget_reference = &reference;
  rest.budget_reference_index = &reference_index;
  BudgetCheck quad_check;
  if (path == PolychordPath::handed_over) {
    quad_check = collapse::measure_budget(q.mesh, reference_index, stop.max_error, options.threads);
    ++measured;
  }
  if (quad_check.within) {
    // The hand-over went over the budget: the triangle engine backs off along its own log from the quad output.
    rest.locked_vertices = locked_vertices_in(q.mesh, mesh, options.locked_vertices);
    SimplifyResult r = collapse::run_within_budget(collapse::run_edge_collapse, triangulated(q.mesh), rest, policies);
    measured += r.budget.prefixes_measured;
    r.mesh = quad::recover_quads(r.mesh, {.keep_triangles = true});
    r.collapses += q.collapses;
    r.vetoes[Veto::weld] += q.rejected;
    return r;
  }
  // Bisection over the quad engine's target: `fails` gives a LOD over the budget, `holds` one within it.
  const std::size_t before = mesh.triangle_count();
  std::size_t fails = path == PolychordPath::restarted ? before : q.triangles_after, holds = before;
  const std::size_t resolution = std::max<std::size_t>(1, (before - fails) / kPolychordResolutionDivisor);
  std::optional<SimplifyResult> best;
  while (holds - fails > resolution) {
    if (options.stop.requested()) {  // one poll per target measured
      if (best) best->stop_reason = StopReason::stopped;
      return best ? std::move(*best) : stopped_quad_result(mesh, quad::PolychordResult(q), 0.0);
    }
    const std::size_t mid = fails + (holds - fails) / 2;
    quad::PolychordResult trial = quad::simplify_polychord(mesh, quad_options(mid));
    if (trial.stopped) return stopped_quad_result(mesh, std::move(trial), 0.0);
    const BudgetCheck c = collapse::measure_budget(trial.mesh, reference_index, stop.max_error, options.threads);
    ++measured;
    if (c.within) {
      holds = mid;
      best = quad_result(std::move(trial), c);
    } else {
      fails = mid;
    }
  }
  if (best && best->triangles_after < before) {
    best->budget.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    return std::move(*best);
  }
  SimplifyResult r = collapse::run_within_budget(collapse::run_edge_collapse, triangulated(mesh), rest, policies);
  measured += r.budget.prefixes_measured;
  r.quad_engine_handed_over = true;
  r.mesh = quad::recover_quads(r.mesh, {.keep_triangles = true});
  return r;
}

// Engine::polychord: quad-preserving sub-polychord collapse (quad part) on the polygon mesh as it is; when it
// stops before the target, the triangle engine takes its output the rest of the way (that output is then
// triangles, with the pairs that split back into the same two triangles as quads: a LOD chain is quads for its
// first LODs and triangles after), or the input itself where the quad engine made under half the reduction.
SimplifyResult run_polychord(const Mesh& mesh, const SimplifyOptions& options, const CollapsePolicies& policies) {
  const auto t0 = std::chrono::steady_clock::now();
  const StopRule stop = collapse::stop_rule(options, mesh.triangle_count(), compute_bounds(mesh).diagonal());
  const std::size_t target = stop.target_triangles;
  auto quad_options = [&](std::size_t quad_target) {
    return quad::PolychordOptions{
             .target_triangles = std::max<std::size_t>(quad_target, 1),
             .max_error_abs = stop.has_budget() ? stop.max_error : -1.0,
             .border_weight = options.border_mode == BorderMode::free ? 0.0 : options.border_weight,
             .max_flip_angle_deg = options.max_flip_angle_deg,
             .lock_boundary = options.border_mode == BorderMode::lock,
             .locked_vertices = options.locked_vertices,
             .priority_lock = options.priority_lock,
             .skin_weight_threshold = options.skin_weight_threshold,
             .skin_max_distance = options.skin_max_distance,
             .normal_weight = options.attribute_weights.normal,
             .uv_weight = options.attribute_weights.uv,
             .color_weight = options.attribute_weights.color,
             .optimal_attributes = options.attribute_placement == AttributePlacement::optimal,
             .symmetry_weight = options.symmetry_weight,
             .symmetry_plane = options.symmetry_plane,
             .vertex_mirror = options.vertex_mirror,
             .stop = options.stop};
  };
  quad::PolychordResult q = quad::simplify_polychord(mesh, quad_options(target));
  const double quad_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  SimplifyResult r;
  if (q.stopped) return stopped_quad_result(mesh, std::move(q), quad_ms);
  PolychordPath path = PolychordPath::quad_only;
  if (q.triangles_after > target) {
    // Where there are too few chords (few quads, or triangles between almost every pair of them), the quad
    // engine stops early, and its few collapses, all on short chords, can cost more than the whole reduction
    // does with the triangle engine: on the corpus's mixedFaring (then with its n-gon corners locked) it made
    // 14% of the reduction to 50% and left the LOD 3.8x the triangle engine's mean distance. When it made less
    // than half of the reduction asked, the triangle engine starts again from the input.
    const std::size_t before = mesh.triangle_count();
    const bool restart = 2 * (before - q.triangles_after) < before - target;
    path = restart ? PolychordPath::restarted : PolychordPath::handed_over;
    SimplifyOptions rest = options;
    rest.engine = Engine::edge_collapse;
    rest.vertex_mirror = nullptr;  // the quad output's vertices are not the input's
    rest.target_triangles = std::max<std::size_t>(target, 1);
    if (!restart) rest.locked_vertices = locked_vertices_in(q.mesh, mesh, options.locked_vertices);
    r = collapse::run_edge_collapse(triangulated(restart ? mesh : q.mesh), rest, policies);
    r.quad_engine_handed_over = restart;
    // Triangle pairs that split back into the same two triangles come back as quads (the quads the triangle
    // engine left untouched among them); pairs that would split the other way stay triangles, so the surface
    // is the triangle engine's.
    r.mesh = quad::recover_quads(r.mesh, {.keep_triangles = true});
    if (!restart) {
      r.collapses += q.collapses;
      r.paired_collapses += q.paired_collapses;
      r.vetoes[Veto::weld] += q.rejected;
      r.vetoes[Veto::error_budget] += q.over_budget;
      r.qem_error_abs = std::max(r.qem_error_abs, q.error_bound_abs);
    }
  } else {
    r = quad_engine_result(std::move(q), options);
  }
  const double diagonal = compute_bounds(mesh).diagonal();
  if (options.verifies_budget() && r.stop_reason != StopReason::stopped) {
    const Mesh& reference = options.budget_reference != nullptr ? *options.budget_reference : mesh;
    std::optional<SurfaceIndex> local_index;
    const SurfaceIndex& index = collapse::reference_index(options, reference, local_index);
    BudgetCheck check = collapse::measure_budget(r.mesh, index, stop.max_error, options.threads);
    std::size_t measured = check.prefixes_measured;
    if (!check.within) r = hold_polychord_budget(mesh, options, policies, reference, index, q, quad_options, path, measured);
    else r.budget = check;
    r.budget.prefixes_measured = measured;
    r.error_bound_abs = r.budget.bound_abs;
    r.error_bound_rel = diagonal > 0.0 ? r.budget.bound_abs / diagonal : 0.0;
  }
  r.qem_error_rel = diagonal > 0.0 ? r.qem_error_abs / diagonal : 0.0;
  r.triangles_before = mesh.triangle_count();
  r.quads_before = q.quads_before;
  r.quads_after = count_face_kinds(r.mesh).quads;
  r.timings.collapse_ms += quad_ms;
  return r;
}

}  // namespace

SimplifyResult simplify(const Mesh& mesh, const SimplifyOptions& options) { return simplify(mesh, options, {}); }

SimplifyResult simplify(const Mesh& mesh, const SimplifyOptions& options, const CollapsePolicies& policies) {
  const std::vector<std::string> problems = options.validate();
  if (!problems.empty()) {
    std::string msg = "invalid simplify options:";
    for (const std::string& p : problems) msg += "\n  " + p;
    throw std::invalid_argument(msg);
  }
  // Clustering drops repeated faces itself (and collapse policies mean nothing to it).
  if (options.engine == Engine::cluster) {
    if (policies.any()) throw std::invalid_argument("invalid simplify options:\n  the cluster engine takes no collapse policies");
    return collapse::run_cluster(mesh, options);
  }
  // Faces repeating an earlier one go first (they draw nothing, and their non-manifold edges would stop the
  // engines around them: the MakeHuman hair at 10% measured a mean distance of 2.05% of the diagonal with
  // them, 0.13% without). A ratio target stays a ratio of the input as given.
  const std::vector<std::uint32_t> repeats = repeated_faces(mesh, options.threads);
  if (!repeats.empty()) {
    SimplifyOptions rest = options;
    rest.target_triangles = std::max<std::size_t>(
        collapse::stop_rule(options, mesh.triangle_count(), 0.0).target_triangles, 1);
    SimplifyResult r = simplify(without_faces(mesh, repeats), rest, policies);
    r.triangles_before = mesh.triangle_count();
    r.quads_before = count_face_kinds(mesh).quads;
    r.repeated_faces_removed = repeats.size();
    return r;
  }
  if (options.engine == Engine::polychord) return run_polychord(mesh, options, policies);
  const auto t0 = std::chrono::steady_clock::now();
  const FaceKindCounts kinds = count_face_kinds(mesh);
  const bool all_triangles = kinds.quads == 0 && kinds.polygons == 0;
  // Copy only when there is something to triangulate: the input is often the largest thing in memory.
  Mesh triangulated_copy;
  if (!all_triangles) triangulated_copy = triangulated(mesh);
  const Mesh& tris = all_triangles ? mesh : triangulated_copy;
  const double triangulate_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();

  const collapse::LoggedEngine engine =
      options.engine == Engine::multiple_choice ? collapse::run_multiple_choice : collapse::run_edge_collapse;
  // The multiple-choice engine is not guarded: it samples a few candidates a step, and where the guard refuses
  // most of them its rounds fail and it stops far above what the back-off along its log reaches.
  const bool guarded = options.engine != Engine::multiple_choice;
  SimplifyResult r = options.verifies_budget()
                         ? collapse::run_within_budget(engine, tris, options, policies, true, guarded)
                         : engine(tris, options, policies, nullptr, nullptr);
  r.triangles_before = mesh.triangle_count();
  r.quads_before = kinds.quads;
  r.timings.setup_ms += triangulate_ms;
  return r;
}

}  // namespace lodforge
