// lods.json, the engine-side LOD manifest: written for every output format with entries that match the files
// and report.json, switch points by the documented formulas, the same bytes for any job count, and kept right by
// incremental runs, failures and --prune.
#include "lodforge/batch/lods_manifest.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "library_fixture.hpp"
#include "lodforge/batch/config.hpp"
#include "lodforge/batch/report.hpp"
#include "lodforge/batch/runner.hpp"
#include "lodforge/batch/shard.hpp"

namespace lodforge::batch {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

using testlib::config;
using testlib::run;

Json manifest_at(const fs::path& out) {
  return Json::parse(io::read_file(out / "lods.json"));
}

const Json* entry_of(const Json& manifest, const std::string& path) {
  for (const Json& a : manifest["assets"]) {
    if (a["path"] == path) return &a;
  }
  return nullptr;
}

std::set<std::string> manifest_paths(const Json& manifest) {
  std::set<std::string> out;
  for (const Json& a : manifest["assets"]) out.insert(a["path"].get<std::string>());
  return out;
}

bool is_gltf(const std::string& path) {
  const std::string ext = fs::path(path).extension().string();
  return ext == ".gltf" || ext == ".glb";
}

// Every entry against its report record and the files on disk.
// Returns the extensions of the assets seen.
std::set<std::string> check_against_report(const Json& manifest, const Json& report, const fs::path& out,
                                           const std::string& mode) {
  EXPECT_EQ(manifest["format"], "lodforge.lods");
  EXPECT_EQ(manifest["version"], kLodsManifestVersion);
  EXPECT_EQ(manifest["gltf_lods"], mode);
  std::set<std::string> extensions;
  std::size_t ok = 0;
  for (const Json& a : report["assets"]) {
    if (a["status"] != "ok") continue;
    ++ok;
    const std::string path = a["path"];
    const Json* e = entry_of(manifest, path);
    if (e == nullptr) {
      ADD_FAILURE() << "no entry for " << path;
      continue;
    }
    extensions.insert(fs::path(path).extension().string());
    const double diagonal = a["input"]["diagonal"];
    EXPECT_EQ((*e)["diagonal"], diagonal);
    EXPECT_EQ((*e)["radius"], diagonal / 2);
    const Json& lods = (*e)["lods"];
    if (lods.size() != a["lods"].size() + 1) {
      ADD_FAILURE() << path << ": " << lods.size() << " levels";
      continue;
    }
    EXPECT_EQ(lods[0]["triangles"], a["input"]["triangles"]);
    EXPECT_EQ(lods[0]["unreal_screen_size"], 1.0);
    EXPECT_EQ(lods[0]["godot_visibility_range_begin"], 0.0);
    std::set<std::string> outputs;
    for (const Json& o : a["outputs"]) outputs.insert(o.get<std::string>());
    const bool msft = is_gltf(path) && mode != "files";
    for (std::size_t k = 0; k < lods.size(); ++k) {
      const Json& l = lods[k];
      EXPECT_EQ(l["level"], k);
      if (!l["file"].is_null()) {
        EXPECT_TRUE(outputs.count(l["file"].get<std::string>())) << path << " LOD" << k << ": " << l["file"];
        EXPECT_TRUE(fs::is_regular_file(out / l["file"].get<std::string>())) << l["file"];
      }
      EXPECT_EQ(l.contains("msft_lod"), msft) << path;
      if (msft) {
        EXPECT_EQ(l["msft_lod"]["file"], path);
        EXPECT_EQ(l["msft_lod"]["index"], k == 0 ? Json(nullptr) : Json(k - 1));
      }
      if (k == 0) continue;
      const Json& r = a["lods"][k - 1];
      EXPECT_EQ(l["triangles"], r["triangles"]) << path << " LOD" << k;
      EXPECT_EQ(l["reuses_previous"], r["shows_previous"]) << path << " LOD" << k;
      EXPECT_DOUBLE_EQ(l["hausdorff"].get<double>(), r["hausdorff_rel"].get<double>() * diagonal);
      EXPECT_DOUBLE_EQ(l["hausdorff_percent"].get<double>(), r["hausdorff_rel"].get<double>() * 100);
      EXPECT_EQ(l["unreal_screen_size"], r["screen_coverage"]);
      EXPECT_EQ(lods[k - 1]["unity_screen_relative_transition_height"], r["screen_coverage"]);
      EXPECT_EQ(lods[k - 1]["godot_visibility_range_end"], l["godot_visibility_range_begin"]);
      EXPECT_DOUBLE_EQ(l["godot_visibility_range_begin"].get<double>(),
                       distance_for_coverage(diagonal / 2, r["screen_coverage"].get<double>(), 60.0));
      if (l["reuses_previous"].get<bool>()) {
        EXPECT_EQ(l["file"], lods[k - 1]["file"]) << path << ": a reused level points at the one before";
      } else if (!msft || mode == "both") {
        EXPECT_EQ(l["file"], (fs::path(path).parent_path() / lod_file_name(path, k)).generic_string());
      } else {
        EXPECT_EQ(l["file"], path);
      }
    }
    EXPECT_EQ(lods.back()["unity_screen_relative_transition_height"], 0.0);
    EXPECT_EQ(lods.back()["godot_visibility_range_end"], 0.0);
  }
  EXPECT_EQ(manifest["assets"].size(), ok);
  return extensions;
}

TEST(LodsManifest, WrittenForEveryOutputFormatAndMatchesTheFilesAndReport) {
  const fs::path dir = testing::temp_dir("lods_manifest_formats");
  const testlib::Library lib = testlib::write_library(dir / "lib", 12);
  for (const std::string mode : {"msft_lod", "files", "both"}) {
    SCOPED_TRACE(mode);
    const RunResult r = run(lib.root, dir / mode, 2, config(mode));
    ASSERT_EQ(r.succeeded, lib.files.size());
    ASSERT_TRUE(fs::exists(dir / mode / "lods.json"));
    // report.json on disk, not only the in-memory one: the manifest's numbers are the report's.
    const std::set<std::string> extensions = check_against_report(
        manifest_at(dir / mode), Json::parse(io::read_file(dir / mode / "report.json")), dir / mode, mode);
    for (const char* ext : {".obj", ".stl", ".ply", ".off", ".glb", ".gltf"}) EXPECT_TRUE(extensions.count(ext)) << ext;
  }
}

TEST(LodsManifest, ReusedLevelsPointAtThePreviousLevel) {
  // A torus too coarse to lose 10% at a ratio of 0.95 shows its source for LOD1.
  const fs::path dir = testing::temp_dir("lods_manifest_reuse");
  fs::create_directories(dir / "lib/props");
  io::save_asset(testlib::asset_of({testlib::make_torus(24, 12, 1.0f, 0.3f)}, io::Format::obj),
                 dir / "lib/props/ring.obj");
  Json j = Json::parse(testlib::config_text("files"));
  j["classes"][0]["lods"] = Json::array({{{"ratio", 0.95}}, {{"ratio", 0.3}}, {{"ratio", 0.29}}});
  ASSERT_EQ(run(dir / "lib", dir / "out", 2, parse_config(j, "test config")).succeeded, 1u);
  const Json manifest = manifest_at(dir / "out");
  const Json* e = entry_of(manifest, "props/ring.obj");
  ASSERT_NE(e, nullptr);
  const Json& lods = (*e)["lods"];
  ASSERT_EQ(lods.size(), 4u);
  EXPECT_TRUE(lods[1]["reuses_previous"].get<bool>());
  EXPECT_TRUE(lods[1]["file"].is_null()) << "LOD1 shows the source, which has no LOD0 file";
  EXPECT_FALSE(lods[2]["reuses_previous"].get<bool>());
  EXPECT_EQ(lods[2]["file"], "props/ring_LOD2.obj");
  EXPECT_TRUE(lods[3]["reuses_previous"].get<bool>());
  EXPECT_EQ(lods[3]["file"], "props/ring_LOD2.obj");
  EXPECT_FALSE(fs::exists(dir / "out/props/ring_LOD3.obj"));
  check_against_report(manifest, Json::parse(io::read_file(dir / "out/report.json")), dir / "out", "files");
}

// A report made by hand with round numbers: diagonal 2 (radius 1), a viewport 1000 pixels tall, a 2-pixel error
// and a 90-degree field of view (tan 45 = 1). LOD1's error is 1% of the diagonal: it switches in at a coverage of
// 2 / (1000 * 0.01) = 0.2, at distance 1 / (0.2 * 1) = 5; LOD2 (5%) at 0.04, distance 25.
TEST(LodsManifest, SwitchPointsFollowTheFormulas) {
  BatchConfig cfg = config();
  cfg.lod_switch = {.screen_height_px = 1000, .error_px = 2, .fov_y_deg = 90};
  auto lod = [&](double hausdorff_rel, std::size_t triangles) {
    const double coverage = coverage_for_error(hausdorff_rel, 2, 1000);
    return Json{{"hausdorff_rel", hausdorff_rel},
                {"triangles", triangles},
                {"screen_coverage", coverage},
                {"shows_previous", false}};
  };
  const Json report = {{"effective_config", effective_config_json(cfg)},
                       {"assets", Json::array({{{"path", "a/rock.ply"},
                                                {"class", "environment"},
                                                {"status", "ok"},
                                                {"input", {{"triangles", 1000}, {"diagonal", 2.0}}},
                                                {"outputs", Json::array({"a/rock_LOD1.ply", "a/rock_LOD2.ply"})},
                                                {"lods", Json::array({lod(0.01, 500), lod(0.05, 100)})}}})}};
  const Json m = lods_manifest(report, nullptr, true);
  EXPECT_EQ(m["lod_switch"], Json({{"screen_height_px", 1000.0}, {"error_px", 2.0}, {"fov_y_deg", 90.0}}));
  ASSERT_EQ(m["assets"].size(), 1u);
  const Json& a = m["assets"][0];
  EXPECT_EQ(a["unity_lodgroup_size"], 2.0);
  const Json& l = a["lods"];
  ASSERT_EQ(l.size(), 3u);
  EXPECT_TRUE(l[0]["file"].is_null());
  EXPECT_EQ(l[1]["file"], "a/rock_LOD1.ply");
  EXPECT_EQ(l[2]["file"], "a/rock_LOD2.ply");
  EXPECT_DOUBLE_EQ(l[1]["hausdorff"].get<double>(), 0.02);
  EXPECT_DOUBLE_EQ(l[2]["hausdorff_percent"].get<double>(), 5.0);
  const double unreal[] = {1.0, 0.2, 0.04}, unity[] = {0.2, 0.04, 0.0}, begin[] = {0, 5, 25}, end[] = {5, 25, 0};
  for (std::size_t k = 0; k < 3; ++k) {
    SCOPED_TRACE(k);
    EXPECT_NEAR(l[k]["unreal_screen_size"].get<double>(), unreal[k], 1e-12);
    EXPECT_NEAR(l[k]["unity_screen_relative_transition_height"].get<double>(), unity[k], 1e-12);
    EXPECT_NEAR(l[k]["godot_visibility_range_begin"].get<double>(), begin[k], 1e-9);
    EXPECT_NEAR(l[k]["godot_visibility_range_end"].get<double>(), end[k], 1e-9);
  }
  // The same projection as a screen_size target: 200 pixels of 1000 at 90 degrees is distance 5 for radius 1.
  EXPECT_NEAR((ScreenSize{.pixels = 200, .screen_height_px = 1000, .fov_y_deg = 90, .error_px = 2}).switch_distance(1),
              5.0, 1e-9);
}

TEST(LodsManifest, ConfigKeysSetTheProjectionAndBadValuesAreNamed) {
  Json j = Json::parse(testlib::config_text());
  j["defaults"]["lod_switch"] = {{"fov_y_deg", 75}, {"screen_height_px", 720}};
  const BatchConfig cfg = parse_config(j, "test config");
  EXPECT_EQ(cfg.lod_switch, (LodSwitch{.screen_height_px = 720, .error_px = 1, .fov_y_deg = 75}));
  EXPECT_EQ(effective_config_json(cfg)["defaults"]["lod_switch"]["fov_y_deg"], 75.0);
  j["defaults"]["lod_switch"] = {{"fov_y_deg", 180}, {"viewport", 1}};
  try {
    parse_config(j, "test config");
    ADD_FAILURE() << "accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("defaults.lod_switch.fov_y_deg"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("viewport"), std::string::npos) << e.what();
  }
}

TEST(LodsManifest, ChangedProjectionMovesTheCoverageHintsAndRebuilds) {
  const fs::path dir = testing::temp_dir("lods_manifest_projection");
  const testlib::Library lib = testlib::write_library(dir / "lib", 6);
  ASSERT_EQ(run(lib.root, dir / "out", 2).cache_hits, 0u);
  BatchConfig cfg = config();
  cfg.lod_switch.screen_height_px = 540;
  const RunResult r = run(lib.root, dir / "out", 2, cfg);
  EXPECT_EQ(r.cache_hits, 0u) << "the coverage hints are in the glTF files: a new projection rebuilds";
  for (const Json& a : r.report["assets"]) {
    for (const Json& l : a["lods"]) {
      if (l["target"]["kind"] == "screen_size") continue;
      EXPECT_LE(l["screen_coverage"].get<double>(),
                coverage_for_error(l["hausdorff_rel"].get<double>(), 1, 540) * (1 + 1e-12));
    }
  }
  check_against_report(manifest_at(dir / "out"), r.report, dir / "out", "msft_lod");
  EXPECT_EQ(manifest_at(dir / "out")["lod_switch"]["screen_height_px"], 540.0);
}

TEST(LodsManifest, SameBytesForAnyJobCount) {
  const fs::path dir = testing::temp_dir("lods_manifest_jobs");
  const testlib::Library lib = testlib::write_library(dir / "lib", 30);
  run(lib.root, dir / "j1", 1);
  run(lib.root, dir / "j3", 3);
  const std::string one = io::read_file(dir / "j1/lods.json");
  EXPECT_EQ(one, io::read_file(dir / "j3/lods.json"));
  EXPECT_EQ(manifest_at(dir / "j1")["assets"].size(), lib.files.size());
  EXPECT_TRUE(testlib::leftovers(dir / "j1").empty());
}

TEST(LodsManifest, IncrementalRunsKeepEntriesAndPruneDropsThem) {
  const fs::path dir = testing::temp_dir("lods_manifest_incremental");
  const testlib::Library lib = testlib::write_library(dir / "lib", 12);
  const fs::path out = dir / "out";
  run(lib.root, out, 2);
  const std::string first = io::read_file(out / "lods.json");

  // All cache hits: the same bytes.
  ASSERT_EQ(run(lib.root, out, 2).cache_hits, lib.files.size());
  EXPECT_EQ(io::read_file(out / "lods.json"), first);

  // One asset changed: its entry is rebuilt, the others are kept, and the result is what a clean run writes.
  const std::string touched = "env/patch_5.ply";
  ASSERT_TRUE(fs::exists(lib.root / touched));
  io::save_asset(testlib::asset_of({testlib::make_terrain(20, 7)}, io::Format::ply), lib.root / touched);
  const RunResult second = run(lib.root, out, 2);
  EXPECT_EQ(second.cache_hits, lib.files.size() - 1);
  run(lib.root, dir / "clean", 2);
  EXPECT_EQ(io::read_file(out / "lods.json"), io::read_file(dir / "clean/lods.json"));
  EXPECT_NE(io::read_file(out / "lods.json"), first);
  EXPECT_EQ((*entry_of(manifest_at(out), touched))["lods"][0]["triangles"], 800);

  // A failing asset keeps the entry of its last good outputs; a removed one stays until --prune removes its files.
  const Json before = manifest_at(out);
  const std::string failing = "env/patch_4.off", removed = "props/prop_0.obj";
  std::ofstream(lib.root / failing) << "OFF\n3 1 0\n0 0 0\n";  // truncated
  fs::remove(lib.root / removed);
  const RunResult third = run(lib.root, out, 2);
  EXPECT_EQ(third.failed, 1u);
  const Json kept = manifest_at(out);
  ASSERT_NE(entry_of(kept, failing), nullptr);
  EXPECT_EQ(*entry_of(kept, failing), *entry_of(before, failing));
  ASSERT_NE(entry_of(kept, removed), nullptr) << "its files are still there";
  EXPECT_EQ(manifest_paths(kept), manifest_paths(before));

  RunOptions prune{.input_dir = lib.root, .output_dir = out, .jobs = 2};
  prune.prune = true;
  run_batch(config(), prune);
  const Json pruned = manifest_at(out);
  EXPECT_EQ(entry_of(pruned, removed), nullptr);
  ASSERT_NE(entry_of(pruned, failing), nullptr) << "a failure keeps its outputs, so its entry too";
  EXPECT_EQ(manifest_paths(pruned).size(), lib.files.size() - 1);
}

// Each shard writes lods.shard-K-of-N.json with its own assets; the merged report gives the unsharded manifest
// (merge-reports writes it).
TEST(LodsManifest, ShardsWriteTheirOwnAndTheMergedReportGivesTheWholeManifest) {
  const fs::path dir = testing::temp_dir("lods_manifest_shards");
  const testlib::Library lib = testlib::write_library(dir / "lib", 24);
  run(lib.root, dir / "whole", 2);
  std::vector<Json> reports;
  std::size_t entries = 0;
  for (std::uint32_t k = 0; k < 2; ++k) {
    const RunResult r = run_batch(config(), {.config_file = "test config",
                                             .input_dir = lib.root,
                                             .output_dir = dir / "sharded",
                                             .jobs = 2,
                                             .shard = Shard{k, 2}});
    const Json shard = Json::parse(io::read_file(dir / "sharded" / ("lods.shard-" + std::to_string(k) + "-of-2.json")));
    EXPECT_EQ(shard["assets"].size(), r.report["assets"].size());
    entries += shard["assets"].size();
    reports.push_back(r.report);
  }
  EXPECT_EQ(entries, lib.files.size());
  EXPECT_FALSE(fs::exists(dir / "sharded/lods.json"));
  EXPECT_EQ(lods_manifest(merge_reports(reports), nullptr, false).dump(1) + "\n",
            io::read_file(dir / "whole/lods.json"));
}

TEST(LodsManifest, AMalformedManifestIsReplaced) {
  const fs::path dir = testing::temp_dir("lods_manifest_malformed");
  const testlib::Library lib = testlib::write_library(dir / "lib", 6);
  fs::create_directories(dir / "out");
  std::ofstream(dir / "out/lods.json") << "{ not json";
  run(lib.root, dir / "out", 2);
  EXPECT_EQ(manifest_at(dir / "out")["assets"].size(), lib.files.size());
  EXPECT_TRUE(read_lods_manifest(dir / "missing.json").is_null());
}

}  // namespace
}  // namespace lodforge::batch
