// `lodforge simplify --symmetry-weight`: mirror pairs are made and counted; bad values exit 2.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "../unit/symmetry/symmetry_meshes.hpp"
#include "lodforge/io/asset.hpp"
#include "test_support.hpp"

namespace {

namespace fs = std::filesystem;
using lodforge::testing::run_cli;
using lodforge::testing::shell_quote;

TEST(CliSymmetry, WeightPairsCollapsesAndSaysSo) {
  const fs::path dir = lodforge::testing::temp_dir("cli_symmetry");
  const fs::path in = dir / "blob.obj";
  lodforge::io::Asset asset;
  asset.meshes.push_back(lodforge::symmetry::testing::make_blob(24, 32, /*mirrored=*/true));
  lodforge::io::save_asset(asset, in);
  const std::string io = shell_quote(in) + " " + shell_quote(dir / "lod.obj");
  const auto on = run_cli("simplify " + io + " --ratio 0.3 --symmetry-weight 1");
  ASSERT_EQ(on.exit_code, 0) << on.output;
  const std::string key = "collapses made in mirror pairs";
  const std::size_t at = on.output.find("symmetry: ");
  ASSERT_NE(at, std::string::npos) << on.output;
  EXPECT_NE(on.output.find(key, at), std::string::npos) << on.output;
  EXPECT_EQ(on.output.find("symmetry: 0 of"), std::string::npos) << on.output;  // some pairs were made
  const auto off = run_cli("simplify " + io + " --ratio 0.3");
  ASSERT_EQ(off.exit_code, 0) << off.output;
  EXPECT_EQ(off.output.find(key), std::string::npos) << off.output;
  const auto bad = run_cli("simplify " + io + " --symmetry-weight -1");
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  EXPECT_NE(bad.output.find("--symmetry-weight"), std::string::npos) << bad.output;
  const auto plane = run_cli("simplify " + io + " --symmetry-weight 1 --symmetry-plane w");
  EXPECT_NE(plane.exit_code, 0) << plane.output;
}

}  // namespace
