// Metro-style surface distance between an original mesh and a simplified one (Cignoni et al. 1998):
// area-weighted samples (fixed seed) plus all vertices of each mesh, exact closest points on triangles
// through a BVH, both directions, in parallel. The same numbers feed tests, the report and benchmarks.
//
// Protocol: N area-uniform samples per direction, drawn by inverting the cumulative
// triangle area with stratified uniforms (i + r_i) / N and folding (u, v) into the triangle; every vertex is
// also sampled, for the maximum. Distances are exact point-to-triangle distances in double precision.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "lodforge/core/mesh.hpp"
#include "lodforge/core/stop.hpp"
#include "lodforge/eval/bvh.hpp"

namespace lodforge {

struct EvalOptions {
  std::size_t samples = 0;        // area samples per direction; 0 = default_eval_samples(larger triangle count)
  std::uint64_t seed = 12345;
  bool include_vertices = true;   // also sample every vertex (maxima usually sit there)
  unsigned threads = 0;           // 0 = all cores; the result is bit-identical for any value
  // Polled between blocks of samples: once requested, the remaining samples are skipped and the result comes
  // back with `stopped` set.
  StopRequest stop{};
};

// Distances from the samples of one mesh to the other surface, in model units.
struct OneSided {
  double max = 0;                 // over area samples and vertices
  double mean = 0, rms = 0;       // over area samples (over vertices only when the mesh has no area)
  double p99 = 0, p999 = 0;       // 99th and 99.9th percentile of the area samples (less noisy than max)
  std::size_t samples = 0;        // area samples taken
  std::size_t vertex_samples = 0; // vertices taken (those used by a triangle)
  // Angle between the oriented face normal at each area sample and that of the closest triangle, in degrees
  // (0..180; samples whose closest triangle has no area are skipped). Samples are area-uniform, so this is
  // the area-weighted mean.
  double normal_deviation_mean_deg = 0, normal_deviation_p95_deg = 0;
};

struct EvalResult {
  OneSided a_to_b, b_to_a;        // a = original, b = simplified
  double hausdorff = 0;           // max of both directions
  double mean = 0, rms = 0;       // pooled over both directions' samples
  double diagonal = 0;            // of the original's bounding box (compute_bounds)
  // Relative values: absolute / diagonal.
  double hausdorff_rel() const { return diagonal > 0 ? hausdorff / diagonal : 0; }
  double mean_rel() const { return diagonal > 0 ? mean / diagonal : 0; }
  double rms_rel() const { return diagonal > 0 ? rms / diagonal : 0; }
  // Face-normal angle (see OneSided), pooled over both directions' area samples.
  double normal_deviation_mean_deg = 0, normal_deviation_p95_deg = 0;
  // options.stop was requested: the figures are incomplete and mean nothing.
  bool stopped = false;
  // Closest-point work of both directions (a machine-independent cost; the same for any thread count).
  BvhWork work;
  // Empty unless a mesh has no triangles: then distances to it are +infinity (never NaN), and this says why.
  std::string note;
};

// The default area sample count per direction when the larger mesh has `larger_triangle_count` triangles
// (after fan triangulation): max(4 x triangles, 200000). Metro's 10 x costs about twice as long; 4 x keeps two
// 100k-triangle meshes at about half a second on 2 cores, and the stratified samples make the mean and RMS
// converge faster than plain Monte Carlo. Pass `samples` explicitly for the 10 x or 1 M protocol.
std::size_t default_eval_samples(std::size_t larger_triangle_count);

// Both meshes are triangulated internally (polygons fan-triangulated). Two meshes without triangles give an
// all-zero result. Triangles with a non-finite corner are ignored.
EvalResult evaluate(const Mesh& original, const Mesh& simplified, const EvalOptions& options = {});

// An original prepared once (its sampling surface, its BVH and its diagonal) for measuring several meshes
// against it, as a batch measures every LOD of a chain against the same source: evaluate(reference, lod)
// gives what evaluate(original, lod) gives, bit for bit, without rebuilding the original's side each time.
class EvalReference {
 public:
  // `threads` as EvalOptions::threads (the preparation's result does not depend on it).
  explicit EvalReference(const Mesh& original, unsigned threads = 0);
  ~EvalReference();
  EvalReference(EvalReference&&) noexcept;
  EvalReference& operator=(EvalReference&&) noexcept;

  struct Prepared;  // private to eval.cpp
  const Prepared& prepared() const { return *prepared_; }

 private:
  std::unique_ptr<Prepared> prepared_;
};

EvalResult evaluate(const EvalReference& original, const Mesh& simplified, const EvalOptions& options = {});

}  // namespace lodforge
