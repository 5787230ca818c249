// The batch runner on a generated library of ~200 small assets (library_fixture.hpp): every LOD written within
// budget, a well-formed report, identical bytes for any job count, incremental re-runs, failure isolation,
// resuming a stopped run, sharding, duplicate reuse, and MSFT_lod output that passes the Khronos validator.
#include "lodforge/batch/runner.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <set>

#include "library_fixture.hpp"
#include "lodforge/batch/cache.hpp"
#include "lodforge/batch/config.hpp"
#include "lodforge/batch/report.hpp"
#include "lodforge/batch/shard.hpp"
#include "lodforge/core/validate.hpp"

namespace lodforge::batch {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

using testlib::config;
using testlib::run;

const Json& record_of(const Json& report, const std::string& path) {
  for (const Json& a : report["assets"]) {
    if (a["path"] == path) return a;
  }
  static const Json kNone;
  ADD_FAILURE() << "no record for " << path;
  return kNone;
}

// Reports of two runs of the same work agree on everything but timings, the job count, the folders they ran on
// and what they say changed since the run before (a run into a fresh folder has no "changes").
Json comparable(Json report) {
  report["jobs"] = 0;
  report.erase("input_dir");
  report.erase("output_dir");
  report.erase("changes");
  return without_timings(std::move(report));
}

TEST(BatchRunner, WritesEveryLodWithinItsBudget) {
  const fs::path dir = testing::temp_dir("batch_runner_budgets");
  const testlib::Library lib = testlib::write_library(dir / "lib");
  const BatchConfig cfg = config();
  const RunResult r = run(lib.root, dir / "out", 2, cfg);

  EXPECT_EQ(r.succeeded, lib.files.size());
  EXPECT_EQ(r.failed, 0u);
  EXPECT_TRUE(r.failures.empty());
  const std::vector<std::string> problems = check_report(r.report);
  EXPECT_TRUE(problems.empty()) << problems.front();
  EXPECT_EQ(r.report["assets"].size(), lib.files.size());
  // report.json on disk is the same document, and report.html exists.
  EXPECT_EQ(Json::parse(io::read_file(dir / "out/report.json")), r.report);
  EXPECT_TRUE(fs::is_regular_file(dir / "out/report.html"));
  EXPECT_EQ(r.report["summary"]["lods"].get<std::size_t>(), [&] {
    std::size_t n = 0;
    for (const Json& a : r.report["assets"]) n += a["lods"].size();
    return n;
  }());

  for (const Json& a : r.report["assets"]) {
    const std::string path = a["path"];
    SCOPED_TRACE(path);
    ASSERT_EQ(a["status"], "ok") << a["error"];
    const AssetClass* cls = find_class(cfg, a["class"].get<std::string>());
    ASSERT_NE(cls, nullptr);
    ASSERT_EQ(a["lods"].size(), cls->lods.size());
    const std::size_t source = a["input"]["triangles"];
    std::size_t previous = source;
    for (const Json& l : a["lods"]) {
      const std::size_t tris = l["triangles"];
      EXPECT_GT(tris, 0u);
      EXPECT_LE(tris, previous) << "LOD chains never grow";
      previous = l["from"] == "previous" ? tris : previous;
      if (l["target_triangles"].is_number()) {
        const std::size_t target = l["target_triangles"];
        // An edge collapse removes two triangles (one at a border): the count lands on the target or one below,
        // unless the simplifier says it stopped early.
        EXPECT_LE(tris, std::max<std::size_t>(target, 1) + (l["stop_reason"] == "target_reached" ? 0 : source));
        if (l["stop_reason"] == "target_reached") {
          EXPECT_GE(tris + 2, target);
        }
      } else {
        EXPECT_LE(l["error_bound_rel"].get<double>(), 0.03 + 1e-9) << "error target respected";
      }
      EXPECT_GE(l["hausdorff_rel"].get<double>(), 0.0);
      EXPECT_GT(l["screen_coverage"].get<double>(), 0.0);
      EXPECT_EQ(l["attributes"]["normal_deviation_mean_deg"], l["normal_deviation_mean_deg"]);
      EXPECT_GE(l["attributes"]["normal_deviation_p95_deg"].get<double>(), 0.0);
    }
    // MSFT_screencoverage from the measured error: where the LOD's Hausdorff error is one pixel of a
    // 1080-pixel-tall screen (the object being its bounding sphere), never above the LOD before it.
    double above = 1.0;
    for (const Json& l : a["lods"]) {
      const double expected = std::min(above, 1.0 / (1080.0 * std::max(l["hausdorff_rel"].get<double>(), 1e-12)));
      EXPECT_DOUBLE_EQ(l["screen_coverage"].get<double>(), expected) << "LOD" << l["level"];
      above = expected;
    }
    // Outputs: a MSFT_lod glTF for glTF sources, one file per LOD otherwise; all exist.
    ASSERT_FALSE(a["outputs"].empty());
    for (const Json& o : a["outputs"]) EXPECT_TRUE(fs::is_regular_file(dir / "out" / o.get<std::string>())) << o;
    const fs::path rel(path);
    const std::string ext = rel.extension().string();
    if (ext == ".gltf" || ext == ".glb") {
      EXPECT_NE(std::find(a["outputs"].begin(), a["outputs"].end(), path), a["outputs"].end());
    } else {
      for (std::size_t k = 1; k <= cls->lods.size(); ++k) {
        const std::string name = (rel.parent_path() / lod_file_name(rel.filename(), k)).generic_string();
        EXPECT_NE(std::find(a["outputs"].begin(), a["outputs"].end(), name), a["outputs"].end()) << name;
        // The LOD file holds what the report says.
        EXPECT_EQ(io::load_asset(dir / "out" / name).meshes.at(0).triangle_count(),
                  a["lods"][k - 1]["triangles"].get<std::size_t>());
      }
    }
  }
  EXPECT_TRUE(testlib::leftovers(dir / "out").empty());
}

TEST(BatchRunner, SameBytesForAnyJobCount) {
  const fs::path dir = testing::temp_dir("batch_runner_jobs");
  const testlib::Library lib = testlib::write_library(dir / "lib");
  // One asset large enough that the simplifier and eval run their own parallel loops inside it.
  io::save_asset(testlib::asset_of({testing::make_uv_sphere(110, 130)}, io::Format::glb), lib.root / "props/big.glb");
  const RunResult one = run(lib.root, dir / "j1", 1);
  const RunResult two = run(lib.root, dir / "j2", 2);
  const RunResult three = run(lib.root, dir / "j3", 3);  // more threads than cores
  const auto a = testlib::read_outputs(dir / "j1");
  EXPECT_EQ(a.size(), testlib::read_outputs(dir / "j2").size());
  EXPECT_TRUE(a == testlib::read_outputs(dir / "j2"));
  EXPECT_TRUE(a == testlib::read_outputs(dir / "j3"));
  EXPECT_EQ(comparable(one.report), comparable(two.report));
  EXPECT_EQ(comparable(one.report), comparable(three.report));
  EXPECT_EQ(one.report["jobs"], 1);
  EXPECT_EQ(two.report["jobs"], 2);
  EXPECT_GT(record_of(two.report, "props/big.glb")["input"]["triangles"].get<std::size_t>(), 20000u);
}

TEST(BatchRunner, SecondRunIsAllCacheHitsAndTouchingOneFileRedoesOne) {
  const fs::path dir = testing::temp_dir("batch_runner_cache");
  const testlib::Library lib = testlib::write_library(dir / "lib");
  const RunResult first = run(lib.root, dir / "out", 2);
  const auto bytes = testlib::read_outputs(dir / "out");
  EXPECT_EQ(first.cache_hits, 0u);

  const RunResult second = run(lib.root, dir / "out", 2);
  EXPECT_EQ(second.cache_hits, lib.files.size());
  EXPECT_EQ(second.succeeded, lib.files.size());
  EXPECT_EQ(second.input_triangles, 0u) << "nothing was simplified";
  EXPECT_TRUE(bytes == testlib::read_outputs(dir / "out"));
  // A cache hit reports the stored record: the same as the run that made it, but for cache_hit and timings.
  Json expected = comparable(first.report);
  for (Json& a : expected["assets"]) a["cache_hit"] = true;
  expected["summary"]["cache_hits"] = lib.files.size();
  EXPECT_EQ(comparable(second.report), expected);

  // Touch one asset: a different mesh under the same name.
  const std::string touched = "env/patch_90.off";
  io::save_asset(testlib::asset_of({testlib::make_terrain(20, 7)}, io::Format::off), lib.root / touched);
  const RunResult third = run(lib.root, dir / "out", 2);
  EXPECT_EQ(third.cache_hits, lib.files.size() - 1);
  for (const Json& a : third.report["assets"]) EXPECT_EQ(a["cache_hit"], a["path"] != touched) << a["path"];
  EXPECT_EQ(record_of(third.report, touched)["input"]["triangles"], 800);
  // Each run into the same output compares itself with the report it replaces.
  EXPECT_FALSE(first.report.contains("changes"));
  const Json& none = second.report["changes"];
  EXPECT_EQ(none["previous_assets"], lib.files.size());
  for (const char* kind : {"added", "removed", "rebuilt", "status_changed", "lods_moved"}) {
    EXPECT_TRUE(none[kind].empty()) << kind;
  }
  const Json& one = third.report["changes"];
  EXPECT_EQ(one["rebuilt"], Json::array({touched}));
  EXPECT_TRUE(one["added"].empty());
  EXPECT_FALSE(one["lods_moved"].empty());  // a different mesh: other triangle counts and errors
  for (const Json& m : one["lods_moved"]) EXPECT_EQ(m["path"], touched);
  EXPECT_EQ(Json::parse(io::read_file(dir / "out/report.json"))["changes"], one);

  // Touching a file without changing it redoes nothing: the key is the content, not the time stamp.
  fs::last_write_time(lib.root / "props/prop_0.obj", fs::file_time_type::clock::now());
  EXPECT_EQ(run(lib.root, dir / "out", 2).cache_hits, lib.files.size());

  // --force rebuilds everything, to the same bytes.
  const auto before_force = testlib::read_outputs(dir / "out");
  const RunResult forced =
      run_batch(config(), {.input_dir = lib.root, .output_dir = dir / "out", .jobs = 2, .force = true});
  EXPECT_EQ(forced.cache_hits, 0u);
  EXPECT_TRUE(before_force == testlib::read_outputs(dir / "out"));
}

TEST(BatchRunner, ChangingOneClassRedoesOnlyItsAssets) {
  const fs::path dir = testing::temp_dir("batch_runner_class_change");
  const testlib::Library lib = testlib::write_library(dir / "lib", 30);
  run(lib.root, dir / "out", 2);
  Json doc = Json::parse(testlib::config_text());
  doc["classes"][1]["lods"][1]["triangles"] = 50;  // environment only
  const RunResult r = run(lib.root, dir / "out", 2, parse_config(doc));
  for (const Json& a : r.report["assets"]) EXPECT_EQ(a["cache_hit"], a["class"] != "environment") << a["path"];
}

TEST(BatchRunner, CorruptAssetsFailAloneAndAreReported) {
  const fs::path dir = testing::temp_dir("batch_runner_corrupt");
  const testlib::Library lib = testlib::write_library(dir / "lib", 40);
  std::ofstream(lib.root / "props/broken.obj") << "v 0 0 0\nv 1 0 0\nf 1 2 9\n";  // index out of range
  std::ofstream(lib.root / "chars/truncated.glb", std::ios::binary) << "glTF\x02\0\0\0";
  std::ofstream(lib.root / "env/empty.ply") << "";
  const RunResult r = run(lib.root, dir / "out", 2);
  EXPECT_EQ(r.failed, 3u);
  EXPECT_EQ(r.succeeded, lib.files.size());
  ASSERT_EQ(r.failures.size(), 3u);
  EXPECT_EQ(r.failures[0].rfind("chars/truncated.glb: ", 0), 0u) << r.failures[0];
  EXPECT_EQ(r.failures[1].rfind("env/empty.ply: ", 0), 0u) << r.failures[1];
  EXPECT_EQ(r.failures[2].rfind("props/broken.obj: ", 0), 0u) << r.failures[2];
  for (const std::string& f : r.failures) {
    EXPECT_EQ(f.find(lib.root.string()), std::string::npos) << "the path is given twice: " << f;
  }
  const Json& broken = record_of(r.report, "props/broken.obj");
  EXPECT_EQ(broken["status"], "failed");
  EXPECT_TRUE(broken["error"].is_string());
  EXPECT_TRUE(broken["outputs"].empty());
  EXPECT_FALSE(fs::exists(dir / "out/props/broken_LOD1.obj"));
  EXPECT_TRUE(check_report(r.report).empty());
  EXPECT_EQ(r.report["summary"]["failed"], 3);
  EXPECT_TRUE(testlib::leftovers(dir / "out").empty());
  // Failures are not cached: the next run tries them again (and the good assets are hits).
  const RunResult again = run(lib.root, dir / "out", 2);
  EXPECT_EQ(again.failed, 3u);
  EXPECT_EQ(again.cache_hits, lib.files.size());
}

TEST(BatchRunner, StoppedRunResumesToIdenticalOutput) {
  const fs::path dir = testing::temp_dir("batch_runner_resume");
  const testlib::Library lib = testlib::write_library(dir / "lib");
  run(lib.root, dir / "clean", 2);

  const RunResult stopped =
      run_batch(config(), {.input_dir = lib.root, .output_dir = dir / "out", .jobs = 2, .stop_after = 60});
  EXPECT_TRUE(stopped.cancelled);
  EXPECT_EQ(stopped.succeeded, 60u);
  EXPECT_EQ(stopped.not_started, lib.files.size() - 60);
  EXPECT_EQ(stopped.skipped, 0u);
  EXPECT_EQ(stopped.report["summary"]["not_started"], lib.files.size() - 60);
  EXPECT_TRUE(check_report(stopped.report).empty());
  EXPECT_TRUE(testlib::leftovers(dir / "out").empty());
  // What a kill in the middle of writing leaves: a staged half-asset and an entry's temporary file.
  const fs::path staging = dir / "out" / kCacheFolder / "staging-0-of-1" / "0123456789abcdef";
  fs::create_directories(staging);
  std::ofstream(staging / "prop_77_LOD1.obj") << "v 0 0";
  const std::string victim = "props/prop_0.obj";
  char name[40];
  std::snprintf(name, sizeof name, "%016llx.json.tmp-1-0", static_cast<unsigned long long>(path_hash(victim)));
  std::ofstream(dir / "out" / kCacheFolder / "entries" / name) << "{";
  ASSERT_FALSE(testlib::leftovers(dir / "out").empty());

  const RunResult resumed = run(lib.root, dir / "out", 2);
  EXPECT_EQ(resumed.cache_hits, 60u);
  EXPECT_EQ(resumed.succeeded, lib.files.size());
  EXPECT_FALSE(resumed.cancelled);
  EXPECT_TRUE(testlib::leftovers(dir / "out").empty()) << testlib::leftovers(dir / "out").front();
  EXPECT_TRUE(testlib::read_outputs(dir / "clean") == testlib::read_outputs(dir / "out"));
}

TEST(BatchRunner, CancelFlagStopsAdmittingAssets) {
  const fs::path dir = testing::temp_dir("batch_runner_cancel");
  const testlib::Library lib = testlib::write_library(dir / "lib", 40);
  std::atomic<bool> cancel{false};
  RunOptions options{.input_dir = lib.root, .output_dir = dir / "out", .jobs = 1};
  options.cancel = &cancel;
  options.on_asset_done = [&](const AssetDone& d) {
    if (d.done == 5) cancel = true;
  };
  const RunResult r = run_batch(config(), options);
  EXPECT_TRUE(r.cancelled);
  EXPECT_GE(r.succeeded, 5u);
  EXPECT_LT(r.succeeded, 10u) << "only the assets already in flight finish";
  EXPECT_EQ(r.succeeded + r.not_started, lib.files.size());
}

TEST(BatchRunner, ThreeShardsMergeToTheUnshardedReport) {
  const fs::path dir = testing::temp_dir("batch_runner_shards");
  const testlib::Library lib = testlib::write_library(dir / "lib");
  const RunResult whole = run(lib.root, dir / "whole", 2);
  std::vector<Json> reports;
  std::size_t assets = 0;
  for (std::uint32_t k = 0; k < 3; ++k) {
    // All shards write into one folder, as on a shared file system.
    const RunResult r = run_batch(config(), {.config_file = "test config",
                                             .input_dir = lib.root,
                                             .output_dir = dir / "sharded",
                                             .jobs = 2,
                                             .shard = Shard{k, 3}});
    EXPECT_EQ(r.report["shard"], std::to_string(k) + "/3");
    EXPECT_EQ(r.report_path.filename(), "report.shard-" + std::to_string(k) + "-of-3.json");
    EXPECT_GT(r.report["assets"].size(), 30u) << "the hash spreads the library";
    assets += r.report["assets"].size();
    reports.push_back(r.report);
  }
  EXPECT_EQ(assets, lib.files.size());
  const Json merged = merge_reports(reports);
  EXPECT_TRUE(check_report(merged).empty());
  EXPECT_EQ(comparable(merged), comparable(whole.report));
  EXPECT_TRUE(testlib::read_outputs(dir / "whole") == testlib::read_outputs(dir / "sharded"));
  EXPECT_THROW(merge_reports({reports[0], reports[0]}), std::invalid_argument) << "an asset twice";
}

TEST(BatchRunner, DuplicateMeshesAreSimplifiedOnce) {
  const fs::path dir = testing::temp_dir("batch_runner_duplicates");
  const testlib::Library lib = testlib::write_library(dir / "lib", 12);
  const RunResult r = run(lib.root, dir / "out", 2);
  const Json& a = record_of(r.report, "props/dup_a.obj");
  const Json& b = record_of(r.report, "props/dup_b.obj");
  ASSERT_EQ(a["lods"].size(), 3u);
  for (std::size_t k = 0; k < 3; ++k) {
    // The second copy reuses the first's chain, simplifier timings included (two separate runs would not
    // measure the same nanoseconds).
    EXPECT_EQ(a["lods"][k]["seconds"], b["lods"][k]["seconds"]);
    EXPECT_EQ(a["lods"][k]["triangles"], b["lods"][k]["triangles"]);
  }
  EXPECT_EQ(io::read_file(dir / "out/props/dup_a_LOD2.obj"), io::read_file(dir / "out/props/dup_b_LOD2.obj"));
}

// An asset with faces written twice: the report counts them under "input", and its LODs are those of the
// clean mesh (no repeated face, no non-manifold edge left).
TEST(BatchRunner, RepeatedFacesAreCountedAndDropped) {
  const fs::path dir = testing::temp_dir("batch_runner_repeated");
  const testlib::Library lib = testlib::write_library(dir / "lib", 6);
  const Mesh clean = testing::make_uv_sphere(12, 16);
  const Mesh twice = testing::with_repeated_faces(clean, 4);
  const std::size_t copies = twice.face_count() - clean.face_count();
  io::save_asset(testlib::asset_of({twice}, io::Format::obj), lib.root / "props/repeated.obj");
  const RunResult r = run(lib.root, dir / "out", 2);
  const Json& a = record_of(r.report, "props/repeated.obj");
  ASSERT_EQ(a["status"], "ok") << a["error"];
  EXPECT_EQ(a["input"]["repeated_faces"], copies);
  EXPECT_EQ(record_of(r.report, "props/dup_a.obj")["input"]["repeated_faces"], 0);
  EXPECT_TRUE(check_report(r.report).empty());
  for (int k = 0; k < 3; ++k) {
    const Mesh lod = io::load_asset(dir / "out/props" / ("repeated_LOD" + std::to_string(k + 1) + ".obj")).meshes.at(0);
    EXPECT_TRUE(repeated_faces(lod).empty()) << "LOD " << k + 1;
    const ValidationReport v = validate(lod);
    EXPECT_EQ(v.non_manifold_edges, 0u) << "LOD " << k + 1;
  }
}

// report.json gives each asset's mirror symmetry (input.symmetry); a class with symmetry_plane none skips it.
TEST(BatchRunner, ReportsTheSymmetryOfEachAsset) {
  const fs::path dir = testing::temp_dir("batch_runner_symmetry");
  const testlib::Library lib = testlib::write_library(dir / "lib", 6);
  io::save_asset(testlib::asset_of({testing::make_cube_quads()}, io::Format::obj), lib.root / "props/cube.obj");
  const RunResult r = run(lib.root, dir / "out", 2);
  EXPECT_TRUE(check_report(r.report).empty());
  const Json& cube = record_of(r.report, "props/cube.obj")["input"]["symmetry"];
  EXPECT_EQ(cube["plane_mode"], "auto");
  EXPECT_EQ(cube["edges"], 12);
  EXPECT_EQ(cube["symmetric_edges"], 12);
  EXPECT_EQ(cube["fraction"], 1.0);
  ASSERT_TRUE(cube["plane"].is_array());
  EXPECT_EQ(cube["plane"].size(), 4u);

  BatchConfig off = config();
  for (AssetClass& cls : off.classes) cls.options.pending.symmetry_plane = symmetry::PlaneMode::none;
  const RunResult none = run(lib.root, dir / "out_none", 2, off);
  EXPECT_TRUE(check_report(none.report).empty());
  const Json& skipped = record_of(none.report, "props/cube.obj")["input"]["symmetry"];
  EXPECT_EQ(skipped["plane_mode"], "none");
  EXPECT_EQ(skipped["symmetric_edges"], 0);
  EXPECT_TRUE(skipped["plane"].is_null());
}

TEST(BatchRunner, UnmatchedAssetsAreSkippedWithTheReason) {
  const fs::path dir = testing::temp_dir("batch_runner_unmatched");
  const testlib::Library lib = testlib::write_library(dir / "lib", 10);
  io::save_asset(testlib::asset_of({testing::make_tetrahedron()}, io::Format::obj), lib.root / "misc.obj");
  const RunResult r = run(lib.root, dir / "out", 2);
  const Json& misc = record_of(r.report, "misc.obj");
  EXPECT_EQ(misc["status"], "skipped");
  EXPECT_TRUE(misc["class"].is_null());
  EXPECT_NE(misc["error"].get<std::string>().find("matches no class"), std::string::npos);
  EXPECT_EQ(r.skipped, 1u);
  EXPECT_EQ(r.failed, 0u);
}

TEST(BatchRunner, GltfLodModesWriteTheRightFiles) {
  const fs::path dir = testing::temp_dir("batch_runner_gltf_modes");
  const testlib::Library lib = testlib::write_library(dir / "lib", 12);
  for (const std::string mode : {"files", "both"}) {
    const RunResult r = run(lib.root, dir / mode, 2, config(mode));
    for (const Json& a : r.report["assets"]) {
      const fs::path rel(a["path"].get<std::string>());
      if (rel.extension() != ".glb" && rel.extension() != ".gltf") continue;
      const auto& outs = a["outputs"];
      auto has = [&](const fs::path& p) {
        return std::find(outs.begin(), outs.end(), p.generic_string()) != outs.end();
      };
      EXPECT_EQ(has(rel), mode == "both") << rel;
      EXPECT_TRUE(has(rel.parent_path() / lod_file_name(rel.filename(), 1))) << rel;
      EXPECT_TRUE(has(rel.parent_path() / lod_file_name(rel.filename(), 2))) << rel;
      if (rel.extension() == ".gltf") {
        EXPECT_TRUE(has(rel.parent_path() / (rel.stem().string() + "_LOD1.bin")));
      }
    }
  }
}

TEST(BatchRunner, MsftLodOutputsPassTheValidator) {
  const fs::path dir = testing::temp_dir("batch_runner_validator");
  const testlib::Library lib = testlib::write_library(dir / "lib", 200);
  const RunResult r = run(lib.root, dir / "out", 2);
  std::vector<fs::path> files;
  for (const Json& a : r.report["assets"]) {
    const fs::path rel(a["path"].get<std::string>());
    if (rel.extension() != ".glb" && rel.extension() != ".gltf") continue;
    const fs::path out = dir / "out" / rel;
    files.push_back(out);
    const Json doc = testlib::gltf_json(out);
    SCOPED_TRACE(rel.string());
    EXPECT_NE(std::find(doc["extensionsUsed"].begin(), doc["extensionsUsed"].end(), "MSFT_lod"),
              doc["extensionsUsed"].end());
    const std::size_t meshes = io::load_asset(lib.root / rel).meshes.size();
    const std::size_t levels = a["lods"].size();
    ASSERT_EQ(doc["meshes"].size(), meshes * (1 + levels)) << "LOD0 plus its LODs, per mesh";
    std::size_t with_lods = 0;
    for (const Json& node : doc["nodes"]) {
      if (!node.contains("extensions")) continue;
      ++with_lods;
      const Json& ids = node["extensions"]["MSFT_lod"]["ids"];
      ASSERT_EQ(ids.size(), levels);
      const Json& coverage = node["extras"]["MSFT_screencoverage"];
      ASSERT_EQ(coverage.size(), levels + 1);
      for (std::size_t k = 1; k <= levels; ++k) EXPECT_GE(coverage[k - 1].get<double>(), coverage[k].get<double>());
      EXPECT_EQ(coverage[levels].get<double>(), 0.0);
      EXPECT_EQ(coverage[0].get<double>(), a["lods"][0]["screen_coverage"].get<double>());
      for (const Json& id : ids) EXPECT_TRUE(doc["nodes"][id.get<std::size_t>()].contains("mesh"));
    }
    EXPECT_EQ(with_lods, meshes);
  }
  ASSERT_GT(files.size(), 50u);
  if (const std::string why = testlib::gltf_validator_unavailable(); !why.empty()) GTEST_SKIP() << why;
  const auto v = testlib::validate_gltf(files);
  EXPECT_EQ(v.exit_code, 0) << v.output;
}

// A textured quad grid through a polychord LOD and a triangle LOD: each LOD record carries the attribute
// metrics of attribute_eval (UV error, flips, chart spans, stretch) and the quad structure of the LOD.
TEST(BatchRunner, ReportsAttributeMetricsAndQuadStructurePerLod) {
  const fs::path dir = testing::temp_dir("batch_runner_attributes");
  Mesh grid = testing::make_grid(12, 12, true);
  grid.uvs.assign(1, {});
  for (const std::uint32_t v : grid.wedge_vertex) {
    grid.uvs[0].push_back(Vec2f{{grid.positions[v][0] / 12.0f, grid.positions[v][1] / 12.0f}});
  }
  grid.normals.assign(grid.wedge_vertex.size(), Vec3f{{0, 0, 1}});
  fs::create_directories(dir / "lib");
  io::save_asset(testlib::asset_of({grid}, io::Format::obj), dir / "lib/grid.obj");
  const BatchConfig cfg = parse_config(Json::parse(R"({
    "version": 1,
    "classes": [{"name": "all", "match": ["**"], "lods": [
      {"ratio": 0.5, "engine": "polychord"},
      {"ratio": 0.25}]}]})"), "test config");
  const RunResult r = run(dir / "lib", dir / "out", 2, cfg);
  ASSERT_EQ(r.succeeded, 1u) << (r.failures.empty() ? std::string() : r.failures.front());
  const Json& lods = record_of(r.report, "grid.obj")["lods"];
  ASSERT_EQ(lods.size(), 2u);
  for (const Json& l : lods) {
    const Json& attrs = l["attributes"];
    ASSERT_TRUE(attrs.contains("rms.TEXCOORD_0")) << attrs.dump();
    EXPECT_LT(attrs["rms.TEXCOORD_0"].get<double>(), 0.05);  // a flat grid with planar UVs stays planar
    EXPECT_EQ(attrs["uv_flipped"], 0);
    EXPECT_EQ(attrs["uv_spanning"], 0);
    EXPECT_GT(attrs["uv_stretch_ratio"].get<double>(), 0.0);
    EXPECT_TRUE(attrs.contains("rms.NORMAL"));
    EXPECT_FALSE(attrs.contains("pose_hausdorff_rel"));  // not skinned
  }
  EXPECT_GT(lods[0]["quad_fraction"].get<double>(), 0.85);  // polychord keeps quads
  EXPECT_EQ(lods[1]["quad_fraction"].get<double>(), 0.0);   // the triangle engine's LOD is triangles
}

TEST(BatchRunner, MissingInputFolderThrows) {
  const fs::path dir = testing::temp_dir("batch_runner_missing");
  EXPECT_THROW(run(dir / "nope", dir / "out", 1), io::IoError);
}

TEST(BatchRunner, OutputFolderInsideTheLibraryIsNotScanned) {
  const fs::path dir = testing::temp_dir("batch_runner_nested_output");
  const testlib::Library lib = testlib::write_library(dir / "lib", 6);
  const RunResult first = run(lib.root, lib.root / "lods", 1);
  EXPECT_EQ(first.report["assets"].size(), lib.files.size());
  const RunResult second = run(lib.root, lib.root / "lods", 1);
  EXPECT_EQ(second.report["assets"].size(), lib.files.size()) << "the LODs of the first run are not assets";
  EXPECT_EQ(second.cache_hits, lib.files.size());
  EXPECT_THROW(run(lib.root, lib.root, 1), io::IoError);
}

TEST(BatchRunner, ScanListsSupportedFilesSortedAndSkipsTheCache) {
  const fs::path dir = testing::temp_dir("batch_runner_scan");
  fs::create_directories(dir / "b/c");
  fs::create_directories(dir / kCacheFolder / "staging-0-of-1");
  for (const char* f : {"b/c/z.obj", "a.GLB", "b/readme.txt", "b/x.ply", ".lodforge-cache/staging-0-of-1/q.obj"}) {
    std::ofstream(dir / f) << "x";
  }
  const LibraryScan scan = scan_library(dir);
  EXPECT_EQ(scan.assets, (std::vector<std::string>{"a.GLB", "b/c/z.obj", "b/x.ply"}));
  EXPECT_TRUE(scan.skipped.empty());
}

TEST(BatchRunner, ScanSkipsSymbolicLinkLoopsAndBrokenLinksWithAWarning) {
  const fs::path dir = testing::temp_dir("batch_runner_scan_links");
  fs::create_directories(dir / "sub");
  for (const char* f : {"a.obj", "sub/b.ply"}) std::ofstream(dir / f) << "x";
  fs::create_symlink("loop_b", dir / "loop_a");  // a -> b -> a: the scan used to stop at a filesystem_error
  fs::create_symlink("loop_a", dir / "loop_b");
  fs::create_symlink("self.glb", dir / "sub/self.glb");
  fs::create_symlink("missing.obj", dir / "gone.obj");  // named like an asset: worth a warning
  fs::create_symlink("missing", dir / "notes");         // not an asset either way: silent
  const LibraryScan scan = scan_library(dir);
  EXPECT_EQ(scan.assets, (std::vector<std::string>{"a.obj", "sub/b.ply"}));
  EXPECT_EQ(scan.skipped,
            (std::vector<std::string>{(dir / "gone.obj").string() + ": skipped: broken symbolic link",
                                      (dir / "loop_a").string() + ": skipped: symbolic link loop",
                                      (dir / "loop_b").string() + ": skipped: symbolic link loop",
                                      (dir / "sub/self.glb").string() + ": skipped: symbolic link loop"}));
}

TEST(BatchRunner, ScanListsALinkedFileUnderItsOwnName) {
  const fs::path dir = testing::temp_dir("batch_runner_scan_alias");
  fs::create_directories(dir / "lib/props");
  std::ofstream(dir / "lib/props/crate.obj") << "x";
  std::ofstream(dir / "elsewhere.obj") << "x";
  fs::create_symlink("crate.obj", dir / "lib/props/crate_alias.obj");
  fs::create_symlink("../../elsewhere.obj", dir / "lib/props/shared.obj");  // target outside the library
  EXPECT_EQ(scan_library(dir / "lib").assets,
            (std::vector<std::string>{"props/crate.obj", "props/crate_alias.obj", "props/shared.obj"}));
}

TEST(BatchRunner, ScanSkipsAFolderItCannotOpenWithAWarning) {
  if (::geteuid() == 0) GTEST_SKIP() << "root opens every folder";
  const fs::path dir = testing::temp_dir("batch_runner_scan_locked");
  fs::create_directories(dir / "locked");
  std::ofstream(dir / "locked/hidden.obj") << "x";
  std::ofstream(dir / "a.obj") << "x";
  fs::permissions(dir / "locked", fs::perms::none);
  const LibraryScan scan = scan_library(dir);
  fs::permissions(dir / "locked", fs::perms::owner_all);
  EXPECT_EQ(scan.assets, (std::vector<std::string>{"a.obj"}));
  ASSERT_EQ(scan.skipped.size(), 1u);
  EXPECT_EQ(scan.skipped[0].rfind((dir / "locked").string() + ": skipped: cannot open the folder: ", 0), 0u)
      << scan.skipped[0];
}

TEST(BatchRunner, SymbolicLinkLoopIsSkippedAndTheRestProcessed) {
  const fs::path dir = testing::temp_dir("batch_runner_link_loop");
  const testlib::Library lib = testlib::write_library(dir / "lib", 6);
  fs::create_symlink("b", lib.root / "props/a");
  fs::create_symlink("a", lib.root / "props/b");
  const RunResult r = run(lib.root, dir / "out", 2);
  EXPECT_EQ(r.succeeded, lib.files.size());
  EXPECT_EQ(r.failed, 0u);
  EXPECT_EQ(r.warnings, (std::vector<std::string>{(lib.root / "props/a").string() + ": skipped: symbolic link loop",
                                                  (lib.root / "props/b").string() + ": skipped: symbolic link loop"}));
}

TEST(BatchRunner, ParsesByteSizes) {
  EXPECT_EQ(parse_byte_size("4G"), 4ull << 30);
  EXPECT_EQ(parse_byte_size("512M"), 512ull << 20);
  EXPECT_EQ(parse_byte_size("1.5k"), 1536u);
  EXPECT_EQ(parse_byte_size("100000"), 100000u);
  EXPECT_EQ(parse_byte_size("2GiB"), 2ull << 30);
  for (const char* bad : {"", "G", "-1G", "4X", "abc", "0"})
    EXPECT_THROW(parse_byte_size(bad), std::invalid_argument) << bad;
  EXPECT_GT(default_memory_limit(), 0u);
}

TEST(BatchRunner, FootprintEstimateCoversTheMeasuredPeakInEveryFormat) {
  // The whole chain of an asset peaks at ~560-1100 bytes per input triangle (runner.hpp); the estimate, made from
  // the file size before loading, must not be below that in any format, nor absurdly above it.
  const fs::path dir = testing::temp_dir("batch_runner_footprint");
  const Mesh sphere = testing::make_uv_sphere(100, 100);
  const double triangles = static_cast<double>(sphere.triangle_count());
  for (const auto& [format, name] : std::vector<std::pair<io::Format, std::string>>{{io::Format::glb, "s.glb"},
                                                                                    {io::Format::gltf, "s.gltf"},
                                                                                    {io::Format::obj, "s.obj"},
                                                                                    {io::Format::ply, "s.ply"},
                                                                                    {io::Format::off, "s.off"},
                                                                                    {io::Format::stl, "s.stl"}}) {
    io::save_asset(testlib::asset_of({sphere}, format), dir / name);
    const double per_triangle = double(estimate_footprint(dir / name) - kFootprintOverhead) / triangles;
    EXPECT_GE(per_triangle, 1100.0) << name;
    EXPECT_LE(per_triangle, 5000.0) << name;
  }
  EXPECT_EQ(estimate_footprint(dir / "missing.obj"), kFootprintOverhead);
}

// A timeout no asset can meet: every asset fails in its first stage, nothing of any is written, and the run
// still ends normally with a valid report. Cache hits are finished work: the same timeout fails none of them.
TEST(BatchRunner, TinyAssetTimeoutFailsEveryAssetAndWritesNothing) {
  const fs::path dir = testing::temp_dir("batch_runner_tiny_timeout");
  const testlib::Library lib = testlib::write_library(dir / "lib", 10);
  BatchConfig tiny = config();
  tiny.limits.asset_timeout_s = 1e-6;
  const RunResult r = run_batch(tiny, {.input_dir = lib.root, .output_dir = dir / "out", .jobs = 2});
  EXPECT_EQ(r.failed, lib.files.size());
  EXPECT_EQ(r.succeeded, 0u);
  for (const std::string& f : r.failures) {
    EXPECT_NE(f.find(": timed out in the fingerprint stage (asset timeout 1e-06 s)"), std::string::npos) << f;
  }
  EXPECT_TRUE(check_report(r.report).empty());
  EXPECT_EQ(r.report["effective_config"]["defaults"]["asset_timeout_s"], 1e-6);
  EXPECT_TRUE(testlib::read_outputs(dir / "out").empty());
  EXPECT_TRUE(testlib::leftovers(dir / "out").empty());

  ASSERT_EQ(run(lib.root, dir / "out", 2).succeeded, lib.files.size());
  const RunResult hits = run_batch(tiny, {.input_dir = lib.root, .output_dir = dir / "out", .jobs = 2});
  EXPECT_EQ(hits.cache_hits, lib.files.size());
  EXPECT_EQ(hits.failed, 0u);
}

// One asset held in a stage past the timeout (the stage hook sleeps) fails naming that stage, nothing of it is
// written, and every other asset completes; failures are not cached, so a run without the limit builds it.
TEST(BatchRunner, AssetTimeoutFailsOnlyTheSlowAssetWithTheStageItWasIn) {
  const fs::path dir = testing::temp_dir("batch_runner_timeout");
  const testlib::Library lib = testlib::write_library(dir / "lib", 8);
  const std::string slow = "props/prop_0.obj";
  BatchConfig limited = config();
  // The slow asset's deadline passes as it enters `stage` (a testing aid, no clock: a real one made the test
  // depend on the machine's load); the limit is long enough that no other asset comes near it.
  limited.limits.asset_timeout_s = 600.0;
  for (const std::string stage : {"load", "simplify", "evaluate", "write"}) {
    SCOPED_TRACE(stage);
    const fs::path out = dir / ("out_" + stage);
    RunOptions options{.input_dir = lib.root, .output_dir = out, .jobs = 2};
    options.expire_on_stage = [&](const std::string& path, const char* entered) {
      return path == slow && entered == stage;
    };
    const RunResult r = run_batch(limited, options);
    EXPECT_EQ(r.succeeded, lib.files.size() - 1);
    ASSERT_EQ(r.failures.size(), 1u);
    const std::string reason = "timed out in the " + stage + " stage (asset timeout 600 s)";
    EXPECT_EQ(r.failures[0], slow + ": " + reason);
    const Json& record = record_of(r.report, slow);
    EXPECT_EQ(record["status"], "failed");
    EXPECT_EQ(record["error"], reason);
    EXPECT_TRUE(record["outputs"].empty());
    EXPECT_TRUE(check_report(r.report).empty());
    for (const auto& [file, bytes] : testlib::read_outputs(out)) {
      EXPECT_NE(file.rfind("props/prop_0", 0), 0u) << file << ": nothing of the timed-out asset";
    }
    EXPECT_TRUE(fs::exists(out / "props/kitchen/prop_1_LOD1.stl")) << "the others completed";
    EXPECT_TRUE(testlib::leftovers(out).empty());
    const RunResult again = run(lib.root, out, 2);
    EXPECT_EQ(again.succeeded, lib.files.size());
    EXPECT_EQ(again.cache_hits, lib.files.size() - 1);
  }
}

// An asset that reads as past its deadline only once its first simplify() call has started (testing aid: no
// clock involved) is stopped by the engine itself and fails naming the simplify stage; the others complete.
TEST(BatchRunner, AssetTimeoutInterruptsSimplify) {
  const fs::path dir = testing::temp_dir("batch_runner_timeout_simplify");
  const testlib::Library lib = testlib::write_library(dir / "lib", 8);
  const std::string slow = "props/prop_0.obj";
  BatchConfig limited = config();
  limited.limits.asset_timeout_s = 3600.0;
  RunOptions options{.input_dir = lib.root, .output_dir = dir / "out", .jobs = 2};
  options.expire_in_simplify = slow;
  const RunResult r = run_batch(limited, options);
  EXPECT_EQ(r.succeeded, lib.files.size() - 1);
  ASSERT_EQ(r.failures.size(), 1u);
  const std::string reason = "timed out in the simplify stage (asset timeout 3600 s)";
  EXPECT_EQ(r.failures[0], slow + ": " + reason);
  const Json& record = record_of(r.report, slow);
  EXPECT_EQ(record["status"], "failed");
  EXPECT_EQ(record["error"], reason);
  EXPECT_TRUE(check_report(r.report).empty());
  for (const auto& [file, bytes] : testlib::read_outputs(dir / "out")) {
    EXPECT_NE(file.rfind("props/prop_0", 0), 0u) << file << ": nothing of the timed-out asset";
  }
  EXPECT_TRUE(testlib::leftovers(dir / "out").empty());
  // Not cached: the next run builds it.
  const RunResult again = run(lib.root, dir / "out", 2);
  EXPECT_EQ(again.succeeded, lib.files.size());
  EXPECT_EQ(again.cache_hits, lib.files.size() - 1);
}

TEST(BatchRunner, TightMemoryLimitStillFinishes) {
  // A budget below one asset's footprint admits one asset at a time, and everything still runs.
  const fs::path dir = testing::temp_dir("batch_runner_memory");
  const testlib::Library lib = testlib::write_library(dir / "lib", 20);
  const RunResult r =
      run_batch(config(), {.input_dir = lib.root, .output_dir = dir / "out", .jobs = 2, .memory_limit_bytes = 1});
  EXPECT_EQ(r.succeeded, lib.files.size());
}

}  // namespace
}  // namespace lodforge::batch

namespace lodforge::batch {
namespace {

// Where the LOD `level` of the asset `rel` goes in the output folder.
std::string lod_output(const std::string& rel, std::size_t level) {
  return (fs::path(rel).parent_path() / lod_file_name(rel, level)).generic_string();
}

// A config whose props class makes `levels` LODs (the others as in the fixture).
BatchConfig props_levels(int levels) {
  Json j = Json::parse(testlib::config_text());
  Json lods = Json::array();
  for (int k = 0; k < levels; ++k) lods.push_back({{"ratio", 0.5 / (k + 1)}});
  j["classes"][0]["lods"] = lods;
  return parse_config(j, "test config");
}

TEST(BatchPlan, NamesClassTargetsAndRebuildsAndWritesNothing) {
  const fs::path dir = testing::temp_dir("batch_plan");
  const testlib::Library lib = testlib::write_library(dir / "lib", 10);
  fs::create_directories(lib.root / "misc");
  std::ofstream(lib.root / "misc/extra.obj") << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  const RunOptions options{.input_dir = lib.root, .output_dir = dir / "out", .jobs = 2};
  const Plan before = plan_batch(config(), options);
  EXPECT_FALSE(fs::exists(dir / "out")) << "a plan writes nothing";
  ASSERT_EQ(before.assets.size(), lib.files.size() + 1);
  for (const PlannedAsset& a : before.assets) {
    if (a.path == "misc/extra.obj") {
      EXPECT_TRUE(a.class_name.empty());
      EXPECT_FALSE(a.rebuild);
      EXPECT_NE(a.reason.find("matches no class"), std::string::npos) << a.reason;
      continue;
    }
    EXPECT_TRUE(a.rebuild) << a.path;
    EXPECT_EQ(a.reason, "not built yet") << a.path;
    if (a.path.rfind("props/", 0) == 0) {
      EXPECT_EQ(a.class_name, "props");
      EXPECT_EQ(a.lods, (std::vector<std::string>{"ratio 0.5", "ratio 0.25", "ratio 0.1"}));
    }
    if (a.path.rfind("chars/", 0) == 0) {
      EXPECT_EQ(a.lods.back(), "max_error 0.03") << a.path;
    }
  }
  run(lib.root, dir / "out", 2);
  const Plan after = plan_batch(config(), options);
  for (const PlannedAsset& a : after.assets) EXPECT_FALSE(a.rebuild) << a.path << ": " << a.reason;
  // An edited input and a changed class are rebuilt; a deleted output too.
  const std::string edited = lib.files.front();
  std::ofstream(lib.root / edited, std::ios::app) << "\n";
  const std::string unwritten = *std::find_if(lib.files.begin(), lib.files.end(),
                                              [](const std::string& p) { return p.rfind("env/", 0) == 0; });
  ASSERT_TRUE(fs::remove(dir / "out" / lod_output(unwritten, 1)));
  const Plan changed = plan_batch(props_levels(2), options);
  for (const PlannedAsset& a : changed.assets) {
    if (a.path == edited || a.path.rfind("props/", 0) == 0) {
      EXPECT_EQ(a.reason, "input or config changed") << a.path;
    } else if (a.path == unwritten) {
      EXPECT_EQ(a.reason, "an output is missing") << a.path;
    } else if (!a.class_name.empty()) {
      EXPECT_FALSE(a.rebuild) << a.path << ": " << a.reason;
    }
  }
}

TEST(BatchPrune, StaleOutputsAreListedAndRemovedOnlyWithPrune) {
  const fs::path dir = testing::temp_dir("batch_prune");
  const testlib::Library lib = testlib::write_library(dir / "lib", 10);
  const fs::path out = dir / "out";
  ASSERT_TRUE(run(lib.root, out, 2).stale_outputs.empty());
  std::ofstream(out / "notes.txt") << "not an output: never judged";

  // A removed asset, a LOD the config dropped, and a failing asset whose last good outputs stay.
  const std::string removed = "props/prop_0.obj", failing = "env/patch_4.off";
  ASSERT_TRUE(fs::exists(lib.root / removed) && fs::exists(lib.root / failing));
  const std::vector<std::string> failing_outputs = [&] {
    std::vector<std::string> v;
    for (const auto& e : fs::recursive_directory_iterator(out / "env")) {
      const std::string rel = e.path().lexically_relative(out).generic_string();
      if (rel.rfind("env/patch_4", 0) == 0) v.push_back(rel);
    }
    return v;
  }();
  ASSERT_FALSE(failing_outputs.empty());
  fs::remove(lib.root / removed);
  std::ofstream(lib.root / failing) << "OFF\n3 1 0\n0 0 0\n";  // truncated
  const RunResult listed = run(lib.root, out, 2, props_levels(2));
  std::vector<std::string> expected;
  for (int k = 1; k <= 3; ++k) expected.push_back(lod_output(removed, k));
  for (std::size_t k = 0; k <= 3; ++k) expected.push_back(picture_file_name(removed, k));  // where drawn
  for (const std::string& p : lib.files) {
    if (p.rfind("props/", 0) == 0 && p != removed) expected.push_back(lod_output(p, 3));
  }
  // glTF-family props keep one file (MSFT_lod); only the per-file formats lose their third LOD file.
  std::erase_if(expected, [&](const std::string& f) { return !fs::exists(out / f); });
  std::sort(expected.begin(), expected.end());
  ASSERT_FALSE(expected.empty());
  EXPECT_EQ(listed.stale_outputs, expected);
  EXPECT_EQ(listed.report["stale_outputs"], Json(expected));
  EXPECT_FALSE(listed.pruned);
  for (const std::string& f : expected) EXPECT_TRUE(fs::exists(out / f)) << f << " removed without --prune";

  RunOptions prune{.input_dir = lib.root, .output_dir = out, .jobs = 2};
  prune.prune = true;
  const RunResult pruned = run_batch(props_levels(2), prune);
  EXPECT_EQ(pruned.stale_outputs, expected);
  EXPECT_TRUE(pruned.pruned);
  for (const std::string& f : expected) EXPECT_FALSE(fs::exists(out / f)) << f;
  for (const std::string& f : failing_outputs) EXPECT_TRUE(fs::exists(out / f)) << f << ": a failure keeps its outputs";
  EXPECT_TRUE(fs::exists(out / "notes.txt"));
  const Cache cache(out, "0-of-1");
  const std::vector<std::string> entries = cache.entry_paths();
  EXPECT_EQ(std::count(entries.begin(), entries.end(), removed), 0) << "the removed asset's cache entry goes too";
  EXPECT_TRUE(run_batch(props_levels(2), prune).stale_outputs.empty());
}

// The report's pictures of an asset that left the library are stale too; the others' stay.
TEST(BatchPrune, PicturesOfRemovedAssetsAreStale) {
  const fs::path dir = testing::temp_dir("batch_prune_pictures");
  const testlib::Library lib = testlib::write_library(dir / "lib", 6);
  const fs::path out = dir / "out";
  BatchConfig cfg = config();
  cfg.report.pictures = ReportPictures::on;
  ASSERT_TRUE(run(lib.root, out, 2, cfg).stale_outputs.empty());
  const std::string removed = lib.files.front(), kept = lib.files.back();
  ASSERT_TRUE(fs::exists(out / picture_file_name(removed, 1))) << "pictures are on";
  ASSERT_TRUE(fs::exists(out / picture_file_name(kept, 1)));
  std::ofstream(out / kPictureFolder / "notes.txt") << "not a picture: never judged";
  fs::remove(lib.root / removed);
  const RunResult listed = run(lib.root, out, 2, cfg);
  std::vector<std::string> pictures;
  for (const std::string& f : listed.stale_outputs) {
    if (f.starts_with(std::string(kPictureFolder) + "/")) pictures.push_back(f);
  }
  ASSERT_FALSE(pictures.empty());
  for (const std::string& f : pictures) {
    EXPECT_EQ(f.rfind(std::string(kPictureFolder) + "/" + removed + "/lod", 0), 0u) << f;
    EXPECT_TRUE(fs::exists(out / f)) << f << " removed without --prune";
  }
  RunOptions prune{.input_dir = lib.root, .output_dir = out, .jobs = 2};
  prune.prune = true;
  run_batch(cfg, prune);
  for (const std::string& f : pictures) EXPECT_FALSE(fs::exists(out / f)) << f;
  EXPECT_FALSE(fs::exists(out / kPictureFolder / removed)) << "its emptied folder goes too";
  EXPECT_TRUE(fs::exists(out / picture_file_name(kept, 1)));
  EXPECT_TRUE(fs::exists(out / kPictureFolder / "notes.txt"));
}

TEST(BatchPrune, ALibraryInsideTheOutputFolderIsNeverStale) {
  const fs::path dir = testing::temp_dir("batch_prune_library_inside");
  const testlib::Library lib = testlib::write_library(dir / "out/lib", 6);
  RunOptions prune{.input_dir = lib.root, .output_dir = dir / "out", .jobs = 2};
  prune.prune = true;
  const RunResult r = run_batch(config(), prune);
  EXPECT_TRUE(r.stale_outputs.empty()) << r.stale_outputs.front();
  for (const std::string& f : lib.files) EXPECT_TRUE(fs::exists(lib.root / f)) << f;
}

}  // namespace
}  // namespace lodforge::batch
