// Mesh files read piece by piece, for inputs larger than the memory a run may use (out-of-core tiling,
// docs/tiling.md): one pass over the file hands each vertex position and each polygon to the caller and
// holds nothing itself. Binary PLY and OBJ, positions and polygons only: a file with normals, UVs, colours or
// several materials is refused (the caller would lose them), naming what it has.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "lodforge/core/vec.hpp"

namespace lodforge::io {

// The read buffer a stream holds (a longer line grows it).
inline constexpr std::size_t kStreamBufferBytes = std::size_t{1} << 20;

// Whether stream_mesh() reads this kind of file: .ply (binary) and .obj, by extension.
bool streamable(const std::filesystem::path& path);

// What a cheap look at the file tells (the PLY header; for OBJ a scan counting `v` and `f` lines and the
// corners of the faces, without parsing numbers).
struct StreamCounts {
  std::uint64_t vertices = 0;
  std::uint64_t triangles = 0;  // after fan triangulation of polygons (PLY: one per face, a lower bound)
  bool readable = true;         // stream_mesh() reads this encoding (false for an ASCII PLY)
};
StreamCounts stream_counts(const std::filesystem::path& path);

struct StreamSinks {
  std::function<void(const Vec3f&)> vertex;                          // in file order
  std::function<void(std::span<const std::uint32_t>)> face;          // 0-based vertex ids, at least 3
};

// What a pass found beside the geometry.
struct StreamResult {
  std::vector<std::string> warnings;  // statements skipped (OBJ)
  std::string material;               // OBJ: the one `usemtl` name its faces use ("" without)
  std::vector<std::string> mtllibs;   // OBJ: its `mtllib` lines, to write back
};

// One pass over the file. Every polygon's ids are below the number of vertices given before it (PLY: the
// vertex element must precede the face element; OBJ: a face may use only vertices defined above it). An OBJ
// whose faces use more than one material is refused (a streamed mesh has one material slot).
// Throws IoError naming the file and the problem.
StreamResult stream_mesh(const std::filesystem::path& path, const StreamSinks& sinks);

}  // namespace lodforge::io
