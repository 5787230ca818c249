// lodforge_bench_symmetry: symmetry detection time and result on corpus meshes (default: the symmetric
// characters and animals of the quad folder plus two 100k-triangle scans) and on a synthetic mirrored mesh of
// about 100 000 triangles. Target: a 100k-triangle mesh well under a second. Prints per mesh the best of
// --reps runs (wall and process CPU time: on a busy machine, CPU time with --threads 1 is the figure to quote),
// the symmetric fraction and the plane; always exits 0.
// --simplify: symmetric simplification instead (run_simplify below: paired fraction, mirror error and mean
// distance with and without symmetry_weight, targets printed MET / NOT MET).
#include <CLI/CLI.hpp>
#include <sys/resource.h>
#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "lodforge/eval/bvh.hpp"
#include "lodforge/eval/eval.hpp"
#include "lodforge/io/asset.hpp"
#include "lodforge/simplify/simplify.hpp"
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

// ---- symmetric simplification (--simplify) -------------------------------------------------------------------

// `mesh` with its half beyond the plane x = mid (the bounding box's middle) replaced by the mirror image of the
// other half (faces whose centroid lies on the far side dropped, vertices of the kept faces beyond the plane
// pulled onto it), then every coordinate moved by up to `noise` × the diagonal: real assets are never symmetric
// bit for bit.
Mesh mirrored_half(const Mesh& mesh, double noise) {
  double lo = INFINITY, hi = -INFINITY;
  for (const Vec3f& p : mesh.positions) {
    lo = std::min(lo, double{p[0]});
    hi = std::max(hi, double{p[0]});
  }
  const float mid = static_cast<float>(0.5 * (lo + hi));
  const std::vector<std::uint32_t> idx = triangle_vertex_indices(mesh);
  Mesh out;
  std::vector<std::uint32_t> left(mesh.vertex_count(), kInvalidIndex), right(mesh.vertex_count(), kInvalidIndex);
  std::vector<std::array<std::uint32_t, 3>> kept;
  for (std::size_t t = 0; t + 2 < idx.size(); t += 3) {
    const float cx = (mesh.positions[idx[t]][0] + mesh.positions[idx[t + 1]][0] + mesh.positions[idx[t + 2]][0]) / 3;
    if (cx < mid) kept.push_back({idx[t], idx[t + 1], idx[t + 2]});
  }
  for (const auto& f : kept) {
    for (std::uint32_t v : f) {
      if (left[v] != kInvalidIndex) continue;
      Vec3f p = mesh.positions[v];
      p[0] = std::min(p[0], mid);
      left[v] = static_cast<std::uint32_t>(out.vertex_count());
      out.add_vertex_with_wedge(p);
    }
  }
  for (const auto& f : kept) {
    for (std::uint32_t v : f) {
      if (right[v] != kInvalidIndex) continue;
      Vec3f p = out.positions[left[v]];
      if (p[0] == mid) {
        right[v] = left[v];
        continue;
      }
      p[0] = 2 * mid - p[0];
      right[v] = static_cast<std::uint32_t>(out.vertex_count());
      out.add_vertex_with_wedge(p);
    }
  }
  for (const auto& f : kept) out.add_face({left[f[0]], left[f[1]], left[f[2]]});
  for (const auto& f : kept) out.add_face({right[f[0]], right[f[2]], right[f[1]]});  // mirrored: reversed winding
  const double diagonal = compute_bounds(out).diagonal();
  std::mt19937 rng(99);
  std::uniform_real_distribution<double> jitter(-noise * diagonal, noise * diagonal);
  for (Vec3f& p : out.positions) {
    for (int k = 0; k < 3; ++k) p[k] = static_cast<float>(p[k] + jitter(rng));
  }
  out.materials.push_back(MaterialSlot{.name = "default"});
  return out;
}

// A LOD's symmetry against its input's: `region` holds the input's vertices with a mirror, `plane` the input's.
struct MirrorFigures {
  double mirror_error = 0;  // symmetric Hausdorff between the symmetric region and its mirror image, % diagonal
  double paired = 0;        // of the edges in the region, the share whose mirror image is an edge too
  std::size_t region_edges = 0;
};

MirrorFigures mirror_figures(const Mesh& lod, const Mesh& input, const std::vector<char>& region,
                             const symmetry::Plane& plane, double diagonal) {
  MirrorFigures out;
  // Inside the region: the input triangle closest to the point has all its corners in it.
  std::vector<Vec3d> positions;
  for (const Vec3f& p : input.positions) positions.push_back(to_double(p));
  const std::vector<std::uint32_t> input_idx = triangle_vertex_indices(input);
  const TriangleBvh input_bvh(positions, input_idx);
  auto inside = [&](const Vec3d& p) {
    const BvhHit h = input_bvh.closest_point(p);
    if (h.triangle == kInvalidIndex) return false;
    for (int k = 0; k < 3; ++k) {
      if (!region[input_idx[3 * std::size_t{h.triangle} + k]]) return false;
    }
    return true;
  };
  const std::vector<std::uint32_t> idx = triangle_vertex_indices(lod);
  std::vector<char> in(lod.vertex_count());
  for (std::uint32_t v = 0; v < lod.vertex_count(); ++v) in[v] = inside(to_double(lod.positions[v]));
  // The region's faces, and the same reflected (winding reversed).
  Mesh part, image;
  std::vector<std::uint32_t> local(lod.vertex_count(), kInvalidIndex);
  for (std::size_t t = 0; t + 2 < idx.size(); t += 3) {
    if (!in[idx[t]] || !in[idx[t + 1]] || !in[idx[t + 2]]) continue;
    std::uint32_t c[3];
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t v = idx[t + k];
      if (local[v] == kInvalidIndex) {
        local[v] = static_cast<std::uint32_t>(part.vertex_count());
        part.add_vertex_with_wedge(lod.positions[v]);
        image.add_vertex_with_wedge(to_float(plane.reflect(to_double(lod.positions[v]))));
      }
      c[k] = local[v];
    }
    part.add_face({c[0], c[1], c[2]});
    image.add_face({c[0], c[2], c[1]});
  }
  if (part.face_count() > 0) {
    const EvalResult e = evaluate(part, image, {.samples = 20000});
    out.mirror_error = diagonal > 0 ? 100.0 * e.hausdorff / diagonal : 0.0;
  }
  // Paired edges: each end's mirror image within 1% of the edge's length of a LOD vertex, and those joined.
  std::set<std::pair<std::uint32_t, std::uint32_t>> edges;
  for (std::size_t t = 0; t + 2 < idx.size(); t += 3) {
    for (int k = 0; k < 3; ++k) edges.insert(std::minmax(idx[t + k], idx[t + (k + 1) % 3]));
  }
  std::vector<Vec3d> lod_positions;
  for (const Vec3f& p : lod.positions) lod_positions.push_back(to_double(p));
  auto nearest = [&](const Vec3d& p, double tol) {
    std::uint32_t best = kInvalidIndex;
    double best_d = tol * tol;
    for (std::uint32_t w = 0; w < lod_positions.size(); ++w) {
      const Vec3d d = lod_positions[w] - p;
      const double dd = dot(d, d);
      if (dd <= best_d) {
        best_d = dd;
        best = w;
      }
    }
    return best;
  };
  std::size_t paired = 0;
  for (const auto& [a, b] : edges) {
    if (!in[a] || !in[b]) continue;
    ++out.region_edges;
    const Vec3d d = lod_positions[b] - lod_positions[a];
    const double tol = 0.01 * std::sqrt(dot(d, d));
    const std::uint32_t ma = nearest(plane.reflect(lod_positions[a]), tol);
    const std::uint32_t mb = nearest(plane.reflect(lod_positions[b]), tol);
    paired += ma != kInvalidIndex && mb != kInvalidIndex && ma != mb && edges.count(std::minmax(ma, mb)) > 0;
  }
  out.paired = out.region_edges == 0 ? 1.0 : static_cast<double>(paired) / static_cast<double>(out.region_edges);
  return out;
}

// Per ratio: the LOD without and with the symmetry term; targets as printed.
// `polychord`: the quad engine on the mesh as it is (quads kept), the figures on its LODs triangulated.
void run_simplify(const std::string& name, const Mesh& mesh, const std::vector<double>& ratios, double weight,
                  bool polychord, std::vector<std::string>& misses) {
  const symmetry::SymmetryMap s = symmetry::detect_symmetry(triangulated(mesh));
  if (!s.found()) {
    std::printf("%-34s no symmetry found: skipped\n", name.c_str());
    return;
  }
  const Mesh tris = triangulated(mesh);
  std::vector<char> region(tris.vertex_count(), 0);
  for (std::uint32_t v = 0; v < tris.vertex_count(); ++v) region[v] = s.vertex_mirror[v] != kInvalidIndex;
  const double diagonal = compute_bounds(tris).diagonal();
  const MirrorFigures input = mirror_figures(tris, tris, region, s.plane, diagonal);
  std::printf("%-34s %7zu tris  symmetric %.4f  input: mirror error %.5f%%, paired %.4f\n", name.c_str(),
              tris.triangle_count(), s.symmetric_fraction(), input.mirror_error, input.paired);
  for (double ratio : ratios) {
    const auto t0 = Clock::now();
    const Engine engine = polychord ? Engine::polychord : Engine::edge_collapse;
    const Mesh& source = polychord ? mesh : tris;
    const SimplifyResult plain = simplify(source, {.target_ratio = ratio, .engine = engine});
    const double plain_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    const auto t1 = Clock::now();
    const SimplifyResult sym = simplify(source, {.target_ratio = ratio, .engine = engine, .symmetry_weight = weight});
    const double sym_ms = std::chrono::duration<double, std::milli>(Clock::now() - t1).count();
    const Mesh plain_lod = triangulated(plain.mesh), sym_lod = triangulated(sym.mesh);
    const MirrorFigures a = mirror_figures(plain_lod, tris, region, s.plane, diagonal);
    const MirrorFigures b = mirror_figures(sym_lod, tris, region, s.plane, diagonal);
    const double mean_a = evaluate(tris, plain_lod).mean_rel() * 100, mean_b = evaluate(tris, sym_lod).mean_rel() * 100;
    const double mirror_limit = std::max(1.1 * input.mirror_error, 0.01);
    const bool ok_paired = b.paired >= 0.95, ok_mirror = b.mirror_error <= mirror_limit,
               ok_mean = mean_b <= 1.05 * mean_a;
    std::printf("  %3.0f%%  off: %6zu tris paired %.4f mirror %.5f%% mean %.5f%% %7.1f ms | weight %.1f: %6zu tris "
                "paired %.4f %s mirror %.5f%% (<= %.5f) %s mean %.5f%% (%.3fx) %s %7.1f ms\n",
                100 * ratio, plain.triangles_after, a.paired, a.mirror_error, mean_a, plain_ms, weight,
                sym.triangles_after, b.paired, ok_paired ? "MET" : "NOT MET", b.mirror_error, mirror_limit,
                ok_mirror ? "MET" : "NOT MET", mean_b, mean_a > 0 ? mean_b / mean_a : 1.0, ok_mean ? "MET" : "NOT MET",
                sym_ms);
    char what[160];
    if (!ok_paired || !ok_mirror || !ok_mean) {
      std::snprintf(what, sizeof what, "%s at %.0f%%:%s%s%s", name.c_str(), 100 * ratio, ok_paired ? "" : " paired",
                    ok_mirror ? "" : " mirror", ok_mean ? "" : " mean");
      misses.push_back(what);
    }
  }
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
  bool simplify_mode = false;
  double weight = 1.0;
  double noise = 1e-6;
  app.add_flag("--simplify", simplify_mode,
               "symmetric simplification instead: per mesh at 50% and 25%, the LOD without and with the symmetry "
               "term (paired fraction >= 0.95, mirror error <= max(1.1x the input's, 0.01% of the diagonal), mean "
               "distance <= 1.05x without); the default meshes then are the symmetric corpus meshes and scans "
               "mirrored from one half with noise");
  app.add_option("--weight", weight, "symmetry_weight of the runs with the term");
  app.add_option("--noise", noise, "noise on the mirrored scans, a fraction of the diagonal");
  std::string engine = "edge_collapse";
  app.add_option("--engine", engine,
                 "with --simplify: edge_collapse, or polychord (the quad engine; the default meshes then are the "
                 "quad corpus meshes, without the mirrored scans)")
      ->check(CLI::IsMember({"edge_collapse", "polychord"}));
  CLI11_PARSE(app, argc, argv);
  if (simplify_mode) {
    const tbb::global_control one(tbb::global_control::max_allowed_parallelism,
                                  threads > 0 ? static_cast<std::size_t>(threads) : tbb::this_task_arena::max_concurrency());
    const std::vector<double> ratios = {0.5, 0.25};
    std::vector<std::string> misses;
    const bool polychord = engine == "polychord";
    if (app.count("files") == 0) {
      files = {"quad/makehuman_base_hm08.obj", "quad/makehuman_male_generic.obj", "quad/makehuman_proxy741.obj",
               "quad/spot_quadrangulated.obj", "quad/blub_quadrangulated.obj"};
      if (polychord) files.push_back("quad/suzanne.obj");
      for (const char* scan : {"scanned/stanford-bunny.obj", "scanned/armadillo-remeshed-29k.obj"}) {
        if (polychord) break;
        try {
          run_simplify(std::string(scan) + " mirrored", mirrored_half(io::load_asset(corpus + "/" + scan).meshes.at(0), noise),
                       ratios, weight, polychord, misses);
        } catch (const std::exception& e) {
          std::printf("%-34s skipped: %s\n", scan, e.what());
        }
      }
    }
    for (const std::string& f : files) {
      try {
        run_simplify(f, io::load_asset(corpus + "/" + f).meshes.at(0), ratios, weight, polychord, misses);
      } catch (const std::exception& e) {
        std::printf("%-34s skipped: %s\n", f.c_str(), e.what());
      }
    }
    std::printf("targets: %zu miss(es)%s\n", misses.size(), misses.empty() ? ": all MET" : "");
    for (const std::string& m : misses) std::printf("  NOT MET: %s\n", m.c_str());
    return 0;
  }
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
