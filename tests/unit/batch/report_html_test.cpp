#include "lodforge/batch/report_html.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "lodforge/batch/runner.hpp"

namespace lodforge::batch {
namespace {

using nlohmann::json;

constexpr std::string_view kDash = "\xE2\x80\x93";
constexpr std::string_view kHostileError = "parse error: <script>alert(1)</script> & \"quoted\" 'single'";

json lod(int level, double ratio, double mean_rel, double hausdorff_rel) {
  return {{"level", level},
          {"from", "previous"},
          {"target", {{"kind", "ratio"}, {"value", ratio}}},
          {"target_triangles", static_cast<int>(1000 * ratio)},
          {"triangles", static_cast<int>(1000 * ratio)},
          {"vertices", static_cast<int>(520 * ratio)},
          {"ratio", ratio},
          {"error_bound_abs", hausdorff_rel * 2.0},
          {"error_bound_rel", hausdorff_rel * 1.5},
          {"mean_rel", mean_rel},
          {"rms_rel", mean_rel * 1.3},
          {"hausdorff_rel", hausdorff_rel},
          {"normal_deviation_mean_deg", 3.25 * level},
          {"attributes", {{"normal_deviation_mean_deg", 3.25 * level}, {"uv_flipped", level}, {"uv_spanning", 1}}},
          {"quad_fraction", 0.25 * level},
          {"irregular_vertices", 4},
          {"stop_reason", "target_reached"},
          {"seconds", 0.012 * level},
          {"screen_coverage", nullptr}};
}

json asset(std::string path, std::string cls, json lods) {
  return {{"path", std::move(path)},
          {"class", std::move(cls)},
          {"status", "ok"},
          {"error", nullptr},
          {"cache_hit", false},
          {"seconds", 0.5},
          {"input", {{"triangles", 1000}, {"vertices", 520}, {"diagonal", 2.5}}},
          {"outputs", json::array({"out.glb"})},
          {"lods", std::move(lods)}};
}

// Three classes, six measured assets (15 LODs), one failure, one skipped asset without a class.
json sample_report() {
  json assets = json::array();
  assets.push_back(asset("props/chair.obj", "props",
                         {lod(1, 0.5, 0.0010, 0.0040), lod(2, 0.25, 0.0030, 0.0120), lod(3, 0.1, 0.0090, 0.0300)}));
  assets.push_back(asset("props/table.obj", "props",
                         {lod(1, 0.5, 0.0008, 0.0035), lod(2, 0.25, 0.0025, 0.0110), lod(3, 0.1, 0.0070, 0.0950)}));
  assets.push_back(asset("rocks/boulder.ply", "rocks", {lod(1, 0.3, 0.0020, 0.0060), lod(2, 0.05, 0.0200, 0.0500)}));
  assets.push_back(asset("rocks/pebble & <b>.ply", "rocks", {lod(1, 0.3, 0.0015, 0.0050), lod(2, 0.05, 0.018, 0.04)}));
  assets.push_back(asset("trees/oak.glb", "trees",
                         {lod(1, 0.5, 0.0005, 0.0020), lod(2, 0.2, 0.0040, 0.0150), lod(3, 0.02, 0.0300, 0.0800)}));
  assets.push_back(asset("trees/pine.glb", "trees", {lod(1, 0.5, 0.0006, 0.0025), lod(2, 0.2, 0.0045, 0.0160)}));
  json failed = asset("rocks/broken.obj", "rocks", json::array());
  failed["status"] = "failed";
  failed["error"] = kHostileError;
  failed["outputs"] = json::array();
  assets.push_back(failed);
  json skipped = asset("misc/readme.obj", "", json::array());
  skipped["class"] = nullptr;
  skipped["status"] = "skipped";
  skipped["error"] = "no class matches misc/readme.obj";
  assets.push_back(skipped);

  return {{"lodforge_version", "0.3.0"},
          {"config_file", "configs/default.json"},
          {"effective_config", {{"version", 1}, {"classes", json::array({{{"name", "props"}}})}}},
          {"jobs", 2},
          {"shard", nullptr},
          {"summary",
           {{"assets", 8},
            {"succeeded", 6},
            {"failed", 1},
            {"skipped", 1},
            {"cache_hits", 0},
            {"lods", 15},
            {"input_triangles", 6000},
            {"output_triangles", 4120},
            {"seconds", 3.5}}},
          {"assets", std::move(assets)}};
}

std::size_t count_of(std::string_view haystack, std::string_view needle) {
  std::size_t n = 0;
  for (std::size_t at = haystack.find(needle); at != std::string_view::npos; at = haystack.find(needle, at + 1)) ++n;
  return n;
}

// The text between `open` (which must occur) and the next `close` after it.
std::string_view between(std::string_view s, std::string_view open, std::string_view close) {
  const std::size_t a = s.find(open);
  EXPECT_NE(a, std::string_view::npos) << open;
  if (a == std::string_view::npos) return {};
  const std::size_t b = s.find(close, a);
  return s.substr(a, b == std::string_view::npos ? std::string_view::npos : b - a);
}

// The page's data block (the table's content), parsed.
json page_data(std::string_view html) {
  const std::string_view open = "<script type=\"application/json\" id=\"report-data\">";
  const std::size_t a = html.find(open);
  EXPECT_NE(a, std::string_view::npos);
  if (a == std::string_view::npos) return json();
  const std::size_t b = html.find("</script>", a);
  return json::parse(html.substr(a + open.size(), b - a - open.size()));
}

// The data's assets, worst first, as full paths.
std::vector<std::string> data_paths(const json& d) {
  std::vector<std::string> out;
  for (std::size_t i = 0; i < d["dir"].size(); ++i) {
    const int dir = d["dir"][i].get<int>();
    out.push_back(dir < 0 ? std::string(kDash) : d["dirs"][dir].get<std::string>() + d["name"][i].get<std::string>());
  }
  return out;
}

// Index of asset `path`'s first LOD in the data's LOD columns.
std::size_t first_lod(const json& d, const std::string& path) {
  const std::vector<std::string> paths = data_paths(d);
  std::size_t k = 0;
  for (std::size_t i = 0; i < paths.size(); ++i) {
    if (paths[i] == path) return k;
    k += d["nl"][i].get<std::size_t>();
  }
  ADD_FAILURE() << "no asset " << path;
  return 0;
}

TEST(ReportHtml, IsOneHtml5Page) {
  const std::string html = render_report_html(sample_report());
  EXPECT_EQ(html.rfind("<!DOCTYPE html>", 0), 0U);
  EXPECT_EQ(count_of(html, "<html"), 1U);
  EXPECT_NE(html.find("<meta charset=\"utf-8\">"), std::string::npos);
  EXPECT_NE(html.find("</html>"), std::string::npos);
}

TEST(ReportHtml, EscapesEveryDocumentString) {
  const std::string html = render_report_html(sample_report());
  EXPECT_NE(html.find("parse error: &lt;script&gt;alert(1)&lt;/script&gt; &amp; &quot;quoted&quot; &#39;single&#39;"),
            std::string::npos);
  EXPECT_EQ(html.find("<script>alert"), std::string::npos);
  EXPECT_EQ(count_of(html, "<script"), 2U);  // the data block and the page's own script
  EXPECT_EQ(count_of(html, "</script"), 2U);
  EXPECT_NE(html.find("rocks/pebble &amp; &lt;b&gt;.ply"), std::string::npos);  // the worst-assets chart
  EXPECT_EQ(html.find("<b>.ply"), std::string::npos);
  // In the data block the same strings are JSON with every "<", ">" and "&" escaped; they parse back intact.
  const json d = page_data(html);
  const std::vector<std::string> paths = data_paths(d);
  EXPECT_NE(std::find(paths.begin(), paths.end(), "rocks/pebble & <b>.ply"), paths.end());
  EXPECT_EQ(d["err"]["0"], std::string(kHostileError));  // the failed asset, first
}

TEST(ReportHtml, ListsFailuresBeforeTheTable) {
  const std::string html = render_report_html(sample_report());
  const std::size_t failures = html.find("<section id=\"failures\">");
  ASSERT_NE(failures, std::string::npos);
  EXPECT_LT(failures, html.find("<table id=\"assets\""));
  const std::string_view section = between(html, "<section id=\"failures\">", "</section>");
  EXPECT_NE(section.find("Failures (1)"), std::string_view::npos);
  EXPECT_NE(section.find("rocks/broken.obj"), std::string_view::npos);
  EXPECT_NE(section.find("&lt;script&gt;"), std::string_view::npos);
  EXPECT_NE(section.find("Skipped (1)"), std::string_view::npos);
  EXPECT_NE(section.find("no class matches misc/readme.obj"), std::string_view::npos);
}

TEST(ReportHtml, ShowsHeaderAndSummary) {
  const std::string html = render_report_html(sample_report());
  const std::string_view header = between(html, "<header>", "</header>");
  EXPECT_NE(header.find("0.3.0"), std::string_view::npos);
  EXPECT_NE(header.find("configs/default.json"), std::string_view::npos);
  EXPECT_NE(header.find("jobs <b>2</b>"), std::string_view::npos);
  EXPECT_NE(header.find("shard <b>" + std::string(kDash) + "</b>"), std::string_view::npos);  // null shard
  EXPECT_NE(header.find("6\xE2\x80\xAF"
                        "000"),
            std::string_view::npos);                         // grouped count
  EXPECT_NE(header.find("0.6867"), std::string_view::npos);  // 4120 / 6000
  EXPECT_NE(header.find("3.50"), std::string_view::npos);
}

TEST(ReportHtml, PlotsShareOneLogAxisPairThatHoldsZeroErrors) {
  json report = sample_report();
  report["assets"][0]["lods"][0]["hausdorff_rel"] = 0.0;  // an exact LOD: no place on a log axis
  const std::string html = render_report_html(report);
  const json d = page_data(html);
  // One pair of axes for every asset's plot: the smallest positive and the largest triangle count and error.
  EXPECT_EQ(d["axes"]["tri"], json::array({20, 1000}));         // trees/oak LOD3 .. the sources
  EXPECT_EQ(d["axes"]["err"][1].get<double>(), 9.5);            // props/table LOD3, in %
  EXPECT_GT(d["axes"]["err"][0].get<double>(), 0.0);            // zero is drawn on its own row, not an axis end
  EXPECT_EQ(d["h"][first_lod(d, "props/chair.obj")], 0);
  EXPECT_NE(html.find("triangles</text>"), std::string::npos);   // the script's plot labels
  EXPECT_EQ(count_of(html, "<svg viewBox"), 1U);  // the worst-assets chart; the script draws the rest on expand
}

TEST(ReportHtml, HeaderNamesConfigInputAndOutput) {
  json report = sample_report();
  report["input_dir"] = "/data/library";
  report["output_dir"] = "/data/lods & <more>";
  report["summary"]["lods_missed"] = 2;
  const std::string html = render_report_html(report);
  const std::string_view header = between(html, "<header>", "</header>");
  EXPECT_NE(header.find("config <b>configs/default.json</b>"), std::string_view::npos);
  EXPECT_NE(header.find("input <b>/data/library</b>"), std::string_view::npos);
  EXPECT_NE(header.find("output <b>/data/lods &amp; &lt;more&gt;</b>"), std::string_view::npos);
  EXPECT_NE(header.find("LODs missed budget"), std::string_view::npos);
}

TEST(ReportHtml, TableHasOneRowPerAssetWithItsLods) {
  const json d = page_data(render_report_html(sample_report()));
  EXPECT_EQ(d["st"].size(), 8U);  // 8 assets
  std::size_t lods = 0;
  for (const json& n : d["nl"]) lods += n.get<std::size_t>();
  EXPECT_EQ(lods, 15U);
  for (const char* column : {"lv", "tgt", "ttri", "tri", "eb", "mean", "h", "sc", "bud", "why", "stop"}) {
    EXPECT_EQ(d[column].size(), 15U) << column;
  }
  for (const char* column : {"dir", "name", "cls", "pr", "st", "hit", "itri", "ib", "ob", "nl"}) {
    EXPECT_EQ(d[column].size(), 8U) << column;
  }
}

TEST(ReportHtml, RowsAreFailedThenBudgetMissedThenWorstHausdorff) {
  json report = sample_report();
  // trees/pine's LOD2 missed its budget: it moves above every asset that met them, whatever its error.
  report["assets"][5]["lods"][1]["budget"] = {{"status", "missed"}, {"reasons", {"target not reached"}}};
  report["assets"][4]["lods"][0]["budget"] = {{"status", "met"}, {"reasons", json::array()}};
  const json d = page_data(render_report_html(report));
  const std::vector<std::string> paths = data_paths(d);
  const std::vector<std::string> expected = {"rocks/broken.obj",     "trees/pine.glb",    "props/table.obj",
                                             "trees/oak.glb",        "rocks/boulder.ply", "rocks/pebble & <b>.ply",
                                             "props/chair.obj",      "misc/readme.obj"};
  EXPECT_EQ(paths, expected);
  EXPECT_EQ(d["st"][0], 1);  // failed
  const std::size_t pine = first_lod(d, "trees/pine.glb");
  EXPECT_EQ(d["bud"][pine + 1], 0);  // missed
  EXPECT_EQ(d["reasons"][d["why"][pine + 1].get<int>()], "target not reached");
  EXPECT_EQ(d["bud"][first_lod(d, "trees/oak.glb")], 1);   // met
  EXPECT_TRUE(d["bud"][first_lod(d, "props/table.obj")].is_null());  // no budget in the record
}

TEST(ReportHtml, TableShowsTargetsAndPercentages) {
  const json d = page_data(render_report_html(sample_report()));
  const std::size_t worst = first_lod(d, "props/table.obj") + 2;  // its LOD3: Hausdorff 9.5%
  EXPECT_EQ(d["lv"][worst], 3);
  EXPECT_EQ(d["targets"][d["tgt"][worst].get<int>()], "ratio 0.1");
  EXPECT_EQ(d["tri"][worst], 100);
  EXPECT_EQ(d["mean"][worst].get<double>(), 0.7);
  EXPECT_EQ(d["h"][worst].get<double>(), 9.5);
  EXPECT_EQ(d["stops"][d["stop"][worst].get<int>()], "target_reached");
  EXPECT_EQ(d["itri"][1], 1000);
}

TEST(ReportHtml, EveryHeaderSortsAndShowsADirection) {
  const std::string html = render_report_html(sample_report());
  EXPECT_NE(html.find("th[aria-sort=\"descending\"]::after"), std::string::npos);
  EXPECT_NE(html.find("addEventListener(\"click\""), std::string::npos);
  for (const char* label : {"\"screen coverage\"", "\"budget\"", "\"input size\"", "\"output size\""}) {
    EXPECT_NE(html.find(label), std::string::npos) << label;  // columns the script draws
  }
  for (const char* control : {"id=\"q\"", "id=\"cls\"", "id=\"st\"", "value=\"missed\"", "id=\"next\""}) {
    EXPECT_NE(html.find(control), std::string::npos) << control;
  }
}

TEST(ReportHtml, WorstAssetsChartKeepsTenLargest) {
  json report = sample_report();
  for (int i = 0; i < 12; ++i) {
    const std::string path = "bulk/" + std::string(60, 'x') + "/asset_" + std::to_string(i) + ".obj";
    // json::array: clang makes a braced lone json a copy of it, gcc an array holding it.
    report["assets"].push_back(asset(path, "bulk", json::array({lod(1, 0.5, 0.001, 0.2 + 0.01 * i)})));
  }
  const std::string html = render_report_html(report);
  const std::string_view chart = between(html, "aria-label=\"worst assets by Hausdorff distance\"", "</svg>");
  EXPECT_EQ(count_of(chart, "<g><title>"), 10U);
  EXPECT_NE(chart.find("asset_11.obj (bulk): 31.0000%"), std::string_view::npos);  // full path in the tooltip
  EXPECT_NE(chart.find("\xE2\x80\xA6"), std::string_view::npos);                   // long labels shortened
  EXPECT_EQ(chart.find("asset_1.obj"), std::string_view::npos);                    // 11th and 12th left out
  EXPECT_LT(chart.find("asset_11.obj"), chart.find("asset_10.obj"));
}

TEST(ReportHtml, EmptyReportSaysSo) {
  json report = sample_report();
  report["assets"] = json::array();
  for (const json& doc : {report, json::object(), json(nullptr), json::array(), json(42), json("text")}) {
    std::string html;
    ASSERT_NO_THROW(html = render_report_html(doc)) << doc.dump();
    EXPECT_NE(html.find("This report has no assets."), std::string::npos) << doc.dump();
    EXPECT_EQ(html.find("<svg"), std::string::npos);
    EXPECT_NE(html.find("</html>"), std::string::npos);
  }
}

TEST(ReportHtml, AbsentValuesRenderAsDash) {
  json bare_lod = {{"level", 1},
                   {"ratio", nullptr},
                   {"mean_rel", std::nan("")},
                   {"hausdorff_rel", std::numeric_limits<double>::infinity()},
                   {"target", nullptr},
                   {"stop_reason", 7},
                   {"surprise", {{"nested", true}}}};
  json report = {{"lodforge_version", nullptr},
                 {"jobs", "two"},
                 {"assets", json::array({{{"path", "a.obj"}, {"lods", json::array({bare_lod, "junk", 5})}},
                                         {{"class", "c"}, {"status", "failed"}, {"cache_hit", "yes"}},
                                         3,
                                         {{"path", 5}, {"lods", "none"}}})}};
  std::string html;
  ASSERT_NO_THROW(html = render_report_html(report));
  const json d = page_data(html);
  ASSERT_EQ(d["st"].size(), 3U);  // the bare LOD, the failure, the asset with no usable fields; 3 is dropped
  EXPECT_EQ(d["dir"][0], -1);     // the failure has no path
  EXPECT_TRUE(d["hit"][0].is_null());  // cache hit of the wrong type
  const std::size_t bare = first_lod(d, "a.obj");
  EXPECT_EQ(d["lv"][bare], 1);
  for (const char* column : {"tri", "mean", "h", "ttri"}) EXPECT_TRUE(d[column][bare].is_null()) << column;
  for (const char* column : {"tgt", "stop"}) EXPECT_EQ(d[column][bare], -1) << column;
  const std::string_view page = between(html, "<body>", "<script");
  for (const char* leak : {"nan", "inf", "null", "surprise"}) EXPECT_EQ(page.find(leak), std::string::npos) << leak;
  const std::string_view header = between(html, "<header>", "</header>");
  EXPECT_NE(header.find("lodforge <b>" + std::string(kDash) + "</b>"), std::string_view::npos);
  EXPECT_NE(header.find("jobs <b>" + std::string(kDash) + "</b>"), std::string_view::npos);
  EXPECT_NE(html.find("no asset has a measured Hausdorff distance"), std::string::npos);
}

TEST(ReportHtml, ExtremeValuesStayOutOfThePlots) {
  json report = sample_report();
  report["assets"].push_back(asset("huge.obj", "props", {lod(1, 1e-300, 1e300, 1e307), lod(2, 0.5, 1e-320, 0.0)}));
  std::string html;
  ASSERT_NO_THROW(html = render_report_html(report));
  const std::string_view page = between(html, "<body>", "<script");
  for (const char* leak : {"nan", "inf"}) EXPECT_EQ(page.find(leak), std::string::npos) << leak;
  const json d = page_data(html);  // still valid JSON, no NaN or Infinity in it
  EXPECT_TRUE(d["h"][first_lod(d, "huge.obj")].is_null());
  EXPECT_LE(d["axes"]["err"][1].get<double>(), 1e282);  // the axes leave out what no log axis can hold
  EXPECT_EQ(count_of(html, "<svg viewBox"), 1U);
}

TEST(ReportHtml, WorstAssetsAreDistinctAssets) {
  json report = sample_report();
  // Every LOD of these assets has the same, largest error: each asset is still one bar.
  for (int i = 0; i < 4; ++i) {
    report["assets"].push_back(asset("same/a" + std::to_string(i) + ".obj", "props",
                                     {lod(1, 0.5, 0.01, 0.5), lod(2, 0.25, 0.01, 0.5), lod(3, 0.1, 0.01, 0.5)}));
  }
  const std::string html = render_report_html(report);
  const std::string_view chart = between(html, "aria-label=\"worst assets by Hausdorff distance\"", "</svg>");
  EXPECT_EQ(count_of(chart, "<g><title>"), 10U);  // these 4 and the sample's 6 measured assets
  for (int i = 0; i < 4; ++i) EXPECT_EQ(count_of(chart, "<title>same/a" + std::to_string(i) + ".obj"), 1U) << i;
}

TEST(ReportHtml, ShowsChangesSinceThePreviousRun) {
  json report = sample_report();
  report["changes"] = {{"previous_assets", 7},
                       {"added", {"trees/pine.glb"}},
                       {"removed", {"old/<gone>.obj"}},
                       {"rebuilt", {"props/chair.obj"}},
                       {"status_changed", json::array()},
                       {"lods_moved", {{{"path", "props/chair.obj"},
                                        {"level", 2},
                                        {"triangles", {300, 250}},
                                        {"hausdorff_rel", {0.012, 0.012}},
                                        {"moved", {"triangles"}}}}}};
  const std::string html = render_report_html(report);
  const std::string_view section = between(html, "<section id=\"changes\">", "</section>");
  EXPECT_NE(section.find("<b>1</b> added, <b>1</b> removed, <b>1</b> rebuilt"), std::string_view::npos);
  EXPECT_NE(section.find("old/&lt;gone&gt;.obj"), std::string_view::npos);
  EXPECT_NE(section.find("props/chair.obj LOD2: triangles 300 \xE2\x86\x92 250"), std::string_view::npos);
  EXPECT_EQ(render_report_html(sample_report()).find("id=\"changes\""), std::string::npos);  // no previous run
}

TEST(ReportHtml, ReplacesBytesHtmlCannotCarry) {
  json report = sample_report();
  // An invalid byte, a C0 and a C1 control character; the hex escapes are split where a letter follows.
  report["assets"][0]["path"] = std::string(
      "props/\xC2\x85"
      "ch\xFF"
      "air\x01.obj");
  report["effective_config"]["note"] = std::string("bad \xC0 byte");
  std::string html;
  ASSERT_NO_THROW(html = render_report_html(report));
  const std::string fffd = "\xEF\xBF\xBD";
  EXPECT_NE(html.find("props/" + fffd + "ch" + fffd + "air" + fffd + ".obj"), std::string::npos);
  EXPECT_NE(html.find("bad " + fffd + " byte"), std::string::npos);  // the effective config dump
  EXPECT_EQ(html.find('\xFF'), std::string::npos);
  EXPECT_EQ(html.find('\x01'), std::string::npos);
  EXPECT_EQ(html.find("\xC2\x85"), std::string::npos);
}

TEST(ReportHtml, IsDeterministic) {
  const json report = sample_report();
  const std::string first = render_report_html(report);
  EXPECT_EQ(first, render_report_html(report));
  EXPECT_EQ(first, render_report_html(json::parse(report.dump())));  // as read back from report.json
}

// Pictures beside the report: the page counts them per asset, only when they carry the names it derives from
// the asset's path (so a report cannot make the page load anything else).
TEST(ReportHtml, CountsOnlyThePicturesItsPathsName) {
  json report = sample_report();
  const auto names = [](const std::string& path, std::size_t n) {
    json list = json::array();
    for (std::size_t k = 0; k < n; ++k) list.push_back(picture_file_name(path, k));
    return list;
  };
  std::map<std::string, int> expected;
  for (json& a : report["assets"]) {
    const std::string path = a["path"];
    if (path == "props/chair.obj") a["pictures"] = names(path, 4), expected[path] = 4;
    if (path == "rocks/pebble & <b>.ply") a["pictures"] = names(path, 3), expected[path] = 3;
    if (path == "trees/oak.glb") a["pictures"] = json::array({"../../etc/passwd", "report_files/x.png"});
    if (path == "trees/pine.glb") a["pictures"] = "report_files/trees/pine.glb/lod0.png";  // not a list
  }
  const json data = page_data(render_report_html(report));
  EXPECT_EQ(data["picdir"], "report_files/");
  ASSERT_EQ(data["pic"].size(), data["name"].size());
  for (std::size_t i = 0; i < data["pic"].size(); ++i) {
    const int dir = data["dir"][i];
    const std::string path = dir < 0 ? "" : data["dirs"][dir].get<std::string>() + data["name"][i].get<std::string>();
    EXPECT_EQ(data["pic"][i], expected.count(path) ? expected[path] : 0) << path;
  }
  // A path the page would show changed (bytes that are not UTF-8) gets none.
  const std::string bad = std::string("props/ch\xFF") + "air.obj";
  report["assets"][0]["path"] = bad;
  report["assets"][0]["pictures"] = names(bad, 4);
  const json bad_data = page_data(render_report_html(report));  // kept alive: the loop reads into it
  for (const json& p : bad_data["pic"]) EXPECT_NE(p, 4);
}

TEST(ReportHtml, IsSelfContained) {
  json report = sample_report();
  const std::string html = render_report_html(report);
  for (const char* external : {"http://", "https://", "src=", "href=", "url(", "@import", "<link", "<iframe"}) {
    EXPECT_EQ(html.find(external), std::string::npos) << external;
  }
  EXPECT_NE(html.find("Content-Security-Policy"), std::string::npos);
}

}  // namespace
}  // namespace lodforge::batch
