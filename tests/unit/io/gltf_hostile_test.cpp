// Hostile glTF/GLB input, one test per case: each must throw IoError whose message names the file and the
// problem, quickly and without allocating what the file claims, and must leave no output behind.

#include <gtest/gtest.h>

#include <chrono>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "lodforge/io/asset.hpp"
#include "test_support.hpp"

namespace lodforge::io::gltf_hostile_test {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;

std::string base64(std::string_view bytes) {
  static const char* k = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  std::size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const unsigned v = (unsigned char)bytes[i] << 16 | (unsigned char)bytes[i + 1] << 8 | (unsigned char)bytes[i + 2];
    out += {k[v >> 18], k[(v >> 12) & 63], k[(v >> 6) & 63], k[v & 63]};
  }
  if (i + 1 == bytes.size()) {
    const unsigned v = (unsigned char)bytes[i] << 16;
    out += {k[v >> 18], k[(v >> 12) & 63], '=', '='};
  } else if (i + 2 == bytes.size()) {
    const unsigned v = (unsigned char)bytes[i] << 16 | (unsigned char)bytes[i + 1] << 8;
    out += {k[v >> 18], k[(v >> 12) & 63], k[(v >> 6) & 63], '='};
  }
  return out;
}

// The binary data of a valid one-triangle mesh: 3 float positions (36 bytes) then 3 uint16 indices (+2 padding).
std::string triangle_bin(float nan_x = 0.0f) {
  const float p[9] = {nan_x, 0, 0, 1, 0, 0, 0, 1, 0};
  const std::uint16_t i[4] = {0, 1, 2, 0};
  std::string bin(reinterpret_cast<const char*>(p), sizeof p);
  bin.append(reinterpret_cast<const char*>(i), sizeof i);
  return bin;
}

// A valid one-triangle document; `bin_uri` empty means a data URI of `bin`.
json triangle_doc(const std::string& bin, const std::string& bin_uri = "") {
  return {
      {"asset", {{"version", "2.0"}}},
      {"scenes", {{{"nodes", {0}}}}},
      {"nodes", {{{"mesh", 0}}}},
      {"meshes", {{{"primitives", {{{"attributes", {{"POSITION", 0}}}, {"indices", 1}}}}}}},
      {"accessors",
       {{{"bufferView", 0},
         {"componentType", 5126},
         {"count", 3},
         {"type", "VEC3"},
         {"min", {0, 0, 0}},
         {"max", {1, 1, 0}}},
        {{"bufferView", 1}, {"componentType", 5123}, {"count", 3}, {"type", "SCALAR"}}}},
      {"bufferViews",
       {{{"buffer", 0}, {"byteOffset", 0}, {"byteLength", 36}, {"target", 34962}},
        {{"buffer", 0}, {"byteOffset", 36}, {"byteLength", 6}, {"target", 34963}}}},
      {"buffers",
       {{{"byteLength", bin.size()},
         {"uri", bin_uri.empty() ? "data:application/octet-stream;base64," + base64(bin) : bin_uri}}}},
  };
}

// A GLB of the JSON text `j` (raw text, so that a test can hold what json would refuse to build) and `bin`.
std::string glb_of(std::string j, const std::string& bin) {
  while (j.size() % 4) j.push_back(' ');
  std::string b = bin;
  while (b.size() % 4) b.push_back('\0');
  auto u32 = [](std::string& s, std::uint32_t v) { s.append(reinterpret_cast<const char*>(&v), 4); };
  std::string out = "glTF";
  u32(out, 2);
  u32(out, static_cast<std::uint32_t>(12 + 8 + j.size() + 8 + b.size()));
  u32(out, static_cast<std::uint32_t>(j.size()));
  out += "JSON";
  out += j;
  u32(out, static_cast<std::uint32_t>(b.size()));
  out.append("BIN\0", 4);
  out += b;
  return out;
}

std::string glb_of(const json& doc, const std::string& bin) {
  return glb_of(doc.dump(), bin);
}

// `text` with its only occurrence of `from` replaced by `to`.
std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

json glb_triangle_doc(const std::string& bin) {
  json d = triangle_doc(bin);
  d["buffers"][0].erase("uri");
  return d;
}

fs::path write_bytes(const fs::path& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
  return path;
}

std::vector<fs::path> listing(const fs::path& dir) {
  std::vector<fs::path> out;
  for (const auto& e : fs::recursive_directory_iterator(dir)) out.push_back(e.path());
  std::sort(out.begin(), out.end());
  return out;
}

// Loads `path` (inside `dir`) expecting IoError for `path` mentioning every needle; checks it was fast and that
// nothing was written to `dir`.
void expect_rejected(const fs::path& dir, const fs::path& path, std::initializer_list<const char*> needles) {
  const auto before = listing(dir);
  const auto start = std::chrono::steady_clock::now();
  try {
    load_asset(path);
    ADD_FAILURE() << path << " loaded; expected an IoError";
  } catch (const IoError& e) {
    const std::string what = e.what();
    EXPECT_EQ(e.file(), path);
    EXPECT_NE(what.find(path.string()), std::string::npos) << what;
    for (const char* n : needles) EXPECT_NE(what.find(n), std::string::npos) << "'" << n << "' not in: " << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << "message is not one line: " << what;
  }
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(2));
  EXPECT_EQ(listing(dir), before) << "loading wrote files";
}

TEST(GltfHostile, ValidTriangleLoads) {  // the base document of the cases below
  const fs::path dir = testing::temp_dir("gltf_hostile_valid");
  const Asset a = load_asset(write_bytes(dir / "t.gltf", triangle_doc(triangle_bin()).dump()));
  EXPECT_EQ(a.meshes.at(0).face_count(), 1u);
  const Asset b = load_asset(write_bytes(dir / "t.glb", glb_of(glb_triangle_doc(triangle_bin()), triangle_bin())));
  EXPECT_EQ(b.meshes.at(0).face_count(), 1u);
}

TEST(GltfHostile, MissingFile) {
  const fs::path dir = testing::temp_dir("gltf_hostile_missing");
  expect_rejected(dir, dir / "nope.gltf", {"no such file"});
}

TEST(GltfHostile, EmptyGltfFile) {
  const fs::path dir = testing::temp_dir("gltf_hostile_empty");
  expect_rejected(dir, write_bytes(dir / "e.gltf", ""), {"empty"});
}

TEST(GltfHostile, EmptyGlbFile) {
  const fs::path dir = testing::temp_dir("gltf_hostile_empty_glb");
  expect_rejected(dir, write_bytes(dir / "e.glb", ""), {"empty"});
}

TEST(GltfHostile, TruncatedGlbHeader) {
  const fs::path dir = testing::temp_dir("gltf_hostile_trunc_header");
  const std::string glb = glb_of(glb_triangle_doc(triangle_bin()), triangle_bin());
  expect_rejected(dir, write_bytes(dir / "t.glb", glb.substr(0, 10)), {"truncated GLB", "12-byte header"});
}

TEST(GltfHostile, TruncatedGlbFile) {
  const fs::path dir = testing::temp_dir("gltf_hostile_trunc_file");
  const std::string glb = glb_of(glb_triangle_doc(triangle_bin()), triangle_bin());
  expect_rejected(dir, write_bytes(dir / "t.glb", glb.substr(0, glb.size() - 5)), {"truncated GLB", "header says"});
}

TEST(GltfHostile, TruncatedGlbJsonChunk) {
  const fs::path dir = testing::temp_dir("gltf_hostile_trunc_json");
  std::string glb = glb_of(glb_triangle_doc(triangle_bin()), triangle_bin()).substr(0, 40);
  const std::uint32_t length = 40;
  std::memcpy(glb.data() + 8, &length, 4);  // a consistent header, a JSON chunk longer than what is left
  expect_rejected(dir, write_bytes(dir / "t.glb", glb), {"truncated GLB", "JSON chunk"});
}

TEST(GltfHostile, TruncatedGlbBinChunk) {
  const fs::path dir = testing::temp_dir("gltf_hostile_trunc_bin");
  std::string glb = glb_of(glb_triangle_doc(triangle_bin()), triangle_bin());
  glb.resize(glb.size() - 8);
  const auto length = static_cast<std::uint32_t>(glb.size());
  std::memcpy(glb.data() + 8, &length, 4);
  expect_rejected(dir, write_bytes(dir / "t.glb", glb), {"truncated GLB", "BIN chunk"});
}

TEST(GltfHostile, WrongGlbMagic) {
  const fs::path dir = testing::temp_dir("gltf_hostile_magic");
  std::string glb = glb_of(glb_triangle_doc(triangle_bin()), triangle_bin());
  glb[3] = 'X';
  expect_rejected(dir, write_bytes(dir / "t.glb", glb), {"wrong magic"});
}

TEST(GltfHostile, JsonSyntaxError) {
  const fs::path dir = testing::temp_dir("gltf_hostile_syntax");
  expect_rejected(dir, write_bytes(dir / "s.gltf", "{\"asset\": {\"version\": \"2.0\"},\n  \"nodes\": [}"),
                  {"JSON syntax error", "line 2"});
}

TEST(GltfHostile, JsonNestedTooDeep) {
  const fs::path dir = testing::temp_dir("gltf_hostile_deep");
  const std::string deep =
      "{\"asset\":{\"version\":\"2.0\"},\"extras\":" + std::string(100000, '[') + std::string(100000, ']') + "}";
  expect_rejected(dir, write_bytes(dir / "d.gltf", deep), {"nested deeper"});
}

TEST(GltfHostile, NumberBeyondDouble) {
  // Valid JSON grammar, but no double holds it: the parser throws out_of_range, not parse_error.
  const fs::path dir = testing::temp_dir("gltf_hostile_number_range");
  const std::string text = replaced(triangle_doc(triangle_bin()).dump(), "\"max\":[1,1,0]", "\"max\":[1e999,1,0]");
  expect_rejected(dir, write_bytes(dir / "t.gltf", text), {"accessors[0].max[0]", "'1e999'", "out of range"});
  const std::string glb_text =
      replaced(glb_triangle_doc(triangle_bin()).dump(), "\"max\":[1,1,0]", "\"max\":[1,-1e999,0]");
  expect_rejected(dir, write_bytes(dir / "t.glb", glb_of(glb_text, triangle_bin())),
                  {"accessors[0].max[1]", "'-1e999'", "out of range"});
}

TEST(GltfHostile, NumberBeyondDoubleDeepInExtras) {
  const fs::path dir = testing::temp_dir("gltf_hostile_number_range_deep");
  json d = triangle_doc(triangle_bin());
  d["nodes"][0]["extras"] = {{"odd key", {{{"a", 1}}, {0, 1, "PLACEHOLDER"}}}};
  const std::string text = replaced(d.dump(), "\"PLACEHOLDER\"", "1" + std::string(400, '0'));
  expect_rejected(dir, write_bytes(dir / "t.gltf", text),
                  {"nodes[0].extras[\"odd key\"][1][2]", "out of range", "..."});
}

TEST(GltfHostile, GltfOneIsNotSupported) {
  // A glTF 1.0 document: dictionaries where 2.0 has arrays. The version is the reason, not the first dictionary.
  const fs::path dir = testing::temp_dir("gltf_hostile_version_one");
  const json v1 = {{"asset", {{"version", "1.0"}}},
                   {"scene", "defaultScene"},
                   {"scenes", {{"defaultScene", {{"nodes", {"node_1"}}}}}},
                   {"nodes", {{"node_1", {{"meshes", {"mesh_1"}}}}}},
                   {"meshes", {{"mesh_1", {{"primitives", json::array()}}}}}};
  expect_rejected(dir, write_bytes(dir / "v1.gltf", v1.dump()), {"glTF 1.0 is not supported", "only glTF 2.0"});
  std::string glb = glb_of(glb_triangle_doc(triangle_bin()), triangle_bin());
  glb[4] = 1;  // binary glTF 1.0 (KHR_binary_glTF) has version 1 in the GLB header
  expect_rejected(dir, write_bytes(dir / "v1.glb", glb), {"GLB version 1", "glTF 1.0", "not supported"});
}

TEST(GltfHostile, AssetVersionMissingOrUnknown) {
  const fs::path dir = testing::temp_dir("gltf_hostile_version");
  json d = triangle_doc(triangle_bin());
  d["asset"] = {{"generator", "hand"}};
  expect_rejected(dir, write_bytes(dir / "none.gltf", d.dump()), {"asset.version is missing"});
  d["asset"] = {{"version", "3.0"}};
  expect_rejected(dir, write_bytes(dir / "three.gltf", d.dump()), {"asset.version \"3.0\"", "only 2.0"});
  d["asset"] = {{"version", "2.0"}, {"minVersion", "2.1"}};
  expect_rejected(dir, write_bytes(dir / "min.gltf", d.dump()), {"asset.minVersion \"2.1\""});
  d["asset"] = {{"version", "2.1"}, {"minVersion", "2.0"}};  // a later 2.x that 2.0 readers can read
  EXPECT_EQ(load_asset(write_bytes(dir / "later.gltf", d.dump())).meshes.size(), 1u);
}

// The triangle document with a second node, a skin, a camera, a texture on a material and an animation, every
// reference in range.
json referencing_doc() {
  json d = triangle_doc(triangle_bin());
  d["scene"] = 0;
  d["nodes"] = {{{"mesh", 0}, {"children", {1}}, {"skin", 0}}, {{"camera", 0}}};
  d["skins"] = {{{"joints", {1}}, {"skeleton", 1}}};
  d["cameras"] = {{{"type", "perspective"}, {"perspective", {{"yfov", 1.0}, {"znear", 0.1}}}}};
  d["images"] = {{{"uri", "missing.png"}}};
  d["samplers"] = json::array({json::object()});
  d["textures"] = {{{"source", 0}, {"sampler", 0}}};
  d["materials"] = {
      {{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}}}, {"normalTexture", {{"index", 0}}}}};
  d["meshes"][0]["primitives"][0]["material"] = 0;
  const json sampler = {{"input", 1}, {"output", 0}};
  const json channel = {{"sampler", 0}, {"target", {{"node", 1}, {"path", "translation"}}}};
  d["animations"] = json::array({{{"samplers", json::array({sampler})}, {"channels", json::array({channel})}}});
  return d;
}

TEST(GltfHostile, ReferencesInRangeLoad) {
  const fs::path dir = testing::temp_dir("gltf_hostile_references_ok");
  const Asset a = load_asset(write_bytes(dir / "t.gltf", referencing_doc().dump()));
  EXPECT_EQ(a.meshes.at(0).face_count(), 1u);
}

TEST(GltfHostile, ReferenceOutOfRange) {
  // Each was accepted and written through to every output; each is refused with its JSON path.
  struct Case {
    const char* pointer;  // JSON pointer of the property set to `value`
    json value;
    const char* message;
  };
  const Case cases[] = {
      {"/nodes/0/mesh", 5, "nodes[0].mesh = 5 is out of range (meshes has 1)"},
      {"/scenes/0/nodes", {9}, "scenes[0].nodes[0] = 9 is out of range (nodes has 2)"},
      {"/scene", 3, "scene = 3 is out of range (scenes has 1)"},
      {"/nodes/0/children", {1, 7}, "nodes[0].children[1] = 7 is out of range (nodes has 2)"},
      {"/nodes/0/skin", 1, "nodes[0].skin = 1 is out of range (skins has 1)"},
      {"/nodes/1/camera", -1, "nodes[1].camera = -1 is not an index into cameras"},
      {"/skins/0/joints", {0, 2}, "skins[0].joints[1] = 2 is out of range (nodes has 2)"},
      {"/textures/0/source", 4, "textures[0].source = 4 is out of range (images has 1)"},
      {"/materials/0/pbrMetallicRoughness/baseColorTexture/index", 1,
       "materials[0].pbrMetallicRoughness.baseColorTexture.index = 1 is out of range (textures has 1)"},
      {"/materials/0/normalTexture", {{"scale", 1}}, "materials[0].normalTexture.index is missing"},
      {"/animations/0/channels/0/target/node", 2,
       "animations[0].channels[0].target.node = 2 is out of range (nodes has 2)"},
      {"/animations/0/channels/0/sampler", 1, "animations[0].channels[0].sampler is not an index into"},
      {"/animations/0/samplers/0/output", 2, "animations[0].samplers[0].output = 2 is out of range (accessors has 2)"},
  };
  const fs::path dir = testing::temp_dir("gltf_hostile_references");
  for (const Case& c : cases) {
    SCOPED_TRACE(c.pointer);
    json d = referencing_doc();
    d[json::json_pointer(c.pointer)] = c.value;
    expect_rejected(dir, write_bytes(dir / "t.gltf", d.dump()), {c.message});
  }
}

TEST(GltfHostile, NodeCycle) {
  const fs::path dir = testing::temp_dir("gltf_hostile_node_cycle");
  json d = triangle_doc(triangle_bin());
  d["nodes"] = {{{"mesh", 0}, {"children", {1}}}, {{"children", {2}}}, {{"children", {3}}}, {{"children", {1}}}};
  expect_rejected(dir, write_bytes(dir / "t.gltf", d.dump()),
                  {"node hierarchy has a cycle: nodes[1] -> nodes[2] -> nodes[3] -> nodes[1]", "nodes[3].children[0]"});
  d["nodes"] = {{{"mesh", 0}, {"children", {0}}}};
  expect_rejected(dir, write_bytes(dir / "self.gltf", d.dump()), {"cycle: nodes[0] -> nodes[0]"});
  d["nodes"] = json::array();  // a deep chain is not a cycle, and must not overflow the stack
  for (int i = 0; i < 100000; ++i) d["nodes"].push_back({{"children", {i + 1}}});
  d["nodes"].push_back({{"mesh", 0}});
  EXPECT_EQ(load_asset(write_bytes(dir / "deep.gltf", d.dump())).meshes.size(), 1u);
}

TEST(GltfHostile, BufferUriOutsideTheFolder) {
  const fs::path dir = testing::temp_dir("gltf_hostile_traversal");
  fs::create_directories(dir / "asset");
  write_bytes(dir / "secret.bin", triangle_bin());  // exists: refused for where it is, not for being missing
  expect_rejected(dir, write_bytes(dir / "asset" / "t.gltf", triangle_doc(triangle_bin(), "../secret.bin").dump()),
                  {"buffer 0", "outside the asset's folder"});
}

TEST(GltfHostile, PercentEncodedTraversal) {
  const fs::path dir = testing::temp_dir("gltf_hostile_traversal_pct");
  fs::create_directories(dir / "asset");
  write_bytes(dir / "secret.bin", triangle_bin());
  expect_rejected(
      dir, write_bytes(dir / "asset" / "t.gltf", triangle_doc(triangle_bin(), "sub/%2E%2E/%2E%2E/secret.bin").dump()),
      {"buffer 0", "outside the asset's folder"});
}

TEST(GltfHostile, AbsoluteBufferUri) {
  const fs::path dir = testing::temp_dir("gltf_hostile_absolute");
  const fs::path outside = write_bytes(dir / "abs.bin", triangle_bin());
  fs::create_directories(dir / "asset");
  expect_rejected(dir, write_bytes(dir / "asset" / "t.gltf", triangle_doc(triangle_bin(), outside.string()).dump()),
                  {"buffer 0", "absolute"});
}

TEST(GltfHostile, ImageUriOutsideTheFolder) {
  const fs::path dir = testing::temp_dir("gltf_hostile_image_traversal");
  json d = triangle_doc(triangle_bin());
  d["images"] = {{{"uri", "../../../../etc/passwd"}}};
  expect_rejected(dir, write_bytes(dir / "t.gltf", d.dump()), {"image 0", "outside the asset's folder"});
}

TEST(GltfHostile, MissingExternalBuffer) {
  const fs::path dir = testing::temp_dir("gltf_hostile_missing_bin");
  expect_rejected(dir, write_bytes(dir / "t.gltf", triangle_doc(triangle_bin(), "t.bin").dump()),
                  {"buffer 0", "not found"});
}

TEST(GltfHostile, ExternalBufferSizeMismatch) {
  const fs::path dir = testing::temp_dir("gltf_hostile_bin_size");
  write_bytes(dir / "t.bin", triangle_bin().substr(0, 20));
  expect_rejected(dir, write_bytes(dir / "t.gltf", triangle_doc(triangle_bin(), "t.bin").dump()),
                  {"buffer 0", "20 bytes", "byteLength"});
}

TEST(GltfHostile, AccessorOffsetPastBufferEnd) {
  const fs::path dir = testing::temp_dir("gltf_hostile_offset");
  json d = triangle_doc(triangle_bin());
  d["accessors"][0]["byteOffset"] = 4000;
  expect_rejected(dir, write_bytes(dir / "t.gltf", d.dump()), {"accessor 0", "past the end of bufferView 0"});
}

TEST(GltfHostile, BufferViewPastBufferEnd) {
  const fs::path dir = testing::temp_dir("gltf_hostile_view");
  json d = triangle_doc(triangle_bin());
  d["bufferViews"][1]["byteOffset"] = 1u << 30;
  expect_rejected(dir, write_bytes(dir / "t.gltf", d.dump()), {"bufferView 1", "past the end of buffer 0"});
}

TEST(GltfHostile, ImageBufferViewPastBufferEnd) {
  // tinygltf would read these image bytes unchecked; the structural check must stop it first.
  const fs::path dir = testing::temp_dir("gltf_hostile_image_view");
  json d = triangle_doc(triangle_bin());
  d["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", 40}, {"byteLength", 1000000}});
  d["images"] = {{{"bufferView", 2}, {"mimeType", "image/png"}}};
  expect_rejected(dir, write_bytes(dir / "t.gltf", d.dump()), {"bufferView 2", "past the end of buffer 0"});
}

TEST(GltfHostile, IndexPastVertexCount) {
  const fs::path dir = testing::temp_dir("gltf_hostile_index");
  std::string bin = triangle_bin();
  const std::uint16_t bad = 7;
  std::memcpy(bin.data() + 36 + 2, &bad, 2);
  expect_rejected(dir, write_bytes(dir / "t.gltf", triangle_doc(bin).dump()),
                  {"index value 7", "past the vertex count 3"});
}

TEST(GltfHostile, NanPosition) {
  const fs::path dir = testing::temp_dir("gltf_hostile_nan");
  expect_rejected(dir, write_bytes(dir / "t.gltf", triangle_doc(triangle_bin(NAN)).dump()), {"POSITION", "NaN"});
}

TEST(GltfHostile, InfinitePosition) {
  const fs::path dir = testing::temp_dir("gltf_hostile_inf");
  expect_rejected(dir, write_bytes(dir / "t.gltf", triangle_doc(triangle_bin(INFINITY)).dump()),
                  {"POSITION", "infinite"});
}

TEST(GltfHostile, ZeroByteBufferReferenced) {
  const fs::path dir = testing::temp_dir("gltf_hostile_zero_buffer");
  json d = triangle_doc(triangle_bin());
  d["buffers"] = {{{"byteLength", 0}, {"uri", "data:application/octet-stream;base64,"}}};
  expect_rejected(dir, write_bytes(dir / "t.gltf", d.dump()), {"buffer 0", "0 bytes long"});
}

TEST(GltfHostile, AbsurdAccessorCount) {
  const fs::path dir = testing::temp_dir("gltf_hostile_count");
  json d = triangle_doc(triangle_bin());
  d["accessors"][0]["count"] = 1ull << 40;
  expect_rejected(dir, write_bytes(dir / "t.gltf", d.dump()), {"accessor 0", "count 1099511627776", "limit"});
}

TEST(GltfHostile, LargeCountPastTheBufferView) {
  const fs::path dir = testing::temp_dir("gltf_hostile_count_view");
  json d = triangle_doc(triangle_bin());
  d["accessors"][0]["count"] = (1u << 31) - 1;  // under the element cap: the bounds check must catch it
  expect_rejected(dir, write_bytes(dir / "t.gltf", d.dump()), {"accessor 0", "past the end of bufferView 0"});
}

TEST(GltfHostile, LargeCountWithoutBufferView) {
  const fs::path dir = testing::temp_dir("gltf_hostile_count_zero");
  json d = triangle_doc(triangle_bin());
  d["accessors"][0].erase("bufferView");
  d["accessors"][0]["count"] = (1u << 31) - 1;  // all zeros: would be 24 GiB of floats
  expect_rejected(dir, write_bytes(dir / "t.gltf", d.dump()), {"accessor 0", "implausible"});
}

TEST(GltfHostile, SparseIndexPastCount) {
  const fs::path dir = testing::temp_dir("gltf_hostile_sparse");
  std::string bin = triangle_bin();
  const std::uint16_t idx = 9;
  const float val[3] = {1, 2, 3};
  bin.append(reinterpret_cast<const char*>(&idx), 2);
  bin.append(2, '\0');
  bin.append(reinterpret_cast<const char*>(val), sizeof val);
  json d = triangle_doc(bin);
  d["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", 44}, {"byteLength", 2}});
  d["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", 48}, {"byteLength", 12}});
  d["accessors"][0]["sparse"] = {
      {"count", 1}, {"indices", {{"bufferView", 2}, {"componentType", 5123}}}, {"values", {{"bufferView", 3}}}};
  expect_rejected(dir, write_bytes(dir / "t.gltf", d.dump()), {"accessor 0", "sparse index 9"});
}

TEST(GltfHostile, DracoRequired) {
  const fs::path dir = testing::temp_dir("gltf_hostile_draco");
  json d = triangle_doc(triangle_bin());
  d["extensionsUsed"] = {"KHR_draco_mesh_compression"};
  d["extensionsRequired"] = {"KHR_draco_mesh_compression"};
  expect_rejected(dir, write_bytes(dir / "t.gltf", d.dump()),
                  {"unsupported compression KHR_draco_mesh_compression", "gltf-transform"});
}

TEST(GltfHostile, DracoOnAPrimitive) {
  const fs::path dir = testing::temp_dir("gltf_hostile_draco_prim");
  json d = triangle_doc(triangle_bin());
  d["extensionsUsed"] = {"KHR_draco_mesh_compression"};
  d["meshes"][0]["primitives"][0]["extensions"] = {
      {"KHR_draco_mesh_compression", {{"bufferView", 0}, {"attributes", {{"POSITION", 0}}}}}};
  expect_rejected(dir, write_bytes(dir / "t.gltf", d.dump()), {"unsupported compression KHR_draco_mesh_compression"});
}

TEST(GltfHostile, MeshoptOnABufferView) {
  const fs::path dir = testing::temp_dir("gltf_hostile_meshopt");
  json d = triangle_doc(triangle_bin());
  d["extensionsUsed"] = {"EXT_meshopt_compression"};
  d["bufferViews"][0]["extensions"] = {
      {"EXT_meshopt_compression",
       {{"buffer", 0}, {"byteLength", 36}, {"byteStride", 12}, {"count", 3}, {"mode", "ATTRIBUTES"}}}};
  expect_rejected(dir, write_bytes(dir / "t.gltf", d.dump()), {"unsupported compression EXT_meshopt_compression"});
}

TEST(GltfHostile, AttributeAccessorOutOfRange) {
  const fs::path dir = testing::temp_dir("gltf_hostile_attr_index");
  json d = triangle_doc(triangle_bin());
  d["meshes"][0]["primitives"][0]["attributes"]["NORMAL"] = 4294967296ull;  // would truncate to 0 as an int
  expect_rejected(dir, write_bytes(dir / "t.gltf", d.dump()), {"NORMAL", "not a valid index"});
}

TEST(GltfHostile, DisallowedAttributeFormat) {
  const fs::path dir = testing::temp_dir("gltf_hostile_format");
  json d = triangle_doc(triangle_bin());
  d["accessors"][0]["componentType"] = 5125;  // UNSIGNED_INT positions
  expect_rejected(dir, write_bytes(dir / "t.gltf", d.dump()), {"POSITION", "UNSIGNED_INT", "does not allow"});
}

}  // namespace
}  // namespace lodforge::io::gltf_hostile_test
