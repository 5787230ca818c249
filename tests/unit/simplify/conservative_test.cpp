// Conservative LODs: bounding LODs contain their input, occluder LODs lie inside it, at every ratio, after
// every collapse, through float output, with the volume budget and the error budget.
#include <gtest/gtest.h>

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "conservative_fixtures.hpp"
#include "lodforge/core/validate.hpp"
#include "lodforge/io/asset.hpp"
#include "lodforge/simplify/simplify.hpp"
#include "test_support.hpp"

namespace lodforge {
namespace {

using conservative_test::Tri;
using conservative_test::count_crossings;
using conservative_test::diagonal_of;
using conservative_test::signed_volume;
using conservative_test::triangles_of;

// Touching tolerance: a millionth of the source's diagonal.
constexpr double kTouch = 1e-6;

struct Shape {
  std::string name;
  Mesh mesh;
};

std::vector<Shape> shapes() {
  return {{"uv_sphere", testing::make_uv_sphere(24, 32)},
          {"torus", conservative_test::make_torus(48, 20, 1.0, 0.35)},
          {"c_shape", conservative_test::make_c_shape(5)},
          {"plate", conservative_test::make_plate(24)},
          {"icosphere", conservative_test::make_icosphere(3)}};
}

// Nesting of `lod` with `src` in `mode`: no crossing triangles, and the inner mesh's corners and samples inside
// or on the outer one. Returns a message, empty when it nests.
std::string nesting_problem(const Mesh& src, const Mesh& lod, Conservative mode, std::size_t samples) {
  const std::vector<Tri> s = triangles_of(src), l = triangles_of(lod);
  const double tol = kTouch * diagonal_of(s);
  const std::size_t crossings = count_crossings(l, s, tol);
  if (crossings > 0) return std::to_string(crossings) + " crossing triangle pairs";
  const bool bounding = mode == Conservative::bounding;
  const std::size_t outside =
      conservative_test::points_outside(conservative_test::test_points(bounding ? src : lod, samples), bounding ? l : s, tol);
  if (outside > 0) return std::to_string(outside) + " points of the inner mesh outside the outer one";
  return {};
}

TEST(Conservative, NestsAtEveryRatio) {
  for (const Shape& shape : shapes()) {
    const std::vector<Tri> src = triangles_of(shape.mesh);
    ASSERT_GT(signed_volume(src), 0.0) << shape.name << ": fixture not outward";
    for (Conservative mode : {Conservative::bounding, Conservative::occluder}) {
      for (double ratio : {0.5, 0.2, 0.05}) {
        const SimplifyResult r = simplify(shape.mesh, {.target_ratio = ratio, .conservative = mode});
        SCOPED_TRACE(shape.name + " " + conservative_name(mode) + " " + std::to_string(ratio));
        EXPECT_TRUE(validate(r.mesh).ok());
        EXPECT_LT(r.triangles_after, shape.mesh.triangle_count());
        EXPECT_EQ(nesting_problem(shape.mesh, r.mesh, mode, 3000), "");
        const double v0 = signed_volume(src), v1 = signed_volume(triangles_of(r.mesh));
        if (mode == Conservative::bounding) {
          EXPECT_GE(v1, v0 * (1 - 1e-9));
        } else {
          EXPECT_LE(v1, v0 * (1 + 1e-9));
        }
      }
    }
  }
}

TEST(Conservative, SmoothShapesReachTheirTargets) {
  // Where nothing is thin, the constraints leave room: the sphere and the icosphere reach 5%.
  for (const Mesh& m : {testing::make_uv_sphere(24, 32), conservative_test::make_icosphere(3)}) {
    for (Conservative mode : {Conservative::bounding, Conservative::occluder}) {
      const SimplifyResult r = simplify(m, {.target_ratio = 0.05, .conservative = mode});
      EXPECT_EQ(r.stop_reason, StopReason::target_reached) << conservative_name(mode);
    }
  }
}

TEST(Conservative, DefaultOptionsUnchanged) {
  const Mesh sphere = testing::make_uv_sphere(24, 32);
  SimplifyOptions plain{.target_ratio = 0.1};
  SimplifyOptions none = plain;
  none.conservative = Conservative::none;
  const SimplifyResult a = simplify(sphere, plain), b = simplify(sphere, none);
  EXPECT_TRUE(a.mesh == b.mesh);
  EXPECT_EQ(a.vetoes[Veto::conservative], 0u);
  // Conservative output differs (it is constrained), so the default path really is the plain one.
  const SimplifyResult c = simplify(sphere, {.target_ratio = 0.1, .conservative = Conservative::bounding});
  EXPECT_FALSE(a.mesh == c.mesh);
}

TEST(Conservative, InfeasibleCollapsesAreParked) {
  // A thin plate taken as far as it goes: a bounding collapse across the thickness would have to lie above the
  // top and below the bottom, so many are infeasible; the engine parks them and goes on until nothing is left.
  const Mesh plate = conservative_test::make_plate(24);
  for (Conservative mode : {Conservative::bounding, Conservative::occluder}) {
    const SimplifyResult r = simplify(plate, {.target_ratio = 0.0001, .max_batch = 1, .conservative = mode});
    EXPECT_EQ(r.stop_reason, StopReason::no_valid_collapse);
    if (mode == Conservative::bounding) {
      EXPECT_GT(r.vetoes[Veto::conservative], 0u);
    }
    EXPECT_TRUE(validate(r.mesh).ok());
    EXPECT_EQ(nesting_problem(plate, r.mesh, mode, 2000), "") << conservative_name(mode);
    EXPECT_EQ(r.rounds, r.collapses + r.vetoes.rejected());
  }
}

TEST(Conservative, FloatRoundedOutputNests) {
  // Far from the origin a float holds about 1e-4 here: rounding moves vertices by far more than the slack.
  const Mesh far = testing::translated(conservative_test::make_icosphere(3, 0.15, 5), Vec3f{{3000.f, -2000.f, 1000.f}});
  for (Conservative mode : {Conservative::bounding, Conservative::occluder}) {
    const SimplifyResult r = simplify(far, {.target_ratio = 0.1, .conservative = mode});
    EXPECT_EQ(nesting_problem(far, r.mesh, mode, 3000), "") << conservative_name(mode);
  }
}

TEST(Conservative, VolumeBudgetStopsBeforeExceeding) {
  const Mesh torus = conservative_test::make_torus(48, 20, 1.0, 0.35);
  const double v0 = signed_volume(triangles_of(torus));
  for (Engine engine : {Engine::edge_collapse, Engine::multiple_choice}) {
    const SimplifyResult free = simplify(torus, {.target_ratio = 0.02, .engine = engine, .conservative = Conservative::bounding});
    const double free_growth = signed_volume(triangles_of(free.mesh)) / v0 - 1.0;
    ASSERT_GT(free_growth, 0.05);
    const SimplifyResult held = simplify(torus, {.target_ratio = 0.02, .engine = engine,
                                                 .conservative = Conservative::bounding, .max_volume_growth = 0.05});
    const double growth = signed_volume(triangles_of(held.mesh)) / v0 - 1.0;
    EXPECT_LE(growth, 0.05 + 1e-6);
    EXPECT_GE(growth, 0.0);
    EXPECT_EQ(held.stop_reason, StopReason::error_budget);
    EXPECT_EQ(held.floors, std::vector<std::string>{"volume_budget"});
    EXPECT_GT(held.triangles_after, free.triangles_after);
  }
  // Occluder: the volume lost.
  const SimplifyResult occ = simplify(torus, {.target_ratio = 0.02, .conservative = Conservative::occluder,
                                              .max_volume_growth = 0.1});
  EXPECT_GE(signed_volume(triangles_of(occ.mesh)) / v0, 0.9 - 1e-6);
}

TEST(Conservative, ErrorBudgetComposes) {
  const Mesh blob = conservative_test::make_icosphere(3, 0.05, 3);
  for (Conservative mode : {Conservative::bounding, Conservative::occluder}) {
    const SimplifyResult r = simplify(blob, {.target_ratio = 0.02, .max_error_rel = 0.03, .conservative = mode});
    EXPECT_TRUE(r.budget.verified);
    EXPECT_TRUE(r.budget.within);
    EXPECT_EQ(nesting_problem(blob, r.mesh, mode, 2000), "") << conservative_name(mode);
  }
}

TEST(Conservative, MultipleChoiceNests) {
  const Mesh torus = conservative_test::make_torus(48, 20, 1.0, 0.35);
  for (Conservative mode : {Conservative::bounding, Conservative::occluder}) {
    const SimplifyResult r = simplify(torus, {.target_ratio = 0.1, .engine = Engine::multiple_choice, .conservative = mode});
    EXPECT_LT(r.triangles_after, torus.triangle_count() / 2);
    EXPECT_EQ(nesting_problem(torus, r.mesh, mode, 2000), "") << conservative_name(mode);
  }
}

TEST(Conservative, DeterministicWhateverTheThreads) {
  const Mesh blob = conservative_test::make_icosphere(4, 0.1, 9);
  const SimplifyResult a = simplify(blob, {.target_ratio = 0.05, .threads = 1, .conservative = Conservative::bounding});
  const SimplifyResult b = simplify(blob, {.target_ratio = 0.05, .threads = 4, .conservative = Conservative::bounding});
  EXPECT_TRUE(a.mesh == b.mesh);
}

TEST(Conservative, OptionsChecked) {
  SimplifyOptions o{.engine = Engine::cluster, .conservative = Conservative::bounding};
  EXPECT_FALSE(o.validate().empty());
  SimplifyOptions v{.max_volume_growth = 0.1};
  EXPECT_FALSE(v.validate().empty());
  EXPECT_STREQ(veto_name(Veto::conservative), "conservative");
}

// Random star-shaped blobs, each collapse replayed on a copy: the new fan never crosses the source, and the
// moved vertex stays on its side; the final LOD nests.
TEST(Conservative, FuzzNestsAfterEveryCollapse) {
  std::size_t meshes = 0, collapses = 0;
  for (std::uint64_t seed = 1; seed <= 200; ++seed) {
    const Conservative mode = seed % 2 ? Conservative::bounding : Conservative::occluder;
    const Mesh src = conservative_test::make_icosphere(seed % 3 == 0 ? 1 : 2, 0.05 + 0.05 * double(seed % 5), seed);
    const std::vector<Tri> s = triangles_of(src);
    const double tol = kTouch * diagonal_of(s);
    // The working copy: faces by vertex id, positions in float as the output writes them.
    std::vector<std::array<std::uint32_t, 3>> faces;
    for (std::size_t f = 0; f < src.face_count(); ++f) {
      const std::uint32_t c = src.face_offsets[f];
      faces.push_back({src.corner_vertex(c), src.corner_vertex(c + 1), src.corner_vertex(c + 2)});
    }
    std::vector<Vec3f> pos = src.positions;
    std::string problem;
    auto on_collapse = [&](const CollapseEvent& e) {
      ++collapses;
      pos[e.survivor] = to_float(e.position);
      std::vector<Tri> fan;
      for (auto& f : faces) {
        const bool has_victim = f[0] == e.victim || f[1] == e.victim || f[2] == e.victim;
        const bool has_survivor = f[0] == e.survivor || f[1] == e.survivor || f[2] == e.survivor;
        if (has_victim && has_survivor) {
          f = {kInvalidIndex, kInvalidIndex, kInvalidIndex};
          continue;
        }
        for (std::uint32_t& v : f) v = v == e.victim ? e.survivor : v;
        if (has_victim || has_survivor) {
          fan.push_back({to_double(pos[f[0]]), to_double(pos[f[1]]), to_double(pos[f[2]])});
        }
      }
      if (!problem.empty()) return;
      if (const std::size_t n = count_crossings(fan, s, tol); n > 0) {
        problem = "collapse " + std::to_string(collapses) + ": " + std::to_string(n) + " crossings";
        return;
      }
      const Vec3d p = to_double(pos[e.survivor]);
      const double w = conservative_test::winding_number(s, p);
      const bool wrong_side = mode == Conservative::bounding ? w > 0.5 : w < 0.5;
      if (wrong_side && conservative_test::distance_to_mesh(s, p) > tol) {
        problem = "collapse " + std::to_string(collapses) + ": moved vertex on the wrong side";
      }
    };
    const SimplifyResult r = simplify(src, {.target_ratio = 0.1, .conservative = mode}, {.on_collapse = on_collapse});
    ASSERT_EQ(problem, "") << "seed " << seed;
    ASSERT_EQ(nesting_problem(src, r.mesh, mode, 300), "") << "seed " << seed;
    ++meshes;
  }
  EXPECT_EQ(meshes, 200u);
  EXPECT_GT(collapses, 200u * 50u);
}

// Closed scanned meshes at 2%: both modes nest.
TEST(Conservative, CorpusClosedScans) {
  LODFORGE_REQUIRE_CORPUS(path, "scanned/armadillo-remeshed-29k.obj");
  const Mesh src = io::load_asset(path).meshes.at(0);
  for (Conservative mode : {Conservative::bounding, Conservative::occluder}) {
    const SimplifyResult r = simplify(src, {.target_ratio = 0.02, .conservative = mode});
    EXPECT_TRUE(validate(r.mesh).ok());
    EXPECT_LE(r.triangles_after, src.triangle_count() / 10) << conservative_name(mode);
    // Bounding: every source vertex and 10,000 source samples; occluder: the LOD's vertices and 2,000 samples
    // against the 29k source triangles.
    EXPECT_EQ(nesting_problem(src, r.mesh, mode, mode == Conservative::bounding ? 10000 : 2000), "")
        << conservative_name(mode);
  }
}

}  // namespace
}  // namespace lodforge

namespace lodforge {
namespace {

// A bumpy height field over [0, n]², open: its rim (the four straight sides) keeps its outline.
Mesh make_terrain(int n) {
  Mesh m;
  for (int y = 0; y <= n; ++y) {
    for (int x = 0; x <= n; ++x) {
      const double z = 0.8 * std::sin(0.4 * x) * std::cos(0.3 * y) + 0.3 * std::sin(1.3 * x + 0.7 * y);
      m.add_vertex_with_wedge({{float(x), float(y), float(z)}});
    }
  }
  auto id = [&](int x, int y) { return static_cast<std::uint32_t>(y * (n + 1) + x); };
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      m.add_face({id(x, y), id(x + 1, y), id(x + 1, y + 1)});
      m.add_face({id(x, y), id(x + 1, y + 1), id(x, y + 1)});
    }
  }
  return conservative_test::with_material(std::move(m));
}

// Height of the triangles at (x, y) (the highest or lowest where several cover it); nullopt where none does.
std::optional<double> height_at(const std::vector<Tri>& tris, double x, double y, bool highest) {
  std::optional<double> out;
  for (const Tri& t : tris) {
    const double d = (t[1][1] - t[2][1]) * (t[0][0] - t[2][0]) + (t[2][0] - t[1][0]) * (t[0][1] - t[2][1]);
    if (d == 0.0) continue;
    const double l0 = ((t[1][1] - t[2][1]) * (x - t[2][0]) + (t[2][0] - t[1][0]) * (y - t[2][1])) / d;
    const double l1 = ((t[2][1] - t[0][1]) * (x - t[2][0]) + (t[0][0] - t[2][0]) * (y - t[2][1])) / d;
    const double l2 = 1.0 - l0 - l1;
    constexpr double e = -1e-9;
    if (l0 < e || l1 < e || l2 < e) continue;
    const double z = l0 * t[0][2] + l1 * t[1][2] + l2 * t[2][2];
    out = !out ? z : highest ? std::max(*out, z) : std::min(*out, z);
  }
  return out;
}

TEST(Conservative, OpenTerrainStaysOnItsSide) {
  // Bounding: the LOD is above the terrain wherever the terrain is; occluder: below. Rim vertices never move,
  // the straight sides lose vertices, the four corners stay.
  const Mesh terrain = make_terrain(40);
  const std::vector<Tri> src = triangles_of(terrain);
  const double tol = kTouch * diagonal_of(src);
  for (Conservative mode : {Conservative::bounding, Conservative::occluder}) {
    SCOPED_TRACE(conservative_name(mode));
    const SimplifyResult r = simplify(terrain, {.target_ratio = 0.05, .conservative = mode});
    EXPECT_TRUE(validate(r.mesh).ok());
    EXPECT_LE(r.triangles_after, terrain.triangle_count() / 10);
    const std::vector<Tri> lod = triangles_of(r.mesh);
    EXPECT_EQ(count_crossings(lod, src, tol), 0u);
    const bool bounding = mode == Conservative::bounding;
    std::size_t wrong = 0, uncovered = 0;
    for (const Vec3d& p : conservative_test::test_points(terrain, 3000)) {
      const std::optional<double> z = height_at(lod, p[0], p[1], !bounding);
      if (!z) {
        ++uncovered;
      } else if (bounding ? *z < p[2] - tol : *z > p[2] + tol) {
        ++wrong;
      }
    }
    EXPECT_EQ(uncovered, 0u);
    EXPECT_EQ(wrong, 0u);
    // The rim kept its corners and lost vertices along its sides.
    std::size_t rim = 0;
    for (const Vec3f& p : r.mesh.positions) rim += p[0] == 0.0f || p[1] == 0.0f || p[0] == 40.0f || p[1] == 40.0f;
    EXPECT_GE(rim, 4u);
    EXPECT_LT(rim, 160u);
  }
}

}  // namespace
}  // namespace lodforge
