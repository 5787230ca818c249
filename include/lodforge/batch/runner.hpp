// The batch LOD processor: every asset of a library through one tbb::flow::graph.
//
//   const BatchConfig config = load_config("configs/default.json");
//   const RunResult r = run_batch(config, {.config_file = "configs/default.json", .input_dir = "library",
//                                          .output_dir = "out", .jobs = 8});
//   // r.report is report.json; OUT_DIR holds the LODs, report.json, report.html and .lodforge-cache/
//
// Per asset: fingerprint + cache lookup -> load -> analyse -> LOD chain -> post-process
// -> measure -> write -> report row. The stages are nodes of one flow graph and many assets are in flight at
// once; the simplifier and eval run their own parallel loops inside an asset's node, in the same thread budget.
//
// Guarantees:
//   - Output bytes (meshes, report.json without its "seconds" fields) are identical for any `jobs`: every stage
//     is deterministic and nothing depends on which asset finishes first.
//   - Memory: the process stays under `memory_limit_bytes`. An asset is admitted only while (a) the estimated
//     footprints of the assets in flight (estimate_footprint) fit in the limit less what the process already held
//     when the run started and less the duplicate-chain cache, and (b) the process's resident memory right now
//     plus the new asset's footprint fits in the limit. Freed memory is handed back to the OS after each large
//     asset, so (b) sees live memory. One asset larger than the whole budget still runs, alone.
//   - Failure isolation: any exception inside a stage fails that asset only (recorded with its message).
//   - Timeouts: with RunLimits::asset_timeout_s (config `defaults.asset_timeout_s`, `run --asset-timeout`) an
//     asset still running that long after its first stage started fails with "timed out in the <stage> stage
//     (asset timeout N s)", stage one of fingerprint, load, analyse, simplify, post-process, evaluate, write.
//     The deadline is checked at every stage boundary, between LODs, inside the simplifier (every engine polls
//     it between rounds of collapses, and the error budget's back-off between measurements), inside eval's
//     sampling loops and before the outputs are published, so nothing of a timed-out asset is written and an
//     asset overruns its timeout by at most one round of work.
//   - Incremental: see cache.hpp. Outputs are staged and renamed into place, then the cache entry is written.
//   - Duplicate meshes (same content and class) are simplified once per run; the copies reuse the result.
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "lodforge/batch/config.hpp"
#include "lodforge/batch/shard.hpp"

namespace lodforge::batch {

// Part of every cache key: bump it whenever a change to lodforge makes the same input and config give
// different output bytes (simplifier, post-process, writers), so stale LODs are rebuilt.
// History: 2 LOD "attributes"; 3 attribute eval, quads; 4 quads split along their shorter diagonal, normals
// within 0.1 degree one wedge, seam UV snap, polychord surface fit and triangle budget; 5 polychord diagonal
// collapses, one fit sample per triangle, fit convergence stop; 6 quads that split into manifold triangles;
// 7 polychord attribute quadrics (merged wedges' optimal values, tangents recomputed); 8 faces repeating an
// earlier face dropped before simplifying; 9 polychord outputs re-pair triangles only into quads that split back
// the same way, and the triangle engine starts over where the quad engine made under half the reduction;
// 10 polychord: n-gon corners move; 11 polychord surface fit by least squares (vertices free in 3D); 12 glTF
// node transforms: budgets and measurements of the asset in world space; 13 report.json input.symmetry.
inline constexpr const char* kAlgorithmVersion = "lodforge-0.1.0/batch-13";
inline constexpr const char* kLodforgeVersion = "0.1.0";

// Estimated peak memory of one asset in flight. Measured with `lodforge run`: the whole chain (loaded Mesh,
// simplifier quadrics, queues and working copies, the LODs and their post-processed copies, eval's BVH and
// samples, output buffers) peaks at ~560 bytes per input triangle for one asset on one thread, ~700 with the
// simplifier's own threads, and up to ~1100 each when two 22k-triangle assets run side by side (what the
// allocator keeps per thread adds up), whatever the format. Memory follows triangles, not bytes, so the
// bytes-to-memory factor is ~1150 bytes over the densest encoding of a triangle in each format: glTF/GLB
// (positions + 32-bit indices: 12 bytes), PLY (binary: ~19), OBJ and OFF (text, positions only: ~32), STL
// (binary: 50). Richer files (normals, UVs) are larger per triangle, so these factors err on the safe side.
inline constexpr std::uint64_t kFootprintOverhead = 1u << 20;  // per asset: buffers, report record, staging
// The footprint of the asset `file` (its bytes, plus the buffers a .gltf declares, x its format's factor, plus
// kFootprintOverhead). Reads only a .gltf's JSON; 0 extra for an unreadable file (the load stage reports it).
std::uint64_t estimate_footprint(const std::filesystem::path& file);

// Half of the physical memory: leaves room for the OS file cache the writes go through.
std::uint64_t default_memory_limit();
// "4G", "512M", "1.5G", "100000" (bytes; K/M/G/T are powers of 1024). Throws std::invalid_argument.
std::uint64_t parse_byte_size(std::string_view text);

// What the observer hears after each asset (serially, in completion order).
struct AssetDone {
  const nlohmann::json& record;  // the asset's report record
  std::size_t done = 0, total = 0;
  std::uint64_t input_triangles_done = 0;  // over assets processed (not cache hits) so far
  double elapsed_seconds = 0;
};

struct RunOptions {
  std::filesystem::path config_file{};  // for the report only
  std::filesystem::path input_dir{};
  std::filesystem::path output_dir{};
  unsigned jobs = 0;  // threads for the whole run (graph and the simplifier inside it); 0 = all cores
  std::optional<Shard> shard{};
  bool force = false;                    // ignore the cache (still writes it)
  // Remove the output files (and the cache entries) that the library and config no longer produce; without it
  // they are only listed (RunResult::stale_outputs). Not in a sharded run, which sees only its own assets.
  bool prune = false;
  std::uint64_t memory_limit_bytes = 0;  // 0 = default_memory_limit()
  bool write_report = true;              // report.json + report.html in output_dir (report.shard-K-of-N.* when sharded)
  std::function<void(const AssetDone&)> on_asset_done{};  // progress observer; must not throw
  // Stops admitting new assets once set (Ctrl-C); assets in flight finish, the rest are reported "not_started".
  const std::atomic<bool>* cancel = nullptr;
  // Testing aid: admit at most this many assets (0 = all), as if the run were stopped there.
  std::size_t stop_after = 0;
  // Testing aid: called as an asset enters a stage ("load", "simplify", "evaluate", ...), on the stage's thread.
  std::function<void(const std::string& path, const char* stage)> on_stage_start{};
  // Testing aid: this asset (its '/'-separated relative path) reads as past its deadline from just before its
  // first simplify() call, after every check outside the engines: only their own polling can time it out.
  std::string expire_in_simplify{};
  // Testing aid: an asset for which this returns true reads as past its deadline from the start of that stage
  // (with an asset timeout set; no clock involved).
  std::function<bool(const std::string& path, const char* stage)> expire_on_stage{};
};

// Seconds spent per stage, summed over assets (cache hits count only their lookup). `pictures` (the report's
// picture of each LOD, rendered beside evaluate and write) is not part of an asset's "seconds".
struct StageSeconds {
  double fingerprint = 0, load = 0, analyse = 0, lods = 0, post_process = 0, measure = 0, write = 0;
  double pictures = 0;
};

struct RunResult {
  nlohmann::json report;  // the report.json document
  std::size_t succeeded = 0, failed = 0, skipped = 0, cache_hits = 0;
  std::size_t not_started = 0;  // assets a stopped run did not reach (status "not_started")
  std::vector<std::string> failures;  // "path: error", sorted by path
  std::vector<std::string> skipped_assets;  // "path: reason" of the skipped ones (no class matches), sorted
  StageSeconds stages;
  std::uint64_t input_triangles = 0;  // of the assets processed (not cache hits)
  std::size_t pictured_assets = 0;    // assets whose LOD pictures this run rendered (report_files/)
  double seconds = 0;
  bool cancelled = false;
  std::filesystem::path report_path;  // where report.json went (empty if not written)
  std::vector<std::string> warnings;  // library entries the scan skipped (LibraryScan::skipped)
  std::vector<std::string> unsupported;  // LibraryScan::unsupported, less the output folder's own files
  // Output files (meshes, buffers, materials, textures; relative to the output folder, sorted) that no asset of
  // this run produced: left by assets since removed, renamed or unmatched, or by LODs the config dropped. Outputs
  // of assets that failed or were not started this time are kept. Empty in a sharded run.
  std::vector<std::string> stale_outputs;
  bool pruned = false;  // RunOptions::prune: stale_outputs were removed
};

// What `run --dry-run` prints: per asset its class, LOD targets and whether a run would rebuild it.
struct PlannedAsset {
  std::string path;
  std::string class_name;         // empty: no class matches (the asset would be skipped)
  std::vector<std::string> lods;  // "ratio 0.5", "triangles 60", "max_error 0.03", "screen_size 2"
  // Collision and occluder LODs: "collision ratio 0.05, max_volume_growth 10%", "occluder triangles 200".
  std::vector<std::string> separate;
  bool rebuild = false;
  std::string reason;  // why it is rebuilt ("not built yet", "input or config changed", ...) or skipped
};
struct Plan {
  std::vector<PlannedAsset> assets;   // sorted by path
  std::vector<std::string> warnings;  // LibraryScan::skipped
  std::vector<std::string> unsupported;
};

// The run `options` would make, with nothing written (no output folder, cache or report is created): reads
// every asset file to fingerprint it, as a run does. Throws io::IoError like run_batch.
Plan plan_batch(const BatchConfig& config, const RunOptions& options);

struct LibraryScan {
  std::vector<std::string> assets;  // the supported files, as sorted '/'-separated relative paths
  // Entries that cannot be read, each "<path>: skipped: <why>" (a symbolic link loop, a broken link with an
  // asset's extension, a folder that cannot be opened); the rest of the library is scanned as usual.
  std::vector<std::string> skipped;
  // Files of no format lodforge reads (.fbx, .txt), as sorted relative paths; companions of assets (.bin
  // buffers, textures, .mtl) and hidden files are not listed.
  std::vector<std::string> unsupported;
  // PNG and .r16 files: assets where a terrain class takes them (the run decides, knowing the config).
  std::vector<std::string> heightmaps;
};

// The supported files under `input_dir`. Throws io::IoError when the folder itself cannot be read.
LibraryScan scan_library(const std::filesystem::path& input_dir);

// Throws io::IoError when the input folder cannot be read or holds no asset file at all (nothing is written then),
// or the output folder cannot be created; everything
// that goes wrong with one asset is recorded in its report record instead.
RunResult run_batch(const BatchConfig& config, const RunOptions& options);

// The report's pictures: "props/crate.obj" level 2 -> "report_files/props/crate.obj/lod2.png" (relative to the
// output folder; level 0 is the source). kPictureSize is their side in pixels.
inline constexpr const char* kPictureFolder = "report_files";
inline constexpr int kPictureSize = 160;
std::string picture_file_name(const std::string& relative_path, std::size_t level);

// Whether ReportPictures::automatic draws an asset's `pictures` pictures, `rendered_triangles` triangles in all,
// for an input of `input_triangles`: where their estimated cost is at most 5% of the asset's own processing
// (the estimates are measured; docs/report.md, "Pictures").
bool pictures_pay(std::size_t input_triangles, std::size_t rendered_triangles, std::size_t pictures);

// Output names: "props/crate.obj" LOD 2 -> "props/crate_LOD2.obj".
std::string lod_file_name(const std::filesystem::path& relative_path, std::size_t level);
// "props/crate.obj" -> "crate_collision.obj" / "crate_occluder.obj" (the file name of a separate output; in a
// glTF with MSFT_lod the same suffix names its meshes and nodes).
std::string conservative_file_name(const std::filesystem::path& relative_path, ConservativeKind kind);

}  // namespace lodforge::batch
