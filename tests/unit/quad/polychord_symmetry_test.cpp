// Soft symmetry in the polychord engine: a run and its mirror image collapse together
// (PolychordOptions::symmetry_weight, SimplifyOptions::symmetry_weight with Engine::polychord).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>
#include <vector>

#include "lodforge/quad/polychord_collapse.hpp"
#include "lodforge/quad/quad_stats.hpp"
#include "lodforge/simplify/simplify.hpp"
#include "quad_meshes.hpp"
#include "test_support.hpp"

namespace lodforge::quad {
namespace {

using testing::add_point;
using testing::expect_valid;

// A bumpy quad torus of `major` × `minor` quads, mirror-symmetric about x = 0 in shape and connectivity
// alone (major even: the angle u maps to pi - u, and the bumps depend on sin(3u)), every coordinate then moved by up
// to `noise` (real assets are never symmetric bit for bit; without noise tie-breaking alone keeps exact
// mirrors symmetric). Vertex (i, j) has id j * major + i.
Mesh mirrored_torus(int major, int minor, double noise) {
  Mesh m;
  std::mt19937 rng(41);
  std::uniform_real_distribution<double> jitter(-noise, noise);
  for (int j = 0; j < minor; ++j) {
    for (int i = 0; i < major; ++i) {
      const double u = 2.0 * std::numbers::pi * i / major, v = 2.0 * std::numbers::pi * j / minor;
      // sin(v) breaks the mirror through z = 0, so that x = 0 is the one plane.
      const double r = 1.0 + 0.25 * std::sin(3.0 * u) * std::cos(2.0 * v) + 0.1 * std::sin(u) + 0.15 * std::sin(v);
      const double ring = 3.0 + r * std::cos(v);
      add_point(m, ring * std::cos(u) + jitter(rng), ring * std::sin(u) + jitter(rng), r * std::sin(v) + jitter(rng));
    }
  }
  auto id = [&](int i, int j) { return static_cast<std::uint32_t>((j % minor) * major + (i % major)); };
  for (int j = 0; j < minor; ++j) {
    for (int i = 0; i < major; ++i) m.add_face({id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)});
  }
  return m;
}

constexpr int kMajor = 48, kMinor = 16;
constexpr double kNoise = 1e-6;


// Mirrored vertices are put at each other's images through the plane found from the noisy input: well
// within this of each other, which is far below an edge (about 0.4).
constexpr double kMirrorTolerance = 1e-3;

TEST(PolychordSymmetry, PairsKeepAMirroredQuadMeshSymmetric) {
  const Mesh mesh = mirrored_torus(kMajor, kMinor, kNoise);
  ASSERT_GT(testing::mirror_paired_fraction(mesh, 0.0, kMirrorTolerance), 0.99);
  for (double ratio : {0.5, 0.25}) {
    const PolychordResult plain = simplify_polychord(mesh, {.target_ratio = ratio});
    const PolychordResult sym = simplify_polychord(mesh, {.target_ratio = ratio, .symmetry_weight = 1.0});
    EXPECT_EQ(plain.paired_collapses, 0u);
    EXPECT_GT(sym.paired_collapses, sym.collapses / 2) << ratio;
    EXPECT_NEAR(static_cast<double>(sym.triangles_after), static_cast<double>(plain.triangles_after),
                0.03 * static_cast<double>(plain.triangles_after));
    const double with = testing::mirror_paired_fraction(sym.mesh, 0.0, kMirrorTolerance);
    const double without = testing::mirror_paired_fraction(plain.mesh, 0.0, kMirrorTolerance);
    EXPECT_GE(with, 0.95) << "ratio " << ratio << ", without the term " << without;
    EXPECT_GT(with, without) << ratio;
    EXPECT_GT(quad_stats(sym.mesh).quad_fraction, 0.8) << ratio;
    expect_valid(sym.mesh);
  }
}

TEST(PolychordSymmetry, SimplifyPassesTheTermToTheQuadEngine) {
  const Mesh mesh = mirrored_torus(kMajor, kMinor, kNoise);
  const SimplifyResult r = simplify(mesh, {.target_ratio = 0.5, .engine = Engine::polychord, .symmetry_weight = 1.0});
  EXPECT_GT(r.paired_collapses, r.collapses / 2);
  EXPECT_GE(testing::mirror_paired_fraction(r.mesh, 0.0, kMirrorTolerance), 0.95);
}

TEST(PolychordSymmetry, AGivenMirrorMapIsUsedAsIs) {
  const Mesh mesh = mirrored_torus(kMajor, kMinor, kNoise);
  std::vector<std::uint32_t> mirror(mesh.vertex_count());
  for (int j = 0; j < kMinor; ++j) {
    for (int i = 0; i < kMajor; ++i) mirror[j * kMajor + i] = j * kMajor + (kMajor / 2 - i + kMajor) % kMajor;
  }
  const PolychordResult given =
      simplify_polychord(mesh, {.target_ratio = 0.4, .symmetry_weight = 1.0, .vertex_mirror = &mirror});
  EXPECT_GT(given.paired_collapses, given.collapses / 2);
  EXPECT_GE(testing::mirror_paired_fraction(given.mesh, 0.0, kMirrorTolerance), 0.95);
  // A map of the wrong size is ignored: no pairs.
  const std::vector<std::uint32_t> wrong(3, 0);
  EXPECT_EQ(simplify_polychord(mesh, {.target_ratio = 0.4, .symmetry_weight = 1.0, .vertex_mirror = &wrong})
                .paired_collapses,
            0u);
}

TEST(PolychordSymmetry, WithoutAMirrorPlaneTheLodIsUnchanged) {
  const Mesh mesh = mirrored_torus(kMajor, kMinor, kNoise);
  const PolychordResult plain = simplify_polychord(mesh, {.target_ratio = 0.3});
  const PolychordResult none = simplify_polychord(
      mesh, {.target_ratio = 0.3, .symmetry_weight = 1.0, .symmetry_plane = symmetry::PlaneMode::none});
  EXPECT_EQ(plain.mesh.positions, none.mesh.positions);
  EXPECT_EQ(plain.mesh.corner_wedge, none.mesh.corner_wedge);
  EXPECT_EQ(none.paired_collapses, 0u);
}

TEST(PolychordSymmetry, PaintedPriorityOnOneSideKeepsThatSide) {
  Mesh mesh = mirrored_torus(kMajor, kMinor, kNoise);
  mesh.priority.assign(mesh.vertex_count(), 1.0f);
  for (std::uint32_t v = 0; v < mesh.vertex_count(); ++v) {
    if (mesh.positions[v][0] > 0.5f) mesh.priority[v] = 10.0f;
  }
  const PolychordResult r = simplify_polychord(mesh, {.target_ratio = 0.3, .symmetry_weight = 1.0});
  std::size_t left = 0, right = 0;
  for (const Vec3f& p : r.mesh.positions) {
    if (p[0] < -0.5f) ++left;
    if (p[0] > 0.5f) ++right;
  }
  // Pairs would keep both sides alike; the painted side must keep clearly more.
  EXPECT_GT(right, 2 * left) << "left " << left << ", right " << right;
}

TEST(PolychordSymmetry, SameOutputEveryRunAndForAnyThreadCount) {
  const Mesh mesh = mirrored_torus(kMajor, kMinor, kNoise);
  SimplifyOptions one{.target_ratio = 0.25, .engine = Engine::polychord, .symmetry_weight = 2.0};
  one.threads = 1;
  SimplifyOptions two = one;
  two.threads = 2;
  const SimplifyResult a = simplify(mesh, one), b = simplify(mesh, two), c = simplify(mesh, one);
  EXPECT_EQ(a.mesh.positions, b.mesh.positions);
  EXPECT_EQ(a.mesh.corner_wedge, b.mesh.corner_wedge);
  EXPECT_EQ(a.mesh.positions, c.mesh.positions);
  EXPECT_EQ(a.paired_collapses, b.paired_collapses);
}

}  // namespace
}  // namespace lodforge::quad
