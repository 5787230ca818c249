// Polychords (dual strips) of a mixed quad/triangle mesh.
//
// A polychord is a maximal sequence of quads q_0 .. q_{K-1} joined through opposite sides. Consecutive quads
// share a rung; quad q_k lies between rungs r_k and r_{k+1}:
//
//        r_0      r_1      r_2      r_3
//    end  |  q_0   |  q_1   |  q_2   |  end       open chord: K quads, K+1 rungs
//         |        |        |        |
//
// A chord ends at a boundary, a triangle (which has no opposite side), an n-gon or a non-manifold edge, or
// closes into a loop (then r_K is r_0 and only K rungs are listed). Direction d of a quad is the pair of
// sides (d, d+2); every quad lies on one chord per direction.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "lodforge/core/mesh.hpp"
#include "lodforge/quad/quad_mesh.hpp"

namespace lodforge::quad {

enum class ChordEnd : std::uint8_t {
  boundary,      // the rung has no face beyond it
  triangle,      // the strip runs into a triangle (end_face)
  polygon,       // ... into an n-gon (end_face)
  non_manifold,  // the rung is shared by more than two faces or traversed the same way twice
  closed,        // the chord is a loop (both ends)
};
const char* chord_end_name(ChordEnd e);

struct Polychord {
  std::vector<std::uint32_t> faces;       // q_0 .. q_{K-1}
  std::vector<std::uint8_t> directions;   // direction of each quad on this chord (0 or 1)
  std::vector<std::array<std::uint32_t, 2>> rungs;  // vertex pairs r_0 .. r_K (r_0 .. r_{K-1} when closed)
  std::array<ChordEnd, 2> ends{ChordEnd::boundary, ChordEnd::boundary};  // at r_0 and at r_K
  std::array<std::uint32_t, 2> end_faces{kInvalidIndex, kInvalidIndex};  // triangle / n-gon beyond r_0, r_K
  bool closed = false;
  // Passes through one quad in both directions (the two directions of a quad cross).
  bool self_intersecting = false;
  // Two rungs share a vertex (includes every self-intersection, and strips touching themselves along a rail,
  // as around valence-2 vertices and in thin spirals). Collapsing both such rungs at once merges rails that
  // are already adjacent: refused.
  bool self_touching = false;

  std::size_t quad_count() const { return faces.size(); }
};

// Traces the chord through direction `direction` (0 or 1) of quad `face` of `mesh`; `face` becomes q_k for
// some k (q_0 when the chord is closed). Requires face to be an alive quad.
Polychord trace_polychord(const QuadMesh& mesh, std::uint32_t face, int direction);

// Scratch for tracing many chords of one mesh: the self-intersection and self-touching tests mark faces and
// vertices instead of sorting the chord's lists (the polychord engine traces about two chords per collapse).
struct TraceScratch {
  std::vector<std::uint32_t> face_mark, vertex_mark;
  std::uint32_t stamp = 0;
};
Polychord trace_polychord(const QuadMesh& mesh, std::uint32_t face, int direction, TraceScratch& scratch);

struct PolychordSet {
  std::vector<Polychord> chords;
  // Chord id of each face per direction; kInvalidIndex for non-quads and dead faces.
  std::vector<std::array<std::uint32_t, 2>> face_chord;
};

// Every chord of the mesh once, in a deterministic order (by the lowest face, then direction, that starts it).
PolychordSet trace_polychords(const QuadMesh& mesh);
PolychordSet trace_polychords(const Mesh& mesh);

}  // namespace lodforge::quad
