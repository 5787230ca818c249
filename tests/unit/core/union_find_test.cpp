#include "lodforge/core/union_find.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <thread>
#include <utility>
#include <vector>

namespace lodforge {
namespace {

// Random edges over n ids: a few large sets and many small ones.
std::vector<std::pair<std::uint32_t, std::uint32_t>> random_edges(std::uint32_t n, std::size_t count, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<std::uint32_t> any(0, n - 1), near(0, 64);
  std::vector<std::pair<std::uint32_t, std::uint32_t>> edges;
  for (std::size_t i = 0; i < count; ++i) {
    const std::uint32_t a = any(rng);
    const std::uint32_t b = i % 3 == 0 ? any(rng) : std::min(n - 1, a + near(rng));
    edges.emplace_back(a, b);
  }
  return edges;
}

TEST(UnionFind, RootsAreTheLowestMemberWhateverTheOrder) {
  const std::uint32_t n = 5000;
  auto edges = random_edges(n, 3000, 7);
  UnionFind forward(n), backward(n);
  for (const auto& [a, b] : edges) forward.unite(a, b);
  for (auto it = edges.rbegin(); it != edges.rend(); ++it) backward.unite(it->second, it->first);
  std::vector<std::uint32_t> lowest(n, n);
  for (std::uint32_t v = 0; v < n; ++v) {
    const std::uint32_t r = forward.find(v);
    EXPECT_LE(r, v);
    lowest[r] = std::min(lowest[r], v);
    EXPECT_EQ(backward.find(v), r) << v;
  }
  std::size_t sets = 0;
  for (std::uint32_t r = 0; r < n; ++r) {
    if (lowest[r] == n) continue;
    EXPECT_EQ(lowest[r], r);  // the root is in its set and lowest in it
    ++sets;
  }
  EXPECT_GT(sets, 100u);   // not one set: the test would say nothing
  EXPECT_LT(sets, n - 1000u);
}

TEST(UnionFind, SharedUnionsOnManyThreadsGiveTheSerialSets) {
  const std::uint32_t n = 200000;
  const auto edges = random_edges(n, 150000, 11);
  UnionFind serial(n);
  for (const auto& [a, b] : edges) serial.unite(a, b);
  for (int trial = 0; trial < 3; ++trial) {
    UnionFind shared(n);
    const unsigned threads = 4;
    std::vector<std::thread> pool;
    for (unsigned k = 0; k < threads; ++k) {
      pool.emplace_back([&, k] {
        for (std::size_t i = k; i < edges.size(); i += threads) shared.unite_shared(edges[i].first, edges[i].second);
      });
    }
    for (std::thread& t : pool) t.join();
    std::size_t differ = 0;
    for (std::uint32_t v = 0; v < n; ++v) differ += shared.find_shared(v) != serial.find(v);
    EXPECT_EQ(differ, 0u) << "trial " << trial;
  }
}

}  // namespace
}  // namespace lodforge
