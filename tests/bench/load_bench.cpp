// lodforge_bench_load: load throughput of lodforge::io::load_asset on the largest corpus meshes of each format,
// against OpenMesh's reader (OpenMesh::IO::read_mesh into a PolyMesh, the peer that lodforge's own readers replaced;
// see docs/formats.md). Google Benchmark: bytes_per_second (file bytes, glTF: .gltf + its buffers) and
// items_per_second (triangles after fan triangulation, as lodforge counts them; the same number for both readers,
// so the ratio of items_per_second is the ratio of speeds). A comparison table follows the benchmark output.
//
//   lodforge_bench_load [--corpus=DIR] [--file=PATH ...] [Google Benchmark flags, e.g. --benchmark_min_time=1
//                        --benchmark_filter=obj --benchmark_out=load.json --benchmark_out_format=json]
//
// Files (default): the 3 largest scanned OBJ files, scanned/lucy-100k.ply, gltf/FlightHelmet/FlightHelmet.gltf,
// the largest ASCII and binary STL (hardsurface/tray_bottom_ascii.stl, hardsurface/featuretype.stl) and
// hardsurface/fandisk.off. Files are read from the page cache after the first iteration (warm cache).
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

// MeshIO first: it registers OpenMesh's readers.
#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/Mesh/PolyMesh_ArrayKernelT.hh>
#include <OpenMesh/Core/System/omstream.hh>

#include "lodforge/io/asset.hpp"

namespace {

namespace fs = std::filesystem;
using OmMesh = OpenMesh::PolyMesh_ArrayKernelT<>;

struct LoadCase {
  fs::path path;
  std::string label;  // corpus-relative path
  std::string format;
  std::uint64_t bytes = 0;
  std::size_t triangles = 0;  // from a lodforge load
  bool openmesh = true;       // OpenMesh reads this format
};

std::uint64_t file_bytes(const fs::path& p) {
  std::error_code ec;
  const auto n = fs::file_size(p, ec);
  return ec ? 0 : n;
}

// A .gltf's bytes: the JSON plus the external buffers it names (images are not mesh data and not counted).
std::uint64_t gltf_bytes(const fs::path& p) {
  std::uint64_t total = file_bytes(p);
  std::ifstream f(p);
  const std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  // Tiny scan for "buffers":[{"uri":"x.bin"...}] without a JSON dependency: every "uri" ending in .bin.
  for (std::size_t pos = 0; (pos = text.find("\"uri\"", pos)) != std::string::npos; ++pos) {
    const std::size_t q1 = text.find('"', text.find(':', pos) + 1);
    const std::size_t q2 = q1 == std::string::npos ? q1 : text.find('"', q1 + 1);
    if (q2 == std::string::npos) break;
    const std::string uri = text.substr(q1 + 1, q2 - q1 - 1);
    if (uri.size() > 4 && uri.compare(uri.size() - 4, 4, ".bin") == 0) total += file_bytes(p.parent_path() / uri);
  }
  return total;
}

std::vector<fs::path> default_files(const fs::path& corpus) {
  std::vector<fs::path> objs;
  if (fs::is_directory(corpus / "scanned"))
    for (const auto& e : fs::directory_iterator(corpus / "scanned"))
      if (e.path().extension() == ".obj") objs.push_back(e.path());
  std::sort(objs.begin(), objs.end(), [](const fs::path& a, const fs::path& b) {
    return file_bytes(a) != file_bytes(b) ? file_bytes(a) > file_bytes(b) : a < b;
  });
  if (objs.size() > 3) objs.resize(3);
  std::vector<fs::path> out = objs;
  for (const char* rel :
       {"scanned/lucy-100k.ply", "gltf/FlightHelmet/FlightHelmet.gltf", "hardsurface/tray_bottom_ascii.stl",
        "hardsurface/featuretype.stl", "hardsurface/fandisk.off"})
    out.push_back(corpus / rel);
  return out;
}

std::string stl_kind(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  char head[5] = {};
  f.read(head, 5);
  // ASCII STL starts with "solid" and is not exactly 84 + 50 n bytes (binary headers may also say "solid").
  const std::uint64_t n = file_bytes(p);
  const bool ascii = std::strncmp(head, "solid", 5) == 0 && (n < 84 || (n - 84) % 50 != 0);
  return ascii ? "STL ascii" : "STL binary";
}

// Counters: tris = triangles (lodforge's count, the items), faces = faces the reader produced (polygons).
void bm_lodforge(benchmark::State& state, const LoadCase& c) {
  std::size_t faces = 0;
  for (auto _ : state) {
    lodforge::io::Asset a = lodforge::io::load_asset(c.path);
    faces = 0;
    for (const lodforge::Mesh& m : a.meshes) faces += m.face_count();
    benchmark::DoNotOptimize(faces);
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * c.bytes));
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * c.triangles));
  state.counters["tris"] = static_cast<double>(c.triangles);
  state.counters["faces"] = static_cast<double>(faces);
}

void bm_openmesh(benchmark::State& state, const LoadCase& c) {
  std::size_t faces = 0;
  for (auto _ : state) {
    OmMesh m;
    if (!OpenMesh::IO::read_mesh(m, c.path.string())) {
      state.SkipWithError("OpenMesh::IO::read_mesh failed");
      return;
    }
    faces = m.n_faces();
    benchmark::DoNotOptimize(faces);
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * c.bytes));
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * c.triangles));
  state.counters["tris"] = static_cast<double>(c.triangles);
  state.counters["faces"] = static_cast<double>(faces);  // OpenMesh drops faces it cannot hold (non-manifold)
}

// Console output as usual, and remembers each benchmark's real time per iteration (ms) for the comparison table.
class CapturingReporter : public benchmark::ConsoleReporter {
 public:
  explicit CapturingReporter(OutputOptions options) : ConsoleReporter(options) {}
  std::map<std::string, double> ms;
  void ReportRuns(const std::vector<Run>& reports) override {
    for (const Run& r : reports) {
      if (r.error_occurred || r.run_type != Run::RT_Iteration) continue;
      ms[r.benchmark_name()] = r.GetAdjustedRealTime() * benchmark::GetTimeUnitMultiplier(benchmark::kMillisecond) /
                               benchmark::GetTimeUnitMultiplier(r.time_unit);
    }
    ConsoleReporter::ReportRuns(reports);
  }
};

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  fs::path corpus = LODFORGE_BENCH_CORPUS_DIR;
  std::vector<fs::path> files;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a.rfind("--corpus=", 0) == 0)
      corpus = a.substr(9);
    else if (a.rfind("--file=", 0) == 0)
      files.emplace_back(a.substr(7));
    else {
      std::fprintf(stderr, "unknown argument %s (use --corpus=DIR, --file=PATH, --benchmark_*)\n", a.c_str());
      return 2;
    }
  }
  if (files.empty()) files = default_files(corpus);
  omerr().disable();
  omlog().disable();

  std::vector<LoadCase> cases;
  for (const fs::path& p : files) {
    LoadCase c;
    c.path = p;
    std::error_code ec;
    const fs::path rel = fs::relative(p, corpus, ec);
    c.label = (!ec && !rel.empty() && rel.native().rfind("..", 0) != 0) ? rel.string() : p.string();
    try {
      const lodforge::io::Format f = lodforge::io::format_from_path(p);
      c.format = f == lodforge::io::Format::stl ? stl_kind(p) : lodforge::io::format_name(f);
      c.openmesh = f != lodforge::io::Format::gltf && f != lodforge::io::Format::glb;
      c.bytes = f == lodforge::io::Format::gltf ? gltf_bytes(p) : file_bytes(p);
      const lodforge::io::Asset a = lodforge::io::load_asset(p);
      for (const lodforge::Mesh& m : a.meshes) c.triangles += m.triangle_count();
    } catch (const std::exception& e) {
      std::fprintf(stderr, "skipping %s: %s\n", p.c_str(), e.what());
      continue;
    }
    cases.push_back(c);
  }
  if (cases.empty()) {
    std::fprintf(stderr, "no loadable files (corpus %s)\n", corpus.c_str());
    return 2;
  }
  for (const LoadCase& c : cases) {
    benchmark::RegisterBenchmark(("load/lodforge/" + c.label).c_str(), bm_lodforge, c)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
    if (c.openmesh)
      benchmark::RegisterBenchmark(("load/openmesh/" + c.label).c_str(), bm_openmesh, c)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
  }

  // Colour only on a terminal (a reporter made here does not see --benchmark_color).
  CapturingReporter reporter(isatty(fileno(stdout)) ? benchmark::ConsoleReporter::OO_ColorTabular
                                                    : benchmark::ConsoleReporter::OO_Tabular);
  benchmark::RunSpecifiedBenchmarks(&reporter);
  benchmark::Shutdown();

  std::printf("\n%-38s %-11s %8s %9s | %9s %8s %8s | %9s %8s %8s | %8s\n", "file", "format", "MB", "tris", "lf ms",
              "lf MB/s", "lf Mt/s", "om ms", "om MB/s", "om Mt/s", "lf/om");
  for (const LoadCase& c : cases) {
    const auto get = [&](const char* who) {
      const auto it = reporter.ms.find(std::string("load/") + who + "/" + c.label + "/real_time");
      return it == reporter.ms.end() ? -1.0 : it->second;
    };
    const double mb = static_cast<double>(c.bytes) / 1e6;
    const double lf = get("lodforge"), om = get("openmesh");
    if (lf <= 0 && om <= 0) continue;  // filtered out (--benchmark_filter) or failed
    char lfs[64], oms[64], ratio[32];
    if (lf > 0)
      std::snprintf(lfs, sizeof lfs, "%9.2f %8.1f %8.2f", lf, mb / (lf / 1e3),
                    static_cast<double>(c.triangles) / 1e6 / (lf / 1e3));
    else
      std::snprintf(lfs, sizeof lfs, "%9s %8s %8s", "-", "-", "-");
    if (om > 0)
      std::snprintf(oms, sizeof oms, "%9.2f %8.1f %8.2f", om, mb / (om / 1e3),
                    static_cast<double>(c.triangles) / 1e6 / (om / 1e3));
    else
      std::snprintf(oms, sizeof oms, "%9s %8s %8s", "-", "-", "-");
    if (lf > 0 && om > 0)
      std::snprintf(ratio, sizeof ratio, "%7.2fx", om / lf);
    else
      std::snprintf(ratio, sizeof ratio, "%8s", "-");
    std::printf("%-38s %-11s %8.2f %9zu | %s | %s | %s\n", c.label.c_str(), c.format.c_str(), mb, c.triangles, lfs, oms,
                ratio);
  }
  std::printf("lf/om: lodforge speed / OpenMesh speed (> 1: lodforge faster). Mt/s: million triangles per second.\n");
  return 0;
}
