#include "lodforge/batch/config.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <numbers>
#include <string>
#include <vector>

#include "test_support.hpp"

namespace lodforge::batch {
namespace {

using Json = nlohmann::json;

constexpr const char* kOptionKeys =
    "engine, border, border_weight, regularization_weight, max_flip_angle_deg, seed, multiple_choice_k, max_batch, "
    "attribute_weights, seams, permissive, priority_channel, attribute_placement, priority_lock, "
    "skin_weight_threshold, "
    "skin_max_distance, tiling, tile_triangles, cluster_stage, cluster_stage_factor, symmetry_weight, conservative, "
    "max_volume_growth";
// `defaults` and class options also take the per-asset options.
const std::string kClassOptionKeys = std::string(kOptionKeys) + ", symmetry_plane";

std::string lod_keys() {
  return std::string("ratio, triangles, max_error, screen_size, from, ") + kOptionKeys;
}

// The smallest valid config; tests change one value and check the one message that change causes.
Json minimal() {
  return Json::parse(R"({
    "version": 1,
    "classes": [
      {"name": "props", "match": ["props/**"], "lods": [{"ratio": 0.5}, {"ratio": 0.25}]}
    ]
  })");
}

// minimal() with its classes replaced.
Json with_classes(const char* classes) {
  Json doc = minimal();
  doc["classes"] = Json::parse(classes);
  return doc;
}

LodInput input(std::size_t source_triangles, double source_diagonal, double accumulated_error_abs = 0) {
  LodInput in;
  in.source_triangles = source_triangles;
  in.source_diagonal = source_diagonal;
  in.accumulated_error_abs = accumulated_error_abs;
  return in;
}

// ConfigError::what() for `doc`, or "" when it parses.
std::string error_of(const Json& doc) {
  try {
    parse_config(doc, "test.json");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

// minimal() with the value at JSON pointer `pointer` set to `value`.
std::string error_with(const std::string& pointer, const Json& value) {
  Json doc = minimal();
  doc[Json::json_pointer(pointer)] = value;
  return error_of(doc);
}

// minimal() without the object member at `pointer`.
std::string error_without(const std::string& pointer) {
  Json doc = minimal();
  const Json::json_pointer p(pointer);
  doc[p.parent_pointer()].erase(p.back());
  return error_of(doc);
}

// minimal() with class 0's LOD chain replaced.
std::string error_with_lods(const Json& lods) {
  return error_with("/classes/0/lods", lods);
}

std::string expected(const std::string& problem) {
  return "test.json: " + problem;
}

// --- happy paths -----------------------------------------------------------------------------------------

TEST(BatchConfig, MinimalConfigGetsBuiltInDefaults) {
  const BatchConfig c = parse_config(minimal());
  EXPECT_EQ(c.version, 1);
  ASSERT_EQ(c.classes.size(), 1u);
  const AssetClass& props = c.classes[0];
  EXPECT_EQ(props.name, "props");
  ASSERT_EQ(props.lods.size(), 2u);
  EXPECT_EQ(props.lods[0].target.kind, TargetKind::ratio);
  EXPECT_EQ(props.lods[0].target.ratio, 0.5);
  EXPECT_EQ(props.lods[1].target.ratio, 0.25);
  EXPECT_EQ(props.lods[1].from, LodFrom::previous);
  const SimplifyOptions built_in;
  const SimplifyOptions& o = props.lods[1].options.simplify;
  EXPECT_EQ(o.engine, built_in.engine);
  EXPECT_EQ(o.border_mode, built_in.border_mode);
  EXPECT_EQ(o.max_flip_angle_deg, built_in.max_flip_angle_deg);
  EXPECT_EQ(o.target_ratio, 0.25);
  EXPECT_EQ(o.target_triangles, 0u);
  EXPECT_EQ(props.lods[1].options.pending, PendingOptions{});
  EXPECT_EQ(c.output, OutputOptions{});
  EXPECT_TRUE(c.default_class.empty());
}

TEST(BatchConfig, OptionsResolveDefaultsThenClassThenLod) {
  const Json doc = Json::parse(R"({
    "version": 1,
    "defaults": {"engine": "multiple_choice", "seed": 5, "max_flip_angle_deg": 50,
                 "attribute_weights": {"normal": 3}, "gltf_lods": "both", "post_process": false,
                 "write_source_lod0": true},
    "classes": [{
      "name": "props", "match": ["props/**"],
      "options": {"border": "lock", "seed": 6, "attribute_weights": {"uv": 4}, "priority_channel": "COLOR_0.r"},
      "lods": [
        {"ratio": 0.5},
        {"ratio": 0.25, "seed": 7, "engine": "edge_collapse", "attribute_weights": {"skin": 2},
         "permissive": true, "skin_weight_threshold": 0.3, "regularization_weight": 0.5, "border_weight": 2,
         "attribute_placement": "keep", "priority_lock": 20, "skin_max_distance": 0.25,
         "multiple_choice_k": 16, "max_batch": 1, "from": "source"}
      ]
    }]
  })");
  const BatchConfig c = parse_config(doc);
  EXPECT_EQ(c.defaults.simplify.engine, Engine::multiple_choice);
  EXPECT_EQ(c.output.gltf_lods, GltfLods::both);
  EXPECT_FALSE(c.output.post_process);
  EXPECT_TRUE(c.output.write_source_lod0);

  const LodSpec& lod1 = c.classes[0].lods[0];
  EXPECT_EQ(lod1.options.simplify.engine, Engine::multiple_choice);  // defaults
  EXPECT_EQ(lod1.options.simplify.border_mode, BorderMode::lock);    // class
  EXPECT_EQ(lod1.options.simplify.seed, 6u);                         // class over defaults
  EXPECT_EQ(lod1.options.simplify.max_flip_angle_deg, 50.0);
  EXPECT_EQ(lod1.options.simplify.attribute_weights, (AttributeWeights{.normal = 3, .uv = 4, .color = 1, .skin = 1}));
  EXPECT_EQ(lod1.options.simplify.priority_channel, "COLOR_0.r");

  const LodSpec& lod2 = c.classes[0].lods[1];
  EXPECT_EQ(lod2.from, LodFrom::source);
  EXPECT_EQ(lod2.options.simplify.engine, Engine::edge_collapse);  // LOD over defaults
  EXPECT_EQ(lod2.options.simplify.border_mode, BorderMode::lock);
  EXPECT_EQ(lod2.options.simplify.seed, 7u);
  EXPECT_EQ(lod2.options.simplify.regularization_weight, 0.5);
  EXPECT_EQ(lod2.options.simplify.border_weight, 2.0);
  EXPECT_EQ(lod2.options.simplify.multiple_choice_k, 16);
  EXPECT_EQ(lod2.options.simplify.max_batch, 1u);
  EXPECT_EQ(lod1.options.simplify.max_batch, 0u);
  // Attribute weights merge key by key through the three levels.
  EXPECT_EQ(lod2.options.simplify.attribute_weights, (AttributeWeights{.normal = 3, .uv = 4, .color = 1, .skin = 2}));
  EXPECT_TRUE(lod2.options.simplify.permissive);
  EXPECT_EQ(lod2.options.simplify.skin_weight_threshold, 0.3);
  EXPECT_EQ(lod2.options.simplify.attribute_placement, AttributePlacement::keep);
  EXPECT_EQ(lod1.options.simplify.attribute_placement, AttributePlacement::optimal);
  EXPECT_EQ(lod2.options.simplify.priority_lock, 20.0);
  EXPECT_EQ(lod2.options.simplify.skin_max_distance, 0.25);
  // The class's own options stay as the class set them.
  EXPECT_EQ(c.classes[0].options.simplify.seed, 6u);
}

TEST(BatchConfig, TrianglesTarget) {
  const BatchConfig c = parse_config(with_classes(R"([
    {"name": "a", "match": ["**"], "lods": [{"triangles": 5000}, {"triangles": 800}]}])"));
  const LodSpec& lod = c.classes[0].lods[1];
  EXPECT_EQ(lod.target.kind, TargetKind::triangles);
  EXPECT_EQ(lod.target.triangles, 800u);
  EXPECT_EQ(lod.options.simplify.target_triangles, 800u);
  EXPECT_EQ(lod.options.simplify.target_ratio, 1.0);  // so that the count decides
}

TEST(BatchConfig, MaxErrorTargets) {
  const BatchConfig c = parse_config(with_classes(R"([
    {"name": "a", "match": ["**"], "lods": [{"max_error": {"relative": 0.01}}, {"max_error": {"relative": 0.02}},
                                           {"max_error": {"absolute": 0.5}}, {"max_error": {"absolute": 0.7}}]}])"));
  ASSERT_EQ(c.classes[0].lods.size(), 4u);
  const LodSpec& rel = c.classes[0].lods[1];
  EXPECT_EQ(rel.target.kind, TargetKind::max_error_rel);
  EXPECT_EQ(rel.target.max_error, 0.02);
  EXPECT_EQ(rel.options.simplify.max_error_rel, 0.02);
  EXPECT_EQ(rel.options.simplify.max_error_abs, -1.0);
  EXPECT_EQ(rel.options.simplify.target_triangles, 1u);  // the error budget decides
  const LodSpec& abs = c.classes[0].lods[2];
  EXPECT_EQ(abs.target.kind, TargetKind::max_error_abs);
  EXPECT_EQ(abs.options.simplify.max_error_abs, 0.5);
  EXPECT_EQ(abs.options.simplify.max_error_rel, -1.0);
}

TEST(BatchConfig, MaxErrorFromSourceNeedNotIncrease) {
  EXPECT_EQ(error_with_lods(Json::parse(R"([{"max_error": {"relative": 0.02}},
                                             {"max_error": {"relative": 0.01}, "from": "source"}])")),
            "");
}

TEST(BatchConfig, ScreenSizeBecomesRelativeError) {
  const BatchConfig c = parse_config(with_classes(R"([
    {"name": "a", "match": ["**"], "lods": [
      {"screen_size": {"pixels": 400, "screen_height_px": 1080, "fov_y_deg": 60, "error_px": 1}},
      {"screen_size": {"pixels": 100, "screen_height_px": 1080, "fov_y_deg": 60, "error_px": 2}}]}])"));
  const LodSpec& lod = c.classes[0].lods[1];
  EXPECT_EQ(lod.target.kind, TargetKind::screen_size);
  EXPECT_EQ(lod.target.screen, (ScreenSize{.pixels = 100, .screen_height_px = 1080, .fov_y_deg = 60, .error_px = 2}));
  EXPECT_DOUBLE_EQ(lod.target.max_error, 0.02);  // error_px / pixels of the diagonal
  EXPECT_DOUBLE_EQ(lod.options.simplify.max_error_rel, 0.02);
  EXPECT_DOUBLE_EQ(lod.target.screen.screen_coverage(), 100.0 / 1080.0);
  // A sphere of radius 1 spans 100 of 1080 pixels at 60 degrees: 1 * 1080 / (100 * tan(30 deg)).
  EXPECT_NEAR(lod.target.screen.switch_distance(1.0), 1080.0 / (100.0 * std::tan(std::numbers::pi / 6)), 1e-9);
  // error_abs = error_px * (2 * radius) / pixels with 2 * radius = the diagonal.
  const SimplifyOptions o = simplify_options_for(lod, input(1000, 4.0));
  EXPECT_DOUBLE_EQ(o.max_error_abs, 2 * 4.0 / 100);
}

TEST(BatchConfig, MixedTargetKindsAreMonotonePerKind) {
  EXPECT_EQ(error_with_lods(Json::parse(R"([{"ratio": 0.5}, {"triangles": 1000}, {"ratio": 0.25},
                                             {"max_error": {"relative": 0.01}}, {"triangles": 500},
                                             {"ratio": 0.1}, {"max_error": {"relative": 0.02}}])")),
            "");
}

TEST(BatchConfig, AcceptsEveryPriorityChannelForm) {
  for (const char* channel : {"none", "_LOD_PRIORITY", "_PAINT.x", "_p.a", "COLOR_0.r", "COLOR_12.a"}) {
    EXPECT_EQ(error_with("/defaults", {{"priority_channel", channel}}), "") << channel;
  }
}

TEST(BatchConfig, AcceptsBoundaryValues) {
  EXPECT_EQ(error_with_lods(Json::parse(R"([{"ratio": 1}, {"ratio": 0.001}])")), "");
  EXPECT_EQ(error_with("/defaults", {{"skin_weight_threshold", 0},
                                     {"regularization_weight", 0},
                                     {"seed", std::numeric_limits<std::uint64_t>::max()}}),
            "");
  EXPECT_EQ(error_with("/defaults", {{"skin_weight_threshold", 1}, {"max_flip_angle_deg", 89.9}}), "");
  EXPECT_EQ(error_with("/$schema", "./schema.json"), "");
  EXPECT_EQ(error_with("/description", "text"), "");
}

TEST(BatchConfig, EightLodsAreAllowed) {
  EXPECT_EQ(error_with_lods(Json::parse(R"([{"ratio": 0.9}, {"ratio": 0.8}, {"ratio": 0.7}, {"ratio": 0.6},
                                             {"ratio": 0.5}, {"ratio": 0.4}, {"ratio": 0.3}, {"ratio": 0.2}])")),
            "");
}

// --- class matching --------------------------------------------------------------------------------------

BatchConfig three_classes(const char* default_class = nullptr) {
  Json doc = Json::parse(R"({
    "version": 1,
    "classes": [
      {"name": "hero", "match": ["props/hero_*"], "lods": [{"ratio": 0.5}]},
      {"name": "props", "match": ["**/props/**", "**/*.stl"], "lods": [{"ratio": 0.5}]},
      {"name": "environment", "match": ["environment/{rocks,cliffs}/**"], "lods": [{"ratio": 0.5}]}
    ]
  })");
  if (default_class) doc["default_class"] = default_class;
  return parse_config(doc);
}

TEST(BatchConfig, FirstMatchingClassWins) {
  const BatchConfig c = three_classes();
  EXPECT_EQ(match_class(c, "props/hero_sword.obj")->name, "hero");  // also matches "props"
  EXPECT_EQ(match_class(c, "props/chair.obj")->name, "props");
  EXPECT_EQ(match_class(c, "level2/props/chair.obj")->name, "props");
  EXPECT_EQ(match_class(c, "misc/bracket.stl")->name, "props");
  EXPECT_EQ(match_class(c, "environment/cliffs/big.ply")->name, "environment");
  EXPECT_TRUE(c.classes[2].matches("environment/rocks/a/b.ply"));
  EXPECT_EQ(find_class(c, "props"), &c.classes[1]);
  EXPECT_EQ(find_class(c, "nope"), nullptr);
}

TEST(BatchConfig, UnmatchedAssetsAreSkippedWithAReason) {
  const BatchConfig c = three_classes();
  EXPECT_EQ(match_class(c, "environment/trees/oak.ply"), nullptr);
  EXPECT_EQ(unmatched_reason(c, "environment/trees/oak.ply"),
            "\"environment/trees/oak.ply\" matches no class (hero, props, environment) and the config sets no "
            "default_class");
}

TEST(BatchConfig, UnmatchedAssetsUseTheDefaultClass) {
  const BatchConfig c = three_classes("environment");
  EXPECT_EQ(c.default_class, "environment");
  EXPECT_EQ(match_class(c, "environment/trees/oak.ply"), &c.classes[2]);
  EXPECT_EQ(match_class(c, "props/chair.obj"), &c.classes[1]);  // a glob match still comes first
}

// --- per-asset options -----------------------------------------------------------------------------------

LodSpec lod_of(const Json& lod) {
  Json doc = minimal();
  doc["classes"][0]["lods"] = Json::array({lod});
  return parse_config(doc).classes[0].lods[0];
}

TEST(BatchConfig, SimplifyOptionsForRatioCountsSourceTriangles) {
  const LodSpec lod = lod_of({{"ratio", 0.25}, {"seed", 9}});
  const SimplifyOptions o = simplify_options_for(lod, input(1001, 2));
  EXPECT_EQ(o.target_triangles, 250u);  // round(0.25 * 1001)
  EXPECT_EQ(o.target_ratio, 1.0);
  EXPECT_EQ(o.max_error_abs, -1.0);
  EXPECT_EQ(o.max_error_rel, -1.0);
  EXPECT_EQ(o.seed, 9u);
  EXPECT_EQ(simplify_options_for(lod, input(1, 2)).target_triangles, 1u);
  // Built from the previous LOD, the ratio is still of the source.
  EXPECT_EQ(simplify_options_for(lod, input(1001, 2, 0.1)).target_triangles, 250u);
}

TEST(BatchConfig, SimplifyOptionsForTriangles) {
  const SimplifyOptions o = simplify_options_for(lod_of({{"triangles", 300}}), input(1000, 1));
  EXPECT_EQ(o.target_triangles, 300u);
  EXPECT_EQ(o.target_ratio, 1.0);
}

TEST(BatchConfig, SimplifyOptionsForErrorSubtractsTheAccumulatedError) {
  const LodSpec rel = lod_of({{"max_error", {{"relative", 0.01}}}});
  SimplifyOptions o = simplify_options_for(rel, input(10, 200));
  EXPECT_DOUBLE_EQ(o.max_error_abs, 2.0);
  EXPECT_EQ(o.max_error_rel, -1.0);
  EXPECT_EQ(o.target_triangles, 1u);
  o = simplify_options_for(rel, input(10, 200, 0.5));
  EXPECT_DOUBLE_EQ(o.max_error_abs, 1.5);
  o = simplify_options_for(rel, input(10, 200, 3));
  EXPECT_EQ(o.max_error_abs, 0.0);  // budget spent: only error-free collapses remain

  const LodSpec abs = lod_of({{"max_error", {{"absolute", 0.5}}}});
  EXPECT_DOUBLE_EQ(simplify_options_for(abs, input(10, 1, 0.2)).max_error_abs, 0.3);
  const LodSpec from_source = lod_of({{"max_error", {{"absolute", 0.5}}}, {"from", "source"}});
  EXPECT_DOUBLE_EQ(simplify_options_for(from_source, input(10, 1, 0.2)).max_error_abs, 0.5);
}

// --- effective config ------------------------------------------------------------------------------------

TEST(BatchConfig, EffectiveConfigHasEveryDefaultApplied) {
  Json doc = minimal();
  doc["defaults"] = {{"engine", "multiple_choice"}};
  doc["classes"][0]["options"] = {{"border", "lock"}};
  doc["classes"][0]["lods"][1]["seed"] = 3;
  const Json e = effective_config_json(parse_config(doc));
  EXPECT_EQ(e["version"], 1);
  EXPECT_EQ(e["defaults"]["engine"], "multiple_choice");
  EXPECT_EQ(e["defaults"]["border"], "preserve");
  EXPECT_EQ(e["defaults"]["max_flip_angle_deg"], 60.0);
  EXPECT_EQ(e["defaults"]["regularization_weight"], 1e-3);
  EXPECT_EQ(e["defaults"]["multiple_choice_k"], 8);
  EXPECT_EQ(e["defaults"]["attribute_weights"], Json::parse(R"({"normal":1.0,"uv":1.0,"color":1.0,"skin":1.0})"));
  EXPECT_EQ(e["defaults"]["priority_channel"], "_LOD_PRIORITY");
  EXPECT_EQ(e["defaults"]["gltf_lods"], "msft_lod");
  EXPECT_EQ(e["defaults"]["post_process"], true);
  EXPECT_EQ(e["defaults"]["write_source_lod0"], false);
  const Json& cls = e["classes"][0];
  EXPECT_EQ(cls["name"], "props");
  EXPECT_EQ(cls["match"], Json::array({"props/**"}));
  EXPECT_EQ(cls["options"]["engine"], "multiple_choice");
  EXPECT_EQ(cls["options"]["border"], "lock");
  const Json& lod2 = cls["lods"][1];
  EXPECT_EQ(lod2["ratio"], 0.25);
  EXPECT_EQ(lod2["from"], "previous");
  EXPECT_EQ(lod2["engine"], "multiple_choice");
  EXPECT_EQ(lod2["border"], "lock");
  EXPECT_EQ(lod2["seed"], 3);
  EXPECT_EQ(cls["lods"][0]["seed"], 1);
  EXPECT_FALSE(e.contains("default_class"));
  EXPECT_FALSE(lod2.contains("threads"));
}

TEST(BatchConfig, EffectiveConfigParsesBackToItself) {
  for (const char* name : {"default.json", "examples/hero_max_error.json", "examples/screen_size.json",
                           "examples/characters.json", "examples/environment.json", "examples/props.json"}) {
    const BatchConfig c = load_config(std::filesystem::path(LODFORGE_SOURCE_DIR) / "configs" / name);
    const Json e = effective_config_json(c);
    EXPECT_EQ(effective_config_json(parse_config(e)), e) << name;
  }
}

TEST(BatchConfig, AssetTimeoutIsARunLimitOutsideTheCacheKey) {
  const BatchConfig none = parse_config(minimal());
  EXPECT_EQ(none.limits.asset_timeout_s, 0.0);
  EXPECT_EQ(effective_config_json(none)["defaults"]["asset_timeout_s"], 0.0);
  Json doc = minimal();
  doc["defaults"] = {{"asset_timeout_s", 90.5}};
  const BatchConfig c = parse_config(doc);
  EXPECT_EQ(c.limits.asset_timeout_s, 90.5);
  const Json e = effective_config_json(c);
  EXPECT_EQ(e["defaults"]["asset_timeout_s"], 90.5);
  EXPECT_EQ(parse_config(e).limits.asset_timeout_s, 90.5);
  // A limit changes whether an asset finishes, never what it produces: the cache key does not see it.
  EXPECT_EQ(effective_class_json(c, c.classes[0]), effective_class_json(none, none.classes[0]));
}

TEST(BatchConfig, ReportPicturesIsAReportOptionOutsideTheCacheKey) {
  const BatchConfig none = parse_config(minimal());
  EXPECT_EQ(none.report.pictures, ReportPictures::automatic);
  EXPECT_EQ(effective_config_json(none)["defaults"]["report_pictures"], "auto");
  for (const auto& [name, value] : {std::pair{"auto", ReportPictures::automatic}, std::pair{"on", ReportPictures::on},
                                    std::pair{"off", ReportPictures::off}}) {
    Json doc = minimal();
    doc["defaults"] = {{"report_pictures", name}};
    const BatchConfig c = parse_config(doc);
    EXPECT_EQ(c.report.pictures, value) << name;
    const Json e = effective_config_json(c);
    EXPECT_EQ(e["defaults"]["report_pictures"], name);
    EXPECT_EQ(parse_config(e).report.pictures, value) << name;
    // Pictures never change a LOD: the cache key does not see them.
    EXPECT_EQ(effective_class_json(c, c.classes[0]), effective_class_json(none, none.classes[0])) << name;
  }
}

TEST(BatchConfigErrors, ReportPictures) {
  EXPECT_EQ(error_with("/defaults/report_pictures", "sometimes"),
            expected("defaults.report_pictures: must be one of \"auto\", \"on\", \"off\", got string \"sometimes\""));
  EXPECT_EQ(error_with("/classes/0/options/report_pictures", "on"),
            expected(std::string("classes[0].options.report_pictures: unknown key; allowed: ") + kClassOptionKeys));
}

TEST(BatchConfigErrors, AssetTimeout) {
  EXPECT_EQ(error_with("/defaults/asset_timeout_s", -1), expected("defaults.asset_timeout_s: must be >= 0"));
  EXPECT_EQ(error_with("/defaults/asset_timeout_s", "1m"),
            expected("defaults.asset_timeout_s: must be a number, got string \"1m\""));
  // A run limit, not an option of a class or a LOD.
  EXPECT_EQ(error_with("/classes/0/options/asset_timeout_s", 5),
            expected(std::string("classes[0].options.asset_timeout_s: unknown key; allowed: ") + kClassOptionKeys));
}

TEST(BatchConfig, EffectiveClassJsonCarriesOutputOptions) {
  const BatchConfig c = parse_config(minimal());
  const Json j = effective_class_json(c, c.classes[0]);
  EXPECT_EQ(j["class"], effective_config_json(c)["classes"][0]);
  EXPECT_EQ(j["output"]["gltf_lods"], "msft_lod");
}

// --- the shipped configs ---------------------------------------------------------------------------------

std::filesystem::path configs_dir() {
  return std::filesystem::path(LODFORGE_SOURCE_DIR) / "configs";
}

TEST(BatchConfig, DefaultConfigCoversTheSampleLibrary) {
  const BatchConfig c = load_config(configs_dir() / "default.json");
  auto class_of = [&](const char* path) {
    const AssetClass* cls = match_class(c, path);
    return cls ? cls->name : std::string("(none)");
  };
  EXPECT_EQ(class_of("props/torus_quads.obj"), "quad_props");
  EXPECT_EQ(class_of("props/kitchen/cup.obj"), "quad_props");
  EXPECT_EQ(class_of("props/bracket.stl"), "props");
  EXPECT_EQ(class_of("environment/rock.ply"), "environment");
  EXPECT_EQ(class_of("environment/terrain_patch.off"), "environment");
  EXPECT_EQ(class_of("characters/torus_ring.gltf"), "characters");
  EXPECT_EQ(class_of("misc/thing.obj"), "other");
  const AssetClass* props = find_class(c, "props");
  ASSERT_NE(props, nullptr);
  ASSERT_EQ(props->lods.size(), 3u);
  EXPECT_EQ(props->lods[2].target.ratio, 0.1);
  const AssetClass* quad_props = find_class(c, "quad_props");
  ASSERT_NE(quad_props, nullptr);
  EXPECT_EQ(quad_props->lods[0].options.simplify.engine, Engine::polychord);
  EXPECT_EQ(quad_props->lods[2].options.simplify.engine, Engine::edge_collapse);
  EXPECT_EQ(find_class(c, "environment")->lods.back().target.ratio, 0.05);
  EXPECT_EQ(find_class(c, "characters")->lods.size(), 2u);
}

TEST(BatchConfig, EveryExampleConfigParses) {
  std::vector<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(configs_dir() / "examples")) {
    if (entry.path().extension() != ".json") continue;
    names.push_back(entry.path().filename().string());
    EXPECT_NO_THROW({
      try {
        load_config(entry.path());
      } catch (const ConfigError& e) {
        ADD_FAILURE() << e.what();
        throw;
      }
    }) << entry.path();
  }
  EXPECT_GE(names.size(), 5u);  // props, characters, environment, hero max_error chain, screen_size chain
}

TEST(BatchConfig, ExamplesCoverEveryTargetKind) {
  std::vector<bool> seen(5, false);
  for (const auto& entry : std::filesystem::directory_iterator(configs_dir() / "examples")) {
    for (const AssetClass& cls : load_config(entry.path()).classes) {
      for (const LodSpec& lod : cls.lods) seen[static_cast<int>(lod.target.kind)] = true;
    }
  }
  for (int kind = 0; kind < 5; ++kind) {
    EXPECT_TRUE(seen[kind]) << target_kind_name(static_cast<TargetKind>(kind));
  }
}

// schema.json must document every key the reader accepts (adding an option means one table line in
// config.cpp and its entry in the schema; this test catches the second being forgotten).
TEST(BatchConfig, SchemaDocumentsEveryKey) {
  std::ifstream in(configs_dir() / "schema.json");
  const Json schema = Json::parse(in);
  EXPECT_EQ(schema["$schema"], "https://json-schema.org/draft/2020-12/schema");
  const Json& defs = schema["$defs"];
  const Json e = effective_config_json(parse_config(minimal()));
  for (const auto& [key, value] : e["defaults"].items()) {
    EXPECT_TRUE(defs["simplifierOptions"]["properties"].contains(key) || defs["defaults"]["properties"].contains(key))
        << key;
  }
  for (const auto& [key, value] : e["defaults"]["attribute_weights"].items()) {
    EXPECT_TRUE(defs["simplifierOptions"]["properties"]["attribute_weights"]["properties"].contains(key)) << key;
  }
  for (const char* key : {"$schema", "version", "description", "defaults", "default_class", "classes"}) {
    EXPECT_TRUE(schema["properties"].contains(key)) << key;
  }
  for (const char* key : {"name", "description", "match", "options", "lods", "collision", "occluder"}) {
    EXPECT_TRUE(defs["class"]["properties"].contains(key)) << key;
  }
  for (const char* key : {"collision", "occluder"}) EXPECT_TRUE(defs["defaults"]["properties"].contains(key)) << key;
  for (const char* key : {"ratio", "triangles", "max_error", "max_volume_growth", "from"}) {
    EXPECT_TRUE(defs["collision"]["properties"].contains(key)) << key;
  }
  for (const char* key : {"ratio", "triangles", "max_error", "from"}) {
    EXPECT_TRUE(defs["occluder"]["properties"].contains(key)) << key;
  }
  for (const char* key : {"ratio", "triangles", "max_error", "screen_size", "from"}) {
    EXPECT_TRUE(defs["lod"]["properties"].contains(key)) << key;
  }
  for (const char* key : {"pixels", "screen_height_px", "fov_y_deg", "error_px"}) {
    EXPECT_TRUE(defs["screenSize"]["properties"].contains(key)) << key;
  }
  EXPECT_EQ(defs["class"]["properties"]["lods"]["maxItems"], kMaxLods);
  EXPECT_EQ(defs["simplifierOptions"]["properties"]["engine"]["enum"],
            Json::parse(R"(["edge_collapse", "multiple_choice", "polychord", "cluster"])"));
}

// --- every error path, with its message ------------------------------------------------------------------

TEST(BatchConfigErrors, RootMustBeAnObject) {
  EXPECT_EQ(error_of(Json::array()), expected("(root): must be an object, got an array"));
}

TEST(BatchConfigErrors, UnknownRootKeySuggestsTheClosest) {
  EXPECT_EQ(error_with("/clases", Json::array()),
            expected("clases: unknown key (did you mean \"classes\"?); allowed: $schema, version, description, "
                     "defaults, default_class, classes"));
  EXPECT_EQ(error_with("/bad key", 1),
            expected("[\"bad key\"]: unknown key; allowed: $schema, version, description, defaults, default_class, "
                     "classes"));
}

TEST(BatchConfigErrors, Version) {
  EXPECT_EQ(error_without("/version"), expected("version: missing (required)"));
  EXPECT_EQ(error_with("/version", "1"), expected("version: must be an integer, got string \"1\""));
  EXPECT_EQ(error_with("/version", 1.0), expected("version: must be an integer, got 1.0"));
  EXPECT_EQ(error_with("/version", 2), expected("version: unsupported version 2; this lodforge reads version 1"));
  EXPECT_EQ(error_with("/version", -1), expected("version: must be >= 0"));
}

TEST(BatchConfigErrors, RootScalars) {
  EXPECT_EQ(error_with("/$schema", 5), expected("$schema: must be a string, got 5"));
  EXPECT_EQ(error_with("/description", true), expected("description: must be a string, got true"));
  EXPECT_EQ(error_with("/defaults", Json::array()), expected("defaults: must be an object, got an array"));
}

TEST(BatchConfigErrors, Classes) {
  EXPECT_EQ(error_without("/classes"), expected("classes: missing (required)"));
  EXPECT_EQ(error_with("/classes", Json::object()), expected("classes: must be an array, got an object"));
  EXPECT_EQ(error_with("/classes", Json::array()), expected("classes: must not be empty"));
}

TEST(BatchConfigErrors, DefaultClass) {
  EXPECT_EQ(error_with("/default_class", 3), expected("default_class: must be a string, got 3"));
  EXPECT_EQ(error_with("/default_class", "other"),
            expected("default_class: no class named \"other\" (classes: props)"));
}

TEST(BatchConfigErrors, RedirectedKeys) {
  EXPECT_EQ(error_with("/defaults/threads", 4),
            expected("defaults.threads: not a config option: the thread count comes from `lodforge run --jobs`"));
  EXPECT_EQ(error_with("/classes/0/lods/1/threads", 1),
            expected("classes[0].lods[1].threads: not a config option: the thread count comes from `lodforge run "
                     "--jobs`"));
  EXPECT_EQ(error_with("/classes/0/options/target_ratio", 0.5),
            expected("classes[0].options.target_ratio: not a config option: a LOD's ratio target is written "
                     "\"ratio\""));
  EXPECT_EQ(error_with("/defaults/target_triangles", 5),
            expected("defaults.target_triangles: not a config option: a LOD's triangle target is written "
                     "\"triangles\""));
  EXPECT_EQ(error_with("/defaults/max_error_abs", 5),
            expected("defaults.max_error_abs: not a config option: write \"max_error\": {\"absolute\": x} in a LOD"));
  EXPECT_EQ(error_with("/defaults/max_error_rel", 5),
            expected("defaults.max_error_rel: not a config option: write \"max_error\": {\"relative\": x} in a LOD"));
  EXPECT_EQ(error_with("/defaults/border_mode", "lock"),
            expected("defaults.border_mode: not a config option: the border mode is written \"border\""));
}

TEST(BatchConfigErrors, UnknownDefaultsKeyListsAllowedKeys) {
  EXPECT_EQ(error_with("/defaults/ratio", 0.5),
            expected(std::string("defaults.ratio: unknown key; allowed: ") + kClassOptionKeys +
                     ", gltf_lods, post_process, write_source_lod0, asset_timeout_s, report_pictures, lod_switch, "
                     "collision, occluder"));
}

TEST(BatchConfigErrors, OutputOptions) {
  EXPECT_EQ(error_with("/defaults/gltf_lods", "glb"),
            expected("defaults.gltf_lods: must be one of \"msft_lod\", \"files\", \"both\", got string \"glb\""));
  EXPECT_EQ(error_with("/defaults/post_process", "yes"),
            expected("defaults.post_process: must be true or false, got string \"yes\""));
  EXPECT_EQ(error_with("/defaults/write_source_lod0", 1),
            expected("defaults.write_source_lod0: must be true or false, got 1"));
  // Output options shape files, so they are not per class or per LOD.
  EXPECT_EQ(error_with("/classes/0/options/gltf_lods", "files"),
            expected(std::string("classes[0].options.gltf_lods: unknown key; allowed: ") + kClassOptionKeys));
}

TEST(BatchConfigErrors, EngineAndBorder) {
  EXPECT_EQ(error_with("/defaults/engine", "quadric"),
            expected("defaults.engine: must be one of \"edge_collapse\", \"multiple_choice\", \"polychord\", "
                     "\"cluster\", got string \"quadric\""));
  EXPECT_EQ(error_with("/defaults/engine", 1),
            expected("defaults.engine: must be one of \"edge_collapse\", \"multiple_choice\", \"polychord\", "
                     "\"cluster\", got 1"));
  EXPECT_EQ(error_with("/classes/0/lods/0/border", "locked"),
            expected("classes[0].lods[0].border: must be one of \"free\", \"preserve\", \"lock\", got string "
                     "\"locked\""));
}

TEST(BatchConfigErrors, NumericOptions) {
  EXPECT_EQ(error_with("/defaults/border_weight", -1), expected("defaults.border_weight: must be >= 0"));
  EXPECT_EQ(error_with("/defaults/regularization_weight", "a"),
            expected("defaults.regularization_weight: must be a number, got string \"a\""));
  EXPECT_EQ(error_with("/defaults/regularization_weight", std::nan("")),
            expected("defaults.regularization_weight: must be finite"));
  EXPECT_EQ(error_with("/defaults/max_flip_angle_deg", 90), expected("defaults.max_flip_angle_deg: must be < 90"));
  EXPECT_EQ(error_with("/defaults/max_flip_angle_deg", 0), expected("defaults.max_flip_angle_deg: must be > 0"));
  EXPECT_EQ(error_with("/defaults/seed", -1), expected("defaults.seed: must be >= 0"));
  EXPECT_EQ(error_with("/defaults/seed", 1.5), expected("defaults.seed: must be an integer, got 1.5"));
  EXPECT_EQ(error_with("/defaults/multiple_choice_k", 0), expected("defaults.multiple_choice_k: must be > 0"));
  EXPECT_EQ(error_with("/defaults/multiple_choice_k", 300), expected("defaults.multiple_choice_k: must be <= 256"));
  EXPECT_EQ(error_with("/defaults/max_batch", -1), expected("defaults.max_batch: must be >= 0"));
  EXPECT_EQ(error_with("/defaults/max_batch", "auto"),
            expected("defaults.max_batch: must be an integer, got string \"auto\""));
  EXPECT_EQ(error_with("/defaults/skin_weight_threshold", 1.5),
            expected("defaults.skin_weight_threshold: must be <= 1"));
  EXPECT_EQ(error_with("/defaults/skin_weight_threshold", -0.1),
            expected("defaults.skin_weight_threshold: must be >= 0"));
  EXPECT_EQ(error_with("/defaults/skin_max_distance", 2.5), expected("defaults.skin_max_distance: must be <= 2"));
  EXPECT_EQ(error_with("/defaults/priority_lock", 0), expected("defaults.priority_lock: must be > 0"));
  EXPECT_EQ(error_with("/defaults/attribute_placement", "survivor"),
            expected("defaults.attribute_placement: must be one of \"optimal\", \"keep\", got string \"survivor\""));
}

TEST(BatchConfigErrors, Seams) {
  EXPECT_EQ(error_with("/defaults/seams", "loose"),
            expected("defaults.seams: must be one of \"keep\", \"relax\", \"relax_materials\", got string \"loose\""));
  EXPECT_EQ(error_with("/classes/0/options/seams", true),
            expected("classes[0].options.seams: must be one of \"keep\", \"relax\", \"relax_materials\", got true"));
}

// Seams relax by default (a production library expects its targets); a class keeps them, a LOD of it lets
// material boundaries move.
TEST(BatchConfig, SeamsPerClassAndLod) {
  Json doc = minimal();
  doc["classes"][0]["options"]["seams"] = "keep";
  doc["classes"][0]["lods"][1]["seams"] = "relax_materials";
  const BatchConfig c = parse_config(doc);
  EXPECT_EQ(parse_config(minimal()).classes[0].lods[0].options.simplify.seams, SeamMode::relax);
  EXPECT_EQ(c.classes[0].lods[0].options.simplify.seams, SeamMode::keep);
  EXPECT_EQ(c.classes[0].lods[1].options.simplify.seams, SeamMode::relax_materials);
}

TEST(BatchConfigErrors, SymmetryPlane) {
  EXPECT_EQ(error_with("/defaults/symmetry_plane", "X"),
            expected("defaults.symmetry_plane: must be one of \"auto\", \"x\", \"y\", \"z\", \"none\", got string \"X\""));
  // Detection is per asset, so a LOD cannot choose another plane.
  EXPECT_EQ(error_with("/classes/0/lods/0/symmetry_plane", "x"),
            expected("classes[0].lods[0].symmetry_plane: unknown key; allowed: " + lod_keys()));
}

// symmetry_weight is a simplifier option at every level; each LOD's options carry its class's plane.
TEST(BatchConfig, SymmetryWeightReachesTheSimplifier) {
  const BatchConfig c = parse_config(with_classes(R"([
    {"name": "characters", "match": ["**"], "options": {"symmetry_plane": "x", "symmetry_weight": 2},
     "lods": [{"ratio": 0.5}, {"ratio": 0.25, "symmetry_weight": 0}]}])"));
  const SimplifyOptions a = simplify_options_for(c.classes[0].lods[0], input(1000, 4.0));
  const SimplifyOptions b = simplify_options_for(c.classes[0].lods[1], input(1000, 4.0));
  EXPECT_DOUBLE_EQ(a.symmetry_weight, 2.0);
  EXPECT_EQ(a.symmetry_plane, symmetry::PlaneMode::x);
  EXPECT_DOUBLE_EQ(b.symmetry_weight, 0.0);
  EXPECT_EQ(error_with("/defaults/symmetry_weight", -1), expected("defaults.symmetry_weight: must be >= 0"));
  // Written back where set, left out at 0 (so configs from before the key keep their cache keys).
  const Json e = effective_config_json(c);
  EXPECT_EQ(e["classes"][0]["options"]["symmetry_weight"], 2.0);
  EXPECT_EQ(e["classes"][0]["lods"][1]["symmetry_weight"], 0.0);  // turns off what its class set
  EXPECT_FALSE(e["defaults"].contains("symmetry_weight"));
  const BatchConfig back = parse_config(e);
  EXPECT_DOUBLE_EQ(back.classes[0].lods[0].options.simplify.symmetry_weight, 2.0);
  EXPECT_DOUBLE_EQ(back.classes[0].lods[1].options.simplify.symmetry_weight, 0.0);
  Json doc = with_classes(R"([{"name": "a", "match": ["**"], "lods": [{"ratio": 0.5}]},
                              {"name": "b", "match": ["b/**"], "options": {"symmetry_weight": 0}, "lods": [{"ratio": 0.5}]}])");
  doc["defaults"]["symmetry_weight"] = 1.5;
  const BatchConfig d = parse_config(doc);
  for (const BatchConfig& x : {d, parse_config(effective_config_json(d))}) {
    EXPECT_DOUBLE_EQ(x.classes[0].lods[0].options.simplify.symmetry_weight, 1.5);
    EXPECT_DOUBLE_EQ(x.classes[1].lods[0].options.simplify.symmetry_weight, 0.0);
  }
  // A config that never sets it keeps the key of its classes as before the option existed.
  const BatchConfig plain = parse_config(with_classes(R"([{"name": "a", "match": ["**"], "lods": [{"ratio": 0.5}]}])"));
  EXPECT_EQ(effective_class_json(plain, plain.classes[0]).dump().find("symmetry_weight"), std::string::npos);
}

// The plane defaults to auto, a class's options override `defaults`, and the effective config writes it back.
TEST(BatchConfig, SymmetryPlanePerClass) {
  Json doc = with_classes(R"([
    {"name": "characters", "match": ["chars/**"], "options": {"symmetry_plane": "x"}, "lods": [{"ratio": 0.5}]},
    {"name": "props", "match": ["props/**"], "lods": [{"ratio": 0.5}]}
  ])");
  EXPECT_EQ(parse_config(doc).classes[1].options.pending.symmetry_plane, symmetry::PlaneMode::automatic);
  doc["defaults"]["symmetry_plane"] = "none";
  const BatchConfig c = parse_config(doc);
  EXPECT_EQ(c.classes[0].options.pending.symmetry_plane, symmetry::PlaneMode::x);
  EXPECT_EQ(c.classes[1].options.pending.symmetry_plane, symmetry::PlaneMode::none);
  const Json e = effective_config_json(c);
  EXPECT_EQ(e["defaults"]["symmetry_plane"], "none");
  EXPECT_EQ(e["classes"][0]["options"]["symmetry_plane"], "x");
  EXPECT_FALSE(e["classes"][0]["lods"][0].contains("symmetry_plane"));
  EXPECT_EQ(parse_config(e).classes[0].options.pending.symmetry_plane, symmetry::PlaneMode::x);
}

// Conservative LODs are separate outputs, never render levels: in the option levels and in a LOD only the neutral
// values parse (the message points to the collision and occluder entries), and the effective config leaves them
// out.
TEST(BatchConfigErrors, ConservativeOnlyAsSeparateEntries) {
  const std::string why =
      "collision and occluder LODs are separate outputs, not render levels of a LOD chain: give them as a "
      "\"collision\" or \"occluder\" entry of the class or of defaults (docs/conservative.md)";
  EXPECT_EQ(error_with("/defaults/conservative", "bounding"), expected("defaults.conservative: " + why));
  EXPECT_EQ(error_with("/classes/0/options/conservative", "occluder"),
            expected("classes[0].options.conservative: " + why));
  EXPECT_EQ(error_with("/classes/0/lods/0/conservative", "bounding"),
            expected("classes[0].lods[0].conservative: " + why));
  EXPECT_EQ(error_with("/classes/0/lods/0/max_volume_growth", 0.1),
            expected("classes[0].lods[0].max_volume_growth: applies to collision LODs only: write it in the "
                     "\"collision\" entry of the class or of defaults (docs/conservative.md)"));
  EXPECT_EQ(error_with("/defaults/conservative", "hull"),
            expected("defaults.conservative: must be one of \"none\", \"bounding\", \"occluder\", got string "
                     "\"hull\""));
  Json doc = minimal();
  doc["defaults"]["conservative"] = "none";
  doc["classes"][0]["lods"][0]["max_volume_growth"] = -1;
  const Json e = effective_config_json(parse_config(doc));
  EXPECT_FALSE(e["defaults"].contains("conservative"));
  EXPECT_FALSE(e["defaults"].contains("max_volume_growth"));
  EXPECT_EQ(e, effective_config_json(parse_config(minimal())));
}

// A class's collision and occluder entries: built from the source with their own target, the class's options
// under their own overrides, the volume budget in per cent; written back so that the document parses the same.
TEST(BatchConfig, CollisionAndOccluderEntries) {
  Json doc = minimal();
  doc["classes"][0]["options"] = {{"seed", 7}};
  doc["classes"][0]["collision"] = {{"ratio", 0.1}, {"max_volume_growth", 12.5}, {"engine", "multiple_choice"}};
  doc["classes"][0]["occluder"] = {{"max_error", {{"relative", 0.02}}}};
  const BatchConfig c = parse_config(doc);
  const AssetClass& cls = c.classes[0];
  ASSERT_EQ(cls.lods.size(), 2u) << "the render chain is unchanged";
  ASSERT_EQ(cls.conservative.size(), 2u);
  const ConservativeSpec& col = cls.conservative[0];
  EXPECT_EQ(col.kind, ConservativeKind::collision);
  ASSERT_TRUE(col.target.has_value());
  EXPECT_EQ(col.target->kind, TargetKind::ratio);
  EXPECT_EQ(col.max_volume_growth_pct, 12.5);
  EXPECT_EQ(col.options.simplify.conservative, Conservative::bounding);
  EXPECT_DOUBLE_EQ(col.options.simplify.max_volume_growth, 0.125);
  EXPECT_EQ(col.options.simplify.engine, Engine::multiple_choice);
  EXPECT_EQ(col.options.simplify.seed, 7u);
  const ConservativeSpec& occ = cls.conservative[1];
  EXPECT_EQ(occ.kind, ConservativeKind::occluder);
  EXPECT_EQ(occ.options.simplify.conservative, Conservative::occluder);
  EXPECT_LT(occ.options.simplify.max_volume_growth, 0.0);
  EXPECT_EQ(occ.options.simplify.engine, Engine::edge_collapse);

  const SimplifyOptions so = simplify_options_for(col, input(1000, 2.0));
  EXPECT_EQ(so.target_triangles, 100u);
  EXPECT_EQ(so.conservative, Conservative::bounding);
  const SimplifyOptions oo = simplify_options_for(occ, input(1000, 2.0));
  EXPECT_DOUBLE_EQ(oo.max_error_abs, 0.04);
  EXPECT_EQ(oo.target_triangles, 1u);

  const Json e = effective_config_json(c);
  EXPECT_EQ(e["classes"][0]["collision"]["max_volume_growth"], 12.5);
  EXPECT_EQ(e["classes"][0]["collision"]["ratio"], 0.1);
  EXPECT_FALSE(e["classes"][0]["collision"].contains("conservative"));
  EXPECT_EQ(effective_config_json(parse_config(e)), e);
  // The cache key of a class without them is what it was before they existed.
  EXPECT_FALSE(effective_class_json(parse_config(minimal()), parse_config(minimal()).classes[0])["class"].contains(
      "collision"));
  EXPECT_NE(effective_class_json(c, cls), effective_class_json(parse_config(minimal()), parse_config(minimal()).classes[0]));
}

// A collision entry may hold a volume budget alone: as few triangles as the budget allows.
TEST(BatchConfig, CollisionWithAVolumeBudgetOnly) {
  Json doc = minimal();
  doc["classes"][0]["collision"] = {{"max_volume_growth", 5}};
  const BatchConfig c = parse_config(doc);
  ASSERT_EQ(c.classes[0].conservative.size(), 1u);
  EXPECT_FALSE(c.classes[0].conservative[0].target.has_value());
  const SimplifyOptions o = simplify_options_for(c.classes[0].conservative[0], input(1000, 1.0));
  EXPECT_EQ(o.target_triangles, 1u);
  EXPECT_DOUBLE_EQ(o.max_volume_growth, 0.05);
  EXPECT_EQ(effective_config_json(parse_config(effective_config_json(c))), effective_config_json(c));
}

// defaults.collision applies to every class that gives none, read against that class's options; null declines it.
TEST(BatchConfig, DefaultCollisionIsInheritedUnlessDeclined) {
  const Json doc = Json::parse(R"({
    "version": 1,
    "defaults": {"collision": {"triangles": 50}, "seed": 3},
    "classes": [
      {"name": "a", "match": ["a/**"], "options": {"border_weight": 2}, "lods": [{"ratio": 0.5}]},
      {"name": "b", "match": ["b/**"], "lods": [{"ratio": 0.5}], "collision": null},
      {"name": "c", "match": ["c/**"], "lods": [{"ratio": 0.5}], "collision": {"ratio": 0.2}}
    ]
  })");
  const BatchConfig c = parse_config(doc);
  ASSERT_EQ(c.classes[0].conservative.size(), 1u);
  EXPECT_EQ(c.classes[0].conservative[0].target->triangles, 50u);
  EXPECT_EQ(c.classes[0].conservative[0].options.simplify.border_weight, 2.0);
  EXPECT_EQ(c.classes[0].conservative[0].options.simplify.seed, 3u);
  EXPECT_TRUE(c.classes[1].conservative.empty());
  ASSERT_EQ(c.classes[2].conservative.size(), 1u);
  EXPECT_EQ(c.classes[2].conservative[0].target->ratio, 0.2);
  const Json e = effective_config_json(c);
  EXPECT_TRUE(e["classes"][1]["collision"].is_null());
  EXPECT_EQ(e["defaults"]["collision"], Json::parse(R"({"triangles": 50})"));
  EXPECT_EQ(effective_config_json(parse_config(e)), e);
}

TEST(BatchConfigErrors, CollisionAndOccluderEntries) {
  EXPECT_EQ(error_with("/classes/0/occluder", Json::parse(R"({"ratio": 0.1, "max_volume_growth": 5})")),
            expected("classes[0].occluder.max_volume_growth: applies to collision LODs only (an occluder loses "
                     "volume; bound it with its target)"));
  EXPECT_EQ(error_with("/classes/0/collision", Json::parse(R"({"ratio": 0.1, "engine": "polychord"})")),
            expected("classes[0].collision.engine: a collision or occluder LOD needs a triangle engine: "
                     "\"edge_collapse\" or \"multiple_choice\", got \"polychord\""));
  {
    Json doc = minimal();
    doc["classes"][0]["options"] = {{"engine", "cluster"}};
    doc["classes"][0]["occluder"] = {{"triangles", 20}};
    EXPECT_EQ(error_of(doc), expected("classes[0].occluder: inherits engine \"cluster\", which cannot build collision "
                                      "or occluder LODs; set \"engine\" here to \"edge_collapse\" or "
                                      "\"multiple_choice\""));
  }
  {
    Json doc = minimal();
    doc["defaults"]["collision"] = {{"ratio", 0.1}};
    doc["classes"][0]["options"] = {{"engine", "polychord"}};
    EXPECT_EQ(error_of(doc), expected("classes[0]: with this class's options, defaults.collision: inherits engine "
                                      "\"polychord\", which cannot build collision or occluder LODs; set "
                                      "\"engine\" here to \"edge_collapse\" or \"multiple_choice\""));
  }
  EXPECT_EQ(error_with("/classes/0/collision", Json::object()),
            expected("classes[0].collision: needs a target: one of ratio, triangles, max_error, or a "
                     "max_volume_growth"));
  EXPECT_EQ(error_with("/classes/0/occluder", Json::object()),
            expected("classes[0].occluder: needs a target: one of ratio, triangles, max_error"));
  EXPECT_EQ(error_with("/classes/0/collision", Json::parse(R"({"ratio": 0.1, "triangles": 5})")),
            expected("classes[0].collision: has 2 targets (ratio, triangles); give exactly one"));
  EXPECT_EQ(error_with("/classes/0/collision", Json::parse(R"({"ratio": 1.5})")),
            expected("classes[0].collision.ratio: must be <= 1"));
  EXPECT_EQ(error_with("/classes/0/collision", Json::parse(R"({"max_volume_growth": -2})")),
            expected("classes[0].collision.max_volume_growth: must be >= 0"));
  EXPECT_EQ(error_with("/defaults/occluder", Json::parse(R"({"screen_size": {"pixels": 100}})")),
            expected("defaults.occluder.screen_size: a collision or occluder LOD is never drawn, so it has no screen "
                     "size; give ratio, triangles or max_error"));
  EXPECT_EQ(error_with("/classes/0/collision", Json::parse(R"({"ratio": 0.1, "from": "previous"})")),
            expected("classes[0].collision.from: a collision or occluder LOD is always built from the source"));
  EXPECT_EQ(error_with("/classes/0/collision", Json::parse(R"({"ratio": 0.1, "conservative": "bounding"})"))
                .rfind("test.json: classes[0].collision.conservative: unknown key; allowed: ratio, triangles, max_error, "
                       "max_volume_growth, from, screen_size, engine, ",
                       0),
            0u);
  EXPECT_EQ(error_with("/classes/0/collision", 0.1), expected("classes[0].collision: must be an object, got 0.1"));
}

TEST(BatchConfigErrors, Tiling) {
  EXPECT_EQ(error_with("/defaults/tiling", "always"),
            expected("defaults.tiling: must be one of \"auto\", \"on\", \"off\", got string \"always\""));
  EXPECT_EQ(error_with("/classes/0/options/tile_triangles", 99),
            expected("classes[0].options.tile_triangles: must be >= 100"));
  EXPECT_NE(error_with("/defaults/cluster_stage", "sometimes").find("defaults.cluster_stage: must be one of"),
            std::string::npos);
  EXPECT_NE(error_with("/defaults/cluster_stage_factor", 0.5).find("defaults.cluster_stage_factor: must be"),
            std::string::npos);
  Json doc = with_classes(R"([{"name": "scans", "match": ["**"], "options": {"cluster_stage": "off",
     "cluster_stage_factor": 12}, "lods": [{"ratio": 0.1}, {"ratio": 0.01, "cluster_stage": "on"}]}])");
  const BatchConfig c = parse_config(doc);
  EXPECT_EQ(c.classes[0].lods[0].options.simplify.cluster_stage, TilingMode::off);
  EXPECT_EQ(c.classes[0].lods[1].options.simplify.cluster_stage, TilingMode::on);
  EXPECT_EQ(c.classes[0].lods[1].options.simplify.cluster_stage_factor, 12.0);
}

// Tiling defaults to auto (200000 triangles per tile); a class and a LOD override it, and the effective config
// writes it back.
TEST(BatchConfig, TilingPerClassAndLod) {
  Json doc = with_classes(R"([
    {"name": "terrain", "match": ["terrain/**"], "options": {"tiling": "on", "tile_triangles": 50000},
     "lods": [{"ratio": 0.5}, {"ratio": 0.1, "tiling": "off"}]},
    {"name": "props", "match": ["props/**"], "lods": [{"ratio": 0.5}]}
  ])");
  const BatchConfig c = parse_config(doc);
  EXPECT_EQ(c.classes[0].lods[0].options.simplify.tiling, TilingMode::on);
  EXPECT_EQ(c.classes[0].lods[0].options.simplify.tile_triangles, 50000u);
  EXPECT_EQ(c.classes[0].lods[1].options.simplify.tiling, TilingMode::off);
  EXPECT_EQ(c.classes[1].lods[0].options.simplify.tiling, TilingMode::automatic);
  EXPECT_EQ(c.classes[1].lods[0].options.simplify.tile_triangles, 200000u);
  const Json e = effective_config_json(c);
  EXPECT_EQ(e["classes"][0]["options"]["tiling"], "on");
  EXPECT_EQ(parse_config(e).classes[0].lods[1].options.simplify.tiling, TilingMode::off);
}

TEST(BatchConfigErrors, AttributeWeights) {
  EXPECT_EQ(error_with("/defaults/attribute_weights", Json::array()),
            expected("defaults.attribute_weights: must be an object, got an array"));
  EXPECT_EQ(error_with("/classes/0/options/attribute_weights", {{"normals", 1}}),
            expected("classes[0].options.attribute_weights.normals: unknown key (did you mean \"normal\"?); "
                     "allowed: normal, uv, color, skin"));
  EXPECT_EQ(error_with("/classes/0/lods/1/attribute_weights", {{"uv", -1}}),
            expected("classes[0].lods[1].attribute_weights.uv: must be >= 0"));
  EXPECT_EQ(error_with("/defaults/attribute_weights", {{"skin", "x"}}),
            expected("defaults.attribute_weights.skin: must be a number, got string \"x\""));
}

TEST(BatchConfigErrors, PermissiveAndPriorityChannel) {
  EXPECT_EQ(error_with("/defaults/permissive", "no"),
            expected("defaults.permissive: must be true or false, got string \"no\""));
  EXPECT_EQ(error_with("/defaults/priority_channel", 5),
            expected("defaults.priority_channel: must be a string, got 5"));
  const std::string channel_problem =
      "must be \"none\", a custom attribute such as \"_LOD_PRIORITY\" or \"_PAINT.x\", or a colour channel such "
      "as \"COLOR_0.r\"; got ";
  for (const char* bad : {"LOD_PRIORITY", "COLOR_0", "COLOR_0.q", "COLOR_.r", "_", "_A.xy", ""}) {
    EXPECT_EQ(error_with("/defaults/priority_channel", bad),
              expected("defaults.priority_channel: " + channel_problem + Json(bad).dump()));
  }
}

TEST(BatchConfigErrors, ClassStructure) {
  EXPECT_EQ(error_with("/classes/0", 5), expected("classes[0]: must be an object, got 5"));
  EXPECT_EQ(error_with("/classes/0/colour", "red"),
            expected("classes[0].colour: unknown key; allowed: name, description, match, options, lods, "
                     "collision, occluder, terrain"));
  EXPECT_EQ(error_with("/classes/0/lod", Json::array()),
            expected("classes[0].lod: unknown key (did you mean \"lods\"?); allowed: name, description, match, "
                     "options, lods, collision, occluder, terrain"));
  EXPECT_EQ(error_without("/classes/0/name"), expected("classes[0].name: missing (required)"));
  EXPECT_EQ(error_with("/classes/0/name", 3), expected("classes[0].name: must be a string, got 3"));
  EXPECT_EQ(error_with("/classes/0/name", ""), expected("classes[0].name: must not be empty"));
  EXPECT_EQ(error_with("/classes/0/description", 1), expected("classes[0].description: must be a string, got 1"));
  EXPECT_EQ(error_with("/classes/0/options", 3), expected("classes[0].options: must be an object, got 3"));
  EXPECT_EQ(error_with("/classes/0/options/engine", "x"),
            expected("classes[0].options.engine: must be one of \"edge_collapse\", \"multiple_choice\", \"polychord\", "
                     "\"cluster\", got string \"x\""));
}

TEST(BatchConfigErrors, DuplicateClassNames) {
  Json doc = minimal();
  doc["classes"].push_back(doc["classes"][0]);
  doc["classes"].push_back(doc["classes"][0]);
  EXPECT_EQ(error_of(doc), expected("classes[1].name: duplicate class name \"props\" (first at classes[0])\n") +
                               expected("classes[2].name: duplicate class name \"props\" (first at classes[0])"));
}

TEST(BatchConfigErrors, Match) {
  EXPECT_EQ(error_without("/classes/0/match"), expected("classes[0].match: missing (required)"));
  EXPECT_EQ(error_with("/classes/0/match", "props/**"),
            expected("classes[0].match: must be an array, got string \"props/**\""));
  EXPECT_EQ(error_with("/classes/0/match", Json::array()), expected("classes[0].match: must not be empty"));
  EXPECT_EQ(error_with("/classes/0/match/0", 3), expected("classes[0].match[0]: must be a string, got 3"));
  EXPECT_EQ(error_with("/classes/0/match/1", "props/[a"),
            expected("classes[0].match[1]: invalid glob \"props/[a\": unclosed '['"));
}

TEST(BatchConfigErrors, Lods) {
  EXPECT_EQ(error_without("/classes/0/lods"), expected("classes[0].lods: missing (required)"));
  EXPECT_EQ(error_with_lods(Json::object()), expected("classes[0].lods: must be an array, got an object"));
  EXPECT_EQ(error_with_lods(Json::array()), expected("classes[0].lods: must not be empty"));
  EXPECT_EQ(error_with_lods(Json::parse(R"([{"ratio": 0.9}, {"ratio": 0.8}, {"ratio": 0.7}, {"ratio": 0.6},
                                             {"ratio": 0.5}, {"ratio": 0.4}, {"ratio": 0.3}, {"ratio": 0.2},
                                             {"ratio": 0.1}])")),
            expected("classes[0].lods: has 9 LODs; at most 8"));
}

TEST(BatchConfigErrors, LodStructure) {
  EXPECT_EQ(error_with("/classes/0/lods/0", "x"), expected("classes[0].lods[0]: must be an object, got string \"x\""));
  EXPECT_EQ(error_with("/classes/0/lods/1/ratoi", 0.2),
            expected("classes[0].lods[1].ratoi: unknown key (did you mean \"ratio\"?); allowed: " + lod_keys()));
  EXPECT_EQ(error_with("/classes/0/lods/1", {{"from", "source"}}),
            expected("classes[0].lods[1]: needs a target: one of ratio, triangles, max_error, screen_size"));
  EXPECT_EQ(error_with("/classes/0/lods/1", {{"ratio", 0.2}, {"triangles", 100}}),
            expected("classes[0].lods[1]: has 2 targets (ratio, triangles); give exactly one"));
  EXPECT_EQ(error_with("/classes/0/lods/1/from", "prev"),
            expected("classes[0].lods[1].from: must be one of \"previous\", \"source\", got string \"prev\""));
}

TEST(BatchConfigErrors, RatioTarget) {
  EXPECT_EQ(error_with("/classes/0/lods/1/ratio", "half"),
            expected("classes[0].lods[1].ratio: must be a number, got string \"half\""));
  EXPECT_EQ(error_with("/classes/0/lods/1/ratio", 0), expected("classes[0].lods[1].ratio: must be > 0"));
  EXPECT_EQ(error_with("/classes/0/lods/1/ratio", -0.5), expected("classes[0].lods[1].ratio: must be > 0"));
  EXPECT_EQ(error_with("/classes/0/lods/0/ratio", 1.5), expected("classes[0].lods[0].ratio: must be <= 1"));
}

TEST(BatchConfigErrors, TrianglesTarget) {
  EXPECT_EQ(error_with("/classes/0/lods/1", {{"triangles", 0}}), expected("classes[0].lods[1].triangles: must be > 0"));
  EXPECT_EQ(error_with("/classes/0/lods/1", {{"triangles", -5}}),
            expected("classes[0].lods[1].triangles: must be > 0"));
  EXPECT_EQ(error_with("/classes/0/lods/1", {{"triangles", 10.5}}),
            expected("classes[0].lods[1].triangles: must be an integer, got 10.5"));
}

TEST(BatchConfigErrors, MaxErrorTarget) {
  EXPECT_EQ(error_with("/classes/0/lods/1", {{"max_error", 0.01}}),
            expected("classes[0].lods[1].max_error: must be an object, got 0.01"));
  EXPECT_EQ(error_with("/classes/0/lods/1", {{"max_error", Json::object()}}),
            expected("classes[0].lods[1].max_error: needs one of relative, absolute"));
  EXPECT_EQ(error_with("/classes/0/lods/1", {{"max_error", {{"relative", 0.1}, {"absolute", 1}}}}),
            expected("classes[0].lods[1].max_error: give only one of relative, absolute"));
  EXPECT_EQ(error_with("/classes/0/lods/1", {{"max_error", {{"relative", -0.1}}}}),
            expected("classes[0].lods[1].max_error.relative: must be >= 0"));
  EXPECT_EQ(error_with("/classes/0/lods/1", {{"max_error", {{"relative", 2}}}}),
            expected("classes[0].lods[1].max_error.relative: must be <= 1"));
  EXPECT_EQ(error_with("/classes/0/lods/1", {{"max_error", {{"absolute", -1}}}}),
            expected("classes[0].lods[1].max_error.absolute: must be >= 0"));
  EXPECT_EQ(error_with("/classes/0/lods/1", {{"max_error", {{"absolute", "1mm"}}}}),
            expected("classes[0].lods[1].max_error.absolute: must be a number, got string \"1mm\""));
  EXPECT_EQ(error_with("/classes/0/lods/1", {{"max_error", {{"relative", 0.1}, {"unit", "m"}}}}),
            expected("classes[0].lods[1].max_error.unit: unknown key; allowed: relative, absolute"));
}

Json screen(double pixels, double height, double fov, double error) {
  return {{"pixels", pixels}, {"screen_height_px", height}, {"fov_y_deg", fov}, {"error_px", error}};
}

TEST(BatchConfigErrors, ScreenSizeTarget) {
  const std::string at = "classes[0].lods[1].screen_size";
  auto with_screen = [](const Json& s) { return error_with("/classes/0/lods/1", {{"screen_size", s}}); };
  EXPECT_EQ(with_screen(5), expected(at + ": must be an object, got 5"));
  EXPECT_EQ(with_screen(Json::object()),
            expected(at + ".pixels: missing (required)\n") + expected(at + ".screen_height_px: missing (required)\n") +
                expected(at + ".fov_y_deg: missing (required)\n") + expected(at + ".error_px: missing (required)"));
  EXPECT_EQ(with_screen(screen(0, 1080, 60, 1)), expected(at + ".pixels: must be > 0"));
  EXPECT_EQ(with_screen(screen(100, -1, 60, 1)), expected(at + ".screen_height_px: must be > 0"));
  EXPECT_EQ(with_screen(screen(100, 1080, 180, 1)), expected(at + ".fov_y_deg: must be < 180"));
  EXPECT_EQ(with_screen(screen(100, 1080, 0, 1)), expected(at + ".fov_y_deg: must be > 0"));
  EXPECT_EQ(with_screen(screen(100, 1080, 60, -1)), expected(at + ".error_px: must be >= 0"));
  EXPECT_EQ(with_screen(screen(2000, 1080, 60, 1)), expected(at + ".pixels: must be <= screen_height_px 1080"));
  EXPECT_EQ(with_screen(screen(100, 1080, 60, 100)), expected(at + ".error_px: must be < pixels 100"));
  Json extra = screen(100, 1080, 60, 1);
  extra["distance"] = 10;
  EXPECT_EQ(with_screen(extra),
            expected(at + ".distance: unknown key; allowed: pixels, screen_height_px, fov_y_deg, error_px"));
}

TEST(BatchConfigErrors, RatiosMustDecrease) {
  EXPECT_EQ(error_with("/classes/0/lods/1/ratio", 0.6),
            expected("classes[0].lods[1].ratio: must be < previous ratio 0.5"));
  EXPECT_EQ(error_with("/classes/0/lods/1/ratio", 0.5),
            expected("classes[0].lods[1].ratio: must be < previous ratio 0.5"));
  // The issue's own example: the third class, second LOD.
  Json doc = minimal();
  doc["classes"] = Json::parse(R"([
    {"name": "a", "match": ["a/**"], "lods": [{"ratio": 0.5}]},
    {"name": "b", "match": ["b/**"], "lods": [{"ratio": 0.5}]},
    {"name": "c", "match": ["c/**"], "lods": [{"ratio": 0.25}, {"ratio": 0.3}]}])");
  EXPECT_EQ(error_of(doc), expected("classes[2].lods[1].ratio: must be < previous ratio 0.25"));
  // Compared with the latest LOD of the same kind, across other kinds.
  EXPECT_EQ(error_with_lods(Json::parse(R"([{"ratio": 0.5}, {"triangles": 1000}, {"ratio": 0.6}])")),
            expected("classes[0].lods[2].ratio: must be < previous ratio 0.5"));
  // Also when built from the source: a LOD chain gets coarser.
  EXPECT_EQ(error_with_lods(Json::parse(R"([{"ratio": 0.5}, {"ratio": 0.6, "from": "source"}])")),
            expected("classes[0].lods[1].ratio: must be < previous ratio 0.5"));
}

TEST(BatchConfigErrors, TriangleCountsMustDecrease) {
  EXPECT_EQ(error_with_lods(Json::parse(R"([{"triangles": 1000}, {"triangles": 1000}])")),
            expected("classes[0].lods[1].triangles: must be < previous triangles 1000"));
}

TEST(BatchConfigErrors, ErrorsMustIncreaseWhenBuiltFromThePrevious) {
  EXPECT_EQ(error_with_lods(Json::parse(R"([{"max_error": {"relative": 0.01}}, {"max_error": {"relative": 0.005}}])")),
            expected("classes[0].lods[1].max_error.relative: must be > previous max_error.relative 0.01 (built "
                     "from the previous LOD, the error only grows)"));
  EXPECT_EQ(error_with_lods(Json::parse(R"([{"max_error": {"absolute": 0.5}}, {"ratio": 0.1},
                                             {"max_error": {"absolute": 0.5}}])")),
            expected("classes[0].lods[2].max_error.absolute: must be > previous max_error.absolute 0.5 (built from "
                     "the previous LOD, the error only grows)"));
}

TEST(BatchConfigErrors, ScreenSizesMustShrinkAndErrorsGrow) {
  EXPECT_EQ(error_with_lods({{{"screen_size", screen(400, 1080, 60, 1)}}, {{"screen_size", screen(400, 1080, 60, 2)}}}),
            expected("classes[0].lods[1].screen_size.pixels: must be < previous pixels 400"));
  EXPECT_EQ(error_with_lods({{{"screen_size", screen(400, 1080, 60, 4)}}, {{"screen_size", screen(200, 1080, 60, 1)}}}),
            expected("classes[0].lods[1].screen_size: error_px / pixels = 0.005 must be > previous 0.01 (built from "
                     "the previous LOD, the error only grows)"));
  EXPECT_EQ(error_with_lods({{{"screen_size", screen(400, 1080, 60, 4)}},
                             {{"screen_size", screen(200, 1080, 60, 1)}, {"from", "source"}}}),
            "");
}

TEST(BatchConfigErrors, ReportsEveryProblemAtOnceOnePerLine) {
  Json doc = minimal();
  doc["version"] = 3;
  doc["defaults"] = {{"engine", "fast"}};
  doc["classes"][0]["lods"][1]["ratio"] = 0.75;
  doc["classes"][0]["lods"][0]["colour"] = 1;
  doc["classes"].push_back({{"name", "env"}, {"match", Json::array()}, {"lods", Json::array()}});
  try {
    parse_config(doc, "x.json");
    FAIL() << "parsed";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.source(), "x.json");
    const std::vector<std::string> want = {
        "version: unsupported version 3; this lodforge reads version 1",
        "defaults.engine: must be one of \"edge_collapse\", \"multiple_choice\", \"polychord\", \"cluster\", got "
        "string \"fast\"",
        "classes[0].lods[0].colour: unknown key; allowed: " + lod_keys(),
        "classes[0].lods[1].ratio: must be < previous ratio 0.5",
        "classes[1].match: must not be empty",
        "classes[1].lods: must not be empty",
    };
    EXPECT_EQ(e.problems(), want);
    std::string joined;
    for (const std::string& p : want) joined += (joined.empty() ? "" : "\n") + ("x.json: " + p);
    EXPECT_EQ(std::string(e.what()), joined);
  }
}

// --- load_config: files ----------------------------------------------------------------------------------

std::filesystem::path write_temp(const std::string& name, const std::string& text) {
  // One folder per file: temp_dir empties the folder it returns.
  std::filesystem::path path = testing::temp_dir("batch_config_" + name) / name;
  std::ofstream(path, std::ios::binary) << text;
  return path;
}

std::string load_error(const std::filesystem::path& path) {
  try {
    load_config(path);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(BatchConfigFile, LoadsAValidFile) {
  const auto path = write_temp("ok.json", minimal().dump(2));
  EXPECT_EQ(load_config(path).classes[0].name, "props");
}

TEST(BatchConfigFile, MissingFile) {
  const auto path = testing::temp_dir("batch_config_missing") / "nope.json";
  EXPECT_EQ(load_error(path), path.string() + ": no such file");
  EXPECT_EQ(load_error(path.parent_path()), path.parent_path().string() + ": not a regular file");
}

TEST(BatchConfigFile, SyntaxErrorNamesLineColumnAndPath) {
  const auto path = write_temp(
      "syntax.json", "{\n  \"version\": 1,\n  \"classes\": [\n    {\"name\": \"a\",, \"match\": []}\n  ]\n}\n");
  EXPECT_EQ(load_error(path), path.string() +
                                  ": classes[0]: invalid JSON at line 4, column 18: syntax error while parsing object "
                                  "key - unexpected ','; expected string literal");
  const auto empty = write_temp("empty.json", "");
  EXPECT_EQ(load_error(empty), empty.string() +
                                   ": (root): invalid JSON at line 1, column 1: syntax error while parsing value - "
                                   "unexpected end of input; expected '[', '{', or a literal");
}

TEST(BatchConfigFile, DuplicateKeysAreErrorsReportedWithTheRest) {
  const auto path = write_temp("dup.json", R"({
  "version": 1,
  "version": 1,
  "classes": [
    {"name": "a", "name": "b", "match": ["**"], "lods": [{"ratio": 0.5}, {"ratio": 0.7}]}
  ]
})");
  EXPECT_EQ(load_error(path), path.string() + ": version: duplicate key\n" + path.string() +
                                  ": classes[0].name: duplicate key\n" + path.string() +
                                  ": classes[0].lods[1].ratio: must be < previous ratio 0.5");
}

}  // namespace
}  // namespace lodforge::batch
