// Height maps for the terrain tests: a small raw map of rolling hills.
#pragma once

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <string>

#include "lodforge/io/file.hpp"

namespace lodforge::testing {

// Writes `dir`/hills_97x65.r16: 97 x 65 little-endian 16-bit samples of rolling hills with a little noise (its
// size from its name). Returns its path.
inline std::filesystem::path write_hills_r16(const std::filesystem::path& dir) {
  std::string bytes;
  for (int r = 0; r < 65; ++r) {
    for (int c = 0; c < 97; ++c) {
      const auto v = static_cast<std::uint16_t>(3000 + 800 * std::sin(0.11 * c) * std::cos(0.07 * r) + (c * r) % 17);
      bytes.push_back(static_cast<char>(v & 0xff));
      bytes.push_back(static_cast<char>(v >> 8));
    }
  }
  const auto path = dir / "hills_97x65.r16";
  io::write_file_atomic(path, bytes);
  return path;
}

}  // namespace lodforge::testing
