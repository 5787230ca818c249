// Height maps: a grid of 16-bit samples, read from a 16-bit (or 8-bit) grey PNG or a raw little-endian
// `.r16` file, and how its samples become positions (spacing, vertical scale, no-data value), from a sidecar
// JSON beside the file (`<file>.json`, e.g. `helens.r16.json`) over the caller's defaults.
//
//   io::HeightMapLayout layout;                       // the class's defaults (config or command line)
//   io::HeightMap map = io::load_heightmap(path, layout);  // the sidecar, when there is one, wins
//
// A raw file has no header: its size comes from the sidecar, else from the layout, else from the last
// "<W>x<H>" in its file name ("helens_327x466_u16le.r16"), else a square file is taken as square. docs/terrain.md.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace lodforge::io {

// How samples become positions: column c, row r, sample s give x = c × spacing_x, z = r × spacing_z (row 0,
// the file's first row, is north at z = 0; +z is south, +x east, y up as in glTF), y = height_offset +
// height_scale × s. A sample equal to `nodata` is a hole.
struct HeightMapLayout {
  std::size_t width = 0, height = 0;  // raw files: columns and rows (0: from the sidecar or the file name)
  double spacing_x = 1.0, spacing_z = 1.0;
  double height_scale = 1.0, height_offset = 0.0;
  std::optional<std::uint16_t> nodata;

  // Every problem at once, one line each; empty = valid.
  std::vector<std::string> validate() const;
};

struct HeightMap {
  std::size_t width = 0, height = 0;   // columns, rows (both at least 2)
  std::vector<std::uint16_t> samples;  // row-major, the first (north) row first
  HeightMapLayout layout;              // as applied (the sidecar over the caller's defaults)
  std::vector<std::string> warnings;   // what the reader converted (an 8-bit PNG, a grey+alpha PNG)

  std::uint16_t sample(std::size_t column, std::size_t row) const { return samples[row * width + column]; }
  bool hole(std::size_t column, std::size_t row) const {
    return layout.nodata && sample(column, row) == *layout.nodata;
  }
  double x(std::size_t column) const { return static_cast<double>(column) * layout.spacing_x; }
  double z(std::size_t row) const { return static_cast<double>(row) * layout.spacing_z; }
  double y(std::size_t column, std::size_t row) const {
    return layout.height_offset + layout.height_scale * static_cast<double>(sample(column, row));
  }
};

// Whether `path` names a file the height-map reader reads (.png, .r16; any case). The batch runner reads such
// a file as a height map only where a terrain class matches it.
bool is_heightmap_path(const std::filesystem::path& path);

// Reads `path` (a PNG or a `.r16`) with `defaults` under its sidecar `<path>.json` when one exists (keys
// width, height, spacing or spacing_x/spacing_z, height_scale, height_offset, nodata). Throws IoError naming the
// file and the problem: unreadable, not a grey PNG, a raw size that does not match the file, a bad sidecar.
HeightMap load_heightmap(const std::filesystem::path& path, const HeightMapLayout& defaults = {});

// Writes `map`'s samples as a 16-bit grey PNG (for tests and the benchmark's generated maps), atomically.
void save_heightmap_png(const HeightMap& map, const std::filesystem::path& path);

}  // namespace lodforge::io
