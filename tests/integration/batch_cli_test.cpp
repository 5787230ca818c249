// End-to-end tests of the batch commands (`run`, `validate-config`, `merge-reports`, `bench`): exit codes,
// log lines, and what a killed or interrupted run leaves behind.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <pty.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "../unit/batch/library_fixture.hpp"
#include "lodforge/core/topology.hpp"
#include "lodforge/core/validate.hpp"
#include "lodforge/io/asset.hpp"
#include "lodforge/io/file.hpp"
#include "test_support.hpp"

namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;
namespace testlib = lodforge::batch::testlib;

using CliResult = lodforge::testing::CommandResult;
using lodforge::testing::run_cli;

std::string q(const fs::path& p) {
  return lodforge::testing::shell_quote(p);
}

std::string run_args(const fs::path& config, const fs::path& lib, const fs::path& out, const std::string& more = "") {
  return "run --config " + q(config) + " --input " + q(lib) + " --output " + q(out) + " " + more;
}

// Starts the CLI in the background (output to `log`); returns its pid.
pid_t spawn_cli(const std::vector<std::string>& args, const fs::path& log) {
  const pid_t pid = fork();
  if (pid == 0) {
    const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    dup2(fd, 1);
    dup2(fd, 2);
    std::vector<char*> argv{const_cast<char*>(LODFORGE_CLI)};
    for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    execv(LODFORGE_CLI, argv.data());
    _exit(127);
  }
  return pid;
}

std::size_t cache_entries(const fs::path& out) {
  std::error_code ec;
  std::size_t n = 0;
  for (auto it = fs::directory_iterator(out / ".lodforge-cache/entries", ec); !ec && it != fs::directory_iterator();
       it.increment(ec)) {
    n += it->path().extension() == ".json";
  }
  return n;
}

// Waits until `out` has at least `entries` finished assets (or the child exits); true if it is still running.
bool wait_for_entries(pid_t pid, const fs::path& out, std::size_t entries) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  while (std::chrono::steady_clock::now() < deadline) {
    if (cache_entries(out) >= entries) return true;
    int status = 0;
    if (waitpid(pid, &status, WNOHANG) == pid) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return true;
}

void strip_seconds(Json& j) {
  if (j.is_object()) {
    j.erase("seconds");
    for (auto& [k, v] : j.items()) strip_seconds(v);
  } else if (j.is_array()) {
    for (Json& v : j) strip_seconds(v);
  }
}

Json comparable_report(const fs::path& file) {
  Json j = Json::parse(lodforge::io::read_file(file));
  strip_seconds(j);
  j["jobs"] = 0;
  j.erase("input_dir");  // the folders a run names differ between runs of the same work, like the job count
  j.erase("output_dir");
  return j;
}

TEST(BatchCli, HelpListsTheBatchCommands) {
  const CliResult r = run_cli("--help");
  for (const char* s : {"run", "validate-config", "merge-reports", "diff-reports", "bench"}) {
    EXPECT_NE(r.output.find(s), std::string::npos) << s;
  }
}

TEST(BatchCli, ValidateConfigPrintsTheEffectiveConfigOrEveryError) {
  const fs::path dir = lodforge::testing::temp_dir("batch_cli_validate");
  const CliResult ok = run_cli("validate-config " + q(fs::path(LODFORGE_SOURCE_DIR) / "configs/default.json"));
  EXPECT_EQ(ok.exit_code, 0) << ok.output;
  const Json effective = Json::parse(ok.output);
  EXPECT_EQ(effective["classes"].size(), 5u);  // quad_props, props, environment, characters, other
  EXPECT_TRUE(effective["defaults"].contains("engine")) << "defaults applied";

  std::ofstream(dir / "bad.json") << R"({"version": 1, "classes": [{"name": "a", "match": ["**"],
      "lods": [{"ratio": 0.5}, {"ratio": 0.7}], "colour": 1}]})";
  const CliResult bad = run_cli("validate-config " + q(dir / "bad.json"));
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.output.find("classes[0].lods[1].ratio"), std::string::npos) << bad.output;
  EXPECT_NE(bad.output.find("colour"), std::string::npos) << bad.output;
  EXPECT_EQ(run_cli("validate-config " + q(dir / "missing.json")).exit_code, 2);
}

TEST(BatchCli, RunWritesLodsAReportAndOneLogLinePerAsset) {
  const fs::path dir = lodforge::testing::temp_dir("batch_cli_run");
  const testlib::Library lib = testlib::write_library(dir / "lib", 30);
  const fs::path config = testlib::write_config(dir);
  const CliResult r = run_cli(run_args(config, lib.root, dir / "out", "--jobs 2"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string n = std::to_string(lib.files.size());
  EXPECT_NE(r.output.find("[1/" + n + "] "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("[" + n + "/" + n + "] "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(" LODs, "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("lodforge run: " + n + " assets: " + n + " ok (0 cache hits), 0 failed, 0 skipped"),
            std::string::npos)
      << r.output;
  EXPECT_TRUE(fs::exists(dir / "out/report.html"));
  const Json report = Json::parse(lodforge::io::read_file(dir / "out/report.json"));
  EXPECT_EQ(report["summary"]["succeeded"], lib.files.size());
  EXPECT_EQ(report["jobs"], 2);
  EXPECT_TRUE(report["shard"].is_null());
  EXPECT_TRUE(fs::exists(dir / "out/props/prop_0_LOD3.obj"));
  EXPECT_TRUE(fs::exists(dir / "out/chars/hero_22.glb"));
  EXPECT_TRUE(fs::exists(dir / "out/chars/hero_21.gltf") && fs::exists(dir / "out/chars/hero_21.bin"));

  const CliResult again = run_cli(run_args(config, lib.root, dir / "out", "--jobs 2"));
  EXPECT_EQ(again.exit_code, 0);
  EXPECT_NE(again.output.find("(" + n + " cache hits)"), std::string::npos) << again.output;
  EXPECT_NE(again.output.find("(cached)"), std::string::npos) << again.output;
}

// Everything the CLI writes to a terminal (stdout and stderr on one pseudo-terminal), and its exit code.
CliResult run_cli_on_terminal(const std::vector<std::string>& args) {
  CliResult r;
  int master = -1;
  const pid_t pid = forkpty(&master, nullptr, nullptr, nullptr);
  if (pid < 0) return r;
  if (pid == 0) {
    std::vector<char*> argv{const_cast<char*>(LODFORGE_CLI)};
    for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    execv(LODFORGE_CLI, argv.data());
    _exit(127);
  }
  std::array<char, 4096> buf{};
  for (;;) {
    const ssize_t n = ::read(master, buf.data(), buf.size());
    if (n > 0) {
      r.output.append(buf.data(), static_cast<std::size_t>(n));
    } else if (n < 0 && errno == EINTR) {
      continue;
    } else {
      break;  // EIO: the child closed the terminal (exited)
    }
  }
  ::close(master);
  int status = 0;
  waitpid(pid, &status, 0);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

TEST(BatchCli, ProgressIsOneLiveLineOnATerminal) {
  const fs::path dir = lodforge::testing::temp_dir("batch_cli_tty");
  const testlib::Library lib = testlib::write_library(dir / "lib", 30);
  const CliResult r = run_cli_on_terminal({"run", "--config", testlib::write_config(dir).string(), "--input",
                                           lib.root.string(), "--output", (dir / "out").string(), "--jobs", "2"});
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string n = std::to_string(lib.files.size());
  // The line is redrawn in place (carriage return, erase to the end of the line), at least for the last asset,
  // with the counts, the rate and the time left; it is erased before the summary.
  EXPECT_NE(r.output.find("\r\x1b[K[" + n + "/" + n + "] 100%  "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(" tri/s  ETA 0:00"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("\r\x1b[Klodforge run: " + n + " assets: " + n + " ok"), std::string::npos) << r.output;
  // No log lines ("[k/N] path: 3 LODs, 0.01 s"): those are for when stderr is not a terminal.
  for (const char* log : {": 2 LODs, ", ": 3 LODs, "}) EXPECT_EQ(r.output.find(log), std::string::npos) << r.output;
}

TEST(BatchCli, FailedAssetsExitOneAndAreListed) {
  const fs::path dir = lodforge::testing::temp_dir("batch_cli_failed");
  const testlib::Library lib = testlib::write_library(dir / "lib", 12);
  std::ofstream(lib.root / "props/broken.stl") << "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0\n";
  const CliResult r = run_cli(run_args(testlib::write_config(dir), lib.root, dir / "out"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("1 asset(s) failed:\n  props/broken.stl: "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("props/broken.stl: FAILED: "), std::string::npos) << r.output;
  EXPECT_TRUE(fs::exists(dir / "out/props/prop_0_LOD1.obj")) << "the others completed";
}

// A LOD that is not 10% smaller than the level before, and a triangle target the engine cannot reach (a
// tetrahedron cannot lose a face), miss their budgets: said per LOD in the report (with the floor that held
// the target), counted in the summary and on the last line, and exit 1 under --strict.
TEST(BatchCli, MissedBudgetsAreReportedAndFailStrictRuns) {
  const fs::path dir = lodforge::testing::temp_dir("batch_cli_missed");
  fs::create_directories(dir / "lib/a");
  lodforge::io::save_asset(testlib::asset_of({lodforge::testing::make_uv_sphere(12, 16)}, lodforge::io::Format::obj),
                           dir / "lib/a/sphere.obj");
  lodforge::io::save_asset(testlib::asset_of({lodforge::testing::make_tetrahedron()}, lodforge::io::Format::obj),
                           dir / "lib/a/tet.obj");
  std::ofstream(dir / "config.json") << R"({"version": 1, "classes": [{"name": "all", "match": ["**"],
            "lods": [{"ratio": 0.95}, {"ratio": 0.5}, {"max_error": {"relative": 0.05}}]}]})";
  const CliResult r = run_cli(run_args(dir / "config.json", dir / "lib", dir / "out"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const Json report = Json::parse(lodforge::io::read_file(dir / "out/report.json"));
  std::size_t missed = 0;
  for (const Json& a : report["assets"]) {
    for (const Json& l : a["lods"]) {
      const Json& b = l["budget"];
      ASSERT_TRUE(b.is_object());
      const bool is_missed = b["status"] == "missed";
      missed += is_missed;
      EXPECT_EQ(is_missed, !b["reasons"].empty());
      if (a["path"] == "a/sphere.obj" && l["level"] == 1) {
        EXPECT_TRUE(is_missed);
        EXPECT_NE(b["reasons"].dump().find("not 10% smaller than the source: shows its meshes"), std::string::npos)
            << b.dump();
        EXPECT_FALSE(fs::exists(dir / "out/a/sphere_LOD1.obj")) << "no near-copy file";
        EXPECT_TRUE(fs::exists(dir / "out/a/sphere_LOD2.obj"));
      }
      if (a["path"] == "a/sphere.obj" && l["level"] == 2) {
        EXPECT_FALSE(is_missed) << b.dump();
      }
      if (a["path"] == "a/sphere.obj" && l["level"] == 3) {
        EXPECT_FALSE(is_missed) << b.dump();
        EXPECT_TRUE(b.contains("collapses_backed_off"));
      }
      if (a["path"] == "a/tet.obj" && l["level"] == 2) {
        EXPECT_TRUE(is_missed);
        EXPECT_NE(b["reasons"].dump().find("target not reached"), std::string::npos) << b.dump();
        // What held it is named: a tetrahedron is a closed part at its smallest.
        EXPECT_NE(b["reasons"].dump().find("; floor: topology"), std::string::npos) << b.dump();
      }
    }
  }
  EXPECT_EQ(report["summary"]["lods_missed"], missed);
  EXPECT_GE(missed, 3u);
  EXPECT_NE(r.output.find(std::to_string(6 - missed) + " of 6 LOD(s) met their budget, " + std::to_string(missed) +
                          " missed"),
            std::string::npos)
      << r.output;
  const CliResult strict = run_cli(run_args(dir / "config.json", dir / "lib", dir / "out2", "--strict"));
  EXPECT_EQ(strict.exit_code, 1) << strict.output;
}

// Collision and occluder LODs: listed by --dry-run after the LODs, counted on their own line of the summary, and
// a missed one (here a volume budget too tight for the triangle target) fails a --strict run.
TEST(BatchCli, CollisionLodsArePlannedCountedAndFailStrictRunsWhenMissed) {
  const fs::path dir = lodforge::testing::temp_dir("batch_cli_collision");
  fs::create_directories(dir / "lib/a");
  lodforge::io::save_asset(testlib::asset_of({lodforge::testing::make_uv_sphere(12, 16)}, lodforge::io::Format::obj),
                           dir / "lib/a/sphere.obj");
  std::ofstream(dir / "config.json")
      << R"({"version": 1, "classes": [{"name": "all", "match": ["**"], "lods": [{"ratio": 0.5}],
            "collision": {"ratio": 0.05, "max_volume_growth": 0.5}, "occluder": {"triangles": 40}}]})";
  const CliResult plan = run_cli(run_args(dir / "config.json", dir / "lib", dir / "out", "--dry-run"));
  ASSERT_EQ(plan.exit_code, 0) << plan.output;
  EXPECT_NE(plan.output.find("LOD1 ratio 0.5; collision ratio 0.05, max_volume_growth 0.5%; occluder triangles 40;"),
            std::string::npos)
      << plan.output;
  const CliResult r = run_cli(run_args(dir / "config.json", dir / "lib", dir / "out"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("1 of 2 collision/occluder LOD(s) met their budget, 1 missed"), std::string::npos)
      << r.output;
  EXPECT_TRUE(fs::exists(dir / "out/a/sphere_collision.obj"));
  EXPECT_TRUE(fs::exists(dir / "out/a/sphere_occluder.obj"));
  const CliResult strict = run_cli(run_args(dir / "config.json", dir / "lib", dir / "out2", "--strict"));
  EXPECT_EQ(strict.exit_code, 1) << strict.output;
}

TEST(BatchCli, BadGltfFailsWithTheMessageOfTheSingleFileCommands) {
  const fs::path dir = lodforge::testing::temp_dir("batch_cli_gltf_number_range");
  const testlib::Library lib = testlib::write_library(dir / "lib", 12);
  const fs::path bad = lib.root / "chars/overflow.gltf";
  std::string text = lodforge::io::read_file(lib.root / "chars/hero_11.gltf");
  const auto max = text.find("\"max\":[");
  ASSERT_NE(max, std::string::npos);
  text.insert(max + 7, "1e999,");  // still valid JSON grammar; no double holds it
  std::ofstream(bad, std::ios::binary) << text;
  const CliResult info = run_cli("info " + q(bad));
  ASSERT_EQ(info.exit_code, 2) << info.output;
  const auto at = info.output.find("error: ");
  ASSERT_NE(at, std::string::npos) << info.output;
  std::string message = info.output.substr(at + 7, info.output.find('\n', at) - at - 7);
  EXPECT_NE(message.find("out of range"), std::string::npos) << message;
  // The run's log and report name the asset by its library path, so the message follows without the file's.
  ASSERT_EQ(message.rfind(bad.string() + ": ", 0), 0u) << message;
  message = message.substr(bad.string().size() + 2);

  const CliResult r = run_cli(run_args(testlib::write_config(dir), lib.root, dir / "out"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("chars/overflow.gltf: FAILED: " + message + "\n"), std::string::npos) << r.output;
  const Json report = Json::parse(lodforge::io::read_file(dir / "out/report.json"));
  for (const Json& a : report["assets"]) {
    if (a["path"] == "chars/overflow.gltf") {
      EXPECT_EQ(a["error"], message);
    }
  }
  EXPECT_TRUE(fs::exists(dir / "out/props/prop_0_LOD1.obj")) << "the others completed";
}

TEST(BatchCli, MemoryLimitBelowSixteenMegabytesIsRefused) {
  const fs::path dir = lodforge::testing::temp_dir("batch_cli_memory_floor");
  const testlib::Library lib = testlib::write_library(dir / "lib", 4);
  const fs::path config = testlib::write_config(dir);
  const CliResult low = run_cli(run_args(config, lib.root, dir / "out", "--memory-limit 15M"));
  EXPECT_EQ(low.exit_code, 2);
  EXPECT_EQ(low.output, "error: --memory-limit 15M is below the smallest limit, 16M\n");
  EXPECT_FALSE(fs::exists(dir / "out")) << "nothing is written";
  const CliResult bad = run_cli(run_args(config, lib.root, dir / "out", "--memory-limit lots"));
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.output.find("error: --memory-limit: 'lots' is not a byte size"), std::string::npos) << bad.output;
  const CliResult floor = run_cli(run_args(config, lib.root, dir / "out", "--memory-limit 16M"));
  EXPECT_EQ(floor.exit_code, 0) << floor.output;
}

// An asset estimated over the run's memory budget runs alone, and each LOD whose untiled run would not fit what
// is left is tiled (the report says the tile size); one that fits stays untiled. The tiled LODs are valid closed
// meshes near their targets; with room to spare nothing is tiled.
TEST(BatchCli, AnAssetOverTheMemoryBudgetIsTiled) {
  const fs::path dir = lodforge::testing::temp_dir("batch_cli_memory_tiles");
  lodforge::io::Asset asset;
  asset.format = lodforge::io::Format::ply;
  asset.meshes.push_back(lodforge::testing::make_uv_sphere(150, 200));  // about 60,000 triangles
  const std::size_t triangles = asset.meshes[0].face_count();
  fs::create_directories(dir / "lib/props");
  lodforge::io::save_asset(asset, dir / "lib/props/sphere.ply");
  const fs::path config = dir / "config.json";
  std::ofstream(config) << R"({"version": 1, "classes": [{"name": "props", "match": ["props/**"],
      "lods": [{"ratio": 0.5}, {"ratio": 0.1}, {"ratio": 0.02}]}]})";
  const CliResult r = run_cli(run_args(config, dir / "lib", dir / "out", "--memory-limit 16M --jobs 2"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const Json report = Json::parse(lodforge::io::read_file(dir / "out/report.json"));
  const Json& a = report["assets"][0];
  EXPECT_EQ(a["status"], "ok") << a.dump(1);
  EXPECT_FALSE(a.contains("warnings") && !a["warnings"].empty()) << a.dump(1);
  ASSERT_EQ(a["lods"].size(), 3u);
  EXPECT_TRUE(a["lods"][0]["memory_tile_triangles"].is_number()) << a["lods"][0].dump(1);
  EXPECT_LT(a["lods"][0]["memory_tile_triangles"].get<std::size_t>(), triangles / 4);
  EXPECT_TRUE(a["lods"][2]["memory_tile_triangles"].is_null()) << "a small LOD fits untiled";
  const double ratios[] = {0.5, 0.1, 0.02};
  for (int k = 0; k < 3; ++k) {
    const lodforge::io::Asset lod =
        lodforge::io::load_asset(dir / ("out/props/sphere_LOD" + std::to_string(k + 1) + ".ply"));
    ASSERT_EQ(lod.meshes.size(), 1u);
    const lodforge::Mesh& m = lod.meshes[0];
    EXPECT_TRUE(lodforge::validate(m).ok()) << k;
    EXPECT_TRUE(lodforge::summarize_topology(m, lodforge::build_topology(m)).closed_manifold()) << k;
    EXPECT_NEAR(static_cast<double>(m.face_count()), ratios[k] * static_cast<double>(triangles),
                0.01 * static_cast<double>(triangles) * ratios[k] + 2)
        << k;
  }
  const CliResult roomy = run_cli(run_args(config, dir / "lib", dir / "out2", "--memory-limit 4G"));
  ASSERT_EQ(roomy.exit_code, 0) << roomy.output;
  const Json report2 = Json::parse(lodforge::io::read_file(dir / "out2/report.json"));
  for (const Json& l : report2["assets"][0]["lods"]) EXPECT_TRUE(l["memory_tile_triangles"].is_null()) << l.dump(1);
}

TEST(BatchCli, JobsBeyondTheCoresAreWarnedAbout) {
  const fs::path dir = lodforge::testing::temp_dir("batch_cli_jobs_warning");
  const testlib::Library lib = testlib::write_library(dir / "lib", 3);
  const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
  const CliResult r =
      run_cli(run_args(testlib::write_config(dir), lib.root, dir / "out", "--jobs " + std::to_string(cores + 1)));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("warning: --jobs " + std::to_string(cores + 1) + " is more than the " +
                          std::to_string(cores) + " cores of this machine"),
            std::string::npos)
      << r.output;
  const CliResult fits = run_cli(run_args(testlib::write_config(dir), lib.root, dir / "out2", "--jobs 1"));
  EXPECT_EQ(fits.output.find("warning: --jobs"), std::string::npos) << fits.output;
}

TEST(BatchCli, UnsupportedFilesAreListedOnceWithACount) {
  const fs::path dir = lodforge::testing::temp_dir("batch_cli_unsupported");
  const testlib::Library lib = testlib::write_library(dir / "lib", 5);
  std::ofstream(lib.root / "props/crate.fbx") << "fbx";
  std::ofstream(lib.root / "props/barrel.fbx") << "fbx";
  std::ofstream(lib.root / "notes.txt") << "notes";
  std::ofstream(lib.root / "props/crate.png") << "a texture: not worth a warning";
  const CliResult r = run_cli(run_args(testlib::write_config(dir), lib.root, lib.root / "out"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  const std::string line =
      "warning: 3 file(s) of the library are not in a format lodforge reads and were ignored (.fbx 2, .txt 1): "
      "notes.txt, props/barrel.fbx, props/crate.fbx\n";
  EXPECT_NE(r.output.find(line), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("ignored", r.output.find(line) + line.size()), std::string::npos) << "listed once";
  // The report of a run into a folder inside the library is not a file of the library.
  const CliResult again = run_cli(run_args(testlib::write_config(dir), lib.root, lib.root / "out"));
  EXPECT_NE(again.output.find(line), std::string::npos) << again.output;
}

TEST(BatchCli, EmptyLibraryIsAnErrorAndWritesNothing) {
  const fs::path dir = lodforge::testing::temp_dir("batch_cli_empty_library");
  fs::create_directories(dir / "lib/sub");
  const CliResult empty = run_cli(run_args(testlib::write_config(dir), dir / "lib", dir / "out"));
  EXPECT_EQ(empty.exit_code, 2);
  EXPECT_NE(empty.output.find("error: " + (dir / "lib").string() + ": the library holds no asset files"),
            std::string::npos)
      << empty.output;
  EXPECT_FALSE(fs::exists(dir / "out"));
  std::ofstream(dir / "lib/sub/model.fbx") << "fbx";
  const CliResult only_fbx = run_cli(run_args(testlib::write_config(dir), dir / "lib", dir / "out"));
  EXPECT_EQ(only_fbx.exit_code, 2);
  EXPECT_NE(
      only_fbx.output.find(
          "no asset files (.gltf .glb .obj .ply .off .stl, or height maps a terrain class takes), only 1 file(s) of "
          "other types"),
      std::string::npos)
      << only_fbx.output;
  const CliResult file = run_cli(run_args(testlib::write_config(dir), dir / "lib/sub/model.fbx", dir / "out"));
  EXPECT_NE(file.output.find("model.fbx: is a file, not a folder (--input must be the library folder)"),
            std::string::npos)
      << file.output;
}

TEST(BatchCli, SkippedAssetsAreNamed) {
  const fs::path dir = lodforge::testing::temp_dir("batch_cli_skipped_named");
  const testlib::Library lib = testlib::write_library(dir / "lib", 5);
  fs::create_directories(lib.root / "misc");
  fs::copy_file(lib.root / lib.files.front(), lib.root / "misc" / fs::path(lib.files.front()).filename());
  const CliResult r = run_cli(run_args(testlib::write_config(dir), lib.root, dir / "out"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  const std::string name = "misc/" + fs::path(lib.files.front()).filename().string();
  EXPECT_NE(r.output.find("1 asset(s) skipped:\n  " + name + ": "), std::string::npos) << r.output;
}

TEST(BatchCli, FailureMessagesGiveThePathOnce) {
  const fs::path dir = lodforge::testing::temp_dir("batch_cli_path_once");
  const testlib::Library lib = testlib::write_library(dir / "lib", 5);
  std::ofstream(lib.root / "props/broken.obj") << "v 0 0 0\nv 1 0 0\nf 1 2 9\n";
  const CliResult r = run_cli(run_args(testlib::write_config(dir), lib.root, dir / "out"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("  props/broken.obj: line 3: "), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find((lib.root / "props/broken.obj").string()), std::string::npos) << r.output;
}

TEST(BatchCli, MergeReportsNamesAFileThatIsNoReport) {
  const fs::path dir = lodforge::testing::temp_dir("batch_cli_merge_not_report");
  const fs::path config = testlib::write_config(dir);
  const CliResult r = run_cli("merge-reports " + q(dir / "m.json") + " " + q(config));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("error: " + config.string() + ": not a lodforge report: "), std::string::npos) << r.output;
}

TEST(BatchCli, DiffReportsPrintsWhatChangedBetweenTwoRuns) {
  const fs::path dir = lodforge::testing::temp_dir("batch_cli_diff_reports");
  const testlib::Library lib = testlib::write_library(dir / "lib", 8);
  const fs::path config = testlib::write_config(dir);
  ASSERT_EQ(run_cli(run_args(config, lib.root, dir / "out")).exit_code, 0);
  fs::copy_file(dir / "out/report.json", dir / "a.json");
  lodforge::io::save_asset(testlib::asset_of({testlib::make_terrain(20, 7)}, lodforge::io::Format::obj),
                           dir / "lib/props/new_one.obj");
  ASSERT_EQ(run_cli(run_args(config, lib.root, dir / "out")).exit_code, 0);
  const CliResult r = run_cli("diff-reports " + q(dir / "a.json") + " " + q(dir / "out/report.json"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("1 added, 0 removed, 0 rebuilt, 0 changed status"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("added:\n  props/new_one.obj\n"), std::string::npos) << r.output;
  // The run itself put the same comparison in report.json and report.html.
  const Json report = Json::parse(lodforge::io::read_file(dir / "out/report.json"));
  EXPECT_EQ(report["changes"]["added"], Json::array({"props/new_one.obj"}));
  EXPECT_NE(lodforge::io::read_file(dir / "out/report.html").find("Changes since the previous run"), std::string::npos);

  const CliResult bad = run_cli("diff-reports " + q(dir / "a.json") + " " + q(config));
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.output.find("error: " + config.string() + ": not a lodforge report: "), std::string::npos)
      << bad.output;
  const CliResult missing = run_cli("diff-reports " + q(dir / "a.json") + " " + q(dir / "nope.json"));
  EXPECT_EQ(missing.exit_code, 2);
  EXPECT_NE(missing.output.find("nope.json"), std::string::npos) << missing.output;
  const CliResult help = run_cli("diff-reports --help");
  EXPECT_EQ(help.exit_code, 0);
  EXPECT_NE(help.output.find("moved by more than 5%"), std::string::npos) << help.output;
}

TEST(BatchCli, DryRunPrintsClassTargetsAndRebuildsAndWritesNothing) {
  const fs::path dir = lodforge::testing::temp_dir("batch_cli_dry_run");
  const testlib::Library lib = testlib::write_library(dir / "lib", 5);
  const fs::path config = testlib::write_config(dir);
  const CliResult dry = run_cli(run_args(config, lib.root, dir / "out", "--dry-run"));
  EXPECT_EQ(dry.exit_code, 0) << dry.output;
  EXPECT_FALSE(fs::exists(dir / "out"));
  const std::string prop =
      *std::find_if(lib.files.begin(), lib.files.end(), [](const std::string& p) { return p.rfind("props/", 0) == 0; });
  EXPECT_NE(dry.output.find(prop + ": class props; LOD1 ratio 0.5, LOD2 ratio 0.25, LOD3 ratio 0.1; rebuild (not "
                                   "built yet)\n"),
            std::string::npos)
      << dry.output;
  const std::string n = std::to_string(lib.files.size());
  EXPECT_NE(dry.output.find("lodforge run --dry-run: " + n + " assets: " + n +
                            " would be rebuilt, 0 up to date, 0 skipped; nothing written"),
            std::string::npos)
      << dry.output;
  ASSERT_EQ(run_cli(run_args(config, lib.root, dir / "out")).exit_code, 0);
  const CliResult again = run_cli(run_args(config, lib.root, dir / "out", "--dry-run"));
  EXPECT_NE(again.output.find(prop + ": class props; LOD1 ratio 0.5, LOD2 ratio 0.25, LOD3 ratio 0.1; up to date\n"),
            std::string::npos)
      << again.output;
}

TEST(BatchCli, StaleOutputsAreReportedAndPrunedWithPrune) {
  const fs::path dir = lodforge::testing::temp_dir("batch_cli_prune");
  const testlib::Library lib = testlib::write_library(dir / "lib", 5);
  const fs::path config = testlib::write_config(dir);
  ASSERT_EQ(run_cli(run_args(config, lib.root, dir / "out")).exit_code, 0);
  const std::string prop = *std::find_if(lib.files.begin(), lib.files.end(), [](const std::string& p) {
    return p.rfind("props/", 0) == 0 && fs::path(p).extension() == ".obj";
  });
  const fs::path lod1 = dir / "out" / fs::path(prop).parent_path() / (fs::path(prop).stem().string() + "_LOD1.obj");
  ASSERT_TRUE(fs::exists(lod1));
  fs::remove(lib.root / prop);
  const CliResult listed = run_cli(run_args(config, lib.root, dir / "out"));
  EXPECT_EQ(listed.exit_code, 0) << listed.output;
  EXPECT_NE(listed.output.find("warning: 3 file(s) in " + (dir / "out").string() +
                               " are no longer produced by the library and config"),
            std::string::npos)
      << listed.output;
  EXPECT_TRUE(fs::exists(lod1));
  const CliResult pruned = run_cli(run_args(config, lib.root, dir / "out", "--prune"));
  EXPECT_EQ(pruned.exit_code, 0) << pruned.output;
  EXPECT_NE(pruned.output.find("pruned 3 output file(s) the library and config no longer produce:\n  removed " +
                               lod1.string() + "\n"),
            std::string::npos)
      << pruned.output;
  EXPECT_FALSE(fs::exists(lod1));
  const CliResult sharded = run_cli(run_args(config, lib.root, dir / "out", "--prune --shard 0/2"));
  EXPECT_EQ(sharded.exit_code, 2);
  EXPECT_NE(sharded.output.find("--prune cannot be used with --shard"), std::string::npos) << sharded.output;
}

TEST(BatchCli, SymbolicLinkLoopIsSkippedWithAWarning) {
  const fs::path dir = lodforge::testing::temp_dir("batch_cli_link_loop");
  const testlib::Library lib = testlib::write_library(dir / "lib", 6);
  fs::create_symlink("b", lib.root / "a");
  fs::create_symlink("a", lib.root / "b");
  const CliResult r = run_cli(run_args(testlib::write_config(dir), lib.root, dir / "out"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("warning: " + (lib.root / "a").string() + ": skipped: symbolic link loop\n"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find(std::to_string(lib.files.size()) + " assets: " + std::to_string(lib.files.size()) + " ok"),
            std::string::npos)
      << r.output;
}

TEST(BatchCli, UsageAndConfigErrorsExitTwoAndWriteNothing) {
  const fs::path dir = lodforge::testing::temp_dir("batch_cli_usage");
  const testlib::Library lib = testlib::write_library(dir / "lib", 3);
  const fs::path config = testlib::write_config(dir);
  std::ofstream(dir / "bad.json") << "{\"version\": 1, \"classes\": []";
  const std::vector<std::string> cases = {
      run_args(config, lib.root, dir / "out", "--shard 3/3"),
      run_args(config, lib.root, dir / "out", "--shard x"),
      run_args(config, lib.root, dir / "out", "--memory-limit lots"),
      run_args(config, dir / "no_such_library", dir / "out"),
      run_args(dir / "bad.json", lib.root, dir / "out"),
      run_args(dir / "missing.json", lib.root, dir / "out"),
      "run --config " + q(config) + " --input " + q(lib.root),  // no --output
  };
  for (const std::string& args : cases) {
    const CliResult r = run_cli(args);
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.output;
    EXPECT_FALSE(r.output.empty()) << args << ": says why";
  }
  EXPECT_FALSE(fs::exists(dir / "out"));
}

TEST(BatchCli, AssetTimeoutFailsSlowAssetsAndTheRunGoesOn) {
  const fs::path dir = lodforge::testing::temp_dir("batch_cli_timeout");
  const testlib::Library lib = testlib::write_library(dir / "lib", 6);
  const fs::path config = testlib::write_config(dir);
  // Too short for any asset: each fails with its stage, exit 1, the report lists them and no LOD is written.
  const CliResult r = run_cli(run_args(config, lib.root, dir / "out", "--asset-timeout 0.000001"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("props/prop_0.obj: timed out in the fingerprint stage (asset timeout 1e-06 s)"),
            std::string::npos)
      << r.output;
  const Json report = Json::parse(lodforge::io::read_file(dir / "out/report.json"));
  EXPECT_EQ(report["summary"]["failed"], lib.files.size());
  EXPECT_TRUE(testlib::read_outputs(dir / "out").empty());
  // The config's default applies unless the flag says otherwise; 0 is no limit.
  Json doc = Json::parse(testlib::config_text());
  doc["defaults"]["asset_timeout_s"] = 1e-6;
  std::ofstream(dir / "limited.json") << doc.dump();
  EXPECT_EQ(run_cli(run_args(dir / "limited.json", lib.root, dir / "out2")).exit_code, 1);
  EXPECT_EQ(run_cli(run_args(dir / "limited.json", lib.root, dir / "out2", "--asset-timeout 0")).exit_code, 0);
  EXPECT_EQ(run_cli(run_args(config, lib.root, dir / "out3", "--asset-timeout -1")).exit_code, 2);
  EXPECT_NE(run_cli("run --help").output.find("--asset-timeout"), std::string::npos);
}

TEST(BatchCli, KilledRunResumesToIdenticalOutputWithoutPartialFiles) {
  const fs::path dir = lodforge::testing::temp_dir("batch_cli_kill");
  const testlib::Library lib = testlib::write_library(dir / "lib", 200);
  const fs::path config = testlib::write_config(dir);
  ASSERT_EQ(run_cli(run_args(config, lib.root, dir / "clean", "--jobs 2")).exit_code, 0);
  const auto clean = testlib::read_outputs(dir / "clean");

  const pid_t pid = spawn_cli({"run", "--config", config.string(), "--input", lib.root.string(), "--output",
                               (dir / "out").string(), "--jobs", "1"},
                              dir / "killed.log");
  ASSERT_GT(pid, 0);
  const bool running = wait_for_entries(pid, dir / "out", 40);
  if (running) {
    kill(pid, SIGKILL);
    int status = 0;
    waitpid(pid, &status, 0);
    EXPECT_TRUE(WIFSIGNALED(status));
  }
  const std::size_t finished = cache_entries(dir / "out");
  EXPECT_GE(finished, 40u);
  // Whatever is in place is complete: every output file present equals the clean run's file.
  for (const auto& [rel, bytes] : testlib::read_outputs(dir / "out")) {
    ASSERT_TRUE(clean.count(rel)) << rel << " is not an output of a clean run";
    EXPECT_TRUE(clean.at(rel) == bytes) << rel << " is partial or different";
  }
  EXPECT_FALSE(fs::exists(dir / "out/report.json")) << "a killed run writes no report";

  const CliResult resumed = run_cli(run_args(config, lib.root, dir / "out", "--jobs 2"));
  EXPECT_EQ(resumed.exit_code, 0) << resumed.output;
  const Json report = Json::parse(lodforge::io::read_file(dir / "out/report.json"));
  EXPECT_GE(report["summary"]["cache_hits"].get<std::size_t>(), finished) << "finished assets are not redone";
  EXPECT_TRUE(testlib::read_outputs(dir / "out") == clean);
  EXPECT_TRUE(testlib::leftovers(dir / "out").empty());
  EXPECT_EQ(comparable_report(dir / "out/report.json")["summary"]["succeeded"], lib.files.size());
}

TEST(BatchCli, CtrlCFinishesAssetsInFlightWritesTheReportAndExits130) {
  const fs::path dir = lodforge::testing::temp_dir("batch_cli_sigint");
  const testlib::Library lib = testlib::write_library(dir / "lib", 200);
  const fs::path config = testlib::write_config(dir);
  const pid_t pid = spawn_cli({"run", "--config", config.string(), "--input", lib.root.string(), "--output",
                               (dir / "out").string(), "--jobs", "1"},
                              dir / "sigint.log");
  ASSERT_GT(pid, 0);
  if (!wait_for_entries(pid, dir / "out", 20)) GTEST_SKIP() << "the run finished before it could be interrupted";
  kill(pid, SIGINT);
  int status = 0;
  waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 130) << lodforge::io::read_file(dir / "sigint.log");
  const Json report = Json::parse(lodforge::io::read_file(dir / "out/report.json"));
  const std::size_t not_started = report["summary"]["not_started"].get<std::size_t>();
  EXPECT_GT(not_started, 0u);
  EXPECT_EQ(report["summary"]["skipped"].get<std::size_t>(), 0u) << "unstarted assets are not \"skipped\"";
  const std::string log = lodforge::io::read_file(dir / "sigint.log");
  EXPECT_NE(log.find(", " + std::to_string(not_started) + " not started\n"), std::string::npos) << log;
  EXPECT_NE(log.find("interrupted: " + std::to_string(not_started) + " asset(s) not started; run again to resume"),
            std::string::npos)
      << log;
  EXPECT_EQ(report["summary"]["succeeded"].get<std::size_t>(), cache_entries(dir / "out"));
  EXPECT_TRUE(testlib::leftovers(dir / "out").empty());
  EXPECT_EQ(run_cli(run_args(config, lib.root, dir / "out")).exit_code, 0);
}

TEST(BatchCli, ThreeShardsMergeToTheUnshardedReport) {
  const fs::path dir = lodforge::testing::temp_dir("batch_cli_shards");
  const testlib::Library lib = testlib::write_library(dir / "lib", 60);
  const fs::path config = testlib::write_config(dir);
  ASSERT_EQ(run_cli(run_args(config, lib.root, dir / "whole")).exit_code, 0);
  std::string merge = "merge-reports " + q(dir / "merged/report.json");
  fs::create_directories(dir / "merged");
  for (int k = 0; k < 3; ++k) {
    const fs::path out = dir / ("shard" + std::to_string(k));
    const CliResult r = run_cli(run_args(config, lib.root, out, "--shard " + std::to_string(k) + "/3"));
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const fs::path report = out / ("report.shard-" + std::to_string(k) + "-of-3.json");
    ASSERT_TRUE(fs::exists(report));
    EXPECT_FALSE(fs::exists(out / "report.json"));
    merge += " " + q(report);
  }
  const CliResult m = run_cli(merge);
  ASSERT_EQ(m.exit_code, 0) << m.output;
  EXPECT_NE(m.output.find("merged 3 reports: " + std::to_string(lib.files.size()) + " assets"), std::string::npos)
      << m.output;
  EXPECT_TRUE(fs::exists(dir / "merged/report.html"));
  const Json whole = comparable_report(dir / "whole/report.json");
  const Json merged = comparable_report(dir / "merged/report.json");
  EXPECT_EQ(merged, whole);
  // Merging a shard twice is refused.
  EXPECT_EQ(run_cli("merge-reports " + q(dir / "x.json") + " " + q(dir / "shard0/report.shard-0-of-3.json") + " " +
                    q(dir / "shard0/report.shard-0-of-3.json"))
                .exit_code,
            2);
}

TEST(BatchCli, BenchPrintsThroughputScalingAndStages) {
  const fs::path dir = lodforge::testing::temp_dir("batch_cli_bench");
  const testlib::Library lib = testlib::write_library(dir / "lib", 10);
  const CliResult r =
      run_cli("bench --config " + q(testlib::write_config(dir)) + " --input " + q(lib.root) + " --max-jobs 2");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  for (const char* s : {"assets/s", "input tri/s", "efficiency", "per-stage time", "measure"}) {
    EXPECT_NE(r.output.find(s), std::string::npos) << s << "\n" << r.output;
  }
  EXPECT_NE(r.output.find("\n   2 "), std::string::npos) << r.output;
}

TEST(BatchCli, DemoLibraryRunsWithTheDefaultConfig) {
  const fs::path dir = lodforge::testing::temp_dir("batch_cli_demo");
  ASSERT_EQ(run_cli("demo " + q(dir / "lib")).exit_code, 0);
  const CliResult r =
      run_cli(run_args(fs::path(LODFORGE_SOURCE_DIR) / "configs/default.json", dir / "lib", dir / "out"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("5 assets: 5 ok"), std::string::npos) << r.output;
  EXPECT_TRUE(fs::exists(dir / "out/characters/torus_ring.gltf"));
}

}  // namespace
