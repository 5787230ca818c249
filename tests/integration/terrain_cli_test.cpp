// `lodforge terrain`: a raw height map in, one glTF with a node per patch (MSFT_lod) or a file per patch out,
// pictures per level, clear errors on bad input.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "heightmap_fixtures.hpp"
#include "lodforge/io/asset.hpp"
#include "lodforge/io/file.hpp"
#include "test_support.hpp"

namespace lodforge {
namespace {

std::filesystem::path write_hills(const std::filesystem::path& dir) {
  return testing::write_hills_r16(dir);
}

TEST(CliTerrain, WritesOneGltfWithANodePerPatchAndPictures) {
  const auto dir = testing::temp_dir("cli_terrain");
  const auto map = write_hills(dir);
  const auto out = dir / "hills.glb";
  const auto r = testing::run_cli("terrain " + testing::shell_quote(map) + " " + testing::shell_quote(out) +
                                  " --patch-cells 32 --ratios 0.25,0.05 --spacing 2 --height-scale 0.01 --picture " +
                                  testing::shell_quote(dir / "hills.png"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("3 x 2 patches"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("LOD2:"), std::string::npos) << r.output;
  const io::Asset asset = io::load_asset(out);
  EXPECT_EQ(asset.meshes.size(), 18u);  // 6 patches x 3 levels, each level its own mesh
  const std::string json = io::read_file(out);
  EXPECT_NE(json.find("MSFT_lod"), std::string::npos);
  EXPECT_NE(json.find("patch_2_1_LOD2"), std::string::npos);
  EXPECT_TRUE(std::filesystem::exists(dir / "hills_LOD1.png"));
  EXPECT_TRUE(std::filesystem::exists(dir / "hills_LOD2.png"));
}

TEST(CliTerrain, FilesModeWritesAGltfPerPatch) {
  const auto dir = testing::temp_dir("cli_terrain_files");
  const auto map = write_hills(dir);
  const auto r = testing::run_cli("terrain " + testing::shell_quote(map) + " " + testing::shell_quote(dir / "out") +
                                  " --files --patch-cells 64 --conservative none");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(std::filesystem::exists(dir / "out" / "hills_97x65_0_0.glb"));
  EXPECT_TRUE(std::filesystem::exists(dir / "out" / "hills_97x65_1_0.glb"));
}

TEST(CliTerrain, BadInputNamesTheFile) {
  const auto dir = testing::temp_dir("cli_terrain_bad");
  io::write_file_atomic(dir / "odd.r16", std::string(7, 'x'));
  auto r =
      testing::run_cli("terrain " + testing::shell_quote(dir / "odd.r16") + " " + testing::shell_quote(dir / "o.glb"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("odd.r16"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "o.glb"));
  r = testing::run_cli("terrain " + testing::shell_quote(write_hills(dir)) + " " + testing::shell_quote(dir / "o.glb") +
                       " --ratios 0.5,x");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("--ratios"), std::string::npos) << r.output;
}

TEST(CliTerrain, OutputPassesTheKhronosValidator) {
  LODFORGE_REQUIRE_GLTF_VALIDATOR();
  const auto dir = testing::temp_dir("cli_terrain_valid");
  const auto out = dir / "hills.gltf";
  const auto r = testing::run_cli("terrain " + testing::shell_quote(write_hills(dir)) + " " +
                                  testing::shell_quote(out) + " --patch-cells 32");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto v = testing::validate_gltf({out});
  EXPECT_EQ(v.exit_code, 0) << v.output;
}

}  // namespace
}  // namespace lodforge
