// The batch config: which LOD chain each asset class gets.
//
//   const BatchConfig config = load_config("configs/default.json");  // throws ConfigError, every problem
//   if (const AssetClass* cls = match_class(config, "props/chair.obj")) {
//     for (const LodSpec& lod : cls->lods) simplify(mesh, simplify_options_for(lod, source));
//   }
//
// configs/schema.json documents every key. Parsing is strict the way PDAL's pipeline reader is: unknown keys,
// wrong types, impossible targets and non-monotone chains are errors naming the JSON path of the bad value
// ("classes[2].lods[1].ratio: must be < previous ratio 0.25"), and all of them are reported at once, so one
// edit fixes a whole file. Options resolve in three layers: `defaults` < class `options` < LOD overrides.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <nlohmann/json_fwd.hpp>  // callers that build or read documents include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "lodforge/batch/glob.hpp"
#include "lodforge/io/heightmap.hpp"
#include "lodforge/simplify/simplify.hpp"
#include "lodforge/symmetry/symmetry.hpp"

namespace lodforge::batch {

inline constexpr int kConfigVersion = 1;
inline constexpr std::size_t kMaxLods = 8;  // LOD1..LOD8 after the source (LOD0); MSFT_lod chains stay short

// Every problem of a config; what() is "<source>: <problem>" per problem, one per line, where a problem is
// "<json path>: <what is wrong>".
class ConfigError : public std::runtime_error {
 public:
  ConfigError(std::string source, std::vector<std::string> problems);
  const std::string& source() const noexcept { return source_; }
  const std::vector<std::string>& problems() const noexcept { return problems_; }

 private:
  std::string source_;
  std::vector<std::string> problems_;
};

// Options the config already parses and validates but the simplifier does not take yet (moving one into
// SimplifyOptions is a one-line change of its table entry in config.cpp).
struct PendingOptions {
  // Which mirror plane to look for (`symmetry_plane`: auto | x | y | z | none). Per asset: set in `defaults` or
  // a class's `options`, not per LOD. The runner reports the detected symmetry (report.json input.symmetry),
  // and every LOD looks for this plane where its symmetry_weight is above 0.
  symmetry::PlaneMode symmetry_plane = symmetry::PlaneMode::automatic;
  friend bool operator==(const PendingOptions&, const PendingOptions&) = default;
};

// Everything a LOD may override. The target fields of `simplify` are not set here (see LodSpec).
struct LodOptions {
  SimplifyOptions simplify;
  PendingOptions pending;
};

enum class TargetKind {
  ratio,          // fraction of the *source* triangle count, also when built from the previous LOD
  triangles,      // absolute triangle count
  max_error_rel,  // error budget as a fraction of the source's bounding-box diagonal
  max_error_abs,  // error budget in model units
  screen_size,    // a max_error_rel derived from a screen projection (ScreenSize)
};
const char* target_kind_name(TargetKind kind);  // the config's spelling: "ratio", "max_error.relative", ...

// Projection assumption: the LOD is shown when the object's bounding sphere -- the sphere around its
// axis-aligned bounding box, radius = half the box diagonal -- covers `pixels` pixels (its projected diameter)
// on a screen `screen_height_px` tall with vertical field of view `fov_y_deg`. An error of `error_px` pixels
// is then error_abs = error_px * (2 * radius) / pixels in object space, that is error_px / pixels of the
// diagonal, independent of the asset's size.
struct ScreenSize {
  double pixels = 0;
  double screen_height_px = 0;
  double fov_y_deg = 0;
  double error_px = 0;

  double max_error_rel() const { return error_px / pixels; }
  // Fraction of the screen height the object covers when this LOD switches in (glTF MSFT_screencoverage).
  double screen_coverage() const { return pixels / screen_height_px; }
  // Camera distance at which a bounding sphere of `radius` covers `pixels` (small-angle: diameter on screen
  // = 2 * radius / (distance * 2 * tan(fov_y / 2)) * screen_height_px).
  double switch_distance(double radius) const;
  friend bool operator==(const ScreenSize&, const ScreenSize&) = default;
};

// The projection behind LOD switch points where the config gives no screen size (config key
// `defaults.lod_switch`): a LOD switches in where its measured Hausdorff error covers `error_px` pixels of a
// viewport `screen_height_px` tall; `fov_y_deg` (vertical) turns that into a camera distance for lods.json.
struct LodSwitch {
  double screen_height_px = 1080;
  double error_px = 1;
  double fov_y_deg = 60;
  friend bool operator==(const LodSwitch&, const LodSwitch&) = default;
};

// The switch formulas, one copy for the glTF screen-coverage hints, report.json and lods.json (docs/lods-json.md).
// Share of the screen height the bounding sphere's diameter covers when an error of `error_rel` (fraction of
// the diagonal = of that diameter) covers `error_px` pixels: error_px / (screen_height_px * error_rel).
double coverage_for_error(double error_rel, double error_px, double screen_height_px);
// Camera distance at which a bounding sphere of `radius` covers `coverage` of the height of a view with
// vertical field of view `fov_y_deg` (small-angle): radius / (coverage * tan(fov_y / 2)). Infinite at 0.
double distance_for_coverage(double radius, double coverage, double fov_y_deg);

struct LodTarget {
  TargetKind kind = TargetKind::ratio;
  double ratio = 0;           // kind ratio: in (0, 1]
  std::size_t triangles = 0;  // kind triangles: > 0
  double max_error = 0;       // max_error_rel / max_error_abs, and screen_size (= screen.max_error_rel())
  ScreenSize screen;          // kind screen_size
  friend bool operator==(const LodTarget&, const LodTarget&) = default;
};

enum class LodFrom {
  previous,  // simplify the previous LOD (the source for LOD1): cheaper, error accumulates along the chain
  source,    // simplify the source: each LOD's error is measured against one reference
};

struct LodSpec {
  LodTarget target;
  LodFrom from = LodFrom::previous;
  // Resolved defaults < class options < this LOD's overrides. The target fields of options.simplify are those
  // of a build from the source (ratio -> target_ratio, error -> max_error_*); simplify_options_for() gives
  // the exact per-asset values, also for chains.
  LodOptions options;
};

// A conservative LOD built beside the render chain, always from the source (docs/conservative.md): a collision
// hull contains the source (SimplifyOptions::conservative = bounding), an occluder lies inside it (occluder).
// It is an output of its own (its own file, or its own glTF node), never a level of the render chain.
enum class ConservativeKind { collision, occluder };
const char* conservative_kind_name(ConservativeKind kind);  // the config's key: "collision", "occluder"

struct ConservativeSpec {
  ConservativeKind kind = ConservativeKind::collision;
  // ratio, triangles or max_error (a screen size means nothing for a mesh never drawn); none only on a collision
  // spec with a volume budget, which then decides alone how far it goes.
  std::optional<LodTarget> target;
  // Collision only: stop before the volume grows by more than this per cent of the source's; negative = none.
  double max_volume_growth_pct = -1;
  // defaults < class options < its own overrides, with conservative and max_volume_growth set from the above;
  // the target fields are those of a build from the source, as for a LodSpec.
  LodOptions options;
};

// A terrain class (`"terrain": {...}`, docs/terrain.md): the height maps it matches (PNG, .r16) are its assets,
// each cut into patches whose LOD chains stitch without cracks. Its LODs are ratio targets, each a fraction of
// a full patch's triangles; a PNG that no terrain class matches stays a texture.
struct TerrainSpec {
  std::size_t patch_cells = 64;  // cells per patch side
  Conservative conservative = Conservative::occluder;
  bool skirts = true;
  io::HeightMapLayout layout;  // what a map's own sidecar JSON does not say
};

struct AssetClass {
  std::string name;
  std::string description;
  std::vector<Glob> match;    // on the '/'-separated path relative to the library root, any one matches
  LodOptions options;         // defaults < class options: what every LOD of the class starts from
  std::vector<LodSpec> lods;  // LOD1..LODn; LOD0 is the source
  // `collision` and `occluder` (own, else inherited from `defaults`): at most one of each, collision first.
  std::vector<ConservativeSpec> conservative;
  std::optional<TerrainSpec> terrain;  // a terrain class: no `collision` / `occluder` entries

  bool matches(std::string_view relative_path) const;
};

enum class GltfLods {
  msft_lod,  // one glTF per asset, the LODs as MSFT_lod alternatives of each node
  files,     // one file per LOD: name_LOD1.glb, ...
  both,
};

struct OutputOptions {
  GltfLods gltf_lods = GltfLods::msft_lod;
  bool post_process = true;        // meshoptimizer vertex-cache and vertex-fetch reordering of each LOD
  bool write_source_lod0 = false;  // also write the (post-processed) source as name_LOD0
  friend bool operator==(const OutputOptions&, const OutputOptions&) = default;
};

// How long a run may spend on one asset. In `defaults` only, and no part of an asset's cache key: a limit
// changes whether an asset finishes, never what it produces.
struct RunLimits {
  // An asset still running this many seconds after it started fails ("timed out in the <stage> stage") and
  // the run goes on with the others; 0 = no limit. `lodforge run --asset-timeout` overrides it.
  double asset_timeout_s = 0;
  friend bool operator==(const RunLimits&, const RunLimits&) = default;
};

// A picture of each LOD beside report.html (report_files/<asset>/lodK.png, docs/report.md). `automatic`
// ("auto") draws them for the assets whose pictures cost little next to their own processing.
enum class ReportPictures { automatic, on, off };

// What the report shows. In `defaults` only, and no part of the cache key (a report never changes a LOD).
struct ReportOptions {
  ReportPictures pictures = ReportPictures::automatic;  // `defaults.report_pictures`, `run --report-pictures`
  friend bool operator==(const ReportOptions&, const ReportOptions&) = default;
};

struct BatchConfig {
  int version = kConfigVersion;
  std::string description;
  LodOptions defaults;  // built-in defaults < `defaults`
  OutputOptions output;
  RunLimits limits;
  ReportOptions report;
  LodSwitch lod_switch;  // `defaults.lod_switch`
  // `defaults.collision` / `defaults.occluder` as JSON text (empty: none): each class without its own entry
  // reads it against its own options.
  std::string default_collision, default_occluder;
  std::vector<AssetClass> classes;  // in file order: the first class whose globs match wins
  std::string default_class;        // class of assets no glob matches; empty = such assets are skipped
};

// `source` names the document in messages (a file name). Throws ConfigError.
BatchConfig parse_config(const nlohmann::json& document, std::string_view source = "<config>");

// Reads and parses a file. Also reports JSON syntax errors (line, column) and duplicate keys, which a parsed
// nlohmann::json can no longer show. Throws ConfigError with `path` as its source.
BatchConfig load_config(const std::filesystem::path& path);

// The config with every default applied, in the config's own format (parse_config accepts it back and gives
// the same config): written into the report, so a run records exactly what it did.
nlohmann::json effective_config_json(const BatchConfig& config);
// One class with its options resolved, plus the output options: what an asset's cache key depends on.
nlohmann::json effective_class_json(const BatchConfig& config, const AssetClass& cls);

// The first class whose globs match, else the `default_class`, else nullptr (see unmatched_reason).
const AssetClass* match_class(const BatchConfig& config, std::string_view relative_path);
// Why match_class returned nullptr for this path, for the report's "skipped" record.
std::string unmatched_reason(const BatchConfig& config, std::string_view relative_path);
const AssetClass* find_class(const BatchConfig& config, std::string_view name);

// What the asset being simplified is: its source triangle count and bounding-box diagonal, and, when the LOD
// builds from the previous one, the error that LOD already has against the source.
struct LodInput {
  std::size_t source_triangles = 0;
  double source_diagonal = 0;
  double accumulated_error_abs = 0;  // achieved error bound of the previous LOD; 0 when building from the source
};

// The SimplifyOptions for one LOD of one asset. A ratio becomes a triangle count of the source (so a chain's
// ratios stay ratios of the source); an error target becomes an absolute budget minus the error already
// accumulated (bounds add along a chain), never below 0, with the triangle target at 1 so error decides.
SimplifyOptions simplify_options_for(const LodSpec& lod, const LodInput& input);
// The same for a conservative LOD (always built from the source); without a target, the volume budget decides.
SimplifyOptions simplify_options_for(const ConservativeSpec& spec, const LodInput& input);

}  // namespace lodforge::batch
