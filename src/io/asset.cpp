#include "lodforge/io/asset.hpp"

#include <algorithm>
#include <cctype>

#include "lodforge/io/file.hpp"
#include "lodforge/io/formats.hpp"

namespace lodforge::io {

Format format_from_path(const std::filesystem::path& path) {
  const std::string ext = lower_extension(path);
  if (ext == ".gltf") return Format::gltf;
  if (ext == ".glb") return Format::glb;
  if (ext == ".obj") return Format::obj;
  if (ext == ".ply") return Format::ply;
  if (ext == ".off") return Format::off;
  if (ext == ".stl") return Format::stl;
  throw IoError(path, "unsupported file extension '" + ext + "' (supported: .gltf .glb .obj .ply .off .stl)");
}

const char* format_name(Format f) {
  switch (f) {
    case Format::gltf: return "glTF";
    case Format::glb: return "GLB";
    case Format::obj: return "OBJ";
    case Format::ply: return "PLY";
    case Format::off: return "OFF";
    case Format::stl: return "STL";
  }
  return "?";
}

Asset load_asset(const std::filesystem::path& path, const LoadOptions& options) {
  const Format format = format_from_path(path);
  if (format == Format::gltf || format == Format::glb) return read_gltf(path, options);
  const std::string bytes = read_file(path);
  if (bytes.empty()) throw IoError(path, "file is empty");
  switch (format) {
    case Format::obj: return read_obj(path, bytes, options);
    case Format::ply: return read_ply(path, bytes, options);
    case Format::off: return read_off(path, bytes, options);
    case Format::stl: return read_stl(path, bytes, options);
    default: break;
  }
  throw IoError(path, "unsupported format");
}

void save_asset(const Asset& asset, const std::filesystem::path& path, const SaveOptions& options) {
  const Format format = format_from_path(path);
  switch (format) {
    case Format::gltf:
    case Format::glb: write_gltf(asset, path, options); return;
    case Format::obj: write_file_atomic(path, write_obj(asset, path)); return;
    case Format::ply: write_file_atomic(path, write_ply(asset, asset.format == Format::ply ? asset.binary : true)); return;
    case Format::off: write_file_atomic(path, write_off(asset)); return;
    case Format::stl: write_file_atomic(path, write_stl(asset, asset.format == Format::stl ? asset.binary : true)); return;
  }
}

}  // namespace lodforge::io
