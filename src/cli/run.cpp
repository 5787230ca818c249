// The batch commands: `lodforge run`, `validate-config`, `merge-reports` and `bench`.
//
// Exit codes follow main.cpp: 0 all assets done, 1 some assets failed (listed on stderr), 2 usage, config or
// input-folder errors (nothing processed), 3 internal error; `run` stopped by Ctrl-C exits 130 after the
// assets in flight are finished and the report is written (a second Ctrl-C kills it at once; either way a
// re-run resumes from the cache).
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "commands.hpp"
#include "lodforge/batch/config.hpp"
#include "lodforge/batch/lods_manifest.hpp"
#include "lodforge/batch/report.hpp"
#include "lodforge/batch/runner.hpp"
#include "lodforge/batch/shard.hpp"
#include "lodforge/io/asset.hpp"
#include "lodforge/io/file.hpp"
#include "lodforge/tiling/tiling.hpp"

namespace lodforge::cli {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;
using Clock = std::chrono::steady_clock;

constexpr int kExitInterrupted = 130;     // 128 + SIGINT, what shells report for a Ctrl-C'd command
constexpr double kRedrawSeconds = 0.1;    // a progress line redrawn more often only flickers
constexpr std::size_t kPathColumns = 36;  // with the counters, the progress line fits 80 columns

std::atomic<bool> g_cancel{false};

// First Ctrl-C / SIGTERM: stop admitting assets and finish cleanly; the second one kills the default way.
extern "C" void on_signal(int sig) {
  if (g_cancel.exchange(true)) {
    std::signal(sig, SIG_DFL);
    std::raise(sig);
  }
}

std::string human_count(double n) {
  char buf[32];
  if (n >= 1e9)
    std::snprintf(buf, sizeof buf, "%.2fG", n / 1e9);
  else if (n >= 1e6)
    std::snprintf(buf, sizeof buf, "%.2fM", n / 1e6);
  else if (n >= 1e3)
    std::snprintf(buf, sizeof buf, "%.1fk", n / 1e3);
  else
    std::snprintf(buf, sizeof buf, "%.0f", n);
  return buf;
}

std::string clock_time(double seconds) {
  const long s = static_cast<long>(seconds + 0.5);
  char buf[32];
  if (s >= 3600)
    std::snprintf(buf, sizeof buf, "%ld:%02ld:%02ld", s / 3600, s / 60 % 60, s % 60);
  else
    std::snprintf(buf, sizeof buf, "%ld:%02ld", s / 60, s % 60);
  return buf;
}

// Progress on stderr: one live line on a terminal, one plain line per asset otherwise (logs, CI).
class Progress {
 public:
  explicit Progress(bool tty) : tty_(tty) {}

  void operator()(const batch::AssetDone& d) {
    const Json& r = d.record;
    const std::string path = r["path"];
    const std::string status = r["status"];
    if (!tty_) {
      std::string what;
      if (status == "failed")
        what = "FAILED: " + r["error"].get<std::string>();
      else if (status == "skipped")
        what = "skipped: " + r["error"].get<std::string>();
      else {
        char buf[96];
        std::snprintf(buf, sizeof buf, "%zu LODs, %.2f s%s", r["lods"].size(), r["seconds"].get<double>(),
                      r["cache_hit"].get<bool>() ? " (cached)" : "");
        what = buf;
      }
      std::fprintf(stderr, "[%zu/%zu] %s: %s\n", d.done, d.total, path.c_str(), what.c_str());
      return;
    }
    if (status == "failed") failed_ += 1;
    const auto now = Clock::now();
    if (d.done < d.total && drawn_ && std::chrono::duration<double>(now - last_).count() < kRedrawSeconds) return;
    last_ = now;
    drawn_ = true;
    // Keep the line inside a terminal's width: long paths show their tail, where the file name is.
    const std::string shown = path.size() > kPathColumns ? "..." + path.substr(path.size() - kPathColumns + 3) : path;
    const double rate = d.elapsed_seconds > 0 ? double(d.input_triangles_done) / d.elapsed_seconds : 0.0;
    const double eta = d.done > 0 ? d.elapsed_seconds * double(d.total - d.done) / double(d.done) : 0.0;
    std::fprintf(stderr, "\r\x1b[K[%zu/%zu] %3.0f%%  %s tri/s  ETA %s%s  %s", d.done, d.total,
                 d.total ? 100.0 * double(d.done) / double(d.total) : 100.0, human_count(rate).c_str(),
                 clock_time(eta).c_str(), failed_ ? ("  " + std::to_string(failed_) + " failed").c_str() : "",
                 shown.c_str());
    std::fflush(stderr);
  }

  void finish() {
    if (tty_ && drawn_) std::fprintf(stderr, "\r\x1b[K");
  }

 private:
  bool tty_;
  bool drawn_ = false;
  std::size_t failed_ = 0;
  Clock::time_point last_{};
};

struct RunArgs {
  std::string config, input, output, shard, memory_limit;
  unsigned jobs = 0;
  bool force = false;
  bool strict = false;
  bool dry_run = false;
  bool prune = false;
  double asset_timeout_s = -1;  // < 0: the config's defaults.asset_timeout_s
  std::string report_pictures;  // auto | on | off; empty: the config's defaults.report_pictures
};

void apply_report_pictures(batch::BatchConfig& config, const std::string& mode) {
  if (mode == "auto") config.report.pictures = batch::ReportPictures::automatic;
  if (mode == "on") config.report.pictures = batch::ReportPictures::on;
  if (mode == "off") config.report.pictures = batch::ReportPictures::off;
}

void add_report_pictures_option(CLI::App* cmd, RunArgs& a) {
  cmd->add_option("--report-pictures", a.report_pictures,
                  "a picture of each LOD beside report.html: auto (where it costs little next to the asset's own "
                  "work), on, off (default: the config's defaults.report_pictures, else auto)")
      ->check(CLI::IsMember({"auto", "on", "off"}));
}

// Config and options shared by `run` and `bench`; prints the problem and returns nullopt on a usage error.
std::optional<batch::BatchConfig> load_config_or_report(const std::string& file) {
  try {
    return batch::load_config(file);
  } catch (const batch::ConfigError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s: %s\n", file.c_str(), e.what());
  }
  return std::nullopt;
}

void print_summary(const batch::RunResult& r) {
  const Json& s = r.report["summary"];
  const unsigned long long not_started = s.value("not_started", 0ull);
  std::printf("lodforge run: %llu assets: %llu ok (%llu cache hits), %llu failed, %llu skipped%s\n",
              s["assets"].get<unsigned long long>(), s["succeeded"].get<unsigned long long>(),
              s["cache_hits"].get<unsigned long long>(), s["failed"].get<unsigned long long>(),
              s["skipped"].get<unsigned long long>(),
              not_started ? (", " + std::to_string(not_started) + " not started").c_str() : "");
  std::printf("  %llu LODs, %s input -> %s output triangles, %.2f s with %llu jobs\n",
              s["lods"].get<unsigned long long>(), human_count(s["input_triangles"].get<double>()).c_str(),
              human_count(s["output_triangles"].get<double>()).c_str(), s["seconds"].get<double>(),
              r.report["jobs"].get<unsigned long long>());
  if (!r.report_path.empty()) {
    fs::path html = r.report_path;
    html.replace_extension(".html");
    std::printf("  report: %s, %s\n", r.report_path.string().c_str(), html.string().c_str());
  }
  if (r.pictured_assets > 0) {
    const batch::StageSeconds& st = r.stages;
    const double work = st.fingerprint + st.load + st.analyse + st.lods + st.post_process + st.measure + st.write;
    std::printf("  pictures: %zu asset(s) drawn (%s/), %.2f s, %.1f%% of the assets' work of %.2f s\n",
                r.pictured_assets, batch::kPictureFolder, st.pictures, work > 0 ? 100.0 * st.pictures / work : 0.0,
                work);
  }
  const unsigned long long missed = s.value("lods_missed", 0ull);
  std::printf("  %llu of %llu LOD(s) met their budget, %llu missed%s\n", s["lods"].get<unsigned long long>() - missed,
              s["lods"].get<unsigned long long>(), missed, missed > 0 ? " (report.json: lods[].budget.reasons)" : "");
  if (s.contains("conservative_lods")) {
    const unsigned long long n = s.value("conservative_lods", 0ull), c_missed = s.value("conservative_lods_missed", 0ull);
    std::printf("  %llu of %llu collision/occluder LOD(s) met their budget, %llu missed%s\n", n - c_missed, n, c_missed,
                c_missed > 0 ? " (report.json: conservative_lods[].budget.reasons)" : "");
  }
}

// One line for the files of no supported format: a count per extension and the first few names.
void warn_unsupported(const std::vector<std::string>& files) {
  if (files.empty()) return;
  constexpr std::size_t kNamesShown = 10;  // a library can hold thousands of textures-to-be or notes
  std::map<std::string, std::size_t> by_extension;
  for (const std::string& f : files) {
    const std::string ext = fs::path(f).extension().string();
    ++by_extension[ext.empty() ? "(no extension)" : ext];
  }
  std::string counts, names;
  for (const auto& [ext, n] : by_extension) counts += (counts.empty() ? "" : ", ") + ext + " " + std::to_string(n);
  for (std::size_t i = 0; i < files.size() && i < kNamesShown; ++i) names += (i ? ", " : "") + files[i];
  if (files.size() > kNamesShown) names += ", and " + std::to_string(files.size() - kNamesShown) + " more";
  std::fprintf(stderr, "warning: %zu file(s) of the library are not in a format lodforge reads and were ignored (%s): %s\n",
               files.size(), counts.c_str(), names.c_str());
}

// `run --dry-run`: one line per asset, then the counts; nothing is written.
void print_plan(const batch::Plan& plan) {
  std::size_t rebuild = 0, fresh = 0, skipped = 0;
  for (const batch::PlannedAsset& a : plan.assets) {
    if (a.class_name.empty()) {
      ++skipped;
      std::printf("%s: skipped: %s\n", a.path.c_str(), a.reason.c_str());
      continue;
    }
    std::string lods;
    for (std::size_t k = 0; k < a.lods.size(); ++k) {
      lods += (k ? ", " : "") + std::string("LOD") + std::to_string(k + 1) + " " + a.lods[k];
    }
    for (const std::string& c : a.separate) lods += "; " + c;
    a.rebuild ? ++rebuild : ++fresh;
    std::printf("%s: class %s; %s; %s\n", a.path.c_str(), a.class_name.c_str(), lods.c_str(),
                a.rebuild ? ("rebuild (" + a.reason + ")").c_str() : "up to date");
  }
  std::printf("lodforge run --dry-run: %zu assets: %zu would be rebuilt, %zu up to date, %zu skipped; nothing "
              "written\n",
              plan.assets.size(), rebuild, fresh, skipped);
}

// Stale outputs: removed with --prune (each listed), otherwise counted with the first few named.
void report_stale(const batch::RunResult& r, const fs::path& output) {
  if (r.stale_outputs.empty()) return;
  if (r.pruned) {
    std::printf("pruned %zu output file(s) the library and config no longer produce:\n", r.stale_outputs.size());
    for (const std::string& f : r.stale_outputs) std::printf("  removed %s\n", (output / f).string().c_str());
    return;
  }
  constexpr std::size_t kNamesShown = 10;
  std::string names;
  for (std::size_t i = 0; i < r.stale_outputs.size() && i < kNamesShown; ++i) {
    names += (i ? ", " : "") + r.stale_outputs[i];
  }
  if (r.stale_outputs.size() > kNamesShown) names += ", and " + std::to_string(r.stale_outputs.size() - kNamesShown) + " more";
  std::fprintf(stderr,
               "warning: %zu file(s) in %s are no longer produced by the library and config (report.json: "
               "stale_outputs; --prune removes them): %s\n",
               r.stale_outputs.size(), output.string().c_str(), names.c_str());
}

void run_command(const RunArgs& a) {
  std::optional<batch::BatchConfig> config = load_config_or_report(a.config);
  if (!config) return set_exit_code(2);
  if (a.asset_timeout_s >= 0) config->limits.asset_timeout_s = a.asset_timeout_s;
  apply_report_pictures(*config, a.report_pictures);
  batch::RunOptions options{
      .config_file = a.config, .input_dir = a.input, .output_dir = a.output, .jobs = a.jobs, .force = a.force};
  options.prune = a.prune;
  if (a.prune && !a.shard.empty()) {
    std::fprintf(stderr, "error: --prune cannot be used with --shard: a shard does not see the other shards' "
                         "outputs\n");
    return set_exit_code(2);
  }
  try {
    if (!a.shard.empty()) options.shard = batch::parse_shard(a.shard);
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return set_exit_code(2);
  }
  try {
    if (!a.memory_limit.empty()) options.memory_limit_bytes = batch::parse_byte_size(a.memory_limit);
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "error: --memory-limit: %s\n", e.what());
    return set_exit_code(2);
  }
  if (!a.memory_limit.empty() && options.memory_limit_bytes < tiling::kMinMemoryLimit) {
    std::fprintf(stderr, "error: --memory-limit %s is below the smallest limit, 16M\n", a.memory_limit.c_str());
    return set_exit_code(2);
  }
  if (const unsigned cores = std::thread::hardware_concurrency(); cores > 0 && a.jobs > cores) {
    std::fprintf(stderr,
                 "warning: --jobs %u is more than the %u cores of this machine: the extra threads share the cores "
                 "and each holds an asset in memory\n",
                 a.jobs, cores);
  }
  std::error_code ec;
  if (!fs::is_directory(a.input, ec)) {
    std::fprintf(stderr, "error: %s: %s (--input must be the library folder)\n", a.input.c_str(),
                 fs::exists(a.input, ec) ? "is a file, not a folder" : "no such folder");
    return set_exit_code(2);
  }

  if (a.dry_run) {
    try {
      const batch::Plan plan = batch::plan_batch(*config, options);
      for (const std::string& w : plan.warnings) std::fprintf(stderr, "warning: %s\n", w.c_str());
      warn_unsupported(plan.unsupported);
      print_plan(plan);
    } catch (const io::IoError& e) {
      std::fprintf(stderr, "error: %s\n", e.what());
      set_exit_code(2);
    }
    return;
  }

  Progress progress(::isatty(::fileno(stderr)) == 1);
  options.on_asset_done = [&progress](const batch::AssetDone& d) { progress(d); };
  g_cancel = false;
  options.cancel = &g_cancel;
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  batch::RunResult r;
  try {
    r = batch::run_batch(*config, options);
  } catch (const io::IoError& e) {
    progress.finish();
    std::fprintf(stderr, "error: %s\n", e.what());
    return set_exit_code(2);
  } catch (const std::exception& e) {
    progress.finish();
    std::fprintf(stderr, "internal error: %s\n", e.what());
    return set_exit_code(3);
  }
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  progress.finish();
  for (const std::string& w : r.warnings) std::fprintf(stderr, "warning: %s\n", w.c_str());
  warn_unsupported(r.unsupported);
  print_summary(r);
  report_stale(r, a.output);
  if (!r.skipped_assets.empty()) {
    std::fprintf(stderr, "%zu asset(s) skipped:\n", r.skipped_assets.size());
    for (const std::string& f : r.skipped_assets) std::fprintf(stderr, "  %s\n", f.c_str());
  }
  if (!r.failures.empty()) {
    std::fprintf(stderr, "%zu asset(s) failed:\n", r.failures.size());
    for (const std::string& f : r.failures) std::fprintf(stderr, "  %s\n", f.c_str());
    set_exit_code(1);
  }
  if (a.strict && (r.report["summary"].value("lods_missed", 0ull) > 0 ||
                   r.report["summary"].value("conservative_lods_missed", 0ull) > 0)) {
    set_exit_code(1);
  }
  if (r.cancelled && g_cancel) {
    std::fprintf(stderr, "interrupted: %zu asset(s) not started; run again to resume\n", r.not_started);
    set_exit_code(kExitInterrupted);
  }
}

void bench_command(const RunArgs& a, unsigned max_jobs) {
  std::optional<batch::BatchConfig> config = load_config_or_report(a.config);
  if (!config) return set_exit_code(2);
  apply_report_pictures(*config, a.report_pictures);
  std::error_code ec;
  if (!fs::is_directory(a.input, ec)) {
    std::fprintf(stderr, "error: %s: no such folder\n", a.input.c_str());
    return set_exit_code(2);
  }
  if (max_jobs == 0) max_jobs = static_cast<unsigned>(std::max(1u, std::thread::hardware_concurrency()));
  std::string pattern = (fs::temp_directory_path() / "lodforge-bench-XXXXXX").string();
  if (!::mkdtemp(pattern.data())) {
    std::fprintf(stderr, "error: cannot create a temporary folder\n");
    return set_exit_code(3);
  }
  const fs::path temp(pattern);
  std::printf("bench: %s with %s, jobs 1..%u (outputs in a temporary folder, --force)\n", a.input.c_str(),
              a.config.c_str(), max_jobs);
  std::printf("%4s %8s %9s %10s %12s %8s %10s\n", "jobs", "assets", "seconds", "assets/s", "input tri/s", "speedup",
              "efficiency");
  double base = 0;
  std::vector<std::pair<unsigned, batch::StageSeconds>> stages;
  try {
    for (unsigned j = 1; j <= max_jobs; ++j) {
      const fs::path out = temp / ("jobs" + std::to_string(j));
      const batch::RunResult r = batch::run_batch(
          *config, {.config_file = a.config, .input_dir = a.input, .output_dir = out, .jobs = j, .force = true});
      const double assets = static_cast<double>(r.succeeded + r.failed);
      if (j == 1) base = r.seconds;
      const double speedup = r.seconds > 0 ? base / r.seconds : 0.0;
      std::printf("%4u %8.0f %9.2f %10.1f %12s %7.2fx %9.0f%%\n", j, assets, r.seconds,
                  r.seconds > 0 ? assets / r.seconds : 0.0,
                  human_count(r.seconds > 0 ? double(r.input_triangles) / r.seconds : 0.0).c_str(), speedup,
                  100.0 * speedup / j);
      stages.emplace_back(j, r.stages);
      if (r.failed) std::printf("     (%zu asset(s) failed; first: %s)\n", r.failed, r.failures.front().c_str());
      fs::remove_all(out, ec);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    fs::remove_all(temp, ec);
    return set_exit_code(2);
  }
  fs::remove_all(temp, ec);
  std::printf("per-stage time, summed over assets (seconds; stages of different assets overlap):\n");
  std::printf("%4s %11s %8s %8s %8s %12s %8s %8s %9s\n", "jobs", "fingerprint", "load", "analyse", "lods",
              "post_process", "measure", "write", "pictures");
  for (const auto& [j, s] : stages) {
    std::printf("%4u %11.2f %8.2f %8.2f %8.2f %12.2f %8.2f %8.2f %9.2f\n", j, s.fingerprint, s.load, s.analyse, s.lods,
                s.post_process, s.measure, s.write, s.pictures);
  }
}

}  // namespace

void register_run(CLI::App& app) {
  auto a = std::make_shared<RunArgs>();
  CLI::App* cmd = app.add_subcommand(
      "run",
      "Build the LOD chains of every asset of a library as a config says (incremental, parallel).\n"
      "Writes OUT_DIR/<same folders>/..., OUT_DIR/report.json and report.html, OUT_DIR/lods.json (per asset and\n"
      "LOD: file, triangles, error, switch points for Unreal, Unity and Godot; docs/lods-json.md),\n"
      "OUT_DIR/report_files/ (a picture of each LOD for report.html; --report-pictures), OUT_DIR/.lodforge-cache/.\n"
      "Classes with `collision` / `occluder` entries also get those LODs as separate outputs: <name>_collision.<ext>,\n"
      "<name>_occluder.<ext>, or nodes <node>_collision outside MSFT_lod in a glTF (docs/conservative.md).");
  cmd->add_option("--config", a->config, "batch config (JSON; see configs/schema.json)")->required();
  cmd->add_option("--input", a->input, "library folder (searched recursively)")->required();
  cmd->add_option("--output", a->output, "output folder (created)")->required();
  cmd->add_option("--jobs", a->jobs, "threads for the whole run (0 = all cores)")->default_val(0);
  cmd->add_option("--shard", a->shard,
                  "K/N: process only the assets whose path hashes to K mod N (K is 0-based); the report goes to "
                  "report.shard-K-of-N.json, see merge-reports");
  cmd->add_flag("--force", a->force, "ignore the cache: rebuild every asset");
  cmd->add_flag("--dry-run", a->dry_run,
                "print each asset's class, LOD targets and whether it would be rebuilt; write nothing");
  cmd->add_flag("--prune", a->prune,
                "remove (and list) output files the library and config no longer produce; without it they are "
                "only reported");
  cmd->add_flag("--strict", a->strict,
                "exit 1 when any LOD misses its budget (target not reached, error budget not met, or not 10% "
                "smaller than the level before), collision and occluder LODs included (volume budget exceeded)");
  cmd->add_option("--memory-limit", a->memory_limit,
                  "memory the run stays under, e.g. 4G or 512M (default: half the RAM); assets start only while "
                  "their estimated memory fits; one estimated over it runs alone, its LODs tiled where an untiled "
                  "run would not fit (report.json memory_tile_triangles; docs/batch.md)");
  cmd->add_option("--asset-timeout", a->asset_timeout_s,
                  "seconds one asset may run; a slower one fails with the stage it was in and the run goes on "
                  "(0 = no limit; default: the config's defaults.asset_timeout_s, else none)")
      ->check(CLI::NonNegativeNumber);
  add_report_pictures_option(cmd, *a);
  cmd->callback([a] { run_command(*a); });
}

void register_validate_config(CLI::App& app) {
  auto file = std::make_shared<std::string>();
  CLI::App* cmd = app.add_subcommand(
      "validate-config", "Check a batch config; print its effective form (defaults applied) or every problem.");
  cmd->add_option("config", *file, "batch config (JSON)")->required();
  cmd->callback([file] {
    const std::optional<batch::BatchConfig> config = load_config_or_report(*file);
    if (!config) return set_exit_code(2);
    std::printf("%s\n", batch::effective_config_json(*config).dump(2).c_str());
  });
}

// A report.json read for merge-reports and diff-reports, or nothing after saying on stderr why it is unusable.
std::optional<Json> read_report(const std::string& file) {
  try {
    Json j = Json::parse(io::read_file(file), nullptr, false);
    if (j.is_discarded()) {
      std::fprintf(stderr, "error: %s: not valid JSON\n", file.c_str());
      return std::nullopt;
    }
    if (const std::vector<std::string> problems = batch::check_report(j); !problems.empty()) {
      std::fprintf(stderr, "error: %s: not a lodforge report: %s%s\n", file.c_str(), problems.front().c_str(),
                   problems.size() > 1 ? (" (and " + std::to_string(problems.size() - 1) + " more)").c_str() : "");
      return std::nullopt;
    }
    return j;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return std::nullopt;
  }
}

void register_merge_reports(CLI::App& app) {
  auto out = std::make_shared<std::string>();
  auto inputs = std::make_shared<std::vector<std::string>>();
  CLI::App* cmd = app.add_subcommand(
      "merge-reports",
      "Merge the report.json files of the shards of one run into one report (and its .html), and write the\n"
      "run's lods.json next to it.");
  cmd->add_option("output", *out, "merged report to write (.json; the page goes next to it as .html)")->required();
  cmd->add_option("reports", *inputs, "shard reports (report.shard-K-of-N.json)")->required();
  cmd->callback([out, inputs] {
    std::vector<Json> reports;
    try {
      for (const std::string& f : *inputs) {
        std::optional<Json> j = read_report(f);
        if (!j) return set_exit_code(2);
        reports.push_back(std::move(*j));
      }
      const Json merged = batch::merge_reports(reports);
      fs::path html(*out);
      html.replace_extension(".html");
      batch::write_report(merged, *out, html);
      // The manifest is a function of the report: the merged one gives what an unsharded run writes.
      const fs::path manifest = fs::path(*out).parent_path() / "lods.json";
      batch::write_lods_manifest(batch::lods_manifest(merged, batch::read_lods_manifest(manifest), false), manifest);
      std::printf("merged %zu reports: %llu assets (%llu ok, %llu failed, %llu skipped) -> %s\n", reports.size(),
                  merged["summary"]["assets"].get<unsigned long long>(),
                  merged["summary"]["succeeded"].get<unsigned long long>(),
                  merged["summary"]["failed"].get<unsigned long long>(),
                  merged["summary"]["skipped"].get<unsigned long long>(), out->c_str());
    } catch (const std::exception& e) {
      std::fprintf(stderr, "error: %s\n", e.what());
      set_exit_code(2);
    }
  });
}

void register_diff_reports(CLI::App& app) {
  auto files = std::make_shared<std::vector<std::string>>();
  CLI::App* cmd = app.add_subcommand(
      "diff-reports",
      "Print what changed from report A to report B (two report.json files of runs into the same output): assets "
      "added, removed and rebuilt, status changes, and LODs whose triangle count or measured Hausdorff distance "
      "moved by more than 5%. The same comparison `lodforge run` puts in report.json and report.html "
      "(\"changes\") when it replaces a report. Exit 0 after printing, 2 when a file is unreadable or not a "
      "lodforge report.");
  cmd->add_option("reports", *files, "A.json (the earlier run) and B.json (the later one)")->required()->expected(2);
  cmd->callback([files] {
    std::vector<Json> reports;
    for (const std::string& f : *files) {
      std::optional<Json> j = read_report(f);
      if (!j) return set_exit_code(2);
      reports.push_back(std::move(*j));
    }
    std::printf("changes from %s to %s:\n%s", (*files)[0].c_str(), (*files)[1].c_str(),
                batch::changes_text(batch::diff_reports(reports[0], reports[1])).c_str());
  });
}

void register_bench(CLI::App& app) {
  auto a = std::make_shared<RunArgs>();
  auto max_jobs = std::make_shared<unsigned>(0);
  CLI::App* cmd = app.add_subcommand(
      "bench", "Run the batch pipeline with 1..N jobs; print throughput, scaling efficiency and per-stage time.");
  cmd->add_option("--config", a->config, "batch config (JSON)")->required();
  cmd->add_option("--input", a->input, "library folder")->required();
  cmd->add_option("--max-jobs", *max_jobs, "largest job count (default: all cores)")->default_val(0);
  add_report_pictures_option(cmd, *a);
  cmd->callback([a, max_jobs] { bench_command(*a, *max_jobs); });
}

}  // namespace lodforge::cli
