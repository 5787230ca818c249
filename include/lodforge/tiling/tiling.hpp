// Tiled simplification of huge meshes: the mesh is cut into spatial tiles by triangle centroid, each tile is
// simplified by the chosen triangle engine with its cut-border vertices locked (in parallel, one task per
// tile), the tiles are stitched back (border vertices never moved, so they weld exactly), and the mesh is cut
// again on a grid shifted by part of a tile so that every former border is interior, until the target is met.
// This part comes after simplify: it calls simplify() per tile, and simplify() knows nothing of it. The batch
// runner and `lodforge simplify` call simplify_maybe_tiled(), which picks the path (docs/tiling.md).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "lodforge/core/mesh.hpp"
#include "lodforge/simplify/simplify.hpp"

namespace lodforge {

// simplify() for a mesh of any size: the tiled path where SimplifyOptions::tiling asks for it (on, or automatic
// and at least tiling::kAutoThresholdTriangles triangles after polygons are triangulated and repeated faces
// dropped) and the engine and options allow it (tiling::applies()); otherwise exactly simplify(mesh, options).
// Throws std::invalid_argument as simplify() does.
SimplifyResult simplify_maybe_tiled(const Mesh& mesh, const SimplifyOptions& options);

}  // namespace lodforge

namespace lodforge::tiling {

// Triangles from which TilingMode::automatic tiles a mesh.
inline constexpr std::size_t kAutoThresholdTriangles = 1'000'000;
// Triangles from which the tiled path clusters first (SimplifyOptions::cluster_stage automatic).
inline constexpr std::size_t kAutoClusterTriangles = 4'000'000;
// Passes at most (cut, simplify, stitch); the last one runs untiled.
inline constexpr int kMaxPasses = 8;
// The first tiled pass takes the mesh to this many times the target; the rest is made by an untiled run once
// the mesh has at most max(tile_triangles, min(1.5 x that, kFinalTiles x tile_triangles)) triangles, else by
// further tiled passes straight to the target.
inline constexpr std::size_t kOversample = 3;
inline constexpr std::size_t kFinalTiles = 4;

// Whether simplify_maybe_tiled() takes the tiled path for this (triangulated, repeat-free) mesh: tiling on, or
// automatic and at least kAutoThresholdTriangles triangles; a triangle engine (edge_collapse, multiple_choice);
// no error budget to verify (budgets stay on the untiled path, which verifies them).
bool applies(const Mesh& triangles, const SimplifyOptions& options);
// Why the options cannot tile at all (a sentence fragment for messages), or nullptr where they can.
const char* why_not_tileable(const SimplifyOptions& options);

// One cut of a mesh into tiles: cell size `cell` on a grid whose origin is the bounding box's minimum moved
// back by `shift` cells on every axis; each triangle goes to the cell of its centroid. Tiles are the occupied
// cells in lexicographic cell order; each lists its triangles in ascending order.
struct TileCut {
  double cell = 0;
  double shift = 0;
  std::vector<std::vector<std::uint32_t>> tiles;  // triangle ids per tile
  std::vector<std::uint8_t> border;               // per vertex: used by triangles of two or more tiles
};
// `triangles` holds triangles only. `tile_triangles` sets the cell size: cells of about that many triangles,
// from the surface area per triangle.
TileCut cut(const Mesh& triangles, std::size_t tile_triangles, double shift);
// The grid shift of pass `pass` (0, 1/2, 1/4, 3/4, ... of a cell): consecutive passes never share a cut plane.
double pass_shift(int pass);

// The sub-mesh of `triangles` made of `faces` (ascending): the vertices and wedges they use, in ascending
// order, with every vertex and wedge attribute; materials, groups, formats and the name as the source's.
// `vertices` receives the source vertex of each sub-mesh vertex.
Mesh extract(const Mesh& triangles, const std::vector<std::uint32_t>& faces, std::vector<std::uint32_t>& vertices);

// ---- memory limit (lodforge simplify --memory-limit; docs/tiling.md) ----

// The smallest limit accepted (small enough for tests).
inline constexpr std::size_t kMinMemoryLimit = std::size_t{16} << 20;
// Peak heap growth per input triangle, measured on the generated terrain (docs/tiling.md): one engine run over
// the whole mesh, and the tiled path's own arrays (cut keys, tile lists, stitched meshes) over the whole mesh.
inline constexpr std::size_t kUntiledBytesPerTriangle = 170;
inline constexpr std::size_t kTiledBytesPerTriangle = 48;

// "512M", "4G", "1048576" (bytes); suffixes K, M, G, T (powers of 1024), any case, optionally followed by "B"
// or "iB". Throws std::invalid_argument naming the text when it is malformed or below kMinMemoryLimit.
std::size_t parse_memory_size(const std::string& text);

// The bytes `mesh`'s arrays hold.
std::size_t mesh_bytes(const Mesh& mesh);

// What a run of `options` over `mesh` needs under `limit` bytes (of which the estimates may use 7/8, the rest
// being left for what they do not count): untiled as asked when its estimate fits;
// else the tiled path with tiles small enough to fit (`tile_triangles`, at most options.tile_triangles); else
// nothing fits (the mesh held in memory plus the tiled path's arrays exceed the limit, or the engine or a
// verified budget cannot tile). `workers`: tiles simplified at once.
struct MemoryPlan {
  std::size_t input_bytes = 0;    // the mesh as held
  std::size_t untiled_bytes = 0;  // estimated peak of one engine run, the input included
  std::size_t tiled_bytes = 0;    // estimated peak of the tiled path with `tile_triangles`, the input included
  std::size_t tile_triangles = 0;
  bool force_tiling = false;  // run tiled with `tile_triangles` (and without the cluster stage)
  bool fits = true;
  // Where force_tiling is set, makes `options` run as planned: tiled, in tiles of `tile_triangles`, without
  // the cluster stage (its arrays over the whole mesh are not in the tiled estimate).
  void apply(SimplifyOptions& options) const;
};
MemoryPlan plan_memory(const Mesh& mesh, const SimplifyOptions& options, std::size_t limit, unsigned workers);

// The tiled simplification (simplify_maybe_tiled() calls it when applies() holds). `triangles` holds triangles only and
// no repeated faces. Deterministic: the output is the same for any thread count.
SimplifyResult simplify_tiled(const Mesh& triangles, const SimplifyOptions& options);

}  // namespace lodforge::tiling
