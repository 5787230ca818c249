// lodforge_bench_quad: the quad-preserving polychord engine against lodforge's triangle engine (edge_collapse)
// and meshoptimizer (meshopt_simplify) on the quad corpus, at the same triangle counts: quad fraction,
// irregular interior vertices, mean / Hausdorff distance (eval, fraction of the bounding-box diagonal), time.
// Prints MET / NOT MET for the targets of the quad issue and always exits 0 (a benchmark, not a test).
//
// The triangle engine and meshoptimizer are asked for exactly the triangle count the polychord engine
// reached, so the quality columns compare like with like. Where attribute seams stop the triangle engine
// above that count, both engines run again on the geometry alone (rows "polychord(geom)", "edge_col(geom)")
// and the mean-distance target compares those two.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numbers>
#include <string>
#include <vector>

#include "lodforge/core/mesh.hpp"
#include "meshopt_peer.hpp"
#include "lodforge/eval/eval.hpp"
#include "lodforge/io/asset.hpp"
#include "lodforge/quad/quad_stats.hpp"
#include "lodforge/simplify/simplify.hpp"

namespace fs = std::filesystem;
using namespace lodforge;

namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

struct Row {
  std::string mesh, method;
  double ratio = 0;
  std::size_t triangles = 0;
  quad::QuadStats stats{};
  double mean_rel = 0, hausdorff_rel = 0, ms = 0;
};

// A torus of major × minor quads (radii 3 and 1): the generated 100k-quad mesh.
Mesh make_torus(int major, int minor) {
  Mesh m;
  m.materials.push_back(MaterialSlot{.name = "default"});
  for (int j = 0; j < minor; ++j) {
    for (int i = 0; i < major; ++i) {
      const double u = 2.0 * std::numbers::pi * i / major, v = 2.0 * std::numbers::pi * j / minor;
      m.add_vertex_with_wedge({{static_cast<float>((3.0 + std::cos(v)) * std::cos(u)),
                                static_cast<float>((3.0 + std::cos(v)) * std::sin(u)), static_cast<float>(std::sin(v))}});
    }
  }
  auto id = [&](int i, int j) { return static_cast<std::uint32_t>((j % minor) * major + (i % major)); };
  for (int j = 0; j < minor; ++j) {
    for (int i = 0; i < major; ++i) m.add_face({id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)});
  }
  m.name = "torus_" + std::to_string(major * minor) + "_quads";
  return m;
}

// One wedge per vertex, no attributes: both engines run again on it when attribute seams stop the triangle
// engine above the polychord engine's triangle count (Suzanne's normals do).
Mesh geometry_only(const Mesh& m) {
  Mesh g;
  g.materials = m.materials;
  g.positions = m.positions;
  for (std::uint32_t v = 0; v < m.vertex_count(); ++v) g.wedge_vertex.push_back(v);
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    std::vector<std::uint32_t> corners;
    for (std::uint32_t c = m.face_offsets[f]; c < m.face_offsets[f + 1]; ++c) corners.push_back(m.corner_vertex(c));
    g.add_face(corners.data(), corners.size(), m.face_material[f]);
  }
  return g;
}

Mesh run_meshopt(const Mesh& mesh, std::size_t target_triangles) {
  const Mesh tris = triangulated(mesh);
  std::vector<std::uint32_t> indices;
  for (std::size_t c = 0; c < tris.corner_count(); ++c) indices.push_back(tris.corner_vertex(c));
  return bench::meshopt_lod(mesh, indices, target_triangles);
}

void measure(Row& row, const Mesh& original, const Mesh& simplified, std::size_t eval_samples) {
  row.triangles = simplified.triangle_count();
  row.stats = quad::quad_stats(simplified);
  const EvalResult e = evaluate(original, simplified, EvalOptions{.samples = eval_samples});
  row.mean_rel = e.mean_rel();
  row.hausdorff_rel = e.hausdorff_rel();
}

void print_row(const Row& r) {
  std::printf("%-34s %5.2f %-14s %8zu %7.3f %9zu %11.5f %11.4f %9.1f\n", r.mesh.c_str(), r.ratio, r.method.c_str(),
              r.triangles, r.stats.quad_fraction, r.stats.irregular_vertices, 100 * r.mean_rel, 100 * r.hausdorff_rel,
              r.ms);
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  std::string input_dir = fs::path(LODFORGE_BENCH_CORPUS_DIR) / "quad";
  std::vector<std::string> mesh_files;
  std::vector<double> ratios{0.5, 0.25, 0.1};
  int generated_quads = 100'000;
  bool no_generated = false;
  std::size_t eval_samples = 0;
  CLI::App app{"lodforge polychord engine vs the triangle engine and meshoptimizer on quad meshes"};
  app.add_option("--input", input_dir, "folder of quad meshes (.obj .ply .off)")->capture_default_str();
  app.add_option("--mesh", mesh_files, "mesh file(s) to run instead of the folder (repeatable)");
  app.add_option("--ratios", ratios, "target ratios (comma separated)")->delimiter(',')->capture_default_str();
  app.add_option("--generated-quads", generated_quads, "quads of the generated torus")->capture_default_str();
  app.add_flag("--no-generated", no_generated, "skip the generated torus");
  app.add_option("--eval-samples", eval_samples, "area samples per direction (0 = eval's default)");
  int repeats = 5;
  app.add_option("--repeats", repeats, "timed runs per engine for the speed target (median)")->capture_default_str()
      ->check(CLI::Range(1, 100));
  CLI11_PARSE(app, argc, argv);

  if (mesh_files.empty()) {
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(input_dir, ec)) {
      const std::string ext = e.path().extension().string();
      if (ext == ".obj" || ext == ".ply" || ext == ".off") mesh_files.push_back(e.path().string());
    }
    std::sort(mesh_files.begin(), mesh_files.end());
  }
  std::vector<Mesh> meshes;
  for (const std::string& f : mesh_files) {
    try {
      io::Asset a = io::load_asset(f);
      if (a.meshes.empty()) continue;
      a.meshes[0].name = fs::path(f).stem().string();
      meshes.push_back(std::move(a.meshes[0]));
    } catch (const std::exception& e) {
      std::fprintf(stderr, "skipping %s: %s\n", f.c_str(), e.what());
    }
  }
  if (!no_generated) {
    // major : minor = 2 : 1 keeps the quads close to square.
    const int minor = std::max(3, static_cast<int>(std::lround(std::sqrt(generated_quads / 2.0))));
    const int major = std::max(3, generated_quads / minor);
    meshes.push_back(make_torus(major, minor));
  }

  std::printf("%-34s %5s %-14s %8s %7s %9s %11s %11s %9s\n", "mesh", "ratio", "method", "tris", "quad%", "irregular",
              "mean %diag", "Haus %diag", "ms");
  struct Check {
    std::string what;
    bool met;
  };
  std::vector<Check> checks;
  for (const Mesh& mesh : meshes) {
    const bool generated = mesh.name.rfind("torus_", 0) == 0;
    for (double ratio : ratios) {
      if (generated && ratio != 0.25) continue;  // the generated mesh is for the speed target only
      Row quad{.mesh = mesh.name, .method = "polychord", .ratio = ratio};
      SimplifyOptions qo{.target_ratio = ratio};
      qo.engine = Engine::polychord;
      auto t0 = Clock::now();
      const SimplifyResult q = simplify(mesh, qo);
      quad.ms = ms_since(t0);
      measure(quad, mesh, q.mesh, eval_samples);
      print_row(quad);

      Row tri{.mesh = mesh.name, .method = "edge_collapse", .ratio = ratio};
      t0 = Clock::now();
      SimplifyResult t = simplify(mesh, {.target_triangles = q.triangles_after});
      tri.ms = ms_since(t0);
      // Attribute seams stop the triangle engine above the polychord engine's count: compare like with like,
      // both engines on the geometry alone (the polychord row above honoured the seams; the spot cage at 10%
      // reaches 52 triangles with them, the triangle engine 56).
      Row quad_geom = quad;
      if (t.triangles_after > q.triangles_after) {
        const Mesh geom = geometry_only(mesh);
        quad_geom.method = "polychord(geom)";
        t0 = Clock::now();
        const SimplifyResult qg = simplify(geom, qo);
        quad_geom.ms = ms_since(t0);
        measure(quad_geom, mesh, qg.mesh, eval_samples);
        print_row(quad_geom);
        tri.method = "edge_col(geom)";
        t0 = Clock::now();
        t = simplify(geom, {.target_triangles = qg.triangles_after});
        tri.ms = ms_since(t0);
      }
      measure(tri, mesh, t.mesh, eval_samples);
      print_row(tri);

      Row mo{.mesh = mesh.name, .method = "meshopt", .ratio = ratio};
      t0 = Clock::now();
      const Mesh m = run_meshopt(mesh, q.triangles_after);
      mo.ms = ms_since(t0);
      measure(mo, mesh, m, eval_samples);
      print_row(mo);

      char line[256];
      const bool character = mesh.name.find("makehuman") != std::string::npos || mesh.name.find("spot") != std::string::npos;
      if (character && ratio == 0.25) {
        std::snprintf(line, sizeof line, "quad fraction >= 0.85 at 25%% on %s: %.3f", mesh.name.c_str(),
                      quad.stats.quad_fraction);
        checks.push_back({line, quad.stats.quad_fraction >= 0.85});
      }
      if (!generated) {
        const bool geom = quad_geom.method != quad.method;
        std::snprintf(line, sizeof line, "mean <= 1.5x triangle engine on %s at %.2f%s: %.5f%% vs %.5f%% (%.2fx)",
                      mesh.name.c_str(), ratio, geom ? " (geometry only, both)" : "", 100 * quad_geom.mean_rel,
                      100 * tri.mean_rel, tri.mean_rel > 0 ? quad_geom.mean_rel / tri.mean_rel : 0.0);
        checks.push_back({line, quad_geom.mean_rel <= 1.5 * tri.mean_rel});
      } else {
        // The rows above are each engine's first run in this process, and the polychord engine runs first:
        // it pays the page faults of fresh memory and the thread pool's start, the triangle engine then reuses
        // both (measured: triangle engine 283 ms cold, 145 ms warm). The target compares like with like: the
        // median of `repeats` runs each, alternating, after the runs above warmed both.
        std::vector<double> quad_ms, tri_ms;
        for (int k = 0; k < repeats; ++k) {
          auto t1 = Clock::now();
          (void)simplify(mesh, qo);
          quad_ms.push_back(ms_since(t1));
          t1 = Clock::now();
          (void)simplify(mesh, {.target_triangles = q.triangles_after});
          tri_ms.push_back(ms_since(t1));
        }
        auto median = [](std::vector<double> v) {
          std::sort(v.begin(), v.end());
          return v[v.size() / 2];
        };
        const double qm = median(quad_ms), tm = median(tri_ms);
        std::snprintf(line, sizeof line,
                      "%s to 25%% in < 5x the triangle engine's time: median of %d warm runs %.0f ms vs %.0f ms "
                      "(%.2fx; first runs %.0f ms vs %.0f ms, %.2fx)",
                      mesh.name.c_str(), repeats, qm, tm, qm / tm, quad.ms, tri.ms, quad.ms / tri.ms);
        checks.push_back({line, qm < 5.0 * tm});
      }
    }
  }
  std::printf("\n");
  for (const Check& c : checks) std::printf("%s  %s\n", c.met ? "MET    " : "NOT MET", c.what.c_str());
  return 0;
}
