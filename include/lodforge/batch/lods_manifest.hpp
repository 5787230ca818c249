// lods.json, the engine-side LOD manifest `lodforge run` writes beside its outputs (docs/lods-json.md): per asset
// and per LOD the file to load (and its place in the MSFT_lod chain), triangles, the measured Hausdorff error,
// whether the level reuses the mesh of the level before, and where it switches in, as Unreal screen size,
// Unity LODGroup relative screen height and Godot visibility range.
//
//   const nlohmann::json manifest = lods_manifest(report, previous_manifest, /*keep_unlisted=*/true);
//   write_lods_manifest(manifest, out / "lods.json");
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>

namespace lodforge::batch {

inline constexpr int kLodsManifestVersion = 1;

// The manifest of a run, from its report.json (assets, effective_config: gltf_lods and lod_switch) alone.
// Assets that succeeded get an entry built from their records; assets that failed or were not started keep the
// entry of `previous` (the manifest the last run wrote; null or malformed: none), as they keep their outputs.
// Entries of `previous` for assets the report skips or no longer lists stay only with `keep_unlisted` (their
// files stay unless pruned). Keys sorted, assets sorted by path: the same report gives the same bytes.
nlohmann::json lods_manifest(const nlohmann::json& report, const nlohmann::json& previous, bool keep_unlisted);

// The manifest at `path`, or null when there is none or it is not a manifest (a run then starts afresh).
nlohmann::json read_lods_manifest(const std::filesystem::path& path);

// Atomically (temporary file + rename).
void write_lods_manifest(const nlohmann::json& manifest, const std::filesystem::path& path);

}  // namespace lodforge::batch
