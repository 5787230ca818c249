// Welding render vertices into surface vertices while keeping them as wedges (explicit seams).
#pragma once

#include "lodforge/core/mesh.hpp"

#include <bit>
#include <cstdint>

namespace lodforge {

// The bits of a coordinate the weld compares: those of the float, with −0 taken as +0.
inline std::uint32_t weld_bits(float x) { return std::bit_cast<std::uint32_t>(x == 0.0f ? 0.0f : x); }

// Merges vertices of `mesh` that are the same surface point: bit-equal position (−0 == +0), equal skin
// influences, equal priority and equal morph position deltas on their wedges. Wedges are kept as they are
// (their wedge_vertex is remapped), so a vertex that had several render vertices becomes a seam vertex.
// Vertex order is the order of first occurrence. Returns the number of vertices removed.
std::size_t weld_by_position(Mesh& mesh);

// Removes vertices no wedge references and wedges no corner references (compacting all arrays, keeping
// order). Returns {vertices removed, wedges removed}.
std::pair<std::size_t, std::size_t> remove_unreferenced(Mesh& mesh);

}  // namespace lodforge
