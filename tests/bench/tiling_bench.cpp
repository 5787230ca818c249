// lodforge_bench_tiling: tiled vs untiled lodforge vs meshopt_simplify on the generated fBm terrain
// (tests/bench/terrain.hpp), in one run: time, peak memory, output triangles, and the error of each LOD
// against the terrain (lodforge's evaluator, the same samples for every method). With --streamed, also the
// out-of-core path on the same terrain written as a binary PLY. With --huge-side, only the out-of-core path on
// a terrain written straight to disk (never held: 7072 = 100M triangles) under --memory-limit: time, the
// child's whole peak RSS against the limit, and peak bytes per input triangle (no error: the source is not
// in memory to measure against).
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
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "lodforge/core/mesh.hpp"
#include "lodforge/eval/eval.hpp"
#include "lodforge/simplify/simplify.hpp"
#include "lodforge/tiling/stream.hpp"
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
  double passes = 0, tile_runs = 0, setup_ms = 0, collapse_ms = 0, stage_triangles = 0, stage_ms = 0;
  double whole_peak_mb = NAN;  // the child's whole peak RSS (VmHWM), not only its growth
};

// Runs `make` in a forked child and brings back its figures.
Figures in_child(const Mesh* terrain, const std::function<Mesh(Figures&)>& make, std::size_t eval_samples,
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
      f.whole_peak_mb = static_cast<double>(status_kb("VmHWM:")) / 1024.0;
      f.peak_mb = static_cast<double>(status_kb("VmHWM:") - before) / 1024.0;
      f.triangles = static_cast<double>(lod.face_count());
      if (terrain != nullptr) {
        const lodforge::EvalResult e =
            lodforge::evaluate(*terrain, lod, {.samples = eval_samples, .include_vertices = false});
        f.rms_rel = e.rms_rel();
        f.mean_rel = e.mean_rel();
        f.hausdorff_rel = e.hausdorff_rel();
      }
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
  std::string cluster_stage = "auto";
  app.add_option("--cluster-stage", cluster_stage, "the tiled run's cluster stage: auto, on, off")
      ->check(CLI::IsMember({"auto", "on", "off"}))
      ->capture_default_str();
  app.add_option("--json", json_path, "write the figures as JSON");
  bool streamed = false;
  std::size_t huge_side = 0;
  std::string memory_limit_text, scratch = "bench-tmp";
  app.add_flag("--streamed", streamed, "also run the out-of-core path on the terrain written as a binary PLY");
  app.add_option("--huge-side", huge_side,
                 "only the out-of-core path, on a terrain of this side written straight to disk (7072: 100M triangles)");
  app.add_option("--memory-limit", memory_limit_text, "limit for the out-of-core runs (plans their tiles), e.g. 6G");
  app.add_option("--scratch", scratch, "folder for the terrain file and the tiles")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  const std::size_t memory_limit = memory_limit_text.empty() ? 0 : lodforge::tiling::parse_memory_size(memory_limit_text);
  std::filesystem::create_directories(scratch);
  // One out-of-core run of `file` in a child: planned under the limit where there is one.
  auto streamed_run = [&](const std::string& file, std::size_t target) {
    return [&, file, target](Figures& f) {
      lodforge::SimplifyOptions o;
      o.target_triangles = target;
      o.threads = threads;
      std::size_t tile = tile_triangles;
      std::uint64_t vertices = 0;
      if (memory_limit > 0) {
        const lodforge::tiling::StreamPlan plan = lodforge::tiling::plan_stream(file, o, memory_limit, threads);
        std::printf("plan under %s: tiles of %zu triangles, estimate %zu MB (fits: %s)\n", memory_limit_text.c_str(),
                    plan.tile_triangles, plan.stream_bytes >> 20, plan.fits ? "yes" : "no");
        std::fflush(stdout);
        tile = plan.tile_triangles;
        vertices = plan.counts.vertices;
      }
      lodforge::tiling::StreamedRun r = lodforge::tiling::simplify_streamed(
          file, o, tile, std::filesystem::path(scratch) / "tiles", memory_limit, vertices);
      f.passes = static_cast<double>(r.result.tiling_passes);
      f.tile_runs = static_cast<double>(r.result.tile_runs);
      return std::move(r.result.mesh);
    };
  };
  if (huge_side > 0) {
    const std::size_t n = 2 * (huge_side - 1) * (huge_side - 1);
    const auto target = static_cast<std::size_t>(std::llround(ratio * static_cast<double>(n)));
    const std::string file = (std::filesystem::path(scratch) / ("terrain-" + std::to_string(huge_side) + ".ply")).string();
    const auto t0 = std::chrono::steady_clock::now();
    if (!lodforge::bench::write_fbm_terrain_ply(huge_side, file)) {
      std::fprintf(stderr, "cannot write %s\n", file.c_str());
      return 1;
    }
    std::printf("terrain %zu x %zu written to %s (%.1f GB) in %.1f s: %zu triangles -> %zu, %u thread(s), limit %s\n",
                huge_side, huge_side, file.c_str(), static_cast<double>(std::filesystem::file_size(file)) / 1e9,
                std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), n, target, threads,
                memory_limit_text.empty() ? "none" : memory_limit_text.c_str());
    const Figures f = in_child(nullptr, streamed_run(file, target), 0, threads);
    std::filesystem::remove(file);
    const double limit_mb = static_cast<double>(memory_limit) / 1048576.0;
    std::printf("out of core: %.0f triangles in %.1f s, peak RSS %.0f MB (%.1f bytes per input triangle), %.0f tile runs\n",
                f.triangles, f.seconds, f.whole_peak_mb, f.whole_peak_mb * 1048576.0 / static_cast<double>(n), f.tile_runs);
    if (memory_limit > 0) {
      std::printf("target: finishes under the limit (within 10%%): peak %.0f MB of %.0f MB (%s)\n", f.whole_peak_mb,
                  limit_mb, f.triangles > 0 && f.whole_peak_mb <= 1.1 * limit_mb ? "met" : "not met");
    }
    return f.triangles > 0 ? 0 : 1;
  }

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
      o.cluster_stage = cluster_stage == "on"    ? lodforge::TilingMode::on
                        : cluster_stage == "off" ? lodforge::TilingMode::off
                                                 : lodforge::TilingMode::automatic;
      lodforge::SimplifyResult r = lodforge::simplify_maybe_tiled(terrain, o);
      f.passes = static_cast<double>(r.tiling_passes);
      f.tile_runs = static_cast<double>(r.tile_runs);
      f.setup_ms = r.timings.setup_ms + r.timings.initial_costs_ms - r.cluster_stage_ms;
      f.stage_triangles = static_cast<double>(r.cluster_stage_triangles);
      f.stage_ms = r.cluster_stage_ms;
      f.collapse_ms = r.timings.collapse_ms + r.timings.output_ms;
      return std::move(r.mesh);
    };
  };
  const Figures meshopt = in_child(
      &terrain, [&](Figures&) { return lodforge::bench::meshopt_lod(terrain, indices, target); }, eval_samples, threads);
  const Figures tiled = in_child(&terrain, lodforge_run(lodforge::TilingMode::on), eval_samples, threads);
  Figures untiled, stream;
  if (!skip_untiled) untiled = in_child(&terrain, lodforge_run(lodforge::TilingMode::off), eval_samples, threads);
  if (streamed) {
    const std::string file = (std::filesystem::path(scratch) / "terrain.ply").string();
    lodforge::bench::write_fbm_terrain_ply(side, file);
    stream = in_child(&terrain, streamed_run(file, target), eval_samples, threads);
    std::filesystem::remove(file);
  }

  std::printf("%-18s %10s %9s %10s %11s %11s %11s\n", "method", "triangles", "time s", "peak MB", "RMS %diag",
              "mean %diag", "Hausdorff %");
  auto row = [](const char* name, const Figures& f) {
    std::printf("%-18s %10.0f %9.2f %10.0f %11.5f %11.5f %11.4f\n", name, f.triangles, f.seconds, f.peak_mb,
                100 * f.rms_rel, 100 * f.mean_rel, 100 * f.hausdorff_rel);
  };
  row("meshopt_simplify", meshopt);
  row("lodforge tiled", tiled);
  if (!skip_untiled) row("lodforge untiled", untiled);
  if (streamed) row("lodforge streamed", stream);
  std::printf("tiled: cluster stage %.0f triangles in %.0f ms, %.0f pass(es), %.0f tile run(s); cut and stitch %.0f ms, "
              "tile runs %.0f ms\n", tiled.stage_triangles, tiled.stage_ms, tiled.passes, tiled.tile_runs,
              tiled.setup_ms, tiled.collapse_ms);
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
                            {"setup_ms", f.setup_ms},   {"collapse_ms", f.collapse_ms},
                            {"cluster_stage_triangles", f.stage_triangles}, {"cluster_stage_ms", f.stage_ms}};
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
    if (streamed) j["streamed"] = obj(stream);
    std::ofstream(json_path) << j.dump(2) << "\n";
  }
  return 0;
}
