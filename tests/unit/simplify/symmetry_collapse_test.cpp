// Soft symmetric simplification: an edge and its mirror image collapse together (SimplifyOptions::symmetry_weight).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <set>
#include <utility>
#include <vector>

#include "lodforge/core/topology.hpp"
#include "lodforge/core/validate.hpp"
#include "lodforge/simplify/simplify.hpp"
#include "simplify_fixtures.hpp"
#include "test_support.hpp"

namespace lodforge {
namespace {

// An open bumpy height field over [0, 2n] × [0, m], mirror-symmetric about x = n in shape and in its
// triangulation (the cells left of the plane split along one diagonal, those right of it along the mirrored
// one), every vertex then moved by up to `noise` in each coordinate (real assets are never symmetric bit for
// bit: without noise, tie-breaking alone keeps exact mirrors symmetric).
Mesh mirrored_terrain(int n, int m, double noise) {
  Mesh mesh;
  std::mt19937 rng(77);
  std::uniform_real_distribution<double> jitter(-noise, noise);
  for (int j = 0; j <= m; ++j) {
    for (int i = 0; i <= 2 * n; ++i) {
      const double x = std::abs(i - n);  // distance to the plane: the height depends on it, not on the side
      const double h = 0.8 * std::sin(0.45 * x + 0.3) * std::cos(0.35 * j) + 0.3 * std::sin(0.9 * j + 0.2 * x * x / n);
      mesh.add_vertex_with_wedge(Vec3f{static_cast<float>(i + jitter(rng)), static_cast<float>(j + jitter(rng)),
                                       static_cast<float>(h + jitter(rng))});
    }
  }
  const auto id = [&](int i, int j) { return static_cast<std::uint32_t>(j * (2 * n + 1) + i); };
  for (int j = 0; j < m; ++j) {
    for (int i = 0; i < 2 * n; ++i) {
      if (i < n) {
        mesh.add_face({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
        mesh.add_face({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
      } else {
        mesh.add_face({id(i, j), id(i + 1, j), id(i, j + 1)});
        mesh.add_face({id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)});
      }
    }
  }
  mesh.materials.push_back(MaterialSlot{.name = "default"});
  return mesh;
}


constexpr int kHalf = 16, kRows = 24;
constexpr double kNoise = 1e-5;  // about 1e-6 of the diagonal

TEST(SymmetricCollapse, PairsKeepAMirroredMeshSymmetric) {
  const Mesh mesh = mirrored_terrain(kHalf, kRows, kNoise);
  ASSERT_GT(testing::mirror_paired_fraction(mesh, kHalf, 0.01), 0.99);
  for (double ratio : {0.5, 0.25}) {
    const SimplifyResult plain = simplify(mesh, {.target_ratio = ratio});
    const SimplifyResult sym = simplify(mesh, {.target_ratio = ratio, .symmetry_weight = 1.0});
    EXPECT_NEAR(static_cast<double>(sym.triangles_after), static_cast<double>(plain.triangles_after), 4.0);
    EXPECT_GT(sym.paired_collapses, sym.collapses / 2) << ratio;
    EXPECT_EQ(plain.paired_collapses, 0u);
    const double with = testing::mirror_paired_fraction(sym.mesh, kHalf, 0.01);
    const double without = testing::mirror_paired_fraction(plain.mesh, kHalf, 0.01);
    EXPECT_GE(with, 0.95) << "ratio " << ratio << ", without the term " << without;
    EXPECT_GT(with, without) << ratio;
    EXPECT_TRUE(validate(sym.mesh).ok());
  }
}

TEST(SymmetricCollapse, AGivenMirrorMapIsUsedAsIs) {
  const Mesh mesh = mirrored_terrain(kHalf, kRows, kNoise);
  std::vector<std::uint32_t> mirror(mesh.vertex_count());
  for (int j = 0; j <= kRows; ++j) {
    for (int i = 0; i <= 2 * kHalf; ++i) mirror[j * (2 * kHalf + 1) + i] = j * (2 * kHalf + 1) + (2 * kHalf - i);
  }
  const SimplifyResult found = simplify(mesh, {.target_ratio = 0.3, .symmetry_weight = 1.0});
  const SimplifyResult given = simplify(mesh, {.target_ratio = 0.3, .symmetry_weight = 1.0, .vertex_mirror = &mirror});
  EXPECT_GE(testing::mirror_paired_fraction(found.mesh, kHalf, 0.01), 0.95);
  EXPECT_GE(testing::mirror_paired_fraction(given.mesh, kHalf, 0.01), 0.95);
  EXPECT_GT(given.paired_collapses, given.collapses / 2);
  // A map of the wrong size is ignored: no pairs.
  const std::vector<std::uint32_t> wrong(3, 0);
  EXPECT_EQ(simplify(mesh, {.target_ratio = 0.3, .symmetry_weight = 1.0, .vertex_mirror = &wrong}).paired_collapses, 0u);
}

TEST(SymmetricCollapse, OffAndAsymmetricMeshesSimplifyAsBefore) {
  const Mesh mesh = mirrored_terrain(kHalf, kRows, kNoise);
  const SimplifyResult plain = simplify(mesh, {.target_ratio = 0.3});
  const SimplifyResult zero = simplify(mesh, {.target_ratio = 0.3, .symmetry_weight = 0.0});
  EXPECT_EQ(plain.mesh.positions, zero.mesh.positions);
  EXPECT_EQ(plain.mesh.corner_wedge, zero.mesh.corner_wedge);
  // No mirror plane at all: nothing to pair, the same LOD.
  const Mesh sphere = simplify_test::make_bumpy_sphere(16, 24);
  const SimplifyResult a = simplify(sphere, {.target_ratio = 0.3});
  const SimplifyResult b = simplify(sphere, {.target_ratio = 0.3, .symmetry_weight = 1.0, .symmetry_plane = symmetry::PlaneMode::none});
  EXPECT_EQ(a.mesh.positions, b.mesh.positions);
  EXPECT_EQ(b.paired_collapses, 0u);
}

TEST(SymmetricCollapse, PaintedPriorityOnOneSideKeepsThatSide) {
  Mesh mesh = mirrored_terrain(kHalf, kRows, kNoise);
  mesh.priority.assign(mesh.vertex_count(), 1.0f);
  for (std::uint32_t v = 0; v < mesh.vertex_count(); ++v) {
    if (mesh.positions[v][0] > kHalf + 0.5f) mesh.priority[v] = 10.0f;  // the right side
  }
  const SimplifyResult r = simplify(mesh, {.target_ratio = 0.3, .symmetry_weight = 1.0});
  std::size_t left = 0, right = 0;
  for (const Vec3f& p : r.mesh.positions) (p[0] < kHalf ? left : right) += p[0] != static_cast<float>(kHalf);
  // Pairs would keep both sides alike; the painted side must keep clearly more.
  EXPECT_GT(right, 2 * left) << "left " << left << ", right " << right;
}

TEST(SymmetricCollapse, SameOutputForAnyThreadCount) {
  const Mesh mesh = mirrored_terrain(kHalf, kRows, kNoise);
  const SimplifyResult one = simplify(mesh, {.target_ratio = 0.25, .threads = 1, .symmetry_weight = 2.0});
  const SimplifyResult two = simplify(mesh, {.target_ratio = 0.25, .threads = 2, .symmetry_weight = 2.0});
  EXPECT_EQ(one.mesh.positions, two.mesh.positions);
  EXPECT_EQ(one.mesh.corner_wedge, two.mesh.corner_wedge);
  EXPECT_EQ(one.paired_collapses, two.paired_collapses);
}

TEST(SymmetricCollapse, NegativeWeightIsRejected) {
  const SimplifyOptions o{.symmetry_weight = -1.0};
  const std::vector<std::string> problems = o.validate();
  ASSERT_EQ(problems.size(), 1u);
  EXPECT_NE(problems[0].find("symmetry_weight"), std::string::npos);
}

}  // namespace
}  // namespace lodforge
