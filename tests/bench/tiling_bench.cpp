// lodforge_bench_tiling: tiled vs untiled lodforge vs meshopt_simplify on the generated fBm terrain
// (tests/bench/terrain.hpp), in one run: time, peak memory, output triangles, and the error of each LOD
// against the terrain (lodforge's evaluator, the same samples for every method).
//
// Each method runs in its own forked child (the parent generates the terrain once): the child resets its
// peak-RSS mark, simplifies, reads VmHWM (peak RSS during the call minus RSS before it), then measures the
// LOD, and sends its figures back through a pipe. Targets (docs/tiling.md): tiled time <= 0.5x meshopt's on
// 2 cores, tiled RMS and mean error <= 1.1x untiled. Timings mean something only on an otherwise idle machine.
#include <malloc.h>
#include <meshoptimizer.h>
#include <sys/wait.h>
#include <tbb/global_control.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "lodforge/core/mesh.hpp"
#include "lodforge/eval/eval.hpp"
#include "lodforge/simplify/simplify.hpp"
#include "lodforge/tiling/tiling.hpp"
#include "meshopt_peer.hpp"
#include "terrain.hpp"
#include "proc_status.hpp"

namespace {

using lodforge::Mesh;

using lodforge::bench::status_kb;

struct Figures {
  double seconds = NAN, peak_mb = NAN;
  double triangles = 0, rms_rel = NAN, mean_rel = NAN, hausdorff_rel = NAN;
  double passes = 0, tile_runs = 0, setup_ms = 0, collapse_ms = 0;
};

// Runs `make` in a forked child and brings back its figures.
Figures in_child(const Mesh& terrain, const std::function<Mesh(Figures&)>& make, std::size_t eval_samples,
                 unsigned threads) {
  int fd[2];
  if (pipe(fd) != 0) return {};
  std::fflush(stdout);
  std::fflush(stderr);
  const pid_t pid = fork();
  if (pid == 0) {
    close(fd[0]);
    Figures f;
    {
      tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
      malloc_trim(0);
      {
        std::ofstream clear("/proc/self/clear_refs");
        clear << "5";  // resets VmHWM to the current VmRSS
      }
      const long before = status_kb("VmRSS:");
      const auto t0 = std::chrono::steady_clock::now();
      const Mesh lod = make(f);
      f.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      f.peak_mb = static_cast<double>(status_kb("VmHWM:") - before) / 1024.0;
      f.triangles = static_cast<double>(lod.face_count());
      const lodforge::EvalResult e =
          lodforge::evaluate(terrain, lod, {.samples = eval_samples, .include_vertices = false});
      f.rms_rel = e.rms_rel();
      f.mean_rel = e.mean_rel();
      f.hausdorff_rel = e.hausdorff_rel();
    }
    const ssize_t w = write(fd[1], &f, sizeof f);
    _exit(w == static_cast<ssize_t>(sizeof f) ? 0 : 1);
  }
  close(fd[1]);
  Figures f;
  const ssize_t r = read(fd[0], &f, sizeof f);
  close(fd[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  if (r != static_cast<ssize_t>(sizeof f)) std::fprintf(stderr, "a child failed (status %d)\n", status);
  return f;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"tiled vs untiled lodforge vs meshopt_simplify on the generated fBm terrain"};
  std::size_t side = 1415;  // 2 x 1414^2 = 4.0M triangles
  double ratio = 0.01;
  unsigned threads = 2;
  std::size_t tile_triangles = lodforge::SimplifyOptions{}.tile_triangles;
  std::size_t eval_samples = 1'000'000;
  std::string json_path;
  bool skip_untiled = false;
  app.add_option("--side", side, "terrain vertices per side (2 (side-1)^2 triangles; 2900 = 16.8M)")
      ->capture_default_str();
  app.add_option("--ratio", ratio, "target fraction of the triangles")->capture_default_str();
  app.add_option("--threads", threads, "threads for every method")->capture_default_str();
  app.add_option("--tile-triangles", tile_triangles, "triangles per tile")->capture_default_str();
  app.add_option("--eval-samples", eval_samples, "area samples per direction for the error")->capture_default_str();
  app.add_flag("--skip-untiled", skip_untiled, "leave out the untiled lodforge run (the slowest)");
  app.add_option("--json", json_path, "write the figures as JSON");
  CLI11_PARSE(app, argc, argv);

  Mesh terrain;
  std::vector<std::uint32_t> indices;
  lodforge::bench::make_fbm_terrain(side, terrain.positions, indices);
  terrain.materials.push_back({.name = "default"});
  terrain.wedge_vertex.resize(terrain.positions.size());
  for (std::uint32_t v = 0; v < terrain.positions.size(); ++v) terrain.wedge_vertex[v] = v;
  terrain.corner_wedge = indices;
  terrain.face_offsets.resize(indices.size() / 3 + 1);
  for (std::size_t f = 0; f < terrain.face_offsets.size(); ++f)
    terrain.face_offsets[f] = static_cast<std::uint32_t>(3 * f);
  terrain.face_material.assign(indices.size() / 3, 0);
  const std::size_t n = terrain.face_count();
  const auto target = static_cast<std::size_t>(std::llround(ratio * static_cast<double>(n)));
  double load[3] = {0, 0, 0};
  if (getloadavg(load, 3) < 0) load[0] = NAN;
  std::printf("terrain %zu x %zu: %zu triangles -> %zu (%.2f%%), %u thread(s), tiles of %zu, load average %.2f\n", side,
              side, n, target, 100 * ratio, threads, tile_triangles, load[0]);

  auto lodforge_run = [&](lodforge::TilingMode mode) {
    return [&, mode](Figures& f) {
      lodforge::SimplifyOptions o;
      o.target_triangles = target;
      o.threads = threads;
      o.tiling = mode;
      o.tile_triangles = tile_triangles;
      lodforge::SimplifyResult r = lodforge::simplify_maybe_tiled(terrain, o);
      f.passes = static_cast<double>(r.tiling_passes);
      f.tile_runs = static_cast<double>(r.tile_runs);
      f.setup_ms = r.timings.setup_ms + r.timings.initial_costs_ms;
      f.collapse_ms = r.timings.collapse_ms + r.timings.output_ms;
      return std::move(r.mesh);
    };
  };
  const Figures meshopt = in_child(
      terrain, [&](Figures&) { return lodforge::bench::meshopt_lod(terrain, indices, target); }, eval_samples, threads);
  const Figures tiled = in_child(terrain, lodforge_run(lodforge::TilingMode::on), eval_samples, threads);
  Figures untiled;
  if (!skip_untiled) untiled = in_child(terrain, lodforge_run(lodforge::TilingMode::off), eval_samples, threads);

  std::printf("%-18s %10s %9s %10s %11s %11s %11s\n", "method", "triangles", "time s", "peak MB", "RMS %diag",
              "mean %diag", "Hausdorff %");
  auto row = [](const char* name, const Figures& f) {
    std::printf("%-18s %10.0f %9.2f %10.0f %11.5f %11.5f %11.4f\n", name, f.triangles, f.seconds, f.peak_mb,
                100 * f.rms_rel, 100 * f.mean_rel, 100 * f.hausdorff_rel);
  };
  row("meshopt_simplify", meshopt);
  row("lodforge tiled", tiled);
  if (!skip_untiled) row("lodforge untiled", untiled);
  std::printf("tiled: %.0f pass(es), %.0f tile run(s); cut and stitch %.0f ms, tile runs %.0f ms\n", tiled.passes,
              tiled.tile_runs, tiled.setup_ms, tiled.collapse_ms);
  const double speed = tiled.seconds / meshopt.seconds;
  std::printf("target: tiled time <= 0.5x meshopt: %.2fx (%s)\n", speed, speed <= 0.5 ? "met" : "not met");
  if (!skip_untiled) {
    const double rms = tiled.rms_rel / untiled.rms_rel, mean = tiled.mean_rel / untiled.mean_rel;
    std::printf("target: tiled RMS <= 1.1x untiled: %.3fx (%s); mean: %.3fx (%s)\n", rms,
                rms <= 1.1 ? "met" : "not met", mean, mean <= 1.1 ? "met" : "not met");
    std::printf("tiled vs untiled: time %.2fx, peak memory %.2fx\n", tiled.seconds / untiled.seconds,
                tiled.peak_mb / untiled.peak_mb);
  }
  if (!json_path.empty()) {
    auto obj = [](const Figures& f) {
      return nlohmann::json{{"seconds", f.seconds},     {"peak_mb", f.peak_mb},
                            {"triangles", f.triangles}, {"rms_rel", f.rms_rel},
                            {"mean_rel", f.mean_rel},   {"hausdorff_rel", f.hausdorff_rel},
                            {"passes", f.passes},       {"tile_runs", f.tile_runs},
                            {"setup_ms", f.setup_ms},   {"collapse_ms", f.collapse_ms}};
    };
    nlohmann::json j{{"side", side},
                     {"triangles", n},
                     {"target", target},
                     {"threads", threads},
                     {"tile_triangles", tile_triangles},
                     {"load_average", load[0]},
                     {"meshopt", obj(meshopt)},
                     {"tiled", obj(tiled)}};
    if (!skip_untiled) j["untiled"] = obj(untiled);
    std::ofstream(json_path) << j.dump(2) << "\n";
  }
  return 0;
}
