// Bilateral (mirror) symmetry of a mesh: the plane, and which edge, vertex and face mirrors which.
//
//   const Topology topo = build_topology(mesh);
//   const symmetry::SymmetryMap s = symmetry::detect_symmetry(mesh, topo);
//   if (s.found()) use(s.plane, s.edge_mirror[e]);  // e indexes topo.edges
//
// Detection estimates one mirror plane from the whole mesh, then grows a combinatorial correspondence face by
// face from mirrored seed faces, checking every new vertex pair against the plane. So a partly symmetric mesh
// (hair parted on one side, a badge) is symmetric only where it is, and separate parts that mirror each other
// (two boots) are found as well. The maps are involutions: mirror[mirror[i]] == i; elements on the plane are
// their own mirror. Deterministic: the same mesh gives the same maps, whatever the thread count.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string_view>
#include <vector>

#include "lodforge/core/mesh.hpp"
#include "lodforge/core/topology.hpp"
#include "lodforge/core/vec.hpp"

namespace lodforge::symmetry {

// Which plane to look for: the best one found (`automatic`), one whose normal is a coordinate axis (its offset
// is still estimated), or none at all.
enum class PlaneMode { automatic, x, y, z, none };

// "auto", "x", "y", "z", "none": the spelling of the config key and the command-line option.
const char* plane_mode_name(PlaneMode mode);
std::optional<PlaneMode> parse_plane_mode(std::string_view name);

// Points x with dot(normal, x) + offset == 0; normal has unit length.
struct Plane {
  Vec3d normal{{1, 0, 0}};
  double offset = 0;

  double signed_distance(const Vec3d& p) const { return dot(normal, p) + offset; }
  Vec3d reflect(const Vec3d& p) const { return p - normal * (2.0 * signed_distance(p)); }
};

struct SymmetryOptions {
  PlaneMode plane = PlaneMode::automatic;
  // How far a vertex may lie from the mirror image of its partner, as a fraction of the mean length of its
  // edges: larger accepts sloppier artist symmetry, smaller keeps edits of a few percent out.
  double tolerance = 0.1;
  // Matched regions smaller than this many faces are dropped as coincidences (unless they are a whole part).
  std::size_t min_region_faces = 16;
};

struct SymmetryMap {
  Plane plane;  // meaningful when found()
  // Per edge of build_topology(mesh) (same order), per vertex and per face: the mirror, or kInvalidIndex.
  std::vector<std::uint32_t> edge_mirror;
  std::vector<std::uint32_t> vertex_mirror;
  std::vector<std::uint32_t> face_mirror;
  std::size_t symmetric_edges = 0;  // edges with a mirror (those on the plane included)
  std::size_t edges = 0;            // all edges of the topology

  bool found() const { return symmetric_edges > 0; }
  double symmetric_fraction() const {
    return edges == 0 ? 0.0 : static_cast<double>(symmetric_edges) / static_cast<double>(edges);
  }
};

// `topo` must be build_topology(mesh). Faces with out-of-range indices are never matched (validate() first for
// a reason); degenerate faces (a repeated vertex) and edges of more than two faces do not carry the walk.
SymmetryMap detect_symmetry(const Mesh& mesh, const Topology& topo, const SymmetryOptions& options = {});
SymmetryMap detect_symmetry(const Mesh& mesh, const SymmetryOptions& options = {});

// The plane of a given vertex mirror map (mirror[v]: v's mirror, itself on the plane, kInvalidIndex: none):
// normal along the mean difference of the pairs, through their mean midpoint. None without a pair.
std::optional<Plane> plane_of_pairs(const Mesh& mesh, const std::vector<std::uint32_t>& mirror);

}  // namespace lodforge::symmetry
