// Fitting moved vertices back to the input surface after the polychord engine.
//
//   refit_to_surface(quad_mesh, input_mesh, input_surface_bvh(input_mesh), {});
//
// Collapses place each merged vertex at its quadric's minimiser, which bounds the distance to the planes of the
// faces it absorbed but not to the surface between them: a strip collapse across a curved region leaves the
// new faces cutting under (or over) it. The fit is least-squares surface fitting with the connectivity fixed
// (Hoppe et al., "Mesh Optimization", SIGGRAPH 1993): each step samples the simplified surface at the midpoint
// of every edge with a moved end (the triangles being those evaluation and output see: quads split along the
// shorter diagonal) and finds each sample's closest point on the input; each input vertex finds its closest
// point on the simplified surface; then every moved vertex is placed, free in 3D, to minimise the area-weighted
// squared distances of both sets (plus a small pull towards where it was, so that a vertex the samples leave
// free to slide stays put), by conjugate gradients. Only vertices a collapse moved are fitted (the others are
// input vertices, on the surface already, and keep their exact positions); locked and boundary ones stay. A
// vertex takes its step only when no face around it turns by more than `max_turn_deg` (a quad's four corner
// triangles checked too, as it may fold along either diagonal); otherwise half of it is tried, then none.
#pragma once

#include "lodforge/core/mesh.hpp"
#include "lodforge/eval/bvh.hpp"
#include "lodforge/quad/quad_mesh.hpp"

namespace lodforge::quad {

struct SurfaceFitOptions {
  // At most this many steps; fewer when converged (surface_fit.cpp). Each step moves the closest points the
  // next one fits to, so the fit converges slowly, as ICP does: on nine quad corpus meshes at 50/25/10% (the
  // cages, Suzanne, MakeHuman proxy, suit and hair, fandisk, mixedFaring) four steps of at most half an edge
  // came up to 11% closer than two of a quarter, eight up to 12% closer than four, sixteen up to 12% closer
  // than eight. Eight took the polychord engine 1.2-1.7 times as long as four on the bench's quad meshes
  // (single runs; MakeHuman hm08 at 50%: 0.59 s against 0.46 s); the 100k-quad torus stops after two steps
  // either way.
  int iterations = 8;
  double max_turn_deg = 20.0;     // most a face normal may turn in one step
  double max_step_edges = 0.5;    // a step is at most this fraction of the vertex's shortest edge
  // Weight of the pull towards the vertex's position before the step, relative to its samples' weight (the
  // diagonal of the least-squares system).
  double regularisation = 0.1;
};

// The input surface the fit measures against: every valid face of `input` as the triangles the output and
// the evaluator see. Built apart so that a caller may build it while it does other work (the polychord engine
// builds it on another core while its collapses run).
TriangleBvh input_surface_bvh(const Mesh& input);

// Returns how many vertex steps were taken. `input_bvh` is input_surface_bvh(input).
std::size_t refit_to_surface(QuadMesh& mesh, const Mesh& input, const TriangleBvh& input_bvh,
                             const SurfaceFitOptions& options);

}  // namespace lodforge::quad
