// Certified one-sided Hausdorff bound by Lipschitz branch and bound (see the header).
//
// Two bounds per triangle T of the mesh:
//  - d(centroid) + R: the distance to a fixed surface is 1-Lipschitz, and every point of T is within R (the
//    largest centroid-to-corner distance) of the centroid;
//  - max over the corners of d(corner), when all three corners have their closest point on the same target
//    triangle τ: a point Σ λᵢ vᵢ of T is within Σ λᵢ |vᵢ − cᵢ| of Σ λᵢ cᵢ, which lies in τ (convex). This one
//    is exact where a LOD triangle lies on the source's surface, where the first would never converge.
#include "lodforge/eval/distance_bound.hpp"

#include <algorithm>
#include <cmath>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

namespace lodforge {
namespace {

bool finite3(const Vec3d& p) { return std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]); }

struct Hit {
  double distance = 0;
  std::uint32_t triangle = kInvalidIndex;
};

Hit query(const TriangleBvh& bvh, const Vec3d& p) {
  const BvhHit h = bvh.closest_point(p);
  return {h.distance(), h.triangle};
}

struct Node {
  Vec3d p[3];
  Hit h[3];
};

// A node's bound and the largest distance measured on it (its corners and, where needed, its centroid).
struct Bound {
  double upper = 0, lower = 0;
  bool queried = false;  // the centroid was measured
};

// Farthest corner of n from target triangle t.
double farthest_corner(const Node& n, const SurfaceIndex& target, std::uint32_t t) {
  const Vec3d& a = target.positions[target.indices[3 * std::size_t{t}]];
  const Vec3d& b = target.positions[target.indices[3 * std::size_t{t} + 1]];
  const Vec3d& c = target.positions[target.indices[3 * std::size_t{t} + 2]];
  double d2 = 0;
  for (const Vec3d& p : n.p) {
    const Vec3d q = closest_point_on_triangle(p, a, b, c).point;
    d2 = std::max(d2, dot(p - q, p - q));
  }
  return std::sqrt(d2);
}

Bound bound(const Node& n, const SurfaceIndex& target) {
  const double corner_max = std::max({n.h[0].distance, n.h[1].distance, n.h[2].distance});
  if (n.h[0].triangle != kInvalidIndex && n.h[0].triangle == n.h[1].triangle && n.h[0].triangle == n.h[2].triangle) {
    return {corner_max, corner_max, false};
  }
  const Vec3d g = (n.p[0] + n.p[1] + n.p[2]) * (1.0 / 3.0);
  double r2 = 0;
  for (const Vec3d& c : n.p) r2 = std::max(r2, dot(c - g, c - g));
  const Hit hg = query(target.bvh, g);
  double upper = hg.distance + std::sqrt(r2);
  // Ties: a corner on an edge or vertex of the target may name any triangle there, so try each triangle
  // named by a corner or the centroid as the common one.
  for (const std::uint32_t t : {n.h[0].triangle, n.h[1].triangle, n.h[2].triangle, hg.triangle}) {
    if (t != kInvalidIndex) upper = std::min(upper, farthest_corner(n, target, t));
  }
  return {std::max(upper, std::max(corner_max, hg.distance)), std::max(corner_max, hg.distance), true};
}

template <typename F>
void parallel_ranges(tbb::task_arena& arena, std::size_t n, std::size_t grain, F&& f) {
  arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, grain),
                      [&](const tbb::blocked_range<std::size_t>& r) { f(r.begin(), r.end()); });
  });
}

}  // namespace

SurfaceIndex::SurfaceIndex(const Mesh& mesh) {
  positions.reserve(mesh.vertex_count());
  for (const Vec3f& p : mesh.positions) positions.push_back(to_double(p));
  indices = triangle_vertex_indices(mesh);
  bvh = TriangleBvh(positions, indices);
}

DistanceBound distance_bound(const Mesh& mesh, const SurfaceIndex& target, const DistanceBoundOptions& options) {
  DistanceBound out;
  const std::vector<std::uint32_t> idx = triangle_vertex_indices(mesh);
  std::vector<std::uint32_t> triangles;  // first index of each triangle with finite corners
  std::vector<std::uint32_t> corners;    // vertices used by those, ascending
  {
    std::vector<char> used(mesh.vertex_count(), 0);
    for (std::uint32_t t = 0; t + 2 < idx.size(); t += 3) {
      bool finite = true;
      for (std::uint32_t k = 0; k < 3; ++k) finite = finite && finite3(to_double(mesh.positions[idx[t + k]]));
      if (!finite) continue;
      triangles.push_back(t);
      for (std::uint32_t k = 0; k < 3; ++k) used[idx[t + k]] = 1;
    }
    for (std::size_t v = 0; v < used.size(); ++v) {
      if (used[v]) corners.push_back(static_cast<std::uint32_t>(v));
    }
  }
  if (triangles.empty()) return out;
  if (target.empty()) {
    out.upper = out.lower = std::numeric_limits<double>::infinity();
    return out;
  }
  const std::size_t max_queries = options.max_queries > 0 ? options.max_queries : 64 * triangles.size() + 1000000;
  tbb::task_arena arena(options.threads == 0 ? tbb::task_arena::automatic : static_cast<int>(options.threads));

  // The corners once each.
  std::vector<Hit> vertex_hit(mesh.vertex_count());
  parallel_ranges(arena, corners.size(), 1024, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) vertex_hit[corners[i]] = query(target.bvh, to_double(mesh.positions[corners[i]]));
  });
  for (std::uint32_t v : corners) out.lower = std::max(out.lower, vertex_hit[v].distance);
  out.queries += corners.size();

  std::vector<Node> active(triangles.size());
  for (std::size_t i = 0; i < triangles.size(); ++i) {
    for (std::uint32_t k = 0; k < 3; ++k) {
      const std::uint32_t v = idx[triangles[i] + k];
      active[i].p[k] = to_double(mesh.positions[v]);
      active[i].h[k] = vertex_hit[v];
    }
  }

  double settled = 0.0;  // largest bound of the nodes no longer refined
  std::vector<Bound> bounds;
  std::vector<std::uint32_t> split;
  std::vector<Node> next;
  for (int round = 0;; ++round) {
    const std::size_t n = active.size();
    bounds.resize(n);
    parallel_ranges(arena, n, 256, [&](std::size_t b, std::size_t e) {
      for (std::size_t i = b; i < e; ++i) bounds[i] = bound(active[i], target);
    });
    for (std::size_t i = 0; i < n; ++i) {
      out.lower = std::max(out.lower, bounds[i].lower);
      out.queries += bounds[i].queried;
    }
    out.rounds = round + 1;
    if (out.lower > options.give_up_above) {
      out.gave_up = true;
      out.upper = std::numeric_limits<double>::infinity();
      return out;
    }
    const double enough = std::max((1.0 + options.tolerance) * out.lower, options.good_enough);
    split.clear();
    double open = 0.0;  // largest bound among the nodes still to refine
    for (std::size_t i = 0; i < n; ++i) {
      if (bounds[i].upper <= enough) {
        settled = std::max(settled, bounds[i].upper);
      } else {
        open = std::max(open, bounds[i].upper);
        split.push_back(static_cast<std::uint32_t>(i));
      }
    }
    if (split.empty() || round + 1 >= options.max_rounds || out.queries + 7 * split.size() > max_queries) {
      out.converged = split.empty();
      out.upper = std::max({settled, open, out.lower});
      return out;
    }
    // Split each into four at its edge midpoints (measured here, once per split).
    next.resize(4 * split.size());
    parallel_ranges(arena, split.size(), 64, [&](std::size_t b, std::size_t e) {
      for (std::size_t s = b; s < e; ++s) {
        const Node& q = active[split[s]];
        Node m;  // the middle child: corners at the midpoints of q's edges 0-1, 1-2, 2-0
        for (int k = 0; k < 3; ++k) {
          m.p[k] = (q.p[k] + q.p[(k + 1) % 3]) * 0.5;
          m.h[k] = query(target.bvh, m.p[k]);
        }
        Node* c = &next[4 * s];
        c[0] = {{q.p[0], m.p[0], m.p[2]}, {q.h[0], m.h[0], m.h[2]}};
        c[1] = {{m.p[0], q.p[1], m.p[1]}, {m.h[0], q.h[1], m.h[1]}};
        c[2] = {{m.p[2], m.p[1], q.p[2]}, {m.h[2], m.h[1], q.h[2]}};
        c[3] = m;
      }
    });
    for (std::size_t i = 0; i < next.size(); i += 4) {
      for (const Hit& h : next[i + 3].h) out.lower = std::max(out.lower, h.distance);
    }
    out.queries += 3 * split.size();
    active.swap(next);
  }
}

}  // namespace lodforge
