// The greedy engine's candidate queue (cost buckets of versioned edge entries, read as sorted runs) and its
// parking lot for candidates refused at check time. Engine-internal.
#pragma once

#include <algorithm>
#include <bit>
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

#include "collapse_mesh.hpp"

namespace lodforge::collapse {

// A queued candidate: edge (u, v), u < v, and vsum = version[u] + version[v] when it was evaluated. Versions
// only grow (a collapse bumps both its endpoints, the dead one included), so an unchanged sum means neither
// endpoint changed since: that is the whole staleness test (lazy invalidation).
// key = float bits of the cost (costs are >= 0, so the bits order like the values) above u; ties on the key
// break by v. 16 bytes, kept inline so that popping never chases a pointer.
struct QueueEntry {
  std::uint64_t key;
  std::uint32_t v, vsum;
  std::uint32_t u() const { return static_cast<std::uint32_t>(key); }
  std::uint32_t bits() const { return static_cast<std::uint32_t>(key >> 32); }
};

inline std::uint32_t cost_bits(double cost) { return std::bit_cast<std::uint32_t>(static_cast<float>(cost)); }

inline QueueEntry make_entry(std::uint32_t bits, std::uint32_t u, std::uint32_t v, std::uint32_t vsum) {
  return {(std::uint64_t{bits} << 32) | u, v, vsum};
}

inline bool entry_less(const QueueEntry& a, const QueueEntry& b) {
  return a.key < b.key || (a.key == b.key && a.v < b.v);
}

// Priority queue: a sorted run and a small 4-ary min-heap in front of cost buckets (a bucketed queue).
//
// Costs only grow as the mesh coarsens (a quadric sum never loses a term), so nearly every re-evaluated
// candidate lands above the current minimum. Such pushes go to a bucket (1/16 of an octave of cost, by the
// float's exponent and top mantissa bits) as a plain append into its last block. When the front runs dry, the
// next bucket is filtered for stale entries (in parallel: one version lookup each) and sorted into the run,
// which is then read front to back; only what is pushed at or below that bucket (the few candidates whose cost
// fell, and what a round popped and put back) goes to the heap, which stays small. Popping is the smaller of
// the run's next entry and the heap's top: exactly the (key, v) order of a single heap over all live entries,
// without a heap walk over a bucket's worth of entries per pop.
class CandidateQueue {
 public:
  static constexpr int kBucketShift = 19;  // float bits >> 19: sign, 8 exponent and 4 mantissa bits
  CandidateQueue() : buckets_(std::size_t{1} << (32 - kBucketShift)) {}

  std::size_t size() const { return stored_; }
  // Entries the buckets' blocks can hold, in use or free (what the buckets' memory is), and in free blocks.
  std::size_t storage_entries() const { return slabs_.size() * kBlocksPerSlab * kBlock; }
  std::size_t spare_entries() const { return free_.size() * kBlock; }
  // The cheapest entry; only after refill() returned true.
  const QueueEntry& top() const { return from_run() ? run_[next_] : heap_.front(); }

  void push(const QueueEntry& e) {
    ++stored_;
    const std::uint32_t b = e.bits() >> kBucketShift;
    if (b <= active_ && active_ != kNone) {
      heap_.push_back(e);
      sift_up(heap_.size() - 1, e);
    } else {
      append(buckets_[b], e);
      first_ = std::min(first_, b);
    }
  }
  void pop() {
    --stored_;
    if (from_run()) {
      ++next_;
      return;
    }
    const QueueEntry last = heap_.back();
    heap_.pop_back();
    if (heap_.empty()) return;
    // Bottom-up: walk the hole down along the smaller children to a leaf, then sift the last entry up from
    // there; the last entry is usually large, so this saves a comparison per level.
    const std::size_t n = heap_.size();
    std::size_t i = 0;
    for (std::size_t c = 1; c < n; c = 4 * i + 1) {
      const std::size_t best = min_child(c, n);
      heap_[i] = heap_[best];
      i = best;
    }
    sift_up(i, last);
  }
  // Once the run and the heap are both empty, moves the next bucket into the run, dropping entries keep()
  // rejects (decided in parallel) and sorting the rest; the bucket's blocks go back to the free list. Returns
  // false when nothing is left.
  template <typename Keep>
  bool refill(Parallel& parallel, Keep&& keep) {
    while (heap_.empty() && next_ == run_.size()) {
      while (first_ < buckets_.size() && buckets_[first_].size == 0) ++first_;
      if (first_ >= buckets_.size()) return false;
      active_ = first_;
      Bucket& bucket = buckets_[active_];
      chain(bucket, chain_);
      stored_ -= bucket.size;
      keep_flags_.resize(bucket.size);
      parallel.for_ranges(chain_.size(), 4, [&](std::size_t b, std::size_t e) {
        for (std::size_t i = b; i < e; ++i) {
          const QueueEntry* p = block(chain_[i]);
          const std::size_t n = entries_in(i, chain_.size(), bucket.fill);
          for (std::size_t j = 0; j < n; ++j) keep_flags_[i * kBlock + j] = keep(p[j]) ? 1 : 0;
        }
      });
      run_.clear();
      next_ = 0;
      for (std::size_t i = 0; i < chain_.size(); ++i) {
        const QueueEntry* p = block(chain_[i]);
        const std::size_t n = entries_in(i, chain_.size(), bucket.fill);
        for (std::size_t j = 0; j < n; ++j) {
          if (keep_flags_[i * kBlock + j]) run_.push_back(p[j]);
        }
        free_.push_back(chain_[i]);
      }
      bucket = Bucket{};
      stored_ += run_.size();
      // A total order (vsum last), so the sorted run is one sequence whatever the sort does with ties.
      parallel.sort(run_.begin(), run_.end(), [](const QueueEntry& a, const QueueEntry& b) {
        return entry_less(a, b) || (a.key == b.key && a.v == b.v && a.vsum < b.vsum);
      });
    }
    return true;
  }
  // Drops every entry keep() rejects from the run, the heap and all buckets (bounds memory); emptied blocks go
  // back to the free list.
  template <typename Keep>
  void purge(Parallel& parallel, Keep&& keep) {
    run_.erase(run_.begin(), run_.begin() + static_cast<std::ptrdiff_t>(next_));
    next_ = 0;
    const auto drop = [&](std::vector<QueueEntry>& l) {
      l.erase(std::remove_if(l.begin(), l.end(), [&](const QueueEntry& x) { return !keep(x); }), l.end());
    };
    drop(run_);
    drop(heap_);
    heapify();
    std::vector<std::uint32_t> used;
    for (std::uint32_t b = 0; b < buckets_.size(); ++b) {
      if (buckets_[b].size > 0) used.push_back(b);
    }
    std::vector<std::vector<std::uint32_t>> chains(used.size());
    parallel.for_ranges(used.size(), 1, [&](std::size_t b, std::size_t e) {
      for (std::size_t i = b; i < e; ++i) compact(buckets_[used[i]], chains[i], keep);
    });
    stored_ = run_.size() + heap_.size();
    for (std::size_t i = 0; i < used.size(); ++i) {
      const Bucket& bucket = buckets_[used[i]];
      stored_ += bucket.size;
      const std::size_t kept_blocks = (bucket.size + kBlock - 1) / kBlock;
      free_.insert(free_.end(), chains[i].begin() + static_cast<std::ptrdiff_t>(kept_blocks), chains[i].end());
    }
  }

 private:
  static constexpr std::uint32_t kNone = 0xffffffffu;
  // Buckets are chains of fixed blocks from one pool with a free list: what a bucket drops (at refill, at purge)
  // is reused by the next pushes, so memory follows the number of entries rather than each bucket's largest size.
  static constexpr std::size_t kBlock = 256;         // entries a block (4 KB)
  static constexpr std::size_t kBlocksPerSlab = 16;  // blocks allocated together (64 KB)
  struct Bucket {
    std::uint32_t head = kNone;  // the newest block, holding `fill` entries; every older one in the chain is full
    std::uint32_t fill = 0;
    std::size_t size = 0;
  };

  QueueEntry* block(std::uint32_t id) const {
    return slabs_[id / kBlocksPerSlab].get() + (id % kBlocksPerSlab) * kBlock;
  }
  void append(Bucket& b, const QueueEntry& e) {
    if (b.head == kNone || b.fill == kBlock) {
      if (free_.empty()) grow();
      const std::uint32_t id = free_.back();
      free_.pop_back();
      next_block_[id] = b.head;
      b.head = id;
      b.fill = 0;
    }
    block(b.head)[b.fill++] = e;
    ++b.size;
  }
  void grow() {
    const auto first = static_cast<std::uint32_t>(slabs_.size() * kBlocksPerSlab);
    slabs_.push_back(std::make_unique_for_overwrite<QueueEntry[]>(kBlock * kBlocksPerSlab));
    next_block_.resize(next_block_.size() + kBlocksPerSlab, kNone);
    for (std::uint32_t i = kBlocksPerSlab; i-- > 0;) free_.push_back(first + i);
  }
  // Entries in block i of a chain of `blocks`, oldest first: full but the head, which holds `fill`.
  static std::size_t entries_in(std::size_t i, std::size_t blocks, std::uint32_t fill) {
    return i + 1 == blocks ? fill : kBlock;
  }
  // The bucket's blocks, oldest first (the head, partly filled, last).
  void chain(const Bucket& b, std::vector<std::uint32_t>& out) const {
    out.clear();
    for (std::uint32_t id = b.head; id != kNone; id = next_block_[id]) out.push_back(id);
    std::reverse(out.begin(), out.end());
  }
  // Slides the entries keep() accepts to the front of the bucket's chain; `ids` gets the whole chain, oldest
  // first, and the blocks past the new size are the caller's to free.
  template <typename Keep>
  void compact(Bucket& b, std::vector<std::uint32_t>& ids, Keep& keep) {
    chain(b, ids);
    std::size_t w = 0;
    for (std::size_t i = 0; i < ids.size(); ++i) {
      const QueueEntry* p = block(ids[i]);
      const std::size_t n = entries_in(i, ids.size(), b.fill);
      for (std::size_t j = 0; j < n; ++j) {
        if (!keep(p[j])) continue;
        block(ids[w / kBlock])[w % kBlock] = p[j];
        ++w;
      }
    }
    b.size = w;
    if (w == 0) {
      b.head = kNone;
      b.fill = 0;
      return;
    }
    const std::size_t used = (w + kBlock - 1) / kBlock;
    b.head = ids[used - 1];
    b.fill = static_cast<std::uint32_t>(w - (used - 1) * kBlock);
  }

  // Whether top() is the run's next entry (else the heap's top).
  bool from_run() const { return next_ < run_.size() && (heap_.empty() || !entry_less(heap_.front(), run_[next_])); }

  void heapify() {
    const std::size_t n = heap_.size();
    if (n < 2) return;
    for (std::size_t i = (n - 2) / 4 + 1; i-- > 0;) {
      const QueueEntry e = heap_[i];
      std::size_t j = i;
      for (std::size_t c = 4 * j + 1; c < n; c = 4 * j + 1) {
        const std::size_t best = min_child(c, n);
        if (!entry_less(heap_[best], e)) break;
        heap_[j] = heap_[best];
        j = best;
      }
      heap_[j] = e;
    }
  }
  std::size_t min_child(std::size_t c, std::size_t n) const {
    const QueueEntry* p = &heap_[c];
    std::size_t best = 0;
    const std::size_t end = std::min<std::size_t>(4, n - c);
    for (std::size_t j = 1; j < end; ++j) best = entry_less(p[j], p[best]) ? j : best;
    return c + best;
  }
  void sift_up(std::size_t i, const QueueEntry& e) {
    while (i > 0) {
      const std::size_t p = (i - 1) / 4;
      if (!entry_less(e, heap_[p])) break;
      heap_[i] = heap_[p];
      i = p;
    }
    heap_[i] = e;
  }

  std::vector<Bucket> buckets_;
  std::vector<std::unique_ptr<QueueEntry[]>> slabs_;  // the blocks, kBlocksPerSlab at a time
  std::vector<std::uint32_t> next_block_;             // per block: the next older block of its bucket
  std::vector<std::uint32_t> free_;                   // blocks in no bucket
  std::vector<std::uint32_t> chain_;                  // refill(): the active bucket's blocks
  std::vector<QueueEntry> run_;   // the active bucket, sorted; entries before next_ are popped
  std::size_t next_ = 0;
  std::vector<QueueEntry> heap_;  // pushed at or below the active bucket since it became the run
  std::vector<std::uint8_t> keep_flags_;
  std::uint32_t active_ = kNone;  // highest bucket whose entries live in the run or the heap
  std::uint32_t first_ = 0;       // no bucket below this one holds entries
  std::size_t stored_ = 0;
};

// Candidates refused at check time wait here, listed on both endpoints, until a collapse changes either
// endpoint's neighbourhood; then they are evaluated again. Without this an edge refused once (say by the
// fold test in a flat region) would never be reconsidered and simplification would stall.
class ParkingLot {
 public:
  explicit ParkingLot(std::size_t vertices) : head_(vertices, kInvalidIndex) {}
  void park(std::uint32_t u, std::uint32_t v) {
    for (std::uint32_t s : {u, v}) {
      entries_.push_back({u, v, head_[s]});
      head_[s] = static_cast<std::uint32_t>(entries_.size() - 1);
      ++waiting_;
    }
  }
  // Appends the candidates parked on x to `out` and forgets them there.
  void release(std::uint32_t x, std::vector<std::pair<std::uint32_t, std::uint32_t>>& out) {
    for (std::uint32_t i = head_[x]; i != kInvalidIndex; i = entries_[i].next) {
      out.emplace_back(entries_[i].u, entries_[i].v);
      --waiting_;
    }
    head_[x] = kInvalidIndex;
  }
  // Whether any list is non-empty (each candidate counts twice, once per endpoint).
  bool any() const { return waiting_ > 0; }
  // Whether a candidate is parked on x.
  bool at(std::uint32_t x) const { return head_[x] != kInvalidIndex; }

 private:
  struct Entry {
    std::uint32_t u, v, next;
  };
  std::vector<std::uint32_t> head_;
  std::vector<Entry> entries_;
  std::size_t waiting_ = 0;
};

}  // namespace lodforge::collapse
