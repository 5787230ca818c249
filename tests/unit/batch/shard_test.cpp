#include "lodforge/batch/shard.hpp"

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

namespace lodforge::batch {
namespace {

TEST(Shard, ParsesZeroBasedKOverN) {
  EXPECT_EQ(parse_shard("0/1"), (Shard{0, 1}));
  EXPECT_EQ(parse_shard("2/3"), (Shard{2, 3}));
  EXPECT_EQ(shard_name(Shard{4, 16}), "4/16");
}

TEST(Shard, RejectsBadSpecsWithTheReason) {
  auto message = [](const char* s) {
    try {
      parse_shard(s);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(message("3/3"), "shard '3/3': K must be in 0..2 (K is 0-based)");
  EXPECT_EQ(message("1/0"), "shard '1/0': N must be at least 1");
  EXPECT_EQ(message("1"), "shard '1': expected K/N, e.g. 0/4 (K is 0-based)");
  EXPECT_NE(message("a/3").find("K must be a whole number"), std::string::npos);
  EXPECT_NE(message("1/3x").find("N must be a whole number"), std::string::npos);
  EXPECT_NE(message("-1/3").find("K must be a whole number"), std::string::npos);
  EXPECT_NE(message("/3").find("K must be a whole number"), std::string::npos);
}

TEST(Shard, EveryPathIsInExactlyOneShard) {
  for (std::uint32_t n : {1u, 2u, 3u, 7u}) {
    for (int i = 0; i < 500; ++i) {
      const std::string path = "lib/asset_" + std::to_string(i) + ".obj";
      int hits = 0;
      for (std::uint32_t k = 0; k < n; ++k) hits += in_shard(Shard{k, n}, path);
      EXPECT_EQ(hits, 1) << path;
    }
  }
}

TEST(Shard, HashIsFixedFnv1a) {
  // FNV-1a 64 reference values: the split must never change between versions or machines.
  EXPECT_EQ(path_hash(""), 0xcbf29ce484222325ull);
  EXPECT_EQ(path_hash("a"), 0xaf63dc4c8601ec8cull);
  EXPECT_EQ(path_hash("foobar"), 0x85944171f73967e8ull);
}

TEST(Shard, SpreadsALibraryEvenly) {
  int counts[4] = {};
  for (int i = 0; i < 4000; ++i) {
    for (std::uint32_t k = 0; k < 4; ++k)
      counts[k] += in_shard(Shard{k, 4}, "props/crate_" + std::to_string(i) + ".glb");
  }
  for (int c : counts) EXPECT_NEAR(c, 1000, 120);
}

}  // namespace
}  // namespace lodforge::batch
