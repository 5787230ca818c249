// The report's LOD pictures (report_files/<asset>/lodK.png beside report.html): written for every LOD and listed
// in the records and the page, the same bytes for any job count, kept for cache hits and replaced on rebuilds,
// the report_pictures switch, and a picture that cannot be written never failing its asset.
#include <gtest/gtest.h>

#include <set>

#include "library_fixture.hpp"
#include "lodforge/batch/config.hpp"
#include "lodforge/batch/report_html.hpp"
#include "lodforge/batch/runner.hpp"
#include "lodforge/io/file.hpp"

namespace lodforge::batch {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

BatchConfig config_with(ReportPictures pictures) {
  BatchConfig c = testlib::config();
  c.report.pictures = pictures;
  return c;
}

// Every file under OUT/report_files: relative path -> bytes.
std::map<std::string, std::string> picture_files(const fs::path& out) {
  std::map<std::string, std::string> files;
  if (!fs::exists(out / kPictureFolder)) return files;
  for (const auto& e : fs::recursive_directory_iterator(out / kPictureFolder)) {
    if (e.is_regular_file()) files[fs::relative(e.path(), out).generic_string()] = io::read_file(e.path());
  }
  return files;
}

// The "pic" column of the page's data block: pictures per asset.
std::vector<int> page_picture_counts(const std::string& html) {
  const std::string open = "id=\"report-data\">";
  const std::size_t begin = html.find(open), end = html.find("</script>", begin);
  if (begin == std::string::npos || end == std::string::npos) return {};
  const Json data = Json::parse(html.substr(begin + open.size(), end - begin - open.size()));
  EXPECT_EQ(data["picdir"], std::string(kPictureFolder) + "/");
  return data["pic"].get<std::vector<int>>();
}

std::uint32_t png_side(const std::string& png) {
  std::uint32_t v = 0;
  for (std::size_t i = 16; i < 20; ++i) v = (v << 8) | static_cast<unsigned char>(png[i]);
  return v;
}

TEST(ReportPictures, OnDrawsEachLodBesideTheReportAndThePageShowsThem) {
  const fs::path dir = testing::temp_dir("pictures_on");
  const testlib::Library lib = testlib::write_library(dir / "lib", 20);
  const RunResult r = testlib::run(lib.root, dir / "out", 2, config_with(ReportPictures::on));
  ASSERT_EQ(r.failed, 0u);
  EXPECT_EQ(r.pictured_assets, r.succeeded);
  EXPECT_GT(r.stages.pictures, 0.0);
  const auto files = picture_files(dir / "out");
  std::set<std::string> listed;
  for (const Json& a : r.report["assets"]) {
    ASSERT_TRUE(a.contains("pictures")) << a["path"];
    const Json& pictures = a["pictures"];
    ASSERT_EQ(pictures.size(), a["lods"].size() + 1) << a["path"];  // the source, then each LOD
    for (std::size_t k = 0; k < pictures.size(); ++k) {
      const std::string name = pictures[k];
      EXPECT_EQ(name, picture_file_name(a["path"], k));
      EXPECT_EQ(name,
                std::string(kPictureFolder) + "/" + a["path"].get<std::string>() + "/lod" + std::to_string(k) + ".png");
      ASSERT_TRUE(files.count(name)) << name;
      EXPECT_EQ(files.at(name).substr(1, 3), "PNG");
      EXPECT_EQ(png_side(files.at(name)), static_cast<std::uint32_t>(kPictureSize));
      EXPECT_LE(kPictureSize, 256);
      listed.insert(name);
    }
  }
  EXPECT_EQ(listed.size(), files.size());  // nothing there that no record lists
  EXPECT_TRUE(testlib::leftovers(dir / "out").empty());
  EXPECT_TRUE(r.stale_outputs.empty());  // pictures are the report's, never stale outputs

  // report.html (written beside them) knows each asset's picture count and where they are.
  const std::string html = io::read_file(dir / "out/report.html");
  const std::vector<int> counts = page_picture_counts(html);
  ASSERT_EQ(counts.size(), r.report["assets"].size());
  int shown = 0;
  for (const int c : counts) shown += c;
  EXPECT_EQ(static_cast<std::size_t>(shown), files.size());
  EXPECT_EQ(html, render_report_html(r.report));
}

TEST(ReportPictures, SameBytesForAnyJobCount) {
  const fs::path dir = testing::temp_dir("pictures_jobs");
  const testlib::Library lib = testlib::write_library(dir / "lib", 20);
  const RunResult one = testlib::run(lib.root, dir / "one", 1, config_with(ReportPictures::on));
  const RunResult three = testlib::run(lib.root, dir / "three", 3, config_with(ReportPictures::on));
  const auto a = picture_files(dir / "one"), b = picture_files(dir / "three");
  EXPECT_FALSE(a.empty());
  EXPECT_TRUE(a == b);
  for (std::size_t i = 0; i < one.report["assets"].size(); ++i) {
    EXPECT_EQ(one.report["assets"][i]["pictures"], three.report["assets"][i]["pictures"]);
  }
}

TEST(ReportPictures, OffDrawsNoneAndAutoFollowsTheCostRule) {
  // The rule: a few small pictures cost more than 5% of a small asset's processing, not of a large one's.
  EXPECT_FALSE(pictures_pay(500, 900, 4));
  EXPECT_FALSE(pictures_pay(5000, 9000, 4));
  EXPECT_TRUE(pictures_pay(30000, 55000, 4));
  EXPECT_TRUE(pictures_pay(100000, 185000, 4));
  EXPECT_FALSE(pictures_pay(100000, 185000, 60));  // many pictures for one asset

  const fs::path dir = testing::temp_dir("pictures_off_auto");
  const testlib::Library lib = testlib::write_library(dir / "lib", 10);
  const RunResult off = testlib::run(lib.root, dir / "off", 2, config_with(ReportPictures::off));
  EXPECT_FALSE(fs::exists(dir / "off" / kPictureFolder));
  for (const Json& a : off.report["assets"]) EXPECT_FALSE(a.contains("pictures")) << a["path"];
  for (const int c : page_picture_counts(io::read_file(dir / "off/report.html"))) EXPECT_EQ(c, 0);

  // Auto: the library's small assets get none; one large asset does.
  io::save_asset(testlib::asset_of({testing::make_uv_sphere(120, 160)}, io::Format::ply), lib.root / "env/large.ply");
  const RunResult automatic = testlib::run(lib.root, dir / "auto", 2, config_with(ReportPictures::automatic));
  ASSERT_EQ(automatic.failed, 0u);
  for (const Json& a : automatic.report["assets"]) {
    EXPECT_EQ(a.contains("pictures"), a["path"] == "env/large.ply") << a["path"];
  }
  EXPECT_EQ(automatic.pictured_assets, 1u);
}

TEST(ReportPictures, CacheHitsKeepThemAndRebuiltAssetsReplaceThem) {
  const fs::path dir = testing::temp_dir("pictures_cache");
  const testlib::Library lib = testlib::write_library(dir / "lib", 10);
  const fs::path out = dir / "out";
  const RunResult first = testlib::run(lib.root, out, 2, config_with(ReportPictures::on));
  const auto before = picture_files(out);
  const RunResult second = testlib::run(lib.root, out, 2, config_with(ReportPictures::on));
  ASSERT_EQ(second.cache_hits, second.succeeded);
  EXPECT_EQ(second.pictured_assets, 0u);  // nothing drawn again
  for (std::size_t i = 0; i < first.report["assets"].size(); ++i) {
    EXPECT_EQ(second.report["assets"][i]["pictures"], first.report["assets"][i]["pictures"]);
  }
  EXPECT_TRUE(picture_files(out) == before);

  // One asset changes and is rebuilt with pictures off: its old pictures (of LODs it no longer has) go, the
  // cache hits list none (the page shows none), and their files stay for a later run.
  io::save_asset(testlib::asset_of({testing::make_uv_sphere(9, 14)}, io::Format::obj), lib.root / "props/dup_a.obj");
  const RunResult third = testlib::run(lib.root, out, 2, config_with(ReportPictures::off));
  for (const Json& a : third.report["assets"]) EXPECT_FALSE(a.contains("pictures")) << a["path"];
  EXPECT_FALSE(fs::exists(out / kPictureFolder / "props/dup_a.obj"));
  EXPECT_TRUE(fs::exists(out / kPictureFolder / "props/dup_b.obj/lod0.png"));

  // Back on: cache hits list the pictures still there; the rebuilt asset has none until it is rebuilt.
  const RunResult fourth = testlib::run(lib.root, out, 2, config_with(ReportPictures::on));
  for (const Json& a : fourth.report["assets"]) {
    EXPECT_EQ(a.contains("pictures"), a["path"] != "props/dup_a.obj") << a["path"];
  }
}

TEST(ReportPictures, APictureThatCannotBeWrittenNeverFailsItsAsset) {
  const fs::path dir = testing::temp_dir("pictures_fail");
  const testlib::Library lib = testlib::write_library(dir / "lib", 10);
  const fs::path out = dir / "out";
  // A file where the asset's picture folder must go.
  fs::create_directories(out / kPictureFolder / "props");
  io::write_file_atomic(out / kPictureFolder / "props/dup_a.obj", "in the way");
  const RunResult r = testlib::run(lib.root, out, 2, config_with(ReportPictures::on));
  EXPECT_EQ(r.failed, 0u);
  for (const Json& a : r.report["assets"]) {
    if (a["path"] != "props/dup_a.obj") {
      EXPECT_TRUE(a.contains("pictures")) << a["path"];
      continue;
    }
    EXPECT_EQ(a["status"], "ok");
    EXPECT_FALSE(a.contains("pictures"));
    ASSERT_TRUE(a.contains("warnings"));
    EXPECT_NE(a["warnings"].dump().find("no pictures: "), std::string::npos) << a["warnings"];
  }
  EXPECT_TRUE(testlib::leftovers(out).empty());
}

}  // namespace
}  // namespace lodforge::batch
