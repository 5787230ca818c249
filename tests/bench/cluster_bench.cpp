// lodforge_bench_cluster: the vertex clustering engine (Engine::cluster) against meshopt_simplifySloppy in the
// same run, on the scanned corpus and a generated fBm terrain.
//
// How each number is taken:
// - Input: every mesh reduced to geometry (positions + triangles, attributes dropped), the same arrays for both.
// - Same triangle count: sloppy runs first; lodforge then gets sloppy's output count as its target
//   (target_triangles), so lodforge's output has at most as many triangles as sloppy's.
// - Time: wall clock of the call (meshopt_simplifySloppy on index + position arrays; lodforge::simplify on a
//   Mesh, output Mesh built), best of --reps. lodforge runs on 1 thread and on all threads.
// - Quality: lodforge::evaluate(input, output), RMS of both directions pooled, --eval-samples area samples.
// Targets: lodforge throughput >= 1.0x sloppy, RMS <= 0.8x sloppy at the same triangle count (geomean over the
// scanned corpus; the terrain on its own). Printed as MET / NOT MET; the exit status is 0 whatever they say.
#include <meshoptimizer.h>
#include <tbb/parallel_for.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numeric>
#include <string>
#include <thread>
#include <vector>

#include "lodforge/core/mesh.hpp"
#include "lodforge/eval/eval.hpp"
#include "lodforge/io/asset.hpp"
#include "lodforge/simplify/simplify.hpp"
#include "asset_geometry.hpp"
#include "terrain.hpp"

namespace {

using lodforge::Mesh;
using lodforge::Vec3f;
using Clock = std::chrono::steady_clock;
namespace fs = std::filesystem;

constexpr double kThroughputTarget = 1.0;  // lodforge cluster speed / sloppy speed, at least
constexpr double kRmsTarget = 0.8;         // lodforge cluster RMS / sloppy RMS, at most

struct Input {
  std::string name{};
  Mesh mesh{};
  std::vector<std::uint32_t> indices{};
  bool terrain = false;
};

Mesh geometry_mesh(std::vector<Vec3f> positions, const std::vector<std::uint32_t>& indices) {
  Mesh m;
  m.positions = std::move(positions);
  m.wedge_vertex.resize(m.positions.size());
  std::iota(m.wedge_vertex.begin(), m.wedge_vertex.end(), 0u);
  const std::size_t tris = indices.size() / 3;
  m.face_offsets.resize(tris + 1);
  for (std::size_t t = 0; t <= tris; ++t) m.face_offsets[t] = static_cast<std::uint32_t>(3 * t);
  m.corner_wedge = indices;
  m.face_material.assign(tris, 0);
  m.materials.push_back(lodforge::MaterialSlot{.name = "", .has_normals = false, .has_tangents = false});
  return m;
}

Input load_input(const fs::path& path) {
  const lodforge::io::Asset asset = lodforge::io::load_asset(path);
  std::vector<Vec3f> positions;
  std::vector<std::uint32_t> indices;
  lodforge::bench::asset_triangles(asset, positions, indices);
  Input in{.name = path.stem().string(), .indices = indices};
  in.mesh = geometry_mesh(std::move(positions), in.indices);
  return in;
}

// The simplify benchmark's terrain: side × side heights over the unit square from 8 octaves of value noise.
Input make_terrain(std::size_t side) {
  std::vector<Vec3f> positions;
  std::vector<std::uint32_t> indices;
  lodforge::bench::make_fbm_terrain(side, positions, indices);
  Input in{.name = "terrain-" + std::to_string(indices.size() / 3), .indices = indices, .terrain = true};
  in.mesh = geometry_mesh(std::move(positions), in.indices);
  return in;
}

template <typename F>
double best_ms(int reps, double budget_s, F&& f) {
  double best = 1e300, total = 0;
  for (int r = 0; r < reps; ++r) {
    const auto t0 = Clock::now();
    f();
    const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    best = std::min(best, ms);
    total += ms;
    if (total > 1000.0 * budget_s) break;
  }
  return best;
}

struct Row {
  std::string mesh{};
  double ratio = 0;
  bool terrain = false;
  std::size_t input = 0, sloppy_tris = 0, cluster_tris = 0, probes = 0;
  double sloppy_ms = 0, cluster_1t_ms = 0, cluster_all_ms = 0;
  double sloppy_rms = 0, cluster_rms = 0, sloppy_haus = 0, cluster_haus = 0;
};

double geomean(const std::vector<double>& v) {
  if (v.empty()) return 0;
  double s = 0;
  for (double x : v) s += std::log(x);
  return std::exp(s / static_cast<double>(v.size()));
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"lodforge vertex clustering vs meshopt_simplifySloppy"};
  std::string corpus = std::string(LODFORGE_BENCH_CORPUS_DIR) + "/scanned";
  std::vector<std::string> meshes;
  std::vector<double> ratios{0.1, 0.02};
  std::vector<double> terrain_ratios{0.01};
  std::size_t terrain_side = 1025;
  std::size_t eval_samples = 1'000'000;
  int reps = 5;
  double rep_budget = 2.0;
  bool no_terrain = false, no_corpus = false;
  app.add_option("--input", corpus, "folder of meshes (the scanned corpus)")->capture_default_str();
  app.add_option("--mesh", meshes, "run these files instead (repeatable)");
  app.add_option("--ratios", ratios, "target ratios for the corpus")->delimiter(',')->capture_default_str();
  app.add_option("--terrain-ratios", terrain_ratios, "target ratios for the terrain")->delimiter(',')->capture_default_str();
  app.add_option("--terrain-side", terrain_side, "terrain vertices per side (2900: 16.8M triangles)")->capture_default_str();
  app.add_flag("--no-terrain", no_terrain, "skip the terrain");
  app.add_flag("--no-corpus", no_corpus, "only the terrain");
  app.add_option("--eval-samples", eval_samples, "area samples per direction")->capture_default_str();
  app.add_option("--reps", reps, "best of N timed repetitions")->capture_default_str();
  app.add_option("--rep-budget", rep_budget, "stop repeating once the repetitions add up to S seconds")->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  std::vector<fs::path> files;
  if (!meshes.empty()) {
    for (const std::string& m : meshes) files.emplace_back(m);
  } else if (!no_corpus && fs::is_directory(corpus)) {
    for (const auto& e : fs::directory_iterator(corpus)) {
      const std::string ext = e.path().extension().string();
      if (ext == ".obj" || ext == ".ply" || ext == ".off" || ext == ".stl" || ext == ".glb" || ext == ".gltf")
        files.push_back(e.path());
    }
    std::sort(files.begin(), files.end());
  }
  double load = 0;
  if (FILE* f = std::fopen("/proc/loadavg", "r")) {
    if (std::fscanf(f, "%lf", &load) != 1) load = -1;
    std::fclose(f);
  }
  std::printf("lodforge_bench_cluster: %u hardware threads, load average %.2f, %zu eval samples\n",
              std::thread::hardware_concurrency(), load, eval_samples);
  std::printf("%-26s %6s %9s %9s %9s %10s %10s %10s %7s %7s %10s %10s %7s %6s\n", "mesh", "ratio", "input", "sloppy",
              "cluster", "sloppy_ms", "clu1t_ms", "cluall_ms", "spd1t", "spdall", "sloppy_rms", "clu_rms", "rms_x", "probes");

  std::vector<Row> rows;
  auto run = [&](const Input& in, double ratio) {
    Row row{.mesh = in.name, .ratio = ratio, .terrain = in.terrain, .input = in.indices.size() / 3};
    const auto target_indices = static_cast<std::size_t>(std::round(ratio * static_cast<double>(row.input))) * 3;
    std::vector<std::uint32_t> dst(in.indices.size());
    std::size_t n = 0;
    row.sloppy_ms = best_ms(reps, rep_budget, [&] {
      n = meshopt_simplifySloppy(dst.data(), in.indices.data(), in.indices.size(), &in.mesh.positions[0][0],
                                 in.mesh.positions.size(), sizeof(Vec3f), target_indices, 1.0f, nullptr);
    });
    row.sloppy_tris = n / 3;
    dst.resize(n);
    const Mesh sloppy = geometry_mesh(in.mesh.positions, dst);
    lodforge::SimplifyOptions o{.target_triangles = std::max<std::size_t>(row.sloppy_tris, 1), .engine = lodforge::Engine::cluster};
    lodforge::SimplifyResult r;
    o.threads = 1;
    row.cluster_1t_ms = best_ms(reps, rep_budget, [&] { r = lodforge::simplify(in.mesh, o); });
    o.threads = 0;
    lodforge::SimplifyResult r_all;
    row.cluster_all_ms = best_ms(reps, rep_budget, [&] { r_all = lodforge::simplify(in.mesh, o); });
    if (!(r_all.mesh == r.mesh)) std::printf("  !! %s: output differs between 1 thread and all threads\n", in.name.c_str());
    row.cluster_tris = r.triangles_after;
    row.probes = r.rounds;
    lodforge::EvalOptions eo{.samples = eval_samples};
    const lodforge::EvalResult es = lodforge::evaluate(in.mesh, sloppy, eo);
    const lodforge::EvalResult ec = lodforge::evaluate(in.mesh, r.mesh, eo);
    row.sloppy_rms = es.rms_rel();
    row.cluster_rms = ec.rms_rel();
    row.sloppy_haus = es.hausdorff_rel();
    row.cluster_haus = ec.hausdorff_rel();
    std::printf("%-26s %6.3f %9zu %9zu %9zu %10.2f %10.2f %10.2f %6.2fx %6.2fx %10.3e %10.3e %6.2fx %6zu\n",
                row.mesh.c_str(), ratio, row.input, row.sloppy_tris, row.cluster_tris, row.sloppy_ms,
                row.cluster_1t_ms, row.cluster_all_ms, row.sloppy_ms / row.cluster_1t_ms,
                row.sloppy_ms / row.cluster_all_ms, row.sloppy_rms, row.cluster_rms, row.cluster_rms / row.sloppy_rms, row.probes);
    std::fflush(stdout);
    rows.push_back(row);
  };
  for (const fs::path& f : files) {
    Input in;
    try {
      in = load_input(f);
    } catch (const std::exception& e) {
      std::printf("  skip %s: %s\n", f.string().c_str(), e.what());
      continue;
    }
    for (double ratio : ratios) run(in, ratio);
  }
  if (!no_terrain) {
    const Input terrain = make_terrain(terrain_side);
    for (double ratio : terrain_ratios) run(terrain, ratio);
  }

  std::printf("\nsummary (geometric means over the rows)\n");
  auto report = [&](const char* what, bool terrain) {
    std::vector<double> s1, sa, q, h;
    for (const Row& r : rows) {
      if (r.terrain != terrain) continue;
      s1.push_back(r.sloppy_ms / r.cluster_1t_ms);
      sa.push_back(r.sloppy_ms / r.cluster_all_ms);
      q.push_back(r.cluster_rms / r.sloppy_rms);
      h.push_back(r.cluster_haus / r.sloppy_haus);
    }
    if (q.empty()) return;
    const double speed_all = geomean(sa), rms = geomean(q);
    std::printf("%-8s (%zu rows): speed vs sloppy %.2fx on 1 thread, %.2fx on all threads (target >= %.1fx: %s); "
                "RMS %.2fx sloppy's (target <= %.1fx: %s); Hausdorff %.2fx\n",
                what, q.size(), geomean(s1), speed_all, kThroughputTarget,
                speed_all >= kThroughputTarget ? "MET" : "NOT MET", rms, kRmsTarget,
                rms <= kRmsTarget ? "MET" : "NOT MET", geomean(h));
  };
  report("scanned", false);
  report("terrain", true);
  return 0;
}
