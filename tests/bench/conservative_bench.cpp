// lodforge_bench_conservative: conservative LODs (SimplifyOptions::conservative) on the closed scanned corpus.
//
// How each number is taken, per mesh, at --ratio of the triangles (default 2%):
// - Bounding: volume overhead = LOD volume / source volume − 1 (signed tetrahedra volumes), against the naive
//   hull: the unconstrained LOD at the same ratio moved outward along its (area-weighted) vertex normals by its
//   own one-sided Hausdorff distance source → LOD (lodforge::evaluate, sampled). Target: the bounding LOD's
//   overhead at most 0.5× the naive one.
// - Occluder: silhouette kept = pixels the occluder LOD covers / pixels the source covers, summed over the six
//   axis views, each rasterised orthographically on a --raster² grid framing the source's box (pixel centres
//   inside a triangle's projection count). Target: at least 90%.
// - Time: wall clock of each simplify() call, all threads.
// Printed as a table with MET / NOT MET; the exit status is 0 whatever they say.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "lodforge/core/mesh.hpp"
#include "lodforge/core/volume.hpp"
#include "lodforge/eval/eval.hpp"
#include "lodforge/io/asset.hpp"
#include "lodforge/simplify/simplify.hpp"

namespace {

using lodforge::Mesh;
using lodforge::Vec3d;
using Clock = std::chrono::steady_clock;
namespace fs = std::filesystem;

constexpr double kVolumeTarget = 0.5;       // bounding overhead / naive overhead, at most
constexpr double kSilhouetteTarget = 0.90;  // occluder silhouette kept, at least

// The closed scanned meshes of the corpus (happy-buddha has non-manifold edges, bunny, demosthenes and the
// SMPL-X body are open).
const char* const kClosedScans[] = {
    "scanned/armadillo-remeshed-29k.obj", "scanned/boot-40k.obj",   "scanned/hammer-60k.obj",
    "scanned/nefertiti-70k.obj",          "scanned/armadillo-86k.obj", "scanned/lucy-100k.ply",
    "scanned/dragon-100k.obj",
};

Vec3d pos(const Mesh& m, std::size_t corner) { return lodforge::to_double(m.positions[m.corner_vertex(corner)]); }

// `m` with every vertex moved by `d` along its area-weighted normal.
Mesh offset(Mesh m, double d) {
  std::vector<Vec3d> n(m.vertex_count(), Vec3d{});
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    const std::uint32_t c = m.face_offsets[f];
    for (std::uint32_t k = 1; k + 1 < m.face_size(f); ++k) {
      const Vec3d fn = lodforge::cross(pos(m, c + k) - pos(m, c), pos(m, c + k + 1) - pos(m, c));
      for (std::uint32_t j : {0u, k, k + 1}) n[m.corner_vertex(c + j)] = n[m.corner_vertex(c + j)] + fn;
    }
  }
  for (std::size_t v = 0; v < m.vertex_count(); ++v) {
    const double len = lodforge::length(n[v]);
    if (len > 0.0) m.positions[v] = lodforge::to_float(lodforge::to_double(m.positions[v]) + n[v] * (d / len));
  }
  return m;
}

// Covered pixels of `m` in the orthographic view along `axis` (the sign flips the image, not the count), on a
// res² grid over the box [lo, hi] of the other two axes.
std::size_t covered_pixels(const Mesh& m, int axis, bool flip, const Vec3d& lo, const Vec3d& hi, int res) {
  const int ua = (axis + 1) % 3, va = (axis + 2) % 3;
  const double extent = std::max(hi[ua] - lo[ua], hi[va] - lo[va]) * 1.02;
  const double cu = 0.5 * (lo[ua] + hi[ua]), cv = 0.5 * (lo[va] + hi[va]);
  std::vector<char> px(std::size_t(res) * res, 0);
  auto to_px = [&](const Vec3d& p, double& x, double& y) {
    x = ((p[ua] - cu) / extent + 0.5) * res;
    y = ((p[va] - cv) / extent + 0.5) * res;
    if (flip) x = res - x;
  };
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    const std::uint32_t c = m.face_offsets[f];
    for (std::uint32_t k = 1; k + 1 < m.face_size(f); ++k) {
      double x[3], y[3];
      to_px(pos(m, c), x[0], y[0]);
      to_px(pos(m, c + k), x[1], y[1]);
      to_px(pos(m, c + k + 1), x[2], y[2]);
      const int x0 = std::max(0, int(std::floor(std::min({x[0], x[1], x[2]}))));
      const int x1 = std::min(res - 1, int(std::ceil(std::max({x[0], x[1], x[2]}))));
      const int y0 = std::max(0, int(std::floor(std::min({y[0], y[1], y[2]}))));
      const int y1 = std::min(res - 1, int(std::ceil(std::max({y[0], y[1], y[2]}))));
      for (int py = y0; py <= y1; ++py) {
        for (int pxl = x0; pxl <= x1; ++pxl) {
          const double qx = pxl + 0.5, qy = py + 0.5;
          double e[3];
          for (int i = 0; i < 3; ++i) {
            const int j = (i + 1) % 3;
            e[i] = (x[j] - x[i]) * (qy - y[i]) - (y[j] - y[i]) * (qx - x[i]);
          }
          const bool in = (e[0] >= 0 && e[1] >= 0 && e[2] >= 0) || (e[0] <= 0 && e[1] <= 0 && e[2] <= 0);
          if (in) px[std::size_t(py) * res + pxl] = 1;
        }
      }
    }
  }
  std::size_t n = 0;
  for (char p : px) n += p;
  return n;
}

double silhouette_kept(const Mesh& src, const Mesh& lod, int res) {
  const lodforge::Bounds3 b = lodforge::compute_bounds(src);
  std::size_t a = 0, l = 0;
  for (int axis = 0; axis < 3; ++axis) {
    for (bool flip : {false, true}) {
      a += covered_pixels(src, axis, flip, b.min, b.max, res);
      l += covered_pixels(lod, axis, flip, b.min, b.max, res);
    }
  }
  return a > 0 ? double(l) / double(a) : 0.0;
}

double ms_since(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"conservative LODs: bounding volume overhead vs the naive offset hull, occluder silhouettes"};
  std::string corpus = LODFORGE_BENCH_CORPUS_DIR;
  std::vector<std::string> files;
  double ratio = 0.02;
  int raster = 512;
  app.add_option("--corpus", corpus, "corpus folder");
  app.add_option("--file", files, "a mesh (repeatable; default: the closed scanned meshes of the corpus)");
  app.add_option("--ratio", ratio, "target fraction of the triangles")->default_val(ratio);
  app.add_option("--raster", raster, "silhouette grid size per view")->default_val(raster);
  CLI11_PARSE(app, argc, argv);
  if (files.empty()) {
    for (const char* f : kClosedScans) {
      if (fs::exists(fs::path(corpus) / f)) files.push_back((fs::path(corpus) / f).string());
    }
  }
  if (files.empty()) {
    std::printf("no corpus meshes found under %s: nothing to measure\n", corpus.c_str());
    return 0;
  }
  std::printf("ratio %.3f, silhouettes on %d^2 per view (6 axis views)\n\n", ratio, raster);
  std::printf("%-26s %7s | %6s %9s %9s %7s %6s | %6s %8s %6s | %8s %8s %8s\n", "mesh", "tris", "LOD", "naive+%",
              "bound+%", "ratio", "", "LOD", "silh.%", "", "plain ms", "bound ms", "occl ms");
  std::size_t volume_met = 0, silhouette_met = 0;
  double log_ratio = 0.0, silhouette_sum = 0.0;
  for (const std::string& file : files) {
    Mesh src = lodforge::io::load_asset(file).meshes.at(0);
    const double v0 = lodforge::signed_volume(src);
    auto t = Clock::now();
    const lodforge::SimplifyResult plain = lodforge::simplify(src, {.target_ratio = ratio});
    const double plain_ms = ms_since(t);
    const lodforge::EvalResult e = lodforge::evaluate(src, plain.mesh, lodforge::EvalOptions{});
    const double naive = lodforge::signed_volume(offset(plain.mesh, e.a_to_b.max)) / v0 - 1.0;
    t = Clock::now();
    const lodforge::SimplifyResult bound =
        lodforge::simplify(src, {.target_ratio = ratio, .conservative = lodforge::Conservative::bounding});
    const double bound_ms = ms_since(t);
    const double overhead = lodforge::signed_volume(bound.mesh) / v0 - 1.0;
    t = Clock::now();
    const lodforge::SimplifyResult occl =
        lodforge::simplify(src, {.target_ratio = ratio, .conservative = lodforge::Conservative::occluder});
    const double occl_ms = ms_since(t);
    const double kept = silhouette_kept(src, occl.mesh, raster);
    const double r = naive > 0.0 ? overhead / naive : INFINITY;
    const bool vmet = r <= kVolumeTarget, smet = kept >= kSilhouetteTarget;
    volume_met += vmet;
    silhouette_met += smet;
    log_ratio += std::log(r);
    silhouette_sum += kept;
    std::printf("%-26s %7zu | %6zu %9.2f %9.2f %7.3f %6s | %6zu %8.2f %6s | %8.0f %8.0f %8.0f\n",
                fs::path(file).filename().string().c_str(), src.triangle_count(), bound.triangles_after,
                100.0 * naive, 100.0 * overhead, r, vmet ? "MET" : "NOT", occl.triangles_after, 100.0 * kept,
                smet ? "MET" : "NOT", plain_ms, bound_ms, occl_ms);
    std::fflush(stdout);
  }
  const double n = double(files.size());
  std::printf("\nbounding overhead / naive overhead: geomean %.3f, target <= %.2f met on %zu of %zu meshes\n",
              std::exp(log_ratio / n), kVolumeTarget, volume_met, files.size());
  std::printf("occluder silhouette kept: mean %.2f%%, target >= %.0f%% met on %zu of %zu meshes\n",
              100.0 * silhouette_sum / n, 100.0 * kSilhouetteTarget, silhouette_met, files.size());
  return 0;
}
