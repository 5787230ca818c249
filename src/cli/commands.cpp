#include "commands.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <tbb/task_arena.h>

#include "lodforge/batch/runner.hpp"
#include "lodforge/core/topology.hpp"
#include "lodforge/core/volume.hpp"
#include "lodforge/core/validate.hpp"
#include "lodforge/eval/attribute_eval.hpp"
#include "lodforge/eval/eval.hpp"
#include "lodforge/io/asset.hpp"
#include "lodforge/io/file.hpp"
#include "lodforge/quad/quad_stats.hpp"
#include "lodforge/simplify/simplify.hpp"
#include "lodforge/symmetry/symmetry.hpp"
#include "lodforge/tiling/stream.hpp"
#include "lodforge/tiling/tiling.hpp"

namespace lodforge::cli {
namespace {

int g_exit_code = 0;

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

// Expands folders into the supported files below them as `run` finds them (sorted, so output order is stable);
// entries that cannot be read (a symbolic link loop) are skipped with a warning on stderr.
std::vector<std::filesystem::path> expand_inputs(const std::vector<std::string>& inputs) {
  std::vector<std::filesystem::path> out;
  for (const std::string& in : inputs) {
    const std::filesystem::path p(in);
    std::error_code ec;
    if (std::filesystem::is_directory(p, ec)) {
      const batch::LibraryScan scan = batch::scan_library(p);
      for (const std::string& w : scan.skipped) std::fprintf(stderr, "warning: %s\n", w.c_str());
      for (const std::string& rel : scan.assets) out.push_back(p / rel);
    } else {
      out.push_back(p);
    }
  }
  return out;
}

std::size_t seam_vertices(const Mesh& m) {
  std::vector<std::uint32_t> wedges(m.vertex_count(), 0);
  for (std::uint32_t v : m.wedge_vertex) {
    if (v < wedges.size()) ++wedges[v];
  }
  return static_cast<std::size_t>(std::count_if(wedges.begin(), wedges.end(), [](std::uint32_t n) { return n > 1; }));
}

std::string attribute_list(const Mesh& m) {
  std::string s = "position";
  if (!m.normals.empty()) s += ", normal";
  if (!m.tangents.empty()) s += ", tangent";
  if (!m.uvs.empty()) s += ", uv x" + std::to_string(m.uvs.size());
  if (!m.colors.empty()) s += ", colour x" + std::to_string(m.colors.size());
  if (!m.skin.empty()) s += ", skin";
  if (!m.priority.empty()) s += ", priority";
  if (!m.morph_targets.empty()) s += ", morph targets x" + std::to_string(m.morph_targets.size());
  for (const CustomAttribute& a : m.custom) s += ", " + a.name;
  return s;
}

void print_symmetry(const Mesh& m, const Topology& topo, symmetry::PlaneMode mode) {
  if (mode == symmetry::PlaneMode::none) {
    std::printf("    symmetry: not looked for (--symmetry-plane none)\n");
    return;
  }
  const symmetry::SymmetryMap s = symmetry::detect_symmetry(m, topo, {.plane = mode});
  if (!s.found()) {
    std::printf("    symmetry: none found (plane %s)\n", symmetry::plane_mode_name(mode));
    return;
  }
  const Vec3d& n = s.plane.normal;
  std::printf("    symmetry: %.4f of edges (%zu of %zu) have a mirror edge; plane normal (%.6g, %.6g, %.6g), "
              "offset %.6g\n",
              s.symmetric_fraction(), s.symmetric_edges, s.edges, n[0], n[1], n[2], s.plane.offset);
}

void print_mesh_info(const Mesh& m, std::size_t index, symmetry::PlaneMode symmetry_plane) {
  const FaceKindCounts k = count_face_kinds(m);
  const Bounds3 b = compute_bounds(m);
  std::printf("  mesh %zu%s%s: %zu vertices, %zu wedges, %zu faces (%zu tri, %zu quad, %zu n-gon), %zu triangles, "
              "%zu material slot(s)\n",
              index, m.name.empty() ? "" : " ", m.name.c_str(), m.vertex_count(), m.wedge_count(), m.face_count(),
              k.triangles, k.quads, k.polygons, m.triangle_count(), m.materials.size());
  std::printf("    attributes: %s\n", attribute_list(m).c_str());
  if (!b.empty()) {
    std::printf("    bounds: [%g %g %g] .. [%g %g %g], diagonal %g\n", b.min[0], b.min[1], b.min[2], b.max[0], b.max[1],
                b.max[2], b.diagonal());
  }
  const ValidationReport r = validate(m);
  if (r.out_of_range_indices == 0) {
    const Topology topo = build_topology(m);
    const TopologySummary s = summarize_topology(m, topo);
    std::printf("    topology: %zu edges, %zu boundary edges in %zu loop(s), %zu non-manifold edges, "
                "%zu non-manifold vertices, %zu component(s), Euler characteristic %lld, %zu seam vertices\n",
                s.edges, s.boundary_edges, s.boundary_loops, s.non_manifold_edges, s.non_manifold_vertices,
                s.components, s.euler_characteristic, seam_vertices(m));
    print_symmetry(m, topo, symmetry_plane);
  }
  if (k.quads > 0) {
    const quad::QuadStats q = quad::quad_stats(m);
    std::printf("    quads: quad fraction %.3f, %zu triangles, %zu of %zu interior vertices irregular (valence != 4)\n",
                q.quad_fraction, q.triangles, q.irregular_vertices, q.interior_vertices);
  }
  if (r.messages.empty()) {
    std::printf("    validation: clean\n");
  } else {
    for (const std::string& msg : r.messages) std::printf("    validation: %s\n", msg.c_str());
  }
}

// An output the command cannot write (unsupported extension, an existing folder) is refused before any work.
bool output_writable(const std::string& out) {
  try {
    io::format_from_path(out);
    io::check_output_path(out);
    return true;
  } catch (const io::IoError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    set_exit_code(2);
    return false;
  }
}

// Whether every edge of the mesh's faces is shared by exactly two faces (a volume means something).
bool closed(const Mesh& m) {
  std::vector<std::pair<std::uint32_t, std::uint32_t>> edges;
  edges.reserve(m.corner_count());
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    const std::uint32_t c = m.face_offsets[f], n = m.face_size(f);
    for (std::uint32_t k = 0; k < n; ++k) {
      const std::uint32_t a = m.corner_vertex(c + k), b = m.corner_vertex(c + (k + 1) % n);
      edges.emplace_back(std::min(a, b), std::max(a, b));
    }
  }
  std::sort(edges.begin(), edges.end());
  for (std::size_t i = 0; i < edges.size();) {
    std::size_t j = i;
    while (j < edges.size() && edges[j] == edges[i]) ++j;
    if (j - i != 2) return false;
    i = j;
  }
  return !edges.empty();
}

// SimplifyOptions::validate() names its fields; on the command line the user wrote options.
std::string with_option_names(const std::string& problem) {
  static const std::pair<const char*, const char*> kNames[] = {
      {"target_ratio", "--ratio"},
      {"max_error_rel", "--max-error"},
      {"attribute_weights.normal", "--normal-weight"},
      {"attribute_weights.uv", "--uv-weight"},
      {"attribute_weights.color", "--color-weight"},
      {"attribute_weights.skin", "--skin-weight"},
      {"priority_channel", "--priority-channel"},
      {"priority_lock", "--priority-lock"},
      {"skin_weight_threshold", "--skin-threshold"},
      {"skin_max_distance", "--skin-max-distance"},
      {"tile_triangles", "--tile-triangles"},
      {"cluster_stage_factor", "--cluster-stage-factor"},
      {"conservative", "--conservative"},
      {"max_volume_growth", "--max-volume-growth"},
      {"symmetry_weight", "--symmetry-weight"},
  };
  for (const auto& [field, option] : kNames) {
    const std::string f(field);
    if (problem.rfind(f + " ", 0) == 0) return option + problem.substr(f.size());
  }
  return problem;
}

}  // namespace

const char* version() { return "0.1.0"; }
int exit_code() { return g_exit_code; }
void set_exit_code(int code) { g_exit_code = std::max(g_exit_code, code); }

CLI::Option* add_conservative_option(CLI::App* cmd, std::string& name, const std::string& help) {
  return cmd->add_option("--conservative", name, help)
      ->default_val(name)
      ->check(CLI::IsMember({"none", "bounding", "occluder"}));
}

Conservative conservative_mode(const std::string& name) {
  return name == "bounding" ? Conservative::bounding : name == "occluder" ? Conservative::occluder : Conservative::none;
}

void register_info(CLI::App& app) {
  auto inputs = std::make_shared<std::vector<std::string>>();
  auto symmetry_plane = std::make_shared<std::string>("auto");
  CLI::App* cmd = app.add_subcommand(
      "info", "Load, validate and summarise assets (files or folders, searched recursively).");
  cmd->add_option("inputs", *inputs, "asset files or folders (.gltf .glb .obj .ply .off .stl)")->required();
  cmd->add_option("--symmetry-plane", *symmetry_plane,
                  "mirror plane to look for: auto (the best found), x, y or z (normal along that axis, offset "
                  "found), none (skip); prints the plane and the fraction of edges that mirror each other")
      ->check(CLI::IsMember({"auto", "x", "y", "z", "none"}))
      ->capture_default_str();
  cmd->callback([inputs, symmetry_plane] {
    const symmetry::PlaneMode plane_mode = *symmetry::parse_plane_mode(*symmetry_plane);
    std::size_t ok = 0, failed = 0, triangles = 0;
    std::vector<std::filesystem::path> files;
    try {
      files = expand_inputs(*inputs);
    } catch (const io::IoError& e) {
      std::fprintf(stderr, "error: %s\n", e.what());
      set_exit_code(2);
      return;
    }
    if (files.empty()) {
      std::fprintf(stderr, "error: no supported asset files found\n");
      set_exit_code(2);
      return;
    }
    for (const auto& path : files) {
      try {
        const auto t0 = Clock::now();
        const io::Asset a = io::load_asset(path);
        const double load_ms = ms_since(t0);
        std::printf("%s: %s, %zu mesh(es), loaded in %.1f ms\n", path.string().c_str(), io::format_name(a.format),
                    a.meshes.size(), load_ms);
        for (std::size_t i = 0; i < a.meshes.size(); ++i) {
          print_mesh_info(a.meshes[i], i, plane_mode);
          triangles += a.meshes[i].triangle_count();
        }
        for (const std::string& w : a.warnings) std::printf("  warning: %s\n", w.c_str());
        ++ok;
      } catch (const io::IoError& e) {
        std::fprintf(stderr, "error: %s\n", e.what());
        ++failed;
      }
    }
    std::printf("summary: %zu asset(s) loaded, %zu failed, %zu triangles in all\n", ok, failed, triangles);
    if (failed > 0) set_exit_code(2);
  });
}

void register_convert(CLI::App& app) {
  auto in = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  CLI::App* cmd = app.add_subcommand("convert", "Convert an asset between formats (format from the extension).");
  cmd->add_option("input", *in, "input asset")->required();
  cmd->add_option("output", *out, "output asset (written atomically)")->required();
  cmd->callback([in, out] {
    if (!output_writable(*out)) return;
    try {
      const io::Asset a = io::load_asset(*in);
      io::save_asset(a, *out);
      for (const std::string& w : a.warnings) std::printf("warning: %s\n", w.c_str());
      std::printf("%s -> %s\n", in->c_str(), out->c_str());
    } catch (const io::IoError& e) {
      std::fprintf(stderr, "error: %s\n", e.what());
      set_exit_code(2);
    }
  });
}

// The worker threads a --memory-limit plan counts on: --threads, or the machine's.
unsigned plan_workers(const SimplifyOptions& opt) {
  return opt.threads ? opt.threads : static_cast<unsigned>(tbb::this_task_arena::max_concurrency());
}

// Why these options cannot tile (so neither split a mesh under a memory limit nor stream it), or null.
using tiling::why_not_tileable;

// `lodforge simplify --memory-limit` on a binary PLY or OBJ too large to load whole under the limit: streamed
// out of core (tiling/stream.hpp). False where the file loads whole (the caller goes on as usual). Tiles are
// written beside the output, in a folder removed afterwards.
bool simplify_out_of_core(const std::string& in, const std::string& out, const SimplifyOptions& opt,
                          std::size_t memory_limit, const std::string& limit_text, bool evaluate) {
  const tiling::StreamPlan plan = tiling::plan_stream(in, opt, memory_limit, plan_workers(opt));
  if (!plan.stream) return false;
  const char* not_tileable = why_not_tileable(opt);
  if (!plan.fits || not_tileable != nullptr) {
    std::fprintf(stderr,
                 "error: %s: %llu triangles do not fit in --memory-limit %s loaded whole (about %zu MiB), and %s%s\n",
                 in.c_str(), static_cast<unsigned long long>(plan.counts.triangles), limit_text.c_str(),
                 plan.whole_bytes >> 20,
                 not_tileable != nullptr ? not_tileable
                                         : "streamed out of core it needs more too (the program, the vertex "
                                           "positions and tiles of at least 1000 triangles)",
                 not_tileable != nullptr ? ", so it cannot stream either" : "");
    set_exit_code(2);
    return true;
  }
  std::printf("%s: about %zu MiB loaded whole, over --memory-limit %s: streamed out of core in tiles of %zu "
              "triangles (about %zu MiB)\n",
              in.c_str(), plan.whole_bytes >> 20, limit_text.c_str(), plan.tile_triangles, plan.stream_bytes >> 20);
  const std::filesystem::path scratch = std::filesystem::path(out).concat(".lodforge-tiles");
  struct RemoveScratch {
    const std::filesystem::path& path;
    ~RemoveScratch() {
      std::error_code ec;
      std::filesystem::remove_all(path, ec);
    }
  } remove_scratch{scratch};
  tiling::StreamedRun run =
      tiling::simplify_streamed(in, opt, plan.tile_triangles, scratch, memory_limit, plan.counts.vertices);
  for (const std::string& w : run.warnings) std::printf("warning: %s\n", w.c_str());
  const SimplifyResult& r = run.result;
  std::printf("mesh 0: %zu -> %zu triangles (%zu vertices read, %zu tiles on disk), QEM error %.4f%% of diagonal (a "
              "ranking, not a bound), stopped: %s, %.1f ms\n",
              r.triangles_before, r.triangles_after, run.input_vertices, run.tiles,
              100.0 * r.qem_error_rel, stop_reason_name(r.stop_reason),
              r.timings.setup_ms + r.timings.initial_costs_ms + r.timings.collapse_ms + r.timings.output_ms);
  std::printf("  tiled: %zu pass(es), %zu tile run(s)\n", r.tiling_passes, r.tile_runs);
  if (evaluate) std::printf("  not measured: --eval needs the whole input in memory\n");
  io::Asset asset;
  asset.source = in;
  asset.format = io::format_from_path(in);
  asset.binary = true;
  asset.obj_mtllibs = run.mtllibs;
  asset.meshes.push_back(std::move(run.result.mesh));
  io::save_asset(asset, out);
  std::printf("wrote %s\n", out.c_str());
  return true;
}

void register_simplify(CLI::App& app) {
  struct Args {
    std::string in, out, engine = "edge_collapse", border = "preserve";
    SimplifyOptions opt;
    double max_error_rel = -1;
    bool keep_attributes = false;
    std::string seams = "relax";
    std::string conservative = "none";
    std::string symmetry_plane = "auto";
    double max_volume_growth_pct = -1;
    std::string tiling = "auto";
    std::string cluster_stage = "auto";
    std::string memory_limit;
    bool evaluate = false;
    bool no_verify = false;
  };
  auto a = std::make_shared<Args>();
  CLI::App* cmd = app.add_subcommand("simplify", "Simplify every mesh of an asset and write the result.");
  cmd->add_option("input", a->in, "input asset")->required();
  cmd->add_option("output", a->out, "output asset (written atomically)")->required();
  cmd->add_option("--ratio", a->opt.target_ratio, "target fraction of the input triangles, in (0, 1]")
      ->default_val(0.5);
  cmd->add_option("--triangles", a->opt.target_triangles, "target triangle count (overrides --ratio)");
  cmd->add_option("--max-error", a->max_error_rel,
                  "error budget as a fraction of the asset's bounding-box diagonal: the LOD stays within it of the "
                  "input, measured both ways");
  cmd->add_flag("--no-verify", a->no_verify,
                "stop on the engine's QEM error alone; do not measure the LOD against the budget (faster, not a bound)");
  cmd->add_option("--engine", a->engine,
                  "edge_collapse | multiple_choice | polychord | cluster (vertex clustering: fastest, coarsest; far "
                  "LODs and huge inputs)")
      ->default_val("edge_collapse");
  cmd->add_option("--border", a->border, "free | preserve | lock")->default_val("preserve");
  cmd->add_option("--threads", a->opt.threads, "worker threads (0 = all cores)")->default_val(0);
  cmd->add_option("--seed", a->opt.seed, "random seed (multiple_choice)")->default_val(1);
  cmd->add_option("--normal-weight", a->opt.attribute_weights.normal, "weight of normal error (0 = ignore)")
      ->default_val(a->opt.attribute_weights.normal);
  cmd->add_option("--uv-weight", a->opt.attribute_weights.uv, "weight of UV error, scaled by UV density (0 = ignore)")
      ->default_val(a->opt.attribute_weights.uv);
  cmd->add_option("--color-weight", a->opt.attribute_weights.color, "weight of vertex colour error (0 = ignore)")
      ->default_val(a->opt.attribute_weights.color);
  cmd->add_option("--skin-weight", a->opt.attribute_weights.skin, "weight of skin weight error (0 = ignore)")
      ->default_val(a->opt.attribute_weights.skin);
  cmd->add_flag("--keep-attributes", a->keep_attributes,
                "moved vertices keep the surviving wedges' attributes (LODs can share one vertex buffer)");
  cmd->add_option("--seams", a->seams,
                  "keep | relax | relax_materials: when seams stop the LOD above its target, relax them in stages "
                  "(soft creases, hard normals, UV-seam corners; material boundaries with relax_materials)")
      ->default_val(a->seams)
      ->check(CLI::IsMember({"keep", "relax", "relax_materials"}));
  cmd->add_flag("--permissive", a->opt.permissive, "deprecated: the same as --seams relax");
  cmd->add_option("--priority-channel", a->opt.priority_channel,
                  "painted priority: _LOD_PRIORITY, a custom attribute (_PAINT, _PAINT.y), COLOR_0.r, or none")
      ->default_val(a->opt.priority_channel);
  cmd->add_option("--priority-lock", a->opt.priority_lock, "painted priority at or above which a vertex is locked")
      ->default_val(a->opt.priority_lock);
  cmd->add_option("--skin-threshold", a->opt.skin_weight_threshold,
                  "influences below this weight are ignored when comparing bones")
      ->default_val(a->opt.skin_weight_threshold);
  cmd->add_option("--skin-max-distance", a->opt.skin_max_distance,
                  "vertices of different dominant bones merge only below this L1 weight distance")
      ->default_val(a->opt.skin_max_distance);
  add_conservative_option(cmd, a->conservative,
                          "none | bounding | occluder: a LOD that contains the input (collision) or lies inside it "
                          "(occlusion culling); edge_collapse and multiple_choice engines; on open meshes the rim "
                          "keeps its outline (docs/conservative.md)");
  cmd->add_option("--max-volume-growth", a->max_volume_growth_pct,
                  "PCT: with --conservative, stop before the LOD's volume grows (bounding) or shrinks (occluder) by "
                  "more than this percentage of the input's");
  cmd->add_option("--symmetry-weight", a->opt.symmetry_weight,
                  "favour mirror pairs: an edge (polychord engine: a run of rungs) and its mirror image collapse "
                  "together, and a collapse that breaks the symmetry costs 1 + this times its error (0 = off; "
                  "edge_collapse and polychord engines; multiple_choice, cluster and tiled runs ignore it; "
                  "docs/symmetry.md)")
      ->default_val(a->opt.symmetry_weight);
  cmd->add_option("--symmetry-plane", a->symmetry_plane,
                  "with --symmetry-weight: the mirror plane to look for: auto, x, y, z (normal along that axis), none")
      ->default_val(a->symmetry_plane)
      ->check(CLI::IsMember({"auto", "x", "y", "z", "none"}));
  cmd->add_option("--tiling", a->tiling,
                  "auto | on | off: cut huge meshes into spatial tiles simplified in parallel with locked shared "
                  "borders, stitched and re-cut on a shifted grid (auto: from 1,000,000 triangles; triangle "
                  "engines without an error budget; docs/tiling.md)")
      ->default_val(a->tiling)
      ->check(CLI::IsMember({"auto", "on", "off"}));
  cmd->add_option("--tile-triangles", a->opt.tile_triangles,
                  "triangles per tile on the tiled path (at least 100)")
      ->default_val(a->opt.tile_triangles);
  cmd->add_option("--cluster-stage", a->cluster_stage,
                  "auto | on | off: on the tiled path, vertex-cluster the whole mesh to --cluster-stage-factor times "
                  "the target first and let the tiled edge-collapse passes finish from there (auto: from "
                  "4,000,000 triangles, where that is at most a quarter of the input, no locked vertices, no "
                  "conservative mode; docs/tiling.md)")
      ->default_val(a->cluster_stage)
      ->check(CLI::IsMember({"auto", "on", "off"}));
  cmd->add_option("--cluster-stage-factor", a->opt.cluster_stage_factor,
                  "the cluster stage's output, in multiples of the target (at least 1)")
      ->default_val(a->opt.cluster_stage_factor);
  cmd->add_option("--memory-limit", a->memory_limit,
                  "SIZE (512M, 4G; at least 16M): estimate each mesh's peak memory from its triangle count and tile "
                  "it, with tiles small enough, where one engine run would not fit; stream a binary PLY or OBJ "
                  "that does not fit loaded whole into tiles on disk (positions and faces only); refuse what does "
                  "not fit even so (docs/tiling.md)");
  cmd->add_flag("--eval", a->evaluate, "measure the result against the input (Hausdorff, mean, RMS)");
  cmd->callback([a] {
    SimplifyOptions opt = a->opt;
    opt.tiling = a->tiling == "on" ? TilingMode::on : a->tiling == "off" ? TilingMode::off : TilingMode::automatic;
    opt.cluster_stage = a->cluster_stage == "on"    ? TilingMode::on
                        : a->cluster_stage == "off" ? TilingMode::off
                                                    : TilingMode::automatic;
    if (a->keep_attributes) opt.attribute_placement = AttributePlacement::keep;
    opt.seams = a->seams == "keep" ? SeamMode::keep : a->seams == "relax" ? SeamMode::relax : SeamMode::relax_materials;
    opt.max_error_rel = a->max_error_rel;
    opt.verify_budget = !a->no_verify;
    opt.conservative = conservative_mode(a->conservative);
    opt.max_volume_growth = a->max_volume_growth_pct >= 0.0 ? a->max_volume_growth_pct / 100.0 : -1.0;
    opt.symmetry_plane = *symmetry::parse_plane_mode(a->symmetry_plane);
    if (a->engine == "edge_collapse") opt.engine = Engine::edge_collapse;
    else if (a->engine == "multiple_choice") opt.engine = Engine::multiple_choice;
    else if (a->engine == "polychord") opt.engine = Engine::polychord;
    else if (a->engine == "cluster") opt.engine = Engine::cluster;
    else {
      std::fprintf(stderr, "error: --engine: unknown engine '%s' (edge_collapse | multiple_choice | polychord | cluster)\n",
                   a->engine.c_str());
      set_exit_code(2);
      return;
    }
    if (a->border == "free") opt.border_mode = BorderMode::free;
    else if (a->border == "preserve") opt.border_mode = BorderMode::preserve;
    else if (a->border == "lock") opt.border_mode = BorderMode::lock;
    else {
      std::fprintf(stderr, "error: --border: unknown mode '%s' (free | preserve | lock)\n", a->border.c_str());
      set_exit_code(2);
      return;
    }
    if (const auto problems = opt.validate(); !problems.empty()) {
      for (const std::string& p : problems) std::fprintf(stderr, "error: %s\n", with_option_names(p).c_str());
      set_exit_code(2);
      return;
    }
    std::size_t memory_limit = 0;
    if (!a->memory_limit.empty()) {
      try {
        memory_limit = tiling::parse_memory_size(a->memory_limit);
      } catch (const std::invalid_argument& e) {
        std::fprintf(stderr, "error: --memory-limit: %s\n", e.what());
        set_exit_code(2);
        return;
      }
    }
    if (!output_writable(a->out)) return;
    try {
      if (memory_limit > 0 && io::streamable(a->in) && simplify_out_of_core(a->in, a->out, opt, memory_limit,
                                                                             a->memory_limit, a->evaluate)) {
        return;
      }
      io::Asset asset = io::load_asset(a->in);
      // Every mesh is planned before any is simplified: a mesh that cannot fit fails the run before the work.
      std::vector<tiling::MemoryPlan> plans(asset.meshes.size());
      if (memory_limit > 0) {
        for (std::size_t i = 0; i < asset.meshes.size(); ++i) {
          plans[i] = tiling::plan_memory(asset.meshes[i], opt, memory_limit, plan_workers(opt));
          if (plans[i].fits) continue;
          const char* not_tileable = why_not_tileable(opt);
          std::fprintf(stderr,
                       "error: %s: mesh %zu (%zu triangles) does not fit in --memory-limit %s: %s%s\n",
                       a->in.c_str(), i, asset.meshes[i].triangle_count(), a->memory_limit.c_str(),
                       not_tileable != nullptr ? "one engine run needs more and " : "",
                       not_tileable != nullptr ? not_tileable
                                               : "the mesh held in memory with the tiled path's arrays needs more");
          set_exit_code(2);
          return;
        }
      }
      // A relative budget is of the asset's diagonal as the scene shows it (glTF node transforms applied), for
      // every mesh of it; each mesh gets it in its own units.
      const double world_diagonal = io::world_bounds(asset).diagonal();
      const double max_error_rel = opt.max_error_rel;
      for (std::size_t i = 0; i < asset.meshes.size(); ++i) {
        const Mesh& src = asset.meshes[i];
        const double diagonal = world_diagonal / io::world_scale(asset, i);
        auto percent = [&](double x) { return diagonal > 0.0 ? 100.0 * x / diagonal : 0.0; };
        SimplifyOptions mesh_opt = opt;
        if (max_error_rel >= 0.0) {
          mesh_opt.max_error_abs = max_error_rel * diagonal;
          mesh_opt.max_error_rel = -1.0;
        }
        if (plans[i].force_tiling) {
          plans[i].apply(mesh_opt);
          std::printf("mesh %zu: about %zu MiB untiled, over --memory-limit %s: tiled in tiles of %zu triangles "
                      "(about %zu MiB)\n",
                      i, plans[i].untiled_bytes >> 20, a->memory_limit.c_str(), plans[i].tile_triangles,
                      plans[i].tiled_bytes >> 20);
        }
        SimplifyResult r = simplify_maybe_tiled(src, mesh_opt);
        std::printf("mesh %zu: %zu -> %zu triangles, QEM error %.4f%% of diagonal (a ranking, not a bound), "
                    "stopped: %s, %.1f ms\n",
                    i, r.triangles_before, r.triangles_after, percent(r.qem_error_abs),
                    stop_reason_name(r.stop_reason),
                    r.timings.setup_ms + r.timings.initial_costs_ms + r.timings.collapse_ms + r.timings.output_ms);
        if (r.cluster_stage_triangles > 0)
          std::printf("  cluster stage: %zu triangles\n", r.cluster_stage_triangles);
        if (r.tiling_passes > 0)
          std::printf("  tiled: %zu pass(es), %zu tile run(s)\n", r.tiling_passes, r.tile_runs);
        if (opt.symmetry_weight > 0.0)
          std::printf("  symmetry: %zu of %zu collapses made in mirror pairs\n", r.paired_collapses, r.collapses);
        if (r.seam_stage != SeamStage::strict)
          std::printf("  seams relaxed: stage %s\n", seam_stage_name(r.seam_stage));
        if (!r.floors.empty()) {
          std::string floors;
          for (const std::string& f : r.floors) floors += (floors.empty() ? "" : ", ") + f;
          std::printf("  target not reached, held by: %s\n", floors.c_str());
        }
        if (opt.conservative != Conservative::none && closed(src)) {
          const double v0 = signed_volume(src), v1 = signed_volume(r.mesh);
          std::printf("  conservative %s: volume %+.3f%% of the input's (%zu collapse(s) refused by the rule)\n",
                      conservative_name(opt.conservative), v0 != 0.0 ? 100.0 * (v1 / v0 - 1.0) : 0.0,
                      r.vetoes[Veto::conservative]);
        }
        if (r.budget.verified) {
          // Measurements stop at the first distance over the budget: those print as "over".
          auto figure = [&](double x) {
            if (!std::isfinite(x)) return std::string("over the budget");
            char text[32];
            std::snprintf(text, sizeof text, "%.4f%%", percent(x));
            return std::string(text);
          };
          const char* how = !r.budget.within    ? ""
                            : r.budget.certified ? ""
                                                 : " (bound not refined to the budget: met by measurement)";
          // The input → LOD bound gives up at 1.1 budgets (the sampling tolerance): "over" there means that.
          std::printf("  budget %.4f%%: %s; LOD to input: bound %s, measured %s%s; input to LOD: bound %s, "
                      "measured %s; %zu collapse(s) backed off, %zu prefix(es) measured, %zu guarded rerun(s), "
                      "%.1f ms\n",
                      percent(r.budget.budget_abs), r.budget.within ? "met" : "MISSED",
                      figure(r.budget.bound_abs).c_str(), figure(r.budget.sampled_abs).c_str(), how,
                      figure(r.budget.reverse_bound_abs).c_str(), figure(r.budget.reverse_abs).c_str(),
                      r.budget.collapses_undone, r.budget.prefixes_measured, r.budget.guard_reruns, r.budget.ms);
        }
        if (r.repeated_faces_removed > 0) {
          std::printf("  note: dropped %zu face(s) repeating an earlier face (same corners, winding and material)\n",
                      r.repeated_faces_removed);
        }
        if (r.quad_engine_handed_over) {
          std::printf("  note: the quad engine could make less than half of this reduction (too few quad strips); "
                      "the triangle engine simplified the input\n");
        }
        if (opt.engine == Engine::polychord) {
          std::printf("  quads: %zu -> %zu (quad fraction %.3f)\n", r.quads_before, r.quads_after,
                      quad::quad_stats(r.mesh).quad_fraction);
        }
        if (a->evaluate) {
          const EvalResult e = evaluate(src, r.mesh, EvalOptions{.threads = opt.threads});
          std::printf("  measured: Hausdorff %.4f%% (LOD to input %.4f%%), mean %.5f%%, RMS %.5f%% of diagonal; "
                      "normals off by %.2f deg on average (95%%: %.2f)\n",
                      100 * e.hausdorff_rel(), percent(e.b_to_a.max), 100 * e.mean_rel(), 100 * e.rms_rel(),
                      e.normal_deviation_mean_deg, e.normal_deviation_p95_deg);
        }
        asset.meshes[i] = std::move(r.mesh);
      }
      io::save_asset(asset, a->out);
      std::printf("wrote %s\n", a->out.c_str());
    } catch (const io::IoError& e) {
      std::fprintf(stderr, "error: %s\n", e.what());
      set_exit_code(2);
    }
  });
}

void register_eval(CLI::App& app) {
  auto a = std::make_shared<std::pair<std::string, std::string>>();
  auto opt = std::make_shared<EvalOptions>();
  auto json = std::make_shared<bool>(false);
  CLI::App* cmd = app.add_subcommand(
      "eval", "Measure the surface distance between an original and a simplified asset (Metro-style, both ways).");
  cmd->add_option("original", a->first, "original asset")->required();
  cmd->add_option("simplified", a->second, "simplified asset")->required();
  cmd->add_option("--samples", opt->samples, "area samples per direction (0 = automatic)");
  cmd->add_option("--seed", opt->seed, "sampling seed");
  cmd->add_option("--threads", opt->threads, "worker threads (0 = all cores)");
  cmd->add_flag("--json", *json, "print the result as JSON");
  cmd->callback([a, opt, json] {
    try {
      const io::Asset orig = io::load_asset(a->first);
      const io::Asset simp = io::load_asset(a->second);
      // Meshes of an asset are measured as one surface, placed as the scene shows them (glTF node transforms).
      const EvalResult r = evaluate(io::world_surface(orig), io::world_surface(simp), *opt);
      // Attributes, UVs and skinning per mesh (meshes pair up by index when both assets have as many).
      std::vector<AttributeEvalResult> attrs;
      if (orig.meshes.size() == simp.meshes.size()) {
        for (std::size_t i = 0; i < orig.meshes.size(); ++i) {
          attrs.push_back(evaluate_attributes(orig.meshes[i], simp.meshes[i],
                                              {.seed = opt->seed, .threads = opt->threads}));
        }
      }
      if (*json) {
        std::printf("{\"hausdorff\": %.9g, \"mean\": %.9g, \"rms\": %.9g, \"diagonal\": %.9g, "
                    "\"hausdorff_rel\": %.9g, \"mean_rel\": %.9g, \"rms_rel\": %.9g, "
                    "\"original_to_simplified\": {\"max\": %.9g, \"mean\": %.9g, \"rms\": %.9g}, "
                    "\"simplified_to_original\": {\"max\": %.9g, \"mean\": %.9g, \"rms\": %.9g}, "
                    "\"normal_deviation_mean_deg\": %.6g, \"normal_deviation_p95_deg\": %.6g, \"meshes\": [",
                    r.hausdorff, r.mean, r.rms, r.diagonal, r.hausdorff_rel(), r.mean_rel(), r.rms_rel(),
                    r.a_to_b.max, r.a_to_b.mean, r.a_to_b.rms, r.b_to_a.max, r.b_to_a.mean, r.b_to_a.rms,
                    r.normal_deviation_mean_deg, r.normal_deviation_p95_deg);
        for (std::size_t i = 0; i < attrs.size(); ++i) {
          const AttributeEvalResult& x = attrs[i];
          std::printf("%s{\"attribute_rms\": {", i ? ", " : "");
          for (std::size_t k = 0; k < x.attributes.size(); ++k) {
            std::printf("%s\"%s\": %.9g", k ? ", " : "", x.attributes[k].name.c_str(), x.attributes[k].rms);
          }
          std::printf("}, \"interpolated_normal_deviation_mean_deg\": %.6g, \"interpolated_normal_deviation_p95_deg\": %.6g, "
                      "\"uv_sets\": [",
                      x.normal_deviation_mean_deg, x.normal_deviation_p95_deg);
          for (std::size_t k = 0; k < x.uv_sets.size(); ++k) {
            const UvSetReport& u = x.uv_sets[k];
            std::printf("%s{\"set\": %d, \"stretch_ratio\": %.6g, \"stretch_max_linf\": %.6g, \"flipped\": %zu, "
                        "\"spanning_charts\": %zu, \"outside_charts\": %zu, \"zero_area\": %zu}",
                        k ? ", " : "", u.set, u.stretch_ratio, u.stretch_max_linf, u.flipped, u.spanning, u.outside,
                        u.degenerate);
          }
          std::printf("], \"poses\": [");
          for (std::size_t k = 0; k < x.poses.size(); ++k) {
            std::printf("%s{\"pose\": \"%s\", \"hausdorff_rel\": %.9g, \"mean_rel\": %.9g}", k ? ", " : "",
                        x.poses[k].name.c_str(), x.poses[k].hausdorff_rel, x.poses[k].mean_rel);
          }
          std::printf("]}");
        }
        std::printf("]}\n");
      } else {
        std::printf("bounding-box diagonal of the original: %.6g\n", r.diagonal);
        std::printf("                      absolute        %% of diagonal\n");
        std::printf("Hausdorff (symmetric) %-15.6g %.5f\n", r.hausdorff, 100 * r.hausdorff_rel());
        std::printf("mean                  %-15.6g %.5f\n", r.mean, 100 * r.mean_rel());
        std::printf("RMS                   %-15.6g %.5f\n", r.rms, 100 * r.rms_rel());
        std::printf("original -> simplified: max %.6g, mean %.6g, RMS %.6g (%zu samples)\n", r.a_to_b.max,
                    r.a_to_b.mean, r.a_to_b.rms, r.a_to_b.samples);
        std::printf("simplified -> original: max %.6g, mean %.6g, RMS %.6g (%zu samples)\n", r.b_to_a.max,
                    r.b_to_a.mean, r.b_to_a.rms, r.b_to_a.samples);
        std::printf("normal deviation: mean %.3f deg, p95 %.3f deg\n", r.normal_deviation_mean_deg,
                    r.normal_deviation_p95_deg);
        for (std::size_t i = 0; i < attrs.size(); ++i) {
          const AttributeEvalResult& x = attrs[i];
          std::printf("mesh %zu:", i);
          for (const AttributeError& a : x.attributes) std::printf(" %s RMS %.4g;", a.name.c_str(), a.rms);
          if (!x.attributes.empty()) {
            std::printf(" interpolated normals: mean %.3f deg, p95 %.3f deg", x.normal_deviation_mean_deg,
                        x.normal_deviation_p95_deg);
          }
          std::printf("\n");
          for (const UvSetReport& u : x.uv_sets) {
            std::printf("  TEXCOORD_%d: stretch x%.3f (max Linf %.3g), %zu flipped, %zu spanning two charts, "
                        "%zu corners outside every chart, %zu zero-area (original %zu)\n",
                        u.set, u.stretch_ratio, u.stretch_max_linf, u.flipped, u.spanning, u.outside, u.degenerate,
                        u.degenerate_original);
          }
          for (const PoseError& p : x.poses) {
            std::printf("  pose %s: Hausdorff %.5f%%, mean %.5f%% of the diagonal\n", p.name.c_str(),
                        100 * p.hausdorff_rel, 100 * p.mean_rel);
          }
        }
      }
    } catch (const io::IoError& e) {
      std::fprintf(stderr, "error: %s\n", e.what());
      set_exit_code(2);
    }
  });
}

}  // namespace lodforge::cli
