// report.json: what a batch run did, one record per asset and LOD. Shape:
//
//   {"lodforge_version": str, "config_file": str, "effective_config": {...}, "jobs": int, "shard": "K/N" | null,
//    "summary": {"assets", "succeeded", "failed", "skipped", "cache_hits", "lods", "input_triangles",
//                "output_triangles": int, "seconds": float, "lods_missed", "not_started": int},
//    "assets": [{"path", "class": str | null, "status": "ok" | "failed" | "skipped" | "not_started",
//                "error": str | null,
//                "cache_hit": bool, "seconds": float, "input": {"triangles", "vertices": int, "diagonal": float,
//                "repeated_faces": int},
//                "outputs": [str], "lods": [{"level", "from", "target": {"kind", "value"}, "target_triangles",
//                "triangles", "vertices", "ratio", "error_bound_abs", "error_bound_rel", "mean_rel", "rms_rel",
//                "hausdorff_rel", "normal_deviation_mean_deg", "attributes": {name: float}, "quad_fraction",
//                "irregular_vertices", "stop_reason", "seconds", "screen_coverage", "shows_previous"}]}]}
//
// Also per asset "input.bytes" (the source's mesh data on disk) and "output_bytes" (everything written for it,
// cache hits and records of earlier versions may lack it); at the top "input_dir" and "output_dir" (the folders
// of the run; merged reports lack them) and "changes" (diff_reports() against the report.json the run replaced in
// the same output folder; absent on a first run).
// "input.repeated_faces": faces that repeat an earlier face of their mesh (core repeated_faces()); simplify()
// drops them before anything else (reports of earlier versions lack it).
// "input.symmetry": {"plane_mode": "auto" | "x" | "y" | "z" | "none" (the class's symmetry_plane),
// "symmetric_edges", "edges": int, "fraction": float, "plane": [nx, ny, nz, d] | null} -- the asset's edges that
// have a mirror edge (symmetry::detect_symmetry, docs/symmetry.md) summed over its meshes, and the plane
// n.x + d = 0 of the mesh with the most of them, in that mesh's coordinates; null when none was found (reports
// of earlier versions lack it).
// Per LOD: "target" is what the config asked ({"kind": "ratio" | "triangles" | "max_error" | "screen_size",
// "value"}), "target_triangles" its triangle count for this asset (null for error targets), "triangles" and
// "vertices" what was achieved; "error_bound_*" the simplifier's bound on the error against the source
// (accumulated along the chain), "mean_rel", "rms_rel" and "hausdorff_rel" the error measured by eval (relative
// to the source's bounding-box diagonal); "attributes" the attribute metrics eval provides (face-normal
// deviation, per-stream attribute RMS, UV flips, chart spans and stretch, skinned pose error: runner.cpp
// attribute_metrics() lists them); "quad_fraction" and "irregular_vertices" the LOD's quad structure (quads /
// faces, interior vertices of valence != 4: quad::quad_stats); "screen_coverage" the LOD's MSFT_screencoverage entry (docs/batch.md, "Screen coverage");
// "shows_previous" true where the LOD was not 10% smaller than the level before and shows that level's meshes
// (no file of its own; reports of earlier versions lack it). lods.json (lods_manifest.hpp) is built from this.
//
// "conservative_lods" (assets of classes with collision or occluder LODs only): [{"kind": "collision" | "occluder",
// "mode": "bounding" | "occluder", "target": {"kind", "value"} (kind "max_volume_growth" for a collision with only a
// volume budget), "target_triangles", "max_volume_growth_pct": float | null, "triangles", "vertices", "ratio",
// "error_bound_abs", "error_bound_rel", "error_bound_kind", "budget", "mean_rel", "rms_rel", "hausdorff_rel",
// "volume_change_pct": float | null (LOD volume / source volume - 1, in %; null for an open source),
// "collapses_refused" (by the nesting rule), "stop_reason", "seconds", "outputs": [str] (its own files),
// "gltf_node_suffix": "_collision" | "_occluder" | null (its nodes in the asset's MSFT_lod glTF)}]. They are no
// render level: not in "lods", lods.json or the summary's "lods" and "output_triangles"; the summary counts them
// as "conservative_lods" and "conservative_lods_missed", present only when some asset has them.
// "skipped": no class of the config matches the asset; "not_started": the run was stopped (Ctrl-C) before the
// asset was reached (reports of earlier versions called those "skipped" and lack "not_started").
// Assets are sorted by path. "seconds" (summary, asset, LOD) are the only fields that differ between two runs
// of the same library, config and cache state, whatever --jobs; the report render (report_html.hpp) and
// `lodforge merge-reports` read this document.
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace lodforge::batch {

// The summary of an asset list (counts and sums as above); `seconds` is the run's wall time.
nlohmann::json report_summary(const nlohmann::json& assets, double seconds);

// Every way `report` differs from the shape above, one line each ("assets[3].lods[0].ratio: expected a
// number"); empty = well-formed.
std::vector<std::string> check_report(const nlohmann::json& report);

// The report with every "seconds" field removed: what two runs of the same work must agree on.
nlohmann::json without_timings(nlohmann::json report);

// One report from the reports of the shards of a run: assets merged and sorted by path, summary recomputed
// (seconds = the slowest shard), "shard" null. Throws std::invalid_argument when the reports are malformed, come
// from different configs or lodforge versions, or list an asset twice.
nlohmann::json merge_reports(const std::vector<nlohmann::json>& reports);

// What changed from `previous` to `current`, two reports of runs into the same output (report.json "changes"):
//   {"previous_assets": int, "added": [path], "removed": [path], "rebuilt": [path],
//    "status_changed": [{"path", "from", "to"}],
//    "lods_moved": [{"path", "level", "triangles": [before, after], "hausdorff_rel": [before, after],
//                    "moved": ["triangles" | "hausdorff_rel" | "lod_count"]}]}
// "rebuilt": in both, simplified again this time (not a cache hit) and ok; "lods_moved": LODs of assets in both
// whose triangle count or measured Hausdorff distance moved by more than 5% of the previous value (from zero:
// any change), and assets whose LOD count changed (level null). Lists are in path, then level, order. Reads
// both documents defensively: missing or mistyped fields count as absent, never throw.
nlohmann::json diff_reports(const nlohmann::json& previous, const nlohmann::json& current);

// The same as human text, one line per change, led by a line of counts; at most `max_lines` listed per kind
// (0: all).
std::string changes_text(const nlohmann::json& changes, std::size_t max_lines = 0);

// Writes report.json (indented) and the HTML page rendered from it, each atomically. Throws io::IoError.
void write_report(const nlohmann::json& report, const std::filesystem::path& json_path,
                  const std::filesystem::path& html_path);

}  // namespace lodforge::batch
