// Loading and saving assets. An Asset is what one file holds: one or more meshes plus, for glTF, the whole
// document (scene graph, materials, skins, animations, images, extensions) so that writing replaces mesh data
// only and everything else round-trips unchanged.
#pragma once

#include <array>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "lodforge/core/mesh.hpp"
#include "lodforge/core/vec.hpp"

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
  // glTF: per mesh, the world transforms (4x4, column-major as in glTF) of the nodes of the default scene (else
  // of every root node) that show it, one per instance. Empty for a mesh no node shows, and for the other
  // formats: identity. A skinned node's own transform is not applied (glTF: the joints place the mesh).
  std::vector<std::vector<std::array<double, 16>>> mesh_transforms;

  // For OBJ: the mtllib lines of the source, written back unchanged.
  std::vector<std::string> obj_mtllibs;
  // For PLY: whether the source was binary (writers keep the encoding); STL likewise.
  bool binary = false;
};

struct LoadOptions {
  // Hard caps against hostile headers; a file claiming more is rejected before anything is allocated.
  std::uint64_t max_elements = 1ull << 31;
};

// The asset's meshes as the scene shows them: every instance of every mesh, positions in world space (see
// Asset::mesh_transforms), as one mesh of position-only faces (for measuring, not for writing).
Mesh world_surface(const Asset& asset);
// Bounds of world_surface(asset), without building it.
Bounds3 world_bounds(const Asset& asset);
// How much larger mesh `m` shows in world space than in its own coordinates: the largest scale of its
// instances' transforms (1 without transforms). A distance in the world divided by it is one in the mesh.
double world_scale(const Asset& asset, std::size_t m);

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
