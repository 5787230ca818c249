// A certified upper bound on the one-sided Hausdorff distance from a mesh's surface to a target surface:
// the largest distance from any point of `mesh` (not only sampled ones) to the closest point of the target.
//
//   SurfaceIndex source = SurfaceIndex(original);           // BVH of the target, reusable across LODs
//   DistanceBound b = distance_bound(lod, source, {.tolerance = 0.1});
//   // b.lower <= max over lod of dist(p, original) <= b.upper
//
// Branch and bound over the mesh's triangles: the distance to a fixed surface is 1-Lipschitz, so every point
// of a triangle is within d(centroid) + R of the target, R the largest centroid-to-corner distance. Triangles
// whose bound could still be the maximum are split into four, in rounds (each round's queries in parallel, the
// result independent of the thread count), until the largest bound is within `tolerance` of the largest
// distance measured. Sampling alone cannot give this: a sampled maximum is only a lower bound.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "lodforge/core/mesh.hpp"
#include "lodforge/eval/bvh.hpp"

namespace lodforge {

// A mesh's triangles with their BVH, for queries against it (the target of distance_bound()).
struct SurfaceIndex {
  SurfaceIndex() = default;
  explicit SurfaceIndex(const Mesh& mesh);
  std::vector<Vec3d> positions;
  std::vector<std::uint32_t> indices;  // three per triangle (triangle_vertex_indices)
  TriangleBvh bvh;
  bool empty() const { return bvh.empty(); }
};

struct DistanceBoundOptions {
  double tolerance = 0.1;  // stop when upper <= (1 + tolerance) × lower (or below `good_enough`)
  // Triangles whose bound is at or below this need no refinement (distances this small do not matter to the
  // caller); 0: refine down to `tolerance`. Also what a zero-distance mesh reports at most.
  double good_enough = 0.0;
  // Triangles whose bound is at or below this are not refined further, however far it is from the distances
  // measured: for a caller that decides against this value and reports the bound only as that decision's proof.
  double settle_below = 0.0;
  // Stop as soon as a measured distance exceeds this (the caller only needs to know that it does).
  double give_up_above = std::numeric_limits<double>::infinity();
  // Instead of stopping there, set aside the parts measured over it and bound the rest: `over` then names
  // every triangle found over it (as far as the query allowance goes), not only the first round's.
  bool list_over = false;
  int max_rounds = 24;     // each round halves the triangles' size
  std::size_t max_queries = 0;  // 0: 64 × triangles + 1M; past it the bound stays valid, only looser
  unsigned threads = 0;    // 0 = all cores
  // Optional, one flag per triangle of the mesh (in triangle_vertex_indices order): triangles known to lie on
  // the target (a LOD's triangles the simplifier left as they were) bound at 0 and are not measured.
  const std::vector<char>* on_target = nullptr;
  // Optional, one per triangle as above: an upper bound on that triangle's distance known already (+inf: none);
  // the result is never above it there, and refinement goes on below it only where that helps.
  const std::vector<double>* known_upper = nullptr;
  // Triangles whose known_upper is at or below give_up_above are taken at that bound, not measured: for a
  // caller that only decides against give_up_above (`lower` then covers the measured triangles only).
  bool settle_known = false;
};

struct DistanceBound {
  double upper = 0;   // no point of the mesh is farther than this from the target (+inf: target empty)
  double lower = 0;   // the largest distance actually measured (a point of the mesh this far exists)
  std::size_t queries = 0;  // closest-point queries made
  int rounds = 0;
  bool gave_up = false;  // stopped because `lower` exceeded give_up_above (then `upper` is +inf)
  // When it gave up: the mesh's triangles (their index in triangle order, ascending) where the last round
  // (with list_over, any round) measured a point farther than give_up_above.
  std::vector<std::uint32_t> over;
  // Every part of the mesh got its bound within the tolerance (or good_enough); false when max_rounds or
  // max_queries stopped the refinement first: `upper` is still a bound, only looser. Parts lying flat on the
  // target across several of its triangles converge slowly (a Lipschitz bound reaches zero only in the limit).
  bool converged = true;
};

// Triangles with a non-finite corner are skipped; a mesh without triangles gives {0, 0}.
DistanceBound distance_bound(const Mesh& mesh, const SurfaceIndex& target, const DistanceBoundOptions& options = {});
// The same for a surface already indexed (its own BVH is not used).
DistanceBound distance_bound(const SurfaceIndex& surface, const SurfaceIndex& target,
                             const DistanceBoundOptions& options = {});

}  // namespace lodforge
