// OFF reader/writer: header variants, comments, polygons, colours, hostile input, corpus round trips.

#include <gtest/gtest.h>

#include <string>

#include "lodforge/io/asset.hpp"
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

Mesh read(const std::string& text, Asset* asset_out = nullptr) {
  Asset a = read_off("test.off", text, {});
  EXPECT_EQ(a.meshes.size(), 1u);
  EXPECT_EQ(structural_problems(a.meshes[0]), "") << text;
  Mesh m = a.meshes[0];
  if (asset_out) *asset_out = std::move(a);
  return m;
}

std::string error(const std::string& text, const LoadOptions& options = {}) { return error_of(read_off, text, options); }

#define EXPECT_ERROR(text, needle)                           \
  do {                                                       \
    const std::string msg_ = error(text);                    \
    EXPECT_NE(msg_.find(needle), std::string::npos) << msg_; \
    EXPECT_EQ(msg_.find('\n'), std::string::npos) << msg_;   \
  } while (0)

constexpr const char* kVertices = "0 0 0\n1 0 0\n1 1 0\n0 1 0\n2 0.5 0\n";

// --- syntax -------------------------------------------------------------------------------------------------

TEST(Off, ReadsPolygonsCommentsAndCrlf) {
  const Mesh m = read("OFF\r\n# a comment\r\n\r\n5 2 0   # counts\r\n0 0 0\r\n1 0 0\r\n1 1 0\r\n0 1 0\r\n2 0.5 0\r\n"
                      "4 0 1 2 3\r\n3 1 4 2 # end\r\n");
  ASSERT_EQ(m.face_count(), 2u);
  EXPECT_EQ(m.face_size(0), 4u);
  EXPECT_EQ(m.face_size(1), 3u);
  EXPECT_EQ(m.positions[4], (Vec3f{{2, 0.5f, 0}}));
  EXPECT_EQ(m.materials.size(), 1u);
  EXPECT_EQ(m.face_material.size(), 2u);
}

TEST(Off, CountsMayFollowTheKeywordAndEdgeCountMayBeMissing) {
  EXPECT_EQ(read(std::string("OFF 5 1 0\n") + kVertices + "5 0 1 4 2 3\n").face_size(0), 5u);
  EXPECT_EQ(read(std::string("OFF\n5 1\n") + kVertices + "3 0 1 2\n").face_count(), 1u);
}

TEST(Off, ReadsCoffColoursAsBytesOrFloats) {
  const Mesh bytes = read("COFF\n3 1 0\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n0 1 0 0 0 255 128\n3 0 1 2\n");
  ASSERT_EQ(bytes.colors.size(), 1u);
  EXPECT_EQ(bytes.color_components[0], 4);
  EXPECT_EQ(bytes.colors[0][2], (Vec4f{{0, 0, 1, 128.0f / 255.0f}}));
  EXPECT_EQ(bytes.formats.at("COLOR_0").component_type, 5121);
  const Mesh floats = read("COFF\n3 1 0\n0 0 0 1 0 0\n1 0 0 0 0.5 0\n0 1 0 0 0 1\n3 0 1 2\n");
  EXPECT_EQ(floats.color_components[0], 3);
  EXPECT_EQ(floats.colors[0][1], (Vec4f{{0, 0.5f, 0, 1}}));
  EXPECT_EQ(floats.formats.count("COLOR_0"), 0u);
}

TEST(Off, ReadsNormalsAndTextureCoordinates) {
  const Mesh m = read("STNOFF\n3 1 0\n0 0 0 0 0 1 0 0\n1 0 0 0 0 1 1 0\n0 1 0 0 0 1 0 1\n3 0 1 2\n");
  ASSERT_EQ(m.normals.size(), 3u);
  EXPECT_EQ(m.normals[1], (Vec3f{{0, 0, 1}}));
  ASSERT_EQ(m.uvs.size(), 1u);
  EXPECT_EQ(m.uvs[0][2], (Vec2f{{0, 1}}));
}

TEST(Off, FaceColoursAreIgnoredWithAWarning) {
  Asset a;
  const Mesh m = read(std::string("OFF\n5 2 0\n") + kVertices + "3 0 1 2 255 0 0\n4 0 1 2 3 0.5 0.5 0.5 1\n", &a);
  EXPECT_EQ(m.face_size(1), 4u);
  ASSERT_EQ(a.warnings.size(), 1u);
  EXPECT_EQ(a.warnings[0], "ignored the colours of 2 faces");
}

TEST(Off, WriterRoundTripsPolygonsAndColours) {
  for (const char* text : {"OFF\n5 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n2 0.5 0\n4 0 1 2 3\n3 1 4 2\n",
                           "COFF\n3 1 0\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n0 1 0 0 0 255 128\n3 0 1 2\n",
                           "COFF\n3 1 0\n0 0 0 1 0 0\n1 0 0 0 0.5 0\n0 1 0 0.1 0.2 0.3\n3 0 1 2\n"}) {
    Asset a;
    const Mesh m = read(text, &a);
    const Asset b = save_and_reload(a, "round.off");
    EXPECT_EQ(first_difference(m, b.meshes[0]), "") << text;
  }
}

TEST(Off, WriterTakesAnyMeshAndKeepsQuads) {
  Asset a;
  a.meshes = {testing::make_cube_quads()};
  const Mesh m = read(write_off(a));
  EXPECT_EQ(count_face_kinds(m).quads, 6u);
  EXPECT_EQ(m.positions, a.meshes[0].positions);
}

// --- hostile input ----------------------------------------------------------------------------------------

TEST(OffHostile, EmptyFile) { EXPECT_ERROR("", "file is empty"); }
TEST(OffHostile, OnlyComments) { EXPECT_ERROR("# nothing\n\n", "file has no content"); }
TEST(OffHostile, WrongKeyword) { EXPECT_ERROR("PLY\n3 1 0\n", "not an OFF file"); }
TEST(OffHostile, BinaryOff) { EXPECT_ERROR("OFF BINARY\n", "binary OFF is not supported"); }
TEST(OffHostile, MalformedCounts) { EXPECT_ERROR("OFF\n3 x 0\n", "line 2: malformed counts line"); }
TEST(OffHostile, CountsLargerThanTheFileHolds) {
  EXPECT_ERROR(std::string("OFF\n1000 1 0\n") + kVertices + "3 0 1 2\n", "header declares 1000 vertices but only");
}
TEST(OffHostile, HeaderClaims2To40Faces) {
  EXPECT_ERROR(std::string("OFF\n5 1099511627776 0\n") + kVertices, "header declares 1099511627776 faces, more than the limit");
  const std::string msg = error(std::string("OFF\n5 1099511627776 0\n") + kVertices, LoadOptions{.max_elements = ~0ull});
  EXPECT_NE(msg.find("header declares 1099511627776 faces, more than 32-bit indices can address"), std::string::npos) << msg;
  const std::string bytes = error(std::string("OFF\n5 4000000000 0\n") + kVertices, LoadOptions{.max_elements = ~0ull});
  EXPECT_NE(bytes.find("header declares 4000000000 faces but only"), std::string::npos) << bytes;
}
TEST(OffHostile, FileEndsBeforeAllVertices) {
  EXPECT_ERROR("OFF\n6 0 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n2 0 0\n# padding so that the counts fit\n",
               "file ends after 5 of 6 vertices");
}
TEST(OffHostile, IndexPastVertexCount) {
  EXPECT_ERROR(std::string("OFF\n5 1 0\n") + kVertices + "3 0 1 5\n", "line 8: face 0 uses vertex 5 but the file has 5 vertices");
}
TEST(OffHostile, NegativeIndex) { EXPECT_ERROR(std::string("OFF\n5 1 0\n") + kVertices + "3 0 -1 2\n", "uses vertex -1"); }
TEST(OffHostile, NanPosition) { EXPECT_ERROR("OFF\n3 1 0\n0 0 0\n1 NaN 0\n0 1 0\n3 0 1 2\n", "vertex 1 has a non-finite coordinate"); }
TEST(OffHostile, InfPosition) { EXPECT_ERROR("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 inf\n3 0 1 2\n", "vertex 2 has a non-finite coordinate"); }
TEST(OffHostile, MalformedNumber) { EXPECT_ERROR("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0,5\n3 0 1 2\n", "malformed number '0,5'"); }
TEST(OffHostile, WrongNumberOfVertexValues) { EXPECT_ERROR("OFF\n3 1 0\n0 0 0\n1 0\n0 1 0\n3 0 1 2\n", "vertex line 1 has 2 values"); }
TEST(OffHostile, FaceWithTwoVertices) {
  EXPECT_ERROR(std::string("OFF\n5 1 0\n") + kVertices + "2 0 1\n", "face 0 has 2 vertices (at least 3 needed)");
}
TEST(OffHostile, FaceListsFewerIndicesThanDeclared) {
  EXPECT_ERROR(std::string("OFF\n5 1 0\n") + kVertices + "4 0 1 2\n", "face 0 declares 4 vertices but lists 3");
}
TEST(OffHostile, FileEndsBeforeAllFaces) {
  EXPECT_ERROR(std::string("OFF\n5 3 0\n") + kVertices + "3 0 1 2\n3 0 2 3 \n", "file ends after 2 of 3 faces");
}
TEST(OffHostile, MoreThanMaxElements) {
  const std::string msg = error(std::string("OFF\n5 1 0\n") + kVertices + "3 0 1 2\n", LoadOptions{.max_elements = 4});
  EXPECT_NE(msg.find("more than the limit of 4"), std::string::npos) << msg;
}

// --- corpus -----------------------------------------------------------------------------------------------

class OffCorpus : public ::testing::TestWithParam<const char*> {};

TEST_P(OffCorpus, LoadsWithManifestCountsAndRoundTrips) {
  LODFORGE_REQUIRE_CORPUS(file, GetParam());
  expect_corpus_round_trip(file, GetParam());
}

INSTANTIATE_TEST_SUITE_P(Corpus, OffCorpus, ::testing::Values("quad/fandisk_quads.off", "hardsurface/fandisk.off"),
                         [](const ::testing::TestParamInfo<const char*>& info) {
                           return std::filesystem::path(info.param).stem().string();
                         });

}  // namespace
}  // namespace lodforge::io::io_test
