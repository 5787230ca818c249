// report.json's shape checker, the timing filter and shard-report merging.
#include "lodforge/batch/report.hpp"

#include <gtest/gtest.h>

#include <stdexcept>

namespace lodforge::batch {
namespace {

using Json = nlohmann::json;

Json lod(int level) {
  return {{"level", level},
          {"from", "previous"},
          {"target", {{"kind", "ratio"}, {"value", 0.5}}},
          {"target_triangles", 50},
          {"triangles", 50},
          {"vertices", 27},
          {"ratio", 0.5},
          {"error_bound_abs", 0.01},
          {"error_bound_rel", 0.001},
          {"mean_rel", 0.0001},
          {"rms_rel", 0.0002},
          {"hausdorff_rel", 0.002},
          {"normal_deviation_mean_deg", 1.5},
          {"attributes", {{"normal_deviation_mean_deg", 1.5}, {"normal_deviation_p95_deg", 4.0}}},
          {"quad_fraction", 0.0},
          {"irregular_vertices", 12},
          {"stop_reason", "target_reached"},
          {"seconds", 0.01},
          {"screen_coverage", 0.4}};
}

Json asset(const std::string& path, const std::string& status = "ok") {
  return {{"path", path},
          {"class", "props"},
          {"status", status},
          {"error", status == "ok" ? Json(nullptr) : Json("bad file")},
          {"cache_hit", false},
          {"seconds", 0.1},
          {"input", {{"triangles", 100}, {"vertices", 52}, {"diagonal", 1.7}}},
          {"outputs", status == "ok" ? Json::array({path + "_LOD1"}) : Json::array()},
          {"lods", status == "ok" ? Json::array({lod(1)}) : Json::array()}};
}

Json report(std::vector<Json> assets, const Json& shard = nullptr) {
  Json list = Json::array();
  for (Json& a : assets) list.push_back(std::move(a));
  return {{"lodforge_version", "0.1.0"},
          {"config_file", "c.json"},
          {"effective_config", {{"version", 1}}},
          {"jobs", 2},
          {"shard", shard},
          {"summary", report_summary(list, 1.5)},
          {"assets", list}};
}

TEST(Report, SummaryCountsStatusesLodsAndTriangles) {
  const Json r = report({asset("a"), asset("b", "failed"), asset("c"), asset("d", "not_started"),
                         asset("e", "skipped")});
  EXPECT_TRUE(check_report(r).empty()) << check_report(r).front();
  EXPECT_EQ(r["summary"], (Json{{"assets", 5},
                                {"succeeded", 2},
                                {"failed", 1},
                                {"skipped", 1},
                                {"cache_hits", 0},
                                {"lods", 2},
                                {"input_triangles", 200},
                                {"output_triangles", 100},
                                {"seconds", 1.5},
                                {"lods_missed", 0},
                                {"not_started", 1}}));
  EXPECT_TRUE(check_report(r).empty());
}

TEST(Report, CheckNamesEveryShapeProblem) {
  Json r = report({asset("b"), asset("a")});
  r["assets"][1]["lods"][0]["ratio"] = "half";
  r["assets"][0]["status"] = "done";
  r["assets"][0]["lods"][0]["attributes"]["normal_deviation_p95_deg"] = nullptr;
  r["summary"].erase("lods");
  r.erase("jobs");
  const std::vector<std::string> problems = check_report(r);
  const std::vector<std::string> expected = {"jobs: missing",
                                             "summary.lods: missing",
                                             "assets[0].status: expected ok, failed, skipped or not_started",
                                             "assets[0].lods[0].attributes.normal_deviation_p95_deg: expected a number",
                                             "assets[1].path: assets are not sorted by path (or a path repeats)",
                                             "assets[1].lods[0].ratio: expected a number"};
  EXPECT_EQ(problems, expected);
}

// input.symmetry is optional (earlier reports lack it); when present its fields and plane are checked.
TEST(Report, CheckReadsTheSymmetryRecord) {
  Json r = report({asset("a"), asset("b")});
  r["assets"][0]["input"]["symmetry"] = {
      {"plane_mode", "auto"}, {"symmetric_edges", 10}, {"edges", 12}, {"fraction", 10.0 / 12},
      {"plane", {1.0, 0.0, 0.0, -0.5}}};
  r["assets"][1]["input"]["symmetry"] = {
      {"plane_mode", "none"}, {"symmetric_edges", 0}, {"edges", 12}, {"fraction", 0.0}, {"plane", nullptr}};
  EXPECT_TRUE(check_report(r).empty()) << check_report(r).front();
  r["assets"][0]["input"]["symmetry"]["plane"] = {1.0, 0.0};
  r["assets"][1]["input"]["symmetry"].erase("fraction");
  const std::vector<std::string> expected = {"assets[0].input.symmetry.plane: expected 4 numbers or null",
                                             "assets[1].input.symmetry.fraction: missing"};
  EXPECT_EQ(check_report(r), expected);
}

TEST(Report, WithoutTimingsDropsEverySecondsField) {
  const Json r = without_timings(report({asset("a")}));
  EXPECT_FALSE(r["summary"].contains("seconds"));
  EXPECT_FALSE(r["assets"][0].contains("seconds"));
  EXPECT_FALSE(r["assets"][0]["lods"][0].contains("seconds"));
  EXPECT_TRUE(r["assets"][0]["lods"][0].contains("triangles"));
}

TEST(Report, MergeSortsAssetsAndRecomputesTheSummary) {
  const Json merged = merge_reports({report({asset("a"), asset("c")}, "0/2"), report({asset("b", "failed")}, "1/2")});
  ASSERT_EQ(merged["assets"].size(), 3u);
  EXPECT_EQ(merged["assets"][0]["path"], "a");
  EXPECT_EQ(merged["assets"][2]["path"], "c");
  EXPECT_TRUE(merged["shard"].is_null());
  EXPECT_EQ(merged["summary"]["failed"], 1);
  EXPECT_EQ(merged["summary"]["seconds"], 1.5) << "the slowest shard";
}

TEST(Report, MergeKeepsTheFoldersTheShardsShare) {
  Json a = report({asset("a")}, "0/2"), b = report({asset("b")}, "1/2");
  for (Json* r : {&a, &b}) {
    (*r)["input_dir"] = "/library";
    (*r)["output_dir"] = "/out";
  }
  Json merged = merge_reports({a, b});
  EXPECT_EQ(merged["input_dir"], "/library");
  EXPECT_EQ(merged["output_dir"], "/out");
  EXPECT_TRUE(check_report(merged).empty());
  b["output_dir"] = "/other-machine/out";
  merged = merge_reports({a, b});
  EXPECT_EQ(merged["input_dir"], "/library");
  EXPECT_TRUE(merged["output_dir"].is_null()) << "the shards disagree";
}

TEST(Report, MergeRefusesMismatchedOrOverlappingReports) {
  const Json a = report({asset("a")}, "0/2");
  Json other_config = report({asset("b")}, "1/2");
  other_config["effective_config"]["version"] = 2;
  EXPECT_THROW(merge_reports({a, other_config}), std::invalid_argument);
  EXPECT_THROW(merge_reports({a, a}), std::invalid_argument);
  EXPECT_THROW(merge_reports({}), std::invalid_argument);
  Json broken = a;
  broken.erase("assets");
  EXPECT_THROW(merge_reports({broken}), std::invalid_argument);
}

TEST(Report, DiffListsAddedRemovedRebuiltAndLodsThatMovedMoreThanFivePercent) {
  Json before = report({asset("a"), asset("b"), asset("c"), asset("d")});
  Json after = report({asset("b"), asset("c"), asset("d", "failed"), asset("e")});
  for (Json& a : before["assets"]) a["cache_hit"] = true;
  for (Json& a : after["assets"]) a["cache_hit"] = a["path"] != "c";
  after["assets"][0]["lods"][0]["triangles"] = 52;         // b: +4%, not a move
  after["assets"][0]["lods"][0]["hausdorff_rel"] = 0.0022;  // b: +10%
  after["assets"][1]["lods"][0]["triangles"] = 40;          // c: -20%, and rebuilt
  const Json d = diff_reports(before, after);
  EXPECT_EQ(d["previous_assets"], 4);
  EXPECT_EQ(d["added"], Json::array({"e"}));
  EXPECT_EQ(d["removed"], Json::array({"a"}));
  EXPECT_EQ(d["rebuilt"], Json::array({"c"}));
  ASSERT_EQ(d["status_changed"].size(), 1u);
  EXPECT_EQ(d["status_changed"][0], Json({{"path", "d"}, {"from", "ok"}, {"to", "failed"}}));
  ASSERT_EQ(d["lods_moved"].size(), 2u);
  EXPECT_EQ(d["lods_moved"][0]["path"], "b");
  EXPECT_EQ(d["lods_moved"][0]["moved"], Json::array({"hausdorff_rel"}));
  EXPECT_EQ(d["lods_moved"][1]["path"], "c");
  EXPECT_EQ(d["lods_moved"][1]["triangles"], Json::array({50, 40}));
  const std::string text = changes_text(d);
  EXPECT_EQ(text.rfind("1 added, 1 removed, 1 rebuilt, 1 changed status, 2 LODs moved by more than 5%\n", 0), 0u)
      << text;
  EXPECT_NE(text.find("  c LOD1: triangles 50 -> 40 Hausdorff 0.2000% -> 0.2000%\n"), std::string::npos) << text;
  EXPECT_NE(text.find("  d: ok -> failed\n"), std::string::npos) << text;
  // The same report twice: nothing changed; junk never throws.
  const Json same = diff_reports(after, after);
  for (const char* kind : {"added", "removed", "status_changed", "lods_moved"}) EXPECT_TRUE(same[kind].empty()) << kind;
  EXPECT_NO_THROW(diff_reports(Json(5), Json::object({{"assets", {1, "x", Json::object()}}})));
  EXPECT_NO_THROW(changes_text(Json("junk")));
}

}  // namespace
}  // namespace lodforge::batch
