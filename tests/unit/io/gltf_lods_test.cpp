// save_gltf_lods: one glTF whose nodes carry their LODs through MSFT_lod. The layout is checked on the JSON,
// the LOD meshes by reading the file back, and validity by the Khronos validator (skipped without node).
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "lodforge/io/asset.hpp"
#include "lodforge/io/file.hpp"
#include "lodforge/io/lods.hpp"
#include "test_support.hpp"

namespace lodforge::io {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

Json document(const fs::path& file) {
  std::string bytes = read_file(file);
  if (file.extension() == ".glb") {
    std::uint32_t length = 0;
    std::memcpy(&length, bytes.data() + 12, 4);
    bytes = bytes.substr(20, length);
  }
  return Json::parse(bytes);
}

// A stand-in for a simplified mesh: the same mesh with only every `keep`-th face (same wedges and attributes,
// which is what a LOD of the mesh may reference).
Mesh thinned(const Mesh& m, std::size_t keep) {
  Mesh out = m;
  out.face_offsets.assign(1, 0);
  out.corner_wedge.clear();
  out.face_material.clear();
  if (!out.face_group.empty()) out.face_group.clear();
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    if (f % keep != 0) continue;
    out.corner_wedge.insert(out.corner_wedge.end(), m.corner_wedge.begin() + m.face_offsets[f],
                            m.corner_wedge.begin() + m.face_offsets[f + 1]);
    out.face_offsets.push_back(static_cast<std::uint32_t>(out.corner_wedge.size()));
    out.face_material.push_back(m.face_material[f]);
    if (!m.face_group.empty()) out.face_group.push_back(m.face_group[f]);
  }
  return out;
}

LodChain chain_of(const Asset& a, std::vector<std::size_t> keeps, std::vector<double> coverage) {
  LodChain chain;
  for (const std::size_t keep : keeps) {
    std::vector<Mesh> level;
    for (const Mesh& m : a.meshes) level.push_back(thinned(m, keep));
    chain.levels.push_back(std::move(level));
  }
  chain.screen_coverage = std::move(coverage);
  return chain;
}

std::string validator_unavailable() {
  if (std::system("node --version > /dev/null 2>&1") != 0) return "node is not installed";
  const fs::path module = std::getenv("LODFORGE_GLTF_VALIDATOR")
                              ? fs::path(std::getenv("LODFORGE_GLTF_VALIDATOR"))
                              : fs::path(LODFORGE_SOURCE_DIR) / "tools/node/node_modules/gltf-validator";
  std::error_code ec;
  return fs::exists(module / "package.json", ec) ? "" : "gltf-validator not found (scripts/setup.sh installs it)";
}

// Exit code of the validator script (0: no errors beyond those `baseline` already has) and its output.
std::pair<int, std::string> validate(const fs::path& file, const fs::path& baseline = {}) {
  std::string cmd = "node '" + (fs::path(LODFORGE_SOURCE_DIR) / "tests/support/validate_gltf.mjs").string() + "'";
  if (!baseline.empty()) cmd += " --baseline '" + baseline.string() + "'";
  cmd += " '" + file.string() + "' 2>&1";
  std::string out;
  FILE* pipe = popen(cmd.c_str(), "r");
  if (!pipe) return {-1, "popen failed"};
  char buf[4096];
  std::size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, pipe)) > 0) out.append(buf, n);
  const int status = pclose(pipe);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
}

TEST(GltfLods, NodesNameTheirLodsAndCoverage) {
  const fs::path dir = testing::temp_dir("gltf_lods_basic");
  Asset a;
  a.format = Format::obj;
  a.meshes.push_back(testing::make_uv_sphere(12, 16));
  a.meshes[0].name = "ball";
  a.meshes.push_back(testing::make_cube_quads());
  const LodChain chain = chain_of(a, {2, 4}, {0.5, 0.2, 0.0});
  for (const char* name : {"lods.glb", "lods.gltf"}) {
    SCOPED_TRACE(name);
    save_gltf_lods(a, chain, dir / name);
    const Json doc = document(dir / name);
    EXPECT_EQ(doc["extensionsUsed"], Json::array({"MSFT_lod"}));
    EXPECT_FALSE(doc.contains("extensionsRequired")) << "readers without MSFT_lod still show LOD0";
    ASSERT_EQ(doc["meshes"].size(), 6u);
    EXPECT_EQ(doc["meshes"][2]["name"], "ball_LOD1");
    EXPECT_EQ(doc["scenes"][0]["nodes"], Json::array({0, 1})) << "LOD nodes are not scene roots";
    for (int n = 0; n < 2; ++n) {
      const Json& node = doc["nodes"][n];
      const Json& ids = node["extensions"]["MSFT_lod"]["ids"];
      ASSERT_EQ(ids.size(), 2u);
      EXPECT_EQ(node["extras"]["MSFT_screencoverage"], Json::array({0.5, 0.2, 0.0}));
      for (int k = 0; k < 2; ++k) {
        const Json& lod = doc["nodes"][ids[k].get<std::size_t>()];
        EXPECT_EQ(lod["mesh"], 2 + 2 * k + n) << "LOD k+1 of mesh n";
      }
    }
    EXPECT_EQ(doc["nodes"][2]["name"], "ball_LOD1");
    // Read back: the LOD meshes are ordinary glTF meshes with the LODs' triangles.
    const Asset back = load_asset(dir / name);
    ASSERT_EQ(back.meshes.size(), 6u);
    EXPECT_EQ(back.meshes[0].triangle_count(), a.meshes[0].triangle_count());
    EXPECT_EQ(back.meshes[2].triangle_count(), chain.levels[0][0].triangle_count());
    EXPECT_EQ(back.meshes[5].triangle_count(), chain.levels[1][1].triangle_count());
  }
  EXPECT_TRUE(fs::exists(dir / "lods.bin"));
  if (const std::string why = validator_unavailable(); !why.empty()) GTEST_SKIP() << why;
  for (const char* name : {"lods.glb", "lods.gltf"}) {
    const auto [code, out] = validate(dir / name);
    EXPECT_EQ(code, 0) << out;
  }
}

// A level marked shows_previous gets its LOD node but no mesh of its own: the node shows the level before's
// (LOD0's for the first level), so a near-copy is not stored twice.
TEST(GltfLods, NearCopyLevelsShowThePreviousMesh) {
  const fs::path dir = testing::temp_dir("gltf_lods_reuse");
  Asset a;
  a.format = Format::obj;
  a.meshes.push_back(testing::make_uv_sphere(12, 16));
  LodChain chain = chain_of(a, {1, 2, 2}, {0.6, 0.5, 0.2, 0.0});
  chain.shows_previous = {true, false, true};
  save_gltf_lods(a, chain, dir / "reuse.glb");
  const Json doc = document(dir / "reuse.glb");
  ASSERT_EQ(doc["meshes"].size(), 2u) << "LOD0 and the one level of its own";
  const Json& ids = doc["nodes"][0]["extensions"]["MSFT_lod"]["ids"];
  ASSERT_EQ(ids.size(), 3u) << "every level keeps its node";
  EXPECT_EQ(doc["nodes"][ids[0].get<std::size_t>()]["mesh"], 0);
  EXPECT_EQ(doc["nodes"][ids[1].get<std::size_t>()]["mesh"], 1);
  EXPECT_EQ(doc["nodes"][ids[2].get<std::size_t>()]["mesh"], 1);
  if (const std::string why = validator_unavailable(); !why.empty()) GTEST_SKIP() << why;
  const auto [code, out] = validate(dir / "reuse.glb");
  EXPECT_EQ(code, 0) << out;
}

TEST(GltfLods, RejectsChainsThatDoNotFit) {
  const fs::path dir = testing::temp_dir("gltf_lods_errors");
  Asset a;
  a.meshes.push_back(testing::make_tetrahedron());
  const LodChain ok = chain_of(a, {2}, {0.3, 0.0});
  EXPECT_THROW(save_gltf_lods(a, ok, dir / "x.obj"), IoError);
  LodChain wrong_count = ok;
  wrong_count.levels[0].push_back(testing::make_tetrahedron());
  EXPECT_THROW(save_gltf_lods(a, wrong_count, dir / "x.glb"), IoError);
  EXPECT_THROW(save_gltf_lods(a, chain_of(a, {2}, {0.3}), dir / "x.glb"), IoError);
  EXPECT_THROW(save_gltf_lods(a, chain_of(a, {2}, {0.3, 0.5}), dir / "x.glb"), IoError) << "must not increase";
  EXPECT_THROW(save_gltf_lods(a, chain_of(a, {2}, {1.5, 0.0}), dir / "x.glb"), IoError);
  EXPECT_FALSE(fs::exists(dir / "x.glb"));
  save_gltf_lods(a, ok, dir / "x.glb");
  EXPECT_TRUE(fs::exists(dir / "x.glb"));
}

TEST(GltfLods, EmptyChainWritesThePlainAsset) {
  const fs::path dir = testing::temp_dir("gltf_lods_empty");
  Asset a;
  a.meshes.push_back(testing::make_tetrahedron());
  save_gltf_lods(a, LodChain{.levels = {}, .screen_coverage = {0.0}, .shows_previous = {}, .separate = {}}, dir / "x.glb");
  const Json doc = document(dir / "x.glb");
  EXPECT_EQ(doc["meshes"].size(), 1u);
  EXPECT_EQ(doc["nodes"][0]["extensions"]["MSFT_lod"]["ids"], Json::array());
}

// Corpus documents keep everything else (skins, morph targets, materials, shared meshes, external images), and
// LOD nodes copy what their mesh still supports.
TEST(GltfLods, CorpusAssetsStayValid) {
  const char* const kFiles[] = {"gltf/CesiumMilkTruck.glb", "skinned/CesiumMan.glb", "gltf/MorphStressTest.gltf",
                                "gltf/FlightHelmet/FlightHelmet.gltf", "skinned/Fox.glb"};
  const fs::path dir = testing::temp_dir("gltf_lods_corpus");
  const bool validator = validator_unavailable().empty();
  std::size_t tested = 0;
  for (const char* rel : kFiles) {
    const fs::path source = testing::corpus_path(rel);
    if (source.empty()) continue;
    SCOPED_TRACE(rel);
    ++tested;
    const Asset a = load_asset(source);
    const fs::path out = dir / fs::path(rel).filename();
    save_gltf_lods(a, chain_of(a, {2, 5}, {0.4, 0.1, 0.0}), out);
    const Json doc = document(out), src = document(source);
    EXPECT_EQ(doc["meshes"].size(), 3 * src["meshes"].size());
    std::size_t mesh_nodes = 0, lod_nodes = 0;
    for (std::size_t n = 0; n < src["nodes"].size(); ++n) {
      const Json& node = doc["nodes"][n];
      if (!src["nodes"][n].contains("mesh")) {
        EXPECT_FALSE(node.contains("extensions") && node["extensions"].contains("MSFT_lod"));
        continue;
      }
      ++mesh_nodes;
      const Json& ids = node["extensions"]["MSFT_lod"]["ids"];
      ASSERT_EQ(ids.size(), 2u);
      for (const Json& id : ids) {
        const Json& lod = doc["nodes"][id.get<std::size_t>()];
        ++lod_nodes;
        EXPECT_EQ(lod.contains("skin"), node.contains("skin"));
        for (const char* key : {"translation", "rotation", "scale", "matrix"}) {
          EXPECT_EQ(lod.contains(key), node.contains(key));
          if (node.contains(key)) {
            EXPECT_EQ(lod[key], node[key]);
          }
        }
      }
    }
    EXPECT_EQ(doc["nodes"].size(), src["nodes"].size() + lod_nodes);
    EXPECT_EQ(lod_nodes, 2 * mesh_nodes);
    // Everything else survives.
    for (const char* key : {"skins", "animations", "materials", "textures"}) {
      EXPECT_EQ(doc.contains(key) ? doc[key].size() : 0, src.contains(key) ? src[key].size() : 0) << key;
    }
    if (validator) {
      const auto [code, output] = validate(out, source);
      EXPECT_EQ(code, 0) << output;
    }
  }
  if (tested == 0) GTEST_SKIP() << "corpus absent (../shared/corpus)";
  if (!validator) GTEST_SKIP() << validator_unavailable();
}

}  // namespace
}  // namespace lodforge::io
