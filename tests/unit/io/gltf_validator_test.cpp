// Everything the glTF writer produces must pass the Khronos glTF validator with zero errors: corpus round trips
// (errors the source itself already has are reported as inherited, see validate_gltf.mjs), documents built for
// assets without a glTF source, and edited meshes. Skips when `node` or the validator module is absent.

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <iterator>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "corpus_assets.hpp"
#include "lodforge/io/asset.hpp"
#include "test_support.hpp"

namespace lodforge::io::gltf_validator_test {
namespace {

namespace fs = std::filesystem;

using ::lodforge::testing::validate_gltf;

// The attribute assets plus three hard-surface glTF files from the Kenney kits.
std::vector<const char*> corpus_files() {
  std::vector<const char*> files(std::begin(::lodforge::testing::kGltfAttributeAssets),
                                 std::end(::lodforge::testing::kGltfAttributeAssets));
  for (const char* f : {"hardsurface/kenney_alien.glb", "hardsurface/kenney_cakeBirthday.glb",
                        "hardsurface/kenney_craft_speederD/craft_speederD.gltf"}) {
    files.push_back(f);
  }
  return files;
}

class GltfValidator : public ::testing::TestWithParam<const char*> {};

std::string case_name(const ::testing::TestParamInfo<const char*>& info) {
  return ::lodforge::testing::test_name_of(info.param);
}

TEST_P(GltfValidator, RoundTripHasNoNewErrors) {
  LODFORGE_REQUIRE_GLTF_VALIDATOR();
  LODFORGE_REQUIRE_CORPUS(src, GetParam());
  const fs::path dir = testing::temp_dir("gltf_validate_" + fs::path(GetParam()).stem().string());
  const Asset a = load_asset(src);
  save_asset(a, dir / "out.glb");
  save_asset(a, dir / "out.gltf");
  const auto r = validate_gltf({dir / "out.glb", dir / "out.gltf"}, src);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  // The per-file summary lines ("N errors, N inherited errors, N warnings ...") for the test log.
  for (std::size_t at = 0; at < r.output.size();) {
    const std::size_t end = std::min(r.output.find('\n', at), r.output.size());
    if (r.output.compare(at, 2, "  ") != 0) std::printf("%s\n", r.output.substr(at, end - at).c_str());
    at = end + 1;
  }
}

INSTANTIATE_TEST_SUITE_P(Corpus, GltfValidator, ::testing::ValuesIn(corpus_files()), case_name);

TEST(GltfValidatorWrite, DocumentBuiltWithoutSourcePasses) {
  LODFORGE_REQUIRE_GLTF_VALIDATOR();
  Asset a;
  a.meshes.push_back(testing::make_cube_quads());
  a.meshes.push_back(testing::make_uv_sphere(8, 12));
  Mesh grid = testing::make_grid(4, 3, true);
  // Streams an OBJ could bring: UVs and (non-unit, as parsed) normals.
  grid.uvs.assign(1, std::vector<Vec2f>(grid.wedge_count()));
  grid.normals.assign(grid.wedge_count(), Vec3f{{0, 0, 2}});
  for (std::size_t w = 0; w < grid.wedge_count(); ++w) {
    const Vec3f& p = grid.positions[grid.wedge_vertex[w]];
    grid.uvs[0][w] = {{p[0] / 4, p[1] / 3}};
  }
  a.meshes.push_back(grid);
  const fs::path dir = testing::temp_dir("gltf_validate_built");
  save_asset(a, dir / "b.gltf");
  save_asset(a, dir / "b.glb");
  const auto r = validate_gltf({dir / "b.gltf", dir / "b.glb"});
  EXPECT_EQ(r.exit_code, 0) << r.output;
}

TEST(GltfValidatorWrite, EditedMeshesPass) {
  LODFORGE_REQUIRE_GLTF_VALIDATOR();
  for (const char* file : {"gltf/CesiumMilkTruck.glb", "skinned/Fox.glb", "gltf/MorphStressTest.gltf"}) {
    SCOPED_TRACE(file);
    LODFORGE_REQUIRE_CORPUS(src, file);
    Asset a = load_asset(src);
    // Keep two faces out of three and nudge normals off unit length (what a simplifier's blending may do).
    for (Mesh& m : a.meshes) {
      Mesh kept = m;
      kept.face_offsets = {0};
      kept.corner_wedge.clear();
      kept.face_material.clear();
      for (std::size_t f = 0; f < m.face_count(); ++f) {
        if (f % 3 != 1) kept.add_face(m.corner_wedge.data() + m.face_offsets[f], m.face_size(f), m.face_material[f]);
      }
      for (Vec3f& n : kept.normals) n = n * 1.01f;
      m = kept;
    }
    const fs::path dir = testing::temp_dir("gltf_validate_edited_" + fs::path(file).stem().string());
    save_asset(a, dir / "e.glb");
    const auto r = validate_gltf({dir / "e.glb"}, src);
    EXPECT_EQ(r.exit_code, 0) << r.output;
  }
}

TEST(GltfValidatorWrite, DroppedAndAddedPrimitivesPass) {
  LODFORGE_REQUIRE_GLTF_VALIDATOR();
  LODFORGE_REQUIRE_CORPUS(src, "gltf/CesiumMilkTruck.glb");
  Asset a = load_asset(src);
  // Mesh 0: slot 1's faces go to a new slot without a source primitive, slot 2 loses all faces. Fewer new
  // accessors than freed ones: exercises the placeholders that keep other indices in place.
  Mesh& m = a.meshes[0];
  MaterialSlot added = m.materials[1];
  added.source_primitive = -1;
  m.materials.push_back(added);
  for (std::uint32_t& s : m.face_material) s = s == 1 ? 3 : s;
  Mesh kept = m;
  kept.face_offsets = {0};
  kept.corner_wedge.clear();
  kept.face_material.clear();
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    if (m.face_material[f] != 2)
      kept.add_face(m.corner_wedge.data() + m.face_offsets[f], m.face_size(f), m.face_material[f]);
  }
  m = kept;
  const fs::path dir = testing::temp_dir("gltf_validate_slots");
  save_asset(a, dir / "s.glb");
  save_asset(a, dir / "s.gltf");
  const auto r = validate_gltf({dir / "s.glb", dir / "s.gltf"}, src);
  EXPECT_EQ(r.exit_code, 0) << r.output;
}

// Small hand-made sources: each is written back and validated against itself as the baseline.
std::string base64(std::string_view bytes) {
  static const char* k = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (std::size_t i = 0; i < bytes.size(); i += 3) {
    unsigned v = (unsigned char)bytes[i] << 16;
    if (i + 1 < bytes.size()) v |= (unsigned char)bytes[i + 1] << 8;
    if (i + 2 < bytes.size()) v |= (unsigned char)bytes[i + 2];
    out += k[v >> 18];
    out += k[(v >> 12) & 63];
    out += i + 1 < bytes.size() ? k[(v >> 6) & 63] : '=';
    out += i + 2 < bytes.size() ? k[v & 63] : '=';
  }
  return out;
}

template <class T>
std::string raw(const std::vector<T>& v) {
  return std::string(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
}

struct Doc {
  nlohmann::json j = nlohmann::json::parse(
      R"({"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],"meshes":[{"primitives":[]}]})");
  std::string bin;
  int view(const std::string& bytes, int target, int stride = 0) {
    while (bin.size() % 4) bin.push_back('\0');
    nlohmann::json v = {{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", bytes.size()}};
    if (stride) v["byteStride"] = stride;
    if (target) v["target"] = target;
    bin += bytes;
    j["bufferViews"].push_back(v);
    return static_cast<int>(j["bufferViews"].size() - 1);
  }
  int accessor(nlohmann::json a) {
    j["accessors"].push_back(std::move(a));
    return static_cast<int>(j["accessors"].size() - 1);
  }
  fs::path write(const fs::path& path) {
    nlohmann::json out = j;
    while (bin.size() % 4) bin.push_back('\0');
    out["buffers"] = {{{"byteLength", bin.size()}, {"uri", "data:application/octet-stream;base64," + base64(bin)}}};
    std::ofstream(path, std::ios::binary) << out.dump();
    return path;
  }
};

TEST(GltfValidatorWrite, HandMadeDocumentsPass) {
  LODFORGE_REQUIRE_GLTF_VALIDATOR();
  const fs::path dir = testing::temp_dir("gltf_validate_handmade");
  const std::vector<float> quad = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0};
  std::vector<fs::path> sources;
  {  // strip + fan + points sharing the strip's positions
    Doc d;
    const int pos = d.accessor({{"bufferView", d.view(raw(quad), 34962)},
                                {"componentType", 5126},
                                {"count", 4},
                                {"type", "VEC3"},
                                {"min", {0, 0, 0}},
                                {"max", {1, 1, 0}}});
    d.j["meshes"][0]["primitives"] = {{{"attributes", {{"POSITION", pos}}}, {"mode", 5}},
                                      {{"attributes", {{"POSITION", pos}}}, {"mode", 0}}};
    sources.push_back(d.write(dir / "modes.gltf"));
  }
  {  // quantized attributes, normalized colours, uint8 joints with a skin
    Doc d;
    d.j["extensionsUsed"] = {"KHR_mesh_quantization"};
    d.j["extensionsRequired"] = {"KHR_mesh_quantization"};
    const std::vector<std::int16_t> pos = {0, 0, 0, 0, 100, 0, 0, 0, 0, 100, 0, 0, 100, 100, 0, 0};
    const std::vector<std::int8_t> nrm = {0, 0, 127, 0, 0, 0, 127, 0, 0, 0, 127, 0, 0, 0, 127, 0};
    const std::vector<std::uint8_t> rgba = {255, 0, 0, 255, 0, 255, 0, 128, 0, 0, 255, 0, 10, 20, 30, 40};
    const std::vector<std::uint8_t> joints = {0, 1, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0};
    const std::vector<std::uint8_t> weights = {128, 127, 0, 0, 255, 0, 0, 0, 255, 0, 0, 0, 255, 0, 0, 0};
    const std::vector<std::uint16_t> idx = {0, 1, 2, 2, 1, 3};
    const std::vector<float> ibm = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1,
                                    1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    nlohmann::json attrs = {
        {"POSITION", d.accessor({{"bufferView", d.view(raw(pos), 34962, 8)},
                                 {"componentType", 5122},
                                 {"count", 4},
                                 {"type", "VEC3"},
                                 {"min", {0, 0, 0}},
                                 {"max", {100, 100, 0}}})},
        {"NORMAL", d.accessor({{"bufferView", d.view(raw(nrm), 34962, 4)},
                               {"componentType", 5120},
                               {"normalized", true},
                               {"count", 4},
                               {"type", "VEC3"}})},
        {"COLOR_0", d.accessor({{"bufferView", d.view(raw(rgba), 34962)},
                                {"componentType", 5121},
                                {"normalized", true},
                                {"count", 4},
                                {"type", "VEC4"}})},
        {"JOINTS_0",
         d.accessor(
             {{"bufferView", d.view(raw(joints), 34962)}, {"componentType", 5121}, {"count", 4}, {"type", "VEC4"}})},
        {"WEIGHTS_0", d.accessor({{"bufferView", d.view(raw(weights), 34962)},
                                  {"componentType", 5121},
                                  {"normalized", true},
                                  {"count", 4},
                                  {"type", "VEC4"}})}};
    const int indices = d.accessor(
        {{"bufferView", d.view(raw(idx), 34963)}, {"componentType", 5123}, {"count", 6}, {"type", "SCALAR"}});
    d.j["meshes"][0]["primitives"] = {{{"attributes", attrs}, {"indices", indices}}};
    d.j["nodes"] = {{{"mesh", 0}, {"skin", 0}}, {{"children", {2}}}, {{"translation", {0, 1, 0}}}};
    d.j["scenes"][0]["nodes"] = {0, 1};
    d.j["skins"] = {
        {{"joints", {1, 2}},
         {"inverseBindMatrices",
          d.accessor({{"bufferView", d.view(raw(ibm), 0)}, {"componentType", 5126}, {"count", 2}, {"type", "MAT4"}})}}};
    sources.push_back(d.write(dir / "quantized.gltf"));
  }
  {  // images of every kind: external (copied when writing elsewhere), data URI, bufferView
    static const char kPng[] =
        "\x89\x50\x4e\x47\x0d\x0a\x1a\x0a\x00\x00\x00\x0d\x49\x48\x44\x52\x00\x00\x00\x01\x00\x00\x00\x01"
        "\x08\x06\x00\x00\x00\x1f\x15\xc4\x89\x00\x00\x00\x0d\x49\x44\x41\x54\x78\x9c\x63\xf8\xcf\xc0\xf0"
        "\x1f\x00\x05\x00\x01\xff\x89\x99\x3d\x1d\x00\x00\x00\x00\x49\x45\x4e\x44\xae\x42\x60\x82";
    const std::string png(kPng, sizeof kPng - 1);  // a 1x1 RGBA PNG
    fs::create_directories(dir / "tex");
    std::ofstream(dir / "tex" / "p.png", std::ios::binary) << png;
    Doc d;
    const int pos = d.accessor({{"bufferView", d.view(raw(quad), 34962)},
                                {"componentType", 5126},
                                {"count", 4},
                                {"type", "VEC3"},
                                {"min", {0, 0, 0}},
                                {"max", {1, 1, 0}}});
    const std::vector<float> uv = {0, 0, 1, 0, 0, 1, 1, 1};
    const int tex =
        d.accessor({{"bufferView", d.view(raw(uv), 34962)}, {"componentType", 5126}, {"count", 4}, {"type", "VEC2"}});
    const std::vector<std::uint16_t> idx = {0, 1, 2, 2, 1, 3};
    const int indices = d.accessor(
        {{"bufferView", d.view(raw(idx), 34963)}, {"componentType", 5123}, {"count", 6}, {"type", "SCALAR"}});
    d.j["meshes"][0]["primitives"] = {
        {{"attributes", {{"POSITION", pos}, {"TEXCOORD_0", tex}}}, {"indices", indices}, {"material", 0}}};
    d.j["images"] = {{{"uri", "tex/p.png"}},
                     {{"uri", "data:image/png;base64," + base64(png)}},
                     {{"bufferView", d.view(png, 0)}, {"mimeType", "image/png"}}};
    d.j["textures"] = {{{"source", 0}}, {{"source", 1}}, {{"source", 2}}};
    d.j["materials"] = {{{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}},
                         {"emissiveTexture", {{"index", 1}}},
                         {"occlusionTexture", {{"index", 2}}}}};
    sources.push_back(d.write(dir / "images.gltf"));
  }
  for (const fs::path& src : sources) {
    SCOPED_TRACE(src.string());
    const Asset a = load_asset(src);
    fs::create_directories(dir / "out");
    const fs::path glb = dir / "out" / (src.stem().string() + ".glb");
    const fs::path gltf = dir / "out" / (src.stem().string() + ".gltf");
    save_asset(a, glb);
    save_asset(a, gltf);
    const auto r = validate_gltf({glb, gltf}, src);
    EXPECT_EQ(r.exit_code, 0) << r.output;
  }
}

}  // namespace
}  // namespace lodforge::io::gltf_validator_test
