// Greedy quadric edge collapse.
//
// Papers and sources implemented here:
//  - M. Garland, P. Heckbert, "Surface Simplification Using Quadric Error Metrics", SIGGRAPH 1997: plane
//    quadrics, full-edge collapse to the optimal position, boundary constraint planes, greedy order.
//  - T. Dey, H. Edelsbrunner, S. Guha, D. Nekhayev, "Topology Preserving Edge Contraction", 1999: the link
//    condition, with boundaries coned to a virtual vertex (which yields the boundary pinch rule).
//  - G. van den Bergen, "Conservative Mesh Decimation", GDC 2021: the rubber-band point quadric (see metric).
//  - Independent-set batches as in ALGORITHMS.md 9.1/9.4 (meshoptimizer's pass structure, Wu & Kobbelt 2002):
//    the batch is chosen sequentially in cost order, so the result does not depend on the thread count.
//
// Driver (run_edge_collapse):
//   setup        normalise to the unit cube, build face lists, classify vertices, accumulate quadrics
//   candidates   every allowed edge evaluated in parallel, queued (bucketed 4-ary min-heap of
//                (cost, u, v, version sum); stale entries are skipped when they surface)
//   rounds       pop the cheapest candidates whose closed neighbourhoods are disjoint (a batch, in cost order;
//                the neighbourhoods are gathered in parallel) → check them in parallel → commit in order
//                (rejected ones are parked on their endpoints; list space is reserved in order, then each
//                rewrite and the re-evaluation of the edges around its survivor run in parallel) → re-evaluate
//                the parked candidates of the survivors' neighbourhoods → push in order
//   output       compact alive faces, wedges and vertices
// Every parallel step writes per-item outputs; everything that orders (pops, pushes, reservations) is
// sequential, so the output is byte-identical for any thread count.
#include "lodforge/simplify/edge_collapse.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <numbers>
#include <span>
#include <stdexcept>
#include <string>

#include "lodforge/core/mesh.hpp"
#include "lodforge/metric/skin.hpp"

namespace lodforge::collapse {
namespace {

// Ordering key: GH97's raw, area-weighted E(x), not E(x)/W. On the bunny the raw key gives about 0.019% / 0.14%
// mean error (of the diagonal) at 10% / 1% against 0.0205% / 0.155% for E/W, which lets vertices that absorbed
// much surface move too easily. The error budget still compares E/W (a distance) and drops what exceeds it.

// A surface quadric whose LDLᵀ pivots all exceed this fraction of its trace pins the placement down by itself
// (corners, where the rubber band would only pull the vertex off); below, the band joins the solve. On the
// bunny any value in [1e-9, 1e-2] gives the same mean error within 3%.
constexpr double kWellConditioned = 1e-4;

// A face whose |n|² is below this fraction of |e1|²|e2|² (sine of its angle below ~1e-6) counts as degenerate.
constexpr double kDegenerateSine2 = 1e-12;

// A UV triangle whose sine at a corner falls below this is a sliver (texels smeared across it): a collapse may
// not make one, though it keeps one the input has. On Duck at 50% this took the L2 stretch ratio (against the
// input's) from 8.7 to 0.8.
constexpr double kUvSliverSine = 1e-3;

// Normals (and tangents) of one vertex closer than this angle's cosine (0.1°) are one direction: well below any
// hard edge a modeller makes, well above float and 16-bit quantisation noise.
constexpr double kSameDirectionCos = 0.9999984769132877;

// A list that outgrows its slot moves to the pool's end with this much extra room (in faces), so that a
// vertex which keeps absorbing neighbours is not moved at every collapse.
constexpr std::uint32_t kListSlack = 4;

// Batch sizing (automatic max_batch): at most 1/kBatchDivisor of the live edges (under 1% of the queue) and at
// most kMaxBatch. Measured on the bunny, mean error (% of the diagonal) at 10% / 1%: strictly sequential
// 0.0191 / 0.141; batches of 1/256 (max 512) 0.0191 / 0.138; 1/128 (max 1024) 0.0191 / 0.142; 1/64 (max 2048)
// 0.0192 / 0.143; 1/32 0.0193 / 0.142. Quality is flat, so the larger batches win: fewer rounds, and each
// round gives the cores more to do.
constexpr std::size_t kBatchDivisor = 128;
constexpr std::size_t kMaxBatch = 1024;

// Heap entries superseded by newer ones stay in the heap until popped; when the heap is this many times the
// live edge count, drop them all at once (bounds memory; O(n) rebuild).
constexpr std::size_t kPurgeFactor = 3;

double elapsed_ms(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - since).count();
}

bool finite3(const Vec3d& p) { return std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]); }

// Local corner of vertex v in face t (t has three vertices, one of them v).
inline int corner_of(const std::uint32_t* t, std::uint32_t v) { return t[0] == v ? 0 : (t[1] == v ? 1 : 2); }

constexpr int kNext[3] = {1, 2, 0};
constexpr int kPrev[3] = {2, 0, 1};

// Insertion sort for the short lists of one vertex star (valence ~6), std::sort beyond.
template <typename T>
void small_sort(T* p, std::size_t n) {
  if (n > 32) {
    std::sort(p, p + n);
    return;
  }
  for (std::size_t i = 1; i < n; ++i) {
    const T x = p[i];
    std::size_t j = i;
    for (; j > 0 && x < p[j - 1]; --j) p[j] = p[j - 1];
    p[j] = x;
  }
}


// ---- the candidate queue ----------------------------------------------------------------------------------

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

// Priority queue: a 4-ary min-heap in front of cost buckets (a bucketed heap).
//
// Costs only grow as the mesh coarsens (a quadric sum never loses a term), so nearly every re-evaluated
// candidate lands above the current minimum. Such pushes go to a bucket (1/16 of an octave of cost, by the
// float's exponent and top mantissa bits) as a plain append; the heap holds only the lowest non-empty bucket
// plus whatever is pushed at or below it. When the heap runs dry the next bucket is filtered for stale
// entries (in parallel: one version lookup each, the dominant cost of a plain heap) and heapified. The pop
// order is exactly the (key, v) order of a single heap over all live entries.
class CandidateQueue {
 public:
  static constexpr int kBucketShift = 19;  // float bits >> 19: sign, 8 exponent and 4 mantissa bits
  CandidateQueue() : buckets_(std::size_t{1} << (32 - kBucketShift)) {}

  std::size_t size() const { return stored_; }
  bool heap_empty() const { return heap_.empty(); }
  const QueueEntry& top() const { return heap_.front(); }

  void push(const QueueEntry& e) {
    ++stored_;
    const std::uint32_t b = e.bits() >> kBucketShift;
    if (b <= active_ && active_ != kNone) {
      heap_.push_back(e);
      sift_up(heap_.size() - 1, e);
    } else {
      buckets_[b].push_back(e);
      first_ = std::min(first_, b);
    }
  }
  void pop() {
    --stored_;
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
  // Moves the next bucket into the heap once the heap is empty, dropping entries keep() rejects (decided in
  // parallel). Returns false when nothing is left.
  template <typename Keep>
  bool refill(Parallel& parallel, Keep&& keep) {
    while (heap_.empty()) {
      while (first_ < buckets_.size() && buckets_[first_].empty()) ++first_;
      if (first_ >= buckets_.size()) return false;
      active_ = first_;
      std::vector<QueueEntry>& bucket = buckets_[active_];
      stored_ -= bucket.size();
      keep_flags_.resize(bucket.size());
      parallel.for_ranges(bucket.size(), 1024, [&](std::size_t b, std::size_t e) {
        for (std::size_t i = b; i < e; ++i) keep_flags_[i] = keep(bucket[i]) ? 1 : 0;
      });
      for (std::size_t i = 0; i < bucket.size(); ++i) {
        if (keep_flags_[i]) heap_.push_back(bucket[i]);
      }
      stored_ += heap_.size();
      std::vector<QueueEntry>().swap(bucket);  // release: this bucket is now the heap
      heapify();
    }
    return true;
  }
  // Drops every entry keep() rejects from the heap and all buckets (bounds memory).
  template <typename Keep>
  void purge(Parallel& parallel, Keep&& keep) {
    std::vector<std::vector<QueueEntry>*> lists;
    lists.push_back(&heap_);
    for (auto& b : buckets_) {
      if (!b.empty()) lists.push_back(&b);
    }
    parallel.for_ranges(lists.size(), 1, [&](std::size_t b, std::size_t e) {
      for (std::size_t i = b; i < e; ++i) {
        std::vector<QueueEntry>& l = *lists[i];
        l.erase(std::remove_if(l.begin(), l.end(), [&](const QueueEntry& x) { return !keep(x); }), l.end());
      }
    });
    stored_ = 0;
    for (auto* l : lists) stored_ += l->size();
    heapify();
  }

 private:
  static constexpr std::uint32_t kNone = 0xffffffffu;

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

  std::vector<std::vector<QueueEntry>> buckets_;
  std::vector<QueueEntry> heap_;
  std::vector<std::uint8_t> keep_flags_;
  std::uint32_t active_ = kNone;  // highest bucket whose entries live in the heap
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

 private:
  struct Entry {
    std::uint32_t u, v, next;
  };
  std::vector<std::uint32_t> head_;
  std::vector<Entry> entries_;
  std::size_t waiting_ = 0;
};

}  // namespace

// ---- Parallel -----------------------------------------------------------------------------------------------

Parallel::Parallel(unsigned threads)
    : concurrency_(threads == 0 ? static_cast<unsigned>(tbb::this_task_arena::max_concurrency()) : threads),
      arena_(static_cast<int>(threads == 0 ? tbb::task_arena::automatic : threads)) {
  if (concurrency_ == 0) concurrency_ = 1;
}

// ---- CollapseMesh: setup ------------------------------------------------------------------------------------

CollapseMesh::CollapseMesh(const Mesh& m, const SimplifyOptions& options, Parallel& parallel)
    : src_(m), options_(options) {
  const std::size_t nv = m.vertex_count(), nw = m.wedge_count();
  for (std::uint32_t v : options.locked_vertices) {
    if (v >= nv) {
      throw std::invalid_argument("simplify: locked vertex " + std::to_string(v) + " out of range (mesh has " +
                                  std::to_string(nv) + " vertices)");
    }
  }
  // Bounding box of the finite positions (as compute_bounds), reduced over fixed chunks: min and max are
  // exact, so the result does not depend on how the chunks are spread over threads.
  constexpr std::size_t kVertexChunk = 16384;
  std::vector<Bounds3> chunk_bounds((nv + kVertexChunk - 1) / kVertexChunk);
  parallel.for_ranges(chunk_bounds.size(), 1, [&](std::size_t cb, std::size_t ce) {
    for (std::size_t c = cb; c < ce; ++c) {
      for (std::size_t v = c * kVertexChunk; v < std::min(nv, (c + 1) * kVertexChunk); ++v) {
        const Vec3f& p = m.positions[v];
        if (std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2])) chunk_bounds[c].add(to_double(p));
      }
    }
  });
  Bounds3 bounds;
  for (const Bounds3& b : chunk_bounds) {
    if (!b.empty()) {
      bounds.add(b.min);
      bounds.add(b.max);
    }
  }
  diagonal_ = bounds.diagonal();
  if (!bounds.empty()) {
    origin_ = bounds.min;
    const Vec3d ext = bounds.max - bounds.min;
    const double e = std::max({ext[0], ext[1], ext[2]});
    scale_ = e > 0.0 ? e : 1.0;
  }
  cos_max_flip_ = std::cos(options.max_flip_angle_deg * std::numbers::pi / 180.0);

  vx_.resize(nv);
  version_.assign(nv, 0);
  kind_.assign(nv, VertexKind::interior);
  state_.assign(nv, 0);
  const double inv = 1.0 / scale_;
  parallel.for_ranges(nv, 4096, [&](std::size_t b, std::size_t e) {
    for (std::size_t v = b; v < e; ++v) vx_[v].pos = (to_double(m.positions[v]) - origin_) * inv;
  });

  // Working triangles: those with valid indices and three distinct vertices. Two parallel passes over fixed
  // chunks of faces (count, then fill at the chunk's prefix offset): input order, whatever the threads.
  const std::size_t nf = m.face_count();
  auto valid = [&](std::size_t f, std::uint32_t* w, std::uint32_t* v) {
    if (m.face_offsets[f + 1] - m.face_offsets[f] != 3) return false;
    const std::uint32_t c = m.face_offsets[f];
    for (int i = 0; i < 3; ++i) {
      w[i] = m.corner_wedge[c + i];
      if (w[i] >= nw) return false;
      v[i] = m.wedge_vertex[w[i]];
      if (v[i] >= nv) return false;
    }
    return v[0] != v[1] && v[1] != v[2] && v[0] != v[2];
  };
  constexpr std::size_t kFaceChunk = 16384;
  const std::size_t chunks = (nf + kFaceChunk - 1) / kFaceChunk;
  std::vector<std::uint32_t> chunk_first(chunks + 1, 0);
  parallel.for_ranges(chunks, 1, [&](std::size_t cb, std::size_t ce) {
    for (std::size_t c = cb; c < ce; ++c) {
      std::uint32_t n = 0, w[3], v[3];
      for (std::size_t f = c * kFaceChunk; f < std::min(nf, (c + 1) * kFaceChunk); ++f) n += valid(f, w, v);
      chunk_first[c] = n;
    }
  });
  std::uint32_t total = 0;
  for (std::size_t c = 0; c <= chunks; ++c) total += std::exchange(chunk_first[c], total);
  tri_.resize(3 * std::size_t{total});
  tri_wedge_.resize(3 * std::size_t{total});
  tri_source_.resize(total);
  parallel.for_ranges(chunks, 1, [&](std::size_t cb, std::size_t ce) {
    for (std::size_t c = cb; c < ce; ++c) {
      std::uint32_t out = chunk_first[c], w[3], v[3];
      for (std::size_t f = c * kFaceChunk; f < std::min(nf, (c + 1) * kFaceChunk); ++f) {
        if (!valid(f, w, v)) continue;
        std::copy(v, v + 3, &tri_[3 * std::size_t{out}]);
        std::copy(w, w + 3, &tri_wedge_[3 * std::size_t{out}]);
        tri_source_[out++] = static_cast<std::uint32_t>(f);
      }
    }
  });
  alive_faces_ = tri_source_.size();

  // Vertex → faces lists (counting sort: each list in face order).
  size_.assign(nv, 0);
  for (std::uint32_t v : tri_) ++size_[v];
  begin_.resize(nv);
  std::uint32_t acc = 0;
  for (std::size_t v = 0; v < nv; ++v) {
    begin_[v] = acc;
    acc += size_[v];
  }
  capacity_ = size_;
  pool_.reserve(acc + acc / 2);
  pool_.resize(acc);
  {
    std::vector<std::uint32_t> fill(begin_);
    for (std::uint32_t f = 0; f < total; ++f) {
      for (int j = 0; j < 3; ++j) pool_[fill[tri_[3 * std::size_t{f} + j]]++] = f;
    }
  }

  // Working copies of what collapses may change.
  if (m.normals.size() == nw) normals_ = m.normals;
  for (const auto& set : m.uvs) uvs_.push_back(set.size() == nw ? set : std::vector<Vec2f>{});
  for (const auto& set : m.colors) colors_.push_back(set.size() == nw ? set : std::vector<Vec4f>{});
  morphs_ = m.morph_targets;
  if (m.skin.size() == nv) {
    skin_ = m.skin;
    for (const SkinInfluences& s : skin_) {
      int n = 0;
      for (float w : s.weights) n += w > 0.0f;
      skin_cap_ = std::max(skin_cap_, n);
    }
  }
  blend_ = options.attribute_placement == AttributePlacement::optimal;

  setup_keys();
  setup(parallel);
  setup_attributes(parallel);
}

namespace {

// Whether two normals (or tangents, xyz) point the same way within kSameDirectionCos. Exporters round the
// normals of one smooth vertex differently per render vertex (CesiumMan: 962 wedge pairs whose normals differ
// only by float noise, under 0.001°); such a split is no hard edge, and treating it as a seam pinned the
// vertex to it (mean distance 0.0088% against 0.0031% of the diagonal at 50%).
bool same_direction(const auto& a, const auto& b) {
  const double d = double{a[0]} * b[0] + double{a[1]} * b[1] + double{a[2]} * b[2];
  const double aa = double{a[0]} * a[0] + double{a[1]} * a[1] + double{a[2]} * a[2];
  const double bb = double{b[0]} * b[0] + double{b[1]} * b[1] + double{b[2]} * b[2];
  if (!(aa > 0.0) || !(bb > 0.0)) return a[0] == b[0] && a[1] == b[1] && a[2] == b[2];
  return d > 0.0 && d * d >= kSameDirectionCos * kSameDirectionCos * aa * bb;
}

}  // namespace

// Wedges and corner keys (see VertexKind). Render vertices of one vertex that are equal in every attribute
// (non-indexed glTF primitives store one per corner), normals and tangents within 0.1° (same_direction), are
// one wedge: corners use the lowest such wedge id, so they are no seam; the others drop out of the output.
// Keys are only materialised when they differ from the wedge ids: with several materials (a wedge used on
// both sides of a material boundary gets one key per side) or in permissive mode (wedges of one vertex equal
// in everything but normals and tangents share a key).
void CollapseMesh::setup_keys() {
  const Mesh& m = src_;
  const std::size_t nw = m.wedge_count(), nv = m.vertex_count(), nf = tri_source_.size();
  auto material = [&](std::size_t f) {
    const std::uint32_t sf = tri_source_[f];
    return sf < m.face_material.size() ? m.face_material[sf] : 0u;
  };
  bool several = false;
  for (std::size_t f = 1; f < nf && !several; ++f) several = material(f) != material(0);

  // Wedges grouped by vertex (counting sort keeps ids ascending); wedges naming no vertex are left out.
  std::vector<std::uint32_t> first(nv + 1, 0), order(nw);
  for (std::uint32_t w = 0; w < nw; ++w) {
    if (m.wedge_vertex[w] < nv) ++first[m.wedge_vertex[w] + 1];
  }
  bool shared = false;
  for (std::size_t v = 0; v < nv; ++v) {
    shared |= first[v + 1] > 1;
    first[v + 1] += first[v];
  }
  std::vector<std::uint32_t> exact, loose;  // class representative of each wedge (identity when empty)
  if (shared) {
    {
      std::vector<std::uint32_t> fill(first.begin(), first.end() - 1);
      for (std::uint32_t w = 0; w < nw; ++w) {
        if (m.wedge_vertex[w] < nv) order[fill[m.wedge_vertex[w]]++] = w;
      }
    }
    auto same = [&](std::uint32_t x, std::uint32_t y, bool with_normals) {
      if (with_normals) {
        if (m.normals.size() == nw && !same_direction(m.normals[x], m.normals[y])) return false;
        if (m.tangents.size() == nw &&
            !(same_direction(m.tangents[x], m.tangents[y]) && (m.tangents[x][3] < 0.0f) == (m.tangents[y][3] < 0.0f))) {
          return false;
        }
        for (const MorphTarget& t : m.morph_targets) {
          if (t.normal_deltas.size() == nw && !(t.normal_deltas[x] == t.normal_deltas[y])) return false;
          if (t.tangent_deltas.size() == nw && !(t.tangent_deltas[x] == t.tangent_deltas[y])) return false;
        }
      }
      for (const MorphTarget& t : m.morph_targets) {
        if (t.position_deltas.size() == nw && !(t.position_deltas[x] == t.position_deltas[y])) return false;
      }
      for (const auto& set : m.uvs) {
        if (set.size() == nw && !(set[x] == set[y])) return false;
      }
      for (const auto& set : m.colors) {
        if (set.size() == nw && !(set[x] == set[y])) return false;
      }
      for (const CustomAttribute& c : m.custom) {
        const auto k = static_cast<std::size_t>(std::max(c.components, 0));
        if (k == 0 || c.values.size() != nw * k) continue;
        for (std::size_t i = 0; i < k; ++i) {
          if (!(c.values[x * k + i] == c.values[y * k + i])) return false;
        }
      }
      return true;
    };
    auto classify = [&](std::vector<std::uint32_t>& cls, bool with_normals) {
      cls.resize(nw);
      for (std::uint32_t w = 0; w < nw; ++w) cls[w] = w;
      for (std::size_t v = 0; v < nv; ++v) {
        for (std::uint32_t i = first[v]; i < first[v + 1]; ++i) {
          for (std::uint32_t j = first[v]; j < i; ++j) {
            if (cls[order[j]] == order[j] && same(order[i], order[j], with_normals)) {
              cls[order[i]] = order[j];
              break;
            }
          }
        }
      }
    };
    classify(exact, true);
    for (std::uint32_t& w : tri_wedge_) w = exact[w];
    if (options_.permissive) classify(loose, false);
  }
  if (!several && loose.empty()) return;

  // Dense ids for (class, material) pairs.
  std::vector<std::uint64_t> pairs(tri_wedge_.size());
  for (std::size_t c = 0; c < tri_wedge_.size(); ++c) {
    const std::uint32_t w = tri_wedge_[c];
    pairs[c] = (std::uint64_t{loose.empty() ? w : loose[w]} << 32) | material(c / 3);
  }
  std::vector<std::uint64_t> sorted(pairs);
  std::sort(sorted.begin(), sorted.end());
  sorted.erase(std::unique(sorted.begin(), sorted.end()), sorted.end());
  tri_key_.resize(pairs.size());
  for (std::size_t c = 0; c < pairs.size(); ++c) {
    tri_key_[c] = static_cast<std::uint32_t>(std::lower_bound(sorted.begin(), sorted.end(), pairs[c]) - sorted.begin());
  }
}

// The painted weight of each vertex (options.priority_channel), 1 where there is none. A per-wedge source
// gives each vertex the largest value of its wedges (a painted seam stays painted on both sides).
void CollapseMesh::setup_priority(std::vector<float>& priority) const {
  const Mesh& m = src_;
  const std::size_t nv = m.vertex_count(), nw = m.wedge_count();
  const std::string& ch = options_.priority_channel;
  priority.clear();
  if (ch.empty() || ch == "none") return;
  if (ch == "_LOD_PRIORITY" && m.priority.size() == nv) {
    priority = m.priority;
  } else {
    const std::size_t dot = ch.find('.');
    const std::string name = ch.substr(0, dot);
    int component = 0;
    if (dot != std::string::npos && dot + 2 == ch.size()) {
      const char c = ch[dot + 1];
      component = (c == 'x' || c == 'r') ? 0 : (c == 'y' || c == 'g') ? 1 : (c == 'z' || c == 'b') ? 2 : 3;
    }
    auto from_wedges = [&](auto&& value) {
      priority.assign(nv, -1.0f);
      for (std::uint32_t w = 0; w < nw; ++w) {
        if (m.wedge_vertex[w] >= nv) continue;
        float& p = priority[m.wedge_vertex[w]];
        p = std::max(p, value(w));
      }
    };
    const bool digits = name.size() > 6 && name.size() < 12 &&
                        std::all_of(name.begin() + 6, name.end(), [](char c) { return c >= '0' && c <= '9'; });
    if (name.starts_with("COLOR_")) {
      // A malformed channel ("COLOR_x") names nothing: no paint (the config rejects it earlier).
      const std::size_t set = digits ? static_cast<std::size_t>(std::stoul(name.substr(6))) : m.colors.size();
      if (set < m.colors.size() && m.colors[set].size() == nw) {
        from_wedges([&](std::uint32_t w) { return m.colors[set][w][component]; });
      }
    } else {
      for (const CustomAttribute& c : m.custom) {
        if (c.name != name || component >= c.components || c.components <= 0) continue;
        const auto k = static_cast<std::size_t>(c.components);
        if (c.values.size() != nw * k) continue;
        from_wedges([&](std::uint32_t w) { return c.values[w * k + static_cast<std::size_t>(component)]; });
        break;
      }
    }
  }
  for (float& p : priority) {
    if (std::isnan(p) || p < 0.0f) p = p < 0.0f ? 0.0f : 1.0f;  // NaN: neutral; negative: don't care
  }
}

// Classifies every vertex from its fan and accumulates its quadric. One pass, parallel over vertices; each
// vertex sums its own faces in list order, so the sums do not depend on the thread count.
void CollapseMesh::setup(Parallel& parallel) {
  const std::size_t nv = vx_.size();
  std::vector<std::uint8_t> user_locked(nv, 0);
  for (std::uint32_t v : options_.locked_vertices) user_locked[v] = 1;
  std::vector<float> priority;
  setup_priority(priority);
  for (std::size_t v = 0; v < priority.size(); ++v) {
    if (priority[v] >= options_.priority_lock) user_locked[v] = 1;
  }
  const bool preserve = options_.border_mode == BorderMode::preserve;
  const bool lock_border = options_.border_mode == BorderMode::lock;

  // Face planes once per face (unit normal, offset, area); each vertex then sums its faces' quadrics.
  // Plain doubles and no value-initialisation: every entry is written below.
  struct FacePlane {
    double n[3], d, area;
  };
  const std::size_t nf = tri_source_.size();
  const std::unique_ptr<FacePlane[]> planes(new FacePlane[nf]);
  parallel.for_ranges(nf, 4096, [&](std::size_t b, std::size_t e) {
    for (std::size_t f = b; f < e; ++f) {
      const std::uint32_t* t = &tri_[3 * f];
      const Vec3d n = cross(vx_[t[1]].pos - vx_[t[0]].pos, vx_[t[2]].pos - vx_[t[0]].pos);
      const double len = length(n);
      if (len > 0.0 && std::isfinite(len)) {
        const Vec3d unit = n * (1.0 / len);
        planes[f] = {{unit[0], unit[1], unit[2]}, -dot(unit, vx_[t[0]].pos), 0.5 * len};
      } else {
        planes[f] = {{0.0, 0.0, 0.0}, 0.0, 0.0};  // degenerate or non-finite: no surface
      }
    }
  });

  // Each vertex's surface area (its quadric's weight), densely: summed in vertex order below.
  std::vector<double> vertex_area(nv, 0.0);
  tbb::enumerable_thread_specific<Scratch> scratch;
  parallel.for_ranges(nv, 1024, [&](std::size_t vb, std::size_t ve) {
    Scratch& s = scratch.local();
    for (std::size_t vi = vb; vi < ve; ++vi) {
      const auto v = static_cast<std::uint32_t>(vi);
      const std::uint32_t m = size_[v];
      const std::uint32_t* fl = &pool_[begin_[v]];
      if (!finite3(vx_[v].pos)) {
        kind_[v] = VertexKind::frozen;
        continue;
      }
      if (m == 0) continue;

      // Spokes (v, x) packed as x << 32 | code, code = 2 × face slot + direction (0: v → x in the face), so
      // that sorting groups the faces of each spoke.
      s.spokes.resize(2 * std::size_t{m});
      Quadric q;
      // Distinct corner keys around v, up to three (three or more: complex).
      std::uint32_t keys[3] = {key(3 * std::size_t{fl[0]} + corner_of(&tri_[3 * std::size_t{fl[0]}], v)), 0, 0};
      int nkeys = 1;
      for (std::uint32_t i = 0; i < m; ++i) {
        const std::uint32_t* t = &tri_[3 * std::size_t{fl[i]}];
        const int j = corner_of(t, v);
        s.spokes[2 * i] = (std::uint64_t{t[kNext[j]]} << 32) | (2 * i);
        s.spokes[2 * i + 1] = (std::uint64_t{t[kPrev[j]]} << 32) | (2 * i + 1);
        const std::uint32_t kc = key(3 * std::size_t{fl[i]} + j);
        if (nkeys < 3 && kc != keys[0] && (nkeys < 2 || kc != keys[1])) keys[nkeys++] = kc;
        const FacePlane& pl = planes[fl[i]];
        Quadric fq = Quadric::from_plane(Vec3d{{pl.n[0], pl.n[1], pl.n[2]}}, pl.d, pl.area);
        fq.weight = pl.area;
        q += fq;
      }
      if (nkeys > 1) state_[v] |= kSeam;
      const VertexKind seam_kind = nkeys >= 3 ? VertexKind::complex : VertexKind::seam;

      // Fast path, most vertices: one closed, consistently oriented fan. Walk from face 0 to the face that
      // has the next spoke as its previous one; a closed fan comes back to face 0 after exactly m steps,
      // each step finding exactly one face.
      if (m <= 16 && !user_locked[v] && nkeys == 1) {
        std::uint32_t cur = 0;
        bool closed = true;
        for (std::uint32_t step = 1; step <= m && closed; ++step) {
          const auto x = static_cast<std::uint32_t>(s.spokes[2 * cur] >> 32);
          std::uint32_t found = 0, count = 0;
          for (std::uint32_t j = 0; j < m; ++j) {
            if (static_cast<std::uint32_t>(s.spokes[2 * j + 1] >> 32) == x) {
              found = j;
              ++count;
            }
          }
          closed = count == 1 && (found != 0 || step == m);
          cur = found;
        }
        if (closed && cur == 0) {
          vx_[v].quadric = q;
          vertex_area[v] = q.weight;
          kind_[v] = nkeys > 1 ? seam_kind : VertexKind::interior;
          if (kind_[v] != VertexKind::complex) state_[v] |= kFan;
          continue;
        }
      }
      small_sort(s.spokes.data(), s.spokes.size());

      // Fans: union faces across spokes shared by exactly two faces.
      s.parent.resize(m);
      for (std::uint32_t i = 0; i < m; ++i) s.parent[i] = i;
      auto find = [&](std::uint32_t x) {
        while (s.parent[x] != x) x = s.parent[x] = s.parent[s.parent[x]];
        return x;
      };
      bool boundary = false, non_manifold = false, inconsistent = false;
      const std::size_t ns = s.spokes.size();
      for (std::size_t i = 0; i < ns;) {
        const std::uint32_t x = static_cast<std::uint32_t>(s.spokes[i] >> 32);
        std::size_t j = i + 1;
        while (j < ns && static_cast<std::uint32_t>(s.spokes[j] >> 32) == x) ++j;
        const std::size_t run = j - i;
        const auto code0 = static_cast<std::uint32_t>(s.spokes[i]);
        if (run == 1) {
          boundary = true;
          if (preserve) {
            const std::uint32_t* t = &tri_[3 * std::size_t{fl[code0 / 2]}];
            const Vec3d n = cross(vx_[t[1]].pos - vx_[t[0]].pos, vx_[t[2]].pos - vx_[t[0]].pos);
            q += Quadric::from_boundary_edge(vx_[v].pos, vx_[x].pos, n, options_.border_weight);
          }
        } else if (run == 2) {
          const auto code1 = static_cast<std::uint32_t>(s.spokes[i + 1]);
          if ((code0 & 1) == (code1 & 1)) inconsistent = true;
          if (nkeys > 1) {
            // A seam edge (the keys of v or x differ across it) gets the constraint planes of a boundary edge
            // on each side, weighted by border_weight (GH97's discontinuity planes): seam vertices move freely
            // along the seam, both sides together, but hardly off it, so charts and material regions keep
            // their outlines (a material boundary across a bumpy grid stays within 0.002 edge lengths of its
            // line; weight 1 lets it drift 0.05 for a 4% lower corpus distance).
            const std::size_t f0 = 3 * std::size_t{fl[code0 / 2]}, f1 = 3 * std::size_t{fl[code1 / 2]};
            const bool seam_edge = key(f0 + corner_of(&tri_[f0], v)) != key(f1 + corner_of(&tri_[f1], v)) ||
                                   key(f0 + corner_of(&tri_[f0], x)) != key(f1 + corner_of(&tri_[f1], x));
            if (seam_edge) {
              for (const std::size_t f3 : {f0, f1}) {
                const std::uint32_t* t = &tri_[f3];
                const Vec3d n = cross(vx_[t[1]].pos - vx_[t[0]].pos, vx_[t[2]].pos - vx_[t[0]].pos);
                q += Quadric::from_boundary_edge(vx_[v].pos, vx_[x].pos, n, options_.border_weight);
              }
            }
          }
          const std::uint32_t r0 = find(code0 / 2), r1 = find(code1 / 2);
          if (r0 != r1) s.parent[std::max(r0, r1)] = std::min(r0, r1);
        } else {
          non_manifold = true;
        }
        i = j;
      }
      std::uint32_t fans = 0;
      for (std::uint32_t i = 0; i < m; ++i) fans += find(i) == i;
      if (fans > 1) non_manifold = true;

      vx_[v].quadric = q;
      vertex_area[v] = q.weight;
      if (user_locked[v] || non_manifold || inconsistent || (lock_border && boundary)) {
        kind_[v] = VertexKind::locked;
      } else {
        kind_[v] = nkeys > 1 ? seam_kind : boundary ? VertexKind::border : VertexKind::interior;
        if (kind_[v] != VertexKind::complex) state_[v] |= kFan | (boundary ? kOpen : 0);
      }
    }
  });

  // Faces touching a frozen vertex: their other vertices lock too (any collapse would test or move a face
  // with a non-finite corner).
  const bool any_frozen = std::find(kind_.begin(), kind_.end(), VertexKind::frozen) != kind_.end();
  for (std::size_t f = 0; any_frozen && f < nf; ++f) {
    const std::uint32_t* t = &tri_[3 * f];
    if (kind_[t[0]] == VertexKind::frozen || kind_[t[1]] == VertexKind::frozen || kind_[t[2]] == VertexKind::frozen) {
      for (int i = 0; i < 3; ++i) {
        if (kind_[t[i]] == VertexKind::frozen) continue;
        kind_[t[i]] = VertexKind::locked;
        state_[t[i]] &= static_cast<std::uint8_t>(~kFan);
      }
    }
  }

  // Rubber band: a point quadric at each vertex, weight relative to the mean face area (each face's area was
  // added to three vertices). Summed in vertex order: deterministic. Kept apart from the surface quadric as
  // (count, sum of positions): it only steers the placement; the cost is the surface error alone.
  double area3 = 0.0;
  for (std::size_t v = 0; v < nv; ++v) area3 += vertex_area[v];
  const double mean_area = alive_faces_ > 0 ? area3 / 3.0 / static_cast<double>(alive_faces_) : 0.0;
  weight_floor_ = std::max(1e-30, 1e-6 * mean_area);
  reg_weight_ = options_.regularization_weight * mean_area;
  parallel.for_ranges(nv, 4096, [&](std::size_t b, std::size_t e) {
    for (std::size_t v = b; v < e; ++v) {
      if (size_[v] > 0 && kind_[v] != VertexKind::frozen) {
        vx_[v].anchors = 1.0f;
        vx_[v].anchor_sum = to_float(vx_[v].pos);
      }
      // Painted priority π scales the whole quadric (faces and constraint planes, and its area, so that the
      // error bound E / W stays an unpainted distance): importance propagates into merged vertices and pulls
      // placement towards the painted side (ALGORITHMS.md 6). The factor is π², so that π acts on distances:
      // a region painted π is held to about 1/π of the distance error. With π itself the greedy order (E
      // grows like edge length⁶ on a smooth surface) moves the painted share of a sphere half painted 10 only
      // from 50% to 68% at 10% of the triangles; with π², 70% and more. 0 leaves the vertex free.
      if (v < priority.size() && priority[v] != 1.0f) {
        const double pi = static_cast<double>(priority[v]);
        vx_[v].quadric *= pi * pi;
      }
    }
  });
  priority_.swap(priority);
}

// Attribute quadrics (Hoppe 1999) of every wedge: each face's linear attribute functions, weighted by the
// face's area × the corner vertex's painted priority squared (as the surface quadric), summed into the wedge at each corner. Parallel over
// vertices (a wedge belongs to one vertex), each vertex's faces in list order: deterministic.
//
// Units (SimplifyOptions::AttributeWeights): positions are normalised to the unit cube; a normal or colour
// component is scaled by sqrt(λ) × L with L = sqrt(2 × mean face area) (about one mean edge length), a UV set
// by sqrt(λ) × sqrt(Σ 3-D area / Σ UV area) (its texel density), so every scaled attribute is a length.
void CollapseMesh::setup_attributes(Parallel& parallel) {
  const Mesh& m = src_;
  const std::size_t nf = tri_source_.size(), nw = m.wedge_count(), nv = vx_.size();
  const AttributeWeights& aw = options_.attribute_weights;
  bool metric = !normals_.empty() || !skin_.empty();  // anything below that needs the areas
  for (const auto& set : uvs_) metric |= !set.empty();
  for (const auto& set : colors_) metric |= !set.empty();
  if (!metric) {  // geometry only (morph deltas at most): no groups, no skin term
    carry_ = blend_ && !morphs_.empty();
    return;
  }
  double area = 0.0;
  std::vector<double> uv_area(uvs_.size(), 0.0);
  for (std::size_t f = 0; f < nf; ++f) {
    const std::uint32_t* t = &tri_[3 * f];
    const std::uint32_t* w = &tri_wedge_[3 * f];
    const Vec3d p0 = vx_[t[0]].pos, p1 = vx_[t[1]].pos, p2 = vx_[t[2]].pos;
    if (!finite3(p0) || !finite3(p1) || !finite3(p2)) continue;
    area += 0.5 * length(cross(p1 - p0, p2 - p0));
    for (std::size_t set = 0; set < uvs_.size(); ++set) {
      if (uvs_[set].empty()) continue;
      const double ua = uv_triangle_area(uvs_[set][w[0]], uvs_[set][w[1]], uvs_[set][w[2]]);
      if (std::isfinite(ua)) uv_area[set] += ua;
    }
  }
  const double length_unit = attribute_length_unit(area, nf);
  skin_cost_scale_ = skin_.empty() ? 0.0 : aw.skin * length_unit * length_unit;

  std::vector<std::uint8_t> color_sets;
  for (const auto& set : colors_) color_sets.push_back(set.empty() ? 0 : 1);
  layout_ = attribute_layout({.normals = !normals_.empty(),
                              .uv_area = uv_area,
                              .color_sets = color_sets,
                              .area = area,
                              .length_unit = length_unit,
                              .normal_weight = aw.normal,
                              .uv_weight = aw.uv,
                              .color_weight = aw.color});
  bool values = !normals_.empty() || !skin_.empty() || !morphs_.empty();
  for (const auto& set : uvs_) values |= !set.empty();
  for (const auto& set : colors_) values |= !set.empty();
  carry_ = layout_.dims > 0 || (blend_ && values);
  if (layout_.dims == 0) return;  // geometry only: nothing below runs, the engine is exactly the plain QEM one

  const auto dims = static_cast<std::size_t>(layout_.dims);
  wq_.assign(nw, {});
  wg_.assign(nw * dims, {});
  // Scaled attribute vector of wedge w.
  auto scaled = [&](std::uint32_t w, double* out) { layout_.scaled(normals_, uvs_, colors_, w, out); };
  // Per face, the in-plane gradient basis: an attribute with corner values s0, s1, s2 has gradient
  // (s1 − s0) B1 + (s2 − s0) B2 (fit_attribute_gradient's Gram solve, done once per face instead of once per
  // attribute and corner).
  struct FaceBasis {
    Vec3d b1, b2;
    double area = 0;  // 0: degenerate, no attribute functions
  };
  std::vector<FaceBasis> basis(nf);
  parallel.for_ranges(nf, 4096, [&](std::size_t fb, std::size_t fe) {
    for (std::size_t f = fb; f < fe; ++f) {
      const std::uint32_t* t = &tri_[3 * f];
      const Vec3d p0 = vx_[t[0]].pos, e1 = vx_[t[1]].pos - p0, e2 = vx_[t[2]].pos - p0;
      const double g11 = dot(e1, e1), g12 = dot(e1, e2), g22 = dot(e2, e2);
      const double det = g11 * g22 - g12 * g12;
      if (!(det > 1e-12 * g11 * g22) || !std::isfinite(det)) continue;
      basis[f] = {(e1 * g22 - e2 * g12) * (1.0 / det), (e2 * g11 - e1 * g12) * (1.0 / det), 0.5 * std::sqrt(det)};
    }
  });
  parallel.for_ranges(nv, 1024, [&](std::size_t vb, std::size_t ve) {
    std::array<double, 3 * kMaxAttributeDims> corner_values;
    for (std::size_t vi = vb; vi < ve; ++vi) {
      const auto v = static_cast<std::uint32_t>(vi);
      if (kind_[v] == VertexKind::frozen) continue;
      const double paint = v < priority_.size() ? static_cast<double>(priority_[v]) * priority_[v] : 1.0;
      const std::uint32_t* fl = &pool_[begin_[v]];
      for (std::uint32_t i = 0; i < size_[v]; ++i) {
        const FaceBasis& fb = basis[fl[i]];
        const double weight = fb.area * paint;
        if (!(weight > 0.0) || !std::isfinite(weight)) continue;
        const std::uint32_t* t = &tri_[3 * std::size_t{fl[i]}];
        const std::uint32_t* w = &tri_wedge_[3 * std::size_t{fl[i]}];
        double* s0 = corner_values.data();
        double* s1 = s0 + dims;
        double* s2 = s1 + dims;
        scaled(w[0], s0);
        scaled(w[1], s1);
        scaled(w[2], s2);
        const std::uint32_t wc = w[corner_of(t, v)];
        AttributeQuadric& q = wq_[wc];
        AttributeGradient* sums = &wg_[wc * dims];
        const Vec3d& p0 = vx_[t[0]].pos;
        bool any = false;
        for (std::size_t d = 0; d < dims; ++d) {
          AttributeGradient fn;
          fn.g = fb.b1 * (s1[d] - s0[d]) + fb.b2 * (s2[d] - s0[d]);
          fn.d = s0[d] - dot(fn.g, p0);
          if (!std::isfinite(fn.d)) continue;  // NaN attribute values carry no information
          accumulate_attribute(q, sums[d], fn, weight);
          any = true;
        }
        if (any) q.alpha += weight;
      }
    }
  });
}

// ---- CollapseMesh: evaluation and checks ----------------------------------------------------------------------

Evaluation CollapseMesh::evaluate(std::uint32_t u, std::uint32_t v, bool with_cost) const {
  const Vertex& xu = vx_[u];
  const Vertex& xv = vx_[v];
  const Quadric surface = xu.quadric + xv.quadric;
  // The cost sees the attribute quadrics too (reduced to position space); the error bound is the surface's
  // alone, and so is the free placement: the reduced attribute quadric is smallest where the faces' linear
  // attribute functions agree, which for a sharp attribute feature lies beside it, not on it. On a flat
  // 40×40 grid with a colour step at x = 12 (10% of the triangles), attribute-driven placement left 22 of 200
  // vertices within 4 units of the step, surface placement 89.
  Quadric q = surface;
  if (layout_.dims > 0 && with_cost) add_attribute_quadrics(u, v, q);
  Evaluation ev;
  switch (rule(u, v)) {
    case EdgeRule::keep_u: ev.position = xu.pos; break;
    case EdgeRule::keep_v: ev.position = xv.pos; break;
    default: {
      // The surface quadric alone where it pins the point down (corners, creases with a third plane);
      // with the rubber band where it does not (flat and nearly flat patches, where the surface error
      // does not care and the band keeps the vertex inside the region it represents).
      const auto x = surface.minimizer(kWellConditioned);
      const Vec3d edge = xv.pos - xu.pos;
      const Vec3d off = x ? *x - (xu.pos + xv.pos) * 0.5 : Vec3d{};
      if (x && dot(off, off) <= kMaxReachEdgeLengths * kMaxReachEdgeLengths * dot(edge, edge)) {
        ev.position = *x;
      } else {
        Quadric solve = surface;
        const double w = reg_weight_ * (static_cast<double>(xu.anchors) + static_cast<double>(xv.anchors));
        const Vec3f sum = xu.anchor_sum + xv.anchor_sum;
        solve.a00 += w;
        solve.a11 += w;
        solve.a22 += w;
        solve.b0 -= reg_weight_ * static_cast<double>(sum[0]);
        solve.b1 -= reg_weight_ * static_cast<double>(sum[1]);
        solve.b2 -= reg_weight_ * static_cast<double>(sum[2]);
        ev.position = place_on_edge(solve, xu.pos, xv.pos).position;
      }
    }
  }
  if (layout_.dims == 0) {
    const double e = q.evaluate(ev.position);
    ev.error = e / (q.weight + weight_floor_);
    ev.cost = e;
  } else {
    ev.error = surface.evaluate(ev.position) / (surface.weight + weight_floor_);
    ev.cost = q.evaluate(ev.position);
  }
  if (skin_cost_scale_ > 0.0 && with_cost) ev.cost += skin_cost(u, v);
  return ev;
}

// The attribute quadrics the merged vertex of edge (u, v) will have, reduced to position space (Hoppe 1999;
// ALGORITHMS.md 2.3 "position optimisation with several wedges"): the wedge pairs across the edge's faces
// merge, every other wedge of u and v counts alone. The geometric quadric is counted once, by the caller.
void CollapseMesh::add_attribute_quadrics(std::uint32_t u, std::uint32_t v, Quadric& q) const {
  const auto dims = static_cast<std::size_t>(layout_.dims);
  auto grads = [&](std::uint32_t w) { return std::span<const AttributeGradient>(&wg_[w * dims], dims); };
  // Most edges: neither endpoint on a seam, so each has one wedge (one key, and outside permissive mode a key
  // is one wedge), read from its first face; the pair merges. Saves the star scans (a third of the time).
  if (((state_[u] | state_[v]) & kSeam) == 0 && !options_.permissive) {
    auto only_wedge = [&](std::uint32_t x) {
      const std::size_t f3 = 3 * std::size_t{pool_[begin_[x]]};
      return tri_wedge_[f3 + corner_of(&tri_[f3], x)];
    };
    const std::uint32_t wu = only_wedge(u), wv = only_wedge(v);
    q += reduce_merged_attributes(wq_[wu], grads(wu), wq_[wv], grads(wv));
    return;
  }
  // One pass over each star: the wedge pairs across the edge's faces, and each endpoint's distinct wedges (at
  // most 8 are looked at: more make a complex vertex, which never moves anyway).
  std::uint32_t pu[2] = {kInvalidIndex, kInvalidIndex}, pv[2] = {kInvalidIndex, kInvalidIndex};
  std::uint32_t wu[8], wv[8];
  int k = 0, nu = 0, nv = 0;
  auto note = [](std::uint32_t* list, int& n, std::uint32_t w) {
    if (n < 8 && std::find(list, list + n, w) == list + n) list[n++] = w;
  };
  {
    const std::uint32_t* fl = &pool_[begin_[u]];
    for (std::uint32_t i = 0; i < size_[u]; ++i) {
      const std::uint32_t* t = &tri_[3 * std::size_t{fl[i]}];
      const std::uint32_t* w = &tri_wedge_[3 * std::size_t{fl[i]}];
      const std::uint32_t wc = w[corner_of(t, u)];
      note(wu, nu, wc);
      if (k < 2 && (t[0] == v || t[1] == v || t[2] == v)) {
        pu[k] = wc;
        pv[k] = w[corner_of(t, v)];
        ++k;
      }
    }
    const std::uint32_t* fv = &pool_[begin_[v]];
    for (std::uint32_t i = 0; i < size_[v]; ++i) {
      const std::uint32_t* t = &tri_[3 * std::size_t{fv[i]}];
      note(wv, nv, tri_wedge_[3 * std::size_t{fv[i]} + corner_of(t, v)]);
    }
  }
  if (k == 2 && pu[0] == pu[1] && pv[0] == pv[1]) k = 1;
  for (int i = 0; i < k; ++i) q += reduce_merged_attributes(wq_[pu[i]], grads(pu[i]), wq_[pv[i]], grads(pv[i]));
  // The other wedges of each endpoint, each once.
  for (int i = 0; i < nu; ++i) {
    if (wu[i] != pu[0] && wu[i] != pu[1]) q += reduce_attributes(wq_[wu[i]], grads(wu[i]));
  }
  for (int i = 0; i < nv; ++i) {
    if (wv[i] != pv[0] && wv[i] != pv[1]) q += reduce_attributes(wq_[wv[i]], grads(wv[i]));
  }
}


// Soft skinning term: merging two point masses of areas W_u, W_v whose weight vectors differ by Δ costs
// W_u W_v / (W_u + W_v) |Δ|² (the spread about their weighted mean), in the units of a normal change.
double CollapseMesh::skin_cost(std::uint32_t u, std::uint32_t v) const {
  const double wu = vx_[u].quadric.weight, wv = vx_[v].quadric.weight;
  if (!(wu + wv > 0.0)) return 0.0;
  const SkinComparison c = compare_skin(skin_[u], skin_[v], 0.0f);
  return skin_cost_scale_ * wu * wv / (wu + wv) * c.l2sq;
}

double CollapseMesh::edge_t(std::uint32_t a, std::uint32_t b, const Vec3d& x) const {
  const Vec3d e = vx_[b].pos - vx_[a].pos;
  const double len2 = dot(e, e);
  if (!(len2 > 0.0)) return 1.0;
  return std::clamp(dot(x - vx_[a].pos, e) / len2, 0.0, 1.0);
}

// The top influences of (1 − t) × a's weights + t × b's, at most as many as any input vertex used,
// renormalised to sum 1; ties by joint id.
SkinInfluences CollapseMesh::blended_skin(std::uint32_t a, std::uint32_t b, double t) const {
  std::pair<std::uint16_t, double> all[2 * kMaxInfluences];
  int n = 0;
  auto add = [&](const SkinInfluences& s, double f) {
    for (int i = 0; i < kMaxInfluences; ++i) {
      if (!(s.weights[i] > 0.0f) || f <= 0.0) continue;
      int j = 0;
      while (j < n && all[j].first != s.joints[i]) ++j;
      if (j == n) all[n++] = {s.joints[i], 0.0};
      all[j].second += f * static_cast<double>(s.weights[i]);
    }
  };
  add(skin_[a], 1.0 - t);
  add(skin_[b], t);
  std::sort(all, all + n, [](const auto& x, const auto& y) {
    return x.second > y.second || (x.second == y.second && x.first < y.first);
  });
  n = std::min(n, std::max(skin_cap_, 1));
  double sum = 0.0;
  for (int i = 0; i < n; ++i) sum += all[i].second;
  if (!(sum > 0.0)) return skin_[b];
  std::sort(all, all + n);  // joint order in the slots
  SkinInfluences out;
  for (int i = 0; i < n; ++i) {
    out.joints[i] = all[i].first;
    out.weights[i] = static_cast<float>(all[i].second / sum);
  }
  return out;
}

bool CollapseMesh::flip_ok(const Vec3d& old_p, const Vec3d& x, const Vec3d& p, const Vec3d& q) const {
  const Vec3d e1n = p - x, e2n = q - x;
  const Vec3d nn = cross(e1n, e2n);
  const double nn2 = dot(nn, nn);
  if (!(nn2 > kDegenerateSine2 * dot(e1n, e1n) * dot(e2n, e2n))) return false;  // also false on NaN
  const Vec3d e1o = p - old_p, e2o = q - old_p;
  const Vec3d no = cross(e1o, e2o);
  const double no2 = dot(no, no);
  // An already degenerate face has no orientation to keep; the test above made it proper.
  if (!(no2 > kDegenerateSine2 * dot(e1o, e1o) * dot(e2o, e2o))) return true;
  const double d = dot(no, nn);
  return d > 0.0 && d * d > cos_max_flip_ * cos_max_flip_ * no2 * nn2;
}

// Whether a's wedges map onto b's without merging distinct ones. The faces of edge ab pair each of their
// a-corner wedges with their b-corner wedge; that pairing must be one-to-one, and every wedge a's other faces
// use must be in it. Otherwise the collapse would have to invent attributes. Seam edges drawn as '=':
//
//   accepted: seam along ab              refused: seam e-a-f (drawn '|') passes through a
//
//        c                                       e
//   w1  / \  v1                                  |    w1     c
//   a ===== b    (w1 -> v1, w2 -> v2)        w2   a ------- b      a's w2 corners have no partner at b
//   w2  \ /  v2                                  |    w1     d
//        d                                       f
bool CollapseMesh::wedges_carry_over(std::uint32_t a, std::uint32_t b, const Check& c) const {
  std::uint32_t ka[2], kb[2];
  for (std::uint32_t i = 0; i < c.edge_face_count; ++i) {
    const std::size_t f3 = 3 * std::size_t{c.edge_faces[i]};
    const std::uint32_t* t = &tri_[f3];
    ka[i] = key(f3 + corner_of(t, a));
    kb[i] = key(f3 + corner_of(t, b));
  }
  if (c.edge_face_count == 2 && ((ka[0] == ka[1]) != (kb[0] == kb[1]))) return false;
  if ((state_[a] & kSeam) == 0) return true;  // one key at a: every corner carries ka[0]
  const std::uint32_t* fl = &pool_[begin_[a]];
  for (std::uint32_t i = 0; i < size_[a]; ++i) {
    const std::size_t f3 = 3 * std::size_t{fl[i]};
    const std::uint32_t k = key(f3 + corner_of(&tri_[f3], a));
    if (k != ka[0] && (c.edge_face_count < 2 || k != ka[1])) return false;
  }
  return true;
}

// Every distinct wedge around a with the wedge of b it becomes (apply()'s mapping: by key, across the edge
// faces), as pairs in s.wedge_map, in a's face order.
void CollapseMesh::map_wedges(std::uint32_t a, std::uint32_t b, const Check& c, Scratch& s) const {
  std::uint32_t ka[2] = {kInvalidIndex, kInvalidIndex}, wb[2] = {kInvalidIndex, kInvalidIndex};
  for (std::uint32_t i = 0; i < c.edge_face_count; ++i) {
    const std::size_t f3 = 3 * std::size_t{c.edge_faces[i]};
    const std::uint32_t* t = &tri_[f3];
    ka[i] = key(f3 + corner_of(t, a));
    wb[i] = tri_wedge_[f3 + corner_of(t, b)];
  }
  s.wedge_map.clear();
  const std::uint32_t* fl = &pool_[begin_[a]];
  for (std::uint32_t i = 0; i < size_[a]; ++i) {
    const std::size_t f3 = 3 * std::size_t{fl[i]};
    const std::size_t corner = f3 + corner_of(&tri_[f3], a);
    const std::uint32_t wx = tri_wedge_[corner];
    const std::uint32_t wt = (c.edge_face_count == 2 && key(corner) == ka[1]) ? wb[1] : wb[0];
    bool seen = false;
    for (std::size_t j = 0; j < s.wedge_map.size(); j += 2) seen |= s.wedge_map[j] == wx;
    if (seen) continue;
    s.wedge_map.push_back(wx);
    s.wedge_map.push_back(wt);
  }
}

Vec2f CollapseMesh::new_uv(int set, std::uint32_t wx, std::uint32_t wt, const Vec3d& x, double t) const {
  const std::vector<Vec2f>& uv = uvs_[static_cast<std::size_t>(set)];
  const Vec2f from = uv[wx], to = uv[wt];
  // The minimiser of the merged quadric where UVs are in the metric, else the point at x's place along the
  // edge; either way projected onto the edge's UV segment, which lies inside the chart away from its outline.
  double s = t;
  const AttributeGroup* g = layout_.find(AttributeGroup::Type::uv, set);
  const double alpha = g != nullptr ? wq_[wx].alpha + wq_[wt].alpha : 0.0;
  if (alpha > 0.0) {
    const auto dims = static_cast<std::size_t>(layout_.dims);
    double opt[2];
    for (int i = 0; i < 2; ++i) {
      const AttributeGradient& gx = wg_[wx * dims + static_cast<std::size_t>(g->dim + i)];
      const AttributeGradient& gt = wg_[wt * dims + static_cast<std::size_t>(g->dim + i)];
      opt[i] = (dot(gx.g + gt.g, x) + gx.d + gt.d) / alpha / g->scale;
    }
    const double ex = double{to[0]} - from[0], ey = double{to[1]} - from[1];
    const double len2 = ex * ex + ey * ey;
    if (len2 > 0.0) s = std::clamp(((opt[0] - from[0]) * ex + (opt[1] - from[1]) * ey) / len2, 0.0, 1.0);
  }
  if (!std::isfinite(s)) s = 1.0;
  // At a seam vertex (either end) the UV takes the nearer end's value. On a UV seam the UV segment is a
  // chord of the chart's outline, which leaves the chart where the outline is concave and may enter a
  // neighbouring chart (FlightHelmet at 25%: 36 triangles reaching into charts stacked in the same UV space);
  // the end's value is one the chart has. On a hard edge or material boundary with continuous UVs, each
  // side's own optimum would tear the UVs apart along it; both sides snap alike. Over the glTF corpus at 50%
  // and 10% this took the geometric mean of the UV stretch ratio (LOD against input) from 1.59 to 1.00, the
  // largest from 648 to 8, at the same UV error; snapping on UV seams only left it at 1.63. Mesh borders keep
  // the interpolated UV: nothing lies beyond them, and snapping there stretches the texture along the border.
  const bool seam =
      kind_[src_.wedge_vertex[wx]] == VertexKind::seam || kind_[src_.wedge_vertex[wt]] == VertexKind::seam;
  if (seam) s = s < 0.5 ? 0.0 : 1.0;
  const auto fs = static_cast<float>(s);
  return {{from[0] + (to[0] - from[0]) * fs, from[1] + (to[1] - from[1]) * fs}};
}

// No face around a or b may turn over (or collapse to zero area) in UV space, in any UV set. Faces keep their
// orientation sign: mirrored charts stay mirrored.
bool CollapseMesh::uv_ok(std::uint32_t a, std::uint32_t b, const Check& c, const Vec3d& x, Scratch& s) const {
  const bool moved = blends(b, x);
  const double t = moved ? edge_t(a, b, x) : 1.0;
  auto target_of = [&](std::uint32_t w) {
    for (std::size_t j = 0; j < s.wedge_map.size(); j += 2) {
      if (s.wedge_map[j] == w) return s.wedge_map[j + 1];
    }
    return kInvalidIndex;
  };
  auto is_target = [&](std::uint32_t w) {
    for (std::size_t j = 1; j < s.wedge_map.size(); j += 2) {
      if (s.wedge_map[j] == w) return true;
    }
    return false;
  };
  auto source_of = [&](std::uint32_t wt) {
    for (std::size_t j = 1; j < s.wedge_map.size(); j += 2) {
      if (s.wedge_map[j] == wt) return s.wedge_map[j - 1];
    }
    return kInvalidIndex;
  };
  auto area2 = [](const Vec2f& p, const Vec2f& q, const Vec2f& r) {
    return (double{q[0]} - p[0]) * (double{r[1]} - p[1]) - (double{r[0]} - p[0]) * (double{q[1]} - p[1]);
  };
  // Whether a UV triangle is a sliver: the sine of its angle at corner 0 below kUvSliverSine.
  auto sliver = [](const Vec2f* c, double a2) {
    const double e1 = (double{c[1][0]} - c[0][0]) * (double{c[1][0]} - c[0][0]) +
                      (double{c[1][1]} - c[0][1]) * (double{c[1][1]} - c[0][1]);
    const double e2 = (double{c[2][0]} - c[0][0]) * (double{c[2][0]} - c[0][0]) +
                      (double{c[2][1]} - c[0][1]) * (double{c[2][1]} - c[0][1]);
    return a2 * a2 <= kUvSliverSine * kUvSliverSine * e1 * e2;
  };
  for (std::size_t set = 0; set < uvs_.size(); ++set) {
    const std::vector<Vec2f>& uv = uvs_[set];
    if (uv.empty()) continue;
    for (std::uint32_t w : {a, b}) {
      const std::uint32_t* fl = &pool_[begin_[w]];
      for (std::uint32_t i = 0; i < size_[w]; ++i) {
        const std::uint32_t f = fl[i];
        if (f == c.edge_faces[0] || f == c.edge_faces[1]) continue;
        const std::uint32_t* tw = &tri_wedge_[3 * std::size_t{f}];
        const int j = corner_of(&tri_[3 * std::size_t{f}], w);
        const std::uint32_t wc = tw[j];
        const std::uint32_t wt = w == a ? target_of(wc) : wc;
        if (w == b && (!moved || !is_target(wc))) continue;  // b's face keeps its UVs
        // A target's new value comes from its first source (as in apply()).
        const Vec2f now = moved ? new_uv(static_cast<int>(set), source_of(wt), wt, x, t) : uv[wt];
        Vec2f corners[3] = {uv[tw[0]], uv[tw[1]], uv[tw[2]]};
        const double before = area2(corners[0], corners[1], corners[2]);
        if (!(before != 0.0)) continue;  // no orientation to keep (or NaN UVs)
        const bool was_sliver = sliver(corners, before);
        corners[j] = now;
        const double after = area2(corners[0], corners[1], corners[2]);
        if (!(after * before > 0.0)) return false;
        if (!was_sliver && sliver(corners, after)) return false;
      }
    }
  }
  return true;
}

// ALGORITHMS.md 2.4 rule 1: a and b may merge only when their dominant joints agree or their weight vectors
// are close (the joint's blend band). Checking every face of the merged vertex instead (no new triangle may
// join distant weights) was tried: on the skinned corpus it vetoes so many cheap collapses that the bind-pose
// distance error grows 3-40x (CesiumMan at 25%: 0.25% of the diagonal against 0.04%).
bool CollapseMesh::skin_ok(std::uint32_t a, std::uint32_t b) const {
  return skin_mergeable(skin_[a], skin_[b], options_.skin_weight_threshold, options_.skin_max_distance);
}

// Link condition with boundaries coned to a virtual vertex ω (ω is a neighbour of every boundary vertex and
// an apex of every boundary edge). For edge ab with apexes c (and d), Lk(a) ∩ Lk(b) must equal Lk(ab):
//
//   vertices: the common neighbours of a and b are exactly the apexes ............ Veto::link_condition
//             (ω common, i.e. both boundary, only if ab is a boundary edge) ....... Veto::boundary_pinch
//   edges:    c-ω in both links (a-c and b-c both boundary edges) ................ Veto::dangling_face
//             c-d in both links (faces a-c-d and b-c-d both exist) ............... Veto::tetrahedron
//
//   boundary pinch:   a ------- b   both on the boundary loop, ab interior:
//                     \  ...   /    collapsing makes the loop touch itself at one vertex
Check CollapseMesh::check(std::uint32_t u, std::uint32_t v, const Vec3d& x, Scratch& s) const {
  Check c;
  const EdgeRule r = rule(u, v);
  // Default survivor: the lower id (u), so survivors keep input order; wedges may swap it below.
  std::uint32_t a = v, b = u;
  if (r == EdgeRule::keep_v) std::swap(a, b);

  // Stars: s.na = [neighbour after a in each face | neighbour before a in each face], s.nb likewise.
  const std::uint32_t ma = size_[a], mb = size_[b];
  s.na.resize(2 * std::size_t{ma});
  s.nb.resize(2 * std::size_t{mb});
  std::uint32_t* const next_a = s.na.data();
  std::uint32_t* const prev_a = next_a + ma;
  std::uint32_t* const next_b = s.nb.data();
  std::uint32_t* const prev_b = next_b + mb;
  std::uint32_t apex[2] = {kInvalidIndex, kInvalidIndex};
  std::uint32_t k = 0;
  for (std::uint32_t w : {a, b}) {
    const std::uint32_t* fl = &pool_[begin_[w]];
    for (std::uint32_t i = 0; i < size_[w]; ++i) __builtin_prefetch(&tri_[3 * std::size_t{fl[i]}]);
  }
  {
    const std::uint32_t* fl = &pool_[begin_[a]];
    for (std::uint32_t i = 0; i < ma; ++i) {
      const std::uint32_t* t = &tri_[3 * std::size_t{fl[i]}];
      const int j = corner_of(t, a);
      const std::uint32_t p = t[kNext[j]], q = t[kPrev[j]];
      next_a[i] = p;
      prev_a[i] = q;
      if (p == b || q == b) {
        if (k < 2) {
          c.edge_faces[k] = fl[i];
          apex[k] = p == b ? q : p;
        }
        ++k;
      }
    }
  }
  if (k == 0 || k > 2) {
    c.veto = Veto::not_an_edge;
    return c;
  }
  c.edge_face_count = k;
  if (k == 2 && apex[0] == apex[1]) {
    c.veto = Veto::link_condition;
    return c;
  }
  {
    const std::uint32_t* fl = &pool_[begin_[b]];
    for (std::uint32_t i = 0; i < mb; ++i) {
      const std::uint32_t* t = &tri_[3 * std::size_t{fl[i]}];
      const int j = corner_of(t, b);
      next_b[i] = t[kNext[j]];
      prev_b[i] = t[kPrev[j]];
    }
  }
  for (std::uint32_t i = 0; i < 2 * ma; ++i) prefetch(s.na[i]);  // positions for the fold test below
  for (std::uint32_t i = 0; i < 2 * mb; ++i) prefetch(s.nb[i]);
  if (k == 2) {
    auto has_face_cd = [&](const std::uint32_t* nx, const std::uint32_t* pv, std::uint32_t m) {
      for (std::uint32_t i = 0; i < m; ++i) {
        if ((nx[i] == apex[0] && pv[i] == apex[1]) || (nx[i] == apex[1] && pv[i] == apex[0])) return true;
      }
      return false;
    };
    if (has_face_cd(next_a, prev_a, ma) && has_face_cd(next_b, prev_b, mb)) {
      c.veto = Veto::tetrahedron;
      return c;
    }
  }

  std::uint32_t common = 0;
  bool a_boundary = false, b_boundary = false, dangling = false;
  if (state_[b] & kFan) {
    // Both stars are single, consistently oriented fans whose kind is kept exact by commit(): the
    // neighbours are the "after" list plus, on a border vertex, the one "before" neighbour that is never
    // "after" (the fan's first spoke). Border spokes are that one and the "after" that is never "before".
    auto contains = [](const std::uint32_t* l, std::uint32_t n, std::uint32_t x) {
      bool f = false;
      for (std::uint32_t i = 0; i < n; ++i) f |= l[i] == x;
      return f;
    };
    auto lone = [&](const std::uint32_t* from, const std::uint32_t* other, std::uint32_t m) {
      for (std::uint32_t i = 0; i < m; ++i) {
        if (!contains(other, m, from[i])) return from[i];
      }
      return kInvalidIndex;
    };
    a_boundary = (state_[a] & kOpen) != 0;
    b_boundary = (state_[b] & kOpen) != 0;
    const std::uint32_t first_a = a_boundary ? lone(prev_a, next_a, ma) : kInvalidIndex;
    const std::uint32_t first_b = b_boundary ? lone(prev_b, next_b, mb) : kInvalidIndex;
    for (std::uint32_t i = 0; i < ma; ++i) {
      const std::uint32_t x = next_a[i];
      common += x != b && (contains(next_b, mb, x) || x == first_b);
    }
    if (first_a != kInvalidIndex && first_a != b) common += contains(next_b, mb, first_a) || first_a == first_b;
    if (k == 1 && a_boundary && b_boundary) {
      const std::uint32_t last_a = lone(next_a, prev_a, ma), last_b = lone(next_b, prev_b, mb);
      dangling = (apex[0] == first_a || apex[0] == last_a) && (apex[0] == first_b || apex[0] == last_b);
    }
  } else {
    // b is locked (possibly non-manifold): count multiplicities on sorted multisets. A spoke with one face
    // is a boundary edge.
    small_sort(s.na.data(), s.na.size());
    small_sort(s.nb.data(), s.nb.size());
    std::size_t i = 0, j = 0;
    const std::size_t ni = s.na.size(), nj = s.nb.size();
    while (i < ni || j < nj) {
      const std::uint32_t xa = i < ni ? s.na[i] : kInvalidIndex;
      const std::uint32_t xb = j < nj ? s.nb[j] : kInvalidIndex;
      const std::uint32_t xm = std::min(xa, xb);
      std::size_t ca = 0, cb = 0;
      while (i < ni && s.na[i] == xm) ++i, ++ca;
      while (j < nj && s.nb[j] == xm) ++j, ++cb;
      if (ca == 1) a_boundary = true;
      if (cb == 1) b_boundary = true;
      if (ca > 0 && cb > 0) ++common;  // a and b themselves appear only in the other's list
      if (ca == 1 && cb == 1 && (xm == apex[0] || xm == apex[1])) dangling = true;
    }
  }
  if (common != k) {
    c.veto = Veto::link_condition;
    return c;
  }
  if (a_boundary && b_boundary && k == 2) {
    c.veto = Veto::boundary_pinch;
    return c;
  }
  if (dangling) {
    c.veto = Veto::dangling_face;
    return c;
  }
  c.boundary = a_boundary || b_boundary;

  // Folds and degenerate faces: every face that survives around a or b, with its corner moved to x.
  for (std::uint32_t w : {a, b}) {
    if (vx_[w].pos == x) continue;  // half-edge collapse: the survivor's own faces do not move
    const std::uint32_t other = w == a ? b : a;
    const std::uint32_t* fl = &pool_[begin_[w]];
    for (std::uint32_t i = 0; i < size_[w]; ++i) {
      const std::uint32_t* t = &tri_[3 * std::size_t{fl[i]}];
      const int j = corner_of(t, w);
      const std::uint32_t p = t[kNext[j]], q = t[kPrev[j]];
      if (p == other || q == other) continue;
      if (!flip_ok(vx_[w].pos, x, vx_[p].pos, vx_[q].pos)) {
        const Vec3d nn = cross(vx_[p].pos - x, vx_[q].pos - x);
        c.veto = dot(nn, nn) > 0.0 ? Veto::fold : Veto::degenerate;
        return c;
      }
    }
  }

  // Wedges: try the default survivor, then (if the rule allows either) the other one.
  if ((state_[a] | state_[b]) & kSeam) {
    if (!wedges_carry_over(a, b, c)) {
      if (r == EdgeRule::optimal && wedges_carry_over(b, a, c)) {
        std::swap(a, b);
      } else {
        c.veto = Veto::seam;
        return c;
      }
    }
  }
  if (!uvs_.empty()) {
    map_wedges(a, b, c, s);
    if (!uv_ok(a, b, c, x, s)) {
      c.veto = Veto::uv_flip;
      return c;
    }
  }
  if (!skin_.empty() && !skin_ok(a, b)) {
    c.veto = Veto::skin;
    return c;
  }
  c.victim = a;
  c.survivor = b;
  return c;
}

// ---- CollapseMesh: commit ------------------------------------------------------------------------------------

void CollapseMesh::reserve(Check& c) {
  const std::uint32_t a = c.victim, b = c.survivor;
  const std::uint32_t n = size_[a] + size_[b] - 2 * c.edge_face_count;
  if (n <= capacity_[b]) {
    c.list_begin = begin_[b];
    c.list_capacity = capacity_[b];
  } else if (n <= capacity_[a]) {  // a's slot is free after the collapse
    c.list_begin = begin_[a];
    c.list_capacity = capacity_[a];
  } else {
    c.list_begin = static_cast<std::uint32_t>(pool_.size());
    c.list_capacity = n + kListSlack;
    pool_.resize(pool_.size() + c.list_capacity);
  }
  alive_faces_ -= c.edge_face_count;
}

void CollapseMesh::apply(const Check& c, const Vec3d& x, Scratch& s) {
  const std::uint32_t a = c.victim, b = c.survivor, k = c.edge_face_count;
  for (std::uint32_t w : {a, b}) {
    const std::uint32_t* fl = &pool_[begin_[w]];
    for (std::uint32_t i = 0; i < size_[w]; ++i) __builtin_prefetch(&tri_[3 * std::size_t{fl[i]}]);
  }
  if (carry_) carry_attributes(c, x, s);
  std::uint32_t ka[2] = {kInvalidIndex, kInvalidIndex}, wb[2] = {kInvalidIndex, kInvalidIndex};
  std::uint32_t kb[2] = {kInvalidIndex, kInvalidIndex};
  for (std::uint32_t i = 0; i < k; ++i) {
    const std::uint32_t f = c.edge_faces[i];
    std::uint32_t* t = &tri_[3 * std::size_t{f}];
    const std::uint32_t* w = &tri_wedge_[3 * std::size_t{f}];
    const int ja = corner_of(t, a), jb = corner_of(t, b);
    ka[i] = key(3 * std::size_t{f} + ja);
    wb[i] = w[jb];
    kb[i] = key(3 * std::size_t{f} + jb);
    // Remove the dying face from its apex's list (order kept).
    const std::uint32_t apex = t[3 - ja - jb];
    std::uint32_t* fl = &pool_[begin_[apex]];
    std::uint32_t* end = fl + size_[apex];
    std::uint32_t* it = std::find(fl, end, f);
    std::copy(it + 1, end, it);
    --size_[apex];
    t[0] = kInvalidIndex;
  }

  // b's new list: its own surviving faces, then a's (renamed to b, wedges carried over).
  s.ring.clear();
  {
    const std::uint32_t* fl = &pool_[begin_[b]];
    for (std::uint32_t i = 0; i < size_[b]; ++i) {
      if (tri_[3 * std::size_t{fl[i]}] != kInvalidIndex) s.ring.push_back(fl[i]);
    }
  }
  {
    // Without a seam every corner of a carries ka[0] == ka[1]: no need to read the keys.
    const bool seam = (state_[a] & kSeam) != 0;
    const std::uint32_t* fl = &pool_[begin_[a]];
    for (std::uint32_t i = 0; i < size_[a]; ++i) {
      const std::uint32_t f = fl[i];
      std::uint32_t* t = &tri_[3 * std::size_t{f}];
      if (t[0] == kInvalidIndex) continue;
      const int j = corner_of(t, a);
      t[j] = b;
      const std::size_t corner = 3 * std::size_t{f} + j;
      const int side = (k == 2 && (!seam || key(corner) == ka[1])) ? 1 : 0;
      tri_wedge_[corner] = wb[side];
      if (!tri_key_.empty()) tri_key_[corner] = kb[side];
      s.ring.push_back(f);
    }
  }
  std::copy(s.ring.begin(), s.ring.end(), pool_.begin() + c.list_begin);
  if (c.list_begin != begin_[b]) capacity_[a] = 0;  // b took a's slot, or moved to a new one
  begin_[b] = c.list_begin;
  capacity_[b] = c.list_capacity;
  size_[b] = static_cast<std::uint32_t>(s.ring.size());
  size_[a] = 0;

  vx_[b].quadric += vx_[a].quadric;
  vx_[b].anchors += vx_[a].anchors;
  vx_[b].anchor_sum = vx_[b].anchor_sum + vx_[a].anchor_sum;
  // Keep the kind of a free survivor exact (ring() and check() rely on it): it is on the boundary when
  // either endpoint was.
  if (state_[b] & kFan) {
    state_[b] = static_cast<std::uint8_t>(c.boundary ? (state_[b] | kOpen) : (state_[b] & ~kOpen));
    if (kind_[b] == VertexKind::interior || kind_[b] == VertexKind::border) {
      kind_[b] = c.boundary ? VertexKind::border : VertexKind::interior;
    }
  }
  if (!(vx_[b].pos == x)) {
    vx_[b].pos = x;
    state_[b] |= kMoved;
  }
  state_[a] |= kDead;
  ++version_[a];
  ++version_[b];
}

// What moves with a collapse besides geometry, before the faces are rewritten: each of a's wedges' attribute
// quadric joins its target's; when the survivor moves (optimal placement) each target gets new values (the
// merged quadric's minimiser, clamped, for attributes in the metric; the point at x's place along the edge
// for the rest; normals renormalised), morph deltas and skin weights blend the same way.
void CollapseMesh::carry_attributes(const Check& c, const Vec3d& x, Scratch& s) {
  const std::uint32_t a = c.victim, b = c.survivor;
  map_wedges(a, b, c, s);
  const bool moved = blends(b, x);
  if (moved) {
    const double t = edge_t(a, b, x);
    const auto ft = static_cast<float>(t);
    const auto dims = static_cast<std::size_t>(layout_.dims);
    for (std::size_t j = 0; j < s.wedge_map.size(); j += 2) {
      const std::uint32_t wx = s.wedge_map[j], wt = s.wedge_map[j + 1];
      bool first = true;  // a target takes its values from its first source only
      for (std::size_t i = 1; i < j; i += 2) first &= s.wedge_map[i] != wt;
      if (!first) continue;
      // Optimal attributes of the merged quadric, scaled units.
      s.attr.assign(dims, 0.0);
      bool optimal = false;
      if (dims > 0) {
        AttributeQuadric merged = wq_[wt];
        std::array<AttributeGradient, kMaxAttributeDims> sums;
        std::copy_n(&wg_[wt * dims], dims, sums.data());
        merge_attribute_quadrics(merged, std::span(sums.data(), dims), wq_[wx],
                                 std::span<const AttributeGradient>(&wg_[wx * dims], dims));
        optimal = optimal_attributes(merged, std::span<const AttributeGradient>(sums.data(), dims), x, s.attr);
      }
      auto group_of = [&](AttributeGroup::Type type, int set) {
        return optimal ? layout_.find(type, set) : nullptr;
      };
      if (!normals_.empty()) {
        Vec3f n = normals_[wx] + (normals_[wt] - normals_[wx]) * ft;
        if (const AttributeGroup* g = group_of(AttributeGroup::Type::normal, 0)) {
          for (int i = 0; i < 3; ++i) n[i] = static_cast<float>(s.attr[static_cast<std::size_t>(g->dim + i)] / g->scale);
        }
        const float len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        normals_[wt] = (len > 1e-6f && std::isfinite(len)) ? n * (1.0f / len) : normals_[wt];
      }
      for (std::size_t set = 0; set < uvs_.size(); ++set) {
        if (!uvs_[set].empty()) uvs_[set][wt] = new_uv(static_cast<int>(set), wx, wt, x, t);
      }
      for (std::size_t set = 0; set < colors_.size(); ++set) {
        if (colors_[set].empty()) continue;
        const Vec4f from = colors_[set][wx], to = colors_[set][wt];
        Vec4f col = from + (to - from) * ft;
        if (const AttributeGroup* g = group_of(AttributeGroup::Type::color, static_cast<int>(set))) {
          for (int i = 0; i < 4; ++i) col[i] = static_cast<float>(s.attr[static_cast<std::size_t>(g->dim + i)] / g->scale);
        }
        // [0, 1], widened to the two sources' own range (HDR colours stay HDR).
        for (int i = 0; i < 4; ++i) {
          const float lo = std::min({0.0f, from[i], to[i]}), hi = std::max({1.0f, from[i], to[i]});
          col[i] = std::isfinite(col[i]) ? std::clamp(col[i], lo, hi) : to[i];
        }
        colors_[set][wt] = col;
      }
      for (MorphTarget& mt : morphs_) {
        for (auto* d : {&mt.position_deltas, &mt.normal_deltas, &mt.tangent_deltas}) {
          if (!d->empty() && d->size() == src_.wedge_count()) (*d)[wt] = (*d)[wx] + ((*d)[wt] - (*d)[wx]) * ft;
        }
      }
    }
    if (!skin_.empty()) skin_[b] = blended_skin(a, b, t);
  }
  if (layout_.dims > 0) {
    const auto dims = static_cast<std::size_t>(layout_.dims);
    for (std::size_t j = 0; j < s.wedge_map.size(); j += 2) {
      const std::uint32_t wx = s.wedge_map[j], wt = s.wedge_map[j + 1];
      if (wx == wt) continue;
      merge_attribute_quadrics(wq_[wt], std::span(&wg_[wt * dims], dims), wq_[wx],
                               std::span<const AttributeGradient>(&wg_[wx * dims], dims));
    }
  }
}

void CollapseMesh::commit(Check c, const Vec3d& x, Scratch& s) {
  reserve(c);
  apply(c, x, s);
}

void CollapseMesh::ring(std::uint32_t v, std::vector<std::uint32_t>& out) const {
  const std::uint32_t m = size_[v];
  out.resize(2 * std::size_t{m});
  std::uint32_t* o = out.data();
  const std::uint32_t* fl = &pool_[begin_[v]];
  for (std::uint32_t i = 0; i < m; ++i) __builtin_prefetch(&tri_[3 * std::size_t{fl[i]}]);
  for (std::uint32_t i = 0; i < m; ++i) {
    const std::uint32_t* t = &tri_[3 * std::size_t{fl[i]}];
    const int j = corner_of(t, v);
    o[i] = t[kNext[j]];      // neighbours that follow v in a face
    o[m + i] = t[kPrev[j]];  // neighbours that precede v in a face
  }
  std::uint32_t n = 0;
  const bool fan = (state_[v] & kFan) != 0, open = (state_[v] & kOpen) != 0;
  if (fan && !open) {
    n = m;  // a closed fan: every neighbour follows v in exactly one face
  } else if (fan && m <= 32) {
    // An open fan: the neighbours that follow v, plus the one that only precedes it (the first spoke).
    n = m;
    for (std::uint32_t i = m; i < 2 * m; ++i) {
      bool seen = false;
      for (std::uint32_t j = 0; j < m; ++j) seen |= o[j] == o[i];
      if (!seen) o[n++] = o[i];
    }
  } else {
    small_sort(o, 2 * std::size_t{m});
    for (std::uint32_t i = 0; i < 2 * m; ++i) {
      if (n == 0 || o[n - 1] != o[i]) o[n++] = o[i];
    }
  }
  out.resize(n);
}

// ---- CollapseMesh: output --------------------------------------------------------------------------------------

Mesh CollapseMesh::output() const {
  const Mesh& m = src_;
  std::vector<std::uint32_t> wedge_map(m.wedge_count(), kInvalidIndex), vertices;
  for (std::size_t f = 0; f < tri_source_.size(); ++f) {
    if (tri_[3 * f] == kInvalidIndex) continue;
    for (int j = 0; j < 3; ++j) wedge_map[tri_wedge_[3 * f + j]] = 0;
  }
  Mesh out = compact_vertices_and_wedges(
      m, wedge_map, vertices,
      {.skin = skin_.empty() ? nullptr : &skin_, .normals = normals_.empty() ? nullptr : &normals_, .uvs = &uvs_,
       .colors = &colors_, .morph_targets = &morphs_});
  for (std::size_t i = 0; i < vertices.size(); ++i) {
    const std::uint32_t v = vertices[i];
    if (state_[v] & kMoved) out.positions[i] = to_float(origin_ + vx_[v].pos * scale_);
  }

  out.face_offsets.reserve(alive_faces_ + 1);
  out.corner_wedge.reserve(3 * alive_faces_);
  out.face_material.reserve(alive_faces_);
  const bool groups = m.face_group.size() == m.face_count();
  for (std::size_t f = 0; f < tri_source_.size(); ++f) {
    if (tri_[3 * f] == kInvalidIndex) continue;
    const std::uint32_t w[3] = {wedge_map[tri_wedge_[3 * f]], wedge_map[tri_wedge_[3 * f + 1]],
                                wedge_map[tri_wedge_[3 * f + 2]]};
    const std::uint32_t sf = tri_source_[f];
    out.add_face(w, 3, sf < m.face_material.size() ? m.face_material[sf] : 0);
    if (groups) out.face_group.push_back(m.face_group[sf]);
  }
  if (blend_ && !out.tangents.empty()) recompute_tangents(out);
  return out;
}

// Tangents of the LOD from its normals and UV set 0 (ALGORITHMS.md 2.4: tangents are not simplified):
// per-triangle UV-space derivatives accumulated per wedge (area-weighted, as MikkTSpace does before its
// splitting rules), Gram-Schmidt against the wedge normal, handedness from the bitangent. A wedge without
// usable UVs keeps its carried tangent.
void recompute_tangents(Mesh& mesh) {
  const std::size_t nw = mesh.wedge_count();
  if (mesh.tangents.size() != nw || mesh.normals.size() != nw || mesh.uvs.empty() || mesh.uvs[0].size() != nw) return;
  const std::vector<Vec2f>& uv = mesh.uvs[0];
  std::vector<Vec3d> tan(nw, Vec3d{}), bit(nw, Vec3d{});
  // Polygons (the polychord engine's quads) count as the triangles they are drawn as.
  auto add = [&](std::uint32_t c0, std::uint32_t c1, std::uint32_t c2) {
    const std::uint32_t w[3] = {mesh.corner_wedge[c0], mesh.corner_wedge[c1], mesh.corner_wedge[c2]};
    const Vec3d p0 = to_double(mesh.positions[mesh.wedge_vertex[w[0]]]);
    const Vec3d e1 = to_double(mesh.positions[mesh.wedge_vertex[w[1]]]) - p0;
    const Vec3d e2 = to_double(mesh.positions[mesh.wedge_vertex[w[2]]]) - p0;
    const double s1 = double{uv[w[1]][0]} - uv[w[0]][0], t1 = double{uv[w[1]][1]} - uv[w[0]][1];
    const double s2 = double{uv[w[2]][0]} - uv[w[0]][0], t2 = double{uv[w[2]][1]} - uv[w[0]][1];
    const double det = s1 * t2 - s2 * t1;
    if (!(std::abs(det) > 0.0) || !std::isfinite(det)) return;
    // Unnormalised (× det² / |det|): each face contributes in proportion to its 3-D area.
    const double sign = det > 0.0 ? 1.0 : -1.0;
    const Vec3d tf = (e1 * t2 - e2 * t1) * sign;
    const Vec3d bf = (e2 * s1 - e1 * s2) * sign;
    for (int j = 0; j < 3; ++j) {
      tan[w[j]] = tan[w[j]] + tf;
      bit[w[j]] = bit[w[j]] + bf;
    }
  };
  for (std::size_t f = 0; f < mesh.face_count(); ++f) for_each_face_triangle(mesh, f, add);
  for (std::size_t w = 0; w < nw; ++w) {
    const Vec3d n = to_double(mesh.normals[w]);
    const Vec3d t = tan[w] - n * dot(n, tan[w]);
    const double len = length(t);
    if (!(len > 0.0) || !std::isfinite(len)) continue;
    const Vec3d unit = t * (1.0 / len);
    const double hand = dot(cross(n, unit), bit[w]) < 0.0 ? -1.0 : 1.0;
    mesh.tangents[w] = {{static_cast<float>(unit[0]), static_cast<float>(unit[1]), static_cast<float>(unit[2]),
                         static_cast<float>(hand)}};
  }
}

// ---- shared helpers ----------------------------------------------------------------------------------------------

double normalised_budget_squared(const SimplifyOptions& o, double scale, double diagonal) {
  double b = std::numeric_limits<double>::infinity();
  if (o.max_error_abs >= 0.0) b = std::min(b, o.max_error_abs / scale);
  if (o.max_error_rel >= 0.0) b = std::min(b, o.max_error_rel * diagonal / scale);
  return b * b;
}

std::size_t target_triangle_count(const SimplifyOptions& o, std::size_t input_triangles) {
  if (o.target_triangles > 0) return std::min(o.target_triangles, input_triangles);
  const double t = std::round(o.target_ratio * static_cast<double>(input_triangles));
  return std::min(input_triangles, static_cast<std::size_t>(std::max(t, 0.0)));
}

void finish_result(const CollapseMesh& cm, double max_error, std::size_t target, bool over_budget,
                   SimplifyResult& result) {
  const auto t0 = std::chrono::steady_clock::now();
  result.mesh = cm.output();
  result.triangles_after = cm.alive_faces();
  result.error_bound_abs = std::sqrt(max_error) * cm.scale();
  result.error_bound_rel = cm.diagonal() > 0.0 ? result.error_bound_abs / cm.diagonal() : 0.0;
  result.stop_reason = cm.alive_faces() <= target ? StopReason::target_reached
                       : over_budget              ? StopReason::error_budget
                                                  : StopReason::no_valid_collapse;
  result.timings.output_ms = elapsed_ms(t0);
}

// ---- the greedy engine -------------------------------------------------------------------------------------------

SimplifyResult run_edge_collapse(const Mesh& triangles, const SimplifyOptions& options) {
  SimplifyResult result;
  auto t0 = std::chrono::steady_clock::now();
  Parallel parallel(options.threads);
  CollapseMesh cm(triangles, options, parallel);
  const std::size_t nv = cm.vertex_count();
  const std::size_t target = target_triangle_count(options, triangles.triangle_count());
  const double budget2 = normalised_budget_squared(options, cm.scale(), cm.diagonal());
  result.timings.setup_ms = elapsed_ms(t0);

  // Initial candidates: every allowed edge once (u < v), evaluated in parallel.
  t0 = std::chrono::steady_clock::now();
  tbb::enumerable_thread_specific<Scratch> scratch;
  CandidateQueue queue;
  {
    // Fixed chunks of vertices (not per thread), concatenated in chunk order: deterministic.
    constexpr std::size_t kChunk = 4096;
    std::vector<std::vector<QueueEntry>> chunks((nv + kChunk - 1) / kChunk);
    parallel.for_ranges(chunks.size(), 1, [&](std::size_t cb, std::size_t ce) {
      Scratch& s = scratch.local();
      for (std::size_t c = cb; c < ce; ++c) {
        std::vector<QueueEntry>& out = chunks[c];
        const std::size_t vend = std::min(nv, (c + 1) * kChunk);
        out.reserve(3 * (vend - c * kChunk) + 64);  // about 3 edges per vertex on a closed surface
        for (std::size_t v = c * kChunk; v < vend; ++v) {
          const auto u = static_cast<std::uint32_t>(v);
          cm.ring(u, s.ring);
          for (std::uint32_t w : s.ring) cm.prefetch(w);
          for (std::uint32_t w : s.ring) {
            if (w <= u || cm.rule(u, w) == EdgeRule::forbidden) continue;
            out.push_back(make_entry(cost_bits(cm.evaluate(u, w).cost), u, w, cm.version(u) + cm.version(w)));
          }
        }
      }
    });
    for (std::vector<QueueEntry>& chunk : chunks) {
      for (const QueueEntry& e : chunk) queue.push(e);
      std::vector<QueueEntry>().swap(chunk);
    }
  }
  result.timings.initial_costs_ms = elapsed_ms(t0);

  // Rounds.
  t0 = std::chrono::steady_clock::now();
  ParkingLot parked(nv);
  std::vector<std::uint32_t> mark(nv, 0);
  std::uint32_t stamp = 0;
  std::vector<QueueEntry> selected, deferred, window;
  std::vector<std::size_t> window_first;
  std::vector<std::uint32_t> closed_ring;
  std::vector<Evaluation> evals;
  std::vector<Check> checks;
  std::vector<std::uint32_t> survivors, committed, ring_first, ring_buf, ring_size;
  std::vector<QueueEntry> fresh;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> released;
  bool over_budget = false;
  double max_error = 0.0;

  auto current = [&](const QueueEntry& e) { return cm.version(e.u()) + cm.version(e.v) == e.vsum; };

  while (cm.alive_faces() > target) {
    const std::size_t remaining = cm.alive_faces() - target;
    std::size_t batch = options.max_batch > 0
                            ? options.max_batch
                            : std::clamp<std::size_t>(cm.alive_faces() * 3 / 2 / kBatchDivisor, 1, kMaxBatch);
    batch = std::min(batch, (remaining + 1) / 2);  // an interior collapse removes two triangles

    // Select: cheapest first; defer candidates whose closed neighbourhood touches an already selected one.
    // Candidates are popped a window at a time and their closed neighbourhoods gathered in parallel (the mesh
    // does not change during selection); the conflict tests then run in pop order, and whatever the window
    // popped beyond the end of the selection goes back into the queue, so the batch is the one a
    // one-at-a-time selection makes.
    selected.clear();
    deferred.clear();
    ++stamp;
    bool full = false;
    while (!full && selected.size() < batch) {
      window.clear();
      // A quarter more than the batch still needs: some will conflict (fewer windows, fewer parallel loops).
      const std::size_t want = std::max<std::size_t>((batch - selected.size()) * 5 / 4, 32);
      while (window.size() < want && queue.refill(parallel, current)) {
        const QueueEntry e = queue.top();
        queue.pop();
        if (current(e)) window.push_back(e);
      }
      if (window.empty()) break;
      const std::size_t nwin = window.size();
      window_first.resize(nwin + 1);
      std::size_t span = 0;
      for (std::size_t i = 0; i < nwin; ++i) {
        window_first[i] = span;
        span += 3 * (std::size_t{cm.star_size(window[i].u())} + cm.star_size(window[i].v));
      }
      window_first[nwin] = span;
      if (closed_ring.size() < span) closed_ring.resize(span);
      parallel.for_ranges(nwin, 32, [&](std::size_t b, std::size_t e) {
        for (std::size_t i = b; i < e; ++i) {
          if (i + 1 < e) {
            cm.prefetch_star(window[i + 1].u());
            cm.prefetch_star(window[i + 1].v);
          }
          std::uint32_t* out = &closed_ring[window_first[i]];
          cm.for_each_closed_ring_vertex(window[i].u(), window[i].v, [&](std::uint32_t w) { *out++ = w; });
        }
      });
      std::size_t i = 0;
      for (; i < nwin && !full && selected.size() < batch; ++i) {
        const std::uint32_t* ring_begin = &closed_ring[window_first[i]];
        const std::uint32_t* ring_end = &closed_ring[window_first[i + 1]];
        bool conflict = false;
        for (const std::uint32_t* w = ring_begin; w != ring_end; ++w) conflict |= mark[*w] == stamp;
        if (conflict) {
          deferred.push_back(window[i]);
          full = deferred.size() >= 2 * batch;
          continue;
        }
        for (const std::uint32_t* w = ring_begin; w != ring_end; ++w) mark[*w] = stamp;
        selected.push_back(window[i]);
      }
      for (; i < nwin; ++i) queue.push(window[i]);  // popped beyond the selection: not looked at
    }
    if (selected.empty()) {
      for (const QueueEntry& e : deferred) queue.push(e);
      break;
    }
    ++result.rounds;

    // Check in parallel: the neighbourhoods are disjoint, so checking before any commit equals checking
    // just before each commit.
    const std::size_t ns = selected.size();
    evals.resize(ns);
    checks.resize(ns);
    parallel.for_ranges(ns, 8, [&](std::size_t b, std::size_t e) {
      Scratch& s = scratch.local();
      for (std::size_t i = b; i < e; ++i) {
        const std::uint32_t u = selected[i].u(), v = selected[i].v;
        if (i + 1 < e) {
          cm.prefetch(selected[i + 1].u());
          cm.prefetch(selected[i + 1].v);
        }
        evals[i] = cm.evaluate(u, v, /*with_cost=*/false);  // the queue had the cost; here only where and how far
        if (evals[i].error <= budget2) checks[i] = cm.check(u, v, evals[i].position, s);
      }
    });

    // Commit in selection order: room for the merged face lists is reserved sequentially (it may grow the
    // pool), then the collapses apply in parallel (their neighbourhoods are disjoint). Each survivor's ring
    // region is sized here by its merged list (two neighbours per face).
    survivors.clear();
    committed.clear();
    ring_first.clear();
    std::uint32_t total = 0;
    for (std::size_t i = 0; i < ns; ++i) {
      if (evals[i].error > budget2) {
        over_budget = true;  // not parked: its cost only changes when an endpoint does
        continue;
      }
      if (!checks[i].ok()) {
        parked.park(selected[i].u(), selected[i].v);
        ++result.rejected;
        continue;
      }
      const Check& c = checks[i];
      ring_first.push_back(total);
      total += 2 * (cm.star_size(c.victim) + cm.star_size(c.survivor) - 2 * c.edge_face_count);
      cm.reserve(checks[i]);
      max_error = std::max(max_error, evals[i].error);
      committed.push_back(static_cast<std::uint32_t>(i));
      survivors.push_back(c.survivor);
      ++result.collapses;
    }
    const std::size_t nsurv = survivors.size();
    ring_first.push_back(total);
    ring_buf.resize(total);
    ring_size.resize(nsurv);
    fresh.resize(total);

    // Each collapse is applied and the edges around its survivor re-evaluated in one parallel pass: a
    // survivor's ring and the quadrics its edges read lie in its own closed neighbourhood, which no other
    // collapse of the batch touches. Each survivor writes its ring and its fresh candidates into its own
    // region, so the result is in survivor order whatever the threads do; no edge appears twice.
    parallel.for_ranges(nsurv, 8, [&](std::size_t b, std::size_t e) {
      Scratch& s = scratch.local();
      for (std::size_t i = b; i < e; ++i) {
        if (i + 1 < e) {  // the next collapse's records, while this one is applied
          const Check& next = checks[committed[i + 1]];
          for (std::uint32_t w : {next.victim, next.survivor}) {
            cm.prefetch(w);
            cm.prefetch_star(w);
          }
        }
        cm.apply(checks[committed[i]], evals[committed[i]].position, s);
        const std::uint32_t sv = survivors[i];
        cm.ring(sv, s.ring);
        for (std::uint32_t w : s.ring) cm.prefetch(w);
        const std::uint32_t base = ring_first[i];
        ring_size[i] = static_cast<std::uint32_t>(s.ring.size());
        for (std::size_t r = 0; r < s.ring.size(); ++r) {
          const std::uint32_t w = s.ring[r];
          ring_buf[base + r] = w;
          if (cm.rule(sv, w) == EdgeRule::forbidden) {
            fresh[base + r].vsum = kInvalidIndex;
            continue;
          }
          const std::uint32_t u = std::min(sv, w), v = std::max(sv, w);
          fresh[base + r] = make_entry(cost_bits(cm.evaluate(u, v).cost), u, v, cm.version(u) + cm.version(v));
        }
      }
    });
    for (std::size_t i = 0; i < nsurv; ++i) {
      for (std::uint32_t r = 0; r < ring_size[i]; ++r) {
        const QueueEntry& e = fresh[ring_first[i] + r];
        if (e.vsum != kInvalidIndex) {
          queue.push(e);
        }
      }
    }

    // Candidates parked anywhere in a survivor's new neighbourhood may have become valid: evaluate again.
    // Pairs with a survivor endpoint were just re-evaluated above.
    if (parked.any()) {
      ++stamp;
      for (std::uint32_t sv : survivors) mark[sv] = stamp;
      released.clear();
      for (std::size_t i = 0; i < nsurv; ++i) {
        parked.release(survivors[i], released);
        for (std::uint32_t r = 0; r < ring_size[i]; ++r) parked.release(ring_buf[ring_first[i] + r], released);
      }
      std::sort(released.begin(), released.end());
      released.erase(std::unique(released.begin(), released.end()), released.end());
      for (const auto& [u, v] : released) {
        if (!cm.alive(u) || !cm.alive(v) || mark[u] == stamp || mark[v] == stamp) continue;
        queue.push(make_entry(cost_bits(cm.evaluate(u, v).cost), u, v, cm.version(u) + cm.version(v)));
      }
    }
    for (const QueueEntry& e : deferred) queue.push(e);

    // Superseded entries: drop them in one sweep when they dominate the queue.
    if (queue.size() > kPurgeFactor * (cm.alive_faces() * 3 / 2) + 4096) {
      queue.purge(parallel, current);
    }
  }
  result.timings.collapse_ms = elapsed_ms(t0);

  finish_result(cm, max_error, target, over_budget, result);
  return result;
}

}  // namespace lodforge::collapse
