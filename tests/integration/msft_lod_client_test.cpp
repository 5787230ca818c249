// A real client on the MSFT_lod outputs: Babylon.js's glTF loader in headless Chromium
// (tests/client/msft_lod_client.mjs) loads every MSFT_lod file `lodforge run` writes for the bundled sample
// library, and for generated glTF and GLB assets with one and two meshes, and must reach each file's finest LOD.
// Skips with the reason where node, the npm packages (scripts/setup.sh) or Chromium are absent.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <string>

#include "../unit/batch/library_fixture.hpp"
#include "test_support.hpp"

namespace {

namespace fs = std::filesystem;
namespace testlib = lodforge::batch::testlib;
using lodforge::testing::CommandResult;
using lodforge::testing::shell_quote;

// Runs the client check on the output folder `out` (exit 77 and "skip: why" where it cannot run).
CommandResult run_client(const fs::path& out) {
  const fs::path script = fs::path(LODFORGE_SOURCE_DIR) / "tests" / "client" / "msft_lod_client.mjs";
  return lodforge::testing::run_command("node " + shell_quote(script) + " " + shell_quote(out));
}

std::string skip_reason(const CommandResult& r) {
  if (r.exit_code != 77) return {};
  const std::size_t at = r.output.find("skip: ");
  return at == std::string::npos ? r.output : r.output.substr(at + 6);
}

TEST(MsftLodClient, BabylonReachesTheFinestLodOfEverySampleLibraryOutput) {
  if (std::system("node --version > /dev/null 2>&1") != 0) GTEST_SKIP() << "node is not installed";
  const fs::path dir = lodforge::testing::temp_dir("msft_lod_client_samples");
  const fs::path source = LODFORGE_SOURCE_DIR;
  const CommandResult run =
      lodforge::testing::run_cli("run --config " + shell_quote(source / "configs/default.json") + " --input " +
                                 shell_quote(source / "samples/library") + " --output " + shell_quote(dir / "out"));
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const CommandResult client = run_client(dir / "out");
  if (const std::string why = skip_reason(client); !why.empty()) GTEST_SKIP() << why;
  EXPECT_EQ(client.exit_code, 0) << client.output;
  EXPECT_NE(client.output.find("\"file\":\"characters/torus_ring.gltf\",\"ok\":true"), std::string::npos)
      << client.output;
  EXPECT_NE(client.output.find("summary: 1 of 1 MSFT_lod file(s) reached their finest LOD"), std::string::npos)
      << client.output;
  std::printf("%s", client.output.c_str());
}

TEST(MsftLodClient, BabylonReachesTheFinestLodOfGltfAndGlbWithSeveralMeshes) {
  if (std::system("node --version > /dev/null 2>&1") != 0) GTEST_SKIP() << "node is not installed";
  const fs::path dir = lodforge::testing::temp_dir("msft_lod_client_generated");
  const testlib::Library lib = testlib::write_library(dir / "lib", 12);  // chars/: 3 .gltf, 2 .glb, some 2-mesh
  const fs::path config = testlib::write_config(dir, "msft_lod");
  const CommandResult run = lodforge::testing::run_cli("run --config " + shell_quote(config) + " --input " +
                                                       shell_quote(lib.root) + " --output " + shell_quote(dir / "out"));
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const CommandResult client = run_client(dir / "out");
  if (const std::string why = skip_reason(client); !why.empty()) GTEST_SKIP() << why;
  EXPECT_EQ(client.exit_code, 0) << client.output;
  // props/prop_2.glb is a glTF-family prop: it gets MSFT_lod output too.
  EXPECT_NE(client.output.find("summary: 6 of 6 MSFT_lod file(s) reached their finest LOD"), std::string::npos)
      << client.output;
  std::printf("%s", client.output.c_str());
}

}  // namespace
