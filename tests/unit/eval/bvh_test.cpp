#include "lodforge/eval/bvh.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <numeric>
#include <vector>

#include "test_support.hpp"

namespace lodforge {
namespace {

Vec3d v3(double x, double y, double z) { return {{x, y, z}}; }

void expect_vec_near(const Vec3d& got, const Vec3d& want, double tol = 1e-12) {
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(got[i], want[i], tol) << "component " << i;
}

// The reference triangle of every region test, in the plane z = 0:
//
//   y
//   c          a = (0,0,0)
//   |`.        b = (2,0,0)
//   |  `.      c = (0,2,0)
//   a----b  x
const Vec3d kA = v3(0, 0, 0), kB = v3(2, 0, 0), kC = v3(0, 2, 0);

struct RegionCase {
  const char* region;
  Vec3d query, point, barycentric;
};

TEST(ClosestPointOnTriangle, EachVoronoiRegionGivesTheHandComputedPoint) {
  const RegionCase cases[] = {
      {"vertex a", v3(-1, -1, 3), v3(0, 0, 0), v3(1, 0, 0)},
      {"vertex b", v3(3, -0.5, -2), v3(2, 0, 0), v3(0, 1, 0)},
      {"vertex c", v3(-0.5, 4, 1), v3(0, 2, 0), v3(0, 0, 1)},
      {"edge ab", v3(0.5, -1, 2), v3(0.5, 0, 0), v3(0.75, 0.25, 0)},
      {"edge ac", v3(-3, 1.5, 0), v3(0, 1.5, 0), v3(0.25, 0, 0.75)},
      // Off the hypotenuse x + y = 2: (2, 1) projects to (1.5, 0.5).
      {"edge bc", v3(2, 1, 7), v3(1.5, 0.5, 0), v3(0, 0.75, 0.25)},
      {"face", v3(0.5, 0.25, -3), v3(0.5, 0.25, 0), v3(0.625, 0.25, 0.125)},
      {"face, point on it", v3(1, 0.5, 0), v3(1, 0.5, 0), v3(0.25, 0.5, 0.25)},
  };
  for (const RegionCase& c : cases) {
    SCOPED_TRACE(c.region);
    const TrianglePoint tp = closest_point_on_triangle(c.query, kA, kB, kC);
    expect_vec_near(tp.point, c.point);
    expect_vec_near(tp.barycentric, c.barycentric);
  }
}

TEST(ClosestPointOnTriangle, BarycentricsReproduceThePoint) {
  const Vec3d a = v3(0.3, -1, 2), b = v3(2, 0.5, 1), c = v3(-1, 1.5, 0.5);
  const Vec3d queries[] = {v3(0, 0, 0), v3(5, 5, 5), v3(-3, 2, 1), v3(0.4, 0.4, 1.2), v3(1, -2, 3)};
  for (const Vec3d& q : queries) {
    const TrianglePoint tp = closest_point_on_triangle(q, a, b, c);
    const Vec3d& w = tp.barycentric;
    EXPECT_NEAR(w[0] + w[1] + w[2], 1.0, 1e-12);
    for (int k = 0; k < 3; ++k) EXPECT_GE(w[k], -1e-12);
    expect_vec_near(a * w[0] + b * w[1] + c * w[2], tp.point);
  }
}

TEST(ClosestPointOnTriangle, DegenerateTrianglesGiveTheClosestPointOfTheirSegmentOrPoint) {
  // Collinear corners on the x axis spanning [0, 3], the middle one last.
  const Vec3d a = v3(0, 0, 0), b = v3(3, 0, 0), c = v3(1, 0, 0);
  const Vec3d queries[] = {v3(2, 1, 0), v3(1.5, 0, -2), v3(-1, 1, 1), v3(4, 0, 0), v3(0.5, 0, 0)};
  const Vec3d expected[] = {v3(2, 0, 0), v3(1.5, 0, 0), v3(0, 0, 0), v3(3, 0, 0), v3(0.5, 0, 0)};
  for (int i = 0; i < 5; ++i) {
    SCOPED_TRACE(i);
    const TrianglePoint tp = closest_point_on_triangle(queries[i], a, b, c);
    expect_vec_near(tp.point, expected[i]);
    const Vec3d& w = tp.barycentric;
    EXPECT_NEAR(w[0] + w[1] + w[2], 1.0, 1e-12);
    expect_vec_near(a * w[0] + b * w[1] + c * w[2], tp.point);
  }
  // All corners equal.
  const Vec3d p = v3(1, 2, 3);
  const TrianglePoint tp = closest_point_on_triangle(v3(4, 6, 3), p, p, p);
  expect_vec_near(tp.point, p);
  EXPECT_NEAR(tp.barycentric[0] + tp.barycentric[1] + tp.barycentric[2], 1.0, 1e-12);
}

TEST(ClosestPointOnTriangle, PointsOnASliverAreAtDistanceZero) {
  // A 1:10000 sliver lying across the axes: from its sharp corner the region tests subtract nearly equal
  // products, so a point built on the triangle used to come back ~1e-8 away from it.
  const Vec3d a = v3(0.1, 0.2, 0.3), b = v3(1.1, 0.9, 1.2), c = v3(1.1001, 0.9, 1.2002);
  double worst = 0;
  for (int i = 1; i < 100; ++i) {
    for (int j = 1; i + j < 100; j += 7) {
      const double u = i / 100.0, v = j / 100.0;
      const Vec3d p = a + (b - a) * u + (c - a) * v;
      const TrianglePoint tp = closest_point_on_triangle(p, a, b, c);
      worst = std::max(worst, length(tp.point - p));
    }
  }
  EXPECT_LT(worst, 1e-14);
}

// Counter-based uniform in [lo, hi): portable, unlike std distributions.
double uniform(std::uint64_t key, double lo, double hi) {
  std::uint64_t x = key * 0x9E3779B97F4A7C15ull + 0x632BE59BD9B4E019ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  x ^= x >> 31;
  return lo + (hi - lo) * (static_cast<double>(x >> 11) * 0x1.0p-53);
}

struct Soup {
  std::vector<Vec3d> positions;
  std::vector<std::uint32_t> indices;
};

// Random triangles of mixed sizes in the unit cube, with a few degenerate ones.
Soup random_soup(int triangles) {
  Soup s;
  std::uint64_t key = 1;
  for (int t = 0; t < triangles; ++t) {
    const double size = t % 7 == 0 ? 0.5 : 0.05;
    const Vec3d c = v3(uniform(key, 0, 1), uniform(key + 1, 0, 1), uniform(key + 2, 0, 1));
    key += 3;
    for (int k = 0; k < 3; ++k) {
      Vec3d p = c + v3(uniform(key, -size, size), uniform(key + 1, -size, size), uniform(key + 2, -size, size));
      key += 3;
      if (t % 31 == 0 && k == 2) p = s.positions[s.positions.size() - 1] * 2.0 - s.positions[s.positions.size() - 2];
      s.positions.push_back(p);
      s.indices.push_back(static_cast<std::uint32_t>(s.positions.size() - 1));
    }
  }
  return s;
}

BvhHit brute_force(const Soup& s, const Vec3d& p) {
  BvhHit best;
  for (std::uint32_t t = 0; t < s.indices.size() / 3; ++t) {
    const TrianglePoint tp = closest_point_on_triangle(p, s.positions[s.indices[3 * t]],
                                                       s.positions[s.indices[3 * t + 1]],
                                                       s.positions[s.indices[3 * t + 2]]);
    const Vec3d d = tp.point - p;
    if (dot(d, d) < best.distance_sq) best = {t, tp.point, tp.barycentric, dot(d, d)};
  }
  return best;
}

TEST(TriangleBvh, ClosestPointEqualsBruteForceOnRandomSoup) {
  const Soup soup = random_soup(1500);
  const TriangleBvh bvh(soup.positions, soup.indices);
  ASSERT_EQ(bvh.triangle_count(), 1500u);
  std::uint64_t key = 1u << 20;
  for (int q = 0; q < 600; ++q) {
    // Near the soup, and far outside it (where pruning works differently).
    const double r = q % 3 == 0 ? 4.0 : 0.6;
    const Vec3d p = v3(uniform(key, 0.5 - r, 0.5 + r), uniform(key + 1, 0.5 - r, 0.5 + r),
                       uniform(key + 2, 0.5 - r, 0.5 + r));
    key += 3;
    const BvhHit want = brute_force(soup, p);
    const BvhHit got = bvh.closest_point(p);
    ASSERT_TRUE(got.found());
    EXPECT_NEAR(got.distance_sq, want.distance_sq, 1e-12 * want.distance_sq) << "query " << q;
    // The reported point really is the closest point of the reported triangle.
    const std::array<Vec3d, 3> t = bvh.triangle(got.triangle);
    const TrianglePoint tp = closest_point_on_triangle(p, t[0], t[1], t[2]);
    expect_vec_near(got.point, tp.point);
    // A hint (here an arbitrary triangle) changes the work, not the answer.
    const BvhHit hinted = bvh.closest_point(p, static_cast<std::uint32_t>((q * 37) % 1500));
    EXPECT_NEAR(hinted.distance_sq, want.distance_sq, 1e-12 * want.distance_sq) << "query " << q;
  }
}

// Queries along a stream with the previous answer as the hint, as eval makes them: the hinted search walks the
// mesh from the hint and must still give the brute-force distance. Here on a closed mesh and on a fan of
// overlapping slivers (many triangles equally close: the answer is one of them, at the same distance).
TEST(TriangleBvh, HintedQueriesOnConnectedMeshesEqualBruteForce) {
  for (const Mesh& mesh : {testing::make_uv_sphere(16, 24), testing::make_zigzag_fan(300, 0.05f)}) {
    const Mesh tris = triangulated(mesh);
    Soup soup;
    for (const Vec3f& p : mesh.positions) soup.positions.push_back(to_double(p));
    soup.indices = triangle_vertex_indices(mesh);
    const TriangleBvh bvh(soup.positions, soup.indices);
    std::uint32_t hint = kInvalidIndex;
    std::uint64_t key = 7;
    for (std::uint32_t t = 0; t < bvh.triangle_count(); ++t) {
      const std::array<Vec3d, 3> c = bvh.triangle(t);
      for (const double lift : {0.0, 0.02, -0.3}) {
        // On triangle t, moved along z (off the surface, to the side of the fan, inside the sphere).
        const double u = uniform(key, 0, 0.5), v = uniform(key + 1, 0, 0.5);
        key += 2;
        const Vec3d p = c[0] + (c[1] - c[0]) * u + (c[2] - c[0]) * v + v3(0.3 * lift, lift, lift);
        const BvhHit want = brute_force(soup, p);
        BvhWork work;
        const BvhHit got = bvh.closest_point(p, hint, work);
        ASSERT_TRUE(got.found());
        // Up to the documented tie tolerance (2^-24 of the largest coordinate, here below 2): of the nested slivers
        // of the fan, and of two sphere triangles that close, either may be returned.
        EXPECT_NEAR(got.distance(), want.distance(), 0x1p-24 * 2.0) << "triangle " << t << " lift " << lift;
        EXPECT_GE(got.distance_sq, want.distance_sq) << "a real triangle's distance";
        const std::array<Vec3d, 3> g = bvh.triangle(got.triangle);
        expect_vec_near(got.point, closest_point_on_triangle(p, g[0], g[1], g[2]).point);
        EXPECT_GE(work.triangles, 1u);
        hint = got.triangle;
      }
    }
  }
}

// any_within answers whether the brute-force distance is within the limit, whatever the hint (none, a far
// triangle, the previous answer), and the hint it leaves is a triangle within the limit.
TEST(TriangleBvh, AnyWithinAgreesWithBruteForceWhateverTheHint) {
  const Soup soup = random_soup(1200);
  const TriangleBvh bvh(soup.positions, soup.indices);
  std::uint64_t key = 1u << 21;
  std::uint32_t stream_hint = kInvalidIndex;
  int inside = 0, outside = 0;
  for (int q = 0; q < 800; ++q) {
    const Vec3d p = v3(uniform(key, -0.2, 1.2), uniform(key + 1, -0.2, 1.2), uniform(key + 2, -0.2, 1.2));
    key += 3;
    const double d = brute_force(soup, p).distance();
    // Limits on both sides of the distance, close to it and far from it.
    for (const double limit : {0.5 * d, d * (1 - 1e-9), d * (1 + 1e-9), 2.0 * d + 0.01}) {
      const bool want = d <= limit;
      for (std::uint32_t hint : {kInvalidIndex, static_cast<std::uint32_t>((q * 53) % 1200), stream_hint}) {
        const std::uint32_t given = hint;
        EXPECT_EQ(bvh.any_within(p, limit, hint), want) << "query " << q << " limit/d " << limit / d;
        if (want) {
          const std::array<Vec3d, 3> t = bvh.triangle(hint);
          const Vec3d e = closest_point_on_triangle(p, t[0], t[1], t[2]).point - p;
          EXPECT_LE(std::sqrt(dot(e, e)), limit);
          stream_hint = hint;
        } else {
          EXPECT_EQ(hint, given) << "a query that finds nothing leaves the hint as it was";
        }
      }
      (want ? inside : outside) += 1;
    }
  }
  EXPECT_GT(inside, 1000);
  EXPECT_GT(outside, 1000);
  std::uint32_t hint = kInvalidIndex;
  EXPECT_FALSE(TriangleBvh().any_within(v3(0, 0, 0), 1.0, hint));
}

// A coherent stream of queries that all pass costs about one triangle each: the hint answers.
TEST(TriangleBvh, AnyWithinOnACoherentStreamTestsAboutOneTrianglePerQuery) {
  const Mesh mesh = testing::make_uv_sphere(64, 96);
  std::vector<Vec3d> positions;
  for (const Vec3f& p : mesh.positions) positions.push_back(to_double(p));
  const TriangleBvh bvh(positions, triangle_vertex_indices(mesh));
  BvhWork work;
  std::uint32_t hint = kInvalidIndex;
  std::size_t queries = 0;
  for (std::uint32_t t = 0; t < bvh.triangle_count(); ++t) {
    const std::array<Vec3d, 3> c = bvh.triangle(t);
    ASSERT_TRUE(bvh.any_within((c[0] + c[1] + c[2]) * (1.0 / 3.0), 1e-3, hint, work));
    ++queries;
  }
  EXPECT_LT(double(work.triangles) / queries, 3.0);
}

TEST(TriangleBvh, WorkCountsOpenedNodesAndTestedTriangles) {
  const std::vector<Vec3d> positions = {v3(0, 0, 0), v3(1, 0, 0), v3(0, 1, 0)};
  const std::vector<std::uint32_t> indices = {0, 1, 2};
  const TriangleBvh single(positions, indices);
  BvhWork work;
  single.closest_point(v3(0.2, 0.2, 1), kInvalidIndex, work);
  EXPECT_EQ(work.nodes, 0u);  // the root is a leaf
  EXPECT_EQ(work.triangles, 1u);
  single.closest_point(v3(0.2, 0.2, 1), 0, work);  // the hint is measured; the tree adds nothing closer
  EXPECT_EQ(work.triangles, 2u);

  const Soup soup = random_soup(500);
  const TriangleBvh bvh(soup.positions, soup.indices);
  BvhWork total;
  for (int q = 0; q < 50; ++q) {
    bvh.closest_point(v3(uniform(q, 0, 1), uniform(q + 99, 0, 1), 0.5), kInvalidIndex, total);
  }
  EXPECT_GT(total.nodes, 50u);
  EXPECT_GT(total.triangles, 50u);
  EXPECT_LT(total.triangles, 50u * 500u / 4) << "the tree prunes most triangles";
}

// Soup of a mesh's triangles, fan-triangulated as the BVH numbers them.
Soup soup_of(const Mesh& mesh) {
  Soup s;
  for (const Vec3f& p : mesh.positions) s.positions.push_back(to_double(p));
  s.indices = triangle_vertex_indices(mesh);
  return s;
}

// The invariants the search relies on, with long slivers entered as several pieces: every slot's piece is inside
// every box above it, every triangle has one slot per piece of one split, and every point of a triangle is inside
// all the boxes above at least one of its slots.
TEST(TriangleBvh, EveryBoxContainsItsSubtreeAndEveryPointOfATriangleIsUnderOneOfItsSlots) {
  const Soup soups[] = {random_soup(800), soup_of(testing::make_needle_strip(600)),
                        soup_of(testing::tilted(testing::make_zigzag_fan(300, 0.01f)))};
  for (const Soup& soup : soups) {
    const TriangleBvh bvh(soup.positions, soup.indices);
    const std::size_t triangles = soup.indices.size() / 3;
    ASSERT_FALSE(bvh.nodes().empty());
    ASSERT_EQ(bvh.triangle_count(), triangles);
    struct Box {
      const float *min, *max;
    };
    auto inside = [](const Box& box, const Vec3d& p) {
      for (int i = 0; i < 3; ++i) {
        if (p[i] < box.min[i] || p[i] > box.max[i]) return false;
      }
      return true;
    };
    std::vector<std::vector<std::uint32_t>> slots_of(triangles);
    std::vector<std::vector<Box>> chain(bvh.slot_count());  // the boxes above each slot
    // Walk the tree checking each slot's piece against every box above it.
    std::function<void(std::uint32_t, std::uint32_t, std::vector<Box>&)> walk =
        [&](std::uint32_t index, std::uint32_t count, std::vector<Box>& above) {
          if (count > 0) {
            for (std::uint32_t s = index; s < index + count; ++s) {
              const std::uint32_t t = bvh.slot_triangle(s);
              slots_of[t].push_back(s);
              chain[s] = above;
              for (const Vec3d& p : triangle_piece(bvh.triangle(t), bvh.slot_piece(s))) {
                for (const Box& b : above) EXPECT_TRUE(inside(b, p)) << "triangle " << t << " slot " << s;
              }
            }
            return;
          }
          const BvhNode& n = bvh.nodes()[index];
          for (int i = 0; i < 2; ++i) {
            above.push_back({n.min[i], n.max[i]});
            walk(n.child[i], n.count[i], above);
            above.pop_back();
          }
        };
    std::vector<Box> above = {{bvh.root().min, bvh.root().max}};
    walk(bvh.root().index, bvh.root().count, above);
    std::size_t split = 0;
    std::uint64_t key = 11;
    for (std::uint32_t t = 0; t < triangles; ++t) {
      ASSERT_GE(slots_of[t].size(), 1u) << "triangle " << t;
      // One slot per piece of one split.
      const std::uint16_t count = bvh.slot_piece(slots_of[t][0]).count;
      ASSERT_EQ(slots_of[t].size(), count) << "triangle " << t;
      std::vector<int> seen(count, 0);
      for (const std::uint32_t s : slots_of[t]) {
        ASSERT_EQ(bvh.slot_piece(s).count, count);
        ASSERT_LT(bvh.slot_piece(s).index, count);
        ++seen[bvh.slot_piece(s).index];
      }
      for (const int k : seen) EXPECT_EQ(k, 1) << "triangle " << t;
      split += count > 1;
      // Points of the triangle (corners, edges, inside) are under all the boxes of one of its slots.
      const std::array<Vec3d, 3> c = bvh.triangle(t);
      for (int q = 0; q < 24; ++q) {
        double u = uniform(key, 0, 1), v = uniform(key + 1, 0, 1);
        key += 2;
        if (u + v > 1) u = 1 - u, v = 1 - v;
        if (q == 3) v = 0;  // an edge
        Vec3d p = q < 3 ? c[q] : c[0] + (c[1] - c[0]) * u + (c[2] - c[0]) * v;
        for (int i = 0; i < 3; ++i) {  // rounding must not put it outside the triangle's own box
          p[i] = std::clamp(p[i], std::min({c[0][i], c[1][i], c[2][i]}), std::max({c[0][i], c[1][i], c[2][i]}));
        }
        bool covered = false;
        for (const std::uint32_t s : slots_of[t]) {
          covered = covered || std::all_of(chain[s].begin(), chain[s].end(), [&](const Box& b) { return inside(b, p); });
        }
        EXPECT_TRUE(covered) << "triangle " << t << " point " << q;
      }
    }
    EXPECT_EQ(bvh.slot_count(), std::accumulate(slots_of.begin(), slots_of.end(), std::size_t{0},
                                                [](std::size_t n, const auto& v) { return n + v.size(); }));
    EXPECT_LE(bvh.slot_count(), 2 * triangles) << "at most one extra piece per triangle in all";
    if (&soup == &soups[1]) {
      EXPECT_EQ(split, triangles) << "every needle is split";
    }
  }
}

TEST(TrianglePiece, PiecesTileTheTriangleFromTheCornerOppositeItsShortestEdge) {
  const std::array<Vec3d, 3> t = {v3(1, 0, 0), v3(0, 0.01, 0), v3(0, 0, 0)};  // shortest edge: corners 1, 2
  const std::array<Vec3d, 4> whole = triangle_piece(t, {0, 1});
  EXPECT_EQ(whole[0], t[0]);
  EXPECT_EQ(whole[1], t[1]);
  EXPECT_EQ(whole[2], t[2]);
  const std::array<Vec3d, 4> first = triangle_piece(t, {0, 4}), last = triangle_piece(t, {3, 4});
  EXPECT_EQ(first[0], t[0]);  // the apex
  EXPECT_EQ(first[1], t[0]);
  expect_vec_near(first[2], v3(0.75, 0.0025, 0));
  expect_vec_near(first[3], v3(0.75, 0, 0));
  EXPECT_EQ(last[2], t[1]);  // the far ends are the exact corners
  EXPECT_EQ(last[3], t[2]);
  // Neighbouring pieces share their cut.
  for (std::uint16_t k = 0; k + 1 < 4; ++k) {
    const std::array<Vec3d, 4> a = triangle_piece(t, {k, 4}), b = triangle_piece(t, {static_cast<std::uint16_t>(k + 1), 4});
    EXPECT_EQ(a[2], b[0]);
    EXPECT_EQ(a[3], b[1]);
  }
}

// Oriented boxes: kept beside the axis-aligned ones for slivers at an angle to the axes, seldom for an
// axis-aligned grid (only small groups of cells that run diagonally), and each holds every piece of its subtree,
// within its wedge cut too where it has one.
TEST(TriangleBvh, OrientedBoxesHoldTheirSubtreesAndAreKeptOnlyWhereTight) {
  const TriangleBvh grid = make_triangle_bvh(testing::make_grid(40, 40, false));
  EXPECT_LT(grid.oriented_box_count(), grid.node_count() / 5);
  std::size_t cuts = 0;
  for (const Mesh& mesh : {testing::make_needle_strip(3000), testing::make_cone(3000),
                           testing::tilted(testing::make_fanned_disk(3000)),
                           testing::tilted(testing::make_zigzag_fan(3000, 0.01f))}) {
    const TriangleBvh bvh = make_triangle_bvh(mesh);
    EXPECT_GT(bvh.oriented_box_count(), bvh.node_count()) << "most children of a sliver mesh get one";
    std::function<void(std::uint32_t, std::uint32_t, std::vector<std::uint32_t>&)> collect =
        [&](std::uint32_t index, std::uint32_t count, std::vector<std::uint32_t>& out) {
          if (count > 0) {
            for (std::uint32_t s = index; s < index + count; ++s) out.push_back(s);
            return;
          }
          for (int i = 0; i < 2; ++i) collect(bvh.nodes()[index].child[i], bvh.nodes()[index].count[i], out);
        };
    for (std::uint32_t node = 0; node < bvh.node_count(); ++node) {
      for (int i = 0; i < 2; ++i) {
        const BvhOrientedBox* box = bvh.oriented_box(node, i);
        if (!box) continue;
        EXPECT_GT(box->shrink, 0.999f);
        EXPECT_LE(box->shrink, 1.0f);
        const bool cut = box->cut[0] != 0 || box->cut[1] != 0 || box->cut[2] != 0;
        cuts += cut;
        if (cut) {
          EXPECT_GT(box->cut_shrink, 0.999f);
          EXPECT_LE(box->cut_shrink, 1.0f);
        }
        auto along = [&](const float* axis, const Vec3d& q) {
          double t = 0;
          for (int j = 0; j < 3; ++j) t += double{axis[j]} * (q[j] - double{box->origin[j]});
          return t;
        };
        std::vector<std::uint32_t> below;
        collect(bvh.nodes()[node].child[i], bvh.nodes()[node].count[i], below);
        for (const std::uint32_t s : below) {
          const std::uint32_t t = bvh.slot_triangle(s);
          for (const Vec3d& q : triangle_piece(bvh.triangle(t), bvh.slot_piece(s))) {
            for (int k = 0; k < 3; ++k) {
              EXPECT_GE(along(box->axis[k], q), box->lo[k]) << "node " << node << " child " << i << " triangle " << t;
              EXPECT_LE(along(box->axis[k], q), box->hi[k]) << "node " << node << " child " << i << " triangle " << t;
            }
            if (cut) {
              EXPECT_GE(along(box->cut, q), box->cut_lo) << "node " << node << " child " << i << " triangle " << t;
              EXPECT_LE(along(box->cut, q), box->cut_hi) << "node " << node << " child " << i << " triangle " << t;
            }
          }
        }
      }
    }
  }
  EXPECT_GT(cuts, 1000u) << "fans of slivers get wedge cuts";
}

// Where oriented boxes and pieces prune (slivers at an angle, nested slivers of a fanned zig-zag polygon, off the
// surface and on it) the answer is still the brute-force distance, up to the documented tie tolerance.
TEST(TriangleBvh, ClosestPointNextToSliversEqualsBruteForce) {
  for (const Mesh& mesh : {testing::make_needle_strip(2000), testing::make_cone(2000),
                           testing::tilted(testing::make_fanned_disk(2000)), testing::make_zigzag_fan(2000, 0.01f),
                           testing::tilted(testing::make_zigzag_fan(2000, 0.01f))}) {
    const Soup soup = soup_of(mesh);
    const TriangleBvh bvh(soup.positions, soup.indices);
    ASSERT_GT(bvh.oriented_box_count(), 0u);
    const double tie = 0x1p-24 * 2.0;  // of the largest coordinate, here below 2
    std::uint64_t key = 7u << 20;
    for (int q = 0; q < 400; ++q) {
      const double r = q % 4 == 0 ? 2.0 : 0.05;  // far from it, or next to a point of it
      const std::uint32_t t = static_cast<std::uint32_t>(q * 7919 % (soup.indices.size() / 3));
      const std::array<Vec3d, 3> c = bvh.triangle(t);
      const Vec3d on = (c[0] + c[1] + c[2]) * (1.0 / 3.0);
      const Vec3d p = on + v3(uniform(key, -r, r), uniform(key + 1, -r, r), uniform(key + 2, -r, r));
      key += 3;
      const BvhHit want = brute_force(soup, p);
      const BvhHit got = bvh.closest_point(p, t);
      ASSERT_TRUE(got.found());
      EXPECT_NEAR(got.distance(), want.distance(), tie) << "query " << q;
      EXPECT_NEAR(bvh.closest_point(p).distance(), want.distance(), tie) << "query " << q;
      EXPECT_GE(got.distance_sq, want.distance_sq) << "the answer is a real triangle's distance";
      std::uint32_t hint = kInvalidIndex;
      EXPECT_TRUE(bvh.any_within(p, want.distance() * (1 + 1e-9), hint)) << "query " << q;
      if (want.distance() > 1e-9) {
        EXPECT_FALSE(bvh.any_within(p, want.distance() * (1 - 1e-6), hint)) << "query " << q;
      }
    }
  }
}

TEST(TriangleBvh, EmptyTreeAndNonFiniteTrianglesGiveNoHit) {
  const TriangleBvh empty;
  EXPECT_TRUE(empty.empty());
  EXPECT_FALSE(empty.closest_point(v3(0, 0, 0)).found());

  const std::vector<Vec3d> positions = {v3(0, 0, 0), v3(1, 0, 0), v3(0, 1, 0), v3(NAN, 0, 0), v3(5, 5, 5)};
  const std::vector<std::uint32_t> indices = {3, 1, 2, 0, 1, 2};  // triangle 0 has a NaN corner
  const TriangleBvh bvh(positions, indices);
  EXPECT_EQ(bvh.triangle_count(), 2u);
  const BvhHit hit = bvh.closest_point(v3(2, 2, 0));
  ASSERT_TRUE(hit.found());
  EXPECT_EQ(hit.triangle, 1u);
  expect_vec_near(hit.point, v3(0.5, 0.5, 0));
  EXPECT_EQ(bvh.closest_point(v3(2, 2, 0), 0).triangle, 1u);  // a left-out hint is ignored
  EXPECT_FALSE(bvh.closest_point(v3(NAN, 0, 0)).found());
}

TEST(TriangleBvh, WithinFindsOnlyStrictlyCloserSurface) {
  const std::vector<Vec3d> positions = {v3(0, 0, 0), v3(1, 0, 0), v3(0, 1, 0)};
  const std::vector<std::uint32_t> indices = {0, 1, 2};
  const TriangleBvh bvh(positions, indices);
  EXPECT_FALSE(bvh.closest_point_within(v3(0.25, 0.25, 2), 2.0).found());
  const BvhHit hit = bvh.closest_point_within(v3(0.25, 0.25, 2), 2.001);
  ASSERT_TRUE(hit.found());
  EXPECT_NEAR(hit.distance(), 2.0, 1e-15);
}

TEST(TriangleBvh, MeshTrianglesAreNumberedLikeTriangulated) {
  const Mesh cube = testing::make_cube_quads();
  const TriangleBvh bvh = make_triangle_bvh(cube);
  const Mesh tris = triangulated(cube);
  ASSERT_EQ(bvh.triangle_count(), tris.face_count());
  for (std::uint32_t t = 0; t < tris.face_count(); ++t) {
    const std::array<Vec3d, 3> corners = bvh.triangle(t);
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(corners[k], to_double(tris.positions[tris.corner_vertex(3 * t + k)])) << t << "," << k;
    }
  }
  // Centre of face z = 0 (quad 0, triangles 0 and 1), seen from below.
  const BvhHit hit = bvh.closest_point(v3(0.25, 0.75, -1));
  EXPECT_LT(hit.triangle, 2u);
  EXPECT_NEAR(hit.distance(), 1.0, 1e-15);
}

}  // namespace
}  // namespace lodforge
