// A generated asset library for the batch tests (unit and CLI): small spheres, grids and tori in every
// supported format across three classes, a test config for it, and helpers to compare output folders.
#pragma once

#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <numbers>
#include <string>
#include <vector>

#include "lodforge/batch/config.hpp"
#include "lodforge/batch/runner.hpp"
#include "lodforge/core/mesh.hpp"
#include "lodforge/io/asset.hpp"
#include "lodforge/io/file.hpp"
#include "test_support.hpp"

namespace lodforge::batch::testlib {

namespace fs = std::filesystem;

// Three classes: props (OBJ/STL/GLB, a ratio chain), environment (PLY/OFF, a ratio then a triangle count
// from the source), characters (glTF/GLB, some with two meshes; a ratio then an error bound).
inline const char* kConfig = R"({
  "version": 1,
  "defaults": {"gltf_lods": "GLTF_LODS"},
  "classes": [
    {"name": "props", "match": ["props/**"], "lods": [{"ratio": 0.5}, {"ratio": 0.25}, {"ratio": 0.1}]},
    {"name": "environment", "match": ["env/**"], "lods": [{"ratio": 0.5}, {"triangles": 60, "from": "source"}]},
    {"name": "characters", "match": ["chars/**"], "lods": [{"ratio": 0.5}, {"max_error": {"relative": 0.03}}]}
  ]
})";

inline std::string config_text(const std::string& gltf_lods = "msft_lod") {
  std::string s = kConfig;
  s.replace(s.find("GLTF_LODS"), 9, gltf_lods);
  return s;
}

inline fs::path write_config(const fs::path& dir, const std::string& gltf_lods = "msft_lod") {
  const fs::path p = dir / "batch_config.json";
  std::ofstream(p, std::ios::binary) << config_text(gltf_lods);
  return p;
}

inline Mesh make_torus(int nu, int nv, float major, float minor) {
  Mesh m;
  for (int j = 0; j < nv; ++j) {
    for (int i = 0; i < nu; ++i) {
      const double u = 2 * std::numbers::pi * i / nu, v = 2 * std::numbers::pi * j / nv;
      const double r = major + minor * std::cos(v);
      m.add_vertex_with_wedge({{static_cast<float>(r * std::cos(u)), static_cast<float>(minor * std::sin(v)),
                                static_cast<float>(r * std::sin(u))}});
    }
  }
  auto id = [&](int i, int j) { return static_cast<std::uint32_t>((j % nv) * nu + (i % nu)); };
  for (int j = 0; j < nv; ++j) {
    for (int i = 0; i < nu; ++i) {
      m.add_face({id(i, j), id(i, j + 1), id(i + 1, j + 1)});
      m.add_face({id(i, j), id(i + 1, j + 1), id(i + 1, j)});
    }
  }
  m.materials.push_back(MaterialSlot{.name = "default"});
  return m;
}

// A bumpy grid (a height field) so that simplification has something to keep.
inline Mesh make_terrain(int n, int seed) {
  Mesh m = testing::make_grid(n, n, false);
  for (Vec3f& p : m.positions) {
    p[2] = static_cast<float>(0.3 * std::sin(p[0] * 0.7 + seed) * std::cos(p[1] * 0.5 + seed * 0.3));
  }
  return m;
}

// Asset i of the library: shape and size vary with i, so almost every asset differs; "props/dup_*" are two
// copies of one mesh (the runner simplifies it once).
inline Mesh library_mesh(int i) {
  switch (i % 3) {
    case 0:
      return testing::make_uv_sphere(8 + i % 9, 12 + i % 13, 1.0f + 0.01f * static_cast<float>(i));
    case 1:
      return make_terrain(10 + i % 14, i);
    default:
      return make_torus(12 + i % 11, 8 + i % 7, 1.0f, 0.25f + 0.002f * static_cast<float>(i));
  }
}

inline io::Asset asset_of(std::vector<Mesh> meshes, io::Format format, bool binary = true) {
  io::Asset a;
  a.format = format;
  a.binary = binary;
  a.meshes = std::move(meshes);
  return a;
}

struct Library {
  fs::path root;
  std::vector<std::string> files;  // relative, sorted
};

inline Library write_library(const fs::path& root, int count = 200) {
  Library lib{root, {}};
  const int props = count * 2 / 5, env = count * 3 / 10;
  for (int i = 0; i < count; ++i) {
    std::string rel;
    io::Format format;
    std::vector<Mesh> meshes{library_mesh(i)};
    if (i < props) {
      static const char* kExt[] = {"obj", "stl", "glb"};
      format = i % 3 == 0 ? io::Format::obj : i % 3 == 1 ? io::Format::stl : io::Format::glb;
      rel = "props/" + std::string(i % 2 ? "kitchen/" : "") + "prop_" + std::to_string(i) + "." + kExt[i % 3];
    } else if (i < props + env) {
      format = i % 2 ? io::Format::ply : io::Format::off;
      rel = "env/patch_" + std::to_string(i) + (i % 2 ? ".ply" : ".off");
    } else {
      format = i % 2 ? io::Format::gltf : io::Format::glb;
      rel = "chars/hero_" + std::to_string(i) + (i % 2 ? ".gltf" : ".glb");
      if (i % 4 == 0) meshes.push_back(make_torus(10, 6, 0.5f, 0.1f));  // a second mesh (and node)
    }
    fs::create_directories((root / rel).parent_path());
    io::save_asset(asset_of(std::move(meshes), format), root / rel);
    lib.files.push_back(rel);
  }
  const Mesh dup = testing::make_uv_sphere(10, 16, 2.0f);
  for (const char* rel : {"props/dup_a.obj", "props/dup_b.obj"}) {
    io::save_asset(asset_of({dup}, io::Format::obj), root / rel);
    lib.files.push_back(rel);
  }
  std::sort(lib.files.begin(), lib.files.end());
  return lib;
}

// Every file under `dir` except the cache, the reports and the LOD manifests (lods.json, lods.shard-*.json;
// lods_manifest_test.cpp checks those): relative path -> bytes.
inline std::map<std::string, std::string> read_outputs(const fs::path& dir) {
  std::map<std::string, std::string> out;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (!e.is_regular_file()) continue;
    const std::string rel = fs::relative(e.path(), dir).generic_string();
    if (rel.rfind(".lodforge-cache/", 0) == 0 || rel.rfind("report", 0) == 0) continue;
    if (rel == "lods.json" || rel.rfind("lods.shard-", 0) == 0) continue;
    out[rel] = io::read_file(e.path());
  }
  return out;
}

// Temporary files of atomic writes, or staged outputs of an unfinished asset, anywhere under `dir`.
inline std::vector<std::string> leftovers(const fs::path& dir) {
  std::vector<std::string> out;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    const std::string rel = fs::relative(e.path(), dir).generic_string();
    if (rel.find(".tmp-") != std::string::npos) out.push_back(rel);
    if (rel.find("/staging-") != std::string::npos && e.is_regular_file()) out.push_back(rel);
  }
  return out;
}

// ---- the Khronos glTF validator (test_support.hpp; skips when node or the module is absent) ----

using ::lodforge::testing::gltf_validator_unavailable;
using ::lodforge::testing::validate_gltf;

// The JSON of a .gltf, or of a .glb's JSON chunk.
inline nlohmann::json gltf_json(const fs::path& file) {
  std::string bytes = io::read_file(file);
  if (file.extension() == ".glb") {
    std::uint32_t length = 0;
    std::memcpy(&length, bytes.data() + 12, 4);
    bytes = bytes.substr(20, length);
  }
  return nlohmann::json::parse(bytes);
}

// The config of config_text() parsed, and a run of it from `lib` into `out` with `jobs` jobs.
inline BatchConfig config(const std::string& gltf_lods = "msft_lod") {
  return parse_config(nlohmann::json::parse(config_text(gltf_lods)), "test config");
}

inline RunResult run(const fs::path& lib, const fs::path& out, unsigned jobs, const BatchConfig& cfg = config()) {
  return run_batch(cfg, {.config_file = "test config", .input_dir = lib, .output_dir = out, .jobs = jobs});
}

}  // namespace lodforge::batch::testlib
