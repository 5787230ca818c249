// lodforge_bench_symmetry: symmetry detection time and result on corpus meshes (default: the symmetric
// characters and animals of the quad folder plus two 100k-triangle scans) and on a synthetic mirrored mesh of
// about 100 000 triangles. Target: a 100k-triangle mesh well under a second. Prints per mesh the best of
// --reps runs (wall and process CPU time: on a busy machine, CPU time with --threads 1 is the figure to quote),
// the symmetric fraction and the plane; always exits 0.
#include <CLI/CLI.hpp>
#include <sys/resource.h>
#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "lodforge/io/asset.hpp"
#include "lodforge/symmetry/symmetry.hpp"

using namespace lodforge;

namespace {

using Clock = std::chrono::steady_clock;

double cpu_seconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

// A closed wavy tube of quads mirrored about x = 0 (positions of the x < 0 half copied from the x > 0 half).
Mesh mirrored_tube(int rings, int segments) {
  Mesh m;
  const double pi = std::acos(-1.0);
  for (int r = 0; r < rings; ++r) {
    const double z = 4.0 * r / rings;
    for (int j = 0; j < segments; ++j) {
      const double phi = 2 * pi * j / segments;
      const double c = std::cos(phi), s = std::sin(phi);
      const double radius = 1 + 0.1 * std::sin(3 * z + 2 * s) + 0.05 * std::cos(5 * std::abs(c) + z);
      m.add_vertex_with_wedge(to_float(Vec3d{{radius * c, radius * s, z}}));
    }
  }
  for (int r = 0; r < rings; ++r) {  // exact copies: vertex j mirrors vertex segments/2 - j
    for (int j = segments / 4 + 1; j < 3 * segments / 4; ++j) {
      const int mj = segments / 2 - j;
      Vec3f p = m.positions[static_cast<std::size_t>(r * segments + (mj + segments) % segments)];
      p[0] = -p[0];
      m.positions[static_cast<std::size_t>(r * segments + j)] = p;
    }
    m.positions[static_cast<std::size_t>(r * segments + segments / 4)][0] = 0;
    m.positions[static_cast<std::size_t>(r * segments + 3 * segments / 4)][0] = 0;
  }
  auto id = [&](int r, int j) { return static_cast<std::uint32_t>(r * segments + j % segments); };
  for (int r = 0; r + 1 < rings; ++r) {
    for (int j = 0; j < segments; ++j) m.add_face({id(r, j), id(r, j + 1), id(r + 1, j + 1), id(r + 1, j)});
  }
  return m;
}

void run(const std::string& name, const Mesh& mesh, int reps) {
  double best = INFINITY, best_cpu = INFINITY;
  symmetry::SymmetryMap s;
  for (int i = 0; i < reps; ++i) {
    const auto t0 = Clock::now();
    const double c0 = cpu_seconds();
    s = symmetry::detect_symmetry(mesh);
    best_cpu = std::min(best_cpu, cpu_seconds() - c0);
    best = std::min(best, std::chrono::duration<double>(Clock::now() - t0).count());
  }
  std::printf("%-38s %7zu tris %7zu edges  symmetric %.4f  plane (%.5f %.5f %.5f) %+.5g  %7.1f ms wall %7.1f ms cpu\n",
              name.c_str(), mesh.triangle_count(), s.edges, s.symmetric_fraction(), s.plane.normal[0],
              s.plane.normal[1], s.plane.normal[2], s.plane.offset, best * 1e3, best_cpu * 1e3);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("Symmetry detection speed and result");
  std::string corpus = LODFORGE_BENCH_CORPUS_DIR;
  std::vector<std::string> files = {"quad/makehuman_base_hm08.obj",   "quad/makehuman_male_generic.obj",
                                    "quad/makehuman_proxy741.obj",    "quad/makehuman_male_casualsuit01.obj",
                                    "quad/makehuman_hair_bob01.obj",  "quad/spot_quadrangulated.obj",
                                    "quad/spot_control_mesh.obj",     "quad/blub_quadrangulated.obj",
                                    "quad/suzanne.obj",               "scanned/smplx-human-neutral.obj",
                                    "scanned/dragon-100k.obj",        "scanned/lucy-100k.ply"};
  int reps = 3;
  int threads = 0;
  app.add_option("--corpus", corpus, "corpus folder");
  app.add_option("files", files, "meshes relative to the corpus folder");
  app.add_option("--reps", reps, "runs per mesh (the best is printed)");
  app.add_option("--threads", threads, "TBB threads (0 = all)");
  CLI11_PARSE(app, argc, argv);
  const tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                                  threads > 0 ? static_cast<std::size_t>(threads) : tbb::this_task_arena::max_concurrency());
  run("synthetic mirrored tube", mirrored_tube(250, 200), reps);
  for (const std::string& f : files) {
    try {
      run(f, io::load_asset(corpus + "/" + f).meshes.at(0), reps);
    } catch (const std::exception& e) {
      std::printf("%-40s skipped: %s\n", f.c_str(), e.what());
    }
  }
  return 0;
}
