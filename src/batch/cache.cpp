#include "lodforge/batch/cache.hpp"

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <set>

#include "lodforge/batch/shard.hpp"
#include "lodforge/io/asset.hpp"
#include "lodforge/io/file.hpp"
#include "lodforge/io/heightmap.hpp"

namespace lodforge::batch {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

std::uint64_t rotl(std::uint64_t x, int r) {
  return (x << r) | (x >> (64 - r));
}

std::uint64_t splitmix(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

std::string hex64(std::uint64_t v) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(v));
  return buf;
}

bool starts_with_data_uri(const std::string& uri) {
  return uri.rfind("data:", 0) == 0;
}

// The JSON of a .gltf file or of a .glb's JSON chunk; null when it cannot be parsed (the loader reports why).
Json gltf_json(std::string_view bytes, bool glb) {
  if (glb) {
    if (bytes.size() < 20 || bytes.substr(0, 4) != "glTF") return nullptr;
    std::uint32_t length = 0;
    std::memcpy(&length, bytes.data() + 12, 4);
    if (length > bytes.size() - 20) return nullptr;
    bytes = bytes.substr(20, length);
  }
  return Json::parse(bytes.begin(), bytes.end(), nullptr, false);
}

// Relative references of the file to other local files, in the order the file lists them.
std::vector<std::string> external_references(const fs::path& file, std::string_view bytes) {
  std::vector<std::string> refs;
  // A height map's sidecar (size, spacing, scale, no-data) changes what it makes.
  if (io::is_heightmap_path(file)) return {file.filename().string() + ".json"};
  io::Format format;
  try {
    format = io::format_from_path(file);
  } catch (const io::IoError&) {
    return refs;
  }
  if (format == io::Format::gltf || format == io::Format::glb) {
    const Json doc = gltf_json(bytes, format == io::Format::glb);
    if (!doc.is_object()) return refs;
    for (const char* key : {"buffers", "images"}) {
      const auto it = doc.find(key);
      if (it == doc.end() || !it->is_array()) continue;
      for (const Json& item : *it) {
        if (!item.is_object()) continue;
        const auto uri = item.find("uri");
        if (uri != item.end() && uri->is_string() && !starts_with_data_uri(uri->get<std::string>())) {
          refs.push_back(uri->get<std::string>());
        }
      }
    }
  } else if (format == io::Format::obj) {
    std::size_t pos = 0;
    while (pos < bytes.size()) {
      std::size_t end = bytes.find('\n', pos);
      if (end == std::string_view::npos) end = bytes.size();
      std::string_view line = bytes.substr(pos, end - pos);
      pos = end + 1;
      while (!line.empty() && (line.front() == ' ' || line.front() == '\t')) line.remove_prefix(1);
      if (line.substr(0, 7) != "mtllib " && line.substr(0, 7) != "mtllib\t") continue;
      line.remove_prefix(7);
      while (!line.empty() && (line.back() == '\r' || line.back() == ' ' || line.back() == '\t')) line.remove_suffix(1);
      while (!line.empty() && (line.front() == ' ' || line.front() == '\t')) line.remove_prefix(1);
      if (!line.empty()) refs.emplace_back(line);
    }
  }
  return refs;
}

}  // namespace

// ---- Hasher ---------------------------------------------------------------------------------------------------

void Hasher::word(std::uint64_t w) {
  a_ = rotl((a_ ^ w) * 0x87c37b91114253d5ull, 31);
  b_ = rotl((b_ + w) * 0x4cf5ad432745937full, 27) ^ a_;
}

Hasher& Hasher::u64(std::uint64_t v) {
  word(v);
  return *this;
}

Hasher& Hasher::bytes(std::string_view data) {
  word(data.size());
  std::size_t i = 0;
  for (; i + 8 <= data.size(); i += 8) {
    std::uint64_t w;
    std::memcpy(&w, data.data() + i, 8);
    word(w);
  }
  if (i < data.size()) {
    std::uint64_t w = 0;
    std::memcpy(&w, data.data() + i, data.size() - i);
    word(w);
  }
  return *this;
}

std::string Hasher::hex() const {
  return hex64(splitmix(a_ ^ rotl(b_, 17))) + hex64(splitmix(b_ + a_));
}

// ---- keys -----------------------------------------------------------------------------------------------------

std::string input_fingerprint(const fs::path& file) {
  const std::string bytes = io::read_file(file);
  Hasher h;
  h.bytes(bytes);
  const fs::path folder = file.parent_path();
  for (const std::string& uri : external_references(file, bytes)) {
    h.bytes(uri);
    try {
      h.bytes(io::read_file(io::resolve_inside(file, folder, uri)));
    } catch (const io::IoError&) {
      h.bytes("missing");  // the loader decides whether that is an error; the key only has to change with it
    }
  }
  return h.hex();
}

std::string cache_key(std::string_view input_fingerprint, const Json& effective_class,
                      std::string_view algorithm_version) {
  return Hasher().bytes(input_fingerprint).bytes(effective_class.dump()).bytes(algorithm_version).hex();
}

// ---- Cache ----------------------------------------------------------------------------------------------------

Cache::Cache(fs::path output_dir, std::string staging_tag, bool read_only)
    : output_dir_(std::move(output_dir)),
      root_(output_dir_ / kCacheFolder),
      staging_root_(root_ / ("staging-" + staging_tag)) {
  if (read_only) return;
  std::error_code ec;
  fs::create_directories(root_ / "entries", ec);
  if (ec) throw io::IoError(root_ / "entries", "cannot create the cache folder: " + ec.message());
}

fs::path Cache::entry_path(std::string_view relative_path) const {
  return root_ / "entries" / (hex64(path_hash(relative_path)) + ".json");
}

namespace {

// The entry of `relative_path` when it is well formed and is that asset's; null otherwise.
Json read_entry(const fs::path& file, std::string_view relative_path) {
  std::string text;
  try {
    text = io::read_file(file);
  } catch (const io::IoError&) {
    return nullptr;
  }
  Json entry = Json::parse(text, nullptr, false);
  if (!entry.is_object() || entry.value("path", std::string()) != relative_path || !entry.contains("key") ||
      !entry["key"].is_string() || !entry.contains("outputs") || !entry["outputs"].is_array() ||
      !entry.contains("record") || !entry["record"].is_object()) {
    return nullptr;
  }
  return entry;
}

// Why `entry` (from read_entry) does not stand for the outputs of `key`; empty when it does.
std::string stale_reason(const Json& entry, std::string_view key, const fs::path& output_dir) {
  if (entry.is_null()) return "not built yet";
  if (entry["key"].get<std::string>() != key) return "input or config changed";
  for (const Json& out : entry["outputs"]) {
    std::error_code ec;
    if (!out.is_string() || !fs::is_regular_file(output_dir / out.get<std::string>(), ec)) {
      return "an output is missing";
    }
  }
  return {};
}

}  // namespace

std::string Cache::why_stale(std::string_view relative_path, std::string_view key) const {
  return stale_reason(read_entry(entry_path(relative_path), relative_path), key, output_dir_);
}

std::optional<Json> Cache::lookup(std::string_view relative_path, std::string_view key) const {
  Json entry = read_entry(entry_path(relative_path), relative_path);
  if (!stale_reason(entry, key, output_dir_).empty()) return std::nullopt;
  return std::move(entry["record"]);
}

std::vector<std::string> Cache::listed_outputs(std::string_view relative_path) const {
  std::vector<std::string> out;
  const Json entry = read_entry(entry_path(relative_path), relative_path);
  if (entry.is_null()) return out;
  for (const Json& o : entry["outputs"]) {
    if (o.is_string()) out.push_back(o.get<std::string>());
  }
  return out;
}

std::vector<std::string> Cache::entry_paths() const {
  std::vector<std::string> out;
  std::error_code ec;
  for (auto it = fs::directory_iterator(root_ / "entries", ec); !ec && it != fs::directory_iterator();
       it.increment(ec)) {
    if (it->path().extension() != ".json") continue;
    std::string text;
    try {
      text = io::read_file(it->path());
    } catch (const io::IoError&) {
      continue;
    }
    const Json entry = Json::parse(text, nullptr, false);
    if (entry.is_object() && entry.contains("path") && entry["path"].is_string()) {
      const std::string path = entry["path"];
      if (it->path().filename() == entry_path(path).filename()) out.push_back(path);
    }
  }
  std::sort(out.begin(), out.end());
  return out;
}

void Cache::remove_entry(std::string_view relative_path) const {
  std::error_code ec;
  fs::remove(entry_path(relative_path), ec);
}

void Cache::store(std::string_view relative_path, std::string_view key, const std::vector<std::string>& outputs,
                  const Json& record) const {
  const Json entry = {{"path", relative_path}, {"key", key}, {"outputs", outputs}, {"record", record}};
  io::write_file_atomic(entry_path(relative_path), entry.dump(1) + "\n");
}

fs::path Cache::staging_for(std::string_view relative_path) const {
  const fs::path dir = staging_root_ / hex64(path_hash(relative_path));
  std::error_code ec;
  fs::remove_all(dir, ec);
  fs::create_directories(dir, ec);
  if (ec) throw io::IoError(dir, "cannot create a staging folder: " + ec.message());
  return dir;
}

std::vector<std::string> Cache::publish(const fs::path& staging, const fs::path& folder) const {
  std::vector<fs::path> files;
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(staging, ec); !ec && it != fs::recursive_directory_iterator();
       it.increment(ec)) {
    if (it->is_regular_file()) files.push_back(fs::relative(it->path(), staging));
  }
  if (ec) throw io::IoError(staging, "cannot list the staged outputs: " + ec.message());
  std::sort(files.begin(), files.end());
  std::vector<std::string> outputs;
  for (const fs::path& rel : files) {
    const fs::path dest = output_dir_ / folder / rel;
    fs::create_directories(dest.parent_path(), ec);
    if (ec) throw io::IoError(dest.parent_path(), "cannot create the folder: " + ec.message());
    fs::rename(staging / rel, dest, ec);
    if (ec) throw io::IoError(dest, "cannot move the output into place: " + ec.message());
    outputs.push_back((folder / rel).lexically_normal().generic_string());
  }
  fs::remove_all(staging, ec);
  std::sort(outputs.begin(), outputs.end());
  return outputs;
}

void Cache::remove_empty_staging() const {
  std::error_code ec;
  fs::remove(staging_root_, ec);  // fails, harmlessly, when an asset's staging folder is still there
}

void Cache::remove_leftovers(const std::vector<std::string>& relative_paths) const {
  std::error_code ec;
  fs::remove_all(staging_root_, ec);
  std::set<std::string> mine;
  for (const std::string& p : relative_paths) mine.insert(entry_path(p).filename().string());
  std::vector<fs::path> stale;
  for (auto it = fs::directory_iterator(root_ / "entries", ec); !ec && it != fs::directory_iterator();
       it.increment(ec)) {
    const std::string name = it->path().filename().string();
    const auto tmp = name.find(".tmp-");
    if (tmp != std::string::npos && mine.count(name.substr(0, tmp))) stale.push_back(it->path());
  }
  for (const fs::path& p : stale) fs::remove(p, ec);
}

}  // namespace lodforge::batch
