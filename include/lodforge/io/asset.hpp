// Loading and saving assets. An Asset is what one file holds: one or more meshes plus, for glTF, the whole
// document (scene graph, materials, skins, animations, images, extensions) so that writing replaces mesh data
// only and everything else round-trips unchanged.
#pragma once

#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "lodforge/core/mesh.hpp"

namespace lodforge::io {

enum class Format { gltf, glb, obj, ply, off, stl };

// Format from the file extension (case-insensitive); throws IoError for an unknown extension.
Format format_from_path(const std::filesystem::path& path);
const char* format_name(Format f);

// Bad data or an I/O failure. what() is one line: "<file>: <problem>".
class IoError : public std::runtime_error {
 public:
  IoError(const std::filesystem::path& file, const std::string& problem);
  const std::filesystem::path& file() const { return file_; }
  const std::string& problem() const { return problem_; }

 private:
  std::filesystem::path file_;
  std::string problem_;
};

struct GltfDocument;  // opaque: the source glTF document (defined in src/io/gltf_internal.hpp)

struct Asset {
  std::filesystem::path source;
  Format format = Format::obj;
  std::vector<Mesh> meshes;           // glTF: one per glTF mesh (primitives are material slots)
  std::vector<std::string> warnings;  // things carried or converted that the user should know about
  std::shared_ptr<const GltfDocument> gltf;  // set for glTF/GLB sources

  // For OBJ: the mtllib lines of the source, written back unchanged.
  std::vector<std::string> obj_mtllibs;
  // For PLY: whether the source was binary (writers keep the encoding); STL likewise.
  bool binary = false;
};

struct LoadOptions {
  // Hard caps against hostile headers; a file claiming more is rejected before anything is allocated.
  std::uint64_t max_elements = 1ull << 31;
};

// Loads any supported file. Throws IoError (naming the file and the problem) on any bad input.
Asset load_asset(const std::filesystem::path& path, const LoadOptions& options = {});

struct SaveOptions {
  bool pretty_json = false;  // .gltf JSON indentation
};

// Saves `asset` to `path` in the format of the path's extension, atomically (temporary file, then rename).
// glTF output needs a glTF source asset or builds a minimal document; OBJ/PLY/OFF/STL write meshes[0]..
// (several meshes are concatenated). Throws IoError.
void save_asset(const Asset& asset, const std::filesystem::path& path, const SaveOptions& options = {});

}  // namespace lodforge::io
