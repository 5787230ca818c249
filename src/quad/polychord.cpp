// Polychord tracing (after vcglib's PolychordCollapse walk and Daniels et al. 2008): from
// a rung into its quad, across to the opposite side, to the face beyond, and again, in both directions.
#include "lodforge/quad/polychord.hpp"

#include <algorithm>

namespace lodforge::quad {

const char* chord_end_name(ChordEnd e) {
  switch (e) {
    case ChordEnd::boundary: return "boundary";
    case ChordEnd::triangle: return "triangle";
    case ChordEnd::polygon: return "polygon";
    case ChordEnd::non_manifold: return "non_manifold";
    case ChordEnd::closed: return "closed";
  }
  return "unknown";
}

namespace {

std::array<std::uint32_t, 2> side_vertices(const QuadMesh& m, std::uint32_t f, std::uint32_t side) {
  return {m.face_vertex(f, side), m.face_vertex(f, (side + 1) % m.face_size(f))};
}

// One direction of the walk: leaves quad `face` through side `exit` and follows the strip until it ends.
// Appends (quad, entry side) pairs; returns how it ended and the face that ended it. Stops at `start` with
// ChordEnd::closed when the strip comes back into it in the same direction.
struct Step {
  std::uint32_t face, entry;
};
ChordEnd walk(const QuadMesh& m, std::uint32_t face, std::uint32_t exit, std::uint32_t start, int start_direction,
              std::vector<Step>& steps, std::uint32_t& end_face) {
  const std::size_t limit = 2 * m.face_slots() + 2;  // a manifold strip visits a quad at most twice
  while (steps.size() <= limit) {
    const QuadMesh::Across next = m.across(face, exit);
    if (next.kind == QuadMesh::Across::boundary) return ChordEnd::boundary;
    if (next.kind == QuadMesh::Across::non_manifold) return ChordEnd::non_manifold;
    const std::uint32_t g = next.face_id, n = m.face_size(g);
    if (n == 3) {
      end_face = g;
      return ChordEnd::triangle;
    }
    if (n > 4) {
      end_face = g;
      return ChordEnd::polygon;
    }
    if (g == start && static_cast<int>(next.side % 2) == start_direction) return ChordEnd::closed;
    steps.push_back({g, next.side});
    face = g;
    exit = (next.side + 2) % 4;
  }
  return ChordEnd::non_manifold;  // unreachable on a mesh whose edges have at most two faces
}

}  // namespace

Polychord trace_polychord(const QuadMesh& m, std::uint32_t face, int direction, TraceScratch& scratch) {
  Polychord chord;
  const std::uint32_t d = static_cast<std::uint32_t>(direction);
  std::vector<Step> forward, backward;
  std::uint32_t end_forward = kInvalidIndex, end_backward = kInvalidIndex;
  const ChordEnd fwd = walk(m, face, d + 2, face, direction, forward, end_forward);
  std::vector<Step> steps;
  if (fwd == ChordEnd::closed) {
    chord.closed = true;
    chord.ends = {ChordEnd::closed, ChordEnd::closed};
    steps.reserve(forward.size() + 1);
    steps.push_back({face, d});
    steps.insert(steps.end(), forward.begin(), forward.end());
  } else {
    const ChordEnd bwd = walk(m, face, d, face, direction, backward, end_backward);
    // The backward walk enters each quad through the side facing the start; flip it to the forward entry.
    steps.reserve(backward.size() + forward.size() + 1);
    for (auto it = backward.rbegin(); it != backward.rend(); ++it) steps.push_back({it->face, (it->entry + 2) % 4});
    steps.push_back({face, d});
    steps.insert(steps.end(), forward.begin(), forward.end());
    chord.ends = {bwd, fwd};
    chord.end_faces = {end_backward, end_forward};
  }
  chord.faces.reserve(steps.size());
  chord.directions.reserve(steps.size());
  chord.rungs.reserve(steps.size() + 1);
  for (const Step& s : steps) {
    chord.faces.push_back(s.face);
    chord.directions.push_back(static_cast<std::uint8_t>(s.entry % 2));
    chord.rungs.push_back(side_vertices(m, s.face, s.entry));
  }
  if (!chord.closed) chord.rungs.push_back(side_vertices(m, steps.back().face, (steps.back().entry + 2) % 4));

  // Self-intersection: a quad visited in both directions. Self-touching: two rungs sharing a vertex.
  if (scratch.face_mark.size() < m.face_slots()) scratch.face_mark.resize(m.face_slots(), 0);
  if (scratch.vertex_mark.size() < m.vertex_count()) scratch.vertex_mark.resize(m.vertex_count(), 0);
  if (++scratch.stamp == 0) {  // wrapped: clear the marks once
    std::fill(scratch.face_mark.begin(), scratch.face_mark.end(), 0);
    std::fill(scratch.vertex_mark.begin(), scratch.vertex_mark.end(), 0);
    scratch.stamp = 1;
  }
  for (std::uint32_t f : chord.faces) {
    if (scratch.face_mark[f] == scratch.stamp) chord.self_intersecting = true;
    scratch.face_mark[f] = scratch.stamp;
  }
  for (const auto& r : chord.rungs) {
    for (std::uint32_t v : r) {
      if (scratch.vertex_mark[v] == scratch.stamp) chord.self_touching = true;
      scratch.vertex_mark[v] = scratch.stamp;
    }
  }
  return chord;
}

Polychord trace_polychord(const QuadMesh& m, std::uint32_t face, int direction) {
  TraceScratch scratch;
  return trace_polychord(m, face, direction, scratch);
}

PolychordSet trace_polychords(const QuadMesh& m) {
  PolychordSet set;
  TraceScratch scratch;
  set.face_chord.assign(m.face_slots(), {kInvalidIndex, kInvalidIndex});
  for (std::uint32_t f = 0; f < m.face_slots(); ++f) {
    if (m.face_size(f) != 4) continue;
    for (int d = 0; d < 2; ++d) {
      if (set.face_chord[f][d] != kInvalidIndex) continue;
      Polychord chord = trace_polychord(m, f, d, scratch);
      const auto id = static_cast<std::uint32_t>(set.chords.size());
      for (std::size_t k = 0; k < chord.faces.size(); ++k) set.face_chord[chord.faces[k]][chord.directions[k]] = id;
      set.chords.push_back(std::move(chord));
    }
  }
  return set;
}

PolychordSet trace_polychords(const Mesh& mesh) { return trace_polychords(QuadMesh(mesh)); }

}  // namespace lodforge::quad
