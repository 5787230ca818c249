// Surface fitting of moved vertices (see surface_fit.hpp): closest points through eval's triangle BVH (queries
// in parallel, their offsets summed in a fixed order, so the result does not depend on the thread count),
// then normal-direction Jacobi steps checked against face turning.
#include "lodforge/quad/surface_fit.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
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

}  // namespace

// A step shorter than this fraction of the vertex's shortest edge is not taken.
constexpr double kNegligibleStep = 1e-6;
// The fit stops early when fewer than one vertex in kConvergedShare stepped by at least kConvergedStep of its
// shortest edge. On the bench's 100k-quad torus the first step moves 110 of 24.7k vertices that far (the
// second moves them by under 0.1%): one step, half the fit's time. The MakeHuman suit and hair move most of
// theirs by 1-10% and get both steps.
constexpr double kConvergedStep = 0.01;
constexpr std::size_t kConvergedShare = 100;

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
  // The input's vertices are the points sampled on it (its triangles' centroids as well changed no bench
  // figure by more than 1% and doubled the fit's time).
  std::vector<Vec3d> input_samples;
  input_samples.reserve(input.vertex_count());
  for (const Vec3f& p : input.positions) input_samples.push_back(to_double(p));

  const std::size_t nv = mesh.vertex_count();
  // Boundary vertices stay: their collapses kept them on the boundary line (border quadrics), which a step
  // along the surface normal would bend.
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
  // Each triangle of the simplified surface is sampled at its centroid (with the movable vertices
  // themselves): three more samples per triangle, towards its corners, changed no bench figure by more than
  // 1.5% and took a fifth more of the polychord engine's time on the 100k-quad torus.
  constexpr std::array<double, 3> kCentroid{1.0 / 3, 1.0 / 3, 1.0 / 3};
  std::vector<Vec3d> normal(nv);
  std::vector<double> offset(nv), weight(nv);
  // Adds the offset d, seen at a point with barycentric weights w on triangle v, to its movable corners.
  auto pull = [&](const std::array<std::uint32_t, 3>& v, const std::array<double, 3>& w, const Vec3d& d) {
    for (std::size_t k = 0; k < 3; ++k) {
      if (!movable[v[k]] || !(w[k] > 0.0)) continue;
      offset[v[k]] += w[k] * dot(d, normal[v[k]]);
      weight[v[k]] += w[k];
    }
  };
  std::size_t steps = 0;
  // Buffers kept across steps (large ones freed and allocated again cost page faults every step).
  std::vector<std::array<std::uint32_t, 3>> triangles;  // the simplified surface now, as vertex triples
  std::vector<Vec3d> positions(nv), on_input;
  std::vector<std::uint32_t> sampled, indices;
  std::vector<BvhHit> hits(input_samples.size());
  std::vector<std::array<Vec3d, 5>> before;  // normals of one vertex's faces before its step
  for (int it = 0; it < options.iterations; ++it) {
    triangles.clear();
    for (std::uint32_t f = 0; f < mesh.face_slots(); ++f) {
      if (!mesh.face_alive(f)) continue;
      face_triangles(mesh, f, [&](std::uint32_t i0, std::uint32_t i1, std::uint32_t i2) {
        triangles.push_back({mesh.face_vertex(f, i0), mesh.face_vertex(f, i1), mesh.face_vertex(f, i2)});
      });
    }
    for (std::uint32_t v : order) {
      Vec3d n{};
      for (std::uint32_t f : mesh.vertex_faces(v)) n = n + mesh.face_normal(f);
      const double l = length(n);
      normal[v] = l > 0.0 ? n * (1.0 / l) : Vec3d{};
      offset[v] = 0.0;
      weight[v] = 0.0;
    }
    // Simplified -> input: each sample of a face (and each movable vertex) moves towards the input surface.
    for (std::uint32_t v = 0; v < nv; ++v) {
      if (mesh.vertex_alive(v)) positions[v] = mesh.position(v);
    }
    sampled.clear();  // triangles with a movable corner
    for (std::uint32_t t = 0; t < triangles.size(); ++t) {
      const auto& v = triangles[t];
      if (movable[v[0]] || movable[v[1]] || movable[v[2]]) sampled.push_back(t);
    }
    auto sample_point = [&](std::uint32_t t, const std::array<double, 3>& w) {
      const auto& v = triangles[t];
      return positions[v[0]] * w[0] + positions[v[1]] * w[1] + positions[v[2]] * w[2];
    };
    on_input.resize(sampled.size() + order.size());
    tbb::parallel_for(std::size_t{0}, on_input.size(), [&](std::size_t i) {
      const Vec3d s = i < sampled.size() ? sample_point(sampled[i], kCentroid) : positions[order[i - sampled.size()]];
      const BvhHit hit = input_bvh.closest_point(s);
      on_input[i] = hit.found() ? hit.point : s;
    });
    for (std::size_t i = 0; i < sampled.size(); ++i) {
      pull(triangles[sampled[i]], kCentroid, on_input[i] - sample_point(sampled[i], kCentroid));
    }
    for (std::size_t k = 0; k < order.size(); ++k) {
      const std::uint32_t v = order[k];
      pull({v, v, v}, {1.0, 0.0, 0.0}, on_input[sampled.size() + k] - positions[v]);
    }
    // Input -> simplified: each input sample pulls the closest point of the simplified surface towards it.
    indices.clear();
    for (const auto& v : triangles) indices.insert(indices.end(), v.begin(), v.end());
    const TriangleBvh simplified_bvh(positions, indices);
    tbb::parallel_for(std::size_t{0}, hits.size(),
                      [&](std::size_t i) { hits[i] = simplified_bvh.closest_point(input_samples[i]); });
    for (std::size_t i = 0; i < hits.size(); ++i) {
      const BvhHit& hit = hits[i];
      if (hit.found()) {
        pull(triangles[hit.triangle], {hit.barycentric[0], hit.barycentric[1], hit.barycentric[2]},
             input_samples[i] - hit.point);
      }
    }

    std::size_t taken = 0, significant = 0;
    for (std::uint32_t v : order) {
      if (!(weight[v] > 0.0)) continue;
      const Vec3d start = mesh.position(v);
      double shortest = std::numeric_limits<double>::infinity();
      for (std::uint32_t f : mesh.vertex_faces(v)) {
        const std::uint32_t n = mesh.face_size(f), i = mesh.corner_of(f, v);
        for (std::uint32_t j : {(i + 1) % n, (i + n - 1) % n}) {
          const Vec3d e = mesh.position(mesh.face_vertex(f, j)) - start;
          shortest = std::min(shortest, dot(e, e));
        }
      }
      const double limit = options.max_step_edges * std::sqrt(shortest);
      const double t = std::clamp(offset[v] / weight[v], -limit, limit);
      // Steps at rounding level would only stir vertices that are on the surface already.
      if (!(std::abs(t) > kNegligibleStep * std::sqrt(shortest))) continue;
      before.clear();
      for (std::uint32_t f : mesh.vertex_faces(v)) before.push_back(face_normals(mesh, f));
      for (double fraction : {1.0, 0.5}) {
        mesh.set_position(v, start + normal[v] * (t * fraction));
        bool ok = true;
        for (std::size_t k = 0; k < before.size() && ok; ++k) {
          ok = turned_within(before[k], face_normals(mesh, mesh.vertex_faces(v)[k]), cos_max);
        }
        if (ok) {
          ++taken;
          if (std::abs(t * fraction) >= kConvergedStep * std::sqrt(shortest)) ++significant;
          break;
        }
        mesh.set_position(v, start);
      }
    }
    steps += taken;
    // Converged: hardly any vertex moved by a noticeable part of its edges, so another step would not either.
    if (significant * kConvergedShare < order.size()) break;
  }
  return steps;
}

}  // namespace lodforge::quad
