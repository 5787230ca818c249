// Surface fitting of moved vertices (see surface_fit.hpp): closest points through eval's triangle BVH (queries
// in parallel, each answer written to its own slot), a least-squares solve whose sums run in a fixed order (so
// the result does not depend on the thread count), then steps checked against face turning.
#include "lodforge/quad/surface_fit.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <tuple>
#include <vector>

#include <tbb/parallel_for.h>

#include "lodforge/eval/bvh.hpp"

namespace lodforge::quad {
namespace {

// The triangles face f is drawn as (core/mesh.hpp triangulation_start: a quad along its shorter diagonal, the
// one through corner 0 on a tie), as corner numbers.
template <class Emit>
void face_triangles(const QuadMesh& m, std::uint32_t f, Emit&& emit) {
  const std::uint32_t n = m.face_size(f);
  const std::uint32_t s = n != 4 ? 0
                                  : quad_triangulation_start(m.position(m.face_vertex(f, 0)), m.position(m.face_vertex(f, 1)),
                                                             m.position(m.face_vertex(f, 2)), m.position(m.face_vertex(f, 3)));
  for (std::uint32_t i = 1; i + 1 < n; ++i) emit(s, (s + i) % n, (s + i + 1) % n);
}

// Face f's Newell normal and, for a quad, the normal of each corner's triangle (a quad may fold along either
// diagonal while its Newell normal stays put).
std::array<Vec3d, 5> face_normals(const QuadMesh& m, std::uint32_t f) {
  std::array<Vec3d, 5> out{};
  out[0] = m.face_normal(f);
  if (m.face_size(f) != 4) return out;
  for (std::uint32_t i = 0; i < 4; ++i) {
    const Vec3d& p = m.position(m.face_vertex(f, i));
    out[i + 1] = cross(m.position(m.face_vertex(f, (i + 1) % 4)) - p, m.position(m.face_vertex(f, (i + 3) % 4)) - p);
  }
  return out;
}

// Whether no normal turned by more than the angle of cosine cos_max (zero normals, degenerate before, aside).
bool turned_within(const std::array<Vec3d, 5>& before, const std::array<Vec3d, 5>& now, double cos_max) {
  for (std::size_t i = 0; i < before.size(); ++i) {
    const double lb = length(before[i]);
    if (!(lb > 0.0)) continue;
    if (dot(before[i], now[i]) < cos_max * lb * length(now[i])) return false;
  }
  return true;
}

// An edge of the simplified surface (lo < hi) with a movable end, sampled at its midpoint for the area it
// stands for: a third of each triangle it borders. Midpoints see where an edge cuts under (or over) a
// curved input, which is what the fit corrects. Measured on nine quad corpus meshes at 50/25/10%: with each
// triangle's centroid and the moved vertices as samples instead (about as many queries) the LODs came out up
// to 7% farther; with four samples per triangle (2.7 times the queries) about as close.
struct SampledEdge {
  std::uint32_t lo = 0, hi = 0, triangle = 0;
  double area = 0.0;
};

// One least-squares term: weight * |sum_k w[k] x[unknown[k]] - target|^2, over the corners that are unknowns
// (kInvalidIndex: a fixed corner, already taken out of `target`). A zero weight is no term.
struct Observation {
  std::array<std::uint32_t, 3> unknown{kInvalidIndex, kInvalidIndex, kInvalidIndex};
  Vec3d w{};
  Vec3d target{};
  double weight = 0.0;
};

// Minimises the sum of the observations' terms plus sum_k lambda_k |x_k - start_k|^2, where lambda_k is
// `regularisation` times the k-th diagonal entry of the terms' normal matrix: a vertex the observations
// hardly pin (sliding along a flat region) stays near where it was. Conjugate gradients on the normal
// equations, matrix-free, with the diagonal as preconditioner, from `start`; sums run in observation order,
// so the answer is the same on any number of threads.
class LeastSquares {
 public:
  std::vector<Vec3d> solve(const std::vector<Observation>& observations, const std::vector<Vec3d>& start,
                           double regularisation) {
    const std::size_t n = start.size();
    diagonal_.assign(n, 0.0);
    b_.assign(n, Vec3d{});
    for (const Observation& o : observations) {
      for (std::size_t i = 0; i < 3; ++i) {
        if (o.unknown[i] == kInvalidIndex) continue;
        diagonal_[o.unknown[i]] += o.weight * o.w[i] * o.w[i];
        b_[o.unknown[i]] = b_[o.unknown[i]] + o.target * (o.weight * o.w[i]);
      }
    }
    lambda_.resize(n);
    for (std::size_t k = 0; k < n; ++k) {
      lambda_[k] = diagonal_[k] > 0.0 ? regularisation * diagonal_[k] : 1.0;
      diagonal_[k] += lambda_[k];
      b_[k] = b_[k] + start[k] * lambda_[k];
    }
    std::vector<Vec3d> x = start;
    multiply(observations, x, product_);
    r_.resize(n);
    z_.resize(n);
    for (std::size_t k = 0; k < n; ++k) {
      r_[k] = b_[k] - product_[k];
      z_[k] = r_[k] * (1.0 / diagonal_[k]);
    }
    p_ = z_;
    double rz = inner(r_, z_);
    const double stop = kTolerance * kTolerance * inner(r_, r_);
    for (int it = 0; it < kMaxIterations && inner(r_, r_) > stop && rz > 0.0; ++it) {
      multiply(observations, p_, product_);
      const double curvature = inner(p_, product_);
      if (!(curvature > 0.0)) break;
      const double alpha = rz / curvature;
      for (std::size_t k = 0; k < n; ++k) {
        x[k] = x[k] + p_[k] * alpha;
        r_[k] = r_[k] - product_[k] * alpha;
        z_[k] = r_[k] * (1.0 / diagonal_[k]);
      }
      const double next = inner(r_, z_);
      const double beta = next / rz;
      rz = next;
      for (std::size_t k = 0; k < n; ++k) p_[k] = z_[k] + p_[k] * beta;
    }
    return x;
  }

 private:
  // Stop when the residual has shrunk by this factor, or after this many iterations.
  static constexpr double kTolerance = 1e-3;
  static constexpr int kMaxIterations = 60;

  static double inner(const std::vector<Vec3d>& a, const std::vector<Vec3d>& b) {
    double sum = 0.0;
    for (std::size_t k = 0; k < a.size(); ++k) sum += dot(a[k], b[k]);
    return sum;
  }
  // out = (A^T W A + Lambda) x.
  void multiply(const std::vector<Observation>& observations, const std::vector<Vec3d>& x, std::vector<Vec3d>& out) {
    out.resize(x.size());
    for (std::size_t k = 0; k < x.size(); ++k) out[k] = x[k] * lambda_[k];
    for (const Observation& o : observations) {
      Vec3d at{};
      for (std::size_t i = 0; i < 3; ++i) {
        if (o.unknown[i] != kInvalidIndex) at = at + x[o.unknown[i]] * o.w[i];
      }
      for (std::size_t i = 0; i < 3; ++i) {
        if (o.unknown[i] != kInvalidIndex) out[o.unknown[i]] = out[o.unknown[i]] + at * (o.weight * o.w[i]);
      }
    }
  }

  std::vector<double> diagonal_, lambda_;
  std::vector<Vec3d> b_, product_, r_, z_, p_;
};

}  // namespace

// A step shorter than this fraction of the vertex's shortest edge is not taken.
constexpr double kNegligibleStep = 1e-6;
// Closest-point queries per task (see refit_to_surface).
constexpr std::size_t kChunk = 64;
// The fit stops early when fewer than one vertex in kConvergedShare stepped by at least kConvergedStep of its
// shortest edge. On the bench's 100k-quad torus the first step moves 410 of 24.7k vertices that far, the
// second none: two steps. Of the 27 LODs of the nine corpus meshes above, 25 get all eight.
constexpr double kConvergedStep = 0.01;
constexpr std::size_t kConvergedShare = 50;

TriangleBvh input_surface_bvh(const Mesh& input) {
  std::vector<Vec3d> positions;
  positions.reserve(input.vertex_count());
  for (const Vec3f& p : input.positions) positions.push_back(to_double(p));
  std::vector<std::uint32_t> indices;
  for (std::size_t f = 0; f < input.face_count(); ++f) {
    if (!face_indices_in_range(input, f)) continue;  // not surface (QuadMesh drops it too)
    for_each_face_triangle(input, f, [&](std::uint32_t c0, std::uint32_t c1, std::uint32_t c2) {
      for (std::uint32_t c : {c0, c1, c2}) indices.push_back(input.corner_vertex(c));
    });
  }
  return TriangleBvh(positions, indices);
}

std::size_t refit_to_surface(QuadMesh& mesh, const Mesh& input, const TriangleBvh& input_bvh,
                             const SurfaceFitOptions& options) {
  if (input_bvh.empty()) return 0;
  // The input's vertices are the points sampled on it.
  std::vector<Vec3d> input_samples;
  input_samples.reserve(input.vertex_count());
  for (const Vec3f& p : input.positions) input_samples.push_back(to_double(p));
  // Each stands for a third of the area of every input triangle it is a corner of.
  std::vector<double> input_area(input_samples.size(), 0.0);
  for (std::size_t f = 0; f < input.face_count(); ++f) {
    if (!face_indices_in_range(input, f)) continue;
    for_each_face_triangle(input, f, [&](std::uint32_t c0, std::uint32_t c1, std::uint32_t c2) {
      const std::uint32_t a = input.corner_vertex(c0), b = input.corner_vertex(c1), c = input.corner_vertex(c2);
      const double third = length(cross(input_samples[b] - input_samples[a], input_samples[c] - input_samples[a])) / 6.0;
      if (!std::isfinite(third)) return;  // a non-finite corner: not surface (the BVH leaves it out too)
      for (std::uint32_t v : {a, b, c}) input_area[v] += third;
    });
  }

  const std::size_t nv = mesh.vertex_count();
  // Boundary vertices stay: their collapses kept them on the boundary line (border quadrics), which a step
  // towards the surface would bend.
  std::vector<std::uint8_t> movable(nv, 0);
  std::vector<std::uint32_t> order;
  for (std::uint32_t v = 0; v < nv; ++v) {
    if (mesh.vertex_alive(v) && mesh.moved(v) && !mesh.locked(v) && !mesh.vertex_faces(v).empty() &&
        !mesh.on_boundary(v)) {
      movable[v] = 1;
      order.push_back(v);
    }
  }
  if (order.empty()) return 0;
  const double cos_max = std::cos(options.max_turn_deg * std::numbers::pi / 180.0);
  std::vector<std::uint32_t> unknown(nv, kInvalidIndex);
  for (std::uint32_t k = 0; k < order.size(); ++k) unknown[order[k]] = k;
  const std::size_t n = order.size();

  std::size_t steps = 0;
  // Buffers kept across steps (large ones freed and allocated again cost page faults every step).
  std::vector<std::array<std::uint32_t, 3>> triangles;  // the simplified surface now, as vertex triples
  std::vector<double> triangle_area;
  std::vector<Vec3d> positions(nv), start(n);  // start: the moved vertices' positions before the step
  std::vector<std::uint32_t> indices;
  std::vector<SampledEdge> edges;
  // The last step's answers: the edges and triangles keep their numbers from step to step (unless a quad's
  // shorter diagonal changed), so each is a close first guess for the next step's query.
  std::vector<std::uint32_t> edge_hint, input_hint(input_samples.size(), kInvalidIndex);
  std::vector<Observation> observations;
  std::vector<std::array<Vec3d, 5>> before;  // normals of one vertex's faces before its step
  LeastSquares system;
  for (int it = 0; it < options.iterations; ++it) {
    triangles.clear();
    triangle_area.clear();
    for (std::uint32_t v = 0; v < nv; ++v) {
      if (mesh.vertex_alive(v)) positions[v] = mesh.position(v);
    }
    for (std::uint32_t f = 0; f < mesh.face_slots(); ++f) {
      if (!mesh.face_alive(f)) continue;
      face_triangles(mesh, f, [&](std::uint32_t i0, std::uint32_t i1, std::uint32_t i2) {
        const std::array<std::uint32_t, 3> t{mesh.face_vertex(f, i0), mesh.face_vertex(f, i1), mesh.face_vertex(f, i2)};
        triangles.push_back(t);
        const double area = 0.5 * length(cross(positions[t[1]] - positions[t[0]], positions[t[2]] - positions[t[0]]));
        triangle_area.push_back(std::isfinite(area) ? area : 0.0);  // a non-finite (locked) corner: no samples
      });
    }
    // Edges with a movable end, once each (sorted by ends, then triangle: sums in a fixed order).
    edges.clear();
    for (std::uint32_t t = 0; t < triangles.size(); ++t) {
      const auto& v = triangles[t];
      for (std::size_t k = 0; k < 3; ++k) {
        const std::uint32_t a = v[k], b = v[(k + 1) % 3];
        if (movable[a] || movable[b]) edges.push_back({std::min(a, b), std::max(a, b), t, triangle_area[t] / 3.0});
      }
    }
    std::sort(edges.begin(), edges.end(), [](const SampledEdge& x, const SampledEdge& y) {
      return std::tie(x.lo, x.hi, x.triangle) < std::tie(y.lo, y.hi, y.triangle);
    });
    std::size_t kept = 0;
    for (std::size_t i = 0; i < edges.size(); ++i) {
      if (kept > 0 && edges[kept - 1].lo == edges[i].lo && edges[kept - 1].hi == edges[i].hi) {
        edges[kept - 1].area += edges[i].area;
      } else {
        edges[kept++] = edges[i];
      }
    }
    edges.resize(kept);
    // An observation: the point with weights w on the corners t should be at `target`, for `area` of surface.
    auto observation = [&](const std::array<std::uint32_t, 3>& t, const Vec3d& w, const Vec3d& target, double area) {
      Observation o;
      o.target = target;
      o.weight = area;
      for (std::size_t k = 0; k < 3; ++k) {
        o.unknown[k] = unknown[t[k]];
        o.w[k] = w[k];
        if (o.unknown[k] == kInvalidIndex) o.target = o.target - positions[t[k]] * w[k];
      }
      return o;
    };
    observations.resize(edges.size() + input_samples.size());
    edge_hint.resize(edges.size(), kInvalidIndex);
    // Queries run in fixed chunks. Each is hinted with its answer in the last step, else with the answer to the
    // query before it (edges sorted by their ends and input vertices in the input's order are mostly near the
    // one before): a close first guess prunes most of the tree.
    auto chunks = [](std::size_t count) { return (count + kChunk - 1) / kChunk; };
    // Simplified -> input: each edge's midpoint should lie on the input surface.
    tbb::parallel_for(std::size_t{0}, chunks(edges.size()), [&](std::size_t chunk) {
      std::uint32_t near = kInvalidIndex;
      for (std::size_t i = chunk * kChunk; i < std::min(edges.size(), (chunk + 1) * kChunk); ++i) {
        const SampledEdge& e = edges[i];
        const Vec3d mid = (positions[e.lo] + positions[e.hi]) * 0.5;
        const BvhHit hit = input_bvh.closest_point(mid, edge_hint[i] != kInvalidIndex ? edge_hint[i] : near);
        if (hit.found()) near = edge_hint[i] = hit.triangle;
        observations[i] =
            hit.found() ? observation({e.lo, e.hi, e.hi}, {0.5, 0.5, 0.0}, hit.point, e.area) : Observation{};
      }
    });
    // Input -> simplified: the closest point of the simplified surface to each input vertex should be on it.
    indices.clear();
    for (const auto& v : triangles) indices.insert(indices.end(), v.begin(), v.end());
    const TriangleBvh simplified_bvh(positions, indices);
    tbb::parallel_for(std::size_t{0}, chunks(input_samples.size()), [&](std::size_t chunk) {
      std::uint32_t near = kInvalidIndex;
      for (std::size_t i = chunk * kChunk; i < std::min(input_samples.size(), (chunk + 1) * kChunk); ++i) {
        const std::uint32_t guess = input_hint[i] != kInvalidIndex ? input_hint[i] : near;
        const BvhHit hit = simplified_bvh.closest_point(input_samples[i], guess);
        if (hit.found()) near = input_hint[i] = hit.triangle;
        observations[edges.size() + i] =
            hit.found() ? observation(triangles[hit.triangle], hit.barycentric, input_samples[i], input_area[i])
                        : Observation{};
      }
    });
    for (std::size_t k = 0; k < n; ++k) start[k] = positions[order[k]];
    const std::vector<Vec3d> solution = system.solve(observations, start, options.regularisation);

    std::size_t taken = 0, significant = 0;
    for (std::uint32_t k = 0; k < n; ++k) {
      const std::uint32_t v = order[k];
      Vec3d d = solution[k] - start[k];
      if (!(std::isfinite(d[0]) && std::isfinite(d[1]) && std::isfinite(d[2]))) continue;
      double shortest = std::numeric_limits<double>::infinity();
      for (std::uint32_t f : mesh.vertex_faces(v)) {
        const std::uint32_t fn = mesh.face_size(f), i = mesh.corner_of(f, v);
        for (std::uint32_t j : {(i + 1) % fn, (i + fn - 1) % fn}) {
          const Vec3d e = mesh.position(mesh.face_vertex(f, j)) - start[k];
          shortest = std::min(shortest, dot(e, e));
        }
      }
      shortest = std::sqrt(shortest);
      const double limit = options.max_step_edges * shortest, step = length(d);
      if (step > limit) d = d * (limit / step);
      // Steps at rounding level would only stir vertices that are on the surface already.
      if (!(std::min(step, limit) > kNegligibleStep * shortest)) continue;
      before.clear();
      for (std::uint32_t f : mesh.vertex_faces(v)) before.push_back(face_normals(mesh, f));
      for (double fraction : {1.0, 0.5}) {
        mesh.set_position(v, start[k] + d * fraction);
        bool ok = true;
        for (std::size_t q = 0; q < before.size() && ok; ++q) {
          ok = turned_within(before[q], face_normals(mesh, mesh.vertex_faces(v)[q]), cos_max);
        }
        if (ok) {
          ++taken;
          if (std::min(step, limit) * fraction >= kConvergedStep * shortest) ++significant;
          break;
        }
        mesh.set_position(v, start[k]);
      }
    }
    steps += taken;
    // Converged: hardly any vertex moved by a noticeable part of its edges, so another step would not either.
    if (significant * kConvergedShare < order.size()) break;
  }
  return steps;
}

}  // namespace lodforge::quad
