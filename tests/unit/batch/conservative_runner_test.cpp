// Collision and occluder LODs in `lodforge run`: separate outputs beside the render chain (their own files, or
// glTF nodes outside MSFT_lod), that nest with the source, with their own report entries, cached and pruned like
// every output. Tiny closed solids keep it fast.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <vector>

#include "../simplify/conservative_fixtures.hpp"
#include "library_fixture.hpp"
#include "lodforge/batch/config.hpp"
#include "lodforge/batch/report.hpp"
#include "lodforge/batch/runner.hpp"
#include "lodforge/io/asset.hpp"
#include "lodforge/io/file.hpp"

namespace lodforge::batch {
namespace {

namespace fs = std::filesystem;
namespace ct = conservative_test;
using Json = nlohmann::json;

// Closed solids (an OBJ blob, a GLB torus, and a .gltf holding both as two meshes) and one class with a render chain, a collision hull with a
// volume budget and an occluder.
struct Solids {
  fs::path root;
  Mesh blob, ring;
};

Solids write_solids(const fs::path& root) {
  Solids s{root, ct::make_icosphere(3, 0.15, 7), ct::make_torus(24, 12, 1.0, 0.3)};
  fs::create_directories(root / "solids");
  io::save_asset(testlib::asset_of({s.blob}, io::Format::obj), root / "solids/blob.obj");
  io::save_asset(testlib::asset_of({s.ring}, io::Format::glb), root / "solids/ring.glb");
  io::save_asset(testlib::asset_of({s.blob, s.ring}, io::Format::gltf, false), root / "solids/pair.gltf");
  return s;
}

BatchConfig solids_config(const std::string& gltf_lods, bool with_conservative = true) {
  Json doc = Json::parse(R"({
    "version": 1,
    "classes": [{"name": "solids", "match": ["solids/**"], "lods": [{"ratio": 0.5}, {"ratio": 0.25}],
                 "collision": {"ratio": 0.1, "max_volume_growth": 60},
                 "occluder": {"ratio": 0.1}}]
  })");
  doc["defaults"]["gltf_lods"] = gltf_lods;
  if (!with_conservative) {
    doc["classes"][0].erase("collision");
    doc["classes"][0].erase("occluder");
  }
  return parse_config(doc, "test config");
}

const Json& record_of(const Json& report, const std::string& path) {
  for (const Json& a : report["assets"]) {
    if (a["path"] == path) return a;
  }
  static const Json kNone;
  ADD_FAILURE() << "no record for " << path;
  return kNone;
}

const Json& entry_of(const Json& record, const std::string& kind) {
  for (const Json& e : record["conservative_lods"]) {
    if (e["kind"] == kind) return e;
  }
  static const Json kNone;
  ADD_FAILURE() << "no " << kind << " entry";
  return kNone;
}

// The source's vertices all lie inside or on `outer` (generalised winding number), and `inner`'s inside `source`.
void expect_nests(const Mesh& source, const Mesh& collision, const Mesh& occluder) {
  const double tol = 1e-6 * ct::diagonal_of(ct::triangles_of(source));
  EXPECT_EQ(ct::points_outside(ct::test_points(source, 500, 1), ct::triangles_of(collision), tol), 0u)
      << "the collision hull must contain the source";
  EXPECT_EQ(ct::points_outside(ct::test_points(occluder, 500, 2), ct::triangles_of(source), tol), 0u)
      << "the occluder must lie inside the source";
}

bool listed(const Json& outputs, const std::string& file) {
  return std::find(outputs.begin(), outputs.end(), Json(file)) != outputs.end();
}

TEST(BatchConservative, FilesModeWritesNestingCollisionAndOccluderFiles) {
  const fs::path dir = testing::temp_dir("batch_conservative_files");
  const Solids lib = write_solids(dir / "lib");
  const RunResult r = testlib::run(lib.root, dir / "out", 2, solids_config("files"));
  ASSERT_EQ(r.failed, 0u) << (r.failures.empty() ? "" : r.failures.front());
  EXPECT_TRUE(check_report(r.report).empty()) << check_report(r.report).front();
  EXPECT_EQ(r.report["summary"]["conservative_lods"], 6);
  EXPECT_EQ(r.report["summary"]["lods"], 6) << "collision and occluder LODs are no render levels";
  // A .gltf's separate outputs are a .gltf and its buffer each, both listed under the entry.
  EXPECT_EQ(entry_of(record_of(r.report, "solids/pair.gltf"), "collision")["outputs"],
            Json::array({"solids/pair_collision.bin", "solids/pair_collision.gltf"}));
  EXPECT_EQ(io::load_asset(dir / "out/solids/pair_collision.gltf").meshes.size(), 2u);

  struct Case {
    std::string path;
    const Mesh* source;
  };
  for (const Case& c : {Case{"solids/blob.obj", &lib.blob}, Case{"solids/ring.glb", &lib.ring}}) {
    SCOPED_TRACE(c.path);
    const Json& rec = record_of(r.report, c.path);
    ASSERT_EQ(rec["status"], "ok");
    ASSERT_EQ(rec["lods"].size(), 2u);
    const fs::path rel(c.path);
    const std::string folder = rel.parent_path().generic_string() + "/";
    const std::string collision_file = folder + conservative_file_name(rel, ConservativeKind::collision);
    const std::string occluder_file = folder + conservative_file_name(rel, ConservativeKind::occluder);
    EXPECT_TRUE(listed(rec["outputs"], collision_file));
    EXPECT_TRUE(listed(rec["outputs"], occluder_file));

    const Json& col = entry_of(rec, "collision");
    EXPECT_EQ(col["mode"], "bounding");
    EXPECT_EQ(col["outputs"], Json::array({collision_file}));
    EXPECT_TRUE(col["gltf_node_suffix"].is_null());
    EXPECT_EQ(col["target"], (Json{{"kind", "ratio"}, {"value", 0.1}}));
    EXPECT_EQ(col["max_volume_growth_pct"], 60.0);
    ASSERT_TRUE(col["volume_change_pct"].is_number());
    EXPECT_GE(col["volume_change_pct"].get<double>(), 0.0);
    EXPECT_LE(col["volume_change_pct"].get<double>(), 60.0 + 1e-6);
    EXPECT_GT(col["hausdorff_rel"].get<double>(), 0.0);
    EXPECT_LT(col["triangles"].get<std::size_t>(), c.source->triangle_count());
    // Met, or missed only because the volume budget held the count (and said so).
    if (col["budget"]["status"] == "missed") {
      EXPECT_NE(col["budget"]["reasons"][0].get<std::string>().find("volume_budget"), std::string::npos)
          << col["budget"].dump();
    }
    const Json& occ = entry_of(rec, "occluder");
    EXPECT_EQ(occ["mode"], "occluder");
    EXPECT_EQ(occ["outputs"], Json::array({occluder_file}));
    ASSERT_TRUE(occ["volume_change_pct"].is_number());
    EXPECT_LE(occ["volume_change_pct"].get<double>(), 0.0);
    EXPECT_TRUE(occ["max_volume_growth_pct"].is_null());

    const Mesh collision = io::load_asset(dir / "out" / collision_file).meshes.at(0);
    const Mesh occluder = io::load_asset(dir / "out" / occluder_file).meshes.at(0);
    EXPECT_EQ(collision.triangle_count(), col["triangles"].get<std::size_t>());
    expect_nests(io::load_asset(lib.root / c.path).meshes.at(0), collision, occluder);
  }
  // lods.json projects render levels only.
  const std::string manifest = io::read_file(dir / "out/lods.json");
  EXPECT_EQ(manifest.find("collision"), std::string::npos);
  EXPECT_EQ(manifest.find("occluder"), std::string::npos);
}

TEST(BatchConservative, MsftLodModeWritesNodesOutsideTheLodExtension) {
  const fs::path dir = testing::temp_dir("batch_conservative_gltf");
  const Solids lib = write_solids(dir / "lib");
  const RunResult r = testlib::run(lib.root, dir / "out", 2, solids_config("msft_lod"));
  ASSERT_EQ(r.failed, 0u) << (r.failures.empty() ? "" : r.failures.front());
  const Json& rec = record_of(r.report, "solids/ring.glb");
  EXPECT_EQ(rec["outputs"], Json::array({"solids/ring.glb"})) << "one file: the nodes are inside it";
  EXPECT_EQ(entry_of(rec, "collision")["gltf_node_suffix"], "_collision");
  EXPECT_EQ(entry_of(rec, "collision")["outputs"], Json::array());
  // The OBJ asset has no glTF to hold them: its own files as in files mode.
  EXPECT_TRUE(listed(record_of(r.report, "solids/blob.obj")["outputs"], "solids/blob_collision.obj"));

  const fs::path file = dir / "out/solids/ring.glb";
  const Json doc = testlib::gltf_json(file);
  std::set<std::size_t> lod_nodes, roots;
  for (const Json& node : doc["nodes"]) {
    if (node.contains("extensions") && node["extensions"].contains("MSFT_lod")) {
      for (const Json& id : node["extensions"]["MSFT_lod"]["ids"]) lod_nodes.insert(id.get<std::size_t>());
    }
  }
  for (const Json& scene : doc["scenes"]) {
    for (const Json& n : scene["nodes"]) roots.insert(n.get<std::size_t>());
  }
  std::map<std::string, std::size_t> separate;  // output -> node
  for (std::size_t n = 0; n < doc["nodes"].size(); ++n) {
    const Json& node = doc["nodes"][n];
    if (!node.contains("extras") || !node["extras"].contains("lodforge")) continue;
    separate[node["extras"]["lodforge"]["output"].get<std::string>()] = n;
    EXPECT_FALSE(lod_nodes.count(n)) << "a collision or occluder node is no MSFT_lod level";
    EXPECT_FALSE(node.contains("extensions"));
    EXPECT_FALSE(node["extras"].contains("MSFT_screencoverage"));
    EXPECT_TRUE(roots.count(n)) << "placed beside its source node, a root";
  }
  ASSERT_EQ(separate.size(), 2u);
  ASSERT_TRUE(separate.count("collision") && separate.count("occluder"));

  // Two meshes: a collision and an occluder node beside each of their nodes.
  const fs::path pair = dir / "out/solids/pair.gltf";
  const Json pair_doc = testlib::gltf_json(pair);
  std::size_t pair_separate = 0;
  for (const Json& node : pair_doc["nodes"]) pair_separate += node.contains("extras") && node["extras"].contains("lodforge");
  EXPECT_EQ(pair_separate, 4u);
  EXPECT_EQ(entry_of(record_of(r.report, "solids/pair.gltf"), "occluder")["gltf_node_suffix"], "_occluder");

  // The meshes those nodes show nest with the source (load_asset converts the file's glTF meshes in order).
  const io::Asset written = io::load_asset(file);
  auto mesh_of = [&](std::size_t node) {
    return written.meshes.at(doc["nodes"][node]["mesh"].get<std::size_t>());
  };
  expect_nests(lib.ring, mesh_of(separate["collision"]), mesh_of(separate["occluder"]));
  EXPECT_EQ(mesh_of(separate["collision"]).triangle_count(),
            entry_of(rec, "collision")["triangles"].get<std::size_t>());
  if (const std::string why = testlib::gltf_validator_unavailable(); !why.empty()) GTEST_SKIP() << why;
  const auto v = testlib::validate_gltf({file, pair});
  EXPECT_EQ(v.exit_code, 0) << v.output;
}

TEST(BatchConservative, ReRunsAreCacheHitsAndPruneRemovesDroppedOutputs) {
  const fs::path dir = testing::temp_dir("batch_conservative_cache");
  const Solids lib = write_solids(dir / "lib");
  const fs::path out = dir / "out";
  const RunResult first = testlib::run(lib.root, out, 2, solids_config("files"));
  ASSERT_EQ(first.failed, 0u);
  const auto bytes = testlib::read_outputs(out);

  // Same bytes for any thread count.
  const RunResult one = testlib::run(lib.root, dir / "out1", 1, solids_config("files"));
  EXPECT_EQ(testlib::read_outputs(dir / "out1"), bytes);
  EXPECT_EQ(without_timings(one.report)["assets"], without_timings(first.report)["assets"]);

  const RunResult again = testlib::run(lib.root, out, 2, solids_config("files"));
  EXPECT_EQ(again.cache_hits, 3u);
  EXPECT_EQ(without_timings(record_of(again.report, "solids/blob.obj"))["conservative_lods"],
            without_timings(record_of(first.report, "solids/blob.obj"))["conservative_lods"]);

  // A missing collision file rebuilds its asset only.
  fs::remove(out / "solids/blob_collision.obj");
  const RunResult repaired = testlib::run(lib.root, out, 2, solids_config("files"));
  EXPECT_EQ(repaired.cache_hits, 2u);
  EXPECT_EQ(record_of(repaired.report, "solids/blob.obj")["cache_hit"], false);
  EXPECT_TRUE(fs::exists(out / "solids/blob_collision.obj"));

  // A config without them: a new cache key, and their files are stale (removed with --prune).
  const std::vector<std::string> dropped = {"solids/blob_collision.obj",  "solids/blob_occluder.obj",
                                            "solids/pair_collision.bin",  "solids/pair_collision.gltf",
                                            "solids/pair_occluder.bin",   "solids/pair_occluder.gltf",
                                            "solids/ring_collision.glb",  "solids/ring_occluder.glb"};
  const RunResult listed_run = testlib::run(lib.root, out, 2, solids_config("files", false));
  EXPECT_EQ(listed_run.cache_hits, 0u);
  EXPECT_FALSE(record_of(listed_run.report, "solids/blob.obj").contains("conservative_lods"));
  EXPECT_FALSE(listed_run.report["summary"].contains("conservative_lods"));
  EXPECT_EQ(listed_run.stale_outputs, dropped);
  RunOptions prune{.input_dir = lib.root, .output_dir = out, .jobs = 2};
  prune.prune = true;
  const RunResult pruned = run_batch(solids_config("files", false), prune);
  EXPECT_TRUE(pruned.pruned);
  for (const std::string& f : dropped) EXPECT_FALSE(fs::exists(out / f)) << f;
  EXPECT_TRUE(fs::exists(out / "solids/blob_LOD1.obj"));
}

// A class with conservative LODs and an asset they fail on (a timeout in the simplify stage here) fails that
// asset alone, with nothing of it written; the others go on.
TEST(BatchConservative, AFailingAssetFailsAlone) {
  const fs::path dir = testing::temp_dir("batch_conservative_failure");
  const Solids lib = write_solids(dir / "lib");
  BatchConfig cfg = solids_config("files");
  cfg.limits.asset_timeout_s = 1000;
  RunOptions options{.input_dir = lib.root, .output_dir = dir / "out", .jobs = 2};
  options.expire_on_stage = [](const std::string& path, const char* stage) {
    return path == "solids/blob.obj" && std::string(stage) == "simplify";
  };
  const RunResult r = run_batch(cfg, options);
  EXPECT_EQ(r.failed, 1u);
  EXPECT_EQ(r.succeeded, 2u);
  EXPECT_FALSE(record_of(r.report, "solids/blob.obj").contains("conservative_lods"));
  EXPECT_FALSE(fs::exists(dir / "out/solids/blob_collision.obj"));
  EXPECT_TRUE(fs::exists(dir / "out/solids/ring_collision.glb"));
  EXPECT_TRUE(check_report(r.report).empty());
}

}  // namespace
}  // namespace lodforge::batch
