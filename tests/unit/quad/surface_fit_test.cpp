// Least-squares fitting of moved vertices to the input surface (quad/surface_fit.hpp), on a QuadMesh whose
// vertices a test displaced by hand: they come back to the surface, everything else stays bit for bit, and
// the answer does not depend on the thread count.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <tbb/task_arena.h>

#include "lodforge/eval/eval.hpp"
#include "lodforge/quad/quad_mesh.hpp"
#include "lodforge/quad/surface_fit.hpp"
#include "quad_meshes.hpp"

namespace lodforge::quad {
namespace {

using testing::make_quad_grid;

bool interior(const Mesh& grid, std::uint32_t v, int n) {
  const Vec3f& p = grid.positions[v];
  return p[0] > 0.5f && p[0] < n - 0.5f && p[1] > 0.5f && p[1] < n - 0.5f;
}

TEST(SurfaceFit, DisplacedVerticesComeBackToAFlatSurface) {
  const int n = 8;
  const Mesh grid = make_quad_grid(n, n);
  QuadMesh mesh(grid);
  // Three interior vertices lifted off the plane and pushed sideways (as a collapse's placement might).
  const std::vector<std::uint32_t> lifted{20, 40, 51};
  for (std::uint32_t v : lifted) {
    ASSERT_TRUE(interior(grid, v, n));
    mesh.set_position(v, mesh.position(v) + Vec3d{0.1, -0.05, 0.3});
  }
  const std::size_t steps = refit_to_surface(mesh, grid, input_surface_bvh(grid), {});
  EXPECT_GT(steps, 0u);
  for (std::uint32_t v : lifted) EXPECT_LT(std::abs(mesh.position(v)[2]), 0.01) << "vertex " << v;
  // Vertices no collapse moved keep their input positions exactly.
  for (std::uint32_t v = 0; v < grid.vertex_count(); ++v) {
    if (std::find(lifted.begin(), lifted.end(), v) != lifted.end()) continue;
    EXPECT_EQ(mesh.position(v), to_double(grid.positions[v])) << "vertex " << v;
  }
}

TEST(SurfaceFit, BoundaryAndLockedVerticesStay) {
  const int n = 6;
  const Mesh grid = make_quad_grid(n, n);
  QuadMesh mesh(grid);
  const std::uint32_t border = 3, locked = 15;  // (3, 0) on the boundary; (1, 2) inside
  ASSERT_FALSE(interior(grid, border, n));
  ASSERT_TRUE(interior(grid, locked, n));
  const Vec3d lift{0.0, 0.0, 0.25};
  mesh.set_position(border, mesh.position(border) + lift);
  mesh.set_position(locked, mesh.position(locked) + lift);
  mesh.lock(locked);
  refit_to_surface(mesh, grid, input_surface_bvh(grid), {});
  EXPECT_EQ(mesh.position(border), to_double(grid.positions[border]) + lift);
  EXPECT_EQ(mesh.position(locked), to_double(grid.positions[locked]) + lift);
}

// A wavy surface; the fitted mesh starts as the same grid with every interior vertex jittered (moved): the fit
// brings it much closer, the same way on one thread as on two.
TEST(SurfaceFit, JitteredVerticesFitAWavySurfaceTheSameOnAnyThreadCount) {
  const int n = 16;
  Mesh wavy = make_quad_grid(n, n);
  for (Vec3f& p : wavy.positions) p[2] = static_cast<float>(0.6 * std::sin(0.7 * p[0]) * std::cos(0.5 * p[1]));
  auto jittered = [&] {
    QuadMesh mesh(wavy);
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-0.15, 0.15);
    for (std::uint32_t v = 0; v < wavy.vertex_count(); ++v) {
      if (interior(wavy, v, n)) mesh.set_position(v, mesh.position(v) + Vec3d{u(rng), u(rng), u(rng)});
    }
    return mesh;
  };
  const TriangleBvh bvh = input_surface_bvh(wavy);
  const double before = evaluate(wavy, jittered().to_mesh(wavy)).mean;
  QuadMesh one = jittered(), two = jittered();
  tbb::task_arena(1).execute([&] { refit_to_surface(one, wavy, bvh, {}); });
  tbb::task_arena(2).execute([&] { refit_to_surface(two, wavy, bvh, {}); });
  for (std::uint32_t v = 0; v < wavy.vertex_count(); ++v) ASSERT_EQ(one.position(v), two.position(v)) << "vertex " << v;
  const Mesh fitted = one.to_mesh(wavy);
  testing::expect_valid(fitted);
  const double after = evaluate(wavy, fitted).mean;
  EXPECT_LT(after, 0.25 * before) << "mean distance " << before << " before the fit, " << after << " after";
}

}  // namespace
}  // namespace lodforge::quad
