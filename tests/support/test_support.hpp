// Shared helpers for the test suite: corpus paths, small hand-made meshes, temporary folders.
#pragma once

#include <filesystem>
#include <string>

#include "lodforge/core/mesh.hpp"

namespace lodforge::testing {

// Path of a corpus file, or empty when ../shared/corpus is absent (callers GTEST_SKIP with a message).
std::filesystem::path corpus_path(const std::string& relative);
#define LODFORGE_REQUIRE_CORPUS(var, rel)                                             \
  const auto var = ::lodforge::testing::corpus_path(rel);                            \
  if (var.empty()) GTEST_SKIP() << "corpus file " << (rel) << " absent (../shared/corpus)"

// A fresh empty folder under the build tree, removed by the caller's scope if wanted.
std::filesystem::path temp_dir(const std::string& name);

// Hand-made meshes (one wedge per vertex, material 0).
Mesh make_tetrahedron();
Mesh make_cube_quads();                 // 8 vertices, 6 quads, closed, outward
Mesh make_grid(int nx, int ny, bool quads);  // open planar grid in z=0 over [0,nx]x[0,ny]
Mesh make_uv_sphere(int rings, int segments, float radius = 1.0f);  // closed triangle sphere

}  // namespace lodforge::testing
