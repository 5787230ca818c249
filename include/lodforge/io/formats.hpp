// Per-format readers and writers behind load_asset/save_asset. Each reader validates everything it reads
// (counts against file size, index ranges) and throws IoError naming the file.
#pragma once

#include <filesystem>
#include <string_view>

#include "lodforge/io/asset.hpp"

namespace lodforge::io {

// Text/binary formats (own readers: OpenMesh's IO drops non-manifold faces, per-corner UVs of n-gons, OBJ
// groups and material names, which a lossless round trip needs).
Asset read_obj(const std::filesystem::path& path, std::string_view bytes, const LoadOptions& options);
Asset read_off(const std::filesystem::path& path, std::string_view bytes, const LoadOptions& options);
Asset read_ply(const std::filesystem::path& path, std::string_view bytes, const LoadOptions& options);
Asset read_stl(const std::filesystem::path& path, std::string_view bytes, const LoadOptions& options);
Asset read_gltf(const std::filesystem::path& path, const LoadOptions& options);  // .gltf and .glb

std::string write_obj(const Asset& asset, const std::filesystem::path& path);
std::string write_off(const Asset& asset);
std::string write_ply(const Asset& asset, bool binary);
std::string write_stl(const Asset& asset, bool binary);
// Writes the file(s) itself (external .bin and copied images for .gltf), each atomically.
void write_gltf(const Asset& asset, const std::filesystem::path& path, const SaveOptions& options);

}  // namespace lodforge::io
