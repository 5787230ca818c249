// The incremental cache: what its keys depend on, and what makes an entry valid.
#include "lodforge/batch/cache.hpp"

#include <gtest/gtest.h>

#include <fstream>

#include "lodforge/io/asset.hpp"
#include "lodforge/io/file.hpp"
#include "test_support.hpp"

namespace lodforge::batch {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

void write(const fs::path& p, const std::string& s) {
  fs::create_directories(p.parent_path());
  std::ofstream(p, std::ios::binary) << s;
}

TEST(Cache, HasherSeparatesFieldsAndIsStable) {
  EXPECT_NE(Hasher().bytes("ab").bytes("c").hex(), Hasher().bytes("a").bytes("bc").hex());
  EXPECT_EQ(Hasher().bytes("lodforge").hex(), Hasher().bytes("lodforge").hex());
  EXPECT_EQ(Hasher().bytes("x").hex().size(), 32u);
  EXPECT_NE(Hasher().u64(1).hex(), Hasher().u64(2).hex());
  // Every byte counts, also in a partial last word.
  EXPECT_NE(Hasher().bytes("0123456789").hex(), Hasher().bytes("0123456788").hex());
}

TEST(Cache, FingerprintFollowsExternalGltfBuffers) {
  const fs::path dir = testing::temp_dir("batch_cache_gltf");
  io::Asset a;
  a.format = io::Format::gltf;
  a.meshes.push_back(testing::make_tetrahedron());
  io::save_asset(a, dir / "t.gltf");
  ASSERT_TRUE(fs::exists(dir / "t.bin"));
  const std::string before = input_fingerprint(dir / "t.gltf");
  EXPECT_EQ(before, input_fingerprint(dir / "t.gltf"));
  std::string bin = io::read_file(dir / "t.bin");
  bin[0] ^= 1;
  write(dir / "t.bin", bin);
  EXPECT_NE(before, input_fingerprint(dir / "t.gltf")) << "a changed buffer changes the key";
  fs::remove(dir / "t.bin");
  EXPECT_NE(before, input_fingerprint(dir / "t.gltf")) << "so does a missing one";
}

TEST(Cache, FingerprintFollowsObjMaterialLibraries) {
  const fs::path dir = testing::temp_dir("batch_cache_obj");
  write(dir / "a.obj", "mtllib a.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  write(dir / "a.mtl", "newmtl red\nKd 1 0 0\n");
  const std::string before = input_fingerprint(dir / "a.obj");
  write(dir / "a.mtl", "newmtl red\nKd 0 1 0\n");
  EXPECT_NE(before, input_fingerprint(dir / "a.obj"));
  EXPECT_THROW(input_fingerprint(dir / "missing.obj"), io::IoError);
}

TEST(Cache, KeyDependsOnInputClassAndVersion) {
  const Json cls = {{"class", {{"name", "props"}}}};
  const std::string k = cache_key("f", cls, "v1");
  EXPECT_NE(k, cache_key("g", cls, "v1"));
  EXPECT_NE(k, cache_key("f", Json{{"class", {{"name", "other"}}}}, "v1"));
  EXPECT_NE(k, cache_key("f", cls, "v2"));
  EXPECT_EQ(k, cache_key("f", cls, "v1"));
}

TEST(Cache, EntryIsValidOnlyWithTheSameKeyAndAllOutputs) {
  const fs::path dir = testing::temp_dir("batch_cache_entry");
  const Cache cache(dir, "0-of-1");
  write(dir / "props/a_LOD1.obj", "x");
  write(dir / "props/a_LOD2.obj", "x");
  const Json record = {{"path", "props/a.obj"}, {"status", "ok"}};
  EXPECT_FALSE(cache.lookup("props/a.obj", "k1"));
  cache.store("props/a.obj", "k1", {"props/a_LOD1.obj", "props/a_LOD2.obj"}, record);
  ASSERT_TRUE(cache.lookup("props/a.obj", "k1"));
  EXPECT_EQ(*cache.lookup("props/a.obj", "k1"), record);
  EXPECT_FALSE(cache.lookup("props/a.obj", "k2")) << "another key";
  EXPECT_FALSE(cache.lookup("props/b.obj", "k1")) << "another asset";
  fs::remove(dir / "props/a_LOD2.obj");
  EXPECT_FALSE(cache.lookup("props/a.obj", "k1")) << "an output was deleted";
}

TEST(Cache, PublishMovesStagedFilesIntoPlace) {
  const fs::path dir = testing::temp_dir("batch_cache_publish");
  const Cache cache(dir, "1-of-2");
  const fs::path staging = cache.staging_for("chars/hero.gltf");
  EXPECT_TRUE(fs::is_directory(staging));
  EXPECT_NE(staging.string().find("staging-1-of-2"), std::string::npos);
  write(staging / "hero.gltf", "{}");
  write(staging / "hero.bin", "b");
  write(staging / "textures/skin.png", "p");
  const std::vector<std::string> outputs = cache.publish(staging, "chars");
  EXPECT_EQ(outputs, (std::vector<std::string>{"chars/hero.bin", "chars/hero.gltf", "chars/textures/skin.png"}));
  EXPECT_EQ(io::read_file(dir / "chars/textures/skin.png"), "p");
  EXPECT_FALSE(fs::exists(staging));
}

TEST(Cache, RemovesLeftoversOfItsOwnShardOnly) {
  const fs::path dir = testing::temp_dir("batch_cache_leftovers");
  const Cache mine(dir, "0-of-2"), other(dir, "1-of-2");
  write(mine.staging_for("a.obj") / "a_LOD1.obj", "partial");
  write(other.staging_for("b.obj") / "b_LOD1.obj", "in progress elsewhere");
  mine.store("a.obj", "k", {}, Json::object());
  const fs::path entries = dir / kCacheFolder / "entries";
  std::vector<fs::path> tmp;
  for (const auto& e : fs::directory_iterator(entries)) tmp.push_back(e.path().string() + ".tmp-99-0");
  write(tmp[0], "{");
  write(entries / "0000000000000000.json.tmp-99-0", "{");  // not one of `mine`'s assets
  mine.remove_leftovers({"a.obj"});
  EXPECT_FALSE(fs::exists(dir / kCacheFolder / "staging-0-of-2"));
  EXPECT_TRUE(fs::exists(dir / kCacheFolder / "staging-1-of-2"));
  EXPECT_FALSE(fs::exists(tmp[0]));
  EXPECT_TRUE(fs::exists(entries / "0000000000000000.json.tmp-99-0"));
}

}  // namespace
}  // namespace lodforge::batch
