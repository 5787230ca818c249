// PLY reader/writer: ASCII and both binary byte orders, attribute properties, skipping of unknown data,
// hostile input, corpus round trip.

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <limits>
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
std::string blender_247_ply();

namespace {

enum class Enc { ascii, le, be };

// Builds a PLY body value by value in any encoding, so one test can state its data once for all three.
class Body {
 public:
  explicit Body(Enc e) : enc_(e) {}
  template <typename T>
  Body& put(T x) {
    if (enc_ == Enc::ascii) {
      if constexpr (std::is_floating_point_v<T>) bytes_ += std::to_string(x);
      else bytes_ += std::to_string(static_cast<long long>(x));
      bytes_ += ' ';
      return *this;
    }
    char b[sizeof(T)];
    std::memcpy(b, &x, sizeof(T));
    if (enc_ == Enc::be) std::reverse(b, b + sizeof(T));
    bytes_.append(b, sizeof(T));
    return *this;
  }
  Body& eol() {
    if (enc_ == Enc::ascii) bytes_ += '\n';
    return *this;
  }
  const std::string& bytes() const { return bytes_; }

 private:
  Enc enc_;
  std::string bytes_;
};

const char* format_line(Enc e) {
  switch (e) {
    case Enc::ascii: return "format ascii 1.0\n";
    case Enc::le: return "format binary_little_endian 1.0\n";
    case Enc::be: return "format binary_big_endian 1.0\n";
  }
  return "";
}

Mesh read(const std::string& bytes, Asset* asset_out = nullptr) {
  Asset a = read_ply("test.ply", bytes, {});
  EXPECT_EQ(a.meshes.size(), 1u);
  EXPECT_EQ(structural_problems(a.meshes[0]), "");
  Mesh m = a.meshes[0];
  if (asset_out) *asset_out = std::move(a);
  return m;
}

std::string error(const std::string& bytes, const LoadOptions& options = {}) { return error_of(read_ply, bytes, options); }

#define EXPECT_ERROR(bytes, needle)                          \
  do {                                                       \
    const std::string msg_ = error(bytes);                   \
    EXPECT_NE(msg_.find(needle), std::string::npos) << msg_; \
    EXPECT_EQ(msg_.find('\n'), std::string::npos) << msg_;   \
  } while (0)

// A square (quad) and a triangle over 5 vertices, with every attribute kind and unknown data to skip:
// an extra vertex scalar, a vertex list, a face scalar after the index list, and a whole unknown element.
std::string rich_file(Enc e) {
  std::string h = "ply\n" + std::string(format_line(e)) +
                  "comment made by hand\nobj_info anything\n"
                  "element vertex 5\nproperty float x\nproperty float y\nproperty float z\n"
                  "property double quality\nproperty float nx\nproperty float ny\nproperty float nz\n"
                  "property list uchar short junk\nproperty float s\nproperty float t\n"
                  "property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n"
                  "element material 2\nproperty list int float coefficients\nproperty ushort id\n"
                  "element face 2\nproperty list uchar int vertex_indices\nproperty int flags\n"
                  "end_header\n";
  Body b(e);
  const float p[5][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {2, 0.5f, 0}};
  for (int i = 0; i < 5; ++i) {
    b.put(p[i][0]).put(p[i][1]).put(p[i][2]).put(0.25 * i).put(0.0f).put(0.0f).put(1.0f);
    b.put(std::uint8_t(2)).put(std::int16_t(-7)).put(std::int16_t(i));
    b.put(0.5f * float(i)).put(0.25f).put(std::uint8_t(255)).put(std::uint8_t(0)).put(std::uint8_t(51 * i)).put(std::uint8_t(255)).eol();
  }
  b.put(std::int32_t(3)).put(1.5f).put(2.5f).put(3.5f).put(std::uint16_t(7)).eol();
  b.put(std::int32_t(0)).put(std::uint16_t(8)).eol();
  b.put(std::uint8_t(4)).put(0).put(1).put(2).put(3).put(std::int32_t(-1)).eol();
  b.put(std::uint8_t(3)).put(1).put(4).put(2).put(std::int32_t(99)).eol();
  return h + b.bytes();
}

// --- syntax -------------------------------------------------------------------------------------------------

TEST(Ply, ReadsAttributesAndSkipsUnknownDataInAllEncodings) {
  Mesh reference;
  for (Enc e : {Enc::ascii, Enc::le, Enc::be}) {
    Asset a;
    const Mesh m = read(rich_file(e), &a);
    EXPECT_EQ(a.binary, e != Enc::ascii);
    ASSERT_EQ(m.face_count(), 2u);
    EXPECT_EQ(m.face_size(0), 4u);
    EXPECT_EQ(m.face_size(1), 3u);
    EXPECT_EQ(m.vertex_count(), 5u);
    EXPECT_EQ(m.positions[4], (Vec3f{{2, 0.5f, 0}}));
    ASSERT_EQ(m.normals.size(), m.wedge_count());
    EXPECT_EQ(m.normals[2], (Vec3f{{0, 0, 1}}));
    ASSERT_EQ(m.uvs.size(), 1u);
    EXPECT_EQ(m.uvs[0][4], (Vec2f{{2.0f, 0.25f}}));
    ASSERT_EQ(m.colors.size(), 1u);
    EXPECT_EQ(m.color_components[0], 4);
    EXPECT_EQ(m.colors[0][1], (Vec4f{{1, 0, 51.0f / 255.0f, 1}}));
    EXPECT_EQ(m.formats.at("COLOR_0"), (AttributeFormat{5121, true}));
    EXPECT_EQ(m.corner_vertex(5), 4u);
    ASSERT_EQ(m.materials.size(), 1u);
    if (e == Enc::ascii) reference = m;
    else EXPECT_EQ(first_difference(reference, m), "");
  }
}

TEST(Ply, AcceptsAlternativePropertyNamesAndTypes) {
  const std::string text =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float64 x\nproperty float64 y\nproperty float64 z\n"
      "property float32 texture_u\nproperty float32 texture_v\nproperty float red\nproperty float green\n"
      "property float blue\nelement face 1\nproperty list uint8 uint32 vertex_index\nend_header\n"
      "0 0 0 0 0 0.5 0.5 0.5\n1 0 0 1 0 1 0 0\n0 1 0 0 1 0 0 1\n3 0 1 2\n";
  Asset a;
  const Mesh m = read(text, &a);
  EXPECT_EQ(m.face_count(), 1u);
  EXPECT_EQ(m.uvs[0][2], (Vec2f{{0, 1}}));
  EXPECT_EQ(m.color_components[0], 3);
  EXPECT_EQ(m.colors[0][0], (Vec4f{{0.5f, 0.5f, 0.5f, 1}}));
  EXPECT_EQ(m.formats.at("COLOR_0").component_type, 5126);
  ASSERT_EQ(a.warnings.size(), 1u);
  EXPECT_NE(a.warnings[0].find("double"), std::string::npos);
}

TEST(Ply, ReadsWhatBlender247Wrote) {
  // Its comment line lacks the "comment" keyword; it was refused as an unknown header line.
  const Mesh m = read(blender_247_ply());
  ASSERT_EQ(m.face_count(), 1u);
  EXPECT_EQ(m.face_size(0), 4u);
  EXPECT_EQ(m.positions[2], (Vec3f{{-1, -1, 0}}));
  EXPECT_EQ(m.normals[0], (Vec3f{{0, 0, 1}}));
  EXPECT_EQ(m.uvs[0][1], (Vec2f{{0, 1}}));
  EXPECT_EQ(m.colors[0][3], (Vec4f{{0, 0, 1, 1}}));
}

TEST(Ply, EmptyAndBlankHeaderLinesAreSkipped) {
  const std::string text =
      "ply\nformat ascii 1.0\n\n \t\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\r\n"
      "element face 1\nproperty list uchar int vertex_indices\n\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
  EXPECT_EQ(read(text).face_count(), 1u);
}

TEST(Ply, FaceElementBeforeVertexElementIsFine) {
  const std::string text =
      "ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int vertex_indices\nelement vertex 3\n"
      "property float x\nproperty float y\nproperty float z\nend_header\n3 0 1 2\n0 0 0\n1 0 0\n0 1 0\n";
  EXPECT_EQ(read(text).face_count(), 1u);
}

TEST(Ply, WeldsRepeatedPositionsIntoOneVertex) {
  const std::string text =
      "ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 2\nproperty list uchar int vertex_indices\nend_header\n"
      "0 0 0\n1 0 0\n0 1 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n3 3 4 5\n";
  const Mesh m = read(text);
  EXPECT_EQ(m.vertex_count(), 4u);
  EXPECT_EQ(m.wedge_count(), 4u);  // no attributes: repeated positions are not seams
  EXPECT_EQ(m.corner_vertex(3), m.corner_vertex(1));
}

TEST(Ply, WriterRoundTripsInBothEncodings) {
  const Mesh source = read(rich_file(Enc::le));
  for (bool binary : {true, false}) {
    Asset a;
    a.format = Format::ply;
    a.binary = binary;
    a.meshes = {source};
    const Asset b = save_and_reload(a, binary ? "rich_bin.ply" : "rich_ascii.ply");
    EXPECT_EQ(b.binary, binary);
    EXPECT_EQ(first_difference(source, b.meshes[0]), "") << binary;
  }
}

TEST(Ply, WriterKeepsFloatColoursAndLargePolygons) {
  Mesh m;
  const int n = 300;  // more corners than a uchar count can hold
  std::vector<std::uint32_t> ring;
  m.colors.resize(1);
  m.color_components = {3};
  for (int i = 0; i < n; ++i) {
    const float t = 6.2831853f * float(i) / float(n);
    ring.push_back(m.add_vertex_with_wedge(Vec3f{{std::cos(t), std::sin(t), 0}}));
    m.colors[0].push_back(Vec4f{{0.1f * float(i % 7), 0.3f, 0.7f, 1}});
  }
  m.add_face(ring.data(), ring.size());
  m.materials = {MaterialSlot{}};
  m.formats["COLOR_0"] = AttributeFormat{5126, false};  // what the reader notes for float colours
  Asset a;
  a.meshes = {m};
  const Mesh back = read(write_ply(a, true));
  EXPECT_EQ(back.face_size(0), 300u);
  EXPECT_EQ(first_difference(m, back), "");
}

// --- hostile input ----------------------------------------------------------------------------------------

const std::string kTriangleHeader =
    "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
    "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";

std::string triangle_body(float bad = 0.0f, std::int32_t index = 2, std::uint8_t count = 3) {
  Body b(Enc::le);
  b.put(0.0f).put(0.0f).put(0.0f).put(1.0f).put(bad).put(0.0f).put(0.0f).put(1.0f).put(0.0f);
  b.put(count);
  for (int i = 0; i < count; ++i) b.put(i == 2 ? index : std::int32_t(i));
  return b.bytes();
}

TEST(PlyHostile, EmptyFile) { EXPECT_ERROR("", "file is empty"); }
TEST(PlyHostile, NotAPlyFile) { EXPECT_ERROR("plx\nformat ascii 1.0\n", "not a PLY file"); }
TEST(PlyHostile, MissingEndHeader) { EXPECT_ERROR("ply\nformat ascii 1.0\nelement vertex 3\n", "no 'end_header'"); }
TEST(PlyHostile, UnknownFormat) { EXPECT_ERROR("ply\nformat binary_middle_endian 1.0\nend_header\n", "unknown PLY format"); }
TEST(PlyHostile, UnknownPropertyType) {
  EXPECT_ERROR("ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n", "unknown property type");
}
TEST(PlyHostile, TruncatedVertexData) {
  EXPECT_ERROR(kTriangleHeader + triangle_body().substr(0, 30), "header declares 3 vertices but only 30 bytes remain");
}
TEST(PlyHostile, TruncatedFaceData) {
  // Enough bytes for the declared minimum, but the list runs past the end.
  std::string bytes = kTriangleHeader + triangle_body();
  bytes[kTriangleHeader.size() + 36] = char(9);  // the face now claims 9 indices; 3 follow
  EXPECT_ERROR(bytes, "face 0 declares 9 vertices, more than the remaining data holds");
}
TEST(PlyHostile, TruncatedInsideARecord) {
  const std::string header =
      "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
      "property list int float junk\nend_header\n";
  Body b(Enc::le);
  b.put(0.0f).put(0.0f).put(0.0f).put(std::int32_t(50)).put(1.0f);
  EXPECT_ERROR(header + b.bytes(), "binary data ends inside vertex 0");
}
TEST(PlyHostile, CountLargerThanTheFileHolds) {
  std::string header = kTriangleHeader;
  header.replace(header.find("vertex 3"), 8, "vertex 1000");
  EXPECT_ERROR(header + triangle_body(), "header declares 1000 vertices but only");
}
TEST(PlyHostile, HeaderClaims2To40Faces) {
  std::string header = kTriangleHeader;
  header.replace(header.find("face 1"), 6, "face 1099511627776");
  EXPECT_ERROR(header + triangle_body(), "header declares 1099511627776 faces, more than the limit");
  const std::string msg = error(header + triangle_body(), LoadOptions{.max_elements = ~0ull});
  EXPECT_NE(msg.find("header declares 1099511627776 faces, more than 32-bit indices can address"), std::string::npos) << msg;
}
TEST(PlyHostile, BinaryCountJustBelow32BitsLargerThanTheFileHolds) {
  std::string header = kTriangleHeader;
  header.replace(header.find("face 1"), 6, "face 4000000000");
  const std::string msg = error(header + triangle_body(), LoadOptions{.max_elements = ~0ull});
  EXPECT_NE(msg.find("header declares 4000000000 faces but only 13 bytes remain"), std::string::npos) << msg;
}
TEST(PlyHostile, AsciiCountLargerThanTheFileHolds) {
  EXPECT_ERROR("ply\nformat ascii 1.0\nelement vertex 100\nproperty float x\nproperty float y\nproperty float z\n"
               "end_header\n0 0 0\n",
               "header declares 100 vertices but only 6 bytes remain");
}
TEST(PlyHostile, IndexPastVertexCount) { EXPECT_ERROR(kTriangleHeader + triangle_body(0.0f, 3), "face 0 uses vertex 3 but the file has 3 vertices"); }
TEST(PlyHostile, NegativeIndex) { EXPECT_ERROR(kTriangleHeader + triangle_body(0.0f, -1), "uses vertex index -1"); }
TEST(PlyHostile, NanPosition) {
  EXPECT_ERROR(kTriangleHeader + triangle_body(std::numeric_limits<float>::quiet_NaN()), "vertex 1 has a non-finite coordinate");
}
TEST(PlyHostile, InfPosition) {
  EXPECT_ERROR(kTriangleHeader + triangle_body(std::numeric_limits<float>::infinity()), "vertex 1 has a non-finite coordinate");
}
TEST(PlyHostile, MalformedAsciiNumber) {
  EXPECT_ERROR("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
               "end_header\n0 1.5.2 0\n",
               "line 8: malformed number '1.5.2' in vertex 0");
}
TEST(PlyHostile, ListWhereAScalarIsExpected) {
  // A header that says "list" for a vertex attribute the reader takes as one number: refused as such, not as
  // the "malformed number" its scalar data would give.
  const std::string header =
      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
      "property list uchar float nx\nproperty float ny\nproperty float nz\nend_header\n";
  EXPECT_ERROR(header + "0 0 0 0.577 0.577 0.577\n",
               "vertex property 'nx' is declared as a list where a scalar is expected");
  std::string binary = header;
  binary.replace(binary.find("ascii"), 5, "binary_little_endian");
  EXPECT_ERROR(binary + std::string(24, '\0'), "vertex property 'nx' is declared as a list where a scalar is expected");
}
TEST(PlyHostile, ListCountThatIsNotAnInteger) {
  EXPECT_ERROR("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
               "property list uchar float quality\nend_header\n0 0 0 0.5\n",
               "line 9: list property 'quality' of vertex 0: the count '0.5' is not an integer");
}
TEST(PlyHostile, FaceWithTwoVertices) {
  std::string bytes = kTriangleHeader + triangle_body();
  bytes[kTriangleHeader.size() + 36] = char(2);
  EXPECT_ERROR(bytes, "face 0 has 2 vertices (at least 3 needed)");
}
TEST(PlyHostile, HugeListCount) {
  const std::string header =
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list int int vertex_indices\nend_header\n";
  std::string body = triangle_body();
  Body b(Enc::le);
  b.put(std::int32_t(0x7fffffff)).put(0).put(1).put(2);
  body = body.substr(0, 36) + b.bytes();
  EXPECT_ERROR(header + body, "face 0 declares 2147483647 vertices, more than the remaining data holds");
}
TEST(PlyHostile, NoVertexElement) {
  EXPECT_ERROR("ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n",
               "no vertex element");
}
TEST(PlyHostile, MoreThanMaxElements) {
  const std::string msg = error(kTriangleHeader + triangle_body(), LoadOptions{.max_elements = 2});
  EXPECT_NE(msg.find("header declares 3 vertices, more than the limit of 2"), std::string::npos) << msg;
}

// --- corpus -----------------------------------------------------------------------------------------------

TEST(PlyCorpus, LucyLoadsWithManifestCountsAndRoundTrips) {
  LODFORGE_REQUIRE_CORPUS(file, "scanned/lucy-100k.ply");
  expect_corpus_round_trip(file, "scanned/lucy-100k.ply");
}

TEST(PlyCorpus, LucyRoundTripsThroughAscii) {
  LODFORGE_REQUIRE_CORPUS(file, "scanned/lucy-100k.ply");
  Asset a = load_asset(file);
  EXPECT_TRUE(a.binary);
  a.binary = false;
  const Asset b = save_and_reload(a, "lucy_ascii.ply");
  EXPECT_FALSE(b.binary);
  EXPECT_EQ(first_difference(a.meshes[0], b.meshes[0]), "");
}

}  // namespace
}  // namespace lodforge::io::io_test
