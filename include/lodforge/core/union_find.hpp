// Disjoint sets over the ids 0 .. n-1.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <numeric>
#include <vector>

namespace lodforge {

// A root only ever links to a lower root, so every parent is at most its child and the root of a set is its
// lowest id, whatever the order of the unions: roots are deterministic. unite() and find() are for one
// thread; unite_shared() and find_shared() may run on many threads at once (relaxed atomics; a root links by
// compare-and-swap, and path halving may store any ancestor), and give the same sets and roots.
class UnionFind {
 public:
  explicit UnionFind(std::size_t n) : parent_(n) { std::iota(parent_.begin(), parent_.end(), std::uint32_t{0}); }

  std::uint32_t find(std::uint32_t x) {
    while (parent_[x] != x) x = parent_[x] = parent_[parent_[x]];
    return x;
  }
  void unite(std::uint32_t a, std::uint32_t b) {
    a = find(a), b = find(b);
    if (a != b) parent_[std::max(a, b)] = std::min(a, b);
  }

  std::uint32_t find_shared(std::uint32_t x) {
    for (;;) {
      const std::uint32_t up = load(x);
      if (up == x) return x;
      const std::uint32_t above = load(up);
      if (above != up) std::atomic_ref<std::uint32_t>(parent_[x]).store(above, std::memory_order_relaxed);
      x = above;
    }
  }
  void unite_shared(std::uint32_t a, std::uint32_t b) {
    for (;;) {
      a = find_shared(a), b = find_shared(b);
      if (a == b) return;
      if (a < b) std::swap(a, b);
      std::uint32_t expected = a;  // still a root?
      if (std::atomic_ref<std::uint32_t>(parent_[a]).compare_exchange_strong(expected, b, std::memory_order_relaxed)) {
        return;
      }
    }
  }

 private:
  std::uint32_t load(std::uint32_t x) {
    return std::atomic_ref<std::uint32_t>(parent_[x]).load(std::memory_order_relaxed);
  }
  std::vector<std::uint32_t> parent_;
};

}  // namespace lodforge
