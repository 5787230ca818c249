// Height maps in `lodforge run`: a terrain class takes the PNG and .r16 files it matches and writes one glTF
// of stitched patches with MSFT_lod levels; PNGs no terrain class takes stay textures, .r16 files unsupported;
// the sidecar joins the cache key; ratio targets count the surface; terrain classes are checked.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "heightmap_fixtures.hpp"
#include "library_fixture.hpp"
#include "lodforge/batch/config.hpp"
#include "lodforge/batch/runner.hpp"
#include "lodforge/io/asset.hpp"
#include "lodforge/io/file.hpp"
#include "lodforge/io/heightmap.hpp"

namespace lodforge::batch {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

// A 97 x 65 raw map of rolling hills (its size from the name), and a 16-bit PNG of 65 x 65.
void write_maps(const fs::path& root) {
  fs::create_directories(root / "terrain");
  testing::write_hills_r16(root / "terrain");
  io::HeightMap png;
  png.width = png.height = 65;
  for (int r = 0; r < 65; ++r) {
    for (int c = 0; c < 65; ++c) png.samples.push_back(static_cast<std::uint16_t>(2000 + 40 * c + 7 * ((r * c) % 5)));
  }
  io::save_heightmap_png(png, root / "terrain/ramp.png");
}

BatchConfig terrain_config() {
  return parse_config(Json::parse(R"({
    "version": 1,
    "classes": [
      {"name": "terrain", "match": ["terrain/**"],
       "terrain": {"patch_cells": 32, "spacing": 2, "height_scale": 0.01},
       "lods": [{"ratio": 0.25}, {"ratio": 0.0625}]},
      {"name": "props", "match": ["**"], "lods": [{"ratio": 0.5}]}
    ]})"),
                      "test config");
}

const Json& record_of(const Json& report, const std::string& path) {
  for (const Json& a : report["assets"]) {
    if (a["path"] == path) return a;
  }
  static const Json none;
  ADD_FAILURE() << "no record for " << path;
  return none;
}

TEST(TerrainRunner, HeightMapsBecomeGltfPatchChains) {
  const fs::path dir = testing::temp_dir("terrain_runner");
  const fs::path lib = dir / "lib";
  write_maps(lib);
  // A PNG beside a mesh, under a class without "terrain": a texture, neither an asset nor unsupported.
  fs::create_directories(lib / "props");
  io::save_asset(testlib::asset_of({testing::make_uv_sphere(8, 12)}, io::Format::obj), lib / "props/ball.obj");
  io::HeightMap tex;
  tex.width = tex.height = 4;
  tex.samples.assign(16, 7);
  io::save_heightmap_png(tex, lib / "props/ball.png");

  const RunResult r = run_batch(terrain_config(), {.input_dir = lib, .output_dir = dir / "out", .jobs = 2});
  ASSERT_EQ(r.failed, 0u) << (r.failures.empty() ? "" : r.failures.front());
  EXPECT_EQ(r.succeeded, 3u);  // the two maps and the ball
  EXPECT_TRUE(std::find(r.unsupported.begin(), r.unsupported.end(), "props/ball.png") == r.unsupported.end());
  EXPECT_TRUE(fs::exists(dir / "out/terrain/hills_97x65.glb"));
  EXPECT_TRUE(fs::exists(dir / "out/terrain/ramp.glb"));

  const Json& hills = record_of(r.report, "terrain/hills_97x65.r16");
  EXPECT_EQ(hills["class"], "terrain");
  EXPECT_EQ(hills["terrain"]["patches"], Json::array({3, 2}));
  const auto surface = hills["terrain"]["surface_triangles"].get<std::vector<std::size_t>>();
  ASSERT_EQ(surface.size(), 3u);
  EXPECT_EQ(surface[0], 2u * 96 * 64);
  ASSERT_EQ(hills["lods"].size(), 2u);
  for (std::size_t k = 0; k < 2; ++k) {
    const Json& lod = hills["lods"][k];
    // The target counts the surface (the skirts come on top of it), so a reached ratio is met.
    EXPECT_EQ(lod["target_triangles"], std::llround((k == 0 ? 0.25 : 0.0625) * double(surface[0])));
    EXPECT_GT(lod["triangles"].get<std::size_t>(), surface[k + 1]);  // skirts
    EXPECT_LE(double(surface[k + 1]), std::ceil(1.02 * lod["target_triangles"].get<double>()));
    EXPECT_EQ(lod["budget"]["status"], "met") << lod["budget"].dump();
  }
  const io::Asset out = io::load_asset(dir / "out/terrain/hills_97x65.glb");
  EXPECT_EQ(out.meshes.size(), 18u);  // 6 patches x (LOD0 + 2 levels)
  const std::string json = io::read_file(dir / "out/terrain/hills_97x65.glb");
  EXPECT_NE(json.find("MSFT_lod"), std::string::npos);
  // Pictures of every level, drawn from above.
  EXPECT_EQ(hills["pictures"].size(), 3u);
}

TEST(TerrainRunner, SidecarJoinsTheCacheKey) {
  const fs::path dir = testing::temp_dir("terrain_runner_cache");
  const fs::path lib = dir / "lib";
  write_maps(lib);
  const BatchConfig cfg = terrain_config();
  RunResult r = run_batch(cfg, {.input_dir = lib, .output_dir = dir / "out", .jobs = 2});
  ASSERT_EQ(r.succeeded, 2u);
  r = run_batch(cfg, {.input_dir = lib, .output_dir = dir / "out", .jobs = 2});
  EXPECT_EQ(r.cache_hits, 2u);
  // A sidecar beside the PNG changes its spacing: that map is rebuilt, the other is not.
  io::write_file_atomic(lib / "terrain/ramp.png.json", R"({"spacing": 5})");
  r = run_batch(cfg, {.input_dir = lib, .output_dir = dir / "out", .jobs = 2});
  EXPECT_EQ(r.cache_hits, 1u);
  EXPECT_EQ(r.succeeded, 2u);
  EXPECT_NEAR(record_of(r.report, "terrain/ramp.png")["input"]["diagonal"].get<double>(),
              std::hypot(64 * 5.0, 64 * 5.0, 0.01 * 40 * 64 + 0.01 * 28), 0.5);
  // The sidecar is the map's companion, not an unsupported file.
  EXPECT_TRUE(std::find(r.unsupported.begin(), r.unsupported.end(), "terrain/ramp.png.json") == r.unsupported.end());
}

TEST(TerrainRunner, AChangedRegionRebuildsOnlyItsPatchesAcrossRuns) {
  const fs::path dir = testing::temp_dir("terrain_runner_patches");
  const fs::path lib = dir / "lib";
  write_maps(lib);
  const BatchConfig cfg = terrain_config();
  RunResult r = run_batch(cfg, {.input_dir = lib, .output_dir = dir / "out", .jobs = 2});
  ASSERT_EQ(r.succeeded, 2u);
  EXPECT_EQ(record_of(r.report, "terrain/hills_97x65.r16")["terrain"]["rebuilt_patches"], 6);
  // A bump inside patch (1, 1) of the raw map (samples 40..55 both ways), away from its walls.
  const fs::path raw = lib / "terrain/hills_97x65.r16";
  std::string bytes = io::read_file(raw);
  for (std::size_t row = 40; row < 56; ++row) {
    for (std::size_t c = 40; c < 56; ++c)
      bytes[2 * (row * 97 + c) + 1] = static_cast<char>(bytes[2 * (row * 97 + c) + 1] + 2);
  }
  io::write_file_atomic(raw, bytes);
  r = run_batch(cfg, {.input_dir = lib, .output_dir = dir / "out", .jobs = 2});
  EXPECT_EQ(r.cache_hits, 1u);  // the PNG
  const Json& hills = record_of(r.report, "terrain/hills_97x65.r16");
  EXPECT_EQ(hills["cache_hit"], false);
  EXPECT_EQ(hills["terrain"]["rebuilt_patches"], 1);
  // The same bytes as a build from nothing.
  r = run_batch(cfg, {.input_dir = lib, .output_dir = dir / "fresh", .jobs = 1});
  EXPECT_EQ(record_of(r.report, "terrain/hills_97x65.r16")["terrain"]["rebuilt_patches"], 6);
  EXPECT_EQ(io::read_file(dir / "out/terrain/hills_97x65.glb"), io::read_file(dir / "fresh/terrain/hills_97x65.glb"));
  // A damaged saved result costs a full build, nothing else (the map changed back, so it is rebuilt).
  for (const auto& e : fs::directory_iterator(dir / "out/.lodforge-cache/terrain")) {
    io::write_file_atomic(e.path(), "lodforge-terrain-result-1\n???");
  }
  write_maps(lib);
  r = run_batch(cfg, {.input_dir = lib, .output_dir = dir / "out", .jobs = 2});
  EXPECT_EQ(r.failed, 0u);
  EXPECT_EQ(record_of(r.report, "terrain/hills_97x65.r16")["cache_hit"], false);
  EXPECT_EQ(record_of(r.report, "terrain/hills_97x65.r16")["terrain"]["rebuilt_patches"], 6);
}

// The saved build of a map that left the library goes with it; the others stay.
TEST(TerrainRunner, SavedBuildsOfRemovedMapsArePruned) {
  const fs::path dir = testing::temp_dir("terrain_runner_prune");
  const fs::path lib = dir / "lib";
  write_maps(lib);
  const BatchConfig cfg = terrain_config();
  ASSERT_EQ(run_batch(cfg, {.input_dir = lib, .output_dir = dir / "out", .jobs = 2}).succeeded, 2u);
  const fs::path saves = dir / "out/.lodforge-cache/terrain";
  auto count = [&] { return std::distance(fs::directory_iterator(saves), fs::directory_iterator()); };
  ASSERT_EQ(count(), 2);
  io::write_file_atomic(saves / "leftover.bin.tmp-1", "x");
  fs::remove(lib / "terrain/hills_97x65.r16");
  const RunResult r = run_batch(cfg, {.input_dir = lib, .output_dir = dir / "out", .jobs = 2});
  EXPECT_EQ(r.succeeded, 1u);
  EXPECT_EQ(r.cache_hits, 1u);  // the PNG
  EXPECT_EQ(count(), 1) << "the removed map's build and the leftover are gone, the PNG's stays";
}

TEST(TerrainRunner, RawMapsNoTerrainClassTakesAreUnsupported) {
  const fs::path dir = testing::temp_dir("terrain_runner_unmatched");
  const fs::path lib = dir / "lib";
  write_maps(lib);
  io::save_asset(testlib::asset_of({testing::make_uv_sphere(8, 12)}, io::Format::obj), lib / "ball.obj");
  const BatchConfig props = parse_config(Json::parse(R"({
    "version": 1, "classes": [{"name": "props", "match": ["**"], "lods": [{"ratio": 0.5}]}]})"));
  const RunResult r = run_batch(props, {.input_dir = lib, .output_dir = dir / "out", .jobs = 2});
  EXPECT_EQ(r.succeeded, 1u);
  EXPECT_EQ(r.unsupported, std::vector<std::string>{"terrain/hills_97x65.r16"});
}

TEST(TerrainRunner, AMeshUnderATerrainClassFailsClearly) {
  const fs::path dir = testing::temp_dir("terrain_runner_mesh");
  const fs::path lib = dir / "lib";
  fs::create_directories(lib / "terrain");
  io::save_asset(testlib::asset_of({testing::make_uv_sphere(8, 12)}, io::Format::obj), lib / "terrain/ball.obj");
  const RunResult r = run_batch(terrain_config(), {.input_dir = lib, .output_dir = dir / "out", .jobs = 1});
  ASSERT_EQ(r.failed, 1u);
  EXPECT_NE(r.failures.front().find("takes height maps"), std::string::npos) << r.failures.front();
}

TEST(TerrainConfig, RefusesWhatATerrainClassCannotDo) {
  const Json doc = Json::parse(R"({
    "version": 1,
    "classes": [{"name": "t", "match": ["**"],
                 "terrain": {"patch_cells": 1, "conservative": "sideways", "spacing": [1], "skrits": true},
                 "lods": [{"ratio": 0.25}, {"triangles": 100}],
                 "collision": {"ratio": 0.1}}]})");
  try {
    parse_config(doc, "t.json");
    FAIL() << "accepted";
  } catch (const ConfigError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("classes[0].terrain.patch_cells"), std::string::npos) << m;
    EXPECT_NE(m.find("classes[0].terrain.conservative"), std::string::npos) << m;
    EXPECT_NE(m.find("classes[0].terrain.spacing"), std::string::npos) << m;
    EXPECT_NE(m.find("skirts"), std::string::npos) << m;  // the typo's suggestion
    EXPECT_NE(m.find("classes[0].lods[1]: a terrain class takes ratio targets only"), std::string::npos) << m;
    EXPECT_NE(m.find("classes[0].collision"), std::string::npos) << m;
  }
}

TEST(TerrainConfig, EffectiveConfigParsesBackToTheSameTerrain) {
  const BatchConfig cfg = terrain_config();
  const BatchConfig again = parse_config(effective_config_json(cfg));
  ASSERT_TRUE(again.classes[0].terrain);
  EXPECT_EQ(again.classes[0].terrain->patch_cells, 32u);
  EXPECT_EQ(again.classes[0].terrain->layout.spacing_x, 2.0);
  EXPECT_EQ(again.classes[0].terrain->layout.height_scale, 0.01);
  EXPECT_EQ(effective_config_json(again), effective_config_json(cfg));
  EXPECT_FALSE(again.classes[1].terrain);
}

}  // namespace
}  // namespace lodforge::batch
