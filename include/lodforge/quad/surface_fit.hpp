// Fitting moved vertices back to the input surface after the polychord engine.
//
//   refit_to_surface(quad_mesh, input_mesh, input_surface_bvh(input_mesh), {});
//
// Collapses place each merged vertex at its quadric's minimiser, which bounds the distance to the planes of the
// faces it absorbed but not to the surface between them: a strip collapse across a curved region leaves the
// new faces cutting under (or over) it. The fit samples every face (its corners and each triangle's centroid,
// the triangles being those evaluation and output see: quads split along the shorter diagonal), finds each
// sample's closest point on the input surface, and moves every vertex along its normal by the weighted mean
// of its samples' offsets (a Jacobi step of least-squares surface fitting, as in Hoppe et al., "Mesh
// Optimization", SIGGRAPH 1993); the input's vertices pull the closest points of the simplified surface the
// same way. Only vertices a collapse moved are fitted (the others are input vertices, on the surface already,
// and keep their exact positions); locked and boundary ones stay. A step is taken only when no face around
// the vertex turns by more than `max_turn_deg` (a quad's four corner triangles checked too, as it may fold
// along either diagonal); otherwise half of it is tried, then none.
#pragma once

#include "lodforge/core/mesh.hpp"
#include "lodforge/eval/bvh.hpp"
#include "lodforge/quad/quad_mesh.hpp"

namespace lodforge::quad {

struct SurfaceFitOptions {
  // At most this many steps; fewer when converged (surface_fit.cpp). Two give nearly all of the gain: on the
  // bench four lowered no MakeHuman mean by more than 5%. On the bench's 100k-quad torus the fit converges
  // after one step, about 0.2 s of the engine's 0.9 s (2 cores).
  int iterations = 2;
  double max_turn_deg = 20.0;     // most a face normal may turn in one step
  double max_step_edges = 0.25;   // a step is at most this fraction of the vertex's shortest edge
};

// The input surface the fit measures against: every valid face of `input` as the triangles the output and
// the evaluator see. Built apart so that a caller may build it while it does other work (the polychord engine
// builds it on another core while its collapses run).
TriangleBvh input_surface_bvh(const Mesh& input);

// Returns how many vertex steps were taken. `input_bvh` is input_surface_bvh(input).
std::size_t refit_to_surface(QuadMesh& mesh, const Mesh& input, const TriangleBvh& input_bvh,
                             const SurfaceFitOptions& options);

}  // namespace lodforge::quad
