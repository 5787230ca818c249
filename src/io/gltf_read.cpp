// glTF 2.0 reader (.gltf with external or data-URI buffers, .glb): one lodforge::Mesh per glTF mesh, one
// MaterialSlot per triangle primitive, and the whole document kept for a lossless write-back.
//
// Hostile input is the normal case for a batch tool fed by asset libraries, so nothing is trusted: the GLB
// container and the JSON structure are checked here before tinygltf sees them (tinygltf 2.7 reads image bytes
// from a bufferView without a bounds check and truncates large integers), every accessor is bounds-checked with
// overflow-safe arithmetic before a byte of it is read, counts are capped before anything is allocated, and every
// external file read goes through resolve_inside() (no path traversal, no absolute paths, no schemes).
//
// Spec: glTF 2.0 (Khronos), sections 3.6 (buffers, accessors, sparse accessors), 3.7.2 (meshes, primitive
// modes: strip p_i = {v_i, v_{i+(1+i%2)}, v_{i+(2-i%2)}}, fan p_i = {v_{i+1}, v_{i+2}, v_0}), 4.4 (GLB).
#include <algorithm>
#include <array>
#include <bit>
#include <climits>
#include <cmath>
#include <cstring>
#include <numeric>
#include <system_error>

#include "gltf_internal.hpp"
#include "lodforge/core/weld.hpp"
#include "lodforge/io/file.hpp"
#include "lodforge/io/formats.hpp"

namespace lodforge::io {
namespace {

static_assert(std::endian::native == std::endian::little, "the GLB and accessor decoding assume a little-endian host");

using gltf::Semantic;

constexpr std::uint32_t kChunkJson = 0x4E4F534Au;  // "JSON"
constexpr std::uint32_t kChunkBin = 0x004E4942u;   // "BIN\0"
// Deeper JSON than any real glTF needs; tinygltf converts extras/extensions recursively, so a hostile
// "[[[[...]]]]" would otherwise overflow the stack.
constexpr int kMaxJsonDepth = 256;
constexpr const char* kCompressionExtensions[] = {"KHR_draco_mesh_compression", "EXT_meshopt_compression",
                                                  "KHR_meshopt_compression"};
// Synthetic URIs handed to tinygltf for external files (see load_with_tinygltf).
constexpr const char* kSyntheticUriPrefix = "lodforge-external-";

std::string num(std::uint64_t v) {
  return std::to_string(v);
}

std::uint32_t read_u32(std::string_view bytes, std::size_t at) {
  std::uint32_t v;
  std::memcpy(&v, bytes.data() + at, 4);
  return v;
}

std::string unsupported_compression(std::string_view extension) {
  return "unsupported compression " + std::string(extension) +
         " (decompress the asset first, e.g. with gltf-transform)";
}

// ---------------------------------------------------------------------------------------------------------------
// Container: GLB header and chunks, JSON text.

struct GlbParts {
  std::string_view whole;  // the GLB bytes up to the header's length
  std::string_view json;
  std::string_view bin;
  bool has_bin = false;
};

GlbParts split_glb(const std::filesystem::path& path, std::string_view bytes, std::vector<std::string>& warnings) {
  if (bytes.size() < 12) {
    throw IoError(path, "truncated GLB: the file has " + num(bytes.size()) + " bytes, less than the 12-byte header");
  }
  if (std::memcmp(bytes.data(), "glTF", 4) != 0) {
    throw IoError(path, "not a GLB file: wrong magic (expected 'glTF')");
  }
  const std::uint32_t version = read_u32(bytes, 4);
  if (version == 1) throw IoError(path, "GLB version 1 is binary glTF 1.0, which is not supported (only glTF 2.0)");
  if (version != 2) throw IoError(path, "unsupported GLB version " + num(version) + " (only 2 is supported)");
  const std::uint32_t length = read_u32(bytes, 8);
  if (length > bytes.size()) {
    throw IoError(path,
                  "truncated GLB: the header says " + num(length) + " bytes but the file has " + num(bytes.size()));
  }
  if (length < bytes.size()) {
    warnings.push_back(num(bytes.size() - length) + " bytes after the end of the GLB (per its header) ignored");
  }
  GlbParts parts;
  parts.whole = bytes.substr(0, length);
  if (length < 20) throw IoError(path, "truncated GLB: no room for the JSON chunk header");
  const std::uint32_t json_length = read_u32(bytes, 12);
  if (read_u32(bytes, 16) != kChunkJson) throw IoError(path, "invalid GLB: the first chunk is not the JSON chunk");
  if (json_length > length - 20) {
    throw IoError(path, "truncated GLB: the JSON chunk says " + num(json_length) + " bytes but only " +
                            num(length - 20) + " remain");
  }
  parts.json = bytes.substr(20, json_length);
  const std::size_t at = 20 + std::size_t{json_length};
  const std::size_t rest = length - at;
  if (rest > 0 && rest < 8) {
    throw IoError(path, "truncated GLB: " + num(rest) + " bytes after the JSON chunk, too few for a chunk header");
  }
  if (rest >= 8) {
    const std::uint32_t bin_length = read_u32(bytes, at);
    if (bin_length > rest - 8) {
      throw IoError(path, "truncated GLB: the BIN chunk says " + num(bin_length) + " bytes but only " + num(rest - 8) +
                              " remain");
    }
    if (read_u32(bytes, at + 4) == kChunkBin) {
      parts.bin = bytes.substr(at + 8, bin_length);
      parts.has_bin = true;
    }
  }
  return parts;
}

void check_json_depth(const std::filesystem::path& path, std::string_view text) {
  int depth = 0;
  bool in_string = false, escaped = false;
  for (const char c : text) {
    if (in_string) {
      if (escaped) {
        escaped = false;
      } else if (c == '\\') {
        escaped = true;
      } else if (c == '"') {
        in_string = false;
      }
      continue;
    }
    if (c == '"') {
      in_string = true;
    } else if (c == '{' || c == '[') {
      if (++depth > kMaxJsonDepth) {
        throw IoError(path, "JSON nested deeper than " + std::to_string(kMaxJsonDepth) + " levels");
      }
    } else if (c == '}' || c == ']') {
      --depth;
    }
  }
}

// nlohmann's message without its "[json.exception.parse_error.101] " prefix.
std::string json_reason(const nlohmann::json::exception& e) {
  std::string what = e.what();
  if (const auto close = what.find("] "); what.rfind("[json.exception", 0) == 0 && close != std::string::npos) {
    what.erase(0, close + 2);
  }
  return what;
}

// "accessors[0].max" for plain keys, extras["odd key"] otherwise.
std::string json_child(const std::string& path, const std::string& key) {
  const bool plain = !key.empty() && std::all_of(key.begin(), key.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_';
  });
  if (!plain) return path + "[" + OrderedJson(key).dump() + "]";
  return path.empty() ? key : path + "." + key;
}

// The JSON path of the value the parser stopped at ("accessors[0].max[0]"), found by parsing `text` again with
// a callback that follows keys and array positions: nlohmann's number-overflow error names no position.
std::string json_path_of_failure(std::string_view text) {
  struct Frame {
    bool array = false;
    std::string key;        // objects: the key of the value being parsed
    std::size_t count = 0;  // arrays: values begun so far (a container counts when it opens, a scalar when parsed)
  };
  std::vector<Frame> frames;
  using Event = nlohmann::json::parse_event_t;
  const auto follow = [&frames](int, Event event, OrderedJson& parsed) {
    switch (event) {
      case Event::object_start:
      case Event::array_start:
        if (!frames.empty() && frames.back().array) ++frames.back().count;
        frames.push_back({.array = event == Event::array_start, .key = {}, .count = 0});
        break;
      case Event::key:
        frames.back().key = parsed.get<std::string>();
        break;
      case Event::object_end:
      case Event::array_end:
        frames.pop_back();
        break;
      case Event::value:
        if (!frames.empty() && frames.back().array) ++frames.back().count;
        break;
    }
    return true;
  };
  try {
    [[maybe_unused]] const OrderedJson whole = OrderedJson::parse(text.begin(), text.end(), follow);
  } catch (const nlohmann::json::exception&) {
    // expected: the frames now lead to the failing value
  }
  std::string path;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const Frame& f = frames[i];
    if (!f.array) {
      path = json_child(path, f.key);
    } else {
      // The failing value is a scalar not yet counted; an enclosing array counted its open child already.
      const std::size_t index = i + 1 == frames.size() ? f.count : f.count - 1;
      path += "[" + std::to_string(index) + "]";
    }
  }
  return path.empty() ? "the top level" : path;
}

OrderedJson parse_json(const std::filesystem::path& path, std::string_view text) {
  check_json_depth(path, text);
  try {
    OrderedJson j = OrderedJson::parse(text.begin(), text.end());
    if (!j.is_object()) throw IoError(path, "the glTF JSON is not an object");
    return j;
  } catch (const nlohmann::json::parse_error& e) {
    throw IoError(path, "JSON syntax error: " + json_reason(e));
  } catch (const nlohmann::json::out_of_range& e) {
    // The one out_of_range a parse throws: a number beyond double (1e999), which the JSON grammar allows.
    std::string token = json_reason(e);
    if (const auto open = token.find('\''); open != std::string::npos) token.erase(0, open);
    if (token.size() > 34) token = token.substr(0, 30) + "...'";
    throw IoError(path, json_path_of_failure(text) + ": number " + token + " is out of range (too large for a double)");
  } catch (const nlohmann::json::exception& e) {
    throw IoError(path, "invalid JSON: " + json_reason(e));
  }
}

// ---------------------------------------------------------------------------------------------------------------
// Structural checks on the JSON, before tinygltf parses it.

bool has_uri_scheme(std::string_view uri) {
  const auto colon = uri.find(':');
  const auto slash = uri.find('/');
  return colon != std::string_view::npos && colon > 0 && (slash == std::string_view::npos || colon < slash);
}

bool is_data_uri(std::string_view uri) {
  return uri.rfind("data:", 0) == 0;
}

class JsonChecker {
 public:
  JsonChecker(const std::filesystem::path& path, const OrderedJson& root) : path_(path), root_(root) {}

  // The array `key` of the root (empty when absent); throws when present but not an array of objects.
  const OrderedJson& objects(const char* key) const {
    static const OrderedJson kEmpty = OrderedJson::array();
    const auto it = root_.find(key);
    if (it == root_.end()) return kEmpty;
    if (!it->is_array()) fail(std::string("'") + key + "' is not an array");
    for (std::size_t i = 0; i < it->size(); ++i) {
      if (!(*it)[i].is_object()) fail(std::string(key) + "[" + num(i) + "] is not an object");
    }
    return *it;
  }

  // A non-negative integer property (`def` when absent and not required).
  std::uint64_t unsigned_value(const OrderedJson& o, const char* key, const std::string& what, bool required,
                               std::uint64_t def = 0) const {
    const auto it = o.find(key);
    if (it == o.end()) {
      if (required) fail(what + ": '" + key + "' is missing");
      return def;
    }
    if (!it->is_number_unsigned()) fail(what + ": '" + key + "' is not a non-negative integer");
    return it->get<std::uint64_t>();
  }

  // An index property; -1 when absent and not required. Must be below `limit`.
  int index_value(const OrderedJson& o, const char* key, std::size_t limit, const std::string& what,
                  bool required) const {
    const auto it = o.find(key);
    if (it == o.end()) {
      if (required) fail(what + ": '" + key + "' is missing");
      return -1;
    }
    if (!it->is_number_unsigned() || it->get<std::uint64_t>() >= limit) {
      fail(what + ": '" + key + "' = " + it->dump() + " is not a valid index (" + num(limit) + " available)");
    }
    return static_cast<int>(it->get<std::uint64_t>());
  }

  [[noreturn]] void fail(const std::string& problem) const { throw IoError(path_, problem); }

 private:
  const std::filesystem::path& path_;
  const OrderedJson& root_;
};

void check_no_compression_extension(const JsonChecker& check, const OrderedJson& o) {
  const auto ext = o.find("extensions");
  if (ext == o.end() || !ext->is_object()) return;
  for (const char* name : kCompressionExtensions) {
    if (ext->contains(name)) check.fail(unsupported_compression(name));
  }
}

// resolve_inside(), with the refusal naming the buffer or image whose URI it is.
std::filesystem::path resolve_checked(const std::filesystem::path& path, const std::filesystem::path& folder,
                                      const std::string& uri, const std::string& what) {
  try {
    return resolve_inside(path, folder, uri);
  } catch (const IoError& e) {
    throw IoError(path, what + ": " + e.problem());
  }
}

// External files the JSON names, keyed by the synthetic URI tinygltf will ask for.
struct ExternalFiles {
  std::map<std::string, std::filesystem::path> by_synthetic_uri;
  std::vector<std::string> buffer_uri;  // synthetic URI per buffer, empty for data:/GLB buffers
  std::vector<std::string> image_uri;   // synthetic URI per image with a non-data URI
};

// Index properties of the core glTF 2.0 objects outside meshes, accessors, buffers and animations (checked in
// their own passes), as data: where the property is and which top-level array it indexes. tinygltf keeps them
// unchecked and the writer writes them through, so one out of range would reach every output.
enum class RefKind {
  index,         // "mesh": 0
  list,          // "children": [1, 2]
  texture_info,  // "normalTexture": {"index": 0, ...}; the index is required
};
struct Reference {
  const char* from;                 // top-level array of the referring objects
  std::array<const char*, 2> keys;  // the property's keys inside one object (the second nullptr if unused)
  const char* to;                   // top-level array indexed
  RefKind kind;
};
constexpr Reference kReferences[] = {
    {"scenes", {"nodes", nullptr}, "nodes", RefKind::list},
    {"nodes", {"mesh", nullptr}, "meshes", RefKind::index},
    {"nodes", {"skin", nullptr}, "skins", RefKind::index},
    {"nodes", {"camera", nullptr}, "cameras", RefKind::index},
    {"nodes", {"children", nullptr}, "nodes", RefKind::list},
    {"skins", {"joints", nullptr}, "nodes", RefKind::list},
    {"skins", {"skeleton", nullptr}, "nodes", RefKind::index},
    {"skins", {"inverseBindMatrices", nullptr}, "accessors", RefKind::index},
    {"textures", {"source", nullptr}, "images", RefKind::index},
    {"textures", {"sampler", nullptr}, "samplers", RefKind::index},
    {"materials", {"pbrMetallicRoughness", "baseColorTexture"}, "textures", RefKind::texture_info},
    {"materials", {"pbrMetallicRoughness", "metallicRoughnessTexture"}, "textures", RefKind::texture_info},
    {"materials", {"normalTexture", nullptr}, "textures", RefKind::texture_info},
    {"materials", {"occlusionTexture", nullptr}, "textures", RefKind::texture_info},
    {"materials", {"emissiveTexture", nullptr}, "textures", RefKind::texture_info},
};

// Checks of the JSON before tinygltf parses it, one pass per top-level array; each throws IoError on the first
// problem. Also collects the external files (resolved inside the asset's folder) tinygltf may read.
struct StructureCheck {
  const std::filesystem::path& path;
  const OrderedJson& root;
  const JsonChecker check;
  const std::filesystem::path folder;
  ExternalFiles files;
  std::vector<std::uint64_t> buffer_length;

  StructureCheck(const std::filesystem::path& p, const OrderedJson& r)
      : path(p), root(r), check(p, r), folder(p.parent_path()) {}

  // asset.version first: a glTF 1.0 file fails every later check (its top-level properties are dictionaries),
  // and the reason is the version, not those.
  void check_version() const {
    const auto asset = root.find("asset");
    if (asset == root.end() || !asset->is_object()) check.fail("'asset' is missing (it holds the glTF version)");
    const auto version = asset->find("version");
    if (version == asset->end() || !version->is_string()) check.fail("asset.version is missing or not a string");
    const std::string v = version->get<std::string>();
    const std::string major = v.substr(0, v.find('.'));
    if (major == "1" || major == "0") {
      check.fail("glTF " + v + " is not supported, only glTF 2.0 (upgrade it first, e.g. with gltf-pipeline)");
    }
    if (major != "2") check.fail("asset.version \"" + v + "\": unsupported glTF version (only 2.0 is read)");
    const auto min_version = asset->find("minVersion");
    if (min_version != asset->end() && min_version->is_string() && min_version->get<std::string>() != "2.0") {
      check.fail("asset.minVersion \"" + min_version->get<std::string>() + "\": the asset needs a newer glTF " +
                 "reader than 2.0");
    }
  }

  void check_required_extensions() const {
    const auto it = root.find("extensionsRequired");
    if (it == root.end()) return;
    if (!it->is_array()) check.fail("'extensionsRequired' is not an array");
    for (const auto& e : *it) {
      for (const char* name : kCompressionExtensions) {
        if (e.is_string() && e.get<std::string>() == name) check.fail(unsupported_compression(name));
      }
    }
  }

  // Sizes, and every external URI resolved inside the asset's folder, existing, of the declared size.
  void check_buffers(bool glb, std::size_t glb_bin_size) {
    const OrderedJson& buffers = check.objects("buffers");
    buffer_length.assign(buffers.size(), 0);
    files.buffer_uri.resize(buffers.size());
    for (std::size_t b = 0; b < buffers.size(); ++b) {
      const std::string what = "buffer " + num(b);
      buffer_length[b] = check.unsigned_value(buffers[b], "byteLength", what, true);
      check_no_compression_extension(check, buffers[b]);
      const auto uri_it = buffers[b].find("uri");
      if (uri_it == buffers[b].end()) {
        if (!glb) check.fail(what + " has no uri (only the first buffer of a .glb may omit it)");
        if (b != 0) check.fail(what + " has no uri; only buffer 0 can refer to the GLB's BIN chunk");
        if (buffer_length[b] > glb_bin_size) {
          check.fail(what + " says " + num(buffer_length[b]) + " bytes but the GLB BIN chunk has " + num(glb_bin_size));
        }
        continue;
      }
      if (!uri_it->is_string()) check.fail(what + ": 'uri' is not a string");
      const std::string uri = uri_it->get<std::string>();
      if (is_data_uri(uri)) continue;
      const std::filesystem::path file = resolve_checked(path, folder, uri, what);
      std::error_code ec;
      if (!std::filesystem::is_regular_file(file, ec)) check.fail(what + ": file '" + uri + "' not found");
      const std::uintmax_t size = std::filesystem::file_size(file, ec);
      if (ec) check.fail(what + ": cannot read the size of '" + uri + "': " + ec.message());
      if (size != buffer_length[b]) {
        check.fail(what + ": file '" + uri + "' has " + num(size) + " bytes but byteLength says " +
                   num(buffer_length[b]));
      }
      files.buffer_uri[b] = kSyntheticUriPrefix + std::string("buffer-") + num(b);
      files.by_synthetic_uri[files.buffer_uri[b]] = file;
    }
  }

  // Buffer views inside their buffers (tinygltf reads image bytes from them unchecked).
  void check_buffer_views() const {
    const OrderedJson& buffers = check.objects("buffers");
    const OrderedJson& views = check.objects("bufferViews");
    for (std::size_t v = 0; v < views.size(); ++v) {
      const std::string what = "bufferView " + num(v);
      const int b = check.index_value(views[v], "buffer", buffers.size(), what, true);
      const std::uint64_t offset = check.unsigned_value(views[v], "byteOffset", what, false);
      const std::uint64_t length = check.unsigned_value(views[v], "byteLength", what, true);
      check_no_compression_extension(check, views[v]);
      if (buffer_length[static_cast<std::size_t>(b)] == 0) {
        check.fail(what + " references buffer " + num(static_cast<std::uint64_t>(b)) + ", which is 0 bytes long");
      }
      if (length == 0) check.fail(what + " has byteLength 0");
      const std::uint64_t size = buffer_length[static_cast<std::size_t>(b)];
      if (offset > size || length > size - offset) {
        check.fail(what + " (byteOffset " + num(offset) + ", byteLength " + num(length) +
                   ") runs past the end of buffer " + num(static_cast<std::uint64_t>(b)) + " (" + num(size) +
                   " bytes)");
      }
    }
  }

  // Accessors: indices in range and counts capped (tinygltf keeps sparse fields as int).
  void check_accessors(const LoadOptions& options) const {
    const OrderedJson& views = check.objects("bufferViews");
    const OrderedJson& accessors = check.objects("accessors");
    for (std::size_t a = 0; a < accessors.size(); ++a) {
      const std::string what = "accessor " + num(a);
      const OrderedJson& acc = accessors[a];
      check.index_value(acc, "bufferView", views.size(), what, false);
      check.unsigned_value(acc, "byteOffset", what, false);
      const std::uint64_t count = check.unsigned_value(acc, "count", what, true);
      if (count > options.max_elements) {
        check.fail(what + ": count " + num(count) + " exceeds the limit of " + num(options.max_elements) + " elements");
      }
      const auto sparse = acc.find("sparse");
      if (sparse == acc.end()) continue;
      if (!sparse->is_object()) check.fail(what + ": 'sparse' is not an object");
      const std::uint64_t sparse_count = check.unsigned_value(*sparse, "count", what + " sparse", true);
      if (sparse_count == 0 || sparse_count > count) {
        check.fail(what + ": sparse count " + num(sparse_count) + " is not in 1.." + num(count));
      }
      for (const char* part : {"indices", "values"}) {
        const auto it = sparse->find(part);
        if (it == sparse->end() || !it->is_object()) check.fail(what + ": sparse '" + part + "' is missing");
        check.index_value(*it, "bufferView", views.size(), what + " sparse " + part, true);
        if (check.unsigned_value(*it, "byteOffset", what + " sparse " + part, false) > INT_MAX) {
          check.fail(what + ": sparse " + part + " byteOffset is too large");
        }
      }
    }
  }

  // Images: bufferView indices, and external URIs resolved inside the folder.
  void check_images() {
    const OrderedJson& views = check.objects("bufferViews");
    const OrderedJson& images = check.objects("images");
    files.image_uri.resize(images.size());
    for (std::size_t i = 0; i < images.size(); ++i) {
      const std::string what = "image " + num(i);
      check.index_value(images[i], "bufferView", views.size(), what, false);
      const auto uri_it = images[i].find("uri");
      if (uri_it == images[i].end()) continue;
      if (!uri_it->is_string()) check.fail(what + ": 'uri' is not a string");
      const std::string uri = uri_it->get<std::string>();
      files.image_uri[i] = kSyntheticUriPrefix + std::string("image-") + num(i);
      // A remote (http:) texture is not an error for a mesh tool; it stays as it is (see classify_images).
      if (is_data_uri(uri) || has_uri_scheme(uri)) {
        if (is_data_uri(uri)) files.image_uri[i].clear();
        continue;
      }
      const std::filesystem::path file = resolve_checked(path, folder, uri, what);
      std::error_code ec;
      // Missing and empty files are dangling references: not handed to tinygltf (it fails on empty images).
      if (std::filesystem::is_regular_file(file, ec) && std::filesystem::file_size(file, ec) > 0 && !ec) {
        files.by_synthetic_uri[files.image_uri[i]] = file;
      }
    }
  }

  // "<path> = 5 is out of range (meshes has 1)" unless `value` is an index into the array `to` of `limit` items.
  void check_index(const OrderedJson& value, const std::string& path, const char* to, std::size_t limit) const {
    if (!value.is_number_unsigned()) check.fail(path + " = " + value.dump() + " is not an index into " + to);
    if (value.get<std::uint64_t>() >= limit) {
      check.fail(path + " = " + value.dump() + " is out of range (" + to + " has " + num(limit) + ")");
    }
  }

  void check_index_list(const OrderedJson& value, const std::string& path, const char* to, std::size_t limit) const {
    if (!value.is_array()) check.fail(path + " is not an array");
    for (std::size_t i = 0; i < value.size(); ++i) check_index(value[i], path + "[" + num(i) + "]", to, limit);
  }

  // Every index of kReferences, the default scene and the animations in range.
  void check_references() const {
    if (const auto scene = root.find("scene"); scene != root.end()) {
      check_index(*scene, "scene", "scenes", check.objects("scenes").size());
    }
    for (const Reference& r : kReferences) {
      const OrderedJson& objects = check.objects(r.from);
      const std::size_t limit = check.objects(r.to).size();
      for (std::size_t i = 0; i < objects.size(); ++i) {
        std::string path = std::string(r.from) + "[" + num(i) + "]";
        const OrderedJson* value = &objects[i];
        for (const char* key : r.keys) {
          if (!key || !value) break;
          if (!value->is_object()) check.fail(path + " is not an object");
          path += std::string(".") + key;
          const auto it = value->find(key);
          value = it == value->end() ? nullptr : &*it;
        }
        if (!value) continue;  // optional
        switch (r.kind) {
          case RefKind::index:
            check_index(*value, path, r.to, limit);
            break;
          case RefKind::list:
            check_index_list(*value, path, r.to, limit);
            break;
          case RefKind::texture_info: {
            if (!value->is_object()) check.fail(path + " is not an object");
            const auto index = value->find("index");
            if (index == value->end()) check.fail(path + ".index is missing");
            check_index(*index, path + ".index", r.to, limit);
            break;
          }
        }
      }
    }
    const OrderedJson& animations = check.objects("animations");
    const std::size_t accessors = check.objects("accessors").size(), nodes = check.objects("nodes").size();
    for (std::size_t a = 0; a < animations.size(); ++a) {
      const std::string path = "animations[" + num(a) + "]";
      const OrderedJson& anim = animations[a];
      const auto samplers = anim.find("samplers");
      const auto channels = anim.find("channels");
      if (samplers == anim.end() || !samplers->is_array()) check.fail(path + ".samplers is missing or not an array");
      if (channels == anim.end() || !channels->is_array()) check.fail(path + ".channels is missing or not an array");
      for (std::size_t k = 0; k < samplers->size(); ++k) {
        const OrderedJson& sampler = (*samplers)[k];
        const std::string at = path + ".samplers[" + num(k) + "]";
        if (!sampler.is_object()) check.fail(at + " is not an object");
        for (const char* key : {"input", "output"}) {
          const auto it = sampler.find(key);
          if (it == sampler.end()) check.fail(at + "." + key + " is missing");
          check_index(*it, at + "." + key, "accessors", accessors);
        }
      }
      for (std::size_t k = 0; k < channels->size(); ++k) {
        const OrderedJson& channel = (*channels)[k];
        const std::string at = path + ".channels[" + num(k) + "]";
        if (!channel.is_object()) check.fail(at + " is not an object");
        const auto sampler = channel.find("sampler");
        if (sampler == channel.end() || !sampler->is_number_unsigned() ||
            sampler->get<std::uint64_t>() >= samplers->size()) {
          check.fail(at + ".sampler is not an index into " + path + ".samplers (" + num(samplers->size()) + ")");
        }
        const auto target = channel.find("target");
        if (target == channel.end() || !target->is_object()) check.fail(at + ".target is missing");
        if (const auto node = target->find("node"); node != target->end()) {
          check_index(*node, at + ".target.node", "nodes", nodes);
        }
      }
    }
  }

  // The nodes form trees: no node is its own ancestor (a consumer walking the hierarchy would never stop).
  // Depth-first with an explicit stack, so a deep hierarchy cannot overflow ours. Indices are checked already.
  void check_node_cycles() const {
    const OrderedJson& nodes = check.objects("nodes");
    enum class Mark : char { unseen, on_path, done };
    std::vector<Mark> mark(nodes.size(), Mark::unseen);
    struct Step {
      std::size_t node;
      std::size_t next_child;
    };
    std::vector<Step> path;
    auto children = [&nodes](std::size_t n) -> const OrderedJson* {
      const auto it = nodes[n].find("children");
      return it == nodes[n].end() ? nullptr : &*it;
    };
    for (std::size_t start = 0; start < nodes.size(); ++start) {
      if (mark[start] != Mark::unseen) continue;
      mark[start] = Mark::on_path;
      path.push_back({start, 0});
      while (!path.empty()) {
        Step& top = path.back();
        const OrderedJson* list = children(top.node);
        if (!list || top.next_child == list->size()) {
          mark[top.node] = Mark::done;
          path.pop_back();
          continue;
        }
        const std::size_t slot = top.next_child++;
        const auto child = static_cast<std::size_t>((*list)[slot].get<std::uint64_t>());
        if (mark[child] == Mark::on_path) {
          std::string cycle;
          bool in_cycle = false;
          for (const Step& s : path) {
            in_cycle = in_cycle || s.node == child;
            if (in_cycle) cycle += "nodes[" + num(s.node) + "] -> ";
          }
          check.fail("the node hierarchy has a cycle: " + cycle + "nodes[" + num(child) + "] (nodes[" + num(top.node) +
                     "].children[" + num(slot) + "])");
        }
        if (mark[child] == Mark::unseen) {
          mark[child] = Mark::on_path;
          path.push_back({child, 0});
        }
      }
    }
  }

  // Meshes: attribute, index and target accessors exist; modes are known; no compression extensions.
  void check_meshes() const {
    const OrderedJson& accessors = check.objects("accessors");
    const OrderedJson& meshes = check.objects("meshes");
    const std::size_t material_count = check.objects("materials").size();
    for (std::size_t m = 0; m < meshes.size(); ++m) {
      const auto prims = meshes[m].find("primitives");
      if (prims == meshes[m].end() || !prims->is_array()) check.fail("mesh " + num(m) + " has no 'primitives' array");
      for (std::size_t p = 0; p < prims->size(); ++p) {
        const OrderedJson& prim = (*prims)[p];
        const std::string what = "mesh " + num(m) + " primitive " + num(p);
        if (!prim.is_object()) check.fail(what + " is not an object");
        check_no_compression_extension(check, prim);
        const auto attrs = prim.find("attributes");
        if (attrs == prim.end() || !attrs->is_object()) check.fail(what + " has no 'attributes' object");
        for (const auto& [name, value] : attrs->items()) {
          check.index_value(*attrs, name.c_str(), accessors.size(), what + " attribute " + name, true);
        }
        check.index_value(prim, "indices", accessors.size(), what, false);
        check.index_value(prim, "material", material_count, what, false);
        if (check.unsigned_value(prim, "mode", what, false, 4) > 6) check.fail(what + ": unknown mode");
        const auto targets = prim.find("targets");
        if (targets == prim.end()) continue;
        if (!targets->is_array()) check.fail(what + ": 'targets' is not an array");
        for (std::size_t t = 0; t < targets->size(); ++t) {
          if (!(*targets)[t].is_object()) check.fail(what + " target " + num(t) + " is not an object");
          for (const auto& [name, value] : (*targets)[t].items()) {
            check.index_value((*targets)[t], name.c_str(), accessors.size(), what + " target " + num(t) + " " + name,
                              true);
          }
        }
      }
    }
  }
};

ExternalFiles check_structure(const std::filesystem::path& path, const OrderedJson& root, bool glb,
                              std::size_t glb_bin_size, const LoadOptions& options) {
  StructureCheck c(path, root);
  c.check_version();
  c.check_required_extensions();
  c.check_buffers(glb, glb_bin_size);
  c.check_buffer_views();
  c.check_accessors(options);
  c.check_images();
  c.check_meshes();
  c.check_references();
  c.check_node_cycles();
  return std::move(c.files);
}

// ---------------------------------------------------------------------------------------------------------------
// tinygltf with our file access and no image decoding.

// tinygltf asks for a file through these callbacks with the URI found in the JSON joined to a base folder. We
// hand it synthetic URIs (one per external file, already resolved and checked) and an empty base folder, so the
// only files it can reach are those in the map: not its "." fallback (the process's working directory), not a
// URI it percent-decodes differently from resolve_inside ('+' as space).
bool fs_file_exists(const std::string& name, void* user) {
  const auto* files = static_cast<const ExternalFiles*>(user);
  const auto it = files->by_synthetic_uri.find(name);
  std::error_code ec;
  return it != files->by_synthetic_uri.end() && std::filesystem::is_regular_file(it->second, ec);
}

std::string fs_expand_path(const std::string& name, void*) {
  return name;
}

bool fs_read_file(std::vector<unsigned char>* out, std::string* err, const std::string& name, void* user) {
  const auto* files = static_cast<const ExternalFiles*>(user);
  const auto it = files->by_synthetic_uri.find(name);
  if (it == files->by_synthetic_uri.end()) {
    if (err) *err = "not a file of this asset";
    return false;
  }
  try {
    const std::string bytes = read_file(it->second);
    out->assign(bytes.begin(), bytes.end());
    return true;
  } catch (const IoError& e) {
    if (err) *err = e.problem();
    return false;
  }
}

bool fs_write_file(std::string* err, const std::string&, const std::vector<unsigned char>&, void*) {
  if (err) *err = "the reader writes no files";
  return false;
}

// Keeps an image's encoded bytes (PNG, JPEG, KTX2, ...) as they are: lodforge never needs pixels, and the writer
// must return the same bytes.
bool keep_encoded_image(tinygltf::Image* image, const int, std::string*, std::string*, int, int,
                        const unsigned char* bytes, int size, void*) {
  image->image.assign(bytes, bytes + std::max(size, 0));
  image->as_is = true;
  return true;
}

std::string tinygltf_reason(std::string text, const ExternalFiles& files, const OrderedJson& root) {
  // Put the real URIs back into tinygltf's messages and keep them short (a data URI can be megabytes).
  auto replace_all = [&](const std::string& from, const std::string& to) {
    for (std::size_t at = text.find(from); !from.empty() && at != std::string::npos;
         at = text.find(from, at + to.size())) {
      text.replace(at, from.size(), to);
    }
  };
  for (std::size_t b = 0; b < files.buffer_uri.size(); ++b) {
    if (!files.buffer_uri[b].empty()) replace_all(files.buffer_uri[b], root["buffers"][b].value("uri", ""));
  }
  for (std::size_t i = 0; i < files.image_uri.size(); ++i) {
    if (!files.image_uri[i].empty()) replace_all(files.image_uri[i], root["images"][i].value("uri", ""));
  }
  std::replace(text.begin(), text.end(), '\n', ' ');
  while (!text.empty() && text.back() == ' ') text.pop_back();
  if (text.size() > 300) text = text.substr(0, 300) + "...";
  return text.empty() ? "tinygltf gave no reason" : text;
}

tinygltf::Model load_with_tinygltf(const std::filesystem::path& path, const OrderedJson& root,
                                   std::string_view json_text, const GlbParts* glb, ExternalFiles& files) {
  // With external files, tinygltf gets a copy of the JSON whose URIs are the synthetic names.
  std::string rewritten_json, rewritten_glb;
  const bool rewrite = !files.by_synthetic_uri.empty() ||
                       std::any_of(files.image_uri.begin(), files.image_uri.end(), [](auto& s) { return !s.empty(); });
  if (rewrite) {
    OrderedJson copy = root;
    for (std::size_t b = 0; b < files.buffer_uri.size(); ++b) {
      if (!files.buffer_uri[b].empty()) copy["buffers"][b]["uri"] = files.buffer_uri[b];
    }
    for (std::size_t i = 0; i < files.image_uri.size(); ++i) {
      if (!files.image_uri[i].empty()) copy["images"][i]["uri"] = files.image_uri[i];
    }
    rewritten_json = copy.dump(-1, ' ', false, OrderedJson::error_handler_t::replace);
    json_text = rewritten_json;
    if (glb) {
      while (rewritten_json.size() % 4 != 0) rewritten_json.push_back(' ');
      json_text = rewritten_json;
      auto u32 = [&](std::uint32_t v) { rewritten_glb.append(reinterpret_cast<const char*>(&v), 4); };
      const std::size_t bin_chunk = glb->has_bin ? 8 + glb->bin.size() : 0;
      const std::uint64_t total = 12 + 8 + rewritten_json.size() + bin_chunk;
      if (total > UINT32_MAX) throw IoError(path, "GLB larger than 4 GiB");
      rewritten_glb.reserve(static_cast<std::size_t>(total));
      rewritten_glb.append("glTF", 4);
      u32(2);
      u32(static_cast<std::uint32_t>(total));
      u32(static_cast<std::uint32_t>(rewritten_json.size()));
      u32(kChunkJson);
      rewritten_glb += rewritten_json;
      if (glb->has_bin) {
        u32(static_cast<std::uint32_t>(glb->bin.size()));
        u32(kChunkBin);
        rewritten_glb += glb->bin;
      }
    }
  }

  tinygltf::TinyGLTF loader;
  loader.SetImageLoader(&keep_encoded_image, nullptr);
  loader.SetFsCallbacks(tinygltf::FsCallbacks{&fs_file_exists, &fs_expand_path, &fs_read_file, &fs_write_file, &files});
  tinygltf::Model model;
  std::string err, warn;
  bool ok = false;
  try {
    if (glb) {
      const std::string_view bytes = rewrite ? std::string_view(rewritten_glb) : glb->whole;
      if (bytes.size() > UINT32_MAX) throw IoError(path, "GLB larger than 4 GiB");
      ok = loader.LoadBinaryFromMemory(&model, &err, &warn, reinterpret_cast<const unsigned char*>(bytes.data()),
                                       static_cast<unsigned int>(bytes.size()), "");
    } else {
      if (json_text.size() > UINT32_MAX) throw IoError(path, "glTF JSON larger than 4 GiB");
      ok = loader.LoadASCIIFromString(&model, &err, &warn, json_text.data(),
                                      static_cast<unsigned int>(json_text.size()), "");
    }
  } catch (const IoError&) {
    throw;
  } catch (const std::exception& e) {
    throw IoError(path, std::string("invalid glTF: ") + e.what());
  }
  if (!ok) throw IoError(path, "invalid glTF: " + tinygltf_reason(err, files, root));

  // Give the model its real URIs back.
  for (std::size_t b = 0; b < model.buffers.size() && b < files.buffer_uri.size(); ++b) {
    model.buffers[b].uri = root["buffers"][b].value("uri", "");
  }
  for (std::size_t i = 0; i < model.images.size() && i < files.image_uri.size(); ++i) {
    model.images[i].uri = root["images"][i].value("uri", "");
  }
  return model;
}

std::vector<GltfImageSource> classify_images(const OrderedJson& root, const tinygltf::Model& model,
                                             std::vector<std::string>& warnings) {
  std::vector<GltfImageSource> out(model.images.size());
  for (std::size_t i = 0; i < model.images.size(); ++i) {
    const tinygltf::Image& image = model.images[i];
    const OrderedJson& j = root["images"][i];
    if (j.contains("bufferView")) {
      out[i].kind = GltfImageKind::buffer_view;
      continue;
    }
    const std::string uri = j.value("uri", "");
    if (is_data_uri(uri)) {
      out[i].kind = GltfImageKind::data_uri;
    } else if (has_uri_scheme(uri)) {
      out[i].kind = GltfImageKind::dangling;
      warnings.push_back("image " + num(i) + ": '" + uri + "' is not a local file; the reference is kept as it is");
    } else if (!image.image.empty()) {
      out[i].kind = GltfImageKind::external;
      out[i].relative = std::filesystem::path(percent_decode(uri)).lexically_normal();
    } else {
      out[i].kind = GltfImageKind::dangling;
      warnings.push_back("image " + num(i) + ": file '" + uri +
                         "' is missing or empty; the dangling reference is kept as it is");
    }
  }
  return out;
}

// ---------------------------------------------------------------------------------------------------------------
// Accessors: validated layout, then decoding.

bool span_fits(std::uint64_t offset, std::uint64_t count, std::uint64_t stride, std::uint64_t element,
               std::uint64_t length, std::uint64_t& needed) {
  // needed = offset + (count - 1) * stride + element, with every step checked for overflow.
  std::uint64_t span = 0;
  if (count == 0) {
    needed = offset;
    return offset <= length;
  }
  if (__builtin_mul_overflow(count - 1, stride, &span) || __builtin_add_overflow(span, element, &span) ||
      __builtin_add_overflow(span, offset, &needed)) {
    needed = UINT64_MAX;
    return false;
  }
  return needed <= length;
}

class AccessorReader {
 public:
  AccessorReader(const std::filesystem::path& path, const tinygltf::Model& model, const LoadOptions& options)
      : path_(path), model_(model), options_(options) {
    // An accessor without a bufferView is all zeros (plus sparse values): legitimate for sparse morph targets,
    // but a 40-byte file must not make us allocate gigabytes. Its count is capped by the file's data size.
    std::uint64_t bytes = 0;
    for (const auto& b : model.buffers) bytes += b.data.size();
    zero_fill_limit_ = bytes + 4096;
  }

  const tinygltf::Accessor& accessor(int index, const std::string& what) const {
    if (index < 0 || static_cast<std::size_t>(index) >= model_.accessors.size()) {
      fail(what + ": accessor " + std::to_string(index) + " does not exist");
    }
    return model_.accessors[static_cast<std::size_t>(index)];
  }

  // count * components floats (normalized integers converted by the spec formulas).
  std::vector<float> floats(int index, const std::string& what) const {
    const Layout l = layout(index, what);
    const tinygltf::Accessor& a = *l.accessor;
    std::vector<float> out(a.count * static_cast<std::size_t>(l.components), 0.0f);
    for_each_element(l, what + " (accessor " + std::to_string(index) + ")", [&](std::size_t i, const unsigned char* p) {
      float* dst = out.data() + i * static_cast<std::size_t>(l.components);
      for (int c = 0; c < l.components; ++c) {
        dst[c] = p ? gltf::decode_component(p + gltf::component_offset(a.componentType, a.type, c), a.componentType,
                                            a.normalized)
                   : 0.0f;
      }
    });
    if (a.componentType == gltf::kFloat) {
      for (std::size_t k = 0; k < out.size(); ++k) {
        if (!std::isfinite(out[k])) {
          fail(what + " (accessor " + std::to_string(index) + ") element " + num(k / l.components) + " is " +
               (std::isnan(out[k]) ? "NaN" : "infinite"));
        }
      }
    }
    return out;
  }

  std::vector<std::uint32_t> indices(int index, const std::string& what) const {
    const tinygltf::Accessor& a = accessor(index, what);
    const int ct = a.componentType;
    if (a.type != TINYGLTF_TYPE_SCALAR || a.normalized ||
        (ct != gltf::kUnsignedByte && ct != gltf::kUnsignedShort && ct != gltf::kUnsignedInt)) {
      fail(what + " (accessor " + std::to_string(index) + ") must be SCALAR UNSIGNED_BYTE/SHORT/INT, not " +
           std::string(gltf::type_name(gltf::type_components(a.type)) ? gltf::type_name(gltf::type_components(a.type))
                                                                      : "a matrix") +
           " " + gltf::component_name(ct) + (a.normalized ? " normalized" : ""));
    }
    const Layout l = layout(index, what);
    std::vector<std::uint32_t> out(a.count, 0);
    for_each_element(l, what + " (accessor " + std::to_string(index) + ")",
                     [&](std::size_t i, const unsigned char* p) { out[i] = p ? read_index(p, ct) : 0; });
    return out;
  }

  [[noreturn]] void fail(const std::string& problem) const { throw IoError(path_, problem); }

 private:
  struct Layout {
    const tinygltf::Accessor* accessor = nullptr;
    int components = 0;
    std::size_t element = 0;
    const unsigned char* data = nullptr;  // first element; nullptr: no bufferView (zeros)
    std::size_t stride = 0;
    const unsigned char* sparse_indices = nullptr;
    const unsigned char* sparse_values = nullptr;
  };

  static std::uint32_t read_index(const unsigned char* p, int component_type) {
    if (component_type == gltf::kUnsignedByte) return p[0];
    if (component_type == gltf::kUnsignedShort) {
      std::uint16_t v;
      std::memcpy(&v, p, 2);
      return v;
    }
    std::uint32_t v;
    std::memcpy(&v, p, 4);
    return v;
  }

  // The bytes of bufferView `index`, checked to lie inside its buffer's data.
  const tinygltf::BufferView& view(int index, const std::string& what) const {
    if (index < 0 || static_cast<std::size_t>(index) >= model_.bufferViews.size()) {
      fail(what + ": bufferView " + std::to_string(index) + " does not exist");
    }
    const tinygltf::BufferView& v = model_.bufferViews[static_cast<std::size_t>(index)];
    if (v.buffer < 0 || static_cast<std::size_t>(v.buffer) >= model_.buffers.size()) {
      fail(what + ": bufferView " + std::to_string(index) + " names buffer " + std::to_string(v.buffer) +
           ", which does not exist");
    }
    const std::size_t size = model_.buffers[static_cast<std::size_t>(v.buffer)].data.size();
    if (size == 0) {
      fail(what + ": bufferView " + std::to_string(index) + " references buffer " + std::to_string(v.buffer) +
           ", which is 0 bytes long");
    }
    if (v.byteOffset > size || v.byteLength > size - v.byteOffset) {
      fail(what + ": bufferView " + std::to_string(index) + " runs past the end of buffer " + std::to_string(v.buffer));
    }
    return v;
  }

  const unsigned char* view_data(const tinygltf::BufferView& v) const {
    return model_.buffers[static_cast<std::size_t>(v.buffer)].data.data() + v.byteOffset;
  }

  Layout layout(int index, const std::string& what_use) const {
    const tinygltf::Accessor& a = accessor(index, what_use);
    const std::string what = what_use + " (accessor " + std::to_string(index) + ")";
    Layout l;
    l.accessor = &a;
    if (gltf::component_size(a.componentType) == 0) {
      fail(what + ": component type " + std::to_string(a.componentType) + " (" + gltf::component_name(a.componentType) +
           ") is not allowed in glTF 2.0");
    }
    l.components = gltf::type_components(a.type);
    if (l.components == 0) fail(what + ": unknown accessor type");
    if (a.count == 0) fail(what + ": count is 0");
    if (a.count > options_.max_elements) {
      fail(what + ": count " + num(a.count) + " exceeds the limit of " + num(options_.max_elements) + " elements");
    }
    if (a.normalized && (a.componentType == gltf::kFloat || a.componentType == gltf::kUnsignedInt)) {
      fail(what + ": only 8- and 16-bit integer components can be normalized");
    }
    l.element = gltf::element_size(a.componentType, a.type);
    if (a.bufferView >= 0) {
      const tinygltf::BufferView& v = view(a.bufferView, what);
      l.stride = v.byteStride != 0 ? v.byteStride : l.element;
      if (l.stride < l.element) {
        fail(what + ": bufferView " + std::to_string(a.bufferView) + " byteStride " + num(l.stride) +
             " is smaller than one element (" + num(l.element) + " bytes)");
      }
      std::uint64_t needed = 0;
      if (!span_fits(a.byteOffset, a.count, l.stride, l.element, v.byteLength, needed)) {
        fail(what + ": byteOffset " + num(a.byteOffset) + " + " + num(a.count) + " elements (stride " + num(l.stride) +
             ") runs past the end of bufferView " + std::to_string(a.bufferView) + " (" + num(v.byteLength) +
             " bytes)");
      }
      l.data = view_data(v) + a.byteOffset;
    } else if (a.count > zero_fill_limit_) {
      fail(what + ": count " + num(a.count) + " without a bufferView is implausible for a file with " +
           num(zero_fill_limit_ - 4096) + " bytes of data");
    }
    if (a.sparse.isSparse) {
      const std::uint64_t count = static_cast<std::uint64_t>(std::max(a.sparse.count, 0));
      if (count == 0 || count > a.count) fail(what + ": sparse count " + num(count) + " is not in 1.." + num(a.count));
      const int ict = a.sparse.indices.componentType;
      if (ict != gltf::kUnsignedByte && ict != gltf::kUnsignedShort && ict != gltf::kUnsignedInt) {
        fail(what + ": sparse indices must be UNSIGNED_BYTE/SHORT/INT, not " + gltf::component_name(ict));
      }
      const std::uint64_t isize = static_cast<std::uint64_t>(gltf::component_size(ict));
      const tinygltf::BufferView& iv = view(a.sparse.indices.bufferView, what + " sparse indices");
      const tinygltf::BufferView& vv = view(a.sparse.values.bufferView, what + " sparse values");
      std::uint64_t needed = 0;
      const auto ioff = static_cast<std::uint64_t>(std::max(a.sparse.indices.byteOffset, 0));
      const auto voff = static_cast<std::uint64_t>(std::max(a.sparse.values.byteOffset, 0));
      if (a.sparse.indices.byteOffset < 0 || !span_fits(ioff, count, isize, isize, iv.byteLength, needed)) {
        fail(what + ": sparse indices run past the end of bufferView " + std::to_string(a.sparse.indices.bufferView));
      }
      if (a.sparse.values.byteOffset < 0 || !span_fits(voff, count, l.element, l.element, vv.byteLength, needed)) {
        fail(what + ": sparse values run past the end of bufferView " + std::to_string(a.sparse.values.bufferView));
      }
      l.sparse_indices = view_data(iv) + ioff;
      l.sparse_values = view_data(vv) + voff;
    }
    return l;
  }

  // Calls emit(i, bytes of element i) for every element, bytes == nullptr for zeros; sparse elements are
  // emitted again afterwards with their substituted values.
  template <class Emit>
  void for_each_element(const Layout& l, const std::string& what, Emit&& emit) const {
    const tinygltf::Accessor& a = *l.accessor;
    for (std::size_t i = 0; i < a.count; ++i) emit(i, l.data ? l.data + i * l.stride : nullptr);
    if (!a.sparse.isSparse) return;
    const int ict = a.sparse.indices.componentType;
    const std::size_t isize = static_cast<std::size_t>(gltf::component_size(ict));
    for (std::size_t k = 0; k < static_cast<std::size_t>(a.sparse.count); ++k) {
      const std::uint32_t target = read_index(l.sparse_indices + k * isize, ict);
      if (target >= a.count) {
        fail(what + ": sparse index " + num(target) + " (entry " + num(k) + ") is past the accessor's count " +
             num(a.count));
      }
      emit(target, l.sparse_values + k * l.element);
    }
  }

  const std::filesystem::path& path_;
  const tinygltf::Model& model_;
  const LoadOptions& options_;
  std::uint64_t zero_fill_limit_ = 0;
};

// ---------------------------------------------------------------------------------------------------------------
// Mesh conversion.

template <class T>
void fit(std::vector<T>& v, std::size_t n, const T& fill) {
  if (v.size() < n) v.resize(n, fill);
}

const char* mode_name(int mode) {
  switch (mode) {
    case 0:
      return "points";
    case 1:
      return "lines";
    case 2:
      return "line loop";
    case 3:
      return "line strip";
    case 5:
      return "triangle strip";
    case 6:
      return "triangle fan";
    default:
      return "triangles";
  }
}

std::string format_label(const tinygltf::Accessor& a) {
  const char* type = gltf::type_name(gltf::type_components(a.type));
  std::string s = a.type == TINYGLTF_TYPE_MAT2 ? "MAT2" : a.type == TINYGLTF_TYPE_MAT3 ? "MAT3" : type ? type : "?";
  s += std::string(" ") + gltf::component_name(a.componentType);
  if (a.normalized) s += " normalized";
  return s;
}

class MeshConverter {
 public:
  MeshConverter(const AccessorReader& reader, const tinygltf::Model& model, std::vector<std::string>& warnings)
      : reader_(reader), model_(model), warnings_(warnings) {}

  Mesh convert(std::size_t m, std::vector<char>& converted) {
    const tinygltf::Mesh& src = model_.meshes[m];
    Mesh out;
    out.name = src.name;
    label_ = "mesh " + num(m) + (src.name.empty() ? "" : " '" + src.name + "'");
    converted.assign(src.primitives.size(), 0);
    for (std::size_t p = 0; p < src.primitives.size(); ++p) {
      const tinygltf::Primitive& prim = src.primitives[p];
      const std::string where = label_ + " primitive " + num(p);
      const int mode = prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
      if (mode < TINYGLTF_MODE_TRIANGLES) {
        warnings_.push_back(where + ": " + mode_name(mode) +
                            " primitive carried unchanged (only triangles are simplified)");
        continue;
      }
      if (!prim.attributes.count("POSITION")) {
        warnings_.push_back(where + ": no POSITION attribute; carried unchanged");
        continue;
      }
      converted[p] = 1;
      append_primitive(out, prim, static_cast<int>(p), mode, where);
    }
    finish(out, src);
    return out;
  }

 private:
  struct Attribute {
    std::vector<float> values;
    int components = 0;
    AttributeFormat format;
  };

  Attribute read_attribute(const std::string& semantic, int accessor, std::size_t vertex_count, bool morph,
                           const std::string& where) {
    const std::string what = where + (morph ? " target " : " attribute ") + semantic;
    const tinygltf::Accessor& a = reader_.accessor(accessor, what);
    const gltf::SemanticInfo info = gltf::classify_semantic(semantic);
    Attribute attr;
    attr.components = gltf::type_components(a.type);
    attr.format = AttributeFormat{a.componentType, a.normalized};
    const bool matrix = a.type == TINYGLTF_TYPE_MAT2 || a.type == TINYGLTF_TYPE_MAT3;
    if (matrix || !gltf::attribute_format_allowed(info.kind, morph, attr.components, a.componentType, a.normalized)) {
      reader_.fail(what + " (accessor " + std::to_string(accessor) + ") has format " + format_label(a) +
                   ", which glTF does not allow for it" + (matrix ? " (or lodforge cannot carry)" : ""));
    }
    if (vertex_count != kNoCount && a.count != vertex_count) {
      reader_.fail(what + " (accessor " + std::to_string(accessor) + ") has " + num(a.count) +
                   " elements but POSITION has " + num(vertex_count));
    }
    attr.values = reader_.floats(accessor, what);
    return attr;
  }

  static constexpr std::size_t kNoCount = static_cast<std::size_t>(-1);

  void record_format(Mesh& out, const std::string& semantic, const AttributeFormat& f) {
    out.formats.emplace(semantic, f);  // first primitive wins; the writer uses each primitive's own accessor
  }

  void append_primitive(Mesh& out, const tinygltf::Primitive& prim, int p, int mode, const std::string& where) {
    const Attribute pos = read_attribute("POSITION", prim.attributes.at("POSITION"), kNoCount, false, where);
    const std::size_t n = pos.values.size() / 3;
    const std::size_t base = out.wedge_count();
    if (base + n > UINT32_MAX - 1) reader_.fail(where + ": more than 2^32 vertices in one mesh");
    record_format(out, "POSITION", pos.format);
    out.positions.reserve(base + n);
    out.wedge_vertex.reserve(base + n);
    for (std::size_t i = 0; i < n; ++i) {
      out.positions.push_back({{pos.values[3 * i], pos.values[3 * i + 1], pos.values[3 * i + 2]}});
      out.wedge_vertex.push_back(static_cast<std::uint32_t>(base + i));
    }

    MaterialSlot slot;
    slot.gltf_material = prim.material;
    slot.source_primitive = p;
    slot.has_normals = slot.has_tangents = slot.has_custom = false;
    slot.uv_sets = slot.color_sets = 0;
    slot.has_morphs = !prim.targets.empty();
    if (prim.material >= 0 && static_cast<std::size_t>(prim.material) < model_.materials.size() &&
        !model_.materials[static_cast<std::size_t>(prim.material)].name.empty()) {
      slot.name = model_.materials[static_cast<std::size_t>(prim.material)].name;
    } else {
      slot.name = prim.material >= 0 ? "material_" + std::to_string(prim.material) : "default";
    }

    for (const auto& [semantic, accessor] : prim.attributes) {
      if (semantic == "POSITION") continue;
      const Attribute attr = read_attribute(semantic, accessor, n, false, where);
      record_format(out, semantic, attr.format);
      const gltf::SemanticInfo info = gltf::classify_semantic(semantic);
      const float* v = attr.values.data();
      switch (info.kind) {
        case Semantic::normal:
          fit(out.normals, base, Vec3f{});
          for (std::size_t i = 0; i < n; ++i) out.normals.push_back({{v[3 * i], v[3 * i + 1], v[3 * i + 2]}});
          slot.has_normals = true;
          break;
        case Semantic::tangent:
          fit(out.tangents, base, Vec4f{{0, 0, 0, 1}});
          for (std::size_t i = 0; i < n; ++i) {
            out.tangents.push_back({{v[4 * i], v[4 * i + 1], v[4 * i + 2], v[4 * i + 3]}});
          }
          slot.has_tangents = true;
          break;
        case Semantic::texcoord: {
          const auto set = static_cast<std::size_t>(info.set);
          if (out.uvs.size() <= set) out.uvs.resize(set + 1);
          fit(out.uvs[set], base, Vec2f{});
          for (std::size_t i = 0; i < n; ++i) out.uvs[set].push_back({{v[2 * i], v[2 * i + 1]}});
          slot.uv_sets = std::max(slot.uv_sets, info.set + 1);
          break;
        }
        case Semantic::color: {
          const auto set = static_cast<std::size_t>(info.set);
          if (out.colors.size() <= set) {
            out.colors.resize(set + 1);
            out.color_components.resize(set + 1, 0);
          }
          // A set stored as RGB in one primitive and RGBA in another is modelled as RGBA.
          out.color_components[set] = std::max(out.color_components[set], attr.components);
          fit(out.colors[set], base, Vec4f{{1, 1, 1, 1}});
          const int c = attr.components;
          for (std::size_t i = 0; i < n; ++i) {
            const float* e = v + i * static_cast<std::size_t>(c);
            out.colors[set].push_back({{e[0], e[1], e[2], c == 4 ? e[3] : 1.0f}});
          }
          slot.color_sets = std::max(slot.color_sets, info.set + 1);
          break;
        }
        case Semantic::joints:
        case Semantic::weights:
          if (info.set <= 1) {
            fit(out.skin, base + n, SkinInfluences{});
            const std::size_t first = static_cast<std::size_t>(info.set) * 4;
            for (std::size_t i = 0; i < n; ++i) {
              for (std::size_t k = 0; k < 4; ++k) {
                if (info.kind == Semantic::joints) {
                  out.skin[base + i].joints[first + k] = static_cast<std::uint16_t>(v[4 * i + k]);
                } else {
                  out.skin[base + i].weights[first + k] = v[4 * i + k];
                }
              }
            }
            break;
          }
          // More than 8 influences: carried as custom wedge attributes rather than dropped.
          [[fallthrough]];
        case Semantic::custom: {
          const std::string& name = semantic;  // (a structured binding cannot be captured before C++20 in clang 14)
          auto it = std::find_if(out.custom.begin(), out.custom.end(),
                                 [&](const CustomAttribute& c) { return c.name == name; });
          if (it == out.custom.end()) {
            out.custom.push_back(CustomAttribute{semantic, attr.components, attr.format, {}});
            it = out.custom.end() - 1;
          } else if (it->components != attr.components) {
            reader_.fail(where + ": attribute " + semantic + " has " + std::to_string(attr.components) +
                         " components here but " + std::to_string(it->components) + " in an earlier primitive");
          }
          fit(it->values, base * static_cast<std::size_t>(it->components), 0.0f);
          it->values.insert(it->values.end(), attr.values.begin(), attr.values.end());
          slot.has_custom = true;
          break;
        }
        case Semantic::priority:
          fit(out.priority, base, 1.0f);  // 1 = no extra weight, for primitives without paint
          out.priority.insert(out.priority.end(), attr.values.begin(), attr.values.end());
          break;
        case Semantic::position:
          break;
      }
    }

    if (out.morph_targets.size() < prim.targets.size()) out.morph_targets.resize(prim.targets.size());
    for (std::size_t t = 0; t < prim.targets.size(); ++t) {
      MorphTarget& target = out.morph_targets[t];
      for (const auto& [semantic, accessor] : prim.targets[t]) {
        std::vector<Vec3f>* deltas = semantic == "POSITION"  ? &target.position_deltas
                                     : semantic == "NORMAL"  ? &target.normal_deltas
                                     : semantic == "TANGENT" ? &target.tangent_deltas
                                                             : nullptr;
        if (!deltas) {
          warnings_.push_back(where + ": morph target " + num(t) + " attribute " + semantic +
                              " dropped (lodforge keeps POSITION, NORMAL and TANGENT deltas)");
          continue;
        }
        const Attribute attr = read_attribute(semantic, accessor, n, true, where + " target " + num(t));
        const float* v = attr.values.data();
        fit(*deltas, base, Vec3f{});
        for (std::size_t i = 0; i < n; ++i) deltas->push_back({{v[3 * i], v[3 * i + 1], v[3 * i + 2]}});
      }
    }

    pad_streams(out, base + n);
    add_faces(out, prim, mode, n, base, where);
    out.materials.push_back(slot);
  }

  // Every stream the mesh has covers every wedge (primitives without a stream get neutral values; their slot
  // says the stream is absent, so the writer does not write them).
  static void pad_streams(Mesh& out, std::size_t wedges) {
    if (!out.normals.empty()) fit(out.normals, wedges, Vec3f{});
    if (!out.tangents.empty()) fit(out.tangents, wedges, Vec4f{{0, 0, 0, 1}});
    for (auto& s : out.uvs) fit(s, wedges, Vec2f{});
    for (auto& s : out.colors) fit(s, wedges, Vec4f{{1, 1, 1, 1}});
    for (auto& c : out.custom) fit(c.values, wedges * static_cast<std::size_t>(c.components), 0.0f);
    for (auto& t : out.morph_targets) {
      if (!t.position_deltas.empty()) fit(t.position_deltas, wedges, Vec3f{});
      if (!t.normal_deltas.empty()) fit(t.normal_deltas, wedges, Vec3f{});
      if (!t.tangent_deltas.empty()) fit(t.tangent_deltas, wedges, Vec3f{});
    }
    if (!out.skin.empty()) fit(out.skin, wedges, SkinInfluences{});
    if (!out.priority.empty()) fit(out.priority, wedges, 1.0f);
  }

  void add_faces(Mesh& out, const tinygltf::Primitive& prim, int mode, std::size_t n, std::size_t base,
                 const std::string& where) {
    std::vector<std::uint32_t> idx;
    if (prim.indices >= 0) {
      idx = reader_.indices(prim.indices, where + " indices");
      for (std::size_t k = 0; k < idx.size(); ++k) {
        if (idx[k] >= n) {
          reader_.fail(where + ": index value " + num(idx[k]) + " at position " + num(k) +
                       " is past the vertex count " + num(n));
        }
      }
    } else {
      idx.resize(n);
      std::iota(idx.begin(), idx.end(), 0u);
    }
    const auto slot = static_cast<std::uint32_t>(out.materials.size());
    const auto b = static_cast<std::uint32_t>(base);
    auto add = [&](std::uint32_t x, std::uint32_t y, std::uint32_t z) {
      const std::uint32_t w[3] = {b + x, b + y, b + z};
      out.add_face(w, 3, slot);
    };
    std::size_t made = 0;
    if (mode == TINYGLTF_MODE_TRIANGLES) {
      if (idx.size() % 3 != 0) {
        warnings_.push_back(where + ": " + num(idx.size() % 3) + " trailing indices (not a whole triangle) ignored");
      }
      out.face_offsets.reserve(out.face_offsets.size() + idx.size() / 3);
      for (std::size_t t = 0; t + 2 < idx.size(); t += 3) add(idx[t], idx[t + 1], idx[t + 2]);
      return;
    }
    // Strips and fans: degenerate triangles (a repeated index) are the stitching between runs, not surface.
    for (std::size_t i = 0; i + 2 < idx.size(); ++i) {
      std::uint32_t x, y, z;
      if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
        x = idx[i];
        y = idx[i + 1 + i % 2];
        z = idx[i + 2 - i % 2];
      } else {
        x = idx[i + 1];
        y = idx[i + 2];
        z = idx[0];
      }
      if (x == y || y == z || x == z) continue;
      add(x, y, z);
      ++made;
    }
    warnings_.push_back(where + ": " + mode_name(mode) + " converted to " + num(made) + " triangles");
  }

  void finish(Mesh& out, const tinygltf::Mesh& src) {
    pad_streams(out, out.wedge_count());
    if (src.extras.IsObject() && src.extras.Has("targetNames") && src.extras.Get("targetNames").IsArray()) {
      const tinygltf::Value& names = src.extras.Get("targetNames");
      for (std::size_t t = 0; t < out.morph_targets.size() && t < names.ArrayLen(); ++t) {
        const tinygltf::Value& name = names.Get(static_cast<int>(t));
        if (name.IsString()) out.morph_targets[t].name = name.Get<std::string>();
      }
    }
    out.morph_default_weights = src.weights;
    // Vertices no triangle uses (a primitive sharing another's vertex buffer, padding) carry no surface.
    remove_unreferenced(out);
    weld_by_position(out);
  }

  const AccessorReader& reader_;
  const tinygltf::Model& model_;
  std::vector<std::string>& warnings_;
  std::string label_;
};

using Matrix4 = std::array<double, 16>;  // column-major, as glTF stores it

Matrix4 multiply(const Matrix4& a, const Matrix4& b) {
  Matrix4 r{};
  for (int c = 0; c < 4; ++c) {
    for (int row = 0; row < 4; ++row) {
      double v = 0;
      for (int k = 0; k < 4; ++k) v += a[k * 4 + row] * b[c * 4 + k];
      r[c * 4 + row] = v;
    }
  }
  return r;
}

// A node's local transform: its matrix, else translation * rotation * scale.
Matrix4 local_transform(const tinygltf::Node& n) {
  if (n.matrix.size() == 16) {
    Matrix4 m;
    std::copy(n.matrix.begin(), n.matrix.end(), m.begin());
    return m;
  }
  const double x = n.rotation.size() == 4 ? n.rotation[0] : 0, y = n.rotation.size() == 4 ? n.rotation[1] : 0;
  const double z = n.rotation.size() == 4 ? n.rotation[2] : 0, w = n.rotation.size() == 4 ? n.rotation[3] : 1;
  const double sx = n.scale.size() == 3 ? n.scale[0] : 1, sy = n.scale.size() == 3 ? n.scale[1] : 1;
  const double sz = n.scale.size() == 3 ? n.scale[2] : 1;
  Matrix4 m{};
  // Columns of the rotation matrix of the unit quaternion (x, y, z, w), each scaled by its axis' scale.
  m[0] = (1 - 2 * (y * y + z * z)) * sx, m[1] = 2 * (x * y + z * w) * sx, m[2] = 2 * (x * z - y * w) * sx;
  m[4] = 2 * (x * y - z * w) * sy, m[5] = (1 - 2 * (x * x + z * z)) * sy, m[6] = 2 * (y * z + x * w) * sy;
  m[8] = 2 * (x * z + y * w) * sz, m[9] = 2 * (y * z - x * w) * sz, m[10] = (1 - 2 * (x * x + y * y)) * sz;
  m[12] = n.translation.size() == 3 ? n.translation[0] : 0;
  m[13] = n.translation.size() == 3 ? n.translation[1] : 0;
  m[14] = n.translation.size() == 3 ? n.translation[2] : 0;
  m[15] = 1;
  return m;
}

// Per mesh, the world transforms of the nodes that show it (check_structure has ruled out cycles and bad
// indices). Roots: the default scene's nodes, else the first scene's, else every node without a parent.
std::vector<std::vector<Matrix4>> mesh_world_transforms(const tinygltf::Model& model) {
  std::vector<std::vector<Matrix4>> out(model.meshes.size());
  std::vector<int> roots;
  const int scene = model.defaultScene >= 0 ? model.defaultScene : (model.scenes.empty() ? -1 : 0);
  if (scene >= 0 && scene < static_cast<int>(model.scenes.size())) {
    roots = model.scenes[static_cast<std::size_t>(scene)].nodes;
  } else {
    std::vector<bool> child(model.nodes.size(), false);
    for (const tinygltf::Node& n : model.nodes) {
      for (int c : n.children) {
        if (c >= 0 && c < static_cast<int>(child.size())) child[static_cast<std::size_t>(c)] = true;
      }
    }
    for (std::size_t i = 0; i < child.size(); ++i) {
      if (!child[i]) roots.push_back(static_cast<int>(i));
    }
  }
  constexpr Matrix4 kIdentity{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  std::vector<std::pair<int, Matrix4>> stack;
  for (auto it = roots.rbegin(); it != roots.rend(); ++it) stack.emplace_back(*it, kIdentity);
  std::size_t visits = 0;
  while (!stack.empty()) {
    const auto [index, parent] = stack.back();
    stack.pop_back();
    // A node listed twice (two parents, or a root that is also a child) is walked each time; the bound keeps a
    // hostile diamond-shaped hierarchy from growing without end.
    if (index < 0 || index >= static_cast<int>(model.nodes.size()) || ++visits > 16 * model.nodes.size() + 16) continue;
    const tinygltf::Node& n = model.nodes[static_cast<std::size_t>(index)];
    const Matrix4 world = multiply(parent, local_transform(n));
    if (n.mesh >= 0 && n.mesh < static_cast<int>(out.size())) {
      out[static_cast<std::size_t>(n.mesh)].push_back(n.skin >= 0 ? kIdentity : world);
    }
    for (auto c = n.children.rbegin(); c != n.children.rend(); ++c) stack.emplace_back(*c, world);
  }
  return out;
}

}  // namespace

Asset read_gltf(const std::filesystem::path& path, const LoadOptions& options) {
  const std::string bytes = read_file(path);
  if (bytes.empty()) throw IoError(path, "file is empty");
  const std::string ext = lower_extension(path);
  const bool glb = bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0;
  if (!glb && ext == ".glb") {
    throw IoError(path, "not a GLB file: wrong magic (expected 'glTF' in the first 4 bytes)");
  }

  Asset asset;
  asset.source = path;
  asset.format = glb ? Format::glb : Format::gltf;
  GlbParts parts;
  if (glb) parts = split_glb(path, bytes, asset.warnings);
  const std::string_view json_text = glb ? parts.json : std::string_view(bytes);

  GltfDocument doc;
  doc.source = path;
  doc.folder = path.parent_path();
  doc.json = parse_json(path, json_text);
  ExternalFiles files = check_structure(path, doc.json, glb, parts.bin.size(), options);
  doc.model = load_with_tinygltf(path, doc.json, json_text, glb ? &parts : nullptr, files);
  doc.images = classify_images(doc.json, doc.model, asset.warnings);

  const AccessorReader reader(path, doc.model, options);
  MeshConverter converter(reader, doc.model, asset.warnings);
  doc.converted.resize(doc.model.meshes.size());
  asset.meshes.reserve(doc.model.meshes.size());
  for (std::size_t m = 0; m < doc.model.meshes.size(); ++m) {
    asset.meshes.push_back(converter.convert(m, doc.converted[m]));
    doc.loaded_formats.push_back(asset.meshes.back().formats);
  }

  asset.mesh_transforms = mesh_world_transforms(doc.model);

  // The writer rebuilds the buffers; dropping their URIs frees the base64 text of embedded buffers.
  if (auto it = doc.json.find("buffers"); it != doc.json.end()) {
    doc.embedded_buffers = !glb && it->is_array() && !it->empty();
    for (auto& b : *it) {
      const auto uri = b.find("uri");
      const bool data = uri != b.end() && uri->is_string() && uri->get<std::string>().rfind("data:", 0) == 0;
      doc.embedded_buffers = doc.embedded_buffers && data;
      b.erase("uri");
    }
  }
  asset.gltf = std::make_shared<const GltfDocument>(std::move(doc));
  return asset;
}

}  // namespace lodforge::io
