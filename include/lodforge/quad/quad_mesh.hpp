// The working mesh of the quad part: a polygon mesh (triangles, quads and n-gons; chords stop at n-gons) with
// per-vertex face lists, and the generalised weld operator that applies any partition of
// vertices into islands in one step, validates the result and rolls back on failure.
//
// Ids are those of the input mesh throughout (faces only shrink: a quad may become a triangle or die, an n-gon
// lose corners); only to_mesh() compacts. Positions are double while working.
//
//   weld({{a, b}, {c, d}}, {x_ab, x_cd}):
//
//      p ---- a ---- c ---- q            p                    q
//      |  f0  |  f1  |  f2  |     →      | \                / |     f1 dies (both its rungs collapse);
//      |      |      |      |            |  x_ab ------ x_cd  |     f0 = p x_ab r and f2 = x_cd q s
//      r ---- b ---- d ---- s            | /                \ |     become triangles
//                                        r                    s
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "lodforge/core/mesh.hpp"

namespace lodforge::quad {

// Why a weld was refused (and rolled back).
enum class WeldFailure : std::uint8_t {
  none,
  bad_island,        // an island with fewer than two vertices, a dead vertex, or a vertex in two islands
  locked,            // two locked vertices in one island (each must stay where it is)
  seam,              // two wedges of one vertex would merge: the island crosses an attribute seam
  folded_polygon,    // a face would keep a repeated, non-adjacent vertex (A B A C): it folds onto itself
  non_manifold_edge, // an edge would get more than two faces, or two faces traversing it the same way
  non_manifold_vertex,  // a vertex fan would not be a single disc or half-disc (e.g. a pinched strip)
  duplicate_face,    // two faces would have the same vertex set
  diagonal_edge,     // a quad's diagonal would also be an edge of another face or another quad's diagonal
                     // (split along it, that edge would get three or four triangles)
  flipped,           // a face normal would turn by more than the allowed angle, or a corner would turn concave
  degenerate,        // a face would get (almost) zero area
  euler,             // the Euler characteristic would change (a handle or a component closed off)
  skin,              // an island joins vertices bound to different joints (checked by the engine, not weld())
};
const char* weld_failure_name(WeldFailure f);

struct WeldOptions {
  double max_flip_angle_deg = 60.0;  // a face normal may turn by at most this much (< 90)
  // Only check: the weld is rolled back even when valid (the result says whether it would have been made).
  bool dry_run = false;
  // A quad whose two opposite corners fall in one island vanishes (diagonal collapse: its two pairs of sides
  // become one edge each) instead of refusing the weld as a folded polygon, and the wedges of those two
  // corners merge. Off for polychord runs, whose islands never hold a quad's diagonal by design.
  bool dissolve_diagonal_quads = false;
};

struct WeldResult {
  WeldFailure failure = WeldFailure::none;
  std::vector<std::uint32_t> faces;      // faces the weld rewrote (alive or killed), ascending
  std::vector<std::uint32_t> survivors;  // the vertex each island became, in island order
  long long triangles_removed = 0;       // fan-triangle count before minus after
  // Every wedge of an island vertex: the wedge it is now (its class's representative, see weld()) and the
  // island's survivor; the wedges of one class are listed together. Filled when the weld is made (not on failure or dry runs); engines merge per-wedge
  // data (attribute quadrics) along it.
  struct Wedge {
    std::uint32_t wedge, into, survivor;
  };
  std::vector<Wedge> wedges;
  bool ok() const { return failure == WeldFailure::none; }
};

class QuadMesh {
 public:
  // Faces with fewer than 3 corners, out-of-range indices or a repeated vertex are dropped (they carry no
  // surface). Vertices on non-manifold or inconsistently oriented edges and with a non-finite position are
  // locked.
  explicit QuadMesh(const Mesh& mesh);

  std::size_t vertex_count() const { return positions_.size(); }
  std::size_t face_slots() const { return face_size_.size(); }
  bool face_alive(std::uint32_t f) const { return face_size_[f] != 0; }
  std::uint32_t face_size(std::uint32_t f) const { return face_size_[f]; }
  std::uint32_t face_vertex(std::uint32_t f, std::uint32_t i) const { return corner_vertex_[face_begin_[f] + i]; }
  std::uint32_t face_wedge(std::uint32_t f, std::uint32_t i) const { return corner_wedge_[face_begin_[f] + i]; }
  std::uint32_t face_material(std::uint32_t f) const { return face_material_[f]; }
  const std::vector<std::uint32_t>& vertex_faces(std::uint32_t v) const { return vertex_faces_[v]; }
  bool vertex_alive(std::uint32_t v) const { return !vertex_dead_[v]; }
  bool locked(std::uint32_t v) const { return locked_[v] != 0; }
  void lock(std::uint32_t v) { locked_[v] = 1; }
  const Vec3d& position(std::uint32_t v) const { return positions_[v]; }
  // Whether a weld has moved vertex v (else it is where the input had it).
  bool moved(std::uint32_t v) const { return moved_[v] != 0; }
  // Puts vertex v at p without any check (surface fitting checks its own steps); it counts as moved.
  void set_position(std::uint32_t v, const Vec3d& p) {
    positions_[v] = p;
    moved_[v] = 1;
  }
  std::size_t triangle_count() const { return triangles_; }  // after fan triangulation
  std::size_t triangle_faces() const { return triangle_faces_; }  // faces with three corners
  FaceKindCounts face_kinds() const;

  // The face across side `side` (corners side → side+1) of face f.
  struct Across {
    enum Kind : std::uint8_t { face, boundary, non_manifold } kind = boundary;
    std::uint32_t face_id = kInvalidIndex;  // the neighbour when kind == face
    std::uint32_t side = 0;                 // its side on the shared edge
  };
  // O(1): read from a table kept up to date by weld() (polychord tracing asks this for every quad it passes).
  Across across(std::uint32_t f, std::uint32_t side) const { return across_[face_begin_[f] + side]; }
  // Whether across() agrees, for every side of every alive face, with a search of the vertex face lists (for
  // tests of the incremental table).
  bool across_table_consistent() const;
  // Whether a side of a face at v (from v or to v) has no face across: a boundary or non-manifold edge.
  bool on_boundary(std::uint32_t v) const;
  // Position of vertex v in face f, or kInvalidIndex.
  std::uint32_t corner_of(std::uint32_t f, std::uint32_t v) const;
  // Newell normal of face f (area-weighted, not normalised).
  Vec3d face_normal(std::uint32_t f) const;

  // Merges each island (a list of at least two distinct vertices; islands disjoint) into one vertex placed at
  // the island's position, then checks the result: manifold edges and vertex fans, consistent orientation,
  // no duplicate, folded, flipped or degenerate face, Euler characteristic unchanged. On failure everything
  // is rolled back and the result says why.
  //
  // Survivor and wedges: each island keeps the vertex with the most wedges (ties: the lowest id), so a seam
  // vertex survives. Wedges meeting across a face side whose two ends are in the same island merge into one
  // class, represented by the survivor's wedge (else the lowest id): the surviving corners keep the
  // attributes of one side, unchanged. A class holding two wedges of the same vertex would merge two sides of
  // an attribute seam: refused (WeldFailure::seam).
  WeldResult weld(const std::vector<std::vector<std::uint32_t>>& islands, const std::vector<Vec3d>& island_positions,
                  const WeldOptions& options = {});

  // The mesh now: alive faces in input order with their materials and groups; referenced wedges and vertices
  // compacted in id order; unmoved vertices bit-identical to `source` (which must be the mesh this was built
  // from). `values` may replace the source's per-wedge normals, UV sets and colours (indexed by source wedge).
  Mesh to_mesh(const Mesh& source, const AttributeOverrides& values = {}) const;

 private:
  struct Undo;
  struct WeldPlan;
  // weld() in six steps; each returns a failure or WeldFailure::none, weld_release() resets the scratch.
  WeldFailure weld_pick_survivors(WeldPlan& plan);
  WeldFailure weld_wedge_classes(WeldPlan& plan, const WeldOptions& options);
  WeldFailure weld_corner_lists(WeldPlan& plan, const WeldOptions& options);
  void weld_undo_log(WeldPlan& plan, Undo& undo) const;
  void weld_apply(WeldPlan& plan, Undo& undo);
  WeldFailure weld_validate(const WeldPlan& plan, const Undo& undo, const WeldOptions& options) const;
  void weld_release(const WeldPlan& plan);
  std::uint32_t weld_wedge_target(const WeldPlan& plan, std::uint32_t w);  // a wedge's class representative
  WeldFailure check_after_weld(const std::vector<std::uint32_t>& faces, const std::vector<std::uint32_t>& vertices,
                               const Undo& undo, const WeldOptions& options) const;
  void rollback(const Undo& undo);
  bool fan_is_single(std::uint32_t v) const;
  Across find_across(std::uint32_t f, std::uint32_t side) const;  // from the vertex face lists
  // Recomputes across() for every side of an alive face whose two ends are both in `vertices`.
  void refresh_across(const std::vector<std::uint32_t>& vertices);
  long long local_euler_edges(const std::vector<std::uint32_t>& faces) const;

  std::vector<Vec3d> positions_;
  std::vector<std::uint8_t> locked_, vertex_dead_, moved_;
  std::vector<std::uint32_t> wedge_vertex_;
  std::vector<std::uint32_t> face_begin_, face_size_, face_material_;
  std::vector<std::uint32_t> corner_vertex_, corner_wedge_;
  std::vector<std::vector<std::uint32_t>> vertex_faces_;  // ascending face ids
  std::vector<Across> across_;                            // per corner slot (face_begin_[f] + side)
  std::size_t triangles_ = 0, triangle_faces_ = 0;
  // Weld scratch, indexed by vertex / wedge; reset after each use.
  std::vector<std::uint32_t> island_of_, wedge_parent_;
  std::vector<std::uint8_t> vertex_mark_;
};

}  // namespace lodforge::quad
