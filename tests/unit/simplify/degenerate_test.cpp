// Degenerate input must not make the triangle engines quadratic. The reproducer: one polygon of N zig-zag
// corners fanned from its first corner (a vertex of valence N - 1 in every face, every vertex on the border).
// Work is counted, not timed: CollapseMesh::check() reports the list entries it visits (Scratch::work).
#include "collapse_mesh.hpp"

#include <gtest/gtest.h>

#include "lodforge/core/validate.hpp"
#include "lodforge/simplify/simplify.hpp"
#include "test_support.hpp"

namespace lodforge {
namespace {

struct Work {
  std::uint64_t entries = 0;  // Scratch::work of one check()
  std::uint64_t stars = 0;    // faces around both endpoints
};

// check() of the edge (0, v) of the fanned zig-zag, at the midpoint.
Work check_hub_edge(const Mesh& fan, std::uint32_t v) {
  collapse::Parallel par(1);
  const SimplifyOptions options;
  collapse::CollapseMesh cm(fan, options, par);
  collapse::Scratch s;
  // Normalised coordinates, as the engines place vertices (origin = bbox min, scale = max extent).
  const Vec3d mid = (to_double(fan.positions[0]) + to_double(fan.positions[v])) * 0.5;
  const Vec3d x = (mid - compute_bounds(fan).min) * (1.0 / cm.scale());
  (void)cm.check(0, v, x, s);
  return {s.work, std::uint64_t{cm.star_size(0)} + cm.star_size(v)};
}

TEST(DegenerateInput, CheckAtAHighValenceVertexIsLinearInItsStar) {
  for (const int corners : {1000, 8000}) {
    SCOPED_TRACE(corners);
    const Mesh fan = triangulated(testing::make_zigzag_fan(corners, 0.01f));
    const auto last = static_cast<std::uint32_t>(corners - 1);
    for (const std::uint32_t v : {1u, last / 2, last}) {  // border spoke, interior spoke, border spoke
      const Work w = check_hub_edge(fan, v);
      EXPECT_GE(w.stars, static_cast<std::uint64_t>(corners - 2));
      // A scan of one list per neighbour (the defect) visits about stars² / 2 entries.
      EXPECT_LE(w.entries, 8 * w.stars + 64) << "edge 0-" << v;
    }
    // An interior spoke (two border endpoints: boundary_pinch) is refused from the spoke end's star alone.
    EXPECT_LE(check_hub_edge(fan, last / 2).entries, 16u);
  }
}

// The whole run: every refused candidate is one check() (of O(valence) at the hub); they stay within a
// small multiple of the input, and grow linearly with it.
TEST(DegenerateInput, ZigzagFanSimplifiesWithLinearlyManyRefusals) {
  std::size_t refused[2] = {};
  const int sizes[2] = {2000, 8000};
  for (int k = 0; k < 2; ++k) {
    SCOPED_TRACE(sizes[k]);
    const Mesh fan = testing::make_zigzag_fan(sizes[k], 0.01f);
    const SimplifyResult r = simplify(fan, {.target_ratio = 0.1, .threads = 1});
    EXPECT_EQ(r.stop_reason, StopReason::target_reached);
    EXPECT_TRUE(validate(r.mesh).ok());
    refused[k] = r.vetoes.rejected();
    EXPECT_LE(refused[k], r.triangles_before) << "refused candidates";
    EXPECT_LE(r.rounds, 2 * r.triangles_before) << "rounds";
  }
  EXPECT_LE(refused[1], 8 * refused[0] + 1000) << refused[0] << " -> " << refused[1];
}

}  // namespace
}  // namespace lodforge
