// Metro-style surface distance between two meshes.
//
// Implements:
//   - Cignoni, Rocchini & Scopigno, "Metro: measuring error on simplified surfaces" (CGF 1998): sample one
//     surface, measure each sample's distance to the other surface, both directions; one-sided max / mean /
//     RMS and the symmetric Hausdorff distance; vertices sampled separately because the maxima sit there.
//   - Area-uniform points on a triangle by folding the unit square (Turk, "Generating random points in
//     triangles", Graphics Gems 1990): u, v ~ U(0,1), (u, v) -> (1-u, 1-v) when u + v > 1.
//   - Triangle choice by inverting the cumulative area distribution with jittered (stratified) uniforms
//     (i + r_i) / N: every sample is still area-uniform, the estimate has less variance than plain Monte Carlo,
//     and the samples come out in triangle order, so consecutive queries are spatially coherent and the
//     previous answer is a good BVH hint.
//   - Exact closest points via TriangleBvh (Ericson RTCD 5.1.5), in double precision.
//
// Determinism: sample i draws its random numbers from a counter-based generator (SplitMix64 of seed,
// direction and i), samples are processed in fixed-size blocks whose partial sums are combined in block
// order, and the BVH hint restarts at each block, so the result is bit-identical for any thread count.
#include "lodforge/eval/eval.hpp"

#include <algorithm>
#include <atomic>
#include <cassert>
#include <cmath>
#include <numbers>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <tbb/info.h>
#include <tbb/task_arena.h>

#include "lodforge/eval/bvh.hpp"

namespace lodforge {
namespace {

// Samples per parallel task. Fixed (not derived from the thread count) so the partial sums, and therefore
// the rounding of the totals, are the same for every thread count; large enough to amortise task overhead.
constexpr std::size_t kBlockSize = 4096;
constexpr std::uint64_t kGolden = 0x9E3779B97F4A7C15ull;  // SplitMix64 increment
constexpr double kDegreesPerRadian = 180.0 / std::numbers::pi;

// SplitMix64 output function (Steele, Lea & Flood 2014): a good 64-bit mix of a counter.
std::uint64_t mix64(std::uint64_t x) {
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

// Uniform in [0, 1) with 53 random bits.
double unit_double(std::uint64_t x) { return static_cast<double>(x >> 11) * 0x1.0p-53; }

bool is_finite(const Vec3d& p) { return std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]); }

// One mesh prepared for sampling and for being queried (its BVH built).
struct Surface {
  std::vector<Vec3d> positions;
  std::vector<std::uint32_t> indices;   // three per triangle, as triangulated() makes them
  std::vector<Vec3d> normals;           // unit face normal per triangle; zero when it has no area
  std::vector<double> area_prefix;      // triangles + 1 running sums of triangle areas
  std::uint32_t last_with_area = kInvalidIndex;
  std::vector<std::uint32_t> vertices;  // used by a triangle and finite, ascending
  TriangleBvh bvh;

  std::size_t triangle_count() const { return indices.size() / 3; }
  double total_area() const { return area_prefix.back(); }
  Vec3d corner(std::size_t t, int k) const { return positions[indices[3 * t + static_cast<std::size_t>(k)]]; }
};

Surface make_surface(const Mesh& mesh) {
  Surface s;
  s.positions.reserve(mesh.vertex_count());
  for (const Vec3f& p : mesh.positions) s.positions.push_back(to_double(p));
  s.indices = triangle_vertex_indices(mesh);

  const std::size_t triangles = s.triangle_count();
  s.normals.assign(triangles, Vec3d{});
  s.area_prefix.assign(triangles + 1, 0.0);
  std::vector<char> used(s.positions.size(), 0);
  for (std::size_t t = 0; t < triangles; ++t) {
    const Vec3d a = s.corner(t, 0), b = s.corner(t, 1), c = s.corner(t, 2);
    double area = 0;
    if (is_finite(a) && is_finite(b) && is_finite(c)) {
      for (int k = 0; k < 3; ++k) used[s.indices[3 * t + static_cast<std::size_t>(k)]] = 1;
      const Vec3d n = cross(b - a, c - a);
      const double len = length(n);
      // Non-finite (overflowing) or zero areas are not sampled: zero-width CDF intervals are never chosen.
      if (len > 0 && std::isfinite(len)) {
        area = 0.5 * len;
        s.normals[t] = n * (1.0 / len);
        s.last_with_area = static_cast<std::uint32_t>(t);
      }
    }
    s.area_prefix[t + 1] = s.area_prefix[t] + area;
  }
  for (std::size_t v = 0; v < used.size(); ++v) {
    if (used[v]) s.vertices.push_back(static_cast<std::uint32_t>(v));
  }
  s.bvh = TriangleBvh(s.positions, s.indices);
  return s;
}

struct Sample {
  Vec3d point;
  std::uint32_t triangle;
};

// Area sample i of n. Only call when the surface has area.
Sample area_sample(const Surface& s, std::uint64_t stream, std::size_t i, std::size_t n) {
  const std::uint64_t counter = stream + 3 * static_cast<std::uint64_t>(i) * kGolden;
  const double jitter = unit_double(mix64(counter + kGolden));
  double u = unit_double(mix64(counter + 2 * kGolden));
  double v = unit_double(mix64(counter + 3 * kGolden));

  // Stratum i of the cumulative area: the triangle t with prefix[t] <= x < prefix[t + 1].
  const double x = (static_cast<double>(i) + jitter) / static_cast<double>(n) * s.total_area();
  const auto it = std::upper_bound(s.area_prefix.begin(), s.area_prefix.end(), x);
  auto t = static_cast<std::uint32_t>(std::max<std::ptrdiff_t>(it - s.area_prefix.begin() - 1, 0));
  // Rounding can put x at (or past) the total, landing on a trailing zero-area triangle.
  if (t > s.last_with_area || s.area_prefix[t + 1] <= s.area_prefix[t]) t = s.last_with_area;

  if (u + v > 1) {
    u = 1 - u;
    v = 1 - v;
  }
  const Vec3d a = s.corner(t, 0), b = s.corner(t, 1), c = s.corner(t, 2);
  return {a + (b - a) * u + (c - a) * v, t};
}

// Angle between two unit normals in degrees, accurate near 0 and 180 (unlike acos of the dot product).
double angle_deg(const Vec3d& a, const Vec3d& b) {
  return std::atan2(length(cross(a, b)), dot(a, b)) * kDegreesPerRadian;
}

// Nearest-rank percentile (q in (0, 1]) of the values; reorders them.
double percentile(std::vector<double>& values, double q) {
  if (values.empty()) return 0.0;
  const auto rank = static_cast<std::size_t>(std::ceil(q * static_cast<double>(values.size())));
  const std::size_t k = std::clamp<std::size_t>(rank, 1, values.size()) - 1;
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
  return values[k];
}

struct BlockSums {
  double sum = 0, sum_sq = 0, max = 0;
  double angle_sum = 0;
  std::size_t angle_count = 0;
  BvhWork work;
};

// One direction's raw material: sums for pooling, per-sample values for percentiles.
struct Direction {
  OneSided stats;
  double sum = 0, sum_sq = 0;  // of the samples behind stats.mean / stats.rms
  std::size_t count = 0;
  double angle_sum = 0;
  std::vector<double> angles;  // valid normal deviations, in sample order
  BvhWork work;
};

Direction measure(const Surface& from, const Surface& to, std::size_t area_samples, std::uint64_t stream,
                  bool include_vertices, const StopRequest& stop, std::atomic<bool>& stopped) {
  Direction out;
  const std::size_t n = from.last_with_area == kInvalidIndex ? 0 : area_samples;
  const std::size_t nv = include_vertices ? from.vertices.size() : 0;
  out.stats.samples = n;
  out.stats.vertex_samples = nv;
  if (n == 0 && nv == 0) return out;
  if (to.bvh.empty()) {
    // Distance to an empty set: +infinity by convention, so a mesh that lost all its triangles never looks
    // perfect.
    out.stats.max = out.stats.mean = out.stats.rms = out.stats.p99 = out.stats.p999 = INFINITY;
    out.sum = out.sum_sq = INFINITY;
    out.count = n > 0 ? n : nv;
    return out;
  }

  const std::size_t vertex_blocks = (nv + kBlockSize - 1) / kBlockSize;
  const std::size_t area_blocks = (n + kBlockSize - 1) / kBlockSize;
  std::vector<BlockSums> vertex_sums(vertex_blocks), area_sums(area_blocks);
  std::vector<double> distances(n);
  std::vector<double> angles(n, -1.0);  // -1: closest triangle has no normal

  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, vertex_blocks + area_blocks, 1),
                    [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t block = range.begin(); block != range.end(); ++block) {
      if (stopped.load(std::memory_order_relaxed)) return;
      if (stop.requested()) {
        stopped = true;
        return;
      }
      std::uint32_t hint = kInvalidIndex;  // restarts per block: results must not depend on task grouping
      if (block < vertex_blocks) {
        BlockSums& sums = vertex_sums[block];
        const std::size_t end = std::min(nv, (block + 1) * kBlockSize);
        for (std::size_t i = block * kBlockSize; i < end; ++i) {
          const BvhHit hit = to.bvh.closest_point(from.positions[from.vertices[i]], hint, sums.work);
          assert(hit.found());  // finite point, non-empty tree
          hint = hit.triangle;
          const double d = std::sqrt(hit.distance_sq);
          sums.sum += d;
          sums.sum_sq += hit.distance_sq;
          sums.max = std::max(sums.max, d);
        }
        continue;
      }
      const std::size_t ab = block - vertex_blocks;
      BlockSums& sums = area_sums[ab];
      const std::size_t end = std::min(n, (ab + 1) * kBlockSize);
      for (std::size_t i = ab * kBlockSize; i < end; ++i) {
        const Sample s = area_sample(from, stream, i, n);
        const BvhHit hit = to.bvh.closest_point(s.point, hint, sums.work);
        assert(hit.found());
        hint = hit.triangle;
        const double d = std::sqrt(hit.distance_sq);
        distances[i] = d;
        sums.sum += d;
        sums.sum_sq += hit.distance_sq;
        sums.max = std::max(sums.max, d);
        const Vec3d& target_normal = to.normals[hit.triangle];
        if (dot(target_normal, target_normal) > 0) {
          angles[i] = angle_deg(from.normals[s.triangle], target_normal);
          sums.angle_sum += angles[i];
          ++sums.angle_count;
        }
      }
    }
  });

  // Combine in block order: the same additions in the same order for any thread count.
  BlockSums vertex_total, area_total;
  for (const BlockSums& b : vertex_sums) {
    vertex_total.sum += b.sum;
    vertex_total.sum_sq += b.sum_sq;
    vertex_total.max = std::max(vertex_total.max, b.max);
    out.work += b.work;
  }
  for (const BlockSums& b : area_sums) {
    area_total.sum += b.sum;
    area_total.sum_sq += b.sum_sq;
    area_total.max = std::max(area_total.max, b.max);
    area_total.angle_sum += b.angle_sum;
    area_total.angle_count += b.angle_count;
    out.work += b.work;
  }

  out.stats.max = std::max(vertex_total.max, area_total.max);
  // Vertices are not area-uniform, so they enter mean and RMS only when there is no area to sample.
  const BlockSums& pooled = n > 0 ? area_total : vertex_total;
  out.count = n > 0 ? n : nv;
  out.sum = pooled.sum;
  out.sum_sq = pooled.sum_sq;
  out.stats.mean = out.sum / static_cast<double>(out.count);
  out.stats.rms = std::sqrt(out.sum_sq / static_cast<double>(out.count));
  out.stats.p99 = percentile(distances, 0.99);
  out.stats.p999 = percentile(distances, 0.999);

  out.angle_sum = area_total.angle_sum;
  out.angles.reserve(area_total.angle_count);
  for (const double a : angles) {
    if (a >= 0) out.angles.push_back(a);
  }
  if (!out.angles.empty()) {
    out.stats.normal_deviation_mean_deg = out.angle_sum / static_cast<double>(out.angles.size());
    std::vector<double> scratch = out.angles;
    out.stats.normal_deviation_p95_deg = percentile(scratch, 0.95);
  }
  return out;
}

// Both directions between prepared surfaces; `diagonal` is the original's.
EvalResult evaluate_surfaces(const Surface& a, double diagonal, const Surface& b, const EvalOptions& options) {
  const std::size_t samples = options.samples > 0
                                  ? options.samples
                                  : default_eval_samples(std::max(a.triangle_count(), b.triangle_count()));
  // Independent random streams per direction.
  const std::uint64_t base = mix64(options.seed);
  std::atomic<bool> stopped = false;
  const Direction ab = measure(a, b, samples, mix64(base ^ 0xA), options.include_vertices, options.stop, stopped);
  const Direction ba = measure(b, a, samples, mix64(base ^ 0xB), options.include_vertices, options.stop, stopped);

  EvalResult r;
  r.stopped = stopped;
  r.a_to_b = ab.stats;
  r.b_to_a = ba.stats;
  r.hausdorff = std::max(ab.stats.max, ba.stats.max);
  if (const std::size_t count = ab.count + ba.count; count > 0) {
    r.mean = (ab.sum + ba.sum) / static_cast<double>(count);
    r.rms = std::sqrt((ab.sum_sq + ba.sum_sq) / static_cast<double>(count));
  }
  r.diagonal = diagonal;
  r.work = ab.work;
  r.work += ba.work;

  if (const std::size_t count = ab.angles.size() + ba.angles.size(); count > 0) {
    r.normal_deviation_mean_deg = (ab.angle_sum + ba.angle_sum) / static_cast<double>(count);
    std::vector<double> all = ab.angles;
    all.insert(all.end(), ba.angles.begin(), ba.angles.end());
    r.normal_deviation_p95_deg = percentile(all, 0.95);
  }

  if (a.bvh.empty() && b.bvh.empty()) {
    r.note = "neither mesh has triangles";
  } else if (b.bvh.empty()) {
    r.note = "the simplified mesh has no triangles: distances to it are infinite";
  } else if (a.bvh.empty()) {
    r.note = "the original mesh has no triangles: distances to it are infinite";
  }
  return r;
}

EvalResult evaluate_in_arena(const Mesh& original, const Mesh& simplified, const EvalOptions& options) {
  Surface a, b;
  tbb::parallel_invoke([&] { a = make_surface(original); }, [&] { b = make_surface(simplified); });
  return evaluate_surfaces(a, compute_bounds(original).diagonal(), b, options);
}

// A private arena so `threads` caps this call only, without touching global TBB state. More threads than
// cores would only make TBB warn; the result does not depend on the count anyway.
tbb::task_arena eval_arena(unsigned requested) {
  const int cores = tbb::info::default_concurrency();
  return tbb::task_arena(requested == 0 ? cores : std::min(static_cast<int>(requested), cores));
}

}  // namespace

struct EvalReference::Prepared {
  Surface surface;
  double diagonal = 0;
};

EvalReference::EvalReference(const Mesh& original, unsigned threads) : prepared_(std::make_unique<Prepared>()) {
  tbb::task_arena arena = eval_arena(threads);
  arena.execute([&] { prepared_->surface = make_surface(original); });
  prepared_->diagonal = compute_bounds(original).diagonal();
}

EvalReference::~EvalReference() = default;
EvalReference::EvalReference(EvalReference&&) noexcept = default;
EvalReference& EvalReference::operator=(EvalReference&&) noexcept = default;

EvalResult evaluate(const EvalReference& original, const Mesh& simplified, const EvalOptions& options) {
  tbb::task_arena arena = eval_arena(options.threads);
  return arena.execute([&] {
    return evaluate_surfaces(original.prepared().surface, original.prepared().diagonal, make_surface(simplified),
                             options);
  });
}

std::size_t default_eval_samples(std::size_t larger_triangle_count) {
  // Metro's default is 10 x the face count: about 1.1 s for two 100k-triangle meshes on 2 cores (queries
  // cost ~1 us each on one core). 4 x keeps that near half a second; the floor keeps small meshes from being
  // undersampled, where queries are cheap anyway.
  constexpr std::size_t kPerTriangle = 4, kMinimum = 200000;
  return std::max(kPerTriangle * larger_triangle_count, kMinimum);
}

EvalResult evaluate(const Mesh& original, const Mesh& simplified, const EvalOptions& options) {
  tbb::task_arena arena = eval_arena(options.threads);
  return arena.execute([&] { return evaluate_in_arena(original, simplified, options); });
}

}  // namespace lodforge
