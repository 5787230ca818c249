// The batch targets (benchmarks, not tests; they print MET / NOT MET and always exit 0 unless they
// could not run at all):
//
//   1. Throughput: `lodforge run --jobs 2` is >= 1.8x as fast as `--jobs 1` on the generated library (the tests'
//      200 small assets in 3 classes, tests/unit/batch/library_fixture.hpp).
//   2. Memory: the peak memory of `lodforge run --memory-limit L` stays under L for a library of larger meshes
//      whose files add up to 4 x L.
//
// Method: every measured run is the real command, started with fork + exec so that nothing of this program's
// memory is in it; wall time is taken around the child, peak memory is the child's peak resident set (wait4's
// ru_maxrss: everything the process touched, code and libraries included, so it is an upper bound of what the
// budget governs). Runs use --force so every asset is simplified each time. Jobs 1 and 2 alternate, best of
// --reps each, so that load from other processes hits both about equally; the load average is printed with
// the result because on a shared machine a speedup is only as good as the idle cores it ran on.
//
//   lodforge_bench_batch [--lodforge PATH] [--work DIR] [--assets N] [--reps N] [--memory-limit 32M]
//                        [--memory-asset-triangles N] [--memory-jobs 1 2] [--skip-throughput] [--skip-memory]
//                        [--quick] [--keep]
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include "../unit/batch/library_fixture.hpp"
#include "lodforge/batch/runner.hpp"
#include "lodforge/io/asset.hpp"

namespace {

namespace fs = std::filesystem;
namespace testlib = lodforge::batch::testlib;
using Clock = std::chrono::steady_clock;

constexpr double kSpeedupTarget = 1.8;
constexpr int kLibraryToLimit = 4;  // the memory library's files add up to 4 x --memory-limit

struct ChildRun {
  int exit_code = -1;
  double seconds = 0, cpu_seconds = 0;
  double max_rss_mib = 0;
  double load_before = 0;
};

double load_average() {
  double load[1] = {NAN};
  return getloadavg(load, 1) == 1 ? load[0] : NAN;
}

// Runs `lodforge ARGS...` with its output in `log`; returns its time, CPU time and peak resident set.
ChildRun run_lodforge(const std::string& lodforge, const std::vector<std::string>& args, const fs::path& log) {
  ChildRun r;
  r.load_before = load_average();
  std::fflush(stdout);
  const auto t0 = Clock::now();
  const pid_t pid = fork();
  if (pid < 0) return r;
  if (pid == 0) {
    if (FILE* f = std::freopen(log.c_str(), "w", stdout)) dup2(fileno(f), 2);
    std::vector<char*> argv{const_cast<char*>(lodforge.c_str())};
    for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    execv(lodforge.c_str(), argv.data());
    _exit(127);
  }
  int status = 0;
  rusage usage{};
  while (wait4(pid, &status, 0, &usage) < 0 && errno == EINTR) {
  }
  r.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  r.cpu_seconds = double(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
                  1e-6 * double(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
  r.max_rss_mib = double(usage.ru_maxrss) / 1024.0;  // kilobytes on Linux
  return r;
}

std::vector<std::string> run_args(const fs::path& config, const fs::path& lib, const fs::path& out, unsigned jobs,
                                  const std::string& memory_limit = "") {
  std::vector<std::string> a{"run",        "--config", config.string(),      "--input", lib.string(), "--output",
                             out.string(), "--jobs",   std::to_string(jobs), "--force"};
  if (!memory_limit.empty()) {
    a.push_back("--memory-limit");
    a.push_back(memory_limit);
  }
  return a;
}

std::uint64_t folder_bytes(const fs::path& dir) {
  std::uint64_t n = 0;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (e.is_regular_file()) n += e.file_size();
  }
  return n;
}

void check_exit(const ChildRun& r, const fs::path& log) {
  if (r.exit_code == 0) return;
  std::printf("  lodforge exited with %d; its log (%s):\n", r.exit_code, log.c_str());
  std::ifstream in(log);
  std::string line;
  for (int i = 0; i < 20 && std::getline(in, line); ++i) std::printf("    %s\n", line.c_str());
}

// ---- 1. throughput, jobs 1 vs 2 --------------------------------------------------------------------------------

void throughput(const std::string& lodforge, const fs::path& work, int assets, int reps) {
  std::printf("== throughput: jobs 2 vs jobs 1 on the generated library ==\n");
  const fs::path lib = work / "library";
  fs::remove_all(lib);
  const testlib::Library l = testlib::write_library(lib, assets);
  const fs::path config = testlib::write_config(work);
  std::size_t triangles = 0;
  for (const std::string& f : l.files) {
    for (const lodforge::Mesh& m : lodforge::io::load_asset(lib / f).meshes) triangles += m.triangle_count();
  }
  std::printf("library: %zu assets, %zu input triangles, %.1f MiB (%s); %u hardware threads\n", l.files.size(),
              triangles, double(folder_bytes(lib)) / (1 << 20), lib.c_str(), std::thread::hardware_concurrency());
  std::printf("%4s %4s %9s %9s %11s %9s %7s\n", "rep", "jobs", "seconds", "cpu s", "cpu/wall", "rss MiB", "load");
  double best[3] = {0, std::numeric_limits<double>::max(), std::numeric_limits<double>::max()};
  for (int rep = 0; rep < reps; ++rep) {
    for (unsigned jobs : {1u, 2u}) {
      const fs::path out = work / ("out-jobs" + std::to_string(jobs));
      const fs::path log = work / ("run-jobs" + std::to_string(jobs) + ".log");
      const ChildRun r = run_lodforge(lodforge, run_args(config, lib, out, jobs), log);
      check_exit(r, log);
      std::printf("%4d %4u %9.2f %9.2f %11.2f %9.1f %7.2f\n", rep + 1, jobs, r.seconds, r.cpu_seconds,
                  r.seconds > 0 ? r.cpu_seconds / r.seconds : 0.0, r.max_rss_mib, r.load_before);
      if (r.exit_code == 0) best[jobs] = std::min(best[jobs], r.seconds);
    }
  }
  const double speedup = best[2] > 0 ? best[1] / best[2] : 0.0;
  std::printf("best of %d: jobs 1 %.2f s (%.0f tri/s), jobs 2 %.2f s (%.0f tri/s); load average now %.2f\n", reps,
              best[1], double(triangles) / best[1], best[2], double(triangles) / best[2], load_average());
  std::printf("TARGET batch throughput on 2 cores >= %.1fx one core: %.2fx  %s\n", kSpeedupTarget, speedup,
              speedup >= kSpeedupTarget ? "MET" : "NOT MET");
  if (std::thread::hardware_concurrency() < 2) std::printf("  (fewer than 2 hardware threads: not measurable)\n");
}

// ---- 2. memory under --memory-limit -----------------------------------------------------------------------------

// A closed sphere of about `triangles` triangles; the radius makes every asset's content distinct (no duplicate
// reuse), so every asset is really simplified.
lodforge::Mesh sphere_of(std::size_t triangles, int i) {
  const int segments = std::max(8, static_cast<int>(std::sqrt(double(triangles))));
  const int rings = std::max(4, static_cast<int>(double(triangles) / (2.0 * segments)));
  return lodforge::testing::make_uv_sphere(rings, segments, 1.0f + 0.001f * static_cast<float>(i));
}

void memory(const std::string& lodforge, const fs::path& work, std::uint64_t limit, std::size_t tris,
            const std::vector<unsigned>& job_counts) {
  std::printf("== memory: peak RSS under --memory-limit for a library of %dx that size ==\n", kLibraryToLimit);
  const fs::path lib = work / "memory-library";
  fs::remove_all(lib);
  fs::create_directories(lib / "props");
  // Assets in four formats (their bytes per triangle differ: STL 50, OBJ ~34, PLY ~19, GLB 12), written until
  // their files add up to 4 x the limit.
  using lodforge::io::Format;
  static const std::pair<Format, const char*> kFormats[] = {
      {Format::obj, "obj"}, {Format::glb, "glb"}, {Format::stl, "stl"}, {Format::ply, "ply"}};
  std::uint64_t total = 0, largest_footprint = 0;
  std::size_t count = 0, triangles = 0;
  for (int i = 0; total < kLibraryToLimit * limit; ++i) {
    const auto& [format, ext] = kFormats[i % 4];
    const fs::path file = lib / "props" / ("mesh_" + std::to_string(i) + "." + ext);
    const lodforge::Mesh m = sphere_of(tris, i);
    triangles += m.triangle_count();
    lodforge::io::save_asset(testlib::asset_of({m}, format), file);
    total += fs::file_size(file);
    largest_footprint = std::max(largest_footprint, lodforge::batch::estimate_footprint(file));
    ++count;
  }
  const fs::path config = testlib::write_config(work);
  std::printf(
      "limit %.1f MiB; library: %zu assets (OBJ, GLB, STL, PLY) of %zu triangles, %zu in all, %.1f MiB of "
      "files (%.2fx the limit); largest estimated footprint %.1f MiB\n",
      double(limit) / (1 << 20), count, tris, triangles, double(total) / (1 << 20), double(total) / double(limit),
      double(largest_footprint) / (1 << 20));

  const fs::path empty = work / "empty-library";
  fs::create_directories(empty);
  const ChildRun base = run_lodforge(lodforge, run_args(config, empty, work / "out-empty", 2), work / "empty.log");
  std::printf("baseline (empty library): peak RSS %.1f MiB\n", base.max_rss_mib);

  const std::string limit_arg = std::to_string(limit);
  bool met = true;
  for (unsigned jobs : job_counts) {
    const fs::path log = work / ("memory-jobs" + std::to_string(jobs) + ".log");
    const ChildRun r = run_lodforge(lodforge, run_args(config, lib, work / "out-memory", jobs, limit_arg), log);
    check_exit(r, log);
    const bool ok = r.exit_code == 0 && r.max_rss_mib * (1 << 20) < double(limit);
    met = met && ok;
    std::printf("jobs %u: %.2f s (%.0f tri/s), peak RSS %.1f MiB of %.1f MiB (%.0f%%)  %s\n", jobs, r.seconds,
                double(triangles) / r.seconds, r.max_rss_mib, double(limit) / (1 << 20),
                100.0 * r.max_rss_mib * (1 << 20) / double(limit), ok ? "under" : "OVER");
  }
  std::printf("TARGET peak memory under --memory-limit for a library %dx that size: %s\n", kLibraryToLimit,
              met ? "MET" : "NOT MET");
}

std::string default_lodforge() {
#ifdef LODFORGE_BENCH_CLI
  return LODFORGE_BENCH_CLI;
#else
  return "lodforge";
#endif
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("lodforge batch targets: jobs 2 vs jobs 1 throughput, peak memory under --memory-limit");
  std::string lodforge = default_lodforge(), work_arg, limit_text = "32M";
  int assets = 200, reps = 3;
  std::size_t asset_triangles = 0;
  std::vector<unsigned> memory_jobs{1, 2};
  bool skip_throughput = false, skip_memory = false, quick = false, keep = false;
  app.add_option("--lodforge", lodforge, "the lodforge command to measure")->capture_default_str();
  app.add_option("--work", work_arg, "scratch folder (default: a new temporary folder, removed at the end)");
  app.add_option("--assets", assets, "assets in the generated library")->capture_default_str();
  app.add_option("--reps", reps, "repetitions of each job count (best is kept)")->capture_default_str();
  app.add_option("--memory-limit", limit_text, "the --memory-limit to check")->capture_default_str();
  app.add_option("--memory-asset-triangles", asset_triangles,
                 "triangles per asset of the memory library (default: limit / 4500 bytes, so that two assets "
                 "fit in the budget at once)");
  app.add_option("--memory-jobs", memory_jobs, "job counts for the memory runs")->capture_default_str();
  app.add_flag("--skip-throughput", skip_throughput, "only the memory target");
  app.add_flag("--skip-memory", skip_memory, "only the throughput target");
  app.add_flag("--quick", quick, "one repetition");
  app.add_flag("--keep", keep, "keep the scratch folder");
  CLI11_PARSE(app, argc, argv);
  if (quick) reps = 1;

  std::uint64_t limit = 0;
  try {
    limit = lodforge::batch::parse_byte_size(limit_text);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  }
  fs::path work;
  if (work_arg.empty()) {
    std::string pattern = (fs::temp_directory_path() / "lodforge-bench-batch-XXXXXX").string();
    if (!mkdtemp(pattern.data())) {
      std::fprintf(stderr, "error: cannot create a temporary folder\n");
      return 2;
    }
    work = pattern;
  } else {
    work = work_arg;
    fs::create_directories(work);
  }
  std::printf("lodforge: %s; scratch: %s; load average at start %.2f on %u hardware threads\n", lodforge.c_str(),
              work.c_str(), load_average(), std::thread::hardware_concurrency());
  if (!skip_throughput) throughput(lodforge, work, assets, reps);
  if (!skip_memory) {
    memory(lodforge, work, limit, asset_triangles ? asset_triangles : static_cast<std::size_t>(limit / 4500),
           memory_jobs);
  }
  if (!keep && work_arg.empty()) fs::remove_all(work);
  return 0;
}
