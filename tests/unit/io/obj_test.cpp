// OBJ reader/writer: every syntax feature on hand-written files, hostile input, corpus round trips.

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <fstream>
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

Mesh read(std::string_view text, Asset* asset_out = nullptr) {
  Asset a = read_obj("test.obj", text, {});
  EXPECT_EQ(a.meshes.size(), 1u);
  EXPECT_EQ(structural_problems(a.meshes[0]), "") << text;
  Mesh m = a.meshes[0];
  if (asset_out) *asset_out = std::move(a);
  return m;
}

std::string error(std::string_view text, const LoadOptions& options = {}) { return error_of(read_obj, text, options); }

#define EXPECT_ERROR(text, needle)                                    \
  do {                                                                \
    const std::string msg_ = error(text);                             \
    EXPECT_NE(msg_.find(needle), std::string::npos) << msg_;          \
    EXPECT_EQ(msg_.find('\n'), std::string::npos) << msg_;            \
  } while (0)

Vec3f corner_position(const Mesh& m, std::size_t c) { return m.positions[m.corner_vertex(c)]; }

constexpr const char* kSquare = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";

// --- syntax -------------------------------------------------------------------------------------------------

TEST(Obj, KeepsTrianglesQuadsAndPolygonsAsTheyAre) {
  const Mesh m = read(std::string(kSquare) + "v 2 0 0\nv 2 1 0\nv 3 0 0\nf 1 2 3\nf 1 2 3 4\nf 2 5 6 3 7\n");
  ASSERT_EQ(m.face_count(), 3u);
  EXPECT_EQ(m.face_size(0), 3u);
  EXPECT_EQ(m.face_size(1), 4u);
  EXPECT_EQ(m.face_size(2), 5u);
  EXPECT_EQ(m.vertex_count(), 7u);
  EXPECT_EQ(corner_position(m, 8), (Vec3f{{2, 0, 0}}));  // f 2 5 6 3 7: second corner
  EXPECT_TRUE(m.uvs.empty());
  EXPECT_TRUE(m.normals.empty());
  ASSERT_EQ(m.materials.size(), 1u);
  EXPECT_EQ(m.materials[0].name, "");
  EXPECT_EQ(m.face_material, (std::vector<std::uint32_t>{0, 0, 0}));
  EXPECT_TRUE(m.face_group.empty());
}

TEST(Obj, ReadsAllFaceCornerForms) {
  const std::string head = std::string(kSquare) + "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\nvn 0 0 -1\n";
  {
    const Mesh m = read(head + "f 1/1 2/2 3/3 4/4\n");
    ASSERT_EQ(m.uvs.size(), 1u);
    EXPECT_TRUE(m.normals.empty());
    EXPECT_EQ(m.uvs[0][m.corner_wedge[2]], (Vec2f{{1, 1}}));
  }
  {
    const Mesh m = read(head + "f 1//2 2//2 3//2\n");
    EXPECT_TRUE(m.uvs.empty());
    ASSERT_EQ(m.normals.size(), m.wedge_count());
    EXPECT_EQ(m.normals[m.corner_wedge[0]], (Vec3f{{0, 0, -1}}));
  }
  {
    const Mesh m = read(head + "f 1/4/1 2/3/1 3/2/2 4/1/2\n");
    EXPECT_EQ(m.uvs[0][m.corner_wedge[0]], (Vec2f{{0, 1}}));
    EXPECT_EQ(m.normals[m.corner_wedge[3]], (Vec3f{{0, 0, -1}}));
  }
}

TEST(Obj, ResolvesNegativeRelativeIndices) {
  const Mesh m = read("v 5 5 5\nv 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0.5 0.5\nf -3/-1 -2/-1 -1/-1\n");
  ASSERT_EQ(m.face_count(), 1u);
  EXPECT_EQ(corner_position(m, 0), (Vec3f{{0, 0, 0}}));
  EXPECT_EQ(corner_position(m, 2), (Vec3f{{1, 1, 0}}));
  EXPECT_EQ(m.uvs[0][m.corner_wedge[1]], (Vec2f{{0.5f, 0.5f}}));
  EXPECT_EQ(m.vertex_count(), 4u);  // the unreferenced first vertex is kept
}

TEST(Obj, AcceptsForwardReferences) {
  const Mesh m = read("f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n");
  EXPECT_EQ(m.face_count(), 1u);
}

TEST(Obj, WedgesAreDistinctCornerTriplesAndVerticesDistinctPositions) {
  // Two faces sharing an edge with a UV seam along it; the shared positions are repeated as extra `v` lines.
  const Mesh m = read(
      "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n"
      "vt 0 0\nvt 1 0\nvt 0 1\nvt 0.5 0\nvt 0 0.5\nvt 1 1\n"
      "f 1/1 2/2 3/3\nf 4/2 6/6 5/3\nf 2/4 6/6 3/5\n");
  EXPECT_EQ(m.vertex_count(), 4u);  // welded by position
  // Wedges: (1,1) (2,2) (3,3) (6,6) (2,4) (3,5); (4,2) and (5,3) are the same as (2,2) and (3,3) after welding.
  EXPECT_EQ(m.wedge_count(), 6u);
  EXPECT_EQ(m.corner_wedge[3], m.corner_wedge[1]);
  EXPECT_EQ(m.corner_wedge[5], m.corner_wedge[2]);
  EXPECT_NE(m.corner_wedge[6], m.corner_wedge[1]);  // seam: same vertex, other UV
  EXPECT_EQ(m.corner_vertex(6), m.corner_vertex(1));
}

TEST(Obj, ReadsVertexColoursAndIgnoresW) {
  const Mesh m = read("v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nf 1 2 3\n");
  ASSERT_EQ(m.colors.size(), 1u);
  EXPECT_EQ(m.color_components[0], 3);
  EXPECT_EQ(m.colors[0][m.corner_wedge[1]], (Vec4f{{0, 1, 0, 1}}));
  const Mesh w = read("v 0 0 0 1\nv 1 0 0 0.5\nv 0 1 0 2\nvt 0.25 0.5 0.75\nf 1/1 2/1 3/1\n");
  EXPECT_TRUE(w.colors.empty());
  EXPECT_EQ(w.positions[1], (Vec3f{{1, 0, 0}}));
  EXPECT_EQ(w.uvs[0][0], (Vec2f{{0.25f, 0.5f}}));
}

TEST(Obj, GroupsAndObjectsBecomeFaceGroups) {
  const Mesh m = read(std::string(kSquare) + "f 1 2 3\ng arm left\nf 1 3 4\no body\nf 1 2 4\ng arm left\nf 2 3 4\n");
  ASSERT_EQ(m.groups, (std::vector<std::string>{"", "arm left", "body"}));
  EXPECT_EQ(m.face_group, (std::vector<std::uint32_t>{0, 1, 2, 1}));
}

TEST(Obj, UsemtlCreatesNamedMaterialSlotsAfterADefaultSlot) {
  Asset a;
  const Mesh m = read("mtllib scene.mtl other.mtl\n" + std::string(kSquare) +
                          "f 1 2 3\nusemtl red\nf 1 3 4\nusemtl blue\nf 1 2 4\nusemtl red\nf 2 3 4\n",
                      &a);
  ASSERT_EQ(m.materials.size(), 3u);
  EXPECT_EQ(m.materials[0].name, "");
  EXPECT_EQ(m.materials[1].name, "red");
  EXPECT_EQ(m.materials[2].name, "blue");
  EXPECT_EQ(m.face_material, (std::vector<std::uint32_t>{0, 1, 2, 1}));
  EXPECT_EQ(a.obj_mtllibs, (std::vector<std::string>{"scene.mtl other.mtl"}));
  // No face before the first usemtl: no default slot.
  EXPECT_EQ(read("usemtl only\n" + std::string(kSquare) + "f 1 2 3\n").materials.size(), 1u);
}

TEST(Obj, ToleratesCommentsCrlfTrailingSpacesSmoothingAndContinuations) {
  const Mesh m = read(
      "# comment\r\n\r\n  \r\nv 0 0 0   \r\nv 1 0 0\t \r\nv 1 1 0\r\nv 0 1 \\\r\n 0\r\ns 1\r\ns off\r\n"
      "f 1 2 \\\r\n  3 4   \r\n");
  ASSERT_EQ(m.face_count(), 1u);
  EXPECT_EQ(m.face_size(0), 4u);
  EXPECT_EQ(m.positions[3], (Vec3f{{0, 1, 0}}));
}

TEST(Obj, MissingTextureCoordinatesBecomeZeroWithAWarning) {
  Asset a;
  const Mesh m = read(std::string(kSquare) + "vt 0.5 0.5\nf 1/1 2/1 3/1\nf 1 3 4\n", &a);
  ASSERT_EQ(m.uvs.size(), 1u);
  EXPECT_EQ(m.uvs[0][m.corner_wedge[4]], (Vec2f{{0, 0}}));
  ASSERT_FALSE(a.warnings.empty());
  EXPECT_NE(a.warnings[0].find("no texture coordinate"), std::string::npos);
}

TEST(Obj, UnsupportedStatementsAreIgnoredWithAWarning) {
  Asset a;
  const Mesh m = read(std::string(kSquare) + "l 1 2\nl 2 3\nvp 0.5\nf 1 2 3\n", &a);
  EXPECT_EQ(m.face_count(), 1u);
  ASSERT_EQ(a.warnings.size(), 2u);
  EXPECT_EQ(a.warnings[0], "ignored 2 unsupported 'l' statement(s)");
}

TEST(Obj, NumbersAreReadExactly) {
  const Mesh m = read("v 0.1 -2.5e-3 +3.4028235e38\nv 1e-45 1.17549435e-38 -0\nv 1 1 1\nf 1 2 3\n");
  EXPECT_EQ(m.positions[0][0], 0.1f);
  EXPECT_EQ(m.positions[0][1], -2.5e-3f);
  EXPECT_EQ(m.positions[0][2], 3.4028235e38f);
  EXPECT_EQ(m.positions[1][0], 1e-45f);  // subnormal
  EXPECT_EQ(m.positions[1][1], 1.17549435e-38f);
}

TEST(Obj, WriterRoundTripKeepsEverything) {
  // A cube of quads with per-face UVs and normals, two groups, two materials and a colour per vertex.
  const Mesh m = testing::make_cube_quads();
  Mesh seams;
  seams.positions = m.positions;
  seams.uvs.resize(1);
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    const Vec3d n = face_normal_newell(m, f);
    std::uint32_t w[4];
    for (std::uint32_t i = 0; i < 4; ++i) {
      w[i] = static_cast<std::uint32_t>(seams.wedge_vertex.size());
      seams.wedge_vertex.push_back(m.corner_vertex(m.face_offsets[f] + i));
      seams.uvs[0].push_back(Vec2f{{0.1f * float(i), 1.0f / 3.0f * float(f)}});
      seams.normals.push_back(to_float(n * 0.5));
    }
    seams.add_face(w, 4, f < 3 ? 0u : 1u);
  }
  seams.materials = {MaterialSlot{.name = ""}, MaterialSlot{.name = "metal"}};
  seams.groups = {"top", "bottom"};
  seams.face_group = {0, 0, 1, 1, 0, 1};
  Asset a;
  a.format = Format::obj;
  a.meshes = {seams};
  a.obj_mtllibs = {"cube.mtl"};
  const Asset b = save_and_reload(a, "cube.obj");
  ASSERT_EQ(b.meshes.size(), 1u);
  EXPECT_EQ(first_difference(seams, b.meshes[0]), "");
  EXPECT_EQ(b.obj_mtllibs, a.obj_mtllibs);
}

TEST(Obj, WriterConcatenatesSeveralMeshes) {
  Asset a;
  a.meshes = {testing::make_tetrahedron(), testing::make_cube_quads()};
  const Mesh m = read(write_obj(a, "two.obj"));
  EXPECT_EQ(m.face_count(), 10u);
  EXPECT_EQ(m.vertex_count(), 12u - 4u);  // the tetrahedron's 4 corners coincide with cube corners
  EXPECT_EQ(count_face_kinds(m).quads, 6u);
}

// --- hostile input ----------------------------------------------------------------------------------------

TEST(ObjHostile, EmptyFile) { EXPECT_ERROR("", "file is empty"); }
TEST(ObjHostile, NoGeometry) { EXPECT_ERROR("# only a comment\n\n", "no vertices or faces"); }
TEST(ObjHostile, BinaryData) { EXPECT_ERROR(std::string("v 1 2 3\n\x01\x02\x03\xff\n", 13), "not an OBJ statement"); }
TEST(ObjHostile, IndexPastVertexCount) { EXPECT_ERROR(std::string(kSquare) + "f 1 2 9\n", "line 5: face uses vertex 9 but the file has 4"); }
TEST(ObjHostile, TexcoordIndexOutOfRange) { EXPECT_ERROR(std::string(kSquare) + "vt 0 0\nf 1/1 2/2 3/1\n", "texture coordinate 2"); }
TEST(ObjHostile, NormalIndexOutOfRange) { EXPECT_ERROR(std::string(kSquare) + "f 1//1 2//1 3//1\n", "normal 1"); }
TEST(ObjHostile, IndexZero) { EXPECT_ERROR(std::string(kSquare) + "f 0 1 2\n", "index 0"); }
TEST(ObjHostile, RelativeIndexBeforeFirstVertex) { EXPECT_ERROR(std::string(kSquare) + "f -5 1 2\n", "relative vertex index -5"); }
TEST(ObjHostile, HugeIndex) { EXPECT_ERROR(std::string(kSquare) + "f 1099511627776 1 2\n", "1099511627776"); }
TEST(ObjHostile, NanPosition) { EXPECT_ERROR("v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n", "vertex 1 has a non-finite coordinate"); }
TEST(ObjHostile, InfPosition) { EXPECT_ERROR("v 0 0 0\nv 1 0 0\nv 0 1 -inf\nf 1 2 3\n", "vertex 2 has a non-finite coordinate"); }
TEST(ObjHostile, OverflowingPosition) { EXPECT_ERROR("v 0 0 1e39\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "vertex 0 has a non-finite"); }
TEST(ObjHostile, MalformedNumber) { EXPECT_ERROR("v 0 0 0\nv 1 0x 0\n", "line 2: malformed number '0x'"); }
TEST(ObjHostile, MalformedCorner) { EXPECT_ERROR(std::string(kSquare) + "f 1/a 2 3\n", "malformed face corner '1/a'"); }
TEST(ObjHostile, TooFewCoordinates) { EXPECT_ERROR("v 1 2\n", "'v' statement has 2 values"); }
TEST(ObjHostile, FaceWithTwoVertices) { EXPECT_ERROR(std::string(kSquare) + "f 1 2\n", "face has 2 vertices (at least 3 needed)"); }
TEST(ObjHostile, MoreVerticesThanMaxElements) {
  const std::string msg = error(std::string(kSquare) + "f 1 2 3\n", LoadOptions{.max_elements = 3});
  EXPECT_NE(msg.find("more than 3 "), std::string::npos) << msg;
  EXPECT_NE(msg.find(", the most one file may hold"), std::string::npos) << msg;
  EXPECT_EQ(msg.find("max_elements"), std::string::npos) << "no internal names: " << msg;
}

// --- corpus -----------------------------------------------------------------------------------------------

class ObjCorpus : public ::testing::TestWithParam<const char*> {};

TEST_P(ObjCorpus, LoadsWithManifestCountsAndRoundTrips) {
  LODFORGE_REQUIRE_CORPUS(file, GetParam());
  expect_corpus_round_trip(file, GetParam());
}

INSTANTIATE_TEST_SUITE_P(
    Corpus, ObjCorpus,
    ::testing::Values("scanned/stanford-bunny.obj", "scanned/armadillo-86k.obj", "scanned/armadillo-remeshed-29k.obj",
                      "scanned/dragon-100k.obj", "scanned/happy-buddha-100k.obj", "scanned/nefertiti-70k.obj",
                      "scanned/demosthenes-17k.obj", "scanned/hammer-60k.obj", "scanned/boot-40k.obj",
                      "scanned/smplx-human-neutral.obj", "quad/spot_quadrangulated.obj", "quad/spot_control_mesh.obj",
                      "quad/blub_quadrangulated.obj", "quad/blub_control_mesh.obj", "quad/makehuman_base_hm08.obj",
                      "quad/makehuman_male_generic.obj", "quad/makehuman_proxy741.obj",
                      "quad/makehuman_male_casualsuit01.obj", "quad/makehuman_hair_bob01.obj", "quad/suzanne.obj",
                      "quad/sword-quad-dominant.obj", "quad/penguin_control_mesh.obj", "quad/mixedFaring_polygons.obj",
                      "quad/hexaSphere_polygons.obj", "hardsurface/wingnut.obj", "topology/plane_holes.obj",
                      "topology/blub_open.obj", "topology/hand_lowres_open.obj", "terrain/mountain-remeshed.obj"),
    [](const ::testing::TestParamInfo<const char*>& info) { return ::lodforge::testing::test_name_of(info.param); });

TEST(ObjCorpusDetails, SuzanneKeepsItsMaterialObjectAndMtllib) {
  LODFORGE_REQUIRE_CORPUS(file, "quad/suzanne.obj");
  const Asset a = load_asset(file);
  const Mesh& m = a.meshes[0];
  ASSERT_EQ(m.groups, (std::vector<std::string>{"Suzanne"}));
  ASSERT_FALSE(m.materials.empty());
  EXPECT_EQ(m.materials.back().name, "None");
  EXPECT_EQ(a.obj_mtllibs, (std::vector<std::string>{"affe.mtl"}));
}

TEST(ObjCorpusDetails, SmplxHasOneWedgePerDistinctCornerTriple) {
  LODFORGE_REQUIRE_CORPUS(file, "scanned/smplx-human-neutral.obj");
  const Mesh m = load_asset(file).meshes[0];
  EXPECT_EQ(m.normals.size(), m.wedge_count());
  EXPECT_EQ(m.uvs.at(0).size(), m.wedge_count());
  EXPECT_GE(m.wedge_count(), 11437u - 100u);  // about one wedge per vt: UV seams split vertices
  EXPECT_GT(m.wedge_count(), m.vertex_count());
}

}  // namespace
}  // namespace lodforge::io::io_test
