// Shared helpers for the test suite: corpus paths, small hand-made meshes, temporary folders.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "lodforge/core/mesh.hpp"

namespace lodforge::testing {

// Path of a corpus file, or empty when ../shared/corpus is absent (callers GTEST_SKIP with a message).
std::filesystem::path corpus_path(const std::string& relative);
#define LODFORGE_REQUIRE_CORPUS(var, rel)                                             \
  const auto var = ::lodforge::testing::corpus_path(rel);                            \
  if (var.empty()) GTEST_SKIP() << "corpus file " << (rel) << " absent (../shared/corpus)"

// A GoogleTest parameter name for a corpus file: its stem with every non-alphanumeric character as '_'.
std::string test_name_of(const std::string& path);

// A fresh empty folder under the build tree, removed by the caller's scope if wanted.
std::filesystem::path temp_dir(const std::string& name);

// ---- external commands ----

struct CommandResult {
  int exit_code = -1;   // -1 when the command could not be started or did not exit normally
  std::string output;   // stdout and stderr together
};
// Runs `command` through /bin/sh, capturing stdout and stderr.
CommandResult run_command(const std::string& command);
// `p` quoted for /bin/sh (single quotes, embedded quotes escaped).
std::string shell_quote(const std::filesystem::path& p);
// Runs the `lodforge` command built with the tests, with `args` (already quoted where needed).
CommandResult run_cli(const std::string& args);

// ---- the Khronos glTF validator (tests/support/validate_gltf.mjs; scripts/test.sh installs the npm module) ----

// Empty when the validator can run, else why not (node absent, module not installed).
std::string gltf_validator_unavailable();
#define LODFORGE_REQUIRE_GLTF_VALIDATOR()                                                        \
  if (const std::string why_ = ::lodforge::testing::gltf_validator_unavailable(); !why_.empty()) \
  GTEST_SKIP() << why_
// Validates `files`; exit code 0 when none has an error. With `baseline` (the source asset), errors the
// source itself already has are reported as inherited and do not count.
CommandResult validate_gltf(const std::vector<std::filesystem::path>& files,
                            const std::filesystem::path& baseline = {});

// Hand-made meshes (one wedge per vertex, material 0).
Mesh make_tetrahedron();
Mesh make_cube_quads();                 // 8 vertices, 6 quads, closed, outward
Mesh make_grid(int nx, int ny, bool quads);  // open planar grid in z=0 over [0,nx]x[0,ny]
Mesh make_uv_sphere(int rings, int segments, float radius = 1.0f);  // closed triangle sphere
// Open unit-radius triangle cylinder along z in [0, 4] bound to two joints: joint 0 below z = band_start, joint 1
// above band_start + band_width, weights linear in between (the blend band).
Mesh make_two_bone_cylinder(int rings, int segments, float band_start, float band_width);
// Hostile input for the evaluator's BVH, each about `triangles` triangles in the unit box:
//   zigzag fan      one polygon whose corners zig-zag along x between y = 0 and y = amplitude, fanned from its
//                   first corner into long overlapping slivers (amplitude 0: all corners collinear)
//   fanned disk     one convex polygon on the unit circle, fanned from its first corner: slivers radiating
//                   from one point, each with a loose diagonal box
//   cone            the side of a unit cone, one triangle per segment from the apex: slivers radiating in 3D
//   needle strip    a strip of 1 x 1/(triangles/2) slivers side by side, tilted so that every box is a cube
//   stacked grid    a small grid written `copies` times over itself (coincident triangles)
Mesh make_zigzag_fan(int corners, float amplitude);
Mesh make_fanned_disk(int corners);
Mesh make_cone(int segments);
Mesh make_needle_strip(int triangles);
Mesh make_stacked_grid(int triangles, int copies);
// `mesh` moved by `offset`.
Mesh translated(Mesh mesh, const Vec3f& offset);
// `mesh` turned about x by 0.5 and about y by 0.7 radians (positions rounded to float again): no plane of it
// stays axis-aligned, and a planar polygon's triangles are then coplanar only up to float rounding.
Mesh tilted(Mesh mesh);
// `mesh` with every `every`-th face written again at the end, starting from its second corner (what some
// exporters do: same face, same winding): repeated_faces() lists exactly the copies.
Mesh with_repeated_faces(const Mesh& mesh, std::size_t every);

// Of the mesh's edges (polygon sides), the share whose mirror image through the plane x = plane_x is an edge
// too (each end within `tol` of a vertex).
double mirror_paired_fraction(const Mesh& mesh, double plane_x, double tol);

}  // namespace lodforge::testing
