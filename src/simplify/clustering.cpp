// Vertex clustering engine.
//
// Papers implemented here:
//  - J. Rossignac, P. Borrel, "Multi-resolution 3D approximations for rendering complex scenes", 1993: a grid
//    over the model, one vertex per occupied cell, triangles kept when their corners fall in three cells.
//  - P. Lindstrom, "Out-of-core simplification of large polygonal models", SIGGRAPH 2000: each triangle's plane
//    quadric goes to the cells of its corners; a cell's vertex minimises the sum (truncated eigen-solve about
//    the cell's mean, clamped to the cell); Lindstrom & Silva 2001 for the boundary planes and the clamp.
//  - A. Willmott, "Rapid simplification of multi-attribute meshes", HPG 2011: render vertices cluster apart
//    where the attributes are discontinuous, so UV charts, hard edges and materials survive.
//
// Outline (docs/clustering.md has the details and the figures):
//   prepare   normalised positions, per-vertex class (locked vertices alone; otherwise the dominant joint),
//             boundary vertices (an XOR of neighbour hashes cancels around a closed fan)
//   search    the grid resolution, a real number of cells along the longest axis: steps until the target is
//             bracketed, then regula falsi on the count ~ resolution² law; each probe counts the triangles whose
//             corners lie in three clusters (an O(n) pass, parallel over fixed chunks)
//   build     clusters numbered in vertex order, quadrics summed in triangle order (sequential: sums of
//             doubles in a fixed order), solved in parallel; render vertices grouped by the connected pieces
//             of each cluster's wedges (and the face's material); duplicate and zero-area faces dropped
//   budget    an error budget is held by measuring the output per resolution (there is no collapse sequence
//             to back off along): the coarsest measured resolution that holds
// Every parallel step writes per-item results or integer sums, so the output is the same for any thread count.
#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <unordered_map>
#include <utility>
#include <vector>

#include <Eigen/Dense>

#include "engines.hpp"
#include "lodforge/core/topology.hpp"
#include "lodforge/core/union_find.hpp"

namespace lodforge::collapse {
namespace {

// Eigenvalues of a cell quadric below this fraction of its largest are treated as zero: along those directions
// the cell's vertex stays at the mean of its members (flat and cylindrical cells).
constexpr double kEigenTruncation = 1e-3;
// Finest grid: cells per axis of the normalised box (keys hold 21 bits per axis).
constexpr double kMaxResolution = 1048575.0;
// The search stops once a probe lands within this fraction below the target, or the resolution interval is
// this narrow (relative).
constexpr double kCountTolerance = 0.005;
constexpr double kResolutionTolerance = 1e-3;
constexpr int kMaxProbes = 48;
// Other grid phases are tried while the count is more than this fraction below the target, each with this
// many probes.
constexpr double kPhaseTolerance = 0.02;
constexpr int kPhaseProbes = 8;
// First guess of the search: triangles per unit of normalised surface area at one cell per unit (two per
// occupied cell, and a surface crossing cells obliquely occupies more of them than its area; measured on the
// scanned corpus about 2.5-3.5).
constexpr double kTrianglesPerArea = 3.0;
// Rounds of target correction for faces the probes count but the build drops (duplicates, zero area).
constexpr int kMaxCorrections = 1;
// A build that lands this close below the target is kept without a correction round.
constexpr double kBuildTolerance = 0.01;
// Budget bisection over the resolution: stops when the interval is this narrow (ratio) or after this many
// measurements.
constexpr double kBudgetResolutionRatio = 1.02;
constexpr int kMaxBudgetMeasurements = 16;
// Triangles per parallel chunk of a probe (fixed, so sums do not depend on threads).
constexpr std::size_t kChunk = 1 << 16;
// Rounds of a stage's manifold repair at most (one was needed on the benchmark terrains).
constexpr int kMaxManifoldRounds = 8;
// Influences kept per vertex after blending skin weights.
constexpr int kKeptInfluences = 4;

constexpr std::uint32_t kFreeClass = 0;
constexpr std::uint32_t kLockedClassBase = 0x20000;  // above every joint class (joint + 1 <= 0x10000)

std::uint64_t mix64(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

// Symmetric 3×3 quadric: x^T A x + 2 b^T x + c, plus the area it stands for.
struct Quadric {
  double a00 = 0, a01 = 0, a02 = 0, a11 = 0, a12 = 0, a22 = 0, b0 = 0, b1 = 0, b2 = 0, c = 0, area = 0;
  void add_plane(const Vec3d& n, double d, double w) {
    a00 += w * n[0] * n[0];
    a01 += w * n[0] * n[1];
    a02 += w * n[0] * n[2];
    a11 += w * n[1] * n[1];
    a12 += w * n[1] * n[2];
    a22 += w * n[2] * n[2];
    b0 += w * d * n[0];
    b1 += w * d * n[1];
    b2 += w * d * n[2];
    c += w * d * d;
  }
  Quadric& operator+=(const Quadric& q) {
    a00 += q.a00, a01 += q.a01, a02 += q.a02, a11 += q.a11, a12 += q.a12, a22 += q.a22;
    b0 += q.b0, b1 += q.b1, b2 += q.b2, c += q.c, area += q.area;
    return *this;
  }
  double error(const Vec3d& x) const {
    const double ax0 = a00 * x[0] + a01 * x[1] + a02 * x[2];
    const double ax1 = a01 * x[0] + a11 * x[1] + a12 * x[2];
    const double ax2 = a02 * x[0] + a12 * x[1] + a22 * x[2];
    return x[0] * ax0 + x[1] * ax1 + x[2] * ax2 + 2.0 * (b0 * x[0] + b1 * x[1] + b2 * x[2]) + c;
  }
};

// A position cluster's identity: the grid cell and the vertex class.
struct Key {
  std::uint64_t cell = 0;
  std::uint32_t cls = 0;
  bool operator==(const Key&) const = default;
};

// Open addressing from Key to a dense id, ids given in insertion order.
class KeyTable {
 public:
  explicit KeyTable(std::size_t expected) { rehash(std::bit_ceil(std::max<std::size_t>(64, 2 * expected))); }
  std::uint32_t insert(const Key& k) {
    if (2 * (size_ + 1) > slots_.size()) rehash(2 * slots_.size());
    std::size_t i = hash(k) & (slots_.size() - 1);
    for (;;) {
      Slot& s = slots_[i];
      if (s.id == kInvalidIndex) {
        s.key = k;
        s.id = static_cast<std::uint32_t>(size_++);
        return s.id;
      }
      if (s.key == k) return s.id;
      i = (i + 1) & (slots_.size() - 1);
    }
  }
  std::size_t size() const { return size_; }

 private:
  struct Slot {
    Key key;
    std::uint32_t id = kInvalidIndex;
  };
  static std::size_t hash(const Key& k) { return static_cast<std::size_t>(mix64(k.cell ^ (std::uint64_t{k.cls} << 43))); }
  void rehash(std::size_t n) {
    std::vector<Slot> old = std::move(slots_);
    slots_.assign(n, Slot{});
    for (const Slot& s : old) {
      if (s.id == kInvalidIndex) continue;
      std::size_t i = hash(s.key) & (n - 1);
      while (slots_[i].id != kInvalidIndex) i = (i + 1) & (n - 1);
      slots_[i] = s;
    }
  }
  std::vector<Slot> slots_;
  std::size_t size_ = 0;
};

// A face as clusters in canonical rotation (smallest first, winding kept) and its material.
struct FaceKey {
  std::uint32_t a, b, c, material;
  bool operator==(const FaceKey&) const = default;
};

// Open-addressing set of face keys (no allocation per face: the build inserts one key per surviving triangle).
class FaceSet {
 public:
  explicit FaceSet(std::size_t expected) : slots_(std::bit_ceil(std::max<std::size_t>(64, 2 * expected))) {}
  // Whether `k` was new.
  bool insert(const FaceKey& k) {
    if (2 * (size_ + 1) > slots_.size()) rehash(2 * slots_.size());
    for (std::size_t i = hash(k) & (slots_.size() - 1);; i = (i + 1) & (slots_.size() - 1)) {
      Slot& s = slots_[i];
      if (!s.used) {
        s = {k, true};
        ++size_;
        return true;
      }
      if (s.key == k) return false;
    }
  }
  bool contains(const FaceKey& k) const {
    for (std::size_t i = hash(k) & (slots_.size() - 1);; i = (i + 1) & (slots_.size() - 1)) {
      const Slot& s = slots_[i];
      if (!s.used) return false;
      if (s.key == k) return true;
    }
  }

 private:
  struct Slot {
    FaceKey key{};
    bool used = false;
  };
  static std::size_t hash(const FaceKey& k) {
    return static_cast<std::size_t>(mix64((std::uint64_t{k.a} << 32 | k.b) ^ mix64(std::uint64_t{k.c} << 32 | k.material)));
  }
  void rehash(std::size_t n) {
    std::vector<Slot> old = std::move(slots_);
    slots_.assign(n, Slot{});
    size_ = 0;
    for (const Slot& s : old) {
      if (s.used) insert(s.key);
    }
  }
  std::vector<Slot> slots_;
  std::size_t size_ = 0;
};

// What the search and every build share: the input reduced to what clustering needs.
struct Prepared {
  explicit Prepared(const Mesh& m) : mesh(m) {}
  const Mesh& mesh;
  std::size_t triangles = 0;            // usable triangles (three distinct in-range vertices)
  // Filled by parallel passes, so not zeroed first.
  std::vector<std::uint32_t, UnconstructedAllocator<std::uint32_t>> tri{};       // 3 vertex ids per usable triangle
  std::vector<std::uint32_t, UnconstructedAllocator<std::uint32_t>> tri_face{};  // its face
  std::vector<char> used{};               // per vertex: some usable triangle has it
  std::vector<Vec3f> unit{};              // positions in the normalised box [0, 1]^3 (longest axis 1)
  std::vector<std::uint32_t> cls{};       // vertex class (kFreeClass, joint + 1, or kLockedClassBase + id)
  std::vector<char> boundary{};           // vertex on a boundary edge (1), per vertex
  std::vector<std::pair<std::uint32_t, std::uint32_t>> boundary_edges{};  // (triangle, corner): edge corner→next
  Vec3d origin{};                       // model position of the normalised origin
  double extent = 1.0;                  // model length of the normalised unit
  double diagonal = 0.0;                // of the finite positions' bounding box, model units
  bool has_attributes = false;
  bool single_material = true;
  bool any_class = false;  // some vertex has a class other than kFreeClass
  double area = 0.0;       // surface area in normalised units
};

// A face's material; 0 where the mesh lists none.
std::uint32_t material_of(const Mesh& m, std::size_t f) {
  return f < m.face_material.size() ? m.face_material[f] : 0;
}

bool finite(const Vec3f& p) { return std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]); }

// The dominant joint of a vertex (largest weight, lowest joint on ties), +1; 0 without weights.
std::uint32_t dominant_joint_class(const SkinInfluences& s) {
  int best = -1;
  for (int i = 0; i < kMaxInfluences; ++i) {
    if (!(s.weights[static_cast<std::size_t>(i)] > 0.0f)) continue;
    if (best < 0 || s.weights[static_cast<std::size_t>(i)] > s.weights[static_cast<std::size_t>(best)] ||
        (s.weights[static_cast<std::size_t>(i)] == s.weights[static_cast<std::size_t>(best)] &&
         s.joints[static_cast<std::size_t>(i)] < s.joints[static_cast<std::size_t>(best)])) {
      best = i;
    }
  }
  return best < 0 ? kFreeClass : std::uint32_t{s.joints[static_cast<std::size_t>(best)]} + 1;
}

Prepared prepare(const Mesh& m, const SimplifyOptions& options, Parallel& parallel) {
  Prepared p(m);
  const std::size_t nv = m.vertex_count(), nf = m.face_count();
  for (std::uint32_t v : options.locked_vertices) {
    if (v >= nv) {
      throw std::invalid_argument("simplify: locked vertex " + std::to_string(v) + " out of range (mesh has " +
                                  std::to_string(nv) + " vertices)");
    }
  }
  // Triangles with three distinct vertices in range; the rest carry no surface.
  // Tested and counted per fixed chunk of faces, then written in place.
  auto usable = [&](std::uint32_t f) {
    if (m.face_size(f) != 3 || !face_indices_in_range(m, f)) return false;
    const std::uint32_t c = m.face_offsets[f];
    const std::uint32_t a = m.corner_vertex(c), b = m.corner_vertex(c + 1), d = m.corner_vertex(c + 2);
    return a != b && b != d && a != d;
  };
  std::vector<std::size_t> chunk_start((nf + kChunk - 1) / kChunk + 1, 0);
  std::vector<char> ok(nf);
  parallel.for_ranges(chunk_start.size() - 1, 1, [&](std::size_t cb, std::size_t ce) {
    for (std::size_t k = cb; k < ce; ++k) {
      std::size_t n = 0;
      for (std::size_t f = k * kChunk, end = std::min(nf, (k + 1) * kChunk); f < end; ++f) {
        ok[f] = usable(static_cast<std::uint32_t>(f));
        n += ok[f];
      }
      chunk_start[k + 1] = n;
    }
  });
  for (std::size_t k = 1; k < chunk_start.size(); ++k) chunk_start[k] += chunk_start[k - 1];
  p.triangles = chunk_start.back();
  p.tri.resize(3 * p.triangles);
  p.tri_face.resize(p.triangles);
  parallel.for_ranges(chunk_start.size() - 1, 1, [&](std::size_t cb, std::size_t ce) {
    for (std::size_t k = cb; k < ce; ++k) {
      std::size_t i = chunk_start[k];
      for (std::size_t f = k * kChunk, end = std::min(nf, (k + 1) * kChunk); f < end; ++f) {
        const auto face = static_cast<std::uint32_t>(f);
        if (!ok[f]) continue;
        const std::uint32_t c = m.face_offsets[face];
        p.tri[3 * i] = m.corner_vertex(c), p.tri[3 * i + 1] = m.corner_vertex(c + 1), p.tri[3 * i + 2] = m.corner_vertex(c + 2);
        p.tri_face[i++] = face;
      }
    }
  });

  // Bounds per fixed chunk, then combined (minima and maxima are exact in any order).
  std::vector<Bounds3> boxes((nv + kChunk - 1) / kChunk);
  parallel.for_ranges(boxes.size(), 1, [&](std::size_t cb, std::size_t ce) {
    for (std::size_t k = cb; k < ce; ++k) {
      for (std::size_t v = k * kChunk, end = std::min(nv, (k + 1) * kChunk); v < end; ++v) {
        if (finite(m.positions[v])) boxes[k].add(to_double(m.positions[v]));
      }
    }
  });
  Bounds3 box;
  for (const Bounds3& b : boxes) {
    if (!b.empty()) box.add(b.min), box.add(b.max);
  }
  if (!box.empty()) {
    p.origin = box.min;
    p.extent = std::max({box.max[0] - box.min[0], box.max[1] - box.min[1], box.max[2] - box.min[2]});
    if (!(p.extent > 0.0)) p.extent = 1.0;
  }
  p.diagonal = box.diagonal();
  p.used.assign(nv, 0);
  parallel.for_ranges(p.triangles, kChunk, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = 3 * b; i < 3 * e; ++i) std::atomic_ref<char>(p.used[p.tri[i]]).store(1, std::memory_order_relaxed);
  });
  p.unit.resize(nv);
  parallel.for_ranges(nv, 4096, [&](std::size_t b, std::size_t e) {
    for (std::size_t v = b; v < e; ++v) {
      const Vec3d u = (to_double(m.positions[v]) - p.origin) * (1.0 / p.extent);
      p.unit[v] = finite(m.positions[v]) ? to_float(u) : Vec3f{};
    }
  });

  // Boundary vertices: around a closed, consistently oriented fan every outgoing edge v→x has an incoming x→v,
  // so the XOR of hash(x) over both cancels; elsewhere it does not (up to hash collisions). The edges between
  // two such vertices are then counted exactly.
  std::vector<std::uint64_t> fan(nv, 0);
  for (std::size_t t = 0; t < p.triangles; ++t) {
    const Vec3d a = to_double(p.unit[p.tri[3 * t]]);
    p.area += 0.5 * length(cross(to_double(p.unit[p.tri[3 * t + 1]]) - a, to_double(p.unit[p.tri[3 * t + 2]]) - a));
  }
  for (std::size_t t = 0; t < p.triangles; ++t) {
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = p.tri[3 * t + static_cast<std::size_t>(k)], b = p.tri[3 * t + static_cast<std::size_t>((k + 1) % 3)];
      fan[a] ^= mix64(b);
      fan[b] ^= mix64(a);
    }
  }
  p.boundary.assign(nv, 0);
  for (std::size_t v = 0; v < nv; ++v) p.boundary[v] = fan[v] != 0;
  {
    std::unordered_map<std::uint64_t, std::uint32_t> uses;
    auto edge_key = [](std::uint32_t a, std::uint32_t b) {
      return a < b ? (std::uint64_t{a} << 32) | b : (std::uint64_t{b} << 32) | a;
    };
    for (std::size_t t = 0; t < p.triangles; ++t) {
      for (int k = 0; k < 3; ++k) {
        const std::uint32_t a = p.tri[3 * t + static_cast<std::size_t>(k)], b = p.tri[3 * t + static_cast<std::size_t>((k + 1) % 3)];
        if (p.boundary[a] && p.boundary[b]) ++uses[edge_key(a, b)];
      }
    }
    std::fill(p.boundary.begin(), p.boundary.end(), 0);
    for (std::size_t t = 0; t < p.triangles; ++t) {
      for (int k = 0; k < 3; ++k) {
        const std::uint32_t a = p.tri[3 * t + static_cast<std::size_t>(k)], b = p.tri[3 * t + static_cast<std::size_t>((k + 1) % 3)];
        if (fan[a] == 0 || fan[b] == 0) continue;
        if (uses[edge_key(a, b)] == 1) {
          p.boundary_edges.emplace_back(static_cast<std::uint32_t>(t), static_cast<std::uint32_t>(k));
          p.boundary[a] = p.boundary[b] = 1;
        }
      }
    }
  }

  // Vertex classes: locked vertices (options, painted lock, locked borders, non-finite positions) stay alone;
  // skinned vertices cluster only with vertices of the same dominant joint.
  p.cls.assign(nv, kFreeClass);
  const bool skinned = m.skin.size() == nv;
  if (skinned) {
    for (std::size_t v = 0; v < nv; ++v) p.cls[v] = dominant_joint_class(m.skin[v]);
  }
  auto lock = [&](std::size_t v) { p.cls[v] = kLockedClassBase + static_cast<std::uint32_t>(v); };
  for (std::uint32_t v : options.locked_vertices) lock(v);
  const bool painted = options.priority_channel == "_LOD_PRIORITY" && m.priority.size() == nv;
  for (std::size_t v = 0; v < nv; ++v) {
    if (!finite(m.positions[v])) lock(v);
    if (painted && m.priority[v] >= options.priority_lock) lock(v);
    if (options.border_mode == BorderMode::lock && p.boundary[v]) lock(v);
  }

  p.any_class = std::any_of(p.cls.begin(), p.cls.end(), [](std::uint32_t c) { return c != kFreeClass; });
  const std::size_t nw = m.wedge_count();
  p.has_attributes = (m.normals.size() == nw && nw > 0) || !m.uvs.empty() || !m.colors.empty() || !m.custom.empty() ||
                     !m.morph_targets.empty() || m.tangents.size() == nw;
  for (std::size_t t = 1; t < p.triangles; ++t) {
    if (material_of(m, p.tri_face[t]) != material_of(m, p.tri_face[0])) {
      p.single_material = false;
      break;
    }
  }
  return p;
}

// A grid: `resolution` cells per normalised unit, shifted by `phase` cells per axis. The default half-cell
// shift keeps a model's bounding planes off the cell walls; other phases are tried when a regular mesh (rows
// of vertices crossing cell walls together) makes the count jump over the target.
struct Grid {
  double resolution = 0.0;
  std::array<double, 3> phase{0.5, 0.5, 0.5};
};
constexpr std::array<double, 3> kPhases[] = {{0.5, 0.5, 0.5},    {0.25, 0.25, 0.25}, {0.75, 0.75, 0.75},
                                             {0.25, 0.5, 0.75},  {0.75, 0.25, 0.5},  {0.5, 0.75, 0.25},
                                             {0.125, 0.625, 0.375}, {0.875, 0.375, 0.625}};

// Normalised positions lie in [0, 1] (non-finite ones at 0), so each index fits its 21 bits.
std::uint64_t cell_of(const Vec3f& u, const Grid& g) {
  const auto index = [&](int i) {
    return static_cast<std::uint64_t>(std::max(0.0, double{u[i]} * g.resolution + g.phase[static_cast<std::size_t>(i)]));
  };
  return (index(0) << 42) | (index(1) << 21) | index(2);
}

// Triangles whose corners fall in three different clusters on grid `g` (before duplicates go).
std::size_t count_triangles(const Prepared& p, const Grid& g, Parallel& parallel, std::vector<std::uint64_t>& cells) {
  const std::size_t nv = p.unit.size();
  cells.resize(nv);
  parallel.for_ranges(nv, 8192, [&](std::size_t b, std::size_t e) {
    for (std::size_t v = b; v < e; ++v) cells[v] = cell_of(p.unit[v], g);
  });
  const std::size_t chunks = (p.triangles + kChunk - 1) / kChunk;
  std::vector<std::size_t> counts(chunks, 0);
  // Without classes (the common case) the cells alone decide.
  auto count = [&](auto with_classes) {
    parallel.for_ranges(chunks, 1, [&](std::size_t cb, std::size_t ce) {
      for (std::size_t c = cb; c < ce; ++c) {
        std::size_t n = 0;
        const std::size_t end = std::min(p.triangles, (c + 1) * kChunk);
        for (std::size_t t = c * kChunk; t < end; ++t) {
          const std::uint32_t a = p.tri[3 * t], b = p.tri[3 * t + 1], d = p.tri[3 * t + 2];
          const std::uint64_t ca = cells[a], cb2 = cells[b], cd = cells[d];
          if constexpr (decltype(with_classes)::value) {
            const bool ab = ca == cb2 && p.cls[a] == p.cls[b];
            const bool bd = cb2 == cd && p.cls[b] == p.cls[d];
            const bool ad = ca == cd && p.cls[a] == p.cls[d];
            n += !(ab || bd || ad);
          } else {
            n += ca != cb2 && cb2 != cd && ca != cd;
          }
        }
        counts[c] = n;
      }
    });
  };
  if (p.any_class) count(std::true_type{});
  else count(std::false_type{});
  std::size_t n = 0;
  for (std::size_t c : counts) n += c;
  return n;
}

struct Probe {
  Grid grid;
  std::size_t count = 0;
};

// For one phase: the resolution whose count is the largest found at or below `target`. First a bracket, by
// steps on the count ~ resolution² law, then interpolation and bisection inside it; `probes` counts passes.
Probe search_phase(const Prepared& p, std::size_t target, const std::array<double, 3>& phase, double start,
                   int max_probes, Parallel& parallel, std::size_t& probes, const StopRequest& stop,
                   std::vector<std::uint64_t>& cells) {
  Probe best{.grid = {0.0, phase}, .count = 0};  // resolution 0: one cell, no triangle
  double lo = -1.0, hi = -1.0;  // the bracket: counts at or below / above the target
  double lo_count = 0.0, hi_count = 0.0;
  double res = std::clamp(start, 1e-3, kMaxResolution);
  for (int probe = 0; probe < max_probes && !stop.requested(); ++probe) {
    const Grid g{res, phase};
    const std::size_t n = count_triangles(p, g, parallel, cells);
    ++probes;
    if (n <= target) {
      if (n > best.count || (n == best.count && res > best.grid.resolution)) best = {g, n};
      lo = res;
      lo_count = static_cast<double>(n);
      if (static_cast<double>(target - n) <= kCountTolerance * static_cast<double>(target)) break;
      if (res >= kMaxResolution) break;
    } else {
      hi = res;
      hi_count = static_cast<double>(n);
    }
    const double scale = std::sqrt(static_cast<double>(target) / static_cast<double>(std::max<std::size_t>(n, 1)));
    if (hi < 0.0) {  // no count above the target yet: step up
      res = std::min(kMaxResolution, res * std::max(1.02, 1.02 * scale));
      continue;
    }
    if (lo < 0.0) {  // none at or below it yet: step down
      res = res * std::min(0.98, 0.98 * scale);
      continue;
    }
    if (hi - lo <= kResolutionTolerance * hi) break;
    // Regula falsi on count ~ resolution², kept off the bracket's ends so that it always shrinks.
    const double t = (static_cast<double>(target) - lo_count) / std::max(hi_count - lo_count, 1.0);
    double next = std::sqrt(lo * lo + t * (hi * hi - lo * lo));
    const double margin = 0.1 * (hi - lo);
    next = std::clamp(next, lo + margin, hi - margin);
    res = next;
  }
  return best;
}

// The grid for `target`: the default phase first; where the count stays more than a percent below the
// target (count jumps on regular meshes), a few other phases near the resolution found.
Probe search_grid(const Prepared& p, std::size_t target, double start, Parallel& parallel, std::size_t& probes,
                  const StopRequest& stop) {
  std::vector<std::uint64_t> cells;
  Probe best = search_phase(p, target, kPhases[0], start, kMaxProbes, parallel, probes, stop, cells);
  const double near = best.grid.resolution > 0.0 ? best.grid.resolution : start;
  for (std::size_t i = 1; i < std::size(kPhases); ++i) {
    if (static_cast<double>(target - best.count) <= kPhaseTolerance * static_cast<double>(target)) break;
    const Probe other = search_phase(p, target, kPhases[i], near, kPhaseProbes, parallel, probes, stop, cells);
    if (other.count > best.count) best = other;
  }
  return best;
}

// One clustering of the prepared input at a resolution.
struct Built {
  Mesh mesh;
  std::size_t triangles = 0;
  double max_error2 = 0;  // largest cluster quadric error per area, normalised units squared
  std::vector<std::uint32_t> output_vertex;  // stage builds: per input vertex, its output vertex (or invalid)
};

void blend_skin(const Mesh& m, const std::vector<std::uint32_t>& members, SkinInfluences& out) {
  std::vector<std::pair<std::uint16_t, double>> sum;
  sum.reserve(16);
  for (std::uint32_t v : members) {
    const SkinInfluences& s = m.skin[v];
    for (int i = 0; i < kMaxInfluences; ++i) {
      const float w = s.weights[static_cast<std::size_t>(i)];
      if (!(w > 0.0f)) continue;
      const std::uint16_t j = s.joints[static_cast<std::size_t>(i)];
      auto it = std::find_if(sum.begin(), sum.end(), [&](const auto& x) { return x.first == j; });
      if (it == sum.end()) sum.emplace_back(j, w);
      else it->second += w;
    }
  }
  std::sort(sum.begin(), sum.end(), [](const auto& x, const auto& y) {
    return x.second > y.second || (x.second == y.second && x.first < y.first);
  });
  if (sum.size() > kKeptInfluences) sum.resize(kKeptInfluences);
  double total = 0.0;
  for (const auto& x : sum) total += x.second;
  out = SkinInfluences{};
  for (std::size_t i = 0; i < sum.size(); ++i) {
    out.joints[i] = sum[i].first;
    out.weights[i] = total > 0.0 ? static_cast<float>(sum[i].second / total) : 0.0f;
  }
}

// Per render-vertex class: the sums its attributes are averaged from, and the member kept by `keep` placement.
struct WedgeClass {
  std::uint32_t cluster = 0;
  std::uint32_t corners = 0;
  std::uint32_t first_wedge = kInvalidIndex;  // lowest-index member (custom attributes come from it)
  std::uint32_t nearest_wedge = kInvalidIndex;
  double nearest = std::numeric_limits<double>::infinity();
};

// A clustering on its way to a Built: the steps of build() fill it in order (clusters, placement, faces,
// output); a stage repairs it between the faces and the output.
struct Clustering {
  std::vector<std::uint64_t> cells;       // per input vertex: its grid cell
  std::vector<std::uint32_t> cluster;     // per input vertex: its cluster (invalid where no triangle uses it)
  std::size_t count = 0;                  // clusters
  std::vector<std::uint32_t> any_member;  // per cluster: its lowest vertex
  std::vector<Vec3d> rep;                 // per cluster: its vertex, normalised units
  std::vector<double> err2;               // per cluster: quadric error per area at `rep`
  std::vector<Vec3f> model;               // per cluster: its vertex in model units
  std::vector<std::uint32_t> kept;        // triangles kept, in order
};

// Clusters, numbered in vertex order (used vertices only).
void assign_clusters(const Prepared& p, const Grid& grid, Parallel& parallel, bool stage, Clustering& cl) {
  const double resolution = grid.resolution;
  const std::size_t nv = p.mesh.vertex_count();
  const std::vector<char>& used = p.used;
  std::vector<std::uint64_t>& cells = cl.cells;
  cells.resize(nv);
  parallel.for_ranges(nv, 8192, [&](std::size_t b, std::size_t e) {
    for (std::size_t v = b; v < e; ++v) cells[v] = cell_of(p.unit[v], grid);
  });
  std::vector<std::uint32_t>& cluster = cl.cluster;
  cluster.assign(nv, kInvalidIndex);
  if (stage) {
    // A stage merges only vertices connected within their cell (by edges of the cell, the same class): two
    // sheets crossing one cell stay apart instead of meeting in a non-manifold vertex. A cluster is such a
    // connected piece; its root is its lowest vertex (roots link to the lower root), so numbering roots in
    // vertex order numbers clusters in the order of their first vertex, as the table does for the others.
    UnionFind sets(nv);
    parallel.for_ranges(p.triangles, kChunk, [&](std::size_t b, std::size_t e) {
      for (std::size_t t = b; t < e; ++t) {
        for (int k = 0; k < 3; ++k) {
          const std::uint32_t a = p.tri[3 * t + static_cast<std::size_t>(k)], c = p.tri[3 * t + static_cast<std::size_t>((k + 1) % 3)];
          if (cells[a] == cells[c] && p.cls[a] == p.cls[c]) sets.unite_shared(a, c);
        }
      }
    });
    parallel.for_ranges(nv, 1 << 14, [&](std::size_t b, std::size_t e) {
      for (std::size_t v = b; v < e; ++v) cluster[v] = sets.find_shared(static_cast<std::uint32_t>(v));
    });
    std::vector<std::uint32_t> id(nv);  // per root: its cluster
    std::uint32_t n = 0;
    for (std::size_t v = 0; v < nv; ++v) {
      if (used[v] && cluster[v] == v) id[v] = n++;
    }
    parallel.for_ranges(nv, 1 << 14, [&](std::size_t b, std::size_t e) {
      for (std::size_t v = b; v < e; ++v) cluster[v] = used[v] ? id[cluster[v]] : kInvalidIndex;
    });
    cl.count = n;
    return;
  }
  KeyTable table(std::min<std::size_t>(nv, static_cast<std::size_t>(4.0 * resolution * resolution) + 64));
  for (std::size_t v = 0; v < nv; ++v) {
    if (used[v]) cluster[v] = table.insert({cells[v], p.cls[v]});
  }
  cl.count = table.size();
}

// Each cluster's vertex: quadrics summed in triangle order (then boundary planes), solved about the members'
// mean, truncated, clamped to the cell; locked vertices keep their exact position.
void place(const Prepared& p, const Grid& grid, const SimplifyOptions& options, Parallel& parallel, Clustering& cl) {
  const double resolution = grid.resolution;
  const Mesh& m = p.mesh;
  const std::size_t nv = m.vertex_count(), nc = cl.count;
  const std::vector<std::uint32_t>& cluster = cl.cluster;
  const std::vector<std::uint64_t>& cells = cl.cells;
  std::vector<Quadric> q(nc);
  std::vector<Vec3d> sum(nc, Vec3d{});
  std::vector<std::uint32_t> members(nc, 0);
  for (std::size_t v = 0; v < nv; ++v) {
    if (cluster[v] == kInvalidIndex) continue;
    sum[cluster[v]] = sum[cluster[v]] + to_double(p.unit[v]);
    ++members[cluster[v]];
  }
  auto unit_pos = [&](std::uint32_t v) { return to_double(p.unit[v]); };
  // Unit normal × area (0 for degenerate), computed where used: an array of them is 24 bytes a triangle.
  auto normal_of = [&](std::size_t t) {
    const Vec3d a = unit_pos(p.tri[3 * t]);
    return cross(unit_pos(p.tri[3 * t + 1]) - a, unit_pos(p.tri[3 * t + 2]) - a) * 0.5;
  };
  for (std::size_t t = 0; t < p.triangles; ++t) {
    const Vec3d normal = normal_of(t);
    const double area = length(normal);
    if (!(area > 0.0) || !std::isfinite(area)) continue;
    const Vec3d n = normal * (1.0 / area);
    const double d = -dot(n, unit_pos(p.tri[3 * t]));
    Quadric f;
    f.add_plane(n, d, area);
    f.area = area;
    for (int k = 0; k < 3; ++k) q[cluster[p.tri[3 * t + static_cast<std::size_t>(k)]]] += f;
  }
  if (options.border_mode == BorderMode::preserve && options.border_weight > 0.0) {
    for (const auto& [t, k] : p.boundary_edges) {
      const std::uint32_t a = p.tri[3 * t + k], b = p.tri[3 * t + (k + 1) % 3];
      const Vec3d e = unit_pos(b) - unit_pos(a);
      const double len2 = dot(e, e);
      const Vec3d face_n = normal_of(t);
      Vec3d n = cross(e, face_n);
      const double nl = length(n);
      if (!(nl > 0.0) || !std::isfinite(nl)) continue;
      n = n * (1.0 / nl);
      Quadric f;
      f.add_plane(n, -dot(n, unit_pos(a)), options.border_weight * len2);
      q[cluster[a]] += f;
      q[cluster[b]] += f;
    }
  }

  // Representatives: the quadric's minimiser about the members' mean, truncated, clamped to the cell.
  std::vector<Vec3d>& rep = cl.rep;
  std::vector<double>& err2 = cl.err2;
  std::vector<std::uint32_t>& any_member = cl.any_member;
  rep.assign(nc, Vec3d{});
  err2.assign(nc, 0.0);
  any_member.assign(nc, kInvalidIndex);
  for (std::size_t v = nv; v-- > 0;) {
    if (cluster[v] != kInvalidIndex) any_member[cluster[v]] = static_cast<std::uint32_t>(v);
  }
  const double cell = resolution > 0.0 ? 1.0 / resolution : 2.0;
  parallel.for_ranges(nc, 1024, [&](std::size_t b, std::size_t e) {
    for (std::size_t c = b; c < e; ++c) {
      const std::uint32_t v0 = any_member[c];
      if (p.cls[v0] >= kLockedClassBase) {  // a locked vertex keeps its exact position
        rep[c] = to_double(p.unit[v0]);
        err2[c] = 0.0;
        continue;
      }
      const Vec3d mean = sum[c] * (1.0 / members[c]);
      const Quadric& Q = q[c];
      Eigen::Matrix3d A;
      A << Q.a00, Q.a01, Q.a02, Q.a01, Q.a11, Q.a12, Q.a02, Q.a12, Q.a22;
      const Eigen::Vector3d bv(Q.b0, Q.b1, Q.b2), mv(mean[0], mean[1], mean[2]);
      Eigen::Vector3d x = mv;
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
      eig.computeDirect(A);
      const Eigen::Vector3d lambda = eig.eigenvalues();
      const double top = std::max(std::abs(lambda[0]), std::max(std::abs(lambda[1]), std::abs(lambda[2])));
      if (top > 0.0 && std::isfinite(top)) {
        const Eigen::Vector3d r = -(bv + A * mv);
        for (int i = 0; i < 3; ++i) {
          if (lambda[i] > kEigenTruncation * top) {
            const Eigen::Vector3d vi = eig.eigenvectors().col(i);
            x += vi * (vi.dot(r) / lambda[i]);
          }
        }
      }
      Vec3d pos{{x[0], x[1], x[2]}};
      if (!(std::isfinite(pos[0]) && std::isfinite(pos[1]) && std::isfinite(pos[2]))) pos = mean;
      // The cell of the members (all share it): [i - phase, i + 1 - phase) / resolution per axis.
      const std::uint64_t key = cells[v0];
      for (int i = 0; i < 3; ++i) {
        const auto idx = static_cast<double>((key >> (21 * (2 - i))) & 0x1fffff) - grid.phase[static_cast<std::size_t>(i)];
        const double lo = idx * cell, hi = (idx + 1.0) * cell;
        pos[i] = std::clamp(pos[i], lo, hi);
      }
      rep[c] = pos;
      err2[c] = Q.area > 0.0 ? std::max(0.0, Q.error(pos)) / Q.area : 0.0;
    }
  });

  cl.model.resize(nc);
  for (std::size_t c = 0; c < nc; ++c) {
    const std::uint32_t v0 = any_member[c];
    cl.model[c] = p.cls[v0] >= kLockedClassBase ? m.positions[v0] : to_float(p.origin + rep[c] * p.extent);
  }
}

// Faces: corners in three clusters, no zero area, no repeat of an earlier face (same clusters in the same
// cyclic order, same material); in a stage, no back-to-back pair either. Before placement (no `model` yet)
// the area is not tested. `triangles` lists the candidates in order (all triangles where null); the kept
// ones are appended to `kept`.
void select_faces(const Prepared& p, const Clustering& cl, bool stage, const std::vector<std::uint32_t>* triangles,
                  Parallel& parallel, std::vector<std::uint32_t>& kept) {
  const Mesh& m = p.mesh;
  const std::vector<std::uint32_t>& cluster = cl.cluster;
  const std::vector<Vec3f>& model = cl.model;
  const std::size_t candidates = triangles != nullptr ? triangles->size() : p.triangles;
  const std::size_t first = kept.size();
  // Corners in three clusters and a non-zero area, per fixed chunk in parallel; then the repeats, in order.
  std::vector<std::vector<std::uint32_t>> passing((candidates + kChunk - 1) / kChunk);
  parallel.for_ranges(passing.size(), 1, [&](std::size_t cb, std::size_t ce) {
    for (std::size_t chunk = cb; chunk < ce; ++chunk) {
      const std::size_t end = std::min(candidates, (chunk + 1) * kChunk);
      for (std::size_t i = chunk * kChunk; i < end; ++i) {
        const std::size_t t = triangles != nullptr ? (*triangles)[i] : i;
        const std::uint32_t c0 = cluster[p.tri[3 * t]], c1 = cluster[p.tri[3 * t + 1]], c2 = cluster[p.tri[3 * t + 2]];
        if (c0 == c1 || c1 == c2 || c0 == c2) continue;
        if (!model.empty()) {
          const Vec3d a = to_double(model[c0]);
          const Vec3d n = cross(to_double(model[c1]) - a, to_double(model[c2]) - a);
          if (!(dot(n, n) > 0.0)) continue;
        }
        passing[chunk].push_back(static_cast<std::uint32_t>(t));
      }
    }
  });
  std::size_t survivors = 0;
  for (const auto& list : passing) survivors += list.size();
  // Canonical rotation: the smallest cluster first, the winding kept (`flip`: the reverse face's key).
  auto key_of = [&](std::uint32_t t, bool flip) {
    std::uint32_t c0 = cluster[p.tri[3 * t]], c1 = cluster[p.tri[3 * t + (flip ? 2 : 1)]],
                  c2 = cluster[p.tri[3 * t + (flip ? 1 : 2)]];
    while (c0 > c1 || c0 > c2) {
      const std::uint32_t x = c0;
      c0 = c1, c1 = c2, c2 = x;
    }
    return FaceKey{c0, c1, c2, material_of(m, p.tri_face[t])};
  };
  FaceSet seen(survivors);
  kept.reserve(first + survivors);
  for (const auto& list : passing) {
    for (std::uint32_t t : list) {
      if (seen.insert(key_of(t, false))) kept.push_back(t);
    }
  }
  if (stage) {
    // A face whose reverse was kept too is one of a back-to-back pair (a fold or a thin part within a cell):
    // both go, as their shared edges would be non-manifold and lock their vertices in a later engine.
    std::vector<char> pair(kept.size() - first, 0);
    parallel.for_ranges(pair.size(), 1 << 14, [&](std::size_t b, std::size_t e) {
      for (std::size_t i = b; i < e; ++i) pair[i] = seen.contains(key_of(kept[first + i], true));
    });
    std::size_t n = first;
    for (std::size_t i = first; i < kept.size(); ++i) {
      if (!pair[i - first]) kept[n++] = kept[i];
    }
    kept.resize(n);
  }
}

// The output mesh of a clustering: render vertices, numbering, per-vertex and per-wedge data.
Built emit(const Prepared& p, const SimplifyOptions& options, Parallel& parallel, const Clustering& cl, bool stage) {
  const Mesh& m = p.mesh;
  const std::size_t nv = m.vertex_count(), nw = m.wedge_count(), nc = cl.count;
  const std::vector<std::uint32_t>& cluster = cl.cluster;
  const std::vector<std::uint32_t>& kept = cl.kept;
  const std::vector<Vec3d>& rep = cl.rep;
  const std::vector<double>& err2 = cl.err2;
  const std::vector<Vec3f>& model = cl.model;
  Built out;
  out.triangles = kept.size();
  for (std::uint32_t t : kept) {
    for (int k = 0; k < 3; ++k) out.max_error2 = std::max(out.max_error2, err2[cluster[p.tri[3 * t + static_cast<std::size_t>(k)]]]);
  }

  // Render vertices: a corner's class is the connected piece of its wedge among the wedges of its cluster
  // (wedges joined by a face, both in the cluster), with the face's material. Without attributes a cluster
  // and a material make a class.
  const bool per_cluster = !p.has_attributes && p.single_material;  // a class per cluster: no corner pass
  std::vector<std::uint32_t> corner_class(per_cluster ? 0 : 3 * p.triangles);
  std::vector<WedgeClass> classes;
  auto class_of = [&](std::size_t t, std::uint32_t k) {
    return per_cluster ? cluster[p.tri[3 * t + k]] : corner_class[3 * t + k];
  };
  const bool nearest = options.attribute_placement == AttributePlacement::keep;
  if (per_cluster) {
    classes.resize(nc);
    for (std::uint32_t c = 0; c < nc; ++c) classes[c].cluster = c;
  } else {
    UnionFind pieces(p.has_attributes ? nw : 0);
    if (p.has_attributes) {
      for (std::size_t t = 0; t < p.triangles; ++t) {
        const std::uint32_t f = p.tri_face[t], c = m.face_offsets[f];
        for (int k = 0; k < 3; ++k) {
          const std::uint32_t i = c + static_cast<std::uint32_t>(k), j = c + static_cast<std::uint32_t>((k + 1) % 3);
          if (cluster[m.corner_vertex(i)] != cluster[m.corner_vertex(j)]) continue;
          pieces.unite(m.corner_wedge[i], m.corner_wedge[j]);
        }
      }
    }
    // (root or cluster, material) -> class, in order of first corner.
    std::vector<std::uint32_t> first_class(p.has_attributes ? nw : nc, kInvalidIndex), first_material;
    first_material.assign(first_class.size(), 0);
    std::unordered_map<std::uint64_t, std::uint32_t> other;
    for (std::size_t t = 0; t < p.triangles; ++t) {
      const std::uint32_t f = p.tri_face[t], c = m.face_offsets[f], material = material_of(m, f);
      for (std::uint32_t k = 0; k < 3; ++k) {
        const std::uint32_t w = m.corner_wedge[c + k];
        const std::uint32_t v = m.wedge_vertex[w];
        const std::uint32_t id = p.has_attributes ? pieces.find(w) : cluster[v];
        std::uint32_t cls;
        if (first_class[id] == kInvalidIndex) {
          cls = first_class[id] = static_cast<std::uint32_t>(classes.size());
          first_material[id] = material;
          classes.push_back({.cluster = cluster[v]});
        } else if (first_material[id] == material) {
          cls = first_class[id];
        } else {
          const auto [it, fresh] = other.try_emplace((std::uint64_t{id} << 32) | material,
                                                     static_cast<std::uint32_t>(classes.size()));
          if (fresh) classes.push_back({.cluster = cluster[v]});
          cls = it->second;
        }
        corner_class[3 * t + k] = cls;
        WedgeClass& wc = classes[cls];
        ++wc.corners;
        wc.first_wedge = std::min(wc.first_wedge, w);
        if (!nearest) continue;
        const Vec3d d = to_double(p.unit[v]) - rep[wc.cluster];
        const double dist = dot(d, d);
        if (dist < wc.nearest || (dist == wc.nearest && w < wc.nearest_wedge)) {
          wc.nearest = dist;
          wc.nearest_wedge = w;
        }
      }
    }
  }

  // Output numbering: vertices and wedges in order of first use by a kept face.
  std::vector<std::uint32_t> vertex_id(nc, kInvalidIndex), wedge_id(classes.size(), kInvalidIndex);
  std::vector<std::uint32_t> out_vertex_cluster, out_wedge_class;
  Mesh& o = out.mesh;
  o.name = m.name;
  o.materials = m.materials;
  o.groups = m.groups;
  o.formats = m.formats;
  o.morph_default_weights = m.morph_default_weights;
  o.face_offsets.assign(1, 0);
  o.corner_wedge.reserve(3 * kept.size());
  o.face_material.reserve(kept.size());
  const bool groups = m.face_group.size() == m.face_count();
  for (std::uint32_t t : kept) {
    for (std::uint32_t k = 0; k < 3; ++k) {
      const std::uint32_t cls = class_of(t, k);
      if (wedge_id[cls] == kInvalidIndex) {
        wedge_id[cls] = static_cast<std::uint32_t>(out_wedge_class.size());
        out_wedge_class.push_back(cls);
        const std::uint32_t c = classes[cls].cluster;
        if (vertex_id[c] == kInvalidIndex) {
          vertex_id[c] = static_cast<std::uint32_t>(out_vertex_cluster.size());
          out_vertex_cluster.push_back(c);
        }
      }
      o.corner_wedge.push_back(wedge_id[cls]);
    }
    o.face_offsets.push_back(static_cast<std::uint32_t>(o.corner_wedge.size()));
    o.face_material.push_back(material_of(m, p.tri_face[t]));
    if (groups) o.face_group.push_back(m.face_group[p.tri_face[t]]);
  }
  const std::size_t ov = out_vertex_cluster.size(), ow = out_wedge_class.size();
  o.positions.resize(ov);
  for (std::size_t i = 0; i < ov; ++i) o.positions[i] = model[out_vertex_cluster[i]];
  if (stage) {
    out.output_vertex.assign(nv, kInvalidIndex);
    for (std::size_t v = 0; v < nv; ++v) {
      if (cluster[v] != kInvalidIndex) out.output_vertex[v] = vertex_id[cluster[v]];
    }
  }
  o.wedge_vertex.resize(ow);
  for (std::size_t i = 0; i < ow; ++i) o.wedge_vertex[i] = vertex_id[classes[out_wedge_class[i]].cluster];

  // Per-vertex data: skin blended over the cluster's vertices, painted priority the largest.
  const bool skinned = m.skin.size() == nv, prioritised = m.priority.size() == nv;
  if (skinned || prioritised) {
    std::vector<std::vector<std::uint32_t>> verts(ov);
    for (std::uint32_t v = 0; v < nv; ++v) {
      if (cluster[v] != kInvalidIndex && vertex_id[cluster[v]] != kInvalidIndex) verts[vertex_id[cluster[v]]].push_back(v);
    }
    if (skinned) {
      o.skin.resize(ov);
      parallel.for_ranges(ov, 256, [&](std::size_t b, std::size_t e) {
        for (std::size_t i = b; i < e; ++i) blend_skin(m, verts[i], o.skin[i]);
      });
    }
    if (prioritised) {
      o.priority.assign(ov, 0.0f);
      for (std::size_t i = 0; i < ov; ++i) {
        for (std::uint32_t v : verts[i]) o.priority[i] = std::max(o.priority[i], m.priority[v]);
      }
    }
  }

  // Per-wedge attributes: the mean over the class's corners (normals and tangents renormalised), or with
  // `keep` the values of the member nearest the cluster's vertex; custom attributes from one member.
  const bool keep = options.attribute_placement == AttributePlacement::keep;
  auto source_of = [&](std::uint32_t cls) {
    return keep ? classes[cls].nearest_wedge : classes[cls].first_wedge;
  };
  if (p.has_attributes) {
    // Corner lists per output wedge, in input order, for the means.
    std::vector<std::uint32_t> start(ow + 1, 0), list;
    for (std::size_t t = 0; t < p.triangles; ++t) {
      for (int k = 0; k < 3; ++k) {
        const std::uint32_t id = wedge_id[corner_class[3 * t + static_cast<std::size_t>(k)]];
        if (id != kInvalidIndex) ++start[id + 1];
      }
    }
    for (std::size_t i = 0; i < ow; ++i) start[i + 1] += start[i];
    list.resize(start[ow]);
    {
      std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
      for (std::size_t t = 0; t < p.triangles; ++t) {
        const std::uint32_t c = m.face_offsets[p.tri_face[t]];
        for (std::uint32_t k = 0; k < 3; ++k) {
          const std::uint32_t id = wedge_id[corner_class[3 * t + k]];
          if (id != kInvalidIndex) list[fill[id]++] = m.corner_wedge[c + k];
        }
      }
    }
    auto mean_of = [&](auto get, auto zero, std::size_t i) {
      auto acc = zero;
      for (std::uint32_t j = start[i]; j < start[i + 1]; ++j) acc = acc + get(list[j]);
      return acc * (1.0 / std::max<std::uint32_t>(1, start[i + 1] - start[i]));
    };
    auto per_wedge = [&](auto& dst, const auto& src, auto average) {
      if (src.size() != nw) return;
      dst.resize(ow);
      parallel.for_ranges(ow, 1024, [&](std::size_t b, std::size_t e) {
        for (std::size_t i = b; i < e; ++i) {
          dst[i] = keep ? src[source_of(out_wedge_class[i])] : average(src, i);
        }
      });
    };
    per_wedge(o.normals, m.normals, [&](const std::vector<Vec3f>& src, std::size_t i) {
      Vec3d n = mean_of([&](std::uint32_t w) { return to_double(src[w]); }, Vec3d{}, i);
      const double l = length(n);
      return l > 0.0 ? to_float(n * (1.0 / l)) : src[list[start[i]]];
    });
    per_wedge(o.tangents, m.tangents, [&](const std::vector<Vec4f>& src, std::size_t i) {
      Vec3d t = mean_of([&](std::uint32_t w) { return Vec3d{{src[w][0], src[w][1], src[w][2]}}; }, Vec3d{}, i);
      double hand = 0.0;
      for (std::uint32_t j = start[i]; j < start[i + 1]; ++j) hand += src[list[j]][3];
      const double l = length(t);
      if (!(l > 0.0)) return src[list[start[i]]];
      return Vec4f{{static_cast<float>(t[0] / l), static_cast<float>(t[1] / l), static_cast<float>(t[2] / l),
                    hand < 0.0 ? -1.0f : 1.0f}};
    });
    o.uvs.resize(m.uvs.size());
    for (std::size_t s = 0; s < m.uvs.size(); ++s) {
      per_wedge(o.uvs[s], m.uvs[s], [&](const std::vector<Vec2f>& src, std::size_t i) {
        const Vec<double, 2> uv = mean_of([&](std::uint32_t w) { return Vec<double, 2>{{src[w][0], src[w][1]}}; },
                                          Vec<double, 2>{}, i);
        return Vec2f{{static_cast<float>(uv[0]), static_cast<float>(uv[1])}};
      });
    }
    o.colors.resize(m.colors.size());
    o.color_components = m.color_components;
    for (std::size_t s = 0; s < m.colors.size(); ++s) {
      per_wedge(o.colors[s], m.colors[s], [&](const std::vector<Vec4f>& src, std::size_t i) {
        const Vec<double, 4> c = mean_of(
            [&](std::uint32_t w) { return Vec<double, 4>{{src[w][0], src[w][1], src[w][2], src[w][3]}}; },
            Vec<double, 4>{}, i);
        return Vec4f{{static_cast<float>(c[0]), static_cast<float>(c[1]), static_cast<float>(c[2]),
                      static_cast<float>(c[3])}};
      });
    }
    o.custom = m.custom;
    for (CustomAttribute& ca : o.custom) {
      const auto k = static_cast<std::size_t>(std::max(ca.components, 0));
      const std::vector<float> src = std::move(ca.values);
      ca.values.assign(ow * k, 0.0f);
      if (src.size() != nw * k) continue;
      for (std::size_t i = 0; i < ow; ++i) {
        const std::uint32_t w = source_of(out_wedge_class[i]);
        std::copy_n(src.begin() + static_cast<std::ptrdiff_t>(w * k), k, ca.values.begin() + static_cast<std::ptrdiff_t>(i * k));
      }
    }
    o.morph_targets.resize(m.morph_targets.size());
    for (std::size_t t = 0; t < m.morph_targets.size(); ++t) {
      const MorphTarget& src = m.morph_targets[t];
      MorphTarget& dst = o.morph_targets[t];
      dst.name = src.name;
      auto average = [&](const std::vector<Vec3f>& s, std::size_t i) {
        return to_float(mean_of([&](std::uint32_t w) { return to_double(s[w]); }, Vec3d{}, i));
      };
      per_wedge(dst.position_deltas, src.position_deltas, average);
      per_wedge(dst.normal_deltas, src.normal_deltas, average);
      per_wedge(dst.tangent_deltas, src.tangent_deltas, average);
    }
    if (!keep) recompute_tangents(o);
  } else {
    o.uvs.resize(m.uvs.size());
    o.colors.resize(m.colors.size());
    o.color_components = m.color_components;
  }
  return out;
}

Built build(const Prepared& p, const Grid& grid, const SimplifyOptions& options, Parallel& parallel) {
  Clustering cl;
  assign_clusters(p, grid, parallel, false, cl);
  place(p, grid, options, parallel, cl);
  select_faces(p, cl, false, nullptr, parallel, cl.kept);
  return emit(p, options, parallel, cl, false);
}

// Clusters whose output vertex is not a manifold one (several fans, an edge of three or more faces, an
// inconsistently oriented edge), judged on the kept triangles `kept` with clusters as vertices. Only clusters
// with all their kept faces in `kept` are judged right.
std::vector<std::uint8_t> irregular_clusters(const Clustering& cl, const Prepared& p,
                                             const std::vector<std::uint32_t>& kept) {
  Mesh faces;
  faces.positions.resize(cl.count);
  faces.wedge_vertex.resize(cl.count);
  for (std::uint32_t c = 0; c < cl.count; ++c) faces.wedge_vertex[c] = c;
  faces.corner_wedge.reserve(3 * kept.size());
  faces.face_offsets.reserve(kept.size() + 1);
  faces.face_offsets.push_back(0);
  for (std::uint32_t t : kept) {
    for (int k = 0; k < 3; ++k) faces.corner_wedge.push_back(cl.cluster[p.tri[3 * t + static_cast<std::size_t>(k)]]);
    faces.face_offsets.push_back(static_cast<std::uint32_t>(faces.corner_wedge.size()));
  }
  const Topology topo = build_topology(faces);
  return irregular_vertices(faces, topo);
}

// A stage's build, made a manifold where the input is one: the members of every cluster whose vertex is not
// are set apart, each its own cluster at its own exact position (its class locked), and the faces around
// them selected again, until no such cluster has more than one member. The clusters and faces elsewhere do
// not change (a face's fate depends only on its own clusters), so this is the same as building the grid
// again with those vertices locked, without the full passes. After the first round only the clusters of the
// faces selected again can have changed, and only their faces are checked. Each round sets apart at least one
// more vertex; on inputs that are far from manifold themselves the rounds stop after kMaxManifoldRounds, and
// the engine after the stage locks what is left, as it would in the input.
Built build_stage(Prepared& p, const Grid& grid, const SimplifyOptions& options, Parallel& parallel,
                  std::size_t& rounds) {
  const Mesh& m = p.mesh;
  Clustering cl;
  assign_clusters(p, grid, parallel, true, cl);
  place(p, grid, options, parallel, cl);
  select_faces(p, cl, true, nullptr, parallel, cl.kept);
  std::vector<char> suspect;  // clusters to judge (empty: all)
  for (int round = 0; round < kMaxManifoldRounds && !options.stop.requested() && !cl.kept.empty(); ++round) {
    std::vector<std::uint32_t> near;  // the kept faces around the suspects
    if (!suspect.empty()) {
      for (std::uint32_t t : cl.kept) {
        if (suspect[cl.cluster[p.tri[3 * t]]] || suspect[cl.cluster[p.tri[3 * t + 1]]] ||
            suspect[cl.cluster[p.tri[3 * t + 2]]]) {
          near.push_back(t);
        }
      }
    }
    const std::vector<std::uint8_t> irregular = irregular_clusters(cl, p, suspect.empty() ? cl.kept : near);
    std::vector<std::uint32_t> members(cl.count, 0);
    for (std::uint32_t c : cl.cluster) {
      if (c != kInvalidIndex) ++members[c];
    }
    const auto first_new = static_cast<std::uint32_t>(cl.count);
    for (std::size_t v = 0; v < cl.cluster.size(); ++v) {
      const std::uint32_t c = cl.cluster[v];
      if (c == kInvalidIndex || c >= first_new || !irregular[c] || members[c] < 2) continue;
      if (!suspect.empty() && !suspect[c]) continue;
      p.cls[v] = kLockedClassBase + static_cast<std::uint32_t>(v);
      cl.cluster[v] = static_cast<std::uint32_t>(cl.count++);
      cl.any_member.push_back(static_cast<std::uint32_t>(v));
      cl.rep.push_back(to_double(p.unit[v]));
      cl.err2.push_back(0.0);
      cl.model.push_back(m.positions[v]);
    }
    if (cl.count == first_new) break;
    p.any_class = true;
    ++rounds;
    // Faces with a corner set apart are selected again; their keys hold a new cluster, so they cannot repeat
    // (or mirror) a face elsewhere.
    auto touched = [&](std::size_t t) {
      return cl.cluster[p.tri[3 * t]] >= first_new || cl.cluster[p.tri[3 * t + 1]] >= first_new ||
             cl.cluster[p.tri[3 * t + 2]] >= first_new;
    };
    std::vector<std::uint32_t> again, kept_again;
    for (std::size_t t = 0; t < p.triangles; ++t) {
      if (touched(t)) again.push_back(static_cast<std::uint32_t>(t));
    }
    select_faces(p, cl, true, &again, parallel, kept_again);
    std::vector<std::uint32_t> kept;
    kept.reserve(cl.kept.size() + kept_again.size());
    std::size_t j = 0;
    for (std::uint32_t t : cl.kept) {
      if (touched(t)) continue;
      for (; j < kept_again.size() && kept_again[j] < t; ++j) kept.push_back(kept_again[j]);
      kept.push_back(t);
    }
    kept.insert(kept.end(), kept_again.begin() + static_cast<std::ptrdiff_t>(j), kept_again.end());
    cl.kept = std::move(kept);
    suspect.assign(cl.count, 0);
    for (std::uint32_t t : again) {
      for (int k = 0; k < 3; ++k) suspect[cl.cluster[p.tri[3 * t + static_cast<std::size_t>(k)]]] = 1;
    }
  }
  return emit(p, options, parallel, cl, true);
}

// The output of a run that leaves the input as it is (target at or above the input, or nothing holds a
// budget): its triangles with vertices and wedges unchanged.
SimplifyResult unchanged(const Mesh& tris) {
  SimplifyResult r;
  r.mesh = tris;
  r.triangles_after = tris.triangle_count();
  return r;
}

}  // namespace

SimplifyResult run_cluster(const Mesh& mesh, const SimplifyOptions& options, bool stage) {
  const auto t0 = std::chrono::steady_clock::now();
  const FaceKindCounts kinds = count_face_kinds(mesh);
  Mesh triangulated_copy;
  if (kinds.quads != 0 || kinds.polygons != 0) triangulated_copy = triangulated(mesh);
  const Mesh& tris = kinds.quads != 0 || kinds.polygons != 0 ? triangulated_copy : mesh;
  Parallel parallel(options.threads);
  Prepared p = prepare(tris, options, parallel);
  const double diagonal = p.diagonal;
  const StopRule stop = stop_rule(options, tris.triangle_count(), diagonal);
  const std::size_t target = stop.target_triangles;
  const double setup_ms = elapsed_ms(t0);

  auto finish = [&](SimplifyResult r, std::chrono::steady_clock::time_point since) {
    r.triangles_before = mesh.triangle_count();
    r.quads_before = kinds.quads;
    r.qem_error_rel = diagonal > 0.0 ? r.qem_error_abs / diagonal : 0.0;
    r.timings.setup_ms = setup_ms;
    r.timings.collapse_ms = elapsed_ms(since) - r.timings.output_ms - r.budget.ms;
    return r;
  };
  const auto t1 = std::chrono::steady_clock::now();
  if (options.stop.requested()) {
    SimplifyResult r = unchanged(tris);
    r.stop_reason = StopReason::stopped;
    return finish(std::move(r), t1);
  }
  if (target >= p.triangles) return finish(unchanged(tris), t1);

  std::size_t probes = 0;
  auto to_result = [&](Built&& b) {
    SimplifyResult r;
    r.mesh = std::move(b.mesh);
    r.triangles_after = b.triangles;
    r.qem_error_abs = std::sqrt(b.max_error2) * p.extent;
    return r;
  };

  // The target: probes count faces the build may still drop (repeats, zero area), so the target of the
  // search is raised by the share dropped until the output lands within the tolerance.
  Grid grid;
  Built best;
  {
    double aim = static_cast<double>(target);
    // A first guess from a surface's count ~ 2 × cells: a unit square gives resolution² cells.
    double start = std::sqrt(aim / (kTrianglesPerArea * std::max(p.area, 1e-12)));
    if (stage) {  // a stage's count only has to be near its aim: no correction
      const Probe found = search_grid(p, target, start, parallel, probes, options.stop);
      grid = found.grid;
      best = build_stage(p, grid, options, parallel, probes);
    } else {
      // The correction decides on the faces a grid keeps before placement (the zero-area faces it drops
      // after are rare), so only the chosen grid is placed and built.
      std::optional<Clustering> chosen;
      std::size_t chosen_count = 0;
      for (int round = 0; round <= kMaxCorrections; ++round) {
        const Probe found = search_grid(p, static_cast<std::size_t>(aim), start, parallel, probes, options.stop);
        const std::size_t raw = found.count;
        Clustering cl;
        assign_clusters(p, found.grid, parallel, false, cl);
        select_faces(p, cl, false, nullptr, parallel, cl.kept);
        const std::size_t n = cl.kept.size();
        if (round == 0 || (n <= target && n > chosen_count)) {
          grid = found.grid;
          chosen = std::move(cl);
          chosen_count = n;
        }
        if (options.stop.requested() || raw == 0 || chosen_count == 0) break;
        if (static_cast<double>(target - chosen_count) <= kBuildTolerance * static_cast<double>(target)) break;
        const double next = aim * static_cast<double>(raw) / static_cast<double>(std::max<std::size_t>(1, n));
        if (!(next > aim * (1.0 + kCountTolerance))) break;
        start = found.grid.resolution * std::sqrt(next / aim);
        aim = std::min(next, static_cast<double>(p.triangles));
      }
      chosen->kept.clear();
      place(p, grid, options, parallel, *chosen);
      select_faces(p, *chosen, false, nullptr, parallel, chosen->kept);
      best = emit(p, options, parallel, *chosen, false);
    }
  }
  if (options.stop.requested() && best.triangles == 0) {  // stopped before any LOD was built: the input
    SimplifyResult r = unchanged(tris);
    r.rounds = probes;
    r.stop_reason = StopReason::stopped;
    return finish(std::move(r), t1);
  }
  SimplifyResult r = to_result(std::move(best));
  r.rounds = probes;
  r.stop_reason = options.stop.requested() ? StopReason::stopped : StopReason::target_reached;
  if (r.stop_reason == StopReason::stopped) return finish(std::move(r), t1);

  // An error budget, by measurement per resolution: `lo` fails, `hi` holds.
  const bool has_budget = std::isfinite(stop.max_error) && stop.max_error >= 0.0;
  if (has_budget) {
    const auto tb = std::chrono::steady_clock::now();
    const Mesh& reference = options.budget_reference != nullptr ? *options.budget_reference : tris;
    const double budget = stop.max_error;
    std::optional<SurfaceIndex> local_index;  // built at the first measurement
    const SurfaceIndex* index = nullptr;
    auto measure = [&](const Mesh& output) {
      if (index == nullptr) index = &reference_index(options, reference, local_index);
      return measure_budget(output, *index, budget, options.threads);
    };
    auto holds = [&](const SimplifyResult& x, BudgetCheck& check) {
      if (options.verify_budget) {
        check = measure(x.mesh);
        return check.within;
      }
      return x.qem_error_abs <= budget;
    };
    BudgetCheck check;
    int measured = 1;
    if (!holds(r, check)) {
      double lo = std::max(grid.resolution, 1e-9), hi = kMaxResolution;
      std::optional<SimplifyResult> held;
      BudgetCheck held_check;
      while (hi / lo > kBudgetResolutionRatio && measured < kMaxBudgetMeasurements) {
        if (options.stop.requested()) break;
        const double mid = std::sqrt(lo * hi);
        SimplifyResult trial = to_result(build(p, {mid, grid.phase}, options, parallel));
        BudgetCheck c;
        ++measured;
        if (holds(trial, c)) {
          hi = mid;
          held = std::move(trial);
          held_check = c;
        } else {
          lo = mid;
        }
      }
      if (!held) {  // the finest grid: every vertex alone (nearly the input); failing that, the input itself
        SimplifyResult trial = to_result(build(p, {kMaxResolution, grid.phase}, options, parallel));
        BudgetCheck c;
        ++measured;
        if (holds(trial, c)) {
          held = std::move(trial);
          held_check = c;
        } else {
          held = unchanged(tris);
          if (options.verify_budget) held_check = measure(held->mesh);
        }
      }
      const std::size_t rounds = r.rounds;
      r = std::move(*held);
      r.rounds = rounds;
      check = held_check;
      r.stop_reason = options.stop.requested() ? StopReason::stopped : StopReason::error_budget;
    }
    if (options.verify_budget) {
      r.budget = check;
      r.budget.verified = true;
      r.budget.budget_abs = budget;
      r.budget.prefixes_measured = static_cast<std::size_t>(measured);
      r.error_bound_abs = check.bound_abs;
      r.error_bound_rel = diagonal > 0.0 ? check.bound_abs / diagonal : 0.0;
      r.budget.ms = elapsed_ms(tb);
    }
  }
  return finish(std::move(r), t1);
}

}  // namespace lodforge::collapse
