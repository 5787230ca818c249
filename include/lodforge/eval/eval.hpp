// Metro-style surface distance between an original mesh and a simplified one (Cignoni et al. 1998):
// area-weighted samples (fixed seed) plus all vertices of each mesh, exact closest points on triangles
// through a BVH, both directions, in parallel. The same numbers feed tests, the report and benchmarks.
#pragma once

#include <cstdint>
#include <string>

#include "lodforge/core/mesh.hpp"

namespace lodforge {

struct EvalOptions {
  std::size_t samples = 0;        // area samples per direction; 0 = max(10 x larger face count, 200000)
  std::uint64_t seed = 12345;
  bool include_vertices = true;   // also sample every vertex (maxima usually sit there)
  unsigned threads = 0;           // 0 = all cores
};

struct OneSided {
  double max = 0, mean = 0, rms = 0;
  std::size_t samples = 0;
};

struct EvalResult {
  OneSided a_to_b, b_to_a;        // a = original, b = simplified
  double hausdorff = 0;           // max of both directions
  double mean = 0, rms = 0;       // pooled over both directions
  double diagonal = 0;            // of the original's bounding box
  // Relative values: absolute / diagonal.
  double hausdorff_rel() const { return diagonal > 0 ? hausdorff / diagonal : 0; }
  double mean_rel() const { return diagonal > 0 ? mean / diagonal : 0; }
  double rms_rel() const { return diagonal > 0 ? rms / diagonal : 0; }
  // Angle in degrees between face normals at a sample and its closest point (a -> b), area weighted.
  double normal_deviation_mean_deg = 0, normal_deviation_p95_deg = 0;
};

// Both meshes are triangulated internally (polygons fan-triangulated). Empty meshes give an all-zero result.
EvalResult evaluate(const Mesh& original, const Mesh& simplified, const EvalOptions& options = {});

}  // namespace lodforge
