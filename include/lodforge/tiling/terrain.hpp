// Terrain: a height map cut into square patches, each with its own LOD chain, stitched without cracks.
//
//   terrain::Options o;                    // 64 x 64 cells a patch, occluder LODs at 25%, 6.25%, 1.5%
//   const terrain::Result r = terrain::build(map, o);
//   r.patches[p].lods[k]                   // patch p at level k (0: full resolution), skirts included
//
// How a level is made (docs/terrain.md):
// 1. Every wall between two patches (and every side on the map's edge) is simplified once per level, as a
//    polyline: its corners, the samples next to a hole and as many others as the level keeps stay; each other
//    sample moves onto the nearer kept one. Both patches of a wall get the same polyline, bit for bit.
// 2. In conservative modes the kept samples are lowered (occluder) or raised (bounding) just enough that the
//    triangles the move made stay below (above) the height map everywhere, checked exactly against the grid.
// 3. Each patch is then simplified by the triangle engine with its outline locked, in the same conservative
//    mode, so that it nests with the height map too.
// 4. Skirts: every side a patch shares with another gets vertical triangles hanging from its polyline down to
//    below the lowest polyline of any level on that wall, so patches at different levels leave no gap.
// A patch's output depends only on the samples of its cells and of the cells one sample around them, so a
// height map changed in one region rebuilds only the patches within one sample of it (`previous`).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "lodforge/core/mesh.hpp"
#include "lodforge/io/heightmap.hpp"
#include "lodforge/simplify/simplify.hpp"

namespace lodforge::terrain {

// One level of every patch's chain. The finest is level 1; level 0 is the full-resolution patch.
struct LevelSpec {
  // Share of a full patch's triangles (a partial patch at the map's edge keeps the same share of its own).
  double ratio = 0.25;
  // Also stop where the engine's error would pass this distance (model units); negative = no error budget.
  double max_error = -1.0;
};

struct Options {
  std::size_t patch_cells = 64;  // cells per patch side (65 x 65 samples): 1025 x 1025 maps give 16 x 16
  std::vector<LevelSpec> levels{{0.25, -1.0}, {0.0625, -1.0}, {0.015625, -1.0}};
  Conservative conservative = Conservative::occluder;
  bool skirts = true;
  unsigned threads = 0;  // 0 = all cores; the output is the same for any count

  // Every problem at once, one line each; empty = valid.
  std::vector<std::string> validate() const;
};

struct Patch {
  std::size_t column = 0, row = 0;              // place in the patch grid
  std::size_t first_column = 0, first_row = 0;  // its first sample
  std::size_t columns = 0, rows = 0;            // cells it spans (patch_cells, less at the map's far edges)
  std::vector<Mesh> lods;                       // levels 0..levels.size(), skirts included
  std::vector<std::size_t> surface_triangles;   // per level: triangles without the skirts
  std::vector<std::uint16_t> inputs;            // the samples its output depends on (its cells and one around)
  bool rebuilt = true;                          // false: taken from `previous` unchanged
};

struct Result {
  std::size_t patches_x = 0, patches_z = 0;  // patch grid (columns, rows)
  std::vector<Patch> patches;                // row by row, north first
  std::size_t rebuilt = 0;                   // patches built by this call (the others came from `previous`)
  std::string settings;                      // the map's size and layout and the options, as text: a
                                             // `previous` with other settings is not reused
};

// Cuts, simplifies and stitches `map`. `previous`: an earlier result for the same map size and options; a
// patch whose inputs are unchanged is copied from it. Throws std::invalid_argument on invalid options.
Result build(const io::HeightMap& map, const Options& options, const Result* previous = nullptr);

// `result` as bytes, for a later build's `previous` across runs (the batch runner keeps it in its cache
// folder); empty when a patch mesh holds what the format does not keep (attributes, materials), which build()
// never makes.
std::string encode_result(const Result& result);
// The result encode_result() wrote, bit for bit; nullopt for bytes that are not one (truncated, another
// version), so that a damaged file only costs a full build.
std::optional<Result> decode_result(std::string_view bytes);

// Every patch's surface at `level` (skirts left out) as one mesh, and per face the colour of its patch's
// triangle count: the share of a full patch's triangles on a log scale from 1/1024 (blue) through 1/32 (green)
// to all (red).
Mesh level_surface(const Result& result, std::size_t level, std::size_t patch_cells,
                   std::vector<std::array<std::uint8_t, 3>>* face_colours = nullptr);

// The colour level_surface gives a patch with `surface_triangles` (skirts left out): its share of a full
// patch's triangles (patch_cells² cells, two each) on that log scale.
std::array<std::uint8_t, 3> patch_colour(std::size_t surface_triangles, std::size_t patch_cells);

// The full-resolution surface of the whole map (no skirts), positions as the patches have them: for measuring.
Mesh full_surface(const io::HeightMap& map);

}  // namespace lodforge::terrain
