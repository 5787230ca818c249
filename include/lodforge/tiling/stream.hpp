// Out-of-core simplification: a mesh file larger than the memory a run may use is read twice, front to back,
// and cut into spatial tiles on disk as it is read; each tile is then loaded alone and simplified with its cut
// vertices locked, the tile outputs are stitched, and the stitched mesh (a few times the target) is finished in
// memory by simplify_maybe_tiled(). Only the vertex positions (12 bytes a vertex) and two per-vertex ids are
// held for the whole file (docs/tiling.md). Positions and faces only (io/stream.hpp).
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "lodforge/io/stream.hpp"
#include "lodforge/simplify/simplify.hpp"

namespace lodforge::tiling {

// Whether a run of `options` over the file at `path` under `limit` bytes should stream it, and with what tiles.
struct StreamPlan {
  io::StreamCounts counts;
  std::size_t whole_bytes = 0;   // estimated peak of loading the file whole and taking the tiled path
  bool stream = false;           // whole_bytes is over the limit and the file can be streamed (not ASCII PLY)
  std::size_t stream_bytes = 0;  // estimated peak streamed with `tile_triangles`
  std::size_t tile_triangles = 0;
  bool fits = true;              // streaming fits the limit (tiles of at least kMinStreamTile triangles)
};
inline constexpr std::size_t kMinStreamTile = 1000;
// What the estimates leave to the program itself (code, thread stacks, the allocator's own; about 7.5 MB
// measured for `lodforge simplify` on a one-triangle file).
inline constexpr std::size_t kProgramBytes = std::size_t{8} << 20;
// Per vertex held while streaming: the positions, the weld's and the cut's ids, the weld's sort order.
inline constexpr std::size_t kStreamBytesPerVertex = 24;
StreamPlan plan_stream(const std::filesystem::path& path, const SimplifyOptions& options, std::size_t limit,
                       unsigned workers);

struct StreamedRun {
  SimplifyResult result;             // its mesh has the file's one material slot (OBJ `usemtl`), if any
  std::vector<std::string> warnings;
  std::vector<std::string> mtllibs;  // OBJ: to write back
  std::size_t input_vertices = 0;
  std::size_t tiles = 0;
  std::size_t degenerate_dropped = 0;  // triangles with a repeated corner after the weld
};
// The out-of-core run: tiles of at most `tile_triangles` written under `scratch` (created; its tile files are
// removed as they are read). The result's triangles_before counts the triangles after fan triangulation.
// Deterministic for any thread count. Throws io::IoError for a bad file, std::invalid_argument as simplify() and
// for options that cannot stream (an engine or budget that cannot tile, locked vertices, a vertex mirror map).
// `vertices_hint` (plan_stream()'s count, 0: none) sizes the positions at once instead of by doubling.
StreamedRun simplify_streamed(const std::filesystem::path& path, const SimplifyOptions& options,
                              std::size_t tile_triangles, const std::filesystem::path& scratch,
                              std::size_t memory_limit = 0, std::uint64_t vertices_hint = 0);

}  // namespace lodforge::tiling
