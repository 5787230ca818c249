// The incremental-run cache: which assets a re-run can skip.
//
// Layout under OUT_DIR/.lodforge-cache/ (the manifest is one small JSON file per asset, so that shards writing
// into one shared OUT_DIR never contend for a file, and a killed run loses at most the entries in flight):
//   entries/<16 hex digits of path_hash(relative path)>.json
//       {"path": "props/crate.obj", "key": "<32 hex>", "outputs": ["props/crate_LOD1.obj", ...],
//        "record": {...the asset's report record...}}
//   staging-<K>-of-<N>/<16 hex>/   one asset's outputs while they are written (a shard only touches its own)
//
// Key = hash(input file bytes + bytes of every external file it references (glTF buffers and images, OBJ
// mtllibs), effective class config JSON, algorithm version). An entry is written only after every output of its
// asset has been renamed into place, so an entry always describes complete files; a run killed before that
// redoes the asset, and its staging leftovers are removed when the same shard starts again.
#pragma once

#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace lodforge::batch {

inline constexpr const char* kCacheFolder = ".lodforge-cache";

// A streaming 128-bit non-cryptographic hash (two 64-bit multiply-rotate lanes over 8-byte words, finished by
// splitmix64): fast enough to hash every input byte of a library each run, fixed by definition so keys survive
// compiler and library upgrades. Not collision-resistant against an adversary; nothing here needs that.
class Hasher {
 public:
  Hasher& bytes(std::string_view data);  // length-prefixed: bytes("ab").bytes("c") != bytes("a").bytes("bc")
  Hasher& u64(std::uint64_t v);
  template <class T>
  Hasher& array(const std::vector<T>& values) {  // trivially copyable T, hashed as its bytes
    return bytes(std::string_view(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T)));
  }
  std::string hex() const;  // 32 lowercase hex digits

 private:
  void word(std::uint64_t w);
  std::uint64_t a_ = 0x9e3779b97f4a7c15ull, b_ = 0xc2b2ae3d27d4eb4full;
};

// Hash of the file's bytes and of the local files it references (glTF buffers/images, OBJ mtllib), in the
// order they are referenced; a missing or unreadable reference contributes its URI and "missing". Throws
// io::IoError when the file itself cannot be read.
std::string input_fingerprint(const std::filesystem::path& file);

std::string cache_key(std::string_view input_fingerprint, const nlohmann::json& effective_class,
                      std::string_view algorithm_version);

class Cache {
 public:
  // `staging_tag` names this process's staging folder ("0-of-1" for an unsharded run). A read-only cache
  // (`run --dry-run`) creates nothing; only lookup(), why_stale() and listed_outputs() may be used on it.
  Cache(std::filesystem::path output_dir, std::string staging_tag, bool read_only = false);

  // The stored report record when the entry's key is `key` and every listed output exists.
  std::optional<nlohmann::json> lookup(std::string_view relative_path, std::string_view key) const;
  // Why lookup() would miss, in words ("not built yet", "input or config changed", "an output is missing");
  // empty when it would hit.
  std::string why_stale(std::string_view relative_path, std::string_view key) const;
  // The outputs the asset's entry lists, whatever its key (none without an entry): what an earlier run wrote.
  std::vector<std::string> listed_outputs(std::string_view relative_path) const;
  // The relative paths of every entry ('/'-separated, sorted), and the removal of one entry.
  std::vector<std::string> entry_paths() const;
  void remove_entry(std::string_view relative_path) const;
  // Writes the entry atomically. Call only after every output is in place. Throws io::IoError.
  void store(std::string_view relative_path, std::string_view key, const std::vector<std::string>& outputs,
             const nlohmann::json& record) const;

  // A fresh, empty staging folder for one asset's outputs (created; emptied when it existed).
  std::filesystem::path staging_for(std::string_view relative_path) const;
  // Renames every file under `staging` to the same relative place under OUT_DIR/`folder` (creating folders),
  // removes `staging`, and returns the outputs' paths relative to OUT_DIR ('/'-separated, sorted). Each rename is
  // atomic, so a reader sees either the old or the new version of each file, never a partial one.
  std::vector<std::string> publish(const std::filesystem::path& staging, const std::filesystem::path& folder) const;

  // Removes what a killed run of the same shard left behind: its staging folder, and temporary files of
  // the entries of `relative_paths`.
  void remove_leftovers(const std::vector<std::string>& relative_paths) const;

  // Removes this shard's staging folder when nothing is left in it (the end of a run).
  void remove_empty_staging() const;

  const std::filesystem::path& root() const { return root_; }

 private:
  std::filesystem::path entry_path(std::string_view relative_path) const;
  std::filesystem::path output_dir_, root_, staging_root_;
};

}  // namespace lodforge::batch
