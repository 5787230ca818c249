// End-to-end tests of the `lodforge` command: exit codes, messages, and that bad input writes nothing.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "lodforge/core/validate.hpp"
#include "lodforge/io/asset.hpp"
#include "test_support.hpp"

namespace {

namespace fs = std::filesystem;

using lodforge::testing::run_cli;
using CliRun = lodforge::testing::CommandResult;

void write_text(const fs::path& p, const std::string& s) {
  std::ofstream(p, std::ios::binary) << s;
}

bool no_temporaries(const fs::path& dir) {
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.path().string().find(".tmp-") != std::string::npos) return false;
  }
  return true;
}

// A one-triangle glTF (positions and indices in a data URI) whose POSITION accessor's "max" is `max`.
std::string triangle_gltf(const std::string& max) {
  return R"({"asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
  "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": )" +
         max + R"(},
                {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 6}],
  "buffers": [{"byteLength": 44,
    "uri": "data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAAABAAIAAAA="}]})";
}

void write_scaled_grid(const fs::path& file, float scale);

TEST(Cli, HelpListsSubcommandsAndExitCodes) {
  const CliRun r = run_cli("--help");
  EXPECT_EQ(r.exit_code, 0);
  for (const char* s : {"info", "convert", "simplify", "eval", "demo", "Exit codes"}) {
    EXPECT_NE(r.output.find(s), std::string::npos) << s;
  }
}

TEST(Cli, UnknownSubcommandIsUsageError) { EXPECT_EQ(run_cli("frobnicate").exit_code, 2); }

TEST(Cli, UnknownCommandsAndOptionsAreNamedWithAGuess) {
  const CliRun option = run_cli("run --confg x.json --input a --output b");
  EXPECT_EQ(option.exit_code, 2);
  EXPECT_EQ(option.output.rfind("error: unknown option --confg (did you mean --config?)", 0), 0u) << option.output;
  const CliRun command = run_cli("rnu --config x.json");
  EXPECT_EQ(command.exit_code, 2);
  EXPECT_EQ(command.output, "error: unknown command rnu (did you mean run?)\n");
  const CliRun far = run_cli("frobnicate");
  EXPECT_NE(far.output.find("unknown command frobnicate (commands: "), std::string::npos) << far.output;
  const CliRun with_value = run_cli("simplify in.obj out.obj --ratoi=0.5");
  EXPECT_NE(with_value.output.find("unknown option --ratoi (did you mean --ratio?)"), std::string::npos)
      << with_value.output;
  EXPECT_EQ(with_value.exit_code, 2);
  // Values that look like options, and the options themselves, pass.
  EXPECT_EQ(run_cli("run --help").exit_code, 0);
  EXPECT_EQ(run_cli("--version").exit_code, 0);
}

TEST(Cli, RandomBytesStlSaysItIsNotAValidStlAndWhy) {
  const fs::path dir = lodforge::testing::temp_dir("cli_random_stl");
  std::string bytes(400, '\0');
  std::uint32_t state = 7;
  for (char& c : bytes) {
    state = state * 1664525u + 1013904223u;
    c = static_cast<char>(state >> 24);
  }
  bytes[0] = 'x';
  write_text(dir / "noise.stl", bytes);
  const CliRun r = run_cli("info " + (dir / "noise.stl").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("error: " + (dir / "noise.stl").string() + ": not a valid STL: read as binary STL"),
            std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find("LoadOptions"), std::string::npos) << r.output;
}

TEST(Cli, UnwritableOutputIsRefusedBeforeTheWork) {
  const fs::path dir = lodforge::testing::temp_dir("cli_output_fbx");
  write_text(dir / "t.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  for (const char* command : {"simplify", "convert"}) {
    const CliRun r = run_cli(std::string(command) + " " + (dir / "t.obj").string() + " " + (dir / "out.fbx").string());
    EXPECT_EQ(r.exit_code, 2) << r.output;
    EXPECT_EQ(r.output, "error: " + (dir / "out.fbx").string() +
                            ": unsupported file extension '.fbx' (supported: .gltf .glb .obj .ply .off .stl)\n");
  }
  // Unreadable input after a refused output is never even opened.
  const CliRun r = run_cli("simplify " + (dir / "missing.obj").string() + " " + (dir / "out.fbx").string());
  EXPECT_EQ(r.output.find("missing.obj"), std::string::npos) << r.output;
}

TEST(Cli, EmbeddedBuffersStayEmbedded) {
  const fs::path dir = lodforge::testing::temp_dir("cli_embedded_buffers");
  write_text(dir / "t.gltf", triangle_gltf("[1, 1, 0]"));
  for (const char* command : {"convert", "simplify"}) {
    const fs::path out = dir / (std::string(command) + ".gltf");
    const CliRun r = run_cli(std::string(command) + " " + (dir / "t.gltf").string() + " " + out.string());
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_FALSE(fs::exists(fs::path(out).replace_extension(".bin"))) << command;
    std::ifstream in(out);
    const std::string text((std::istreambuf_iterator<char>(in)), {});
    EXPECT_NE(text.find("\"uri\":\"data:application/octet-stream;base64,"), std::string::npos) << text;
    const CliRun info = run_cli("info " + out.string());
    EXPECT_EQ(info.exit_code, 0) << info.output;
    EXPECT_NE(info.output.find("1 triangles"), std::string::npos) << info.output;
  }
  // A .gltf with an external buffer keeps writing one.
  write_scaled_grid(dir / "grid.gltf", 1.0f);
  ASSERT_EQ(run_cli("convert " + (dir / "grid.gltf").string() + " " + (dir / "grid_out.gltf").string()).exit_code, 0);
  EXPECT_TRUE(fs::exists(dir / "grid_out.bin"));
}

TEST(Cli, InfoOnMissingFileNamesItAndExitsTwo) {
  const CliRun r = run_cli("info /nonexistent/dir/thing.obj");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("/nonexistent/dir/thing.obj: no such file"), std::string::npos) << r.output;
}

// info prints the mirror symmetry of each mesh; --symmetry-plane picks the plane or skips the detection.
TEST(Cli, InfoPrintsTheSymmetry) {
  const fs::path dir = lodforge::testing::temp_dir("cli_info_symmetry");
  write_text(dir / "cube.obj",
             "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
             "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n");
  const CliRun r = run_cli("info " + (dir / "cube.obj").string());
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("symmetry: 1.0000 of edges (12 of 12) have a mirror edge; plane normal"), std::string::npos)
      << r.output;
  const CliRun x = run_cli("info --symmetry-plane x " + (dir / "cube.obj").string());
  EXPECT_NE(x.output.find("plane normal (1, 0, 0), offset -0.5"), std::string::npos) << x.output;
  const CliRun none = run_cli("info --symmetry-plane none " + (dir / "cube.obj").string());
  EXPECT_NE(none.output.find("symmetry: not looked for"), std::string::npos) << none.output;
  EXPECT_NE(run_cli("info --symmetry-plane w " + (dir / "cube.obj").string()).exit_code, 0);
}

TEST(Cli, ConvertOfBadInputWritesNothing) {
  const fs::path dir = lodforge::testing::temp_dir("cli_bad_convert");
  write_text(dir / "broken.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
  const CliRun r = run_cli("convert " + (dir / "broken.obj").string() + " " + (dir / "out.ply").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("broken.obj"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "out.ply"));
  EXPECT_TRUE(no_temporaries(dir));
}

TEST(Cli, OutputThatIsAFolderIsRefusedBeforeAnythingIsWritten) {
  const fs::path dir = lodforge::testing::temp_dir("cli_output_folder");
  write_text(dir / "t.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  write_text(dir / "t.gltf", triangle_gltf("[1, 1, 0]"));
  for (const char* name : {"out.glb", "out.gltf", "out.obj", "out.ply"}) {
    fs::create_directories(dir / name);
    for (const char* in : {"t.obj", "t.gltf"}) {
      for (const char* command : {"convert", "simplify"}) {
        const std::string args = std::string(command) + " " + (dir / in).string() + " " + (dir / name).string();
        const CliRun r = run_cli(args);
        EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.output;
        EXPECT_NE(r.output.find("error: " + (dir / name).string() +
                                ": is an existing folder; the output must be a file name\n"),
                  std::string::npos)
            << args << "\n"
            << r.output;
        EXPECT_TRUE(fs::is_empty(dir / name)) << args;
      }
    }
  }
  EXPECT_FALSE(fs::exists(dir / "out.bin")) << "a .gltf output must not leave its buffer behind";
  EXPECT_TRUE(no_temporaries(dir));
}

TEST(Cli, ConvertEmptyAndWrongMagicGlbExitTwo) {
  const fs::path dir = lodforge::testing::temp_dir("cli_bad_glb");
  write_text(dir / "empty.glb", "");
  write_text(dir / "magic.glb", std::string("glTX\x02\0\0\0\x20\0\0\0", 12) + std::string(20, '\0'));
  for (const char* name : {"empty.glb", "magic.glb"}) {
    const CliRun r = run_cli("convert " + (dir / name).string() + " " + (dir / "out.glb").string());
    EXPECT_EQ(r.exit_code, 2) << name << ": " << r.output;
    EXPECT_NE(r.output.find(name), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(dir / "out.glb"));
  }
  EXPECT_TRUE(no_temporaries(dir));
}

TEST(Cli, GltfNumberOutOfRangeIsBadInputInEveryCommand) {
  const fs::path dir = lodforge::testing::temp_dir("cli_gltf_number_range");
  const fs::path good = dir / "good.gltf", bad = dir / "bad.gltf", out = dir / "out.glb";
  write_text(good, triangle_gltf("[1, 1, 0]"));
  write_text(bad, triangle_gltf("[1e999, 1, 0]"));
  ASSERT_EQ(run_cli("info " + good.string()).exit_code, 0);
  const std::string message = bad.string() + ": accessors[0].max[0]: number '1e999' is out of range";
  for (const std::string& args :
       {"info " + bad.string(), "convert " + bad.string() + " " + out.string(),
        "simplify " + bad.string() + " " + out.string(), "eval " + good.string() + " " + bad.string()}) {
    const CliRun r = run_cli(args);
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.output;
    EXPECT_NE(r.output.find("error: " + message), std::string::npos) << args << "\n" << r.output;
    EXPECT_FALSE(fs::exists(out)) << args;
  }
  EXPECT_TRUE(no_temporaries(dir));
}

TEST(Cli, EscapedExceptionIsAnInternalErrorOnOneLine) {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  GTEST_SKIP() << "a sanitizer's shadow memory does not fit under ulimit -v";
#endif
  // Out of memory while reading a file: not bad input (exit 2), and no abort either.
  const fs::path dir = lodforge::testing::temp_dir("cli_internal_error");
  write_text(dir / "huge.obj", "");
  fs::resize_file(dir / "huge.obj", 1ull << 30);  // sparse: no disk space used
  const CliRun r = lodforge::testing::run_command("ulimit -v 200000 && " + std::string(LODFORGE_CLI) + " info " +
                                                  lodforge::testing::shell_quote(dir / "huge.obj"));
  EXPECT_EQ(r.exit_code, 3) << r.output;
  EXPECT_EQ(r.output, "internal error: out of memory\n");
}

TEST(Cli, InfoOnAFolderSkipsASymbolicLinkLoopWithAWarning) {
  const fs::path dir = lodforge::testing::temp_dir("cli_info_link_loop");
  write_text(dir / "t.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  fs::create_symlink("b", dir / "a");
  fs::create_symlink("a", dir / "b");
  const CliRun r = run_cli("info " + dir.string());
  EXPECT_EQ(r.exit_code, 0) << r.output;
  for (const char* loop : {"a", "b"}) {
    EXPECT_NE(r.output.find("warning: " + (dir / loop).string() + ": skipped: symbolic link loop\n"), std::string::npos)
        << r.output;
  }
  EXPECT_NE(r.output.find("summary: 1 asset(s) loaded, 0 failed"), std::string::npos) << r.output;
}

TEST(Cli, DemoLibraryLoadsCleanlyWithInfo) {
  const fs::path dir = lodforge::testing::temp_dir("cli_demo");
  ASSERT_EQ(run_cli("demo " + dir.string()).exit_code, 0);
  const CliRun r = run_cli("info " + dir.string());
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("summary: 5 asset(s) loaded, 0 failed"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("validation: 1"), std::string::npos) << "a sample asset has validation findings:\n"
                                                                   << r.output;
}

TEST(Cli, DemoOutputMatchesTheBundledSampleLibrary) {
  // samples/library is the committed output of `lodforge demo`; they must not drift apart.
  const fs::path dir = lodforge::testing::temp_dir("cli_demo_match");
  ASSERT_EQ(run_cli("demo " + dir.string()).exit_code, 0);
  const fs::path lib = fs::path(LODFORGE_SOURCE_DIR) / "samples/library";
  std::size_t compared = 0;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (!e.is_regular_file()) continue;
    const fs::path rel = fs::relative(e.path(), dir);
    std::ifstream a(e.path(), std::ios::binary), b(lib / rel, std::ios::binary);
    ASSERT_TRUE(b.good()) << "samples/library lacks " << rel;
    const std::string sa((std::istreambuf_iterator<char>(a)), {}), sb((std::istreambuf_iterator<char>(b)), {});
    EXPECT_TRUE(sa == sb) << rel << " differs from the demo output (regenerate with `lodforge demo samples/library`)";
    ++compared;
  }
  EXPECT_GE(compared, 5u);
}

TEST(Cli, SimplifyAndEvalOnDemoAsset) {
  const fs::path dir = lodforge::testing::temp_dir("cli_simplify");
  ASSERT_EQ(run_cli("demo " + dir.string()).exit_code, 0);
  const fs::path in = dir / "environment/rock.ply", out = dir / "rock_lod1.ply";
  const CliRun s = run_cli("simplify " + in.string() + " " + out.string() + " --ratio 0.25");
  ASSERT_EQ(s.exit_code, 0) << s.output;
  ASSERT_TRUE(fs::exists(out));
  const CliRun e = run_cli("eval " + in.string() + " " + out.string() + " --json");
  ASSERT_EQ(e.exit_code, 0) << e.output;
  EXPECT_NE(e.output.find("\"hausdorff_rel\""), std::string::npos);
}

TEST(Cli, SimplifyRejectsInvalidOptions) {
  const fs::path dir = lodforge::testing::temp_dir("cli_simplify_bad");
  ASSERT_EQ(run_cli("demo " + dir.string()).exit_code, 0);
  const CliRun r = run_cli("simplify " + (dir / "environment/rock.ply").string() + " " + (dir / "x.ply").string() +
                        " --ratio 1.5");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("error: --ratio must be in (0, 1], got 1.5"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("target_ratio"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "x.ply"));
}

// --tiling on cuts even a small mesh into tiles (and says so); off and the automatic default below the threshold
// do not; a tile size below 100 is refused by its option name.
TEST(Cli, SimplifyTilesOnRequest) {
  const fs::path dir = lodforge::testing::temp_dir("cli_simplify_tiling");
  ASSERT_EQ(run_cli("demo " + dir.string()).exit_code, 0);
  const std::string in = (dir / "environment/rock.ply").string(), out = (dir / "rock_tiled.ply").string();
  const CliRun on = run_cli("simplify " + in + " " + out + " --ratio 0.25 --tiling on --tile-triangles 100");
  ASSERT_EQ(on.exit_code, 0) << on.output;
  EXPECT_NE(on.output.find("tiled: "), std::string::npos) << on.output;
  EXPECT_TRUE(fs::exists(out));
  for (const char* mode : {"off", "auto"}) {
    const CliRun r = run_cli("simplify " + in + " " + out + " --ratio 0.25 --tiling " + mode);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_EQ(r.output.find("tiled: "), std::string::npos) << r.output;
  }
  const CliRun small = run_cli("simplify " + in + " " + (dir / "x.ply").string() + " --tiling on --tile-triangles 5");
  EXPECT_EQ(small.exit_code, 2);
  EXPECT_NE(small.output.find("error: --tile-triangles must be at least 100, got 5"), std::string::npos) << small.output;
  const CliRun bad = run_cli("simplify " + in + " " + (dir / "x.ply").string() + " --tiling sometimes");
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  EXPECT_FALSE(fs::exists(dir / "x.ply"));
}

// --memory-limit 16M: a mesh whose untiled estimate is over it is tiled (and its output valid); limits below
// 16M and malformed sizes are refused by the option's name, and nothing is written.
TEST(Cli, SimplifyTilesUnderAMemoryLimit) {
  const fs::path dir = lodforge::testing::temp_dir("cli_simplify_memory");
  lodforge::io::Asset asset;
  asset.format = lodforge::io::Format::ply;
  asset.meshes.push_back(lodforge::testing::make_uv_sphere(200, 300));  // about 120,000 triangles
  const std::size_t triangles = asset.meshes[0].face_count();
  const std::string in = (dir / "sphere.ply").string(), out = (dir / "sphere_lod.ply").string();
  lodforge::io::save_asset(asset, in);
  const CliRun r = run_cli("simplify " + in + " " + out + " --ratio 0.05 --memory-limit 16M");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("over --memory-limit 16M: tiled in tiles of"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("tiled: "), std::string::npos) << r.output;
  const lodforge::io::Asset lod = lodforge::io::load_asset(out);
  ASSERT_EQ(lod.meshes.size(), 1u);
  EXPECT_TRUE(lodforge::validate(lod.meshes[0]).ok());
  EXPECT_LE(lod.meshes[0].face_count(), triangles / 20 + 1);
  const CliRun roomy = run_cli("simplify " + in + " " + out + " --ratio 0.05 --memory-limit 4G");
  ASSERT_EQ(roomy.exit_code, 0) << roomy.output;
  EXPECT_EQ(roomy.output.find("tiled"), std::string::npos) << roomy.output;
  const std::string x = (dir / "x.ply").string();
  for (const char* bad : {"15M", "12X", "M", "1.5G"}) {
    const CliRun b = run_cli("simplify " + in + " " + x + " --ratio 0.5 --memory-limit " + bad);
    EXPECT_EQ(b.exit_code, 2) << b.output;
    EXPECT_NE(b.output.find("error: --memory-limit: memory limit '" + std::string(bad) + "'"), std::string::npos)
        << b.output;
  }
  const CliRun cluster = run_cli("simplify " + in + " " + x + " --ratio 0.5 --engine cluster --memory-limit 16M");
  EXPECT_EQ(cluster.exit_code, 2) << cluster.output;
  EXPECT_NE(cluster.output.find("error: " + in + ": mesh 0 (" + std::to_string(triangles) +
                                " triangles) does not fit in --memory-limit 16M"),
            std::string::npos)
      << cluster.output;
  EXPECT_FALSE(fs::exists(x));
}

// A binary PLY too large to load whole under the limit is streamed out of core: tiles on disk (removed
// afterwards), a valid LOD at the target; an OBJ with normals is refused by name, and nothing is written.
TEST(Cli, SimplifyStreamsAFileThatCannotLoadWhole) {
  const fs::path dir = lodforge::testing::temp_dir("cli_simplify_stream");
  lodforge::io::Asset asset;
  asset.format = lodforge::io::Format::ply;
  asset.binary = true;
  asset.meshes.push_back(lodforge::testing::make_uv_sphere(400, 500));  // about 400,000 triangles
  const std::size_t triangles = asset.meshes[0].face_count();
  const std::string in = (dir / "sphere.ply").string(), out = (dir / "sphere_lod.ply").string();
  lodforge::io::save_asset(asset, in);
  const CliRun r = run_cli("simplify " + in + " " + out + " --ratio 0.01 --memory-limit 32M");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("over --memory-limit 32M: streamed out of core in tiles of"), std::string::npos) << r.output;
  const lodforge::io::Asset lod = lodforge::io::load_asset(out);
  ASSERT_EQ(lod.meshes.size(), 1u);
  EXPECT_TRUE(lodforge::validate(lod.meshes[0]).ok());
  EXPECT_LE(lod.meshes[0].face_count(), triangles / 100 + 1);
  EXPECT_GT(lod.meshes[0].face_count(), triangles / 100 * 9 / 10);
  EXPECT_FALSE(fs::exists(out + ".lodforge-tiles")) << "the tile folder is removed";
  // With room, the same file loads whole.
  const CliRun roomy = run_cli("simplify " + in + " " + out + " --ratio 0.01 --memory-limit 4G");
  ASSERT_EQ(roomy.exit_code, 0) << roomy.output;
  EXPECT_EQ(roomy.output.find("streamed"), std::string::npos) << roomy.output;
  // Normals would be lost: refused, naming the file and what it has.
  asset.format = lodforge::io::Format::obj;
  lodforge::Mesh& m = asset.meshes[0];
  m.normals.assign(m.wedge_count(), lodforge::Vec3f{{0, 0, 1}});
  const std::string obj = (dir / "normals.obj").string(), x = (dir / "x.obj").string();
  lodforge::io::save_asset(asset, obj);
  const CliRun refused = run_cli("simplify " + obj + " " + x + " --ratio 0.01 --memory-limit 32M");
  EXPECT_EQ(refused.exit_code, 2) << refused.output;
  EXPECT_NE(refused.output.find("error: " + obj + ": line "), std::string::npos) << refused.output;
  EXPECT_NE(refused.output.find("normals ('vn')"), std::string::npos) << refused.output;
  EXPECT_FALSE(fs::exists(x));
  EXPECT_FALSE(fs::exists(x + ".lodforge-tiles"));
}

}  // namespace

namespace {

// A glTF of one 2x2-quad grid (8 triangles) spanning [0, 1]^2 in world space, written with its positions divided
// by `scale` under a node that scales by `scale` and moves by (5, 0, 0) (then back by the mesh's offset): what
// gltfpack does when it moves dequantisation into node transforms.
void write_scaled_grid(const fs::path& file, float scale) {
  std::vector<float> positions;
  for (int y = 0; y <= 2; ++y) {
    for (int x = 0; x <= 2; ++x) {
      for (float c : {x * 0.5f, y * 0.5f, 0.0f}) positions.push_back(c / scale);
    }
  }
  std::vector<std::uint16_t> indices;
  for (int y = 0; y < 2; ++y) {
    for (int x = 0; x < 2; ++x) {
      const std::uint16_t a = static_cast<std::uint16_t>(y * 3 + x), b = a + 1, c = a + 3, d = a + 4;
      for (std::uint16_t i : {a, b, d, a, d, c}) indices.push_back(i);
    }
  }
  std::string bin(reinterpret_cast<const char*>(positions.data()), positions.size() * 4);
  bin.append(reinterpret_cast<const char*>(indices.data()), indices.size() * 2);
  const fs::path bin_file = fs::path(file).replace_extension(".bin");
  write_text(bin_file, bin);
  const auto text = [](double x) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.9g", x);
    return std::string(buf);
  };
  const std::string s = text(scale);
  write_text(file, R"({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
  "nodes": [{"translation": [5, 0, 0], "children": [1]}, {"mesh": 0, "scale": [)" + s + "," + s + "," + s + R"(]}],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
  "accessors": [{"bufferView": 0, "componentType": 5126, "count": 9, "type": "VEC3", "min": [0, 0, 0],
                 "max": [)" + text(1 / scale) + "," + text(1 / scale) + R"(, 0]},
                {"bufferView": 1, "componentType": 5123, "count": 24, "type": "SCALAR"}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 108}, {"buffer": 0, "byteOffset": 108, "byteLength": 48}],
  "buffers": [{"byteLength": 156, "uri": ")" + bin_file.filename().string() + R"("}]})");
}

TEST(Cli, EvalMeasuresInWorldSpaceThroughNodeTransforms) {
  const fs::path dir = lodforge::testing::temp_dir("cli_eval_world");
  write_scaled_grid(dir / "plain.gltf", 1.0f);
  write_scaled_grid(dir / "packed.gltf", 1.0f / 16383.0f);  // positions in the thousands, node scale 1/16383
  const CliRun r = run_cli("eval " + (dir / "plain.gltf").string() + " " + (dir / "packed.gltf").string() + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto number = [&](const std::string& key) {
    const auto at = r.output.find("\"" + key + "\": ");
    return at == std::string::npos ? -1.0 : std::stod(r.output.substr(at + key.size() + 4));
  };
  EXPECT_NEAR(number("diagonal"), std::sqrt(2.0), 1e-4) << r.output;
  EXPECT_LT(number("hausdorff_rel"), 1e-4) << "the same surface in the world: " << r.output;
  const CliRun info = run_cli("info " + (dir / "packed.gltf").string());
  EXPECT_EQ(info.exit_code, 0) << info.output;
}

TEST(Cli, RunBudgetsAndReportsTheWorldSizeOfAScaledMesh) {
  const fs::path dir = lodforge::testing::temp_dir("cli_run_world");
  fs::create_directories(dir / "lib");
  write_scaled_grid(dir / "lib/packed.gltf", 1.0f / 16383.0f);
  write_text(dir / "config.json", R"({"version": 1, "classes": [{"name": "all", "match": ["**"],
      "lods": [{"max_error": {"relative": 0.01}}]}]})");
  const CliRun r = run_cli("run --config " + (dir / "config.json").string() + " --input " + (dir / "lib").string() +
                           " --output " + (dir / "out").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const nlohmann::json report = nlohmann::json::parse(std::ifstream(dir / "out/report.json"));
  const nlohmann::json& asset = report["assets"][0];
  EXPECT_NEAR(asset["input"]["diagonal"].get<double>(), std::sqrt(2.0), 1e-4);
  const nlohmann::json& lod = asset["lods"][0];
  EXPECT_LE(lod["hausdorff_rel"].get<double>(), 0.01) << lod.dump();
  EXPECT_LE(lod["error_bound_rel"].get<double>(), 0.01) << lod.dump();
}

}  // namespace
