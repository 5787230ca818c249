// Conservative LODs on the tiled path: each tile's collapses keep the rule on the whole mesh's faces (a tile's
// inner vertices have all their faces in it, its border vertices are locked), so the stitched LOD nests too.
#include <gtest/gtest.h>

#include <string>

#include "../simplify/conservative_fixtures.hpp"
#include "lodforge/core/validate.hpp"
#include "lodforge/simplify/simplify.hpp"
#include "lodforge/tiling/tiling.hpp"

namespace lodforge {
namespace {

TEST(TilingConservative, TiledLodsNest) {
  const Mesh blob = conservative_test::make_icosphere(4, 0.1, 11);
  const std::vector<conservative_test::Tri> src = conservative_test::triangles_of(blob);
  const double tol = 1e-6 * conservative_test::diagonal_of(src);
  for (Conservative mode : {Conservative::bounding, Conservative::occluder}) {
    SimplifyOptions o{.target_ratio = 0.1, .conservative = mode};
    o.tiling = TilingMode::on;
    o.tile_triangles = 800;
    const SimplifyResult r = simplify_maybe_tiled(blob, o);
    SCOPED_TRACE(conservative_name(mode));
    EXPECT_GT(r.tiling_passes, 0u);
    EXPECT_LT(r.triangles_after, blob.triangle_count() / 4);
    EXPECT_TRUE(validate(r.mesh).ok());
    const std::vector<conservative_test::Tri> lod = conservative_test::triangles_of(r.mesh);
    EXPECT_EQ(conservative_test::count_crossings(lod, src, tol), 0u);
    const bool bounding = mode == Conservative::bounding;
    EXPECT_EQ(conservative_test::points_outside(conservative_test::test_points(bounding ? blob : r.mesh, 2000),
                                                bounding ? lod : src, tol),
              0u);
  }
}

// A volume budget is of the whole mesh: such runs never tile.
TEST(TilingConservative, VolumeBudgetRunsUntiled) {
  const Mesh blob = conservative_test::make_icosphere(4, 0.1, 11);
  SimplifyOptions o{.target_ratio = 0.1, .conservative = Conservative::bounding, .max_volume_growth = 0.5};
  o.tiling = TilingMode::on;
  o.tile_triangles = 800;
  EXPECT_FALSE(tiling::applies(blob, o));
}

}  // namespace
}  // namespace lodforge
