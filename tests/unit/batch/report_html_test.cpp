#include "lodforge/batch/report_html.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstddef>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

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

struct Cell {
  std::string text;                  // content with tags stripped
  std::optional<std::string> value;  // data-v
};

// The body rows of the table with id `id`, as cells.
std::vector<std::vector<Cell>> table_rows(std::string_view html, std::string_view id) {
  const std::string_view body =
      between(between(html, "<table id=\"" + std::string(id) + "\"", "</table>"), "<tbody>", "</tbody>");
  std::vector<std::vector<Cell>> rows;
  for (std::size_t tr = body.find("<tr"); tr != std::string_view::npos; tr = body.find("<tr", tr + 1)) {
    const std::string_view row = body.substr(tr, body.find("</tr>", tr) - tr);
    std::vector<Cell> cells;
    for (std::size_t td = row.find("<td"); td != std::string_view::npos; td = row.find("<td", td + 1)) {
      const std::size_t open_end = row.find('>', td);
      const std::string_view tag = row.substr(td, open_end - td);
      Cell cell;
      if (const std::size_t v = tag.find("data-v=\""); v != std::string_view::npos) {
        cell.value = std::string(tag.substr(v + 8, tag.find('"', v + 8) - (v + 8)));
      }
      const std::string_view content = row.substr(open_end + 1, row.find("</td>", open_end) - open_end - 1);
      bool in_tag = false;
      for (const char c : content) {
        if (c == '<') in_tag = true;
        if (!in_tag) cell.text += c;
        if (c == '>') in_tag = false;
      }
      cells.push_back(std::move(cell));
    }
    rows.push_back(std::move(cells));
  }
  return rows;
}

// Column indices of the asset x LOD table.
constexpr std::size_t kRank = 0, kPath = 1, kStatus = 3, kLevel = 5, kTarget = 6, kTriangles = 8, kMean = 11,
                      kHausdorff = 13, kUvProblems = 15, kQuadFraction = 16, kStop = 17;

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
  EXPECT_EQ(count_of(html, "<script"), 1U);  // the page's own sorting script only
  EXPECT_NE(html.find("rocks/pebble &amp; &lt;b&gt;.ply"), std::string::npos);
  EXPECT_EQ(html.find("<b>.ply"), std::string::npos);
}

TEST(ReportHtml, ListsFailuresBeforeTheTable) {
  const std::string html = render_report_html(sample_report());
  const std::size_t failures = html.find("id=\"failures\"");
  ASSERT_NE(failures, std::string::npos);
  EXPECT_LT(failures, html.find("<table id=\"lods\""));
  const std::string_view section = between(html, "id=\"failures\"", "</section>");
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

TEST(ReportHtml, HasOneScatterPerClassPlusWorstAssets) {
  const std::string html = render_report_html(sample_report());
  EXPECT_EQ(count_of(html, "<svg"), 4U);  // props, rocks, trees (the unclassified asset has no LODs) + worst
  for (const char* cls : {"props", "rocks", "trees"}) {
    EXPECT_NE(html.find("aria-label=\"mean error vs triangle ratio: " + std::string(cls) + "\""), std::string::npos);
  }
  EXPECT_NE(html.find("aria-label=\"worst assets by Hausdorff distance\""), std::string::npos);
  // One dot per measured LOD (15) plus one legend dot per LOD level shown in each class (3 + 2 + 3).
  EXPECT_EQ(count_of(between(html, "id=\"plots\"", "</section>"), "<circle"), 15U + 8U);
  EXPECT_NE(html.find("mean error, % of diagonal (log)"), std::string::npos);
  EXPECT_NE(html.find(">LOD3</text>"), std::string::npos);
}

TEST(ReportHtml, ScatterHasAxesTicksAndLabels) {
  const std::string html = render_report_html(sample_report());
  const std::string_view trees = between(html, "aria-label=\"mean error vs triangle ratio: trees\"", "</svg>");
  // trees' ratios span 0.02..0.5, so x is log; mean errors 0.05%..3% give decades 0.01..10.
  EXPECT_NE(trees.find("achieved triangle ratio (log)"), std::string_view::npos);
  for (const char* tick : {">0.01<", ">0.1<", ">1<", ">10<"}) EXPECT_NE(trees.find(tick), std::string_view::npos);
  const std::string_view props = between(html, "aria-label=\"mean error vs triangle ratio: props\"", "</svg>");
  EXPECT_NE(props.find("achieved triangle ratio</text>"), std::string_view::npos);  // 0.1..0.5: linear
  EXPECT_NE(props.find(">0.5<"), std::string_view::npos);
}

TEST(ReportHtml, TableHasOneRowPerAssetLod) {
  const std::string html = render_report_html(sample_report());
  const auto rows = table_rows(html, "lods");
  EXPECT_EQ(rows.size(), 15U + 2U);  // 15 LODs, plus one row each for the failed and the skipped asset
  for (const auto& row : rows) ASSERT_EQ(row.size(), 20U);
  std::size_t chair_rows = 0;
  for (const auto& row : rows) chair_rows += row[kPath].text == "props/chair.obj";
  EXPECT_EQ(chair_rows, 3U);
}

TEST(ReportHtml, RowsAreWorstFirst) {
  const std::string html = render_report_html(sample_report());
  const auto rows = table_rows(html, "lods");
  ASSERT_EQ(rows.size(), 17U);
  EXPECT_EQ(rows[0][kPath].text, "rocks/broken.obj");
  EXPECT_EQ(rows[0][kStatus].text, "failed");
  EXPECT_EQ(rows[1][kPath].text, "props/table.obj");  // its LOD3 has the largest Hausdorff distance, 9.5%
  EXPECT_EQ(rows[1][kHausdorff].text, "9.5000");
  double previous = std::numeric_limits<double>::infinity();
  for (std::size_t i = 1; i + 1 < rows.size(); ++i) {
    ASSERT_TRUE(rows[i][kHausdorff].value) << i;
    const double h = std::stod(*rows[i][kHausdorff].value);
    EXPECT_LE(h, previous) << i;
    previous = h;
  }
  EXPECT_EQ(rows.back()[kPath].text, "misc/readme.obj");  // unmeasured last
  for (std::size_t i = 0; i < rows.size(); ++i) EXPECT_EQ(rows[i][kRank].text, std::to_string(i + 1));
}

TEST(ReportHtml, TableShowsTargetsAndPercentages) {
  const std::string html = render_report_html(sample_report());
  const auto rows = table_rows(html, "lods");
  ASSERT_GE(rows.size(), 2U);
  const auto& worst = rows[1];  // props/table.obj LOD3
  EXPECT_EQ(worst[kLevel].text, "3");
  EXPECT_EQ(worst[kTarget].text, "ratio 0.1");
  EXPECT_EQ(worst[kTriangles].text, "100");
  EXPECT_EQ(worst[kMean].text, "0.7000");
  EXPECT_EQ(worst[kUvProblems].text, "4");      // uv_flipped 3 + uv_spanning 1
  EXPECT_EQ(worst[kQuadFraction].text, "0.7500");
  EXPECT_EQ(worst[kStop].text, "target_reached");
}

TEST(ReportHtml, EveryHeaderSortsAndShowsADirection) {
  const std::string html = render_report_html(sample_report());
  const std::string_view head = between(between(html, "<table id=\"lods\"", "</table>"), "<thead>", "</thead>");
  EXPECT_EQ(count_of(head, "<th "), 20U);
  EXPECT_EQ(count_of(head, "data-type=\"num\"") + count_of(head, "data-type=\"text\""), 20U);
  EXPECT_EQ(count_of(head, "aria-sort=\"ascending\""), 1U);  // the worst-first rank
  EXPECT_NE(html.find("th[aria-sort=\"descending\"]::after"), std::string::npos);
  EXPECT_NE(html.find("addEventListener(\"click\""), std::string::npos);
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
  const auto rows = table_rows(html, "lods");
  ASSERT_EQ(rows.size(), 3U);  // the bare LOD, the failure, the asset with no usable fields; 3 is dropped
  const auto& failed = rows[0];
  EXPECT_EQ(failed[kPath].text, kDash);
  EXPECT_EQ(failed[4].text, kDash);  // cache hit of the wrong type
  const auto& bare = rows[1][kPath].text == "a.obj" ? rows[1] : rows[2];
  EXPECT_EQ(bare[kPath].text, "a.obj");
  EXPECT_EQ(bare[kLevel].text, "1");
  for (const std::size_t col : {kTarget, kTriangles, kMean, kHausdorff, kStop}) {
    EXPECT_EQ(bare[col].text, kDash) << col;
    EXPECT_FALSE(bare[col].value) << col;
  }
  const std::string_view page = between(html, "<body>", "<script>");  // the script itself says "null"
  for (const char* leak : {"nan", "inf", "null", "surprise"}) EXPECT_EQ(page.find(leak), std::string::npos) << leak;
  const std::string_view header = between(html, "<header>", "</header>");
  EXPECT_NE(header.find("lodforge <b>" + std::string(kDash) + "</b>"), std::string_view::npos);
  EXPECT_NE(header.find("jobs <b>" + std::string(kDash) + "</b>"), std::string_view::npos);
  // The class plot of "c" has nothing to plot but still exists; the bare asset has no class and no plottable LOD.
  EXPECT_NE(html.find("no measured LODs"), std::string::npos);
  EXPECT_NE(html.find("no asset has a measured Hausdorff distance"), std::string::npos);
}

TEST(ReportHtml, ExtremeValuesStayOutOfThePlots) {
  json report = sample_report();
  report["assets"].push_back(asset("huge.obj", "props", {lod(1, 1e-300, 1e300, 1e307), lod(2, 0.5, 1e-320, 0.0)}));
  std::string html;
  ASSERT_NO_THROW(html = render_report_html(report));
  const std::string_view page = between(html, "<body>", "<script>");
  for (const char* leak : {"nan", "inf"}) EXPECT_EQ(page.find(leak), std::string_view::npos) << leak;
  EXPECT_NE(html.find("2 not plotted"), std::string::npos);  // ratio 1e-300, mean error 1e-320
  EXPECT_EQ(count_of(html, "<svg"), 4U);
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
