// Hostile input across the OBJ, PLY, OFF and STL readers: every truncation and many seeded byte corruptions of
// small valid files must either load or throw IoError with a one-line message naming the file; nothing may
// crash, hang or allocate without bound. Also home of the small helpers the per-format test files share.

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "lodforge/core/validate.hpp"
#include "lodforge/io/asset.hpp"
#include "lodforge/io/formats.hpp"
#include "test_support.hpp"

namespace lodforge::io::io_test {

using Reader = Asset (*)(const std::filesystem::path&, std::string_view, const LoadOptions&);

// The IoError message of reading `bytes`, or "(no error)". Shared with obj/ply/off/stl_test.cpp.
std::string error_of(Reader read, std::string_view bytes, const LoadOptions& options) {
  try {
    read("hostile.bin", bytes, options);
  } catch (const IoError& e) {
    return e.what();
  }
  return "(no error)";
}

// Empty when `m` is structurally sound (indices in range, attribute arrays sized, no short faces, finite
// positions, a material per face), else what is wrong. Topology (non-manifold, duplicates) is not judged: the
// readers keep what the file holds. Shared with obj/ply/off/stl_test.cpp.
std::string structural_problems(const Mesh& m) {
  const ValidationReport r = validate(m);
  std::string out;
  if (r.out_of_range_indices) out += " out-of-range indices";
  if (r.attribute_size_errors) out += " attribute sizes";
  if (r.short_faces) out += " short faces";
  if (r.nonfinite_positions) out += " non-finite positions";
  if (m.materials.empty() || m.face_material.size() != m.face_count()) out += " materials";
  return out;
}

// Empty when the two meshes are the same (names aside), else the first difference found.
std::string first_difference(const Mesh& a, const Mesh& b) {
  auto diff = [](const char* what, std::size_t i) { return std::string(what) + " differ at " + std::to_string(i); };
  auto compare = [&](const char* what, const auto& x, const auto& y) -> std::string {
    if (x.size() != y.size()) {
      return std::string(what) + " sizes differ: " + std::to_string(x.size()) + " vs " + std::to_string(y.size());
    }
    for (std::size_t i = 0; i < x.size(); ++i) {
      if (!(x[i] == y[i])) return diff(what, i);
    }
    return {};
  };
  for (const std::string& d : {
           compare("positions", a.positions, b.positions),
           compare("wedge_vertex", a.wedge_vertex, b.wedge_vertex),
           compare("normals", a.normals, b.normals),
           compare("uv sets", a.uvs, b.uvs),
           compare("colour sets", a.colors, b.colors),
           compare("color_components", a.color_components, b.color_components),
           compare("face_offsets", a.face_offsets, b.face_offsets),
           compare("corner_wedge", a.corner_wedge, b.corner_wedge),
           compare("face_material", a.face_material, b.face_material),
           compare("face_group", a.face_group, b.face_group),
           compare("materials", a.materials, b.materials),
           compare("groups", a.groups, b.groups),
       }) {
    if (!d.empty()) return d;
  }
  if (a.formats != b.formats) return "formats differ";
  return {};
}

// A quad as Blender's PLY exporter up to 2.47 wrote it (script version 0.9, faces with UVs): its comment line
// has no "comment" keyword, and types are spelled float32/uint8/int32. Shared with ply_test.cpp.
std::string blender_247_ply() {
  return "ply\nformat ascii 1.0\nCreated by Blender3D 247 - www.blender.org, source file: crate.blend\n"
         "element vertex 4\nproperty float32 x\nproperty float32 y\nproperty float32 z\nproperty float32 nx\n"
         "property float32 ny\nproperty float32 nz\nproperty float32 s\nproperty float32 t\nproperty uint8 red\n"
         "property uint8 green\nproperty uint8 blue\nelement face 1\nproperty list uint8 int32 vertex_indices\n"
         "end_header\n"
         "1.000000 1.000000 0.000000 0.000000 0.000000 1.000000 1.000000 1.000000 255 255 255\n"
         "-1.000000 1.000000 0.000000 0.000000 0.000000 1.000000 0.000000 1.000000 255 0 0\n"
         "-1.000000 -1.000000 0.000000 0.000000 0.000000 1.000000 0.000000 0.000000 0 255 0\n"
         "1.000000 -1.000000 0.000000 0.000000 0.000000 1.000000 1.000000 0.000000 0 0 255\n"
         "4 0 1 2 3 \n";
}

// Saves `asset` under `file_name` in a fresh temporary folder and loads it back.
Asset save_and_reload(const Asset& asset, const std::string& file_name) {
  const auto dir = testing::temp_dir("io_round_trip_" + file_name);
  save_asset(asset, dir / file_name);
  Asset back = load_asset(dir / file_name);
  std::filesystem::remove_all(dir);
  return back;
}

namespace {

// The manifest's table row of a corpus file, split into its cells ("| a | b |" -> {"a", "b"}).
std::vector<std::string> manifest_row(const std::string& relative) {
  const auto manifest = testing::corpus_path("MANIFEST.md");
  if (manifest.empty()) return {};
  std::ifstream in(manifest);
  const std::string key = "| `" + relative + "` |";
  for (std::string line; std::getline(in, line);) {
    if (line.rfind(key, 0) != 0) continue;
    std::vector<std::string> cells;
    std::size_t at = 1;
    for (std::size_t bar = line.find('|', at); bar != std::string::npos; bar = line.find('|', at)) {
      std::string cell = line.substr(at, bar - at);
      cell.erase(0, cell.find_first_not_of(' '));
      cell.erase(cell.find_last_not_of(' ') + 1);
      cells.push_back(cell);
      at = bar + 1;
    }
    return cells;
  }
  return {};
}

}  // namespace

// Loads a corpus file, checks it against its MANIFEST.md row (V, face kinds, UVs/normals, groups), then saves
// it in its own format, loads that, and requires the same mesh. Shared with obj/ply/off/stl_test.cpp.
void expect_corpus_round_trip(const std::filesystem::path& file, const std::string& relative) {
  const std::vector<std::string> row = manifest_row(relative);
  // Cells: file, format, size, V, "tris / quads / ngons", Tri, quad-dominant, attributes, ...
  ASSERT_GE(row.size(), 8u) << relative << " has no row in MANIFEST.md";
  const std::size_t manifest_v = std::stoul(row[3]);
  std::size_t tris = 0, quads = 0, ngons = 0;
  ASSERT_EQ(std::sscanf(row[4].c_str(), "%zu / %zu / %zu", &tris, &quads, &ngons), 3) << row[4];
  const std::string& attributes = row[7];

  const auto start = std::chrono::steady_clock::now();
  const Asset a = load_asset(file);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const double mb = static_cast<double>(std::filesystem::file_size(file)) / 1e6;
  std::printf("[ load     ] %-40s %6.2f MB in %6.3f s (%6.1f MB/s)\n", relative.c_str(), mb, seconds, mb / seconds);
  // Generous bound for a shared, loaded build machine; the parser itself reads 100+ MB/s.
  EXPECT_LT(seconds, 0.5 + mb * 0.1) << relative << " loads slowly";

  ASSERT_EQ(a.meshes.size(), 1u);
  const Mesh& m = a.meshes[0];
  const FaceKindCounts kinds = count_face_kinds(m);
  EXPECT_EQ(kinds.triangles, tris) << relative;
  EXPECT_EQ(kinds.quads, quads) << relative;
  EXPECT_EQ(kinds.polygons, ngons) << relative;
  // Manifest V counts stored positions; lodforge welds equal positions (STL rows are already welded).
  EXPECT_LE(m.vertex_count(), manifest_v) << relative;
  if (a.format == Format::stl) {
    EXPECT_EQ(m.vertex_count(), manifest_v) << relative;
  }
  EXPECT_EQ(!m.uvs.empty(), attributes.find("uvs(") != std::string::npos) << relative << ": " << attributes;
  EXPECT_EQ(!m.normals.empty(), attributes.find("normals(") != std::string::npos) << relative << ": " << attributes;
  std::size_t groups = 0;
  for (const char* what : {" groups", " objects"}) {
    const std::size_t at = attributes.find(what);
    if (at == std::string::npos) continue;
    const std::size_t begin = attributes.find_last_of(" ,(", at - 1);
    const std::size_t first = begin == std::string::npos ? 0 : begin + 1;
    groups = std::stoul(attributes.substr(first, at - first));
  }
  EXPECT_EQ(m.groups.size(), groups) << relative;
  EXPECT_EQ(structural_problems(m), "") << relative;

  const Asset b = save_and_reload(a, file.filename().string());
  ASSERT_EQ(b.meshes.size(), 1u);
  EXPECT_EQ(first_difference(m, b.meshes[0]), "") << relative;
  EXPECT_EQ(a.obj_mtllibs, b.obj_mtllibs) << relative;
}

namespace {

struct Case {
  const char* name;
  Reader read;
  std::string bytes;
};

std::string binary_stl_two_triangles() {
  std::string s(80, ' ');
  const std::uint32_t n = 2;
  s.append(reinterpret_cast<const char*>(&n), 4);
  const float tris[2][12] = {{0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 0, 1, 1, 0, 0, 1, 1, 0, 0, 1, 0}};
  for (const auto& t : tris) {
    s.append(reinterpret_cast<const char*>(t), sizeof(t));
    s.append(2, '\0');
  }
  return s;
}

std::string binary_ply_quad(bool big_endian) {
  std::string s = std::string("ply\nformat ") + (big_endian ? "binary_big_endian" : "binary_little_endian") +
                  " 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
                  "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
  auto put = [&](const void* p, std::size_t n) {
    std::string b(static_cast<const char*>(p), n);
    if (big_endian) std::reverse(b.begin(), b.end());
    s += b;
  };
  const float v[4][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  for (const auto& p : v) {
    for (float x : p) put(&x, 4);
  }
  s += '\4';
  for (std::int32_t i = 0; i < 4; ++i) put(&i, 4);
  return s;
}

std::vector<Case> valid_cases() {
  return {
      {"obj", read_obj,
       "# cube corner\nmtllib a.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0 \r\nvt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 1\n"
       "g side\nusemtl red\nf 1/1/1 2/2/1 3/3/1\nf -4//1 -2//1 -1//1 \\\n 2//1\n"},
      {"ply_ascii", read_ply,
       "ply\nformat ascii 1.0\ncomment x\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
       "property uchar red\nproperty uchar green\nproperty uchar blue\nelement face 2\n"
       "property list uchar int vertex_indices\nend_header\n0 0 0 255 0 0\n1 0 0 0 255 0\n1 1 0 0 0 255\n"
       "0 1 0 9 9 9\n3 0 1 2\n4 0 1 2 3\n"},
      {"ply_le", read_ply, binary_ply_quad(false)},
      {"ply_be", read_ply, binary_ply_quad(true)},
      {"ply_blender247", read_ply, blender_247_ply()},
      {"off", read_off, "OFF\n# c\n4 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n4 0 1 2 3 255 0 0\n"},
      {"stl_ascii", read_stl,
       "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 1 1 0\nendloop\nendfacet\n"
       "endsolid t\n"},
      {"stl_binary", read_stl, binary_stl_two_triangles()},
  };
}

// Loads or fails cleanly; a loaded mesh must be internally consistent.
void expect_clean_outcome(const Case& c, std::string_view bytes, const std::string& what) {
  try {
    const Asset a = c.read("hostile.bin", bytes, LoadOptions{.max_elements = 1u << 16});
    ASSERT_EQ(a.meshes.size(), 1u) << what;
    EXPECT_EQ(structural_problems(a.meshes[0]), "") << what;
  } catch (const IoError& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.find('\n'), std::string::npos) << what << ": " << msg;
    EXPECT_EQ(msg.rfind("hostile.bin: ", 0), 0u) << what << ": " << msg;
    EXPECT_GT(e.problem().size(), 5u) << what;
  }
}

TEST(TextHostile, ValidSamplesLoad) {
  for (const Case& c : valid_cases()) {
    const Asset a = c.read("sample.bin", c.bytes, {});
    ASSERT_EQ(a.meshes.size(), 1u) << c.name;
    EXPECT_GE(a.meshes[0].face_count(), 1u) << c.name;
    EXPECT_EQ(structural_problems(a.meshes[0]), "") << c.name;
  }
}

TEST(TextHostile, EveryTruncationLoadsOrFailsCleanly) {
  for (const Case& c : valid_cases()) {
    for (std::size_t n = 0; n < c.bytes.size(); ++n) {
      expect_clean_outcome(c, std::string_view(c.bytes).substr(0, n), std::string(c.name) + " cut at " + std::to_string(n));
    }
  }
}

TEST(TextHostile, SeededByteCorruptionsLoadOrFailCleanly) {
  std::mt19937 rng(12345);  // fixed seed: the same corruptions every run
  const std::string interesting = std::string("0123456789-+.eE/ \n\r\t#nanif\\") + '\0' + "\xff\x7f\x80";
  for (const Case& c : valid_cases()) {
    for (int trial = 0; trial < 3000; ++trial) {
      std::string bytes = c.bytes;
      const int edits = 1 + static_cast<int>(rng() % 3);
      for (int e = 0; e < edits; ++e) {
        const std::size_t at = rng() % bytes.size();
        bytes[at] = (rng() % 2) ? interesting[rng() % interesting.size()] : static_cast<char>(rng());
      }
      expect_clean_outcome(c, bytes, std::string(c.name) + " trial " + std::to_string(trial));
    }
  }
}

TEST(TextHostile, EmptyInputIsRejectedByEveryReader) {
  for (Reader read : {read_obj, read_ply, read_off, read_stl}) {
    EXPECT_NE(error_of(read, "", {}).find("file is empty"), std::string::npos);
  }
}

TEST(TextHostile, LoadAssetNamesTheFileInTheMessage) {
  const auto dir = testing::temp_dir("text_hostile_names");
  for (const char* name : {"bad.obj", "bad.ply", "bad.off", "bad.stl"}) {
    {
      std::ofstream out(dir / name, std::ios::binary);
      out << "garbage \x01\x02 not a mesh\n";
    }
    try {
      load_asset(dir / name);
      ADD_FAILURE() << name << " loaded";
    } catch (const IoError& e) {
      EXPECT_EQ(e.file(), dir / name);
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace lodforge::io::io_test
