// STL reader/writer: binary/ASCII detection, welding, recomputed normals, hostile input, corpus round trips.

#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <cstring>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "lodforge/core/weld.hpp"
#include "lodforge/io/asset.hpp"
#include "lodforge/io/file.hpp"
#include "lodforge/io/formats.hpp"
#include "test_support.hpp"

namespace lodforge::io::io_test {

// Shared helpers, defined in text_hostile_test.cpp.
using Reader = Asset (*)(const std::filesystem::path&, std::string_view, const LoadOptions&);
std::string error_of(Reader read, std::string_view bytes, const LoadOptions& options);
std::string first_difference(const Mesh& a, const Mesh& b);
std::string structural_problems(const Mesh& m);
Asset save_and_reload(const Asset& asset, const std::string& file_name);
void expect_corpus_round_trip(const std::filesystem::path& file, const std::string& relative);

namespace {

using Triangle = std::array<Vec3f, 3>;

// Two triangles of the unit square sharing the edge (1,0,0)-(0,1,0).
const std::vector<Triangle> kSquare = {
    Triangle{Vec3f{{0, 0, 0}}, Vec3f{{1, 0, 0}}, Vec3f{{0, 1, 0}}},
    Triangle{Vec3f{{1, 0, 0}}, Vec3f{{1, 1, 0}}, Vec3f{{0, 1, 0}}},
};

std::string binary_stl(const std::vector<Triangle>& tris, std::string header = "lodforge test",
                       std::optional<std::uint32_t> declared = std::nullopt) {
  header.resize(80, '\0');
  std::string s = header;
  const std::uint32_t n = declared.value_or(static_cast<std::uint32_t>(tris.size()));
  s.append(reinterpret_cast<const char*>(&n), 4);
  for (const Triangle& t : tris) {
    const float normal[3] = {7, 7, 7};  // deliberately wrong: readers must ignore facet normals
    s.append(reinterpret_cast<const char*>(normal), 12);
    for (const Vec3f& p : t) s.append(reinterpret_cast<const char*>(p.v.data()), 12);
    s.append("\x01\x02", 2);
  }
  return s;
}

Mesh read(const std::string& bytes, Asset* asset_out = nullptr) {
  Asset a = read_stl("test.stl", bytes, {});
  EXPECT_EQ(a.meshes.size(), 1u);
  EXPECT_EQ(structural_problems(a.meshes[0]), "");
  Mesh m = a.meshes[0];
  if (asset_out) *asset_out = std::move(a);
  return m;
}

std::string error(const std::string& bytes, const LoadOptions& options = {}) { return error_of(read_stl, bytes, options); }

#define EXPECT_ERROR(bytes, needle)                          \
  do {                                                       \
    const std::string msg_ = error(bytes);                   \
    EXPECT_NE(msg_.find(needle), std::string::npos) << msg_; \
    EXPECT_EQ(msg_.find('\n'), std::string::npos) << msg_;   \
  } while (0)

constexpr const char* kAsciiSquare =
    "solid square\n"
    "  facet normal 0 0 1\n    outer loop\n      vertex 0 0 0\n      vertex 1 0 0\n      vertex 0 1 0\n"
    "    endloop\n  endfacet\n"
    "  facet normal 0 0 0\n    outer loop\n      vertex 1 0 0\n      vertex 1 1 0\n      vertex 0 1 0\n"
    "    endloop\n  endfacet\n"
    "endsolid square\n";

void expect_square(const Mesh& m) {
  ASSERT_EQ(m.face_count(), 2u);
  EXPECT_EQ(m.vertex_count(), 4u);  // welded: the shared edge's corners are one vertex each
  EXPECT_EQ(m.wedge_count(), 4u);
  EXPECT_EQ(m.corner_vertex(1), m.corner_vertex(3));
  EXPECT_EQ(m.corner_vertex(2), m.corner_vertex(5));
  EXPECT_TRUE(m.normals.empty());  // facet normals are not kept
  EXPECT_EQ(m.materials.size(), 1u);
}

// --- syntax -------------------------------------------------------------------------------------------------

TEST(Stl, ReadsBinaryAndWelds) {
  Asset a;
  expect_square(read(binary_stl(kSquare), &a));
  EXPECT_TRUE(a.binary);
}

TEST(Stl, BinaryWhoseHeaderStartsWithSolidIsBinary) {
  Asset a;
  expect_square(read(binary_stl(kSquare, "solid square exported by a CAD tool"), &a));
  EXPECT_TRUE(a.binary);
}

TEST(Stl, ReadsAscii) {
  Asset a;
  expect_square(read(kAsciiSquare, &a));
  EXPECT_FALSE(a.binary);
}

TEST(Stl, AsciiToleratesCrlfUppercaseAndSeveralSolids) {
  std::string text;
  for (const char* p = kAsciiSquare; *p; ++p) {
    if (*p == '\n') text += '\r';
    text += static_cast<char>(std::toupper(static_cast<unsigned char>(*p)));
  }
  text += "solid second\nfacet normal 0 0 1\nouter loop\nvertex 5 5 5\nvertex 6 5 5\nvertex 5 6 5\nendloop\nendfacet\nendsolid\n";
  const Mesh m = read(text);
  EXPECT_EQ(m.face_count(), 3u);
  EXPECT_EQ(m.vertex_count(), 7u);
}

TEST(Stl, NegativeAndPositiveZeroWeld) {
  std::vector<Triangle> tris = kSquare;
  tris[1][0][1] = -0.0f;
  tris[1][2][0] = -0.0f;
  expect_square(read(binary_stl(tris)));
}

TEST(Stl, AsciiPolygonFacetIsKept) {
  const Mesh m = read("solid q\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 1 1 0\nvertex 0 1 0\n"
                      "endloop\nendfacet\nendsolid q\n");
  EXPECT_EQ(m.face_size(0), 4u);
}

TEST(Stl, WriterRecomputesNormalsInBothEncodings) {
  Asset a;
  a.meshes = {testing::make_cube_quads()};
  const std::string bin = write_stl(a, true);
  ASSERT_EQ(bin.size(), 84u + 12u * 50u);  // quads are fan-triangulated
  float n[3];
  std::memcpy(n, bin.data() + 84, 12);
  EXPECT_EQ(n[0], 0.0f);
  EXPECT_EQ(n[1], 0.0f);
  EXPECT_EQ(n[2], -1.0f);  // the cube's z = 0 face points down
  const std::string text = write_stl(a, false);
  EXPECT_EQ(text.rfind("solid ", 0), 0u);
  EXPECT_NE(text.find("facet normal 0 0 -1\n"), std::string::npos);
  const Mesh from_bin = read(bin), from_text = read(text);
  EXPECT_EQ(from_bin.face_count(), 12u);
  EXPECT_EQ(from_bin.vertex_count(), 8u);
  EXPECT_EQ(first_difference(from_bin, from_text), "");
}

TEST(Stl, RoundTripKeepsTheEncoding) {
  for (bool binary : {true, false}) {
    Asset a = read_stl("in.stl", binary ? binary_stl(kSquare) : std::string(kAsciiSquare), {});
    const Asset b = save_and_reload(a, binary ? "sq_bin.stl" : "sq_ascii.stl");
    EXPECT_EQ(b.binary, binary);
    EXPECT_EQ(first_difference(a.meshes[0], b.meshes[0]), "");
  }
}

// --- hostile input ----------------------------------------------------------------------------------------

TEST(StlHostile, EmptyFile) { EXPECT_ERROR("", "file is empty"); }
TEST(StlHostile, TooShortAndNotAscii) { EXPECT_ERROR("binary?", "too short for a binary STL"); }
TEST(StlHostile, TruncatedBinary) {
  std::string bytes = binary_stl(kSquare);
  bytes.resize(bytes.size() - 10);
  EXPECT_ERROR(bytes, "header declares 2 triangles but only 90 bytes remain");
}
TEST(StlHostile, CountLargerThanTheFileHolds) {
  EXPECT_ERROR(binary_stl(kSquare, "x", 1000u), "header declares 1000 triangles but only 100 bytes remain");
  EXPECT_ERROR(binary_stl(kSquare, "x", 0xffffffffu), "header declares 4294967295 triangles, more than the limit");
  const std::string msg = error(binary_stl(kSquare, "x", 0xfffffff0u), LoadOptions{.max_elements = ~0ull});
  EXPECT_NE(msg.find("header declares 4294967280 triangles but only 100 bytes remain"), std::string::npos) << msg;
}
TEST(StlHostile, RandomBytesSayTheFileIsNoStlAndWhy) {
  std::string bytes(300, '\0');
  std::uint32_t state = 12345;
  for (char& c : bytes) {
    state = state * 1664525u + 1013904223u;
    c = static_cast<char>(state >> 24);
  }
  bytes[0] = 'x';  // not "solid"
  const std::string msg = error(bytes);
  EXPECT_EQ(msg.rfind("hostile.bin: not a valid STL: read as binary STL (it does not start with 'solid'): header "
                      "declares ",
                      0),
            0u)
      << msg;
  EXPECT_EQ(msg.find("LoadOptions"), std::string::npos) << msg;
  EXPECT_ERROR(std::string("solid x\nfacet normal 0 0 1\n junk"), "not a valid STL: read as ASCII STL");
}
TEST(StlHostile, CountAboveMaxElements) {
  const std::string msg = error(binary_stl(kSquare), LoadOptions{.max_elements = 1});
  EXPECT_NE(msg.find("header declares 2 triangles, more than the limit of 1"), std::string::npos) << msg;
}
TEST(StlHostile, NanPositionBinary) {
  std::vector<Triangle> tris = kSquare;
  tris[1][2][1] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_ERROR(binary_stl(tris), "vertex 5 has a non-finite coordinate");
}
TEST(StlHostile, InfPositionBinary) {
  std::vector<Triangle> tris = kSquare;
  tris[0][1][0] = -std::numeric_limits<float>::infinity();
  EXPECT_ERROR(binary_stl(tris), "vertex 1 has a non-finite coordinate");
}
TEST(StlHostile, NanPositionAscii) {
  std::string text = kAsciiSquare;
  text.replace(text.find("vertex 1 1 0"), 12, "vertex 1 nan 0");
  EXPECT_ERROR(text, "line 12: vertex 4 has a non-finite coordinate");
}
TEST(StlHostile, MalformedNumberAscii) {
  std::string text = kAsciiSquare;
  text.replace(text.find("vertex 1 0 0"), 12, "vertex 1 0 zero");
  EXPECT_ERROR(text, "line 5: malformed number 'zero' in a vertex");
}
TEST(StlHostile, FacetWithTwoVertices) {
  EXPECT_ERROR("solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\nendfacet\nendsolid t\n",
               "facet has 2 vertices (at least 3 needed)");
}
TEST(StlHostile, TruncatedAscii) {
  const std::string text(kAsciiSquare);
  EXPECT_ERROR(text.substr(0, text.find("endloop")), "expected 'vertex' or 'endloop', found the end of the file");
  EXPECT_ERROR(text.substr(0, text.find("endsolid")), "expected 'facet' or 'endsolid', found the end of the file");
}
TEST(StlHostile, AsciiGarbageAfterSolid) { EXPECT_ERROR("solid x\nfacet normal 0 0 1\nouter circle\n", "expected 'loop', found 'circle'"); }

// --- corpus -----------------------------------------------------------------------------------------------

class StlCorpus : public ::testing::TestWithParam<const char*> {};

TEST_P(StlCorpus, LoadsWithManifestCountsAndRoundTrips) {
  LODFORGE_REQUIRE_CORPUS(file, GetParam());
  expect_corpus_round_trip(file, GetParam());
}

INSTANTIATE_TEST_SUITE_P(Corpus, StlCorpus,
                         ::testing::Values("hardsurface/featuretype.stl", "hardsurface/tray_bottom_ascii.stl",
                                           "hardsurface/plate_holes.stl", "topology/teapot_open.stl"),
                         [](const ::testing::TestParamInfo<const char*>& info) {
                           return std::filesystem::path(info.param).stem().string();
                         });

TEST(StlCorpusDetails, EncodingsAreDetected) {
  LODFORGE_REQUIRE_CORPUS(solid_binary, "hardsurface/plate_holes.stl");  // binary, header starts with "solid"
  LODFORGE_REQUIRE_CORPUS(ascii, "hardsurface/tray_bottom_ascii.stl");
  EXPECT_TRUE(load_asset(solid_binary).binary);
  EXPECT_FALSE(load_asset(ascii).binary);
}

TEST(StlCorpusDetails, WeldMatchesCoreWeldByPosition) {
  LODFORGE_REQUIRE_CORPUS(file, "topology/teapot_open.stl");
  const std::string bytes = read_file(file);
  std::uint32_t count = 0;
  std::memcpy(&count, bytes.data() + 80, 4);
  Mesh soup;
  for (std::uint32_t t = 0; t < count; ++t) {
    std::uint32_t w[3];
    for (int k = 0; k < 3; ++k) {
      Vec3f p;
      std::memcpy(p.v.data(), bytes.data() + 84 + 50 * t + 12 + 12 * k, 12);
      w[k] = soup.add_vertex_with_wedge(p);
    }
    soup.add_face(w, 3);
  }
  weld_by_position(soup);
  const Mesh m = load_asset(file).meshes[0];
  EXPECT_EQ(m.positions, soup.positions);
  ASSERT_EQ(m.corner_count(), soup.corner_count());
  for (std::size_t c = 0; c < m.corner_count(); ++c) ASSERT_EQ(m.corner_vertex(c), soup.corner_vertex(c)) << c;
}

}  // namespace
}  // namespace lodforge::io::io_test
