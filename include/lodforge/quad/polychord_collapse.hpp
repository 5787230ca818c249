// Quad-preserving simplification by polychord and sub-polychord collapse.
//
//   PolychordResult r = quad::simplify_polychord(mesh, {.target_triangles = 1000});
//
// Each step collapses a contiguous run of rungs of one polychord (or the whole chord): every rung's two ends
// become one vertex at the minimiser of their summed quadric, the quads between collapsed rungs vanish, and
// each open end turns one quad into a triangle (or deletes a triangle the chord ends in). Runs are found per
// chord by seed-and-grow and ranked by cost per removed triangle (a run ranks no better than its worst rung)
// in a versioned priority queue; after each collapse the chords through faces around the touched vertices go
// stale and are re-traced when they reach the top. Open run ends leave triangles: they cost a penalty and are
// budgeted, so the result stays quad-dominant. Every collapse goes through QuadMesh::weld, which validates
// and rolls back; when it refuses a run, the rungs it would refuse on their own are left out of that chord's
// later runs. At the end the moved vertices are fitted to the input surface (surface_fit.hpp).
//
// What the output keeps: quads stay quads unless a run ends in them; faces keep their input order, material
// and group; a vertex that never moved keeps its exact input position. Wedges: an island keeps the wedges of
// its survivor (the vertex with the most wedges), one per side of a seam, their values from the merged
// wedges' attribute quadrics (PolychordOptions::optimal_attributes); islands that would merge two wedges of
// one vertex are refused (QuadMesh::weld). Skin, priority and morph deltas are the survivor's; islands
// joining vertices of different dominant joints outside a blend band are refused (metric/skin.hpp).
// Not done here: the "guide plane" re-simplification pass after polychord removal (EA's US patent
// 10,043,310); lodforge::simplify() continues with the triangle engine when this one stops early.
#pragma once

#include <cstdint>
#include <vector>

#include "lodforge/core/mesh.hpp"
#include "lodforge/core/stop.hpp"
#include "lodforge/quad/polychord.hpp"
#include "lodforge/symmetry/symmetry.hpp"

namespace lodforge::quad {

struct PolychordOptions {
  // Target triangle count (fan triangles): target_triangles when non-zero, else round(target_ratio × input).
  double target_ratio = 0.5;
  std::size_t target_triangles = 0;
  // No island whose RMS quadric distance (sqrt(E / area)) exceeds this is made; negative = unlimited.
  double max_error_abs = -1.0;  // model units
  double border_weight = 10.0;  // boundary constraint planes relative to face quadrics
  double max_flip_angle_deg = 60.0;
  bool lock_boundary = false;   // boundary vertices never move and are never removed
  // Cost added per triangle a run leaves behind (an open end in a quad), as a fraction of mean face area ×
  // mean edge length²; a run ending in an existing triangle gets it back. Biases the search towards whole
  // chords and towards runs that close earlier triangles, which keeps the result quad-dominant.
  double triangle_penalty = 0.5;
  // A run ranks no better than its worst rung's cost per removed triangle times this: keeps long, cheap runs
  // from dragging an expensive rung (a feature) along. 0 = rank by the mean cost per removed triangle only.
  // A run's mean cost per removed triangle (triangle penalty aside) is at most its worst rung's, so from 1 up
  // the worst rung decides every rank, and the run's length only breaks ties. Measured at 50% with 0 against
  // 100: Suzanne 3.61x against 2.82x the triangle engine's mean distance, proxy741 1.94x against 1.30x, spot
  // 1.02x against 0.80x (at higher quad fractions: spot 0.99 against 0.91).
  double worst_rung_weight = 100.0;
  // Most triangles runs may leave behind, as a fraction of the faces expected at the target (target / 2);
  // 1 = no limit. Once it is spent, runs that leave more rank over_budget_factor times worse (and runs that
  // delete triangles that many times better), and past hard_budget_factor times the budget they wait until no
  // other run is left: then the budget is doubled (up to no limit). The soft part lets a cheap run that leaves
  // a triangle go before a much dearer one that leaves none: with the hard budget alone (both factors 1) the
  // bench's MakeHuman proxy741 at 50% was 1.51x the triangle engine's mean distance, with 4 / 1.4 it is 1.15x,
  // the quad fraction at 25% staying at 0.87-0.91 on the MakeHuman and spot meshes.
  double max_triangle_fraction = 0.1;
  double over_budget_factor = 4.0;   // >= 1
  double hard_budget_factor = 1.4;   // >= 1
  // Diagonal collapses stand in for runs the triangle budget forces: a quad's two opposite corners merge at
  // their quadric's best point and the quad vanishes (Daniels et al. 2008; Tarini et al., "Practical quad
  // mesh simplification", 2010). Every face stays a quad, but the quad's two other corners lose a valence, so
  // the edge flow gets irregular vertices. A diagonal collapse ranks diagonal_factor times worse than a
  // one-rung run of the same cost, and is made only while the best run allowed ranks more than
  // diagonal_gate times worse than the best run the hard triangle budget holds back (or no run is allowed):
  // that is where the budget would otherwise force a whole loop across a feature. On the bench's MakeHuman
  // proxy741 at 25% (1460 triangles) the mean distance is 1.45x the triangle engine's with them, 2.25x (and
  // quad fraction 0.83) without; Suzanne's 2.3x against 3.8x. Without the gate (diagonals competing with every
  // run) the sword at 10% went from 1.25x to 1.92x, as early diagonal collapses fragment the chords later runs
  // need. Factor 8 against 4: proxy741 at 25% 1.45x against 1.49x, Suzanne 2.3x against 2.8x (quad fraction
  // 0.87 against 0.84), the spot cage 1.47x against 2.77x. diagonal_factor 0 = off.
  double diagonal_factor = 8.0;
  double diagonal_gate = 8.0;
  // A diagonal collapse may not leave its merged vertex with more faces than this (a pole): without the cap
  // the blub and spot subdivision cages at 25% went to 2.4x and 3.0x the triangle engine's mean.
  std::size_t diagonal_max_faces = 6;
  // Fit the vertices collapses moved to the input surface at the end (surface_fit.hpp).
  bool fit_surface = true;
  int seed_rungs = 3;  // length of the seed run of the seed-and-grow search
  // Pair triangles into quads first (quad_recovery.hpp) when the input has no quads at all.
  bool recover_quads = true;
  std::vector<std::uint32_t> locked_vertices{};
  // Painted priority (Mesh::priority) at or above this locks the vertex; below, it scales the vertex's
  // quadric by its square, as in the triangle engine.
  double priority_lock = 1000.0;
  // Skinned meshes: an island may only join vertices that skin_mergeable() allows (metric/skin.hpp) with
  // these parameters, every pair of its vertices.
  double skin_weight_threshold = 0.1;
  double skin_max_distance = 0.5;
  // Attributes (normals, UV sets, colours) as the triangle engine weighs them (SimplifyOptions::
  // AttributeWeights; 0 leaves a stream out): every wedge carries a Hoppe 1999 attribute quadric (metric/
  // attribute_quadric.hpp); they give merged wedges their values (below). Islands are placed by their surface
  // quadric alone.
  double normal_weight = 1.0, uv_weight = 1.0, color_weight = 1.0;
  // A rung's cost adds this times the attribute error of the wedge classes its weld makes (each side of a
  // seam apart; 1 = as the triangle engine ranks its edges). 0: runs are ranked by the surface alone. Measured
  // at 50% / 25% (optimal attribute values both ways), weight 1 against 0: MakeHuman hm08's mean distance
  // 0.00207% / 0.0180% against 0.00159% / 0.0153% (the bench's target against the triangle engine missed at
  // 10%), proxy741 0.0538% / 0.278% against 0.0482% / 0.236% for a UV RMS of 0.059 / 0.114 against 0.091 /
  // 0.143; the Duck's normal RMS 0.045 / 0.105 against 0.057 / 0.098.
  double attribute_cost_weight = 0.0;
  // True: each merged wedge class of a moved island takes its summed attribute quadric's minimiser at the
  // island's position (unit normals; colours in [0, 1] widened to the merged values' range; UVs on the
  // segments between the merged wedges' UVs, snapped to the nearest of them at a seam vertex). False: the
  // survivor's values, unchanged (all LODs can share one vertex buffer).
  bool optimal_attributes = true;
  // Soft symmetry (SimplifyOptions::symmetry_weight; 0 = off). Above 0 the mesh's mirror symmetry is found
  // (symmetry/symmetry.hpp), or taken from vertex_mirror where given (one entry per input vertex), and a run
  // whose mirror image is a run of rungs too (of another chord, or of the same chord) collapses with it in
  // one weld, ranked by the mean of the two runs' keys, its mirror's islands placed at the mirror images of
  // its own; a run whose mirror image is no run (or is refused) ranks (1 + symmetry_weight)
  // times worse first, then goes alone. Runs outside the symmetric region and runs that are their own mirror
  // image rank as without it.
  double symmetry_weight = 0.0;
  symmetry::PlaneMode symmetry_plane = symmetry::PlaneMode::automatic;
  const std::vector<std::uint32_t>* vertex_mirror = nullptr;
  // Polled every few hundred steps of the collapse loop; once requested, the mesh as far as it got is returned
  // (without the surface fit) with PolychordResult::stopped set.
  StopRequest stop{};
};

struct PolychordResult {
  Mesh mesh;
  std::size_t triangles_before = 0, triangles_after = 0;
  std::size_t quads_before = 0, quads_after = 0;
  bool target_reached = false;
  double error_bound_abs = 0;  // running maximum over collapsed islands of sqrt(E / area)
  std::size_t collapses = 0;   // committed runs
  std::size_t paired_collapses = 0;  // of those, runs made together with their mirror image (symmetry_weight)
  std::size_t diagonal_collapses = 0;  // committed diagonal collapses
  std::size_t rejected = 0;    // runs the weld refused
  std::size_t over_budget = 0; // runs and diagonal collapses left out for exceeding the error budget
  std::size_t recovered_quads = 0;  // quads made by quad recovery of triangle input
  std::size_t paired_triangles = 0; // quads made at the end from adjacent triangles the runs left (see .cpp)
  bool stopped = false;  // PolychordOptions::stop was requested before the target was reached
};

// Whether rungs [first, last] of `chord` may collapse as one run: none of them shares a vertex with another
// (a run through a self-intersection or along a self-touching stretch would merge rails that are already
// adjacent). The whole chord of a self-touching polychord is never allowed.
bool run_allowed(const Polychord& chord, std::size_t first, std::size_t last);

// Throws std::invalid_argument for out-of-range locked vertices or options (ratio outside (0, 1]).
PolychordResult simplify_polychord(const Mesh& mesh, const PolychordOptions& options);

}  // namespace lodforge::quad
