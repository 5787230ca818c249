// `lodforge simplify --conservative`: the written hull contains the input, the occluder lies inside it, and
// option errors exit 2.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "../unit/simplify/conservative_fixtures.hpp"
#include "lodforge/io/asset.hpp"
#include "test_support.hpp"

namespace {

namespace fs = std::filesystem;
using lodforge::testing::run_cli;
using lodforge::testing::shell_quote;

TEST(CliConservative, WrittenLodsNest) {
  const fs::path dir = lodforge::testing::temp_dir("cli_conservative");
  const fs::path in = dir / "blob.obj";
  lodforge::io::Asset asset;
  asset.meshes.push_back(lodforge::conservative_test::make_icosphere(3, 0.1, 4));
  lodforge::io::save_asset(asset, in);
  const lodforge::Mesh src = lodforge::io::load_asset(in).meshes.at(0);
  const auto s = lodforge::conservative_test::triangles_of(src);
  const double tol = 1e-6 * lodforge::conservative_test::diagonal_of(s);
  for (const std::string mode : {"bounding", "occluder"}) {
    const fs::path out = dir / ("blob_" + mode + ".obj");
    const auto r = run_cli("simplify " + shell_quote(in) + " " + shell_quote(out) + " --ratio 0.1 --conservative " + mode);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("conservative " + mode + ": volume "), std::string::npos) << r.output;
    const lodforge::Mesh lod = lodforge::io::load_asset(out).meshes.at(0);
    const auto l = lodforge::conservative_test::triangles_of(lod);
    EXPECT_EQ(lodforge::conservative_test::count_crossings(l, s, tol), 0u) << mode;
    const bool bounding = mode == "bounding";
    EXPECT_EQ(lodforge::conservative_test::points_outside(
                  lodforge::conservative_test::test_points(bounding ? src : lod, 2000), bounding ? l : s, tol),
              0u)
        << mode;
  }
  const std::string io = shell_quote(in) + " " + shell_quote(dir / "x.obj");
  const auto cluster = run_cli("simplify " + io + " --conservative bounding --engine cluster");
  EXPECT_EQ(cluster.exit_code, 2);
  EXPECT_NE(cluster.output.find("needs the edge_collapse or multiple_choice engine"), std::string::npos);
  const auto volume = run_cli("simplify " + io + " --max-volume-growth 5");
  EXPECT_EQ(volume.exit_code, 2);
  EXPECT_NE(volume.output.find("--max-volume-growth needs conservative"), std::string::npos) << volume.output;
  EXPECT_EQ(run_cli("simplify " + io + " --conservative hull").exit_code, 2);
  const auto held = run_cli("simplify " + io + " --ratio 0.01 --conservative bounding --max-volume-growth 1");
  EXPECT_EQ(held.exit_code, 0);
  EXPECT_NE(held.output.find("held by: volume_budget"), std::string::npos) << held.output;
}

}  // namespace
