// Streaming readers (out-of-core input): binary PLY and OBJ read front to back, positions and polygons only,
// with everything they would drop refused by name.
#include "lodforge/io/stream.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include "lodforge/io/asset.hpp"
#include "test_support.hpp"

namespace lodforge::io {
namespace {

struct Read {
  std::vector<Vec3f> positions;
  std::vector<std::vector<std::uint32_t>> faces;
  std::vector<std::string> warnings;
  std::string material;
  std::vector<std::string> mtllibs;
};

Read stream(const std::filesystem::path& path) {
  Read r;
  StreamResult s = stream_mesh(path, {.vertex = [&](const Vec3f& p) { r.positions.push_back(p); },
                                      .face = [&](std::span<const std::uint32_t> f) { r.faces.emplace_back(f.begin(), f.end()); }});
  r.warnings = std::move(s.warnings);
  r.material = std::move(s.material);
  r.mtllibs = std::move(s.mtllibs);
  return r;
}

std::string error_of(const std::filesystem::path& path) {
  try {
    stream(path);
  } catch (const IoError& e) {
    return e.what();
  }
  return "";
}

std::filesystem::path write(const std::string& name, const std::string& bytes) {
  // A folder per file: ctest runs these tests in parallel processes.
  const std::filesystem::path p = testing::temp_dir("io_stream_" + name) / name;
  std::ofstream(p, std::ios::binary) << bytes;
  return p;
}

template <typename T>
void put_be(std::string& out, T x) {
  unsigned char b[sizeof(T)];
  std::memcpy(b, &x, sizeof(T));
  for (std::size_t i = sizeof(T); i-- > 0;) out.push_back(static_cast<char>(b[i]));
}

// A big-endian PLY with an extra vertex property, an extra face property and an element the reader skips:
// a quad and a triangle over five vertices.
std::string big_endian_ply(const std::string& extra_vertex_property = "float confidence") {
  std::string s =
      "ply\nformat binary_big_endian 1.0\ncomment test\nelement vertex 5\nproperty float x\nproperty float y\n"
      "property float z\nproperty " + extra_vertex_property + "\nelement face 2\nproperty list uchar int vertex_indices\n"
      "property uchar flags\nelement edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n";
  const float v[5][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {2, 0.5f, 0.25f}};
  for (const auto& p : v) {
    for (float x : p) put_be(s, x);
    put_be(s, 0.5f);
  }
  s.push_back(4);
  for (std::int32_t i : {0, 1, 2, 3}) put_be(s, i);
  s.push_back(7);
  s.push_back(3);
  for (std::int32_t i : {1, 4, 2}) put_be(s, i);
  s.push_back(7);
  put_be(s, std::int32_t{0});
  put_be(s, std::int32_t{1});
  return s;
}

TEST(StreamMesh, BinaryPlyGivesWhatTheWholeReaderGives) {
  const std::filesystem::path p = write("be.ply", big_endian_ply());
  const Read r = stream(p);
  const Asset whole = load_asset(p);
  ASSERT_EQ(whole.meshes.size(), 1u);
  EXPECT_EQ(r.positions, whole.meshes[0].positions);
  ASSERT_EQ(r.faces.size(), 2u);
  EXPECT_EQ(r.faces[0], (std::vector<std::uint32_t>{0, 1, 2, 3}));
  EXPECT_EQ(r.faces[1], (std::vector<std::uint32_t>{1, 4, 2}));
  const StreamCounts c = stream_counts(p);
  EXPECT_EQ(c.vertices, 5u);
  EXPECT_EQ(c.triangles, 2u);  // one per face: the header does not say how many corners
}

TEST(StreamMesh, PlyRefusesWhatItWouldDropAndBadData) {
  EXPECT_NE(error_of(write("normals.ply", big_endian_ply("float nx"))).find("'nx'"), std::string::npos);
  const std::string whole = big_endian_ply();
  const std::string truncated = error_of(write("short.ply", whole.substr(0, whole.size() - 50)));
  EXPECT_NE(truncated.find("truncated"), std::string::npos) << truncated;
  EXPECT_NE(error_of(write("ascii.ply", "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n"
                                        "property float z\nend_header\n"))
                .find("ASCII"),
            std::string::npos);
  std::string late = big_endian_ply();
  const std::string out_of_range = error_of(write("range.ply", [&] {
    std::string s = late;
    // The triangle's last index (the file's last face index before the flags and the edge) becomes 9.
    const std::size_t at = s.size() - 8 - 1 - 4;
    s[at + 3] = 9;
    return s;
  }()));
  EXPECT_NE(out_of_range.find("uses vertex 9"), std::string::npos) << out_of_range;
  const std::string faces_first =
      error_of(write("faces_first.ply", "ply\nformat binary_little_endian 1.0\nelement face 0\nproperty list uchar int "
                                        "vertex_indices\nelement vertex 0\nproperty float x\nproperty float y\nproperty "
                                        "float z\nend_header\n"));
  EXPECT_NE(faces_first.find("before the vertex element"), std::string::npos) << faces_first;
}

TEST(StreamMesh, ObjPolygonsRelativeIndicesAndSkippedStatements) {
  const std::filesystem::path p =
      write("quad.obj", "# a quad and a triangle\nmtllib x.mtl\no thing\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0 1\n"
                        "s off\nusemtl red\nf 1 2 3 4\nv 2 0.5 0.25\nusemtl red\nf -4 -1 -3\nl 1 2\n");
  const Read r = stream(p);
  ASSERT_EQ(r.positions.size(), 5u);
  EXPECT_EQ(r.positions[4], (Vec3f{{2, 0.5f, 0.25f}}));
  ASSERT_EQ(r.faces.size(), 2u);
  EXPECT_EQ(r.faces[0], (std::vector<std::uint32_t>{0, 1, 2, 3}));
  EXPECT_EQ(r.faces[1], (std::vector<std::uint32_t>{1, 4, 2}));
  EXPECT_EQ(r.material, "red");
  EXPECT_EQ(r.mtllibs, std::vector<std::string>{"x.mtl"});
  ASSERT_EQ(r.warnings.size(), 2u);  // 'l' and 'o', each once
  EXPECT_NE(r.warnings[1].find("groups are not kept"), std::string::npos) << r.warnings[1];
  const StreamCounts c = stream_counts(p);
  EXPECT_EQ(c.vertices, 5u);
  EXPECT_EQ(c.triangles, 3u);
}

TEST(StreamMesh, ObjRefusesAttributesForwardReferencesAndGarbage) {
  EXPECT_NE(error_of(write("vt.obj", "v 0 0 0\nvt 0 0\n")).find("texture coordinates"), std::string::npos);
  EXPECT_NE(error_of(write("vn.obj", "v 0 0 0\nvn 0 0 1\n")).find("normals"), std::string::npos);
  const std::string two = error_of(write("mtl.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nusemtl red\nf 1 2 3\n"));
  EXPECT_NE(two.find("two materials"), std::string::npos) << two;
  EXPECT_NE(error_of(write("rgb.obj", "v 0 0 0 1 0 0\n")).find("vertex colours"), std::string::npos);
  const std::string forward = error_of(write("forward.obj", "v 0 0 0\nv 1 0 0\nf 1 2 3\nv 0 1 0\n"));
  EXPECT_NE(forward.find("line 3"), std::string::npos) << forward;
  EXPECT_NE(forward.find("not defined above it"), std::string::npos) << forward;
  EXPECT_NE(error_of(write("zero.obj", "v 0 0 0\nf 0 1 1\n")).find("index 0"), std::string::npos);
  EXPECT_NE(error_of(write("bin.obj", std::string("v 0 0 0\n\x01\x02\x03 4\n"))).find("not an OBJ statement"),
            std::string::npos);
  EXPECT_NE(error_of(write("nan.obj", "v 0 nan 0\n")).find("line 1"), std::string::npos);
  EXPECT_NE(error_of(testing::temp_dir("io_stream_missing") / "missing.obj").find("cannot open"), std::string::npos);
  EXPECT_FALSE(streamable("a.stl"));
  EXPECT_TRUE(streamable("A.PLY"));
}

}  // namespace
}  // namespace lodforge::io
