// Shared between the glTF reader (gltf_read.cpp) and writer (gltf_write.cpp): the GltfDocument an Asset carries,
// and small helpers for glTF component types, accessor types and attribute semantics.
//
// Why the document keeps the source JSON next to tinygltf's Model: the writer patches the source JSON (mesh
// primitives, accessors, bufferViews, buffers) and leaves every other byte of meaning alone, which is lossless for
// properties tinygltf does not model (unknown top-level keys, extension objects it rewrites, number spellings).
// The Model supplies the binary data (buffers, encoded images) and typed access for the reader and the tests.
#pragma once

#include <tiny_gltf.h>

#include <cstdint>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "lodforge/core/mesh.hpp"
#include "lodforge/io/asset.hpp"

namespace lodforge::io {

using OrderedJson = nlohmann::ordered_json;

// Where an image's encoded bytes came from; the writer keeps each image the way it was stored.
enum class GltfImageKind {
  buffer_view,  // bytes in a bufferView (kept in the rebuilt buffer)
  data_uri,     // base64 data: URI (the URI string is written back unchanged)
  external,     // a file inside the asset's folder (copied next to the output when writing elsewhere)
  dangling,     // a URI whose file was missing or not local at load time (written back unchanged)
};

struct GltfImageSource {
  GltfImageKind kind = GltfImageKind::dangling;
  std::filesystem::path relative;  // external: normalised path relative to the asset's folder
};

struct GltfDocument {
  tinygltf::Model model;  // as loaded; images hold their encoded bytes (as_is), buffers their data
  OrderedJson json;       // the source JSON, without the buffers' URIs (the writer rebuilds the buffers)
  std::filesystem::path source;
  std::filesystem::path folder;         // the source's folder: external URIs are relative to it
  std::vector<GltfImageSource> images;  // per model.images entry
  // [mesh][primitive]: true for a triangle primitive that became a MaterialSlot (its data is rewritten on save);
  // false for one carried unchanged (points, lines, no POSITION).
  std::vector<std::vector<char>> converted;
  // [mesh]: Mesh::formats as loaded. The writer stores an attribute the way its own source accessor stored it,
  // unless the caller changed the mesh-wide format since loading.
  std::vector<std::map<std::string, AttributeFormat>> loaded_formats;
  // A .gltf whose buffers were all data: URIs: a .gltf written from it embeds its buffer too (no .bin file).
  bool embedded_buffers = false;
};

namespace gltf {

inline constexpr int kByte = 5120, kUnsignedByte = 5121, kShort = 5122, kUnsignedShort = 5123, kUnsignedInt = 5125,
                     kFloat = 5126;
inline constexpr int kArrayBuffer = 34962, kElementArrayBuffer = 34963;

// Bytes of one component; 0 for a component type glTF 2.0 does not allow (5124 int32, 5130 double, ...).
int component_size(int component_type);
const char* component_name(int component_type);
// Components of a tinygltf accessor type code (TINYGLTF_TYPE_*); 0 if unknown.
int type_components(int tinygltf_type);
// JSON accessor type for a component count (1..4, 16); nullptr for anything else.
const char* type_name(int components);
// Bytes of one element, with the column padding glTF requires for 1- and 2-byte MAT2/MAT3 components.
std::size_t element_size(int component_type, int tinygltf_type);
// Byte offset of component `i` inside an element (differs from i * size only for padded matrix columns).
std::size_t component_offset(int component_type, int tinygltf_type, int i);

// Decodes one component to float; normalized integers use the glTF 2.0 formulas (e.g. int8 max(c / 127, -1)).
float decode_component(const unsigned char* p, int component_type, bool normalized);

// What an attribute semantic means to lodforge (which Mesh array it fills and which formats glTF allows).
enum class Semantic { position, normal, tangent, texcoord, color, joints, weights, priority, custom };
struct SemanticInfo {
  Semantic kind = Semantic::custom;
  int set = 0;  // n of TEXCOORD_n, COLOR_n, JOINTS_n, WEIGHTS_n
};
SemanticInfo classify_semantic(std::string_view name);

// Whether glTF allows `components` x `component_type` (normalized or not) for this kind of attribute. Lenient
// where KHR_mesh_quantization widens the core table (8/16-bit integer positions, normals, UVs).
bool attribute_format_allowed(Semantic kind, bool morph_target, int components, int component_type, bool normalized);

// Percent-encodes a relative file name for use as a URI (unreserved characters and '/' stay as they are).
std::string uri_encode(std::string_view path);

}  // namespace gltf
}  // namespace lodforge::io
