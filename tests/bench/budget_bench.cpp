// lodforge_bench_budget: how well error budgets are held. For each mesh and budget (a fraction of the bounding-box
// diagonal), the LOD simplify() returns with that budget and target_ratio 0.0001 (so the budget stops it) is
// compared with:
//  - its reported bound (SimplifyResult::error_bound_abs) against the measured one-sided Hausdorff distance
//    LOD → source (eval, many samples): the bound must hold (bound >= measured) and be tight (bound / measured
//    <= 3, geometric mean over all cases); the symmetric Hausdorff must stay within budget × 1.1 (eval's
//    sampling tolerance);
//  - the oracle: the longest prefix of the same collapse sequence all of whose shorter prefixes meet the budget
//    by measurement (symmetric Hausdorff, eval), found by a scan at a coarse stride then a finer one; target:
//    held triangles <= 1.25 × oracle triangles;
//  - meshoptimizer: the fewest triangles at which meshopt_simplify's output meets the budget by measurement
//    (bisection on its target count); target: held triangles <= 1.5 × that.
// Meshes are taken as geometry: every mesh of an asset, triangulated, without attributes, concatenated, with
// repeated faces removed (simplify() drops them first anyway), so that all three see the same surface.
// Prints a table and MET / NOT MET lines; always exits 0 (a benchmark, not a test).
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "engines.hpp"
#include "lodforge/core/mesh.hpp"
#include "meshopt_peer.hpp"
#include "lodforge/eval/eval.hpp"
#include "lodforge/io/asset.hpp"
#include "lodforge/simplify/simplify.hpp"

namespace fs = std::filesystem;
using namespace lodforge;

namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

constexpr double kTightnessTarget = 3.0;   // reported bound / measured LOD → source, geometric mean
constexpr double kSamplingTolerance = 1.1; // symmetric Hausdorff by eval may exceed the budget by this factor
constexpr double kOracleTarget = 1.25;     // held triangles / oracle triangles
constexpr double kMeshoptTarget = 1.5;     // held triangles / meshopt triangles
// Distances below this fraction of the diagonal are rounding (a LOD equal to its source measures ~1e-9, not 0).
constexpr double kZero = 1e-6;

// One wedge per vertex, triangles only, one material: the geometry every method sees. glTF meshes stay in their
// own coordinates (node transforms are not applied): it is a test surface, not the scene.
Mesh geometry_of(const io::Asset& asset) {
  Mesh g;
  g.materials.push_back(MaterialSlot{.name = "default"});
  for (const Mesh& m : asset.meshes) {
    const auto base = static_cast<std::uint32_t>(g.positions.size());
    for (const Vec3f& p : m.positions) g.add_vertex_with_wedge(p);
    for (std::size_t f = 0; f < m.face_count(); ++f) {
      if (!face_indices_in_range(m, f)) continue;
      for_each_face_triangle(m, f, [&](std::uint32_t a, std::uint32_t b, std::uint32_t c) {
        g.add_face({base + m.corner_vertex(a), base + m.corner_vertex(b), base + m.corner_vertex(c)});
      });
    }
  }
  return g;
}

std::vector<std::uint32_t> vertex_indices(const Mesh& m) {
  std::vector<std::uint32_t> idx;
  idx.reserve(m.corner_count());
  for (std::size_t c = 0; c < m.corner_count(); ++c) idx.push_back(m.corner_vertex(c));
  return idx;
}

// Replays a collapse log on a working mesh the way the budget back-off does (same check and commit).
class Replay {
 public:
  Replay(const Mesh& triangles, const SimplifyOptions& options, collapse::Parallel& parallel,
         const std::vector<collapse::CollapseRecord>& log)
      : cm_(triangles, options, parallel), log_(&log) {}
  // Applies records up to prefix `to` (>= the current one); false if a record no longer applies.
  bool advance(std::size_t to) {
    for (; at_ < to; ++at_) {
      const collapse::CollapseRecord& r = (*log_)[at_];
      collapse::Check c = cm_.check(r.u, r.v, r.position, scratch_);
      if (!c.ok()) return false;
      cm_.commit(c, r.position, scratch_);
    }
    return true;
  }
  std::size_t at() const { return at_; }
  std::size_t triangles() const { return cm_.alive_faces(); }
  Mesh output() const { return cm_.output(); }

 private:
  collapse::CollapseMesh cm_;
  const std::vector<collapse::CollapseRecord>* log_;
  collapse::Scratch scratch_;
  std::size_t at_ = 0;
};

struct Case {
  std::string mesh;
  double budget = 0;        // fraction of the diagonal
  double diagonal = 0;
  std::size_t source_tris = 0;
  std::size_t held_tris = 0, held_collapses = 0, log_size = 0;
  std::size_t guard_reruns = 0, collapses_undone = 0;
  double bound = 0;         // reported, model units
  bool certified = false, within = false;
  StopReason stop = StopReason::target_reached;
  double verify_ms = 0, total_ms = 0;
  double lod_to_src = 0, hausdorff = 0;  // measured, model units
  bool oracle_run = false;
  std::size_t oracle_tris = 0, oracle_prefix = 0, prefixes_measured = 0;
  bool oracle_at_log_end = false;  // every prefix measured held: the engine's own stop limited the oracle
  bool replay_failed = false;
  bool same_sequence = true;       // the held LOD's prefix of this log has the held LOD's triangle count
  double oracle_ms = 0;
  std::size_t meshopt_tris = 0;
  double meshopt_ms = 0;
};

bool violates(const Case& c) { return c.bound < c.lod_to_src - kZero * c.diagonal; }
// bound / measured means nothing where the LOD lies on its source (measured 0).
bool has_ratio(const Case& c) { return c.lod_to_src > kZero * c.diagonal; }

double geomean(const std::vector<double>& v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  double s = 0;
  for (double x : v) s += std::log(x);
  return std::exp(s / static_cast<double>(v.size()));
}

struct Settings {
  std::size_t eval_samples = 1'000'000;
  std::size_t scan_samples = 0;
  std::size_t coarse_steps = 64, fine_steps = 512;
  int meshopt_steps = 12;
  double oracle_max_budget = 0.01;
};

// Symmetric Hausdorff within the budget by eval (scan sample count).
bool meets(const Mesh& src, const Mesh& lod, double budget_abs, const Settings& s) {
  return evaluate(src, lod, EvalOptions{.samples = s.scan_samples}).hausdorff <= budget_abs;
}

void run_oracle(Case& c, const Mesh& src, const SimplifyOptions& options, const Settings& s) {
  const auto t0 = Clock::now();
  const double budget_abs = c.budget * c.diagonal;
  // The engine run simplify() logs and backs off along (guarded, as simplify() runs it): same triangles, same
  // options.
  std::vector<collapse::CollapseRecord> log;
  (void)collapse::run_within_budget(collapse::run_edge_collapse, src, options, {}, true, true, &log);
  c.log_size = log.size();
  collapse::Parallel parallel(options.threads);
  SimplifyOptions replay_options = options;
  replay_options.max_error_abs = replay_options.max_error_rel = -1.0;
  const std::size_t n = log.size();
  const std::size_t coarse = std::max<std::size_t>(1, n / s.coarse_steps);
  const std::size_t fine = std::max<std::size_t>(1, n / s.fine_steps);

  Replay walk(src, replay_options, parallel, log);
  std::optional<Replay> last_pass;  // the working mesh at the last coarse prefix that held
  std::size_t pass_prefix = 0, pass_tris = src.triangle_count();
  std::size_t fail_prefix = n + 1;  // none failed
  last_pass.emplace(walk);
  while (walk.at() < n) {
    const std::size_t next = std::min(n, walk.at() + coarse);
    if (!walk.advance(next)) {
      c.replay_failed = true;
      fail_prefix = next;
      break;
    }
    ++c.prefixes_measured;
    if (!meets(src, walk.output(), budget_abs, s)) {
      fail_prefix = next;
      break;
    }
    pass_prefix = next;
    pass_tris = walk.triangles();
    last_pass.emplace(walk);
  }
  if (fail_prefix <= n && fail_prefix - pass_prefix > 1) {
    // The last coarse interval, at the finer stride: stop at the first prefix that fails.
    Replay& w = *last_pass;
    while (w.at() + fine < fail_prefix) {
      if (!w.advance(w.at() + fine)) {
        c.replay_failed = true;
        break;
      }
      ++c.prefixes_measured;
      if (!meets(src, w.output(), budget_abs, s)) break;
      pass_prefix = w.at();
      pass_tris = w.triangles();
    }
  }
  // The held LOD must be a prefix of this very sequence for the comparison to mean anything.
  Replay held(src, replay_options, parallel, log);
  c.same_sequence = c.held_collapses <= n && held.advance(c.held_collapses) && held.triangles() == c.held_tris;
  c.oracle_at_log_end = fail_prefix > n;
  c.oracle_prefix = pass_prefix;
  c.oracle_tris = pass_tris;
  c.oracle_run = true;
  c.oracle_ms = ms_since(t0);
}

void run_meshopt_search(Case& c, const Mesh& src, const Settings& s) {
  const auto t0 = Clock::now();
  const double budget_abs = c.budget * c.diagonal;
  const std::vector<std::uint32_t> indices = vertex_indices(src);
  // lo: a target count assumed to fail, hi: one that holds (the source itself); bisection in log space.
  double lo = 1, hi = static_cast<double>(src.triangle_count());
  std::size_t hi_tris = src.triangle_count();
  for (int step = 0; step < s.meshopt_steps; ++step) {
    const auto mid = static_cast<std::size_t>(std::llround(std::sqrt(lo * hi)));
    if (mid <= static_cast<std::size_t>(lo) || mid >= static_cast<std::size_t>(hi)) break;
    const Mesh out = bench::meshopt_lod(src, indices, mid);
    if (meets(src, out, budget_abs, s)) {
      hi = static_cast<double>(mid);
      hi_tris = out.triangle_count();
    } else {
      lo = static_cast<double>(mid);
    }
  }
  c.meshopt_tris = hi_tris;
  c.meshopt_ms = ms_since(t0);
}

void run_case(Case& c, const Mesh& src, const Settings& s) {
  const SimplifyOptions options{.target_ratio = 0.0001, .max_error_rel = c.budget};
  const auto t0 = Clock::now();
  const SimplifyResult r = simplify(src, options);
  c.total_ms = ms_since(t0);
  c.held_tris = r.triangles_after;
  c.held_collapses = r.collapses;
  c.bound = r.error_bound_abs;
  c.certified = r.budget.certified;
  c.within = r.budget.within;
  c.guard_reruns = r.budget.guard_reruns;
  c.collapses_undone = r.budget.collapses_undone;
  c.verify_ms = r.budget.ms;
  c.stop = r.stop_reason;
  const EvalResult e = evaluate(src, r.mesh, EvalOptions{.samples = s.eval_samples});
  c.lod_to_src = e.b_to_a.max;
  c.hausdorff = e.hausdorff;
  if (c.budget <= s.oracle_max_budget) {
    run_oracle(c, src, options, s);
    run_meshopt_search(c, src, s);
  }
}

std::string fmt(const char* f, double x) {
  char b[64];
  std::snprintf(b, sizeof b, f, x);
  return b;
}

void print_header() {
  std::printf("%-26s %7s %7s %7s %7s %6s %7s %6s %9s %9s %6s %8s %5s %8s %8s %8s %8s %s\n", "mesh", "budget%", "src",
              "held", "oracle", "h/or", "meshopt", "h/mo", "bound%", "lod>src%", "b/m", "sym/bud", "cert", "verifyms",
              "totalms", "oracle_s", "mopt_s", "notes");
}

void print_case(const Case& c) {
  const double d = c.diagonal;
  std::string notes = std::string("stop ") + stop_reason_name(c.stop) + " ";
  if (violates(c)) notes += "VIOLATION(bound<measured) ";
  if (c.hausdorff > kSamplingTolerance * c.budget * d) notes += "OVER-BUDGET ";
  if (!c.within) notes += "not-within ";
  if (c.guard_reruns > 0) notes += "reruns " + std::to_string(c.guard_reruns) + " ";
  if (c.collapses_undone > 0) notes += "backed-off " + std::to_string(c.collapses_undone) + " ";
  if (c.oracle_at_log_end) notes += "oracle=log-end ";
  if (c.replay_failed) notes += "REPLAY-FAILED ";
  if (c.oracle_run && !c.same_sequence) notes += "SEQUENCE-MISMATCH ";
  if (c.oracle_run) notes += "prefix held " + std::to_string(c.held_collapses) + " oracle " +
                             std::to_string(c.oracle_prefix) + " of " + std::to_string(c.log_size) + " (" +
                             std::to_string(c.prefixes_measured) + " measured)";
  std::printf("%-26s %7.3f %7zu %7zu %7s %6s %7s %6s %9.5f %9.5f %6s %8.3f %5s %8.1f %8.1f %8.1f %8.1f %s\n",
              c.mesh.c_str(),
              100 * c.budget, c.source_tris, c.held_tris,
              c.oracle_run ? std::to_string(c.oracle_tris).c_str() : "-",
              c.oracle_run && c.oracle_tris > 0 ? fmt("%.3f", double(c.held_tris) / c.oracle_tris).c_str() : "-",
              c.oracle_run ? std::to_string(c.meshopt_tris).c_str() : "-",
              c.oracle_run && c.meshopt_tris > 0 ? fmt("%.3f", double(c.held_tris) / c.meshopt_tris).c_str() : "-",
              100 * c.bound / d, 100 * c.lod_to_src / d,
              has_ratio(c) ? fmt("%.2f", c.bound / c.lod_to_src).c_str() : "-", c.hausdorff / (c.budget * d),
              c.certified ? "yes" : "no", c.verify_ms, c.total_ms, c.oracle_ms / 1000, c.meshopt_ms / 1000,
              notes.c_str());
  std::fflush(stdout);
}

// Mesh files under the corpus's scanned/ and hardsurface/ folders.
std::vector<std::string> corpus_meshes(const fs::path& corpus) {
  static const std::set<std::string> kExt = {".obj", ".ply", ".off", ".stl", ".gltf", ".glb"};
  std::vector<std::string> files;
  for (const char* sub : {"scanned", "hardsurface"}) {
    std::error_code ec;
    for (fs::recursive_directory_iterator it(corpus / sub, ec), end; !ec && it != end; it.increment(ec)) {
      std::string ext = it->path().extension().string();
      std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char ch) { return std::tolower(ch); });
      if (it->is_regular_file() && kExt.contains(ext)) files.push_back(it->path().string());
    }
  }
  std::sort(files.begin(), files.end());
  return files;
}

}  // namespace

int main(int argc, char** argv) {
  std::string corpus = LODFORGE_BENCH_CORPUS_DIR;
  std::vector<std::string> mesh_files;
  std::vector<double> budgets{0.0005, 0.002, 0.01, 0.05};
  bool quick = false;
  Settings s;
  CLI::App app{"lodforge_bench_budget: error budgets against measurement, the prefix oracle and meshoptimizer"};
  app.add_option("--corpus", corpus, "corpus folder (its scanned/ and hardsurface/ meshes)")->capture_default_str();
  app.add_option("--mesh", mesh_files, "mesh file(s) to run instead of the corpus (repeatable)");
  auto* budgets_opt = app.add_option("--budgets", budgets, "budgets, fractions of the bounding-box diagonal")
                          ->delimiter(',')
                          ->capture_default_str();
  app.add_flag("--quick", quick,
               "bunny, fandisk, armadillo-remeshed-29k, wingnut at 0.0005,0.002,0.01 (unless --budgets/--mesh)");
  app.add_option("--eval-samples", s.eval_samples, "area samples per direction measuring the held LOD")
      ->capture_default_str();
  app.add_option("--scan-samples", s.scan_samples,
                 "area samples per direction for the oracle and meshopt searches (0 = eval's default)")
      ->capture_default_str();
  app.add_option("--coarse-steps", s.coarse_steps, "oracle scan: coarse stride = log / this")->capture_default_str()
      ->check(CLI::Range(1, 100000));
  app.add_option("--fine-steps", s.fine_steps, "oracle scan: fine stride = log / this")->capture_default_str()
      ->check(CLI::Range(1, 1000000));
  app.add_option("--meshopt-steps", s.meshopt_steps, "bisection steps on meshopt's target count")
      ->capture_default_str();
  app.add_option("--oracle-max-budget", s.oracle_max_budget,
                 "oracle and meshopt searches only for budgets up to this")->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  if (mesh_files.empty()) {
    mesh_files = corpus_meshes(corpus);
    if (quick) {
      static const std::set<std::string> kQuick = {"stanford-bunny", "fandisk", "armadillo-remeshed-29k", "wingnut"};
      std::erase_if(mesh_files, [](const std::string& f) { return !kQuick.contains(fs::path(f).stem().string()); });
    }
  }
  if (quick && budgets_opt->count() == 0) budgets = {0.0005, 0.002, 0.01};
  if (mesh_files.empty()) {
    std::fprintf(stderr, "no meshes found (corpus %s)\n", corpus.c_str());
    return 0;
  }

  std::printf("budgets as %% of the bounding-box diagonal; bound = reported error bound, lod>src = measured one-sided "
              "Hausdorff LOD -> source (%zu samples), sym/bud = symmetric Hausdorff / budget; oracle and meshopt "
              "for budgets <= %.3f%%\n\n",
              s.eval_samples, 100 * s.oracle_max_budget);
  print_header();
  std::vector<Case> cases;
  for (const std::string& f : mesh_files) {
    Mesh src;
    std::size_t repeats = 0;
    try {
      src = geometry_of(io::load_asset(f));
      const std::vector<std::uint32_t> rep = repeated_faces(src);
      repeats = rep.size();
      if (!rep.empty()) src = without_faces(src, rep);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "skipping %s: %s\n", f.c_str(), e.what());
      continue;
    }
    if (src.triangle_count() == 0) continue;
    if (repeats > 0) std::printf("(%s: %zu repeated faces removed)\n", fs::path(f).stem().string().c_str(), repeats);
    const double diagonal = compute_bounds(src).diagonal();
    for (double budget : budgets) {
      Case c{.mesh = fs::path(f).stem().string(), .budget = budget, .diagonal = diagonal,
             .source_tris = src.triangle_count()};
      try {
        run_case(c, src, s);
      } catch (const std::exception& e) {
        std::fprintf(stderr, "%s at %g failed: %s\n", c.mesh.c_str(), budget, e.what());
        continue;
      }
      print_case(c);
      cases.push_back(c);
    }
  }

  // Summary.
  std::vector<double> tightness, oracle_ratio, meshopt_ratio, over;
  std::size_t violations = 0, over_tolerance = 0, uncertified = 0, mismatches = 0;
  const Case* worst_tight = nullptr;
  const Case* worst_oracle = nullptr;
  const Case* worst_meshopt = nullptr;
  const Case* worst_over = nullptr;
  for (const Case& c : cases) {
    if (violates(c)) ++violations;
    if (!c.certified) ++uncertified;
    if (c.oracle_run && !c.same_sequence) ++mismatches;
    const double o = c.hausdorff / (c.budget * c.diagonal);
    if (o > kZero) over.push_back(o);  // a LOD equal to its source has no ratio to average
    if (o > kSamplingTolerance) ++over_tolerance;
    if (!worst_over || o > worst_over->hausdorff / (worst_over->budget * worst_over->diagonal)) worst_over = &c;
    if (has_ratio(c)) {
      tightness.push_back(c.bound / c.lod_to_src);
      if (!worst_tight || c.bound / c.lod_to_src > worst_tight->bound / worst_tight->lod_to_src) worst_tight = &c;
    }
    if (c.oracle_run && c.oracle_tris > 0) {
      const double r = double(c.held_tris) / c.oracle_tris;
      oracle_ratio.push_back(r);
      if (!worst_oracle || r > double(worst_oracle->held_tris) / worst_oracle->oracle_tris) worst_oracle = &c;
    }
    if (c.oracle_run && c.meshopt_tris > 0) {
      const double r = double(c.held_tris) / c.meshopt_tris;
      meshopt_ratio.push_back(r);
      if (!worst_meshopt || r > double(worst_meshopt->held_tris) / worst_meshopt->meshopt_tris) worst_meshopt = &c;
    }
  }
  auto name = [](const Case* c) { return c ? c->mesh + " at " + fmt("%.3g%%", 100 * c->budget) : std::string("-"); };
  auto verdict = [](bool met) { return met ? "MET    " : "NOT MET"; };
  std::printf("\n%zu cases; bound certified in %zu; held LOD not a prefix of the replayed sequence in %zu\n",
              cases.size(), cases.size() - uncertified, mismatches);
  std::printf("%s reported bound >= measured LOD->source in every case: %zu violation(s)\n", verdict(violations == 0),
              violations);
  const double gt = geomean(tightness);
  std::printf("%s bound / measured <= %.1f (geometric mean over %zu cases): %.3f; worst %.3f (%s)\n",
              verdict(gt <= kTightnessTarget), kTightnessTarget, tightness.size(), gt,
              worst_tight ? worst_tight->bound / worst_tight->lod_to_src : 0.0, name(worst_tight).c_str());
  std::printf("%s symmetric Hausdorff <= budget x %.1f in every case: %zu over; worst %.3f x budget (%s), geometric "
              "mean %.3f\n",
              verdict(over_tolerance == 0), kSamplingTolerance, over_tolerance,
              worst_over ? worst_over->hausdorff / (worst_over->budget * worst_over->diagonal) : 0.0,
              name(worst_over).c_str(), geomean(over));
  if (!oracle_ratio.empty()) {
    const double go = geomean(oracle_ratio);
    const double wo = double(worst_oracle->held_tris) / worst_oracle->oracle_tris;
    std::printf("%s held / oracle triangles <= %.2f in every case (%zu cases): worst %.3f (%s); geometric mean %.3f "
                "(%s)\n",
                verdict(wo <= kOracleTarget), kOracleTarget, oracle_ratio.size(), wo, name(worst_oracle).c_str(), go,
                go <= kOracleTarget ? "met" : "not met");
  }
  if (!meshopt_ratio.empty()) {
    const double gm = geomean(meshopt_ratio);
    const double wm = double(worst_meshopt->held_tris) / worst_meshopt->meshopt_tris;
    std::printf("%s held / meshopt triangles <= %.2f in every case (%zu cases): worst %.3f (%s); geometric mean %.3f "
                "(%s)\n",
                verdict(wm <= kMeshoptTarget), kMeshoptTarget, meshopt_ratio.size(), wm, name(worst_meshopt).c_str(),
                gm, gm <= kMeshoptTarget ? "met" : "not met");
  }
  return 0;
}
