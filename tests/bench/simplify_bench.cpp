// lodforge_bench_simplify: lodforge's simplifier against its peers, meshoptimizer (meshopt_simplify) and the
// OpenMesh Decimater (ModQuadricT + ModNormalFlippingT), on the scanned corpus, a generated ~2M-triangle mesh and a
// generated flat CAD-like plate (and, with --terrain, a generated 16.8M-triangle fBm terrain at 1%), at several
// ratios; lodforge's multiple_choice engine (lodforge-mc) against its default engine. Meshes of 1M triangles and
// more also run two lodforge-1t processes at once: the two-thread ceiling of the machine, printed beside
// lodforge's own two-thread scaling. Per run: output triangles, time, input triangles per second, peak memory per input triangle
// and Metro-style quality from lodforge::evaluate. Prints a table, writes the same as JSON, and checks the
// performance contract (docs/performance.md) target by target: MET / NOT MET.
//
// How each number is taken (the same way for every method):
// - Input: every mesh is reduced to geometry (welded positions + triangles, attributes dropped), because the
//   peers simplify positions only; all methods get the same vertex array and triangle list.
// - Isolation: every (mesh, ratio, method) runs in its own forked child. The parent loads and generates meshes
//   (io uses no TBB) and never starts TBB itself, so each child begins with a fresh scheduler and a clean heap,
//   and a crash or hang (timeout) of one run is recorded in its row instead of ending the benchmark.
// - Time: wall clock of the simplification call on the method's own input representation: lodforge::Mesh ->
//   SimplifyResult; index + position arrays -> index array (meshopt); an OpenMesh TriMesh with face normals ->
//   decimated, garbage-collected TriMesh (building the TriMesh is not timed). Best of up to --reps repetitions,
//   stopping early once the repetitions add up to --rep-budget seconds (so big meshes run once).
// - Memory: in the child, malloc_trim(0), read VmRSS, reset VmHWM to it (/proc/self/clear_refs "5"), run once,
//   read VmHWM: peak RSS during the call minus RSS before it, divided by the input triangles.
// - Quality: lodforge::evaluate(input, output) with --eval-samples area samples per direction plus all vertices of
//   both meshes (the published bunny protocol uses 1M); outputs are compacted (unreferenced vertices removed)
//   first. lodforge with threads=all is evaluated only when its output differs from threads=1 (determinism check).
#include <malloc.h>
#include <meshoptimizer.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <tbb/parallel_for.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Core/System/omstream.hh>
#include <OpenMesh/Tools/Decimater/DecimaterT.hh>
#include <OpenMesh/Tools/Decimater/ModNormalFlippingT.hh>
#include <OpenMesh/Tools/Decimater/ModQuadricT.hh>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>
#include <numeric>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <unordered_map>
#include <vector>

#include "lodforge/core/mesh.hpp"
#include "lodforge/eval/eval.hpp"
#include "lodforge/io/asset.hpp"
#include "lodforge/simplify/simplify.hpp"
#include "asset_geometry.hpp"
#include "terrain.hpp"
#include "proc_status.hpp"

namespace {

using lodforge::Mesh;
using lodforge::Vec3f;
using nlohmann::json;
using Clock = std::chrono::steady_clock;
namespace fs = std::filesystem;

static_assert(sizeof(Vec3f) == 3 * sizeof(float), "meshopt reads positions as packed float triples");

// ---------------------------------------------------------------------------------------------------------------
// Contract thresholds (docs/performance.md)

constexpr double kQualityVsMeshopt = 0.65;        // lodforge mean and RMS <= 0.65 x meshopt (geomean, scanned)
constexpr double kHausdorffVsMeshopt = 1.0;       // lodforge Hausdorff no worse than meshopt (geomean, scanned)
constexpr double kQualityRatios[] = {0.1, 0.02};  // the ratios the quality targets are judged at
constexpr double kThroughputRatio = 0.1;          // the ratio the throughput targets are judged at
constexpr double kThroughputVsMeshopt = 1.0;      // lodforge 1 thread >= meshopt, input triangles per second
constexpr double kThreadSpeedup = 1.6;            // lodforge all threads >= 1.6 x lodforge 1 thread
// "Meshes >= 100k triangles": the corpus' "-100k" decimations (lucy has 99,970) and the generated mesh.
constexpr std::size_t kLargeMeshTriangles = 99'000;
constexpr double kMaxBytesPerTriangle = 250.0;  // peak memory during simplification per input triangle
// Speed targets: 1 thread vs meshopt at 10% and 2% (geomean, scanned); no scanned mesh nor the flat plate below
// kWorstSpeedVsMeshopt; the 16.8M terrain (--terrain) at 1% at least kTerrainSpeedVsMeshopt.
constexpr double kSpeedRatios[] = {0.1, 0.02};
constexpr double kWorstSpeedVsMeshopt = 0.5;
constexpr double kTerrainSpeedVsMeshopt = 0.8;
constexpr double kTerrainRatio = 0.01;
// Meshes of 1M triangles and more: two threads vs one, and peak memory per input triangle.
constexpr std::size_t kHugeMeshTriangles = 1'000'000;
constexpr double kMaxBytesPerTriangleHuge = 150.0;
// multiple_choice (the speed preset) vs the default engine, 1 thread, scanned, 10%: throughput and mean error.
constexpr double kChoiceSpeedup = 2.0, kChoiceMeanError = 1.3;
constexpr double kTargetCountRatio = 0.01;      // count target judged at 1% ...
constexpr double kTargetCountTolerance = 0.01;  // ... reached within 1% on closed meshes
// Stanford bunny reference (textbook Garland-Heckbert figures): mean error, fraction of the bbox diagonal.
constexpr double kBunnyMeanAt10 = 0.00020, kBunnyMeanAt1 = 0.00150;
// meshopt_simplify ("subset") on the bunny in the §10.5 protocol, to sanity-check this harness' evaluation.
constexpr double kBunnyMeshoptMeanAt10 = 0.000310, kBunnyMeshoptHausAt10 = 0.00249;
constexpr double kBunnyMeshoptMeanAt1 = 0.00239, kBunnyMeshoptHausAt1 = 0.01338;

// ---------------------------------------------------------------------------------------------------------------
// Settings

enum class Method { lodforge_1t, lodforge_all, lodforge_mc, meshopt, openmesh };
constexpr Method kAllMethods[] = {Method::lodforge_1t, Method::lodforge_all, Method::lodforge_mc, Method::meshopt,
                                  Method::openmesh};

const char* method_name(Method m) {
  switch (m) {
    case Method::lodforge_1t:
      return "lodforge-1t";
    case Method::lodforge_all:
      return "lodforge-all";
    case Method::lodforge_mc:
      return "lodforge-mc";
    case Method::meshopt:
      return "meshopt";
    case Method::openmesh:
      return "openmesh";
  }
  return "?";
}

std::optional<Method> method_from_name(const std::string& s) {
  for (Method m : kAllMethods)
    if (s == method_name(m)) return m;
  return std::nullopt;
}

// The --quick subset: the bunny (reference row), and three ~100k meshes (OBJ closed, OBJ non-manifold, PLY).
const std::set<std::string> kQuickMeshes = {"stanford-bunny", "dragon-100k", "happy-buddha-100k", "lucy-100k"};

struct Settings {
  std::vector<fs::path> files;
  std::vector<double> ratios{0.5, 0.1, 0.02, 0.01};
  std::vector<Method> methods{std::begin(kAllMethods), std::end(kAllMethods)};
  bool generated = true;
  std::size_t generated_triangles = 2'000'000;
  bool plate = true;
  std::size_t plate_triangles = 400'000;
  bool terrain = false;
  std::size_t terrain_side = 2'900;  // vertices per side: 2 x 2899² = 16.8M triangles
  bool ceiling = true;  // two lodforge-1t processes at once on meshes of kHugeMeshTriangles and more
  std::size_t eval_samples = 1'000'000;  // per direction, §10.5 protocol
  bool eval = true;
  int max_reps = 3;
  double rep_budget_s = 1.0;
  unsigned timeout_s = 900;
  // The Decimater is by far the slowest method (~10-50k triangles/s here): skipped above this size by default.
  std::size_t openmesh_max_triangles = 1'000'000;
  std::string json_path = "bench-simplify.json";
  bool quick = false;
};

// ---------------------------------------------------------------------------------------------------------------
// Inputs

struct Input {
  std::string name;
  std::string path;      // empty for the generated mesh
  bool scanned = false;  // a file (--input folder or --mesh), not generated: counts in the corpus geometric means
  bool plate = false;    // the generated flat CAD-like plate
  std::vector<double> only_ratios;  // non-empty: runs at these ratios instead of the settings' (the terrain)
  Mesh mesh;             // positions + triangles only, one wedge per vertex
  std::vector<std::uint32_t> indices;  // 3 vertex ids per triangle (the same triangles as `mesh`)
  std::size_t boundary_edges = 0, nonmanifold_edges = 0;
  double diagonal = 0;
  std::size_t triangles() const { return indices.size() / 3; }
  bool closed() const { return boundary_edges == 0 && nonmanifold_edges == 0; }
};

Mesh geometry_mesh(std::vector<Vec3f> positions, std::vector<std::uint32_t> indices) {
  Mesh m;
  m.positions = std::move(positions);
  m.wedge_vertex.resize(m.positions.size());
  std::iota(m.wedge_vertex.begin(), m.wedge_vertex.end(), 0u);
  const std::size_t tris = indices.size() / 3;
  m.face_offsets.resize(tris + 1);
  for (std::size_t t = 0; t <= tris; ++t) m.face_offsets[t] = static_cast<std::uint32_t>(3 * t);
  m.corner_wedge = std::move(indices);
  m.face_material.assign(tris, 0);
  m.materials.push_back(lodforge::MaterialSlot{.name = "", .has_normals = false, .has_tangents = false});
  return m;
}

// Keeps only the vertices the triangles use, in order of first use (so equal outputs hash equal).
Mesh compacted(const std::vector<Vec3f>& positions, const std::vector<std::uint32_t>& indices) {
  std::vector<std::uint32_t> remap(positions.size(), lodforge::kInvalidIndex);
  std::vector<Vec3f> out_pos;
  std::vector<std::uint32_t> out_idx(indices.size());
  for (std::size_t i = 0; i < indices.size(); ++i) {
    std::uint32_t& r = remap[indices[i]];
    if (r == lodforge::kInvalidIndex) {
      r = static_cast<std::uint32_t>(out_pos.size());
      out_pos.push_back(positions[indices[i]]);
    }
    out_idx[i] = r;
  }
  return geometry_mesh(std::move(out_pos), std::move(out_idx));
}

// Every mesh of an asset, fan-triangulated, attributes dropped, concatenated.
Input load_input(const fs::path& path) {
  const lodforge::io::Asset asset = lodforge::io::load_asset(path);
  std::vector<Vec3f> positions;
  std::vector<std::uint32_t> indices;
  lodforge::bench::asset_triangles(asset, positions, indices);
  Input in;
  in.name = path.stem().string();
  in.path = path.string();
  in.indices = indices;
  in.mesh = geometry_mesh(std::move(positions), std::move(indices));
  return in;
}

std::string fmt_millions(std::size_t n) {
  char b[32];
  std::snprintf(b, sizeof b, "%.1fM", static_cast<double>(n) / 1e6);
  return b;
}

// A closed genus-1 surface with bumps at three scales: a torus whose tube radius is modulated by sines.
// Deterministic; about `triangles` triangles in a (n_u x n_v) grid, n_u / n_v ~ major / tube radius.
Input make_bumpy_torus(std::size_t triangles) {
  constexpr double kMajor = 1.0, kTube = 0.35, kTwoPi = 2.0 * std::numbers::pi;
  const auto n_v = static_cast<std::size_t>(
      std::max(3.0, std::round(std::sqrt(static_cast<double>(triangles) / (2.0 * kMajor / kTube)))));
  const auto n_u =
      std::max<std::size_t>(3, static_cast<std::size_t>(std::round(static_cast<double>(triangles) / (2.0 * n_v))));
  std::vector<Vec3f> positions;
  positions.reserve(n_u * n_v);
  for (std::size_t i = 0; i < n_u; ++i) {
    const double u = kTwoPi * static_cast<double>(i) / static_cast<double>(n_u);
    for (std::size_t j = 0; j < n_v; ++j) {
      const double v = kTwoPi * static_cast<double>(j) / static_cast<double>(n_v);
      const double bump = 1.0 + 0.10 * std::sin(5 * u) * std::cos(3 * v) +
                          0.04 * std::sin(17 * u + 0.3) * std::sin(11 * v) +
                          0.015 * std::sin(47 * u) * std::cos(29 * v + 1.1);
      const double r = kTube * bump;
      positions.push_back(
          {{static_cast<float>((kMajor + r * std::cos(v)) * std::cos(u)),
            static_cast<float>((kMajor + r * std::cos(v)) * std::sin(u)), static_cast<float>(r * std::sin(v))}});
    }
  }
  std::vector<std::uint32_t> indices;
  indices.reserve(6 * n_u * n_v);
  auto id = [&](std::size_t i, std::size_t j) { return static_cast<std::uint32_t>((i % n_u) * n_v + (j % n_v)); };
  for (std::size_t i = 0; i < n_u; ++i) {
    for (std::size_t j = 0; j < n_v; ++j) {
      // d--c     (i, j) -> a; u grows to the right, v upwards; (a, b, c) faces outwards
      // | /|
      // |/ |
      // a--b
      const std::uint32_t a = id(i, j), b = id(i + 1, j), c = id(i + 1, j + 1), d = id(i, j + 1);
      indices.insert(indices.end(), {a, b, c, a, c, d});
    }
  }
  Input in;
  in.name = "generated-torus-" + std::to_string((2 * n_u * n_v + 500'000) / 1'000'000) + "M";
  if (2 * n_u * n_v < 1'000'000) in.name = "generated-torus-" + std::to_string(2 * n_u * n_v / 1000) + "k";
  in.indices = indices;
  in.mesh = geometry_mesh(std::move(positions), std::move(indices));
  return in;
}

// A flat CAD-like part: a closed rectangular plate (1 x 0.75 x 1/32) whose six faces are uniform grids, aligned
// with the axes like most CAD exports, so that every edge inside a face costs exactly 0. About `triangles`
// triangles.
Input make_cad_plate(std::size_t triangles) {
  // 2 (2 nx ny + 2 nx nz + 2 ny nz) triangles with ny = 3/4 nx, nz = nx / 32.
  const double per_nx2 = 2.0 * (2.0 * 0.75 + 2.0 / 32.0 + 2.0 * 0.75 / 32.0);
  const auto nx = std::max<std::size_t>(32, static_cast<std::size_t>(std::sqrt(static_cast<double>(triangles) / per_nx2)));
  const std::size_t n[3] = {nx, std::max<std::size_t>(1, nx * 3 / 4), std::max<std::size_t>(1, nx / 32)};
  const double h = 1.0 / static_cast<double>(nx);
  std::vector<Vec3f> positions;
  std::vector<std::uint32_t> indices;
  std::unordered_map<std::uint64_t, std::uint32_t> ids;  // lattice point -> vertex (faces share their rims)
  auto vertex = [&](std::size_t x, std::size_t y, std::size_t z) {
    const std::uint64_t key = (std::uint64_t{x} << 42) | (std::uint64_t{y} << 21) | z;
    const auto [it, fresh] = ids.try_emplace(key, static_cast<std::uint32_t>(positions.size()));
    if (fresh) {
      positions.push_back({{static_cast<float>(static_cast<double>(x) * h), static_cast<float>(static_cast<double>(y) * h),
                            static_cast<float>(static_cast<double>(z) * h)}});
    }
    return it->second;
  };
  for (int axis = 0; axis < 3; ++axis) {
    const int a = axis == 0 ? 1 : 0, b = axis == 2 ? 1 : 2;  // the face's grid axes, a < b
    const bool cyclic = axis != 1;                             // (a, b, axis) right-handed: the grid's normal is +axis
    for (const std::size_t level : {std::size_t{0}, n[axis]}) {
      const bool flip = (level != 0) != cyclic;  // outward normals
      for (std::size_t i = 0; i < n[a]; ++i) {
        for (std::size_t j = 0; j < n[b]; ++j) {
          std::uint32_t q[4];
          const std::size_t corners[4][2] = {{i, j}, {i + 1, j}, {i + 1, j + 1}, {i, j + 1}};
          for (int c = 0; c < 4; ++c) {
            std::size_t p[3];
            p[axis] = level;
            p[a] = corners[c][0];
            p[b] = corners[c][1];
            q[c] = vertex(p[0], p[1], p[2]);
          }
          if (flip) std::swap(q[1], q[3]);
          indices.insert(indices.end(), {q[0], q[1], q[2], q[0], q[2], q[3]});
        }
      }
    }
  }
  Input in;
  in.name = "generated-plate-" + std::to_string(indices.size() / 3 / 1000) + "k";
  in.plate = true;
  in.indices = indices;
  in.mesh = geometry_mesh(std::move(positions), std::move(indices));
  return in;
}

// A terrain: a height field of side x side vertices over the unit square, heights from 8 octaves of value noise
// (fBm) with a fixed seed, 2 (side - 1)² triangles. Run at kTerrainRatio only.
Input make_terrain(std::size_t side) {
  std::vector<Vec3f> positions;
  std::vector<std::uint32_t> indices;
  lodforge::bench::make_fbm_terrain(side, positions, indices);
  Input in;
  in.name = "generated-terrain-" + fmt_millions(indices.size() / 3);
  in.only_ratios = {kTerrainRatio};
  in.indices = indices;
  in.mesh = geometry_mesh(std::move(positions), std::move(indices));
  return in;
}

// Boundary edges (one triangle) and non-manifold edges (more than two), on undirected vertex pairs.
void count_edges(Input& in) {
  std::vector<std::uint64_t> edges;
  edges.reserve(in.indices.size());
  for (std::size_t t = 0; t < in.triangles(); ++t) {
    for (int k = 0; k < 3; ++k) {
      std::uint64_t a = in.indices[3 * t + k], b = in.indices[3 * t + (k + 1) % 3];
      if (a > b) std::swap(a, b);
      edges.push_back(a << 32 | b);
    }
  }
  std::sort(edges.begin(), edges.end());
  for (std::size_t i = 0; i < edges.size();) {
    std::size_t j = i;
    while (j < edges.size() && edges[j] == edges[i]) ++j;
    if (j - i == 1) ++in.boundary_edges;
    if (j - i > 2) ++in.nonmanifold_edges;
    i = j;
  }
}

// ---------------------------------------------------------------------------------------------------------------
// One run (executed in a child process)

struct Run {
  std::string mesh;
  Method method = Method::lodforge_1t;
  double ratio = 0;
  std::size_t triangles_in = 0, target = 0, triangles_out = 0, vertices_out = 0;
  double seconds = 0;  // best repetition
  int reps = 0;
  double peak_bytes = NAN;  // peak RSS during the first repetition minus RSS before it
  bool evaluated = false;
  double hausdorff_rel = NAN, mean_rel = NAN, rms_rel = NAN;  // fractions of the input's bbox diagonal
  double hausdorff_abs = NAN, mean_abs = NAN, rms_abs = NAN;
  std::uint64_t output_hash = 0;
  std::optional<bool> same_as_1t;  // lodforge-all only: output identical to lodforge-1t's (when that ran)
  std::string error;               // non-empty: the run failed
  json details = json::object();

  double tris_per_second() const { return seconds > 0 ? static_cast<double>(triangles_in) / seconds : NAN; }
  double bytes_per_triangle() const { return triangles_in ? peak_bytes / static_cast<double>(triangles_in) : NAN; }
  bool ok() const { return error.empty(); }
};

Run new_run(const Input& in, Method method, double ratio, std::size_t target) {
  Run run;
  run.mesh = in.name;
  run.method = method;
  run.ratio = ratio;
  run.triangles_in = in.triangles();
  run.target = target;
  return run;
}

json num(double v) {
  return std::isfinite(v) ? json(v) : json(nullptr);
}
double num_from(const json& j) {
  return j.is_number() ? j.get<double>() : NAN;
}

json to_json(const Run& r) {
  return {{"mesh", r.mesh},
          {"method", method_name(r.method)},
          {"ratio", r.ratio},
          {"triangles_in", r.triangles_in},
          {"target_triangles", r.target},
          {"triangles_out", r.triangles_out},
          {"vertices_out", r.vertices_out},
          {"seconds", num(r.seconds)},
          {"repetitions", r.reps},
          {"input_triangles_per_second", num(r.tris_per_second())},
          {"peak_bytes", num(r.peak_bytes)},
          {"peak_bytes_per_input_triangle", num(r.bytes_per_triangle())},
          {"evaluated", r.evaluated},
          {"hausdorff_rel", num(r.hausdorff_rel)},
          {"mean_rel", num(r.mean_rel)},
          {"rms_rel", num(r.rms_rel)},
          {"hausdorff_abs", num(r.hausdorff_abs)},
          {"mean_abs", num(r.mean_abs)},
          {"rms_abs", num(r.rms_abs)},
          {"output_hash", r.output_hash},
          {"same_as_1t", r.same_as_1t ? json(*r.same_as_1t) : json(nullptr)},
          {"error", r.error},
          {"details", r.details}};
}

Run run_from_json(const json& j) {
  Run r;
  r.mesh = j.at("mesh");
  r.method = *method_from_name(j.at("method"));
  r.ratio = j.at("ratio");
  r.triangles_in = j.at("triangles_in");
  r.target = j.at("target_triangles");
  r.triangles_out = j.at("triangles_out");
  r.vertices_out = j.at("vertices_out");
  r.seconds = num_from(j.at("seconds"));
  r.reps = j.at("repetitions");
  r.peak_bytes = num_from(j.at("peak_bytes"));
  r.evaluated = j.at("evaluated");
  r.hausdorff_rel = num_from(j.at("hausdorff_rel"));
  r.mean_rel = num_from(j.at("mean_rel"));
  r.rms_rel = num_from(j.at("rms_rel"));
  r.hausdorff_abs = num_from(j.at("hausdorff_abs"));
  r.mean_abs = num_from(j.at("mean_abs"));
  r.rms_abs = num_from(j.at("rms_abs"));
  r.output_hash = j.at("output_hash");
  if (j.at("same_as_1t").is_boolean()) r.same_as_1t = j.at("same_as_1t").get<bool>();
  r.error = j.at("error");
  r.details = j.at("details");
  return r;
}

using lodforge::bench::status_kb;

// Peak resident memory of a stretch of code, relative to the resident memory when it starts.
class MemoryProbe {
 public:
  void start() {
    malloc_trim(0);  // give back what earlier allocations left in the heap, so the peak is not hidden by reuse
    {
      std::ofstream clear("/proc/self/clear_refs");
      clear << "5";  // resets VmHWM to the current VmRSS
    }
    baseline_kb_ = status_kb("VmRSS:");
    // The reset worked if the high-water mark is now (within reading noise) the current RSS.
    hwm_reset_ = status_kb("VmHWM:") <= baseline_kb_ + 1024;
  }
  // NaN when the high-water mark could not be reset (it would include the parent's history).
  double peak_bytes() const {
    const long hwm = status_kb("VmHWM:");
    if (!hwm_reset_ || hwm < 0 || baseline_kb_ < 0) return NAN;
    return 1024.0 * static_cast<double>(std::max(0L, hwm - baseline_kb_));
  }

 private:
  long baseline_kb_ = -1;
  bool hwm_reset_ = false;
};

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// Runs `once` (which returns the output) up to max_reps times, keeping the best time and the first output; the
// memory probe covers the first repetition only, while its output is still alive.
template <typename Output, typename Prepare, typename Once>
Output measure(Run& run, const Settings& s, Prepare&& prepare, Once&& once) {
  MemoryProbe probe;
  std::optional<Output> first;
  double total = 0;
  for (int rep = 0; rep < std::max(1, s.max_reps); ++rep) {
    prepare();
    if (rep == 0) probe.start();
    const Clock::time_point t0 = Clock::now();
    Output out = once();
    const double t = seconds_since(t0);
    if (rep == 0) {
      run.peak_bytes = probe.peak_bytes();
      first.emplace(std::move(out));
      run.seconds = t;
    }
    run.seconds = std::min(run.seconds, t);
    run.reps = rep + 1;
    total += t;
    if (total >= s.rep_budget_s) break;
  }
  return std::move(*first);
}

using OmMesh = OpenMesh::TriMesh_ArrayKernelT<>;

struct Geometry {
  std::vector<Vec3f> positions;
  std::vector<std::uint32_t> indices;
};

Geometry run_lodforge(Run& run, const Input& in, const Settings& s, unsigned threads,
                      lodforge::Engine engine = lodforge::Engine::edge_collapse) {
  lodforge::SimplifyOptions options;  // defaults otherwise: the engine as a user gets it
  options.engine = engine;
  options.target_ratio = run.ratio;
  options.target_triangles = run.target;
  options.threads = threads;
  lodforge::SimplifyResult res = measure<lodforge::SimplifyResult>(
      run, s, [] {}, [&] { return lodforge::simplify(in.mesh, options); });
  run.details = {{"stop_reason", lodforge::stop_reason_name(res.stop_reason)},
                 {"error_bound_rel", res.error_bound_rel},
                 {"collapses", res.collapses},
                 {"rounds", res.rounds},
                 {"rejected", res.vetoes.rejected()},
                 {"setup_ms", res.timings.setup_ms},
                 {"initial_costs_ms", res.timings.initial_costs_ms},
                 {"collapse_ms", res.timings.collapse_ms},
                 {"output_ms", res.timings.output_ms},
                 {"threads", threads}};
  Geometry g;
  g.positions = std::move(res.mesh.positions);
  for (std::size_t f = 0; f < res.mesh.face_count(); ++f) {
    const std::uint32_t begin = res.mesh.face_offsets[f], k = res.mesh.face_size(f);
    for (std::uint32_t i = 1; i + 1 < k; ++i) {
      g.indices.push_back(res.mesh.corner_vertex(begin));
      g.indices.push_back(res.mesh.corner_vertex(begin + i));
      g.indices.push_back(res.mesh.corner_vertex(begin + i + 1));
    }
  }
  return g;
}

Geometry run_meshopt(Run& run, const Input& in, const Settings& s) {
  float result_error = 0;
  std::vector<std::uint32_t> out = measure<std::vector<std::uint32_t>>(
      run, s, [] {},
      [&] {
        std::vector<std::uint32_t> dst(in.indices.size());
        const std::size_t n = meshopt_simplify(dst.data(), in.indices.data(), in.indices.size(),
                                               &in.mesh.positions[0][0], in.mesh.positions.size(), sizeof(Vec3f),
                                               3 * run.target, /*target_error=*/1.0f, /*options=*/0, &result_error);
        dst.resize(n);
        return dst;
      });
  run.details = {{"result_error_rel", result_error}};
  return {in.mesh.positions, std::move(out)};
}

Geometry run_openmesh(Run& run, const Input& in, const Settings& s) {
  using Decimater = OpenMesh::Decimater::DecimaterT<OmMesh>;
  using Quadric = OpenMesh::Decimater::ModQuadricT<OmMesh>::Handle;
  using NormalFlipping = OpenMesh::Decimater::ModNormalFlippingT<OmMesh>::Handle;
  omerr().disable();  // complex-edge messages for non-manifold input
  omlog().disable();

  OmMesh base;
  std::vector<OmMesh::VertexHandle> vh;
  vh.reserve(in.mesh.positions.size());
  for (const Vec3f& p : in.mesh.positions) vh.push_back(base.add_vertex(OmMesh::Point(p[0], p[1], p[2])));
  std::size_t skipped = 0;
  for (std::size_t t = 0; t < in.triangles(); ++t) {
    const auto f = base.add_face(vh[in.indices[3 * t]], vh[in.indices[3 * t + 1]], vh[in.indices[3 * t + 2]]);
    if (!f.is_valid()) ++skipped;  // OpenMesh cannot hold non-manifold edges or degenerate faces
  }
  base.request_face_normals();
  base.update_face_normals();
  vh.clear();
  vh.shrink_to_fit();

  // The decimated mesh stays in `mesh` (no copy inside the timed call); every repetition starts from a fresh copy.
  std::optional<OmMesh> mesh;
  measure<int>(
      run, s, [&] { mesh.reset(), mesh.emplace(base); },
      [&] {
        {
          Decimater decimater(*mesh);
          Quadric quadric;
          NormalFlipping flipping;
          decimater.add(quadric);
          decimater.add(flipping);
          decimater.initialize();
          decimater.decimate_to_faces(0, run.target);
          // While the decimater lives: its destructor releases the status flags that garbage_collection reads.
          mesh->garbage_collection();
        }
        return 0;
      });
  const OmMesh& result = *mesh;
  run.details = {{"faces_rejected_on_input", skipped}};
  Geometry g;
  g.positions.reserve(result.n_vertices());
  for (const auto v : result.vertices()) {
    const OmMesh::Point& p = result.point(v);
    g.positions.push_back({{p[0], p[1], p[2]}});
  }
  g.indices.reserve(3 * result.n_faces());
  for (const auto f : result.faces())
    for (const auto v : result.fv_range(f)) g.indices.push_back(static_cast<std::uint32_t>(v.idx()));
  return g;
}

std::uint64_t fnv1a(const void* data, std::size_t n, std::uint64_t h = 1469598103934665603ull) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < n; ++i) h = (h ^ p[i]) * 1099511628211ull;
  return h;
}

// The body of a child: simplify, measure, evaluate. `skip_eval_hash`: an output with this hash has already been
// evaluated (lodforge threads=1), so the parent copies that quality instead.
Run execute(const Input& in, Method method, double ratio, std::size_t target, const Settings& s,
            std::uint64_t skip_eval_hash) {
  Run run = new_run(in, method, ratio, target);
  // Start TBB's workers before the memory baseline: thread stacks are not the simplifier's memory.
  tbb::parallel_for(0, 1024, [](int) {});

  Geometry g;
  switch (method) {
    case Method::lodforge_1t:
      g = run_lodforge(run, in, s, 1);
      break;
    case Method::lodforge_all:
      g = run_lodforge(run, in, s, 0);
      break;
    case Method::lodforge_mc:
      g = run_lodforge(run, in, s, 1, lodforge::Engine::multiple_choice);
      break;
    case Method::meshopt:
      g = run_meshopt(run, in, s);
      break;
    case Method::openmesh:
      g = run_openmesh(run, in, s);
      break;
  }
  const Mesh out = compacted(g.positions, g.indices);
  run.triangles_out = out.face_count();
  run.vertices_out = out.vertex_count();
  run.output_hash = fnv1a(out.positions.data(), out.positions.size() * sizeof(Vec3f));
  run.output_hash = fnv1a(out.corner_wedge.data(), out.corner_wedge.size() * sizeof(std::uint32_t), run.output_hash);
  if (s.eval && !(skip_eval_hash != 0 && skip_eval_hash == run.output_hash)) {
    const Clock::time_point t0 = Clock::now();
    const lodforge::EvalResult e = lodforge::evaluate(in.mesh, out, {.samples = s.eval_samples, .threads = 0});
    run.details["eval_seconds"] = seconds_since(t0);
    run.evaluated = true;
    run.hausdorff_rel = e.hausdorff_rel();
    run.mean_rel = e.mean_rel();
    run.rms_rel = e.rms_rel();
    run.hausdorff_abs = e.hausdorff;
    run.mean_abs = e.mean;
    run.rms_abs = e.rms;
  }
  return run;
}

// A forked child running `execute`; its Run comes back through the pipe.
struct Child {
  pid_t pid = -1;
  int fd = -1;
  Run failed;  // what to report when the child cannot start or does not answer
};

Child spawn(const Input& in, Method method, double ratio, std::size_t target, const Settings& s,
            std::uint64_t skip_eval_hash) {
  Child child;
  child.failed = new_run(in, method, ratio, target);
  Run& failed = child.failed;

  int fds[2];
  if (pipe(fds) != 0) {
    failed.error = std::string("pipe: ") + std::strerror(errno);
    return child;
  }
  std::fflush(stdout);
  std::fflush(stderr);
  const pid_t pid = fork();
  if (pid < 0) {
    failed.error = std::string("fork: ") + std::strerror(errno);
    close(fds[0]);
    close(fds[1]);
    return child;
  }
  if (pid == 0) {
    close(fds[0]);
    alarm(s.timeout_s);
    // A runaway run fails with bad_alloc instead of taking the machine down: at most 3/4 of physical memory.
    const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGE_SIZE);
    if (pages > 0 && page > 0) {
      const rlimit lim{static_cast<rlim_t>(pages) / 4 * 3 * static_cast<rlim_t>(page), RLIM_INFINITY};
      setrlimit(RLIMIT_AS, &lim);
    }
    std::string text;
    try {
      text = to_json(execute(in, method, ratio, target, s, skip_eval_hash)).dump();
    } catch (const std::exception& e) {
      failed.error = e.what();
      text = to_json(failed).dump();
    }
    for (std::size_t off = 0; off < text.size();) {
      const ssize_t w = write(fds[1], text.data() + off, text.size() - off);
      if (w <= 0) break;
      off += static_cast<std::size_t>(w);
    }
    close(fds[1]);
    _exit(0);  // no static destructors: the child shares nothing the parent must see flushed
  }
  close(fds[1]);
  child.pid = pid;
  child.fd = fds[0];
  return child;
}

Run collect(Child& child, const Settings& s) {
  Run failed = child.failed;
  if (child.pid < 0) return failed;
  const pid_t pid = child.pid;
  int fds[1] = {child.fd};
  std::string text;
  char buf[65536];
  for (ssize_t n; (n = read(fds[0], buf, sizeof buf)) != 0;) {
    if (n < 0) {
      if (errno == EINTR) continue;
      break;
    }
    text.append(buf, static_cast<std::size_t>(n));
  }
  close(fds[0]);
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (WIFSIGNALED(status)) {
    const int sig = WTERMSIG(status);
    failed.error = sig == SIGALRM ? "timeout after " + std::to_string(s.timeout_s) + " s"
                                  : std::string("child killed by signal ") + strsignal(sig);
    return failed;
  }
  try {
    return run_from_json(json::parse(text));
  } catch (const std::exception& e) {
    failed.error = std::string("bad child report: ") + e.what();
    return failed;
  }
}

// Runs `execute` in a forked child and brings its Run back through a pipe.
Run run_isolated(const Input& in, Method method, double ratio, std::size_t target, const Settings& s,
                 std::uint64_t skip_eval_hash) {
  Child child = spawn(in, method, ratio, target, s, skip_eval_hash);
  return collect(child, s);
}

// Two lodforge-1t children at once, without evaluation: what two independent single-threaded processes get out
// of the machine. Returns their mean time (NaN if either failed).
double run_pair(const Input& in, double ratio, std::size_t target, const Settings& s) {
  Settings quiet = s;
  quiet.eval = false;
  Child a = spawn(in, Method::lodforge_1t, ratio, target, quiet, 0);
  Child b = spawn(in, Method::lodforge_1t, ratio, target, quiet, 0);
  const Run ra = collect(a, quiet), rb = collect(b, quiet);
  return ra.ok() && rb.ok() ? 0.5 * (ra.seconds + rb.seconds) : NAN;
}

// ---------------------------------------------------------------------------------------------------------------
// Printing

std::string fmt(const char* f, double v) {
  if (!std::isfinite(v)) return "-";
  char b[64];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

std::string ratio_label(double r) {
  return fmt("%g%%", 100.0 * r);
}

void print_row_header() {
  std::printf("%-22s %9s %6s %-13s %9s %9s %8s %7s %9s %9s %8s  %s\n", "mesh", "tris_in", "ratio", "method", "tris_out",
              "time_ms", "Mtri/s", "B/tri", "mean%", "rms%", "haus%", "note");
}

void print_row(const Run& r) {
  std::string note;
  if (!r.ok())
    note = r.error.rfind("skipped", 0) == 0 ? r.error : "ERROR: " + r.error;
  else if (r.same_as_1t)
    note = *r.same_as_1t ? "output = 1t output" : "output DIFFERS from 1t";
  if (r.ok() && r.reps > 1) note += (note.empty() ? "" : ", ") + std::string("best of ") + std::to_string(r.reps);
  if (r.ok() && r.details.contains("faces_rejected_on_input") && r.details["faces_rejected_on_input"] != 0)
    note += (note.empty() ? "" : ", ") + r.details["faces_rejected_on_input"].dump() + " input faces rejected";
  if (r.ok() && r.details.contains("stop_reason") && r.details["stop_reason"] != "target_reached")
    note += (note.empty() ? "" : ", ") + std::string("stop: ") + r.details["stop_reason"].get<std::string>();
  std::printf("%-22s %9zu %6s %-13s %9s %9s %8s %7s %9s %9s %8s  %s\n", r.mesh.c_str(), r.triangles_in,
              ratio_label(r.ratio).c_str(), method_name(r.method),
              r.ok() ? std::to_string(r.triangles_out).c_str() : "-", fmt("%.1f", 1e3 * r.seconds).c_str(),
              fmt("%.3f", r.tris_per_second() / 1e6).c_str(), fmt("%.0f", r.bytes_per_triangle()).c_str(),
              fmt("%.4f", 100 * r.mean_rel).c_str(), fmt("%.4f", 100 * r.rms_rel).c_str(),
              fmt("%.3f", 100 * r.hausdorff_rel).c_str(), note.c_str());
  std::fflush(stdout);
}

// ---------------------------------------------------------------------------------------------------------------
// Summary and targets

double geomean(const std::vector<double>& v) {
  if (v.empty()) return NAN;
  double s = 0;
  for (double x : v) s += std::log(x);
  return std::exp(s / static_cast<double>(v.size()));
}

// Two lodforge-1t processes at once against one (meshes of kHugeMeshTriangles and more).
struct Ceiling {
  std::string mesh;
  double ratio = 0;
  double single_s = NAN, pair_s = NAN;  // one process alone; the mean of two at once
  double speedup() const { return 2.0 * single_s / pair_s; }  // throughput of two processes over one
};

struct Results {
  std::vector<Input>* inputs;
  std::vector<Run> runs;
  std::vector<Ceiling> ceilings;

  const Run* find(const std::string& mesh, Method m, double ratio) const {
    for (const Run& r : runs)
      if (r.mesh == mesh && r.method == m && r.ratio == ratio && r.ok()) return &r;
    return nullptr;
  }
};

// Geometric mean over meshes (filtered by `use`) of field(a)/field(b) for methods a, b at one ratio.
struct Ratio {
  double value = NAN;
  std::size_t n = 0;
};
template <typename Field, typename Use>
Ratio mean_ratio(const Results& res, Method a, Method b, double ratio, Field field, Use use) {
  std::vector<double> q;
  for (const Input& in : *res.inputs) {
    if (!use(in)) continue;
    const Run* ra = res.find(in.name, a, ratio);
    const Run* rb = res.find(in.name, b, ratio);
    if (!ra || !rb) continue;
    const double x = field(*ra), y = field(*rb);
    if (std::isfinite(x) && std::isfinite(y) && x > 0 && y > 0) q.push_back(x / y);
  }
  return {geomean(q), q.size()};
}

struct Target {
  std::string name, value, threshold;
  double number = NAN;      // the value as a number (the unit is in `value`)
  std::size_t n = 0;        // meshes or runs it is computed over (0: a single row)
  std::optional<bool> met;  // nullopt: no data
};

json summarize(const Results& res, const Settings& s, std::vector<Target>& targets) {
  const auto scanned = [](const Input& in) { return in.scanned; };
  const auto large = [](const Input& in) { return in.triangles() >= kLargeMeshTriangles; };
  const auto all = [](const Input&) { return true; };
  const auto mean = [](const Run& r) { return r.mean_rel; };
  const auto rms = [](const Run& r) { return r.rms_rel; };
  const auto haus = [](const Run& r) { return r.hausdorff_rel; };
  const auto speed = [](const Run& r) { return r.tris_per_second(); };

  std::printf("\n== Summary per ratio (geometric means; quality over the scanned meshes, lodforge = 1 thread) ==\n");
  std::printf("%6s %10s %10s %10s %14s %14s %14s %14s\n", "ratio", "mean lf/mo", "rms lf/mo", "haus lf/mo",
              "1t/mo speed", "1t/mo >=100k", "all/1t speed", "all/1t >=100k");
  json per_ratio = json::array();
  for (double ratio : s.ratios) {
    const Ratio m = mean_ratio(res, Method::lodforge_1t, Method::meshopt, ratio, mean, scanned);
    const Ratio r = mean_ratio(res, Method::lodforge_1t, Method::meshopt, ratio, rms, scanned);
    const Ratio h = mean_ratio(res, Method::lodforge_1t, Method::meshopt, ratio, haus, scanned);
    const Ratio sp = mean_ratio(res, Method::lodforge_1t, Method::meshopt, ratio, speed, all);
    const Ratio spl = mean_ratio(res, Method::lodforge_1t, Method::meshopt, ratio, speed, large);
    const Ratio th = mean_ratio(res, Method::lodforge_all, Method::lodforge_1t, ratio, speed, all);
    const Ratio thl = mean_ratio(res, Method::lodforge_all, Method::lodforge_1t, ratio, speed, large);
    std::printf("%6s %10s %10s %10s %14s %14s %14s %14s\n", ratio_label(ratio).c_str(), fmt("%.3f", m.value).c_str(),
                fmt("%.3f", r.value).c_str(), fmt("%.3f", h.value).c_str(), fmt("%.2fx", sp.value).c_str(),
                fmt("%.2fx", spl.value).c_str(), fmt("%.2fx", th.value).c_str(), fmt("%.2fx", thl.value).c_str());
    per_ratio.push_back({{"ratio", ratio},
                         {"mean_lodforge_over_meshopt", num(m.value)},
                         {"rms_lodforge_over_meshopt", num(r.value)},
                         {"hausdorff_lodforge_over_meshopt", num(h.value)},
                         {"quality_meshes", m.n},
                         {"speed_1t_over_meshopt", num(sp.value)},
                         {"speed_1t_over_meshopt_large", num(spl.value)},
                         {"speed_all_over_1t", num(th.value)},
                         {"speed_all_over_1t_large", num(thl.value)},
                         {"large_meshes", spl.n}});
  }

  // --- the contract ---
  auto add = [&](std::string name, double v, const char* vf, std::string threshold, bool le, double limit,
                 std::size_t n) {
    Target t{std::move(name), fmt(vf, v) + (n ? " (n=" + std::to_string(n) + ")" : ""), std::move(threshold), v, n, {}};
    if (std::isfinite(v)) t.met = le ? v <= limit : v >= limit;
    targets.push_back(std::move(t));
  };
  for (double q : kQualityRatios) {
    const Ratio m = mean_ratio(res, Method::lodforge_1t, Method::meshopt, q, mean, scanned);
    const Ratio r = mean_ratio(res, Method::lodforge_1t, Method::meshopt, q, rms, scanned);
    const Ratio h = mean_ratio(res, Method::lodforge_1t, Method::meshopt, q, haus, scanned);
    add("mean / meshopt at " + ratio_label(q) + " (geomean, scanned)", m.value, "%.3fx", "<= 0.65x", true,
        kQualityVsMeshopt, m.n);
    add("RMS / meshopt at " + ratio_label(q) + " (geomean, scanned)", r.value, "%.3fx", "<= 0.65x", true,
        kQualityVsMeshopt, r.n);
    add("Hausdorff / meshopt at " + ratio_label(q) + " (geomean, scanned)", h.value, "%.3fx", "<= 1.00x", true,
        kHausdorffVsMeshopt, h.n);
  }
  {
    const Ratio sp = mean_ratio(res, Method::lodforge_1t, Method::meshopt, kThroughputRatio, speed, large);
    add("1-thread speed / meshopt at " + ratio_label(kThroughputRatio) + " (geomean, >=100k tris)", sp.value, "%.2fx",
        ">= 1.00x", false, kThroughputVsMeshopt, sp.n);
    const Ratio th = mean_ratio(res, Method::lodforge_all, Method::lodforge_1t, kThroughputRatio, speed, large);
    add("all-threads / 1-thread speed at " + ratio_label(kThroughputRatio) + " (geomean, >=100k tris, " +
            std::to_string(std::thread::hardware_concurrency()) + " hw threads)",
        th.value, "%.2fx", ">= 1.60x", false, kThreadSpeedup, th.n);
  }
  // Speed against meshopt per ratio: the corpus' geometric mean, and the worst mesh (scanned or the flat plate).
  for (double q : kSpeedRatios) {
    const Ratio sp = mean_ratio(res, Method::lodforge_1t, Method::meshopt, q, speed, scanned);
    add("1-thread speed / meshopt at " + ratio_label(q) + " (geomean, scanned)", sp.value, "%.2fx", ">= 1.00x", false,
        kThroughputVsMeshopt, sp.n);
    double worst = NAN;
    std::string where;
    std::size_t n = 0;
    for (const Input& in : *res.inputs) {
      if (!in.scanned && !in.plate) continue;
      const Run* a = res.find(in.name, Method::lodforge_1t, q);
      const Run* b = res.find(in.name, Method::meshopt, q);
      if (!a || !b) continue;
      const double x = a->tris_per_second() / b->tris_per_second();
      if (!std::isfinite(x)) continue;
      ++n;
      if (!(x >= worst)) {
        worst = x;
        where = in.name;
      }
    }
    add("1-thread speed / meshopt at " + ratio_label(q) + ", worst of scanned + plate" +
            (where.empty() ? "" : " (" + where + ")"),
        worst, "%.2fx", ">= 0.50x", false, kWorstSpeedVsMeshopt, n);
  }
  {
    const auto terrain = [](const Input& in) { return !in.only_ratios.empty(); };
    const Ratio t = mean_ratio(res, Method::lodforge_1t, Method::meshopt, kTerrainRatio, speed, terrain);
    add("1-thread speed / meshopt, terrain at " + ratio_label(kTerrainRatio) + " (--terrain)", t.value, "%.2fx",
        ">= 0.80x", false, kTerrainSpeedVsMeshopt, t.n);
  }
  {
    // Two threads over one on meshes of 1M triangles and more, every ratio they ran at, beside the ceiling.
    std::vector<double> scaling, ceiling;
    for (const Input& in : *res.inputs) {
      if (in.triangles() < kHugeMeshTriangles) continue;
      for (double q : in.only_ratios.empty() ? s.ratios : in.only_ratios) {
        const Run* a = res.find(in.name, Method::lodforge_all, q);
        const Run* b = res.find(in.name, Method::lodforge_1t, q);
        if (a && b && a->seconds > 0) scaling.push_back(b->seconds / a->seconds);
      }
    }
    for (const Ceiling& c : res.ceilings) {
      if (std::isfinite(c.speedup())) ceiling.push_back(c.speedup());
    }
    add("all-threads / 1-thread speed (geomean, >=1M tris; two 1-thread processes at once: " +
            fmt("%.2fx", geomean(ceiling)) + ")",
        geomean(scaling), "%.2fx", ">= 1.60x", false, kThreadSpeedup, scaling.size());
  }
  {
    double worst = NAN;
    std::string where;
    std::size_t n = 0;
    for (const Run& r : res.runs) {
      if (!r.ok() || (r.method != Method::lodforge_1t && r.method != Method::lodforge_all)) continue;
      if (r.triangles_in < kHugeMeshTriangles || !std::isfinite(r.bytes_per_triangle())) continue;
      ++n;
      if (!(r.bytes_per_triangle() <= worst)) {
        worst = r.bytes_per_triangle();
        where = r.mesh + " " + ratio_label(r.ratio) + " " + method_name(r.method);
      }
    }
    add("peak memory, worst lodforge run on >=1M tris" + (where.empty() ? "" : " (" + where + ")"), worst,
        "%.0f B/tri", "<= 150 B/tri", true, kMaxBytesPerTriangleHuge, n);
  }
  {
    const Ratio sp = mean_ratio(res, Method::lodforge_mc, Method::lodforge_1t, kThroughputRatio, speed, scanned);
    const Ratio m = mean_ratio(res, Method::lodforge_mc, Method::lodforge_1t, kThroughputRatio, mean, scanned);
    add("multiple_choice / edge_collapse speed at " + ratio_label(kThroughputRatio) + " (1 thread, geomean, scanned)",
        sp.value, "%.2fx", ">= 2.00x", false, kChoiceSpeedup, sp.n);
    add("multiple_choice / edge_collapse mean error at " + ratio_label(kThroughputRatio) + " (geomean, scanned)",
        m.value, "%.3fx", "<= 1.30x", true, kChoiceMeanError, m.n);
  }
  // Memory: the worst lodforge run of all (the contract), and of the large meshes only, where fixed costs (thread
  // pools, allocator arenas) no longer inflate the per-triangle figure.
  for (const bool only_large : {false, true}) {
    double worst = NAN;
    std::string where;
    std::size_t n = 0;
    for (const Run& r : res.runs) {
      if (!r.ok() || (r.method != Method::lodforge_1t && r.method != Method::lodforge_all)) continue;
      if (only_large && r.triangles_in < kLargeMeshTriangles) continue;
      const double b = r.bytes_per_triangle();
      if (!std::isfinite(b)) continue;
      ++n;
      if (!(b <= worst)) {
        worst = b;
        where = r.mesh + " " + ratio_label(r.ratio) + " " + method_name(r.method);
      }
    }
    add(std::string("peak memory, worst lodforge run") + (only_large ? " on >=100k tris" : "") +
            (where.empty() ? "" : " (" + where + ")"),
        worst, "%.0f B/tri", "<= 250 B/tri", true, kMaxBytesPerTriangle, n);
  }
  {
    double worst = NAN;
    std::string where;
    std::size_t n = 0;
    for (const Input& in : *res.inputs) {
      if (!in.closed()) continue;
      for (Method m : {Method::lodforge_1t, Method::lodforge_all}) {
        const Run* r = res.find(in.name, m, kTargetCountRatio);
        if (!r) continue;
        ++n;
        const double dev = std::abs(static_cast<double>(r->triangles_out) - static_cast<double>(r->target)) /
                           static_cast<double>(r->target);
        if (!(dev <= worst)) {
          worst = dev;
          where = in.name + " " + method_name(m) + ": " + std::to_string(r->triangles_out) + " for " +
                  std::to_string(r->target);
        }
      }
    }
    add("count reached at " + ratio_label(kTargetCountRatio) + ", closed meshes, worst" +
            (where.empty() ? "" : " (" + where + ")"),
        100 * worst, "%.2f%% off", "<= 1%", true, 100 * kTargetCountTolerance, n);
  }
  for (auto [ratio, limit] : {std::pair{0.1, kBunnyMeanAt10}, std::pair{0.01, kBunnyMeanAt1}}) {
    const Run* r = res.find("stanford-bunny", Method::lodforge_1t, ratio);
    add("bunny mean at " + ratio_label(ratio) + " (% of diagonal)", r ? 100 * r->mean_rel : NAN, "%.4f%%",
        "<= " + fmt("%.3f%%", 100 * limit), true, 100 * limit, 0);
  }

  std::printf("\n== Performance contract ==\n");
  json jt = json::array();
  for (const Target& t : targets) {
    const char* verdict = !t.met ? "N/A" : *t.met ? "MET" : "NOT MET";
    std::printf("  %-8s %-86s %-22s target %s\n", verdict, t.name.c_str(), t.value.c_str(), t.threshold.c_str());
    jt.push_back({{"target", t.name},
                  {"value", t.value},
                  {"number", num(t.number)},
                  {"n", t.n},
                  {"threshold", t.threshold},
                  {"met", t.met ? json(*t.met) : json(nullptr)}});
  }

  // --- bunny rows vs the §10.5 reference numbers ---
  json jb = json::array();
  bool bunny_header = false;
  for (double ratio : {0.1, 0.01}) {
    const double ref_mean = ratio == 0.1 ? kBunnyMeanAt10 : kBunnyMeanAt1;
    for (Method m : kAllMethods) {
      const Run* r = res.find("stanford-bunny", m, ratio);
      if (!r) continue;
      if (!bunny_header) {
        std::printf("\n== Stanford bunny vs the textbook reference (%% of diagonal) ==\n");
        std::printf("  %-6s %-13s %9s %9s %9s %9s  %s\n", "ratio", "method", "tris_out", "mean%", "rms%", "haus%",
                    "reference");
        bunny_header = true;
      }
      std::string ref;
      if (m == Method::lodforge_1t || m == Method::lodforge_all)
        ref = "target mean <= " + fmt("%.3f%%", 100 * ref_mean) +
              (r->mean_rel <= ref_mean      ? "  MET"
               : std::isfinite(r->mean_rel) ? "  NOT MET"
                                            : "");
      if (m == Method::meshopt)
        ref = "§10.5 meshopt subset: mean " +
              fmt("%.4f%%", 100 * (ratio == 0.1 ? kBunnyMeshoptMeanAt10 : kBunnyMeshoptMeanAt1)) + ", haus " +
              fmt("%.3f%%", 100 * (ratio == 0.1 ? kBunnyMeshoptHausAt10 : kBunnyMeshoptHausAt1));
      std::printf("  %-6s %-13s %9zu %9s %9s %9s  %s\n", ratio_label(ratio).c_str(), method_name(m), r->triangles_out,
                  fmt("%.4f", 100 * r->mean_rel).c_str(), fmt("%.4f", 100 * r->rms_rel).c_str(),
                  fmt("%.3f", 100 * r->hausdorff_rel).c_str(), ref.c_str());
      jb.push_back({{"ratio", ratio},
                    {"method", method_name(m)},
                    {"triangles_out", r->triangles_out},
                    {"mean_rel", num(r->mean_rel)},
                    {"rms_rel", num(r->rms_rel)},
                    {"hausdorff_rel", num(r->hausdorff_rel)}});
    }
  }
  return {{"per_ratio", per_ratio}, {"targets", jt}, {"bunny", jb}};
}

// ---------------------------------------------------------------------------------------------------------------

// Timings mean little on a busy machine: say how busy it is (1-minute load average vs hardware threads).
double print_load_average(const char* when) {
  double load[1] = {NAN};
  if (getloadavg(load, 1) != 1) return NAN;
  const unsigned hw = std::max(1u, std::thread::hardware_concurrency());
  std::printf("load average at %s: %.2f on %u hardware threads%s\n", when, load[0], hw,
              load[0] > 0.5 * hw ? "  (busy machine: timings and thread scaling are unreliable)" : "");
  return load[0];
}

std::vector<fs::path> list_meshes(const fs::path& dir) {
  std::vector<fs::path> out;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (!e.is_regular_file()) continue;
    try {
      lodforge::io::format_from_path(e.path());
      out.push_back(e.path());
    } catch (const lodforge::io::IoError&) {
    }
  }
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  Settings s;
  std::string input_dir = fs::path(LODFORGE_BENCH_CORPUS_DIR) / "scanned";
  std::vector<std::string> mesh_files, method_names;
  bool no_generated = false;
  CLI::App app{"lodforge simplify vs meshoptimizer and OpenMesh Decimater: speed, peak memory, quality"};
  app.add_option("--input", input_dir, "folder of meshes (all supported files in it)")->capture_default_str();
  app.add_option("--mesh", mesh_files, "mesh file(s) to run instead of the folder (repeatable)");
  app.add_option("--ratios", s.ratios, "target ratios (comma separated)")->delimiter(',')->capture_default_str();
  app.add_option("--methods", method_names, "subset of lodforge-1t,lodforge-all,lodforge-mc,meshopt,openmesh")
      ->delimiter(',');
  app.add_flag("--no-generated", no_generated, "skip the generated torus");
  app.add_flag("!--no-plate", s.plate, "skip the generated flat CAD-like plate");
  app.add_option("--plate-triangles", s.plate_triangles, "size of the generated plate")->capture_default_str();
  app.add_flag("--terrain", s.terrain, "add the generated 16.8M-triangle fBm terrain, at 1% (slow: minutes)");
  app.add_option("--terrain-side", s.terrain_side, "vertices per side of the terrain")->capture_default_str();
  app.add_flag("!--no-ceiling", s.ceiling, "skip two lodforge-1t processes at once on meshes of 1M triangles+");
  app.add_option("--generated-triangles", s.generated_triangles, "size of the generated mesh")->capture_default_str();
  app.add_option("--eval-samples", s.eval_samples, "area samples per direction for evaluate()")->capture_default_str();
  app.add_flag("!--no-eval", s.eval, "skip the quality evaluation");
  app.add_option("--reps", s.max_reps, "most repetitions per run (best time is kept)")->capture_default_str();
  app.add_option("--rep-budget", s.rep_budget_s, "stop repeating once the repetitions took this long (s)")
      ->capture_default_str();
  app.add_option("--timeout", s.timeout_s, "seconds before one run is killed")->capture_default_str();
  app.add_option("--openmesh-max", s.openmesh_max_triangles, "skip the OpenMesh Decimater on larger meshes")
      ->capture_default_str();
  app.add_option("--json", s.json_path, "JSON output file")->capture_default_str();
  app.add_flag("--quick", s.quick,
               "fast subset: bunny, dragon, buddha, lucy; ratios 0.1,0.02,0.01; 500k generated mesh; 300k samples; "
               "1 repetition; OpenMesh only up to 150k triangles (explicit options still win)");
  CLI11_PARSE(app, argc, argv);

  if (s.quick) {
    if (app.count("--ratios") == 0) s.ratios = {0.1, 0.02, 0.01};
    if (app.count("--generated-triangles") == 0) s.generated_triangles = 500'000;
    if (app.count("--plate-triangles") == 0) s.plate_triangles = 200'000;
    if (app.count("--eval-samples") == 0) s.eval_samples = 300'000;
    if (app.count("--reps") == 0) s.max_reps = 1;
    if (app.count("--openmesh-max") == 0) s.openmesh_max_triangles = 150'000;
  }
  s.generated = !no_generated;
  if (!method_names.empty()) {
    s.methods.clear();
    for (const std::string& n : method_names) {
      const auto m = method_from_name(n);
      if (!m) {
        std::fprintf(stderr, "unknown method '%s'\n", n.c_str());
        return 2;
      }
      s.methods.push_back(*m);
    }
  }
  for (double r : s.ratios) {
    if (!(r > 0 && r <= 1)) {
      std::fprintf(stderr, "ratio %g is not in (0, 1]\n", r);
      return 2;
    }
  }

  if (!mesh_files.empty()) {
    for (const std::string& f : mesh_files) s.files.emplace_back(f);
  } else {
    if (!fs::is_directory(input_dir)) {
      std::fprintf(stderr, "input folder %s not found (use --input DIR or --mesh FILE)\n", input_dir.c_str());
      return 2;
    }
    for (const fs::path& p : list_meshes(input_dir))
      if (!s.quick || kQuickMeshes.count(p.stem().string())) s.files.push_back(p);
    if (s.files.empty() && s.quick) s.files = list_meshes(input_dir);  // another folder: all of it
  }

  // Inputs are loaded here, in the parent, once; children inherit them.
  std::vector<Input> inputs;
  for (const fs::path& f : s.files) {
    try {
      Input in = load_input(f);
      in.scanned = true;
      if (in.triangles() == 0) {
        std::fprintf(stderr, "skipping %s: no triangles\n", f.c_str());
        continue;
      }
      inputs.push_back(std::move(in));
    } catch (const std::exception& e) {
      std::fprintf(stderr, "skipping %s: %s\n", f.c_str(), e.what());
    }
  }
  if (s.generated) inputs.push_back(make_bumpy_torus(s.generated_triangles));
  if (s.plate) inputs.push_back(make_cad_plate(s.plate_triangles));
  if (s.terrain) inputs.push_back(make_terrain(s.terrain_side));
  for (Input& in : inputs) {
    count_edges(in);
    in.diagonal = lodforge::compute_bounds(in.mesh).diagonal();
  }

  std::printf("lodforge_bench_simplify: %zu meshes, ratios", inputs.size());
  for (double r : s.ratios) std::printf(" %s", ratio_label(r).c_str());
  std::printf("; %u hardware threads; eval %s; up to %d repetition(s)\n", std::thread::hardware_concurrency(),
              s.eval ? (std::to_string(s.eval_samples) + " samples/direction + vertices").c_str() : "off", s.max_reps);
  const double load_start = print_load_average("start");
  std::printf(
      "mean/rms/haus: %% of the input bbox diagonal; Mtri/s: input triangles per second; "
      "B/tri: peak RSS growth per input triangle\n\n");
  print_row_header();

  const Clock::time_point t_start = Clock::now();
  Results res;
  res.inputs = &inputs;
  for (const Input& in : inputs) {
    for (double ratio : in.only_ratios.empty() ? s.ratios : in.only_ratios) {
      const std::size_t target =
          std::max<std::size_t>(1, static_cast<std::size_t>(std::llround(ratio * static_cast<double>(in.triangles()))));
      std::optional<Run> lf1;
      for (Method m : s.methods) {
        const std::uint64_t skip =
            (m == Method::lodforge_all && lf1 && lf1->ok() && lf1->evaluated) ? lf1->output_hash : 0;
        Run r;
        if (m == Method::openmesh && in.triangles() > s.openmesh_max_triangles) {
          r = new_run(in, m, ratio, target);
          r.error = "skipped: more than " + std::to_string(s.openmesh_max_triangles) + " triangles (--openmesh-max)";
        } else {
          r = run_isolated(in, m, ratio, target, s, skip);
        }
        if (m == Method::lodforge_all && lf1 && r.ok() && lf1->ok()) {
          r.same_as_1t = r.output_hash == lf1->output_hash;
          if (*r.same_as_1t && !r.evaluated && lf1->evaluated) {
            r.evaluated = true;
            r.hausdorff_rel = lf1->hausdorff_rel;
            r.mean_rel = lf1->mean_rel;
            r.rms_rel = lf1->rms_rel;
            r.hausdorff_abs = lf1->hausdorff_abs;
            r.mean_abs = lf1->mean_abs;
            r.rms_abs = lf1->rms_abs;
          }
        }
        if (m == Method::lodforge_1t) lf1 = r;
        print_row(r);
        res.runs.push_back(std::move(r));
      }
      if (s.ceiling && in.triangles() >= kHugeMeshTriangles && lf1 && lf1->ok()) {
        const Ceiling c{in.name, ratio, lf1->seconds, run_pair(in, ratio, target, s)};
        std::printf("%-22s %9zu %6s %-13s %9s %9s %8s  two lodforge-1t processes at once: %s the throughput of one\n",
                    in.name.c_str(), in.triangles(), ratio_label(ratio).c_str(), "2x lodforge-1t", "-",
                    fmt("%.1f", 1e3 * c.pair_s).c_str(), fmt("%.3f", 2.0 * static_cast<double>(in.triangles()) / c.pair_s / 1e6).c_str(),
                    fmt("%.2fx", c.speedup()).c_str());
        res.ceilings.push_back(c);
      }
    }
  }

  std::vector<Target> targets;
  json summary = summarize(res, s, targets);
  const double total_s = seconds_since(t_start);
  std::printf("\ntotal %.1f s\n", total_s);
  const double load_end = print_load_average("end");

  json jm = json::array();
  for (const Input& in : inputs)
    jm.push_back({{"name", in.name},
                  {"path", in.path},
                  {"scanned", in.scanned},
                  {"triangles", in.triangles()},
                  {"vertices", in.mesh.vertex_count()},
                  {"boundary_edges", in.boundary_edges},
                  {"nonmanifold_edges", in.nonmanifold_edges},
                  {"closed", in.closed()},
                  {"diagonal", in.diagonal}});
  json jr = json::array();
  for (const Run& r : res.runs) jr.push_back(to_json(r));
  json jc = json::array();
  for (const Ceiling& c : res.ceilings)
    jc.push_back({{"mesh", c.mesh},
                  {"ratio", c.ratio},
                  {"one_process_seconds", num(c.single_s)},
                  {"two_processes_mean_seconds", num(c.pair_s)},
                  {"two_process_speedup", num(c.speedup())}});
  json ms = json::array();
  for (Method m : s.methods) ms.push_back(method_name(m));
  const json doc = {{"tool", "lodforge_bench_simplify"},
                    {"hardware_threads", std::thread::hardware_concurrency()},
                    {"meshoptimizer_version", MESHOPTIMIZER_VERSION},
                    {"settings",
                     {{"ratios", s.ratios},
                      {"methods", ms},
                      {"eval_samples_per_direction", s.eval_samples},
                      {"eval", s.eval},
                      {"max_repetitions", s.max_reps},
                      {"repetition_budget_s", s.rep_budget_s},
                      {"quick", s.quick},
                      {"generated_triangles", s.generated ? s.generated_triangles : 0},
                      {"plate_triangles", s.plate ? s.plate_triangles : 0},
                      {"terrain_side", s.terrain ? s.terrain_side : 0}}},
                    {"meshes", jm},
                    {"runs", jr},
                    {"two_process_ceiling", jc},
                    {"summary", summary},
                    {"load_average_1min", {{"start", num(load_start)}, {"end", num(load_end)}}},
                    {"total_seconds", total_s}};
  std::ofstream out(s.json_path);
  out << doc.dump(2) << "\n";
  if (!out) {
    std::fprintf(stderr, "could not write %s\n", s.json_path.c_str());
    return 1;
  }
  std::printf("wrote %s\n", s.json_path.c_str());
  return 0;
}
