// Invariant checks of a mesh, with counts. Tests call validate() after every operation.
#pragma once

#include <string>
#include <vector>

#include "lodforge/core/mesh.hpp"
#include "lodforge/core/topology.hpp"

namespace lodforge {

struct ValidationReport {
  std::size_t nonfinite_positions = 0;     // NaN or Inf coordinates (counted per vertex)
  std::size_t out_of_range_indices = 0;    // corner->wedge, wedge->vertex, face->material/group
  std::size_t short_faces = 0;             // faces with fewer than 3 corners
  std::size_t degenerate_faces = 0;        // a repeated vertex, or zero area
  std::size_t duplicate_faces = 0;         // same vertex set as an earlier face (either orientation)
  std::size_t non_manifold_edges = 0;
  std::size_t non_manifold_vertices = 0;
  std::size_t inconsistent_orientation = 0;  // edges whose two faces disagree on orientation
  std::size_t attribute_size_errors = 0;   // attribute arrays of the wrong length
  std::size_t unreferenced_vertices = 0;   // informational: not counted as an error
  std::vector<std::string> messages;       // one line per finding kind, with its count

  // True when there are no errors (unreferenced vertices are not an error).
  bool ok() const;
  // Topology findings only (non-manifold, orientation): used to check "nothing new" after simplification.
  bool operator==(const ValidationReport&) const = default;
};

ValidationReport validate(const Mesh& mesh);

}  // namespace lodforge
