// lodforge_bench_report: report.html for a synthetic library of 100 000 assets, measured in headless Chromium.
//
// Generates a report.json of --assets assets (seeded, so every run sees the same document: classes, 3-4 LODs,
// a few failed, skipped and budget-missing assets, some zero-error LODs, and a "changes" section against a
// perturbed previous run), renders report.html with the product's own write_report(), then drives the page
// with tests/browser/report_page.mjs (node + puppeteer-core + Chromium) and prints each target as MET / NOT MET:
//   load <= 3 s, filter or sort <= 200 ms (to the next painted frame), report.html <= 1 KB per asset.
// Without node, puppeteer-core or Chromium it still prints the size and render time and says why the browser
// part did not run.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <random>
#include <string>

#include "lodforge/batch/report.hpp"

namespace fs = std::filesystem;
using Json = nlohmann::json;

namespace {

Json make_report(std::size_t assets, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const char* classes[] = {"props", "rocks", "trees", "env", "characters", "vehicles"};
  Json list = Json::array();
  char path[160];
  for (std::size_t i = 0; i < assets; ++i) {
    const std::size_t c = i % 6;
    std::snprintf(path, sizeof path, "%s/set_%03zu/%s_%06zu.glb", classes[c], (i / 6) % 400, classes[c], i);
    const double roll = u(rng);
    const bool failed = roll < 0.005, skipped = !failed && roll < 0.007;
    const std::uint64_t tris = 500 + static_cast<std::uint64_t>(std::pow(10.0, 2.5 * u(rng)) * 400);
    Json a = {{"path", path},
              {"class", skipped ? Json(nullptr) : Json(classes[c])},
              {"status", failed ? "failed" : skipped ? "skipped" : "ok"},
              {"error", failed ? Json("load failed: unexpected end of file in buffer 0") :
                        skipped ? Json("no class matches " + std::string(path)) : Json(nullptr)},
              {"cache_hit", u(rng) < 0.7},
              {"seconds", 0.5 * u(rng)},
              {"input", {{"triangles", failed || skipped ? 0 : tris}, {"vertices", tris / 2}, {"diagonal", 2.5},
                         {"repeated_faces", 0}, {"bytes", tris * 40 + 2000}}},
              {"output_bytes", failed || skipped ? Json(nullptr) : Json(tris * 30)},
              {"outputs", Json::array()},
              {"lods", Json::array()}};
    if (!failed && !skipped) {
      const int levels = 3 + (u(rng) < 0.5);
      const double ratios[] = {0.5, 0.25, 0.1, 0.05};
      double error = std::pow(10.0, -5 + 2 * u(rng));
      const bool zero = u(rng) < 0.02;  // flat assets: the first LODs are exact
      const bool miss = u(rng) < 0.05;
      double coverage = 0.5;
      for (int k = 0; k < levels; ++k) {
        const auto target = static_cast<std::uint64_t>(std::ceil(ratios[k] * static_cast<double>(tris)));
        const std::uint64_t got = miss && k == levels - 1 ? target * 2 : target;
        error *= 2 + 3 * u(rng);
        const double h = zero && k < 2 ? 0.0 : error;
        coverage *= 0.5;
        Json reasons = Json::array();
        if (miss && k == levels - 1) {
          reasons.push_back("target not reached: " + std::to_string(got) + " triangles for " + std::to_string(target));
        }
        a["lods"].push_back({{"level", k + 1},
                             {"from", "previous"},
                             {"target", {{"kind", "ratio"}, {"value", ratios[k]}}},
                             {"target_triangles", target},
                             {"triangles", got},
                             {"vertices", got / 2},
                             {"ratio", double(got) / double(tris)},
                             {"error_bound_abs", h * 3.0},
                             {"error_bound_rel", h * 1.2},
                             {"error_bound_kind", "certified"},
                             {"budget", {{"status", reasons.empty() ? "met" : "missed"}, {"reasons", reasons}}},
                             {"mean_rel", h * 0.2},
                             {"rms_rel", h * 0.3},
                             {"hausdorff_rel", h},
                             {"normal_deviation_mean_deg", 3.0 * u(rng)},
                             {"attributes", Json::object()},
                             {"quad_fraction", 0.0},
                             {"irregular_vertices", 0},
                             {"stop_reason", reasons.empty() ? "target_reached" : "boundary_locked"},
                             {"seconds", 0.01},
                             {"screen_coverage", coverage}});
      }
    }
    list.push_back(std::move(a));
  }
  Json report = {{"lodforge_version", "bench"},
                 {"config_file", "configs/library.json"},
                 {"effective_config", {{"classes", Json::array()}}},
                 {"jobs", 2},
                 {"shard", nullptr},
                 {"input_dir", "/data/library"},
                 {"output_dir", "/data/lods"}};
  report["summary"] = lodforge::batch::report_summary(list, 1234.5);
  report["assets"] = std::move(list);
  return report;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("report.html for a synthetic library, measured in headless Chromium");
  std::size_t assets = 100000;
  std::string out = "build/bench/report";
  std::string script = LODFORGE_BENCH_REPORT_SCRIPT;
  int reps = 3;
  app.add_option("--assets", assets, "assets in the synthetic report (default 100000)");
  app.add_option("--out", out, "folder for report.json, report.html (default build/bench/report)");
  app.add_option("--reps", reps, "page loads, best of (default 3)");
  app.add_option("--script", script, "the page driver (tests/browser/report_page.mjs)");
  CLI11_PARSE(app, argc, argv);

  fs::create_directories(out);
  const auto t0 = std::chrono::steady_clock::now();
  Json report = make_report(assets, 7);
  // The previous night: 1% of assets changed, 0.2% new, 0.2% gone.
  Json previous = make_report(assets, 7);
  Json kept = Json::array();
  for (std::size_t i = 0; i < previous["assets"].size(); ++i) {
    Json& a = previous["assets"][i];
    if (i % 500 == 3) continue;  // new tonight
    if (i % 100 == 7 && !a["lods"].empty()) a["lods"][0]["triangles"] = a["lods"][0]["triangles"].get<double>() * 1.2;
    kept.push_back(std::move(a));
  }
  for (std::size_t i = 0; i < assets / 500; ++i) {
    Json gone = kept[0];
    gone["path"] = "zz_removed/asset_" + std::to_string(i) + ".glb";
    kept.push_back(std::move(gone));
  }
  previous["assets"] = std::move(kept);
  const auto t1 = std::chrono::steady_clock::now();
  report["changes"] = lodforge::batch::diff_reports(previous, report);
  const auto t2 = std::chrono::steady_clock::now();
  const fs::path json_path = fs::path(out) / "report.json", html_path = fs::path(out) / "report.html";
  lodforge::batch::write_report(report, json_path, html_path);
  const auto t3 = std::chrono::steady_clock::now();
  const auto seconds = [](auto a, auto b) { return std::chrono::duration<double>(b - a).count(); };

  const double html_bytes = static_cast<double>(fs::file_size(html_path));
  const double per_asset = html_bytes / static_cast<double>(assets);
  std::printf("assets            %zu\n", assets);
  std::printf("report.json       %.1f MB\n", static_cast<double>(fs::file_size(json_path)) / 1e6);
  std::printf("report.html       %.2f MB, %.0f bytes per asset\n", html_bytes / 1e6, per_asset);
  std::printf("generate          %.2f s, diff %.2f s, write report.json + report.html %.2f s\n", seconds(t0, t1),
              seconds(t1, t2), seconds(t2, t3));

  const std::string cmd = "node '" + script + "' bench '" + html_path.string() + "' " + std::to_string(reps) + " 2>&1";
  std::string output;
  if (FILE* p = popen(cmd.c_str(), "r")) {
    char buf[4096];
    while (fgets(buf, sizeof buf, p)) output += buf;
    const int status = pclose(p);
    if (status != 0) {
      std::printf("browser           did not run: %s", output.c_str());
      std::printf("size  <= 1 KB/asset: %s (%.0f B)\n", per_asset <= 1024 ? "MET" : "NOT MET", per_asset);
      return 0;
    }
  }
  const Json m = Json::parse(output.substr(output.find('{')), nullptr, false);
  if (m.is_discarded()) {
    std::printf("browser           unreadable output: %s\n", output.c_str());
    return 1;
  }
  std::printf("browser           %s\n", m.dump().c_str());
  const double load = m.value("load_ms", 1e9);
  double filter = 0, sort = 0;
  for (const char* k : {"search_ms", "search_clear_ms", "status_filter_ms", "status_clear_ms", "class_filter_ms",
                        "class_clear_ms"}) {
    filter = std::max(filter, m.value(k, 1e9));
  }
  for (const char* k : {"sort_ms", "sort_reverse_ms", "sort_path_ms"}) sort = std::max(sort, m.value(k, 1e9));
  std::printf("load   <= 3000 ms:   %s (%.0f ms)\n", load <= 3000 ? "MET" : "NOT MET", load);
  std::printf("filter <= 200 ms:    %s (slowest %.0f ms)\n", filter <= 200 ? "MET" : "NOT MET", filter);
  std::printf("sort   <= 200 ms:    %s (slowest %.0f ms)\n", sort <= 200 ? "MET" : "NOT MET", sort);
  std::printf("size   <= 1 KB/asset: %s (%.0f B)\n", per_asset <= 1024 ? "MET" : "NOT MET", per_asset);
  std::printf("console errors:      %d\n", m.value("console_errors", -1));
  return 0;
}
