// Attribute, UV and skinning quality of a simplified mesh against its original.
//
//   const AttributeEvalResult r = evaluate_attributes(original, lod);
//
// - attribute error: area-uniform samples on the original (fixed seed); at each, the attribute interpolated on
//   the original and at the closest point of the simplified mesh; RMS of the difference per attribute stream
//   (normals as unit vectors, each UV set, each colour set). Near UV seams the closest point may fall in the
//   neighbouring chart, so UV RMS includes some seam noise; compare LODs of one asset with each other.
// - normal deviation: angle between the interpolated (renormalised) vertex normals at those sample pairs.
// - UV, per set: Sander et al. 2001 L2 stretch of the whole mesh (normalised so that 1 is ideal) of the LOD
//   divided by that of the original; UV-flipped triangles; triangles spanning two UV charts. Charts are the
//   original's (wedges of one face, and wedges of one vertex with equal UVs in every set, share a chart); an
//   output corner belongs to the charts whose original UV triangles contain its UV (a 2-D grid over the
//   original layout, exact UV matches first). A triangle spans charts when its located corners share none
//   (a corner in no chart, `outside`, constrains nothing); it is flipped when the sign of its UV area
//   differs from that of every original triangle of the shared charts under its UV centroid (or, when
//   none is there, from that of the shared charts' original triangle nearest to the centroid in UV space:
//   a chart may hold mirrored parts, so its overall orientation says nothing about one place). A triangle
//   whose centroid lies in no such triangle but on a strip of the charts' zero-area UV triangles (within a
//   quarter of its longest UV edge) has no original orientation to compare with: `unoriented`, not flipped.
//   A triangle flipped by that UV test whose surface place agrees with it (the original triangle nearest to
//   its 3-D centroid lies in the shared charts and has its UV orientation) sits beside a fold of a chart onto
//   itself (mirrored halves that meet in UV space): `fold`, not flipped. Overlapping charts (mirrored or
//   stacked UVs) make both counts lenient where they overlap, never stricter. Triangles with zero UV area are
//   counted apart (degenerate, with the original's count for comparison).
// - skinning: the Mesh model carries joint indices and weights but no skeleton or animation, so poses are
//   synthetic: the bind pose, then for each of the `poses` joints with the largest total weight a rotation of
//   `pose_angle_deg` about that joint's weighted centroid (axis perpendicular to the centroid's offset from
//   the mesh centre and to +y; x when they are parallel), applied linearly-blended by each vertex's weight for
//   that joint. Each pose is measured with evaluate() (Metro, both ways); the result lists every pose.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "lodforge/core/mesh.hpp"
#include "lodforge/core/stop.hpp"

namespace lodforge {

struct AttributeEvalOptions {
  std::size_t samples = 0;       // area samples on the original; 0 = clamp(4 × triangles, 20000, 400000)
  std::uint64_t seed = 12345;
  unsigned threads = 0;          // 0 = all cores; results are identical for any value
  int poses = 3;                 // synthetic joint rotations (skinned meshes), besides the bind pose
  double pose_angle_deg = 45.0;
  std::size_t pose_samples = 50000;  // area samples per direction of each pose's Metro evaluation
  // As EvalOptions::stop: polled between chunks of samples; once requested the rest is skipped, `stopped` set.
  StopRequest stop{};
};

struct AttributeError {
  std::string name;  // "NORMAL", "TEXCOORD_0", "COLOR_0", ...
  double rms = 0;    // in the attribute's own units (UV units, colour 0..1, unit-normal difference)
};

struct UvSetReport {
  int set = 0;
  double stretch_original = 0, stretch_simplified = 0;  // normalised L2 stretch (1 = no stretch)
  double stretch_ratio = 0;                             // simplified / original
  double stretch_max_linf = 0;                          // largest per-triangle L∞ stretch of the LOD (normalised)
  std::size_t flipped = 0;
  std::size_t spanning = 0;
  std::size_t outside = 0;  // LOD wedges whose UV lies in no original chart (not counted as spans)
  std::size_t degenerate = 0, degenerate_original = 0;  // triangles with zero UV area (not counted as flips)
  std::size_t unoriented = 0;  // over a zero-area UV strip of their chart: no orientation to compare (no flips)
  std::size_t fold = 0;        // flipped by their UV place, not by their surface place (not counted as flips)
};

struct PoseError {
  std::string name;  // "bind", "joint 12"
  double hausdorff_rel = 0, mean_rel = 0, rms_rel = 0;  // of the original's bind-pose diagonal
};

struct AttributeEvalResult {
  std::vector<AttributeError> attributes;
  double normal_deviation_mean_deg = 0, normal_deviation_p95_deg = 0;  // interpolated normals; 0 without
  std::vector<UvSetReport> uv_sets;
  std::vector<PoseError> poses;  // empty unless both meshes are skinned
  double pose_max_hausdorff_rel = 0;
  std::size_t samples = 0;
  bool stopped = false;  // options.stop was requested: the figures are incomplete and mean nothing
  // Counts of the LOD's triangles over all UV sets (a triangle flipped in two sets counts twice).
  std::size_t uv_flipped() const;
  std::size_t uv_spanning() const;
};

// UV chart id of every wedge of `m`, dense in order of first wedge: the wedges of one face, and the wedges of
// one vertex with equal UVs in every set, share a chart (the chart definition the metrics above use).
std::vector<std::uint32_t> uv_charts(const Mesh& m);

// Both meshes are triangulated internally. Attribute streams present in only one mesh are skipped.
AttributeEvalResult evaluate_attributes(const Mesh& original, const Mesh& simplified,
                                        const AttributeEvalOptions& options = {});

}  // namespace lodforge
