// Private to the tiling part: one tile's run and the stitch of tile outputs, shared by the in-memory tiled
// path (tiling.cpp) and the out-of-core one (stream.cpp).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "lodforge/core/mesh.hpp"
#include "lodforge/simplify/simplify.hpp"

namespace lodforge::tiling::detail {

// Cell keys: a cell index per axis in kCellBits bits (clamped), axes packed x, y, z.
inline constexpr int kCellBits = 21;
inline constexpr std::int64_t kCellMax = (std::int64_t{1} << kCellBits) - 1;
inline std::uint64_t cell_key(const Vec3d& p, const Vec3d& origin, double cell) {
  std::uint64_t k = 0;
  for (int a = 0; a < 3; ++a) {
    const double x = std::floor((p[a] - origin[a]) / cell);
    const std::int64_t i = std::isfinite(x) ? std::clamp<std::int64_t>(static_cast<std::int64_t>(std::clamp(x, -1.0, double(kCellMax))), 0, kCellMax) : 0;
    k = (k << kCellBits) | static_cast<std::uint64_t>(i);
  }
  return k;
}

// The global target of a run over `n` triangles (as every engine reads the options).
std::size_t global_target(const SimplifyOptions& o, std::size_t n);
// applies() without the size: whether these options may tile a mesh at all.
bool may_tile(const SimplifyOptions& options);

// The cell side that cuts about `tile_triangles` of a surface of `area` made of `triangles` triangles
// (s^2 = area per triangle x triangles per tile), never so small that a cell index overflows its bits.
double cell_size(double area, std::size_t triangles, std::size_t tile_triangles, double diagonal);

// The options every tile runs with: no tiling, no mirror (a tile does not hold both sides), no ratio (each
// tile gets a count), no caller locks (each tile gets its own), a relative QEM cap made absolute on the
// whole mesh's diagonal.
SimplifyOptions tile_base_options(const SimplifyOptions& options, double diagonal);
// The threads these options allow (their `threads`, or the arena's).
unsigned concurrency(const SimplifyOptions& options);
// Each tile's engine threads: tiles are the parallel unit, and an engine's own threads only help when there
// are fewer tiles than twice the cores.
unsigned tile_threads(const SimplifyOptions& options, std::size_t tiles);
// The first pass's target: kOversample x the global target where that is below half of the `n` triangles,
// so that the final untiled run spends the last collapses where the whole mesh's error is least.
std::size_t first_pass_target(std::size_t target, std::size_t n);
// The cluster stage's target for a mesh of `n` triangles going to `target` (SimplifyOptions::cluster_stage);
// 0: no cluster stage.
std::size_t cluster_stage_target(const SimplifyOptions& options, std::size_t n, std::size_t target);
// A tile's share of `pass_target` by its `tile_triangles` of the pass's `pass_triangles`, rounded to nearest.
std::size_t tile_share(std::size_t pass_target, std::size_t tile_triangles, std::size_t pass_triangles);
// Folds one run's statistics into a total (largest error and seam stage, summed counts).
void add_stats(SimplifyResult& total, const SimplifyResult& r);

// One tile's run: its output, the output vertex of each tracked (locked) sub-mesh vertex with its source vertex.
struct TileRun {
  SimplifyResult result;
  std::vector<std::uint32_t> tracked_source;  // source vertex (in the pass's mesh), ascending by output vertex
  std::vector<std::uint32_t> tracked_output;  // output vertex of each
};

// Fills run.tracked_*: `locked` (ascending sub-mesh vertices) found in run.result.mesh, `source_of` the
// source vertex of each sub-mesh vertex. Throws std::logic_error if one moved or vanished.
void track_locked(TileRun& run, const Mesh& sub, const std::vector<std::uint32_t>& locked,
                  const std::vector<std::uint32_t>& source_of, std::size_t tile);

// The tiles' outputs as one mesh, in tile order: tracked vertices (borders, user locks) weld to one vertex each,
// and their wedges with the same attributes to one wedge. `like` gives the attribute layout and materials;
// `source_vertices` is the vertex count of the mesh the tiles were cut from, and `locked` (one per such vertex)
// becomes the user locks of the stitched mesh.
Mesh stitch(const Mesh& like, std::size_t source_vertices, const std::vector<TileRun>& runs,
            std::vector<std::uint8_t>& locked, const SimplifyOptions& options);

}  // namespace lodforge::tiling::detail
