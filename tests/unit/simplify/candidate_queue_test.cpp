#include "candidate_queue.hpp"

#include <gtest/gtest.h>

#include <bit>
#include <cstdint>
#include <random>
#include <set>
#include <tuple>
#include <vector>

namespace lodforge::collapse {
namespace {

using Key = std::tuple<std::uint64_t, std::uint32_t, std::uint32_t>;  // (key, v, vsum): the pop order

Key key_of(const QueueEntry& e) { return {e.key, e.v, e.vsum}; }

// Pops everything left, each pop the reference's least entry, until both are empty.
template <typename Keep>
void drain(CandidateQueue& queue, Parallel& parallel, Keep&& keep, std::set<Key>& reference) {
  while (queue.refill(parallel, keep)) {
    ASSERT_FALSE(reference.empty());
    ASSERT_EQ(key_of(queue.top()), *reference.begin());
    reference.erase(reference.begin());
    queue.pop();
  }
  EXPECT_TRUE(reference.empty());
}

// Pushes and pops interleaved, most pushes above the current minimum (as re-evaluations are) and some at or
// below it (as a round's put-backs are): the queue must pop exactly what an ordered set of the same entries
// would, through bucket changes, runs and the side heap.
void expect_same_order_as_a_set(unsigned threads, std::size_t pushes_per_step, float first_spread, int steps) {
  Parallel parallel(threads);
  CandidateQueue queue;
  std::set<Key> reference;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> jitter(0.0f, 1.0f);
  auto keep_all = [](const QueueEntry&) { return true; };
  std::uint32_t next_id = 0;
  float floor = 1e-6f;  // roughly the cost of what was popped last
  auto push = [&](float cost) {
    const std::uint32_t id = next_id++;
    const QueueEntry e = make_entry(cost_bits(cost), id % 977, id, id % 5);
    queue.push(e);
    reference.insert(key_of(e));
  };
  for (std::size_t i = 0; i < 3 * pushes_per_step; ++i) push(floor * (1.0f + first_spread * jitter(rng)));
  std::size_t popped = 0;
  for (int step = 0; step < steps; ++step) {
    for (std::size_t i = 0; i < pushes_per_step && queue.refill(parallel, keep_all); ++i) {
      ASSERT_FALSE(reference.empty());
      const QueueEntry top = queue.top();
      ASSERT_EQ(key_of(top), *reference.begin()) << "pop " << popped;
      reference.erase(reference.begin());
      queue.pop();
      ++popped;
      floor = std::bit_cast<float>(top.bits());
    }
    for (std::size_t i = 0; i < pushes_per_step; ++i) {
      const float r = jitter(rng);
      // One in eight at or below the current minimum (same bucket or lower), the rest above it.
      push(r < 0.125f ? floor * (0.5f + 4.0f * r) : floor * (1.0f + 50.0f * r));
    }
    ASSERT_EQ(queue.size(), reference.size());
  }
  drain(queue, parallel, keep_all, reference);
  EXPECT_GT(popped, static_cast<std::size_t>(steps) * pushes_per_step / 2);
}

TEST(CandidateQueue, PopsInKeyOrderThroughRunsAndHeap) { expect_same_order_as_a_set(1, 500, 100.0f, 60); }

// A first bucket large enough to be sorted in parallel (60,000 entries within 1% of one cost): the same order.
TEST(CandidateQueue, PopsInKeyOrderWithAParallelSort) { expect_same_order_as_a_set(2, 20000, 0.01f, 10); }

// A bucket filtered at refill and everything filtered at purge: only kept entries come out, in order.
TEST(CandidateQueue, RefillAndPurgeDropWhatKeepRejects) {
  Parallel parallel(1);
  CandidateQueue queue;
  std::set<Key> reference;
  auto even = [](const QueueEntry& e) { return e.v % 2 == 0; };
  for (std::uint32_t id = 0; id < 2000; ++id) {
    const QueueEntry e = make_entry(cost_bits(1.0 + id % 37), id, id, 0);
    queue.push(e);
    if (even(e)) reference.insert(key_of(e));
  }
  for (int i = 0; i < 100; ++i) {  // some pops from the first run, then entries at its level into the heap
    ASSERT_TRUE(queue.refill(parallel, even));
    ASSERT_EQ(key_of(queue.top()), *reference.begin());
    reference.erase(reference.begin());
    queue.pop();
  }
  for (std::uint32_t id = 2000; id < 2100; ++id) {
    const QueueEntry e = make_entry(cost_bits(1.0), id, id, 0);
    queue.push(e);
    if (even(e)) reference.insert(key_of(e));
  }
  queue.purge(parallel, even);
  EXPECT_EQ(queue.size(), reference.size());
  drain(queue, parallel, even, reference);
}

// Buckets of several blocks each, a purge that empties most of them, then as many pushes into other buckets:
// the freed blocks take the new entries (no new storage), and everything comes out in order, on two threads.
TEST(CandidateQueue, PurgedBlocksAreReusedByLaterPushes) {
  Parallel parallel(2);
  CandidateQueue queue;
  std::set<Key> reference;
  auto kept = [](const QueueEntry& e) { return e.vsum == 1 || e.v % 3 == 0; };
  for (std::uint32_t id = 0; id < 30000; ++id) {
    const QueueEntry e = make_entry(cost_bits(1.0 + id % 3), id, id, 0);  // three buckets of many blocks
    queue.push(e);
    if (kept(e)) reference.insert(key_of(e));
  }
  const std::size_t storage = queue.storage_entries();
  EXPECT_GE(storage, 30000u);
  queue.purge(parallel, kept);
  EXPECT_EQ(queue.size(), reference.size());
  for (std::uint32_t id = 30000; id < 50000; ++id) {
    const QueueEntry e = make_entry(cost_bits(8.0 + 8.0 * (id % 2)), id, id, 1);  // two other buckets
    queue.push(e);
    reference.insert(key_of(e));
  }
  EXPECT_EQ(queue.storage_entries(), storage);
  drain(queue, parallel, kept, reference);
}

}  // namespace
}  // namespace lodforge::collapse
