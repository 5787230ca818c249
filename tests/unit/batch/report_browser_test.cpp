// report.html of a real batch run, opened in headless Chromium (tests/browser/report_page.mjs): no console
// errors, search, class and status filters, sorting and row expansion work, an expanded row's LOD pictures
// load, the per-class overview draws, and screenshots are written to the test's temp folder. Skips where node, puppeteer-core (scripts/setup.sh) or Chromium are absent.
#include <gtest/gtest.h>

#include "library_fixture.hpp"
#include "lodforge/batch/config.hpp"
#include "lodforge/batch/runner.hpp"
#include "lodforge/io/file.hpp"
#include "test_support.hpp"

namespace lodforge::batch {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

TEST(ReportBrowser, SampleLibraryPageWorksInChromium) {
  if (testing::run_command("node --version").exit_code != 0) GTEST_SKIP() << "node is not installed";
  const fs::path dir = testing::temp_dir("report_browser");
  const testlib::Library lib = testlib::write_library(dir / "lib");
  io::write_file_atomic(lib.root / "props/broken.obj", "v 0 0 0\nf 1 2 3\n");  // a failed row
  BatchConfig cfg = parse_config(Json::parse(testlib::config_text("msft_lod")), "test config");
  cfg.report.pictures = ReportPictures::on;
  const RunOptions options{.config_file = "test config", .input_dir = lib.root, .output_dir = dir / "out", .jobs = 2};
  run_batch(cfg, options);
  // A second run after one asset changed: the page then has a "changes since the previous run" section.
  io::save_asset(testlib::asset_of({testlib::make_terrain(20, 7)}, io::Format::off), lib.root / "env/patch_90.off");
  const RunResult second = run_batch(cfg, options);
  ASSERT_TRUE(second.report.contains("changes"));
  const std::string html = io::read_file(dir / "out/report.html");
  EXPECT_NE(html.find("Changes since the previous run"), std::string::npos);
  std::size_t pictures = 0;
  for (const Json& a : second.report["assets"]) {
    for (const Json& p : a.value("pictures", Json::array())) pictures += fs::is_regular_file(dir / "out" / p.get<std::string>());
  }
  EXPECT_GT(pictures, 0u);  // the page's check below needs some to load

  const fs::path screenshot = dir / "report.png";
  const testing::CommandResult r = testing::run_command(
      "node " + testing::shell_quote(fs::path(LODFORGE_SOURCE_DIR) / "tests/browser/report_page.mjs") + " check " +
      testing::shell_quote(dir / "out/report.html") + ' ' + testing::shell_quote(screenshot));
  if (r.exit_code == 77) GTEST_SKIP() << r.output;
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(r.output.find("FAIL"), std::string::npos) << r.output;
  EXPECT_TRUE(fs::is_regular_file(screenshot)) << r.output;
  EXPECT_NE(r.output.find("LOD pictures and they load"), std::string::npos) << r.output;
  std::printf("%s(screenshot: %s)\n", r.output.c_str(), screenshot.string().c_str());
}

}  // namespace
}  // namespace lodforge::batch
