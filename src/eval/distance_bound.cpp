// Certified one-sided Hausdorff bound by Lipschitz branch and bound (see the header).
//
// Two bounds per triangle T of the mesh:
//  - d(centroid) + R: the distance to a fixed surface is 1-Lipschitz, and every point of T is within R (the
//    largest centroid-to-corner distance) of the centroid;
//  - max over the corners of d(corner), when all three corners have their closest point on the same target
//    triangle τ: a point Σ λᵢ vᵢ of T is within Σ λᵢ |vᵢ − cᵢ| of Σ λᵢ cᵢ, which lies in τ (convex). This one
//    is exact where a LOD triangle lies on the source's surface, where the first would never converge. The
//    same holds for two target triangles that share an edge and lie flat (their union convex, up to a slack),
//    so parts of a LOD lying on a flat region of the target converge across its edges too.
#include "lodforge/eval/distance_bound.hpp"

#include <algorithm>
#include <array>
#include <span>
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

// A round splits the worst open nodes with at most this fraction (1/k) of the query allowance left.
constexpr std::size_t kDeepFraction = 4;
// A node lying on a flat region of the target counts as on it within this fraction of `good_enough`.
constexpr double kFlatSlack = 0.05;
// ... and its walk may follow the target up to this fraction of `good_enough` off the start triangle's plane.
constexpr double kPlaneTolerance = 0.5;

// `hint`: a triangle near p (a neighbouring point's answer), which prunes the search from the start.
Hit query(const TriangleBvh& bvh, const Vec3d& p, std::uint32_t hint) {
  const BvhHit h = bvh.closest_point(p, hint);
  return {h.distance(), h.triangle};
}

struct Node {
  Vec3d p[3];
  Hit h[3];
  double cap = std::numeric_limits<double>::infinity();  // a bound known for the triangle it is part of
  std::uint32_t source = 0;  // that triangle, in the mesh's triangle order
};

// A node's bound and the largest distance measured on it (its corners and, where needed, its centroid).
struct Bound {
  double upper = 0, lower = 0;
  bool queried = false;  // the centroid was measured
};

// Squared distances of n's corners to target triangle t.
std::array<double, 3> corner_distances(const Node& n, const SurfaceIndex& target, std::uint32_t t) {
  const auto [a, b, c] = target.bvh.triangle(t);
  std::array<double, 3> d2{};
  for (int k = 0; k < 3; ++k) {
    const Vec3d q = closest_point_on_triangle(n.p[k], a, b, c).point;
    d2[k] = dot(n.p[k] - q, n.p[k] - q);
  }
  return d2;
}

// Target triangles t and u sharing the edge opposite t's corner k: when u's far corner, moved onto t's plane,
// makes a convex quad with t, every point of the hull of t ∪ u is within 2h of t ∪ u (h that corner's distance
// to the plane: h to move it onto the plane, h back). Returns 2h, or -1 where the quad is not convex.
double flat_pair_slack(const SurfaceIndex& target, std::uint32_t t, int k, std::uint32_t u) {
  const auto ct = target.bvh.triangle(t);
  const auto cu = target.bvh.triangle(u);
  const Vec3d& r = ct[k];
  const Vec3d& p = ct[(k + 1) % 3];
  const Vec3d& q = ct[(k + 2) % 3];
  const std::uint32_t ip = target.indices[3 * std::size_t{t} + (k + 1) % 3];
  const std::uint32_t iq = target.indices[3 * std::size_t{t} + (k + 2) % 3];
  int far = -1;
  for (int j = 0; j < 3; ++j) {
    const std::uint32_t i = target.indices[3 * std::size_t{u} + j];
    if (i != ip && i != iq) far = j;
  }
  if (far < 0) return -1;
  const Vec3d n = cross(p - r, q - r);
  const double nn = dot(n, n);
  if (!(nn > 0) || !std::isfinite(nn)) return -1;
  const double off = dot(cu[far] - r, n) / nn;
  const Vec3d s = cu[far] - n * off;  // on t's plane
  auto side = [&](const Vec3d& a, const Vec3d& b, const Vec3d& c) { return dot(cross(b - a, c - a), n); };
  // Convex: r and s on opposite sides of pq, p and q on opposite sides of rs.
  if (!(side(p, q, r) * side(p, q, s) < 0) || !(side(r, s, p) * side(r, s, q) < 0)) return -1;
  return 2.0 * std::abs(off) * std::sqrt(nn);
}

// The smallest corner bound over the candidate target triangles and the flat convex pairs they form with their
// neighbours: a point Σ λᵢ vᵢ of the node is within Σ λᵢ |vᵢ − cᵢ| of Σ λᵢ cᵢ, cᵢ a closest point of a convex set.
// Also gives, per valid candidate, its squared corner distances (corner_d2, one per candidate).
double corner_bound(const Node& n, const SurfaceIndex& target, std::span<const std::uint32_t> candidates,
                    std::span<std::array<double, 3>> corner_d2) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < candidates.size(); ++i) {
    const std::uint32_t t = candidates[i];
    if (t == kInvalidIndex) continue;
    if (const auto seen = std::find(candidates.begin(), candidates.begin() + i, t); seen != candidates.begin() + i) {
      corner_d2[i] = corner_d2[seen - candidates.begin()];
      continue;
    }
    const std::array<double, 3>& dt = corner_d2[i] = corner_distances(n, target, t);
    best = std::min(best, std::sqrt(std::max({dt[0], dt[1], dt[2]})));
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t u = target.bvh.neighbor(t, k);
      if (u == kInvalidIndex) continue;
      const double slack = flat_pair_slack(target, t, k, u);
      if (slack < 0 || slack >= best) continue;
      const std::array<double, 3> du = corner_distances(n, target, u);
      double d2 = 0;
      for (int c = 0; c < 3; ++c) d2 = std::max(d2, std::min(dt[c], du[c]));
      best = std::min(best, std::sqrt(d2) + slack);
    }
  }
  return best;
}

// Corners whose closest target triangles differ (a node across an edge or a vertex of the target): the node
// is cut into pieces, one per corner, each held to its corner's triangle. An edge whose ends name different
// triangles is cut where their distances cross (estimated linearly from the ends); where all three differ,
// the pieces also meet at the centroid. Each piece lies in the hull of its cut points and corner, and the
// distance to one triangle is convex, so the piece is within that triangle's largest distance at them.
// corner_d2[m][k]: corner k's squared distance to corner m's triangle (corner_bound's).
double piecewise_bound(const Node& n, const SurfaceIndex& target, std::span<const std::array<double, 3>, 3> corner_d2) {
  const std::uint32_t f[3] = {n.h[0].triangle, n.h[1].triangle, n.h[2].triangle};
  if (f[0] == kInvalidIndex || f[1] == kInvalidIndex || f[2] == kInvalidIndex) return std::numeric_limits<double>::infinity();
  auto distance = [&](const Vec3d& x, std::uint32_t t) {
    const auto [a, b, c] = target.bvh.triangle(t);
    return length(x - closest_point_on_triangle(x, a, b, c).point);
  };
  double worst = std::max({n.h[0].distance, n.h[1].distance, n.h[2].distance});
  for (int i = 0; i < 3; ++i) {
    const int j = (i + 1) % 3;
    if (f[i] == f[j]) continue;
    // The difference of the two distances, negative at corner i (its own triangle is the closer), positive at j.
    const double at_i = n.h[i].distance - std::sqrt(corner_d2[j][i]);
    const double at_j = std::sqrt(corner_d2[i][j]) - n.h[j].distance;
    const double s = at_j - at_i > 0 ? std::clamp(-at_i / (at_j - at_i), 0.0, 1.0) : 0.5;
    const Vec3d m = n.p[i] + (n.p[j] - n.p[i]) * s;
    worst = std::max({worst, distance(m, f[i]), distance(m, f[j])});
  }
  if (f[0] != f[1] && f[1] != f[2] && f[0] != f[2]) {
    const Vec3d g = (n.p[0] + n.p[1] + n.p[2]) * (1.0 / 3.0);
    worst = std::max({worst, distance(g, f[0]), distance(g, f[1]), distance(g, f[2])});
  }
  return worst;
}

// A node lying on a nearly flat region of the target made of many triangles (a CAD face tessellated into
// slivers, or a small patch of a smooth surface): walk the target's triangles from the one under the centroid
// across the edges that reach into the node, projected onto that triangle's plane P, as long as their corners
// stay within `plane_tolerance` of P and they keep P's orientation (so the walked patch projects without
// folds). If no edge on the border of the walked region reaches deeper than `slack` into the node, the node,
// shrunk by `slack`, lies in the region's projection, and every point of the node is within
//   (largest corner distance to P) + (largest distance of a walked vertex to P) + slack / sin(θmin / 2)
// of the target, θmin the node's smallest angle. Returns that, or +inf where the walk fails.
double flat_region_bound(const Node& n, const SurfaceIndex& target, std::uint32_t start, const Vec3d& from,
                         double slack, double plane_tolerance) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  constexpr std::size_t kMaxWalk = 256;
  constexpr std::size_t kSlots = 1024;  // open addressing over the walked triangles, under a quarter full
  if (start == kInvalidIndex || !(slack > 0)) return kInf;
  const auto t0 = target.bvh.triangle(start);
  Vec3d normal = cross(t0[1] - t0[0], t0[2] - t0[0]);
  const double length = std::sqrt(dot(normal, normal));
  if (!(length > 0) || !std::isfinite(length)) return kInf;
  normal = normal * (1.0 / length);
  Vec3d e1 = t0[1] - t0[0];
  e1 = e1 * (1.0 / std::sqrt(dot(e1, e1)));
  const Vec3d e2 = cross(normal, e1);
  struct P2 {
    double x, y;
  };
  auto flat = [&](const Vec3d& p) { return P2{dot(p - t0[0], e1), dot(p - t0[0], e2)}; };
  auto cross2 = [](P2 a, P2 b, P2 c) { return (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x); };

  const P2 q[3] = {flat(n.p[0]), flat(n.p[1]), flat(n.p[2])};
  const double area2 = cross2(q[0], q[1], q[2]);
  if (!(std::abs(area2) > 0)) return kInf;
  const double sign = area2 > 0 ? 1.0 : -1.0;
  double inv_len[3], min_sin_half = 1.0;
  for (int i = 0; i < 3; ++i) {
    const P2 a = q[i], b = q[(i + 1) % 3], c = q[(i + 2) % 3];
    inv_len[i] = 1.0 / std::hypot(b.x - a.x, b.y - a.y);
    // The angle at corner i, between its two edges.
    const double ux = b.x - a.x, uy = b.y - a.y, vx = c.x - a.x, vy = c.y - a.y;
    const double angle = std::atan2(std::abs(ux * vy - uy * vx), ux * vx + uy * vy);
    min_sin_half = std::min(min_sin_half, std::sin(0.5 * angle));
  }
  if (!(min_sin_half > 0)) return kInf;
  // Depth of a point inside the node: its distance to the nearest edge line (negative outside).
  auto depth_along = [&](P2 a, P2 b, double t) {
    const P2 x{a.x + t * (b.x - a.x), a.y + t * (b.y - a.y)};
    double d = kInf;
    for (int i = 0; i < 3; ++i) d = std::min(d, sign * cross2(q[i], q[(i + 1) % 3], x) * inv_len[i]);
    return d;
  };
  // The deepest point of segment ab in the node: the minimum of three linear functions peaks at an end or
  // where two of them cross.
  auto penetration = [&](P2 a, P2 b) {
    double f0[3], f1[3];
    for (int i = 0; i < 3; ++i) {
      f0[i] = sign * cross2(q[i], q[(i + 1) % 3], a) * inv_len[i];
      f1[i] = sign * cross2(q[i], q[(i + 1) % 3], b) * inv_len[i];
    }
    double best = std::max(depth_along(a, b, 0.0), depth_along(a, b, 1.0));
    for (int i = 0; i < 3; ++i) {
      for (int j = i + 1; j < 3; ++j) {
        const double denom = (f0[i] - f1[i]) - (f0[j] - f1[j]);
        if (denom == 0) continue;
        const double t = (f0[i] - f0[j]) / denom;
        if (t > 0 && t < 1) best = std::max(best, depth_along(a, b, t));
      }
    }
    return best;
  };

  // The walk starts from `from`, a point of `start` (the centroid's closest point): it must lie inside the
  // shrunk node.
  {
    const P2 f = flat(from);
    if (!(depth_along(f, f, 0.0) > slack)) return kInf;
  }
  const double start_orientation = cross2(flat(t0[0]), flat(t0[1]), flat(t0[2]));
  double off_plane = 0;  // largest distance of a walked triangle's corner to P
  std::uint32_t walked[kMaxWalk];
  std::uint32_t slots[kSlots];
  std::fill(slots, slots + kSlots, kInvalidIndex);
  // Inserts t; false if it was there.
  auto insert = [&](std::uint32_t t) {
    std::size_t i = (t * 2654435761u) % kSlots;
    while (slots[i] != kInvalidIndex) {
      if (slots[i] == t) return false;
      i = (i + 1) % kSlots;
    }
    slots[i] = t;
    return true;
  };
  std::size_t count = 0, next = 0;
  walked[count++] = start;
  insert(start);
  while (next < count) {
    const std::uint32_t t = walked[next++];
    const auto c = target.bvh.triangle(t);
    for (const Vec3d& v : c) off_plane = std::max(off_plane, std::abs(dot(v - t0[0], normal)));
    if (off_plane > plane_tolerance) return kInf;
    if (!(cross2(flat(c[0]), flat(c[1]), flat(c[2])) * start_orientation > 0)) return kInf;  // flipped in P
    for (int k = 0; k < 3; ++k) {
      if (!(penetration(flat(c[(k + 1) % 3]), flat(c[(k + 2) % 3])) > slack)) continue;
      const std::uint32_t u = target.bvh.neighbor(t, k);
      if (u == kInvalidIndex) return kInf;  // the region's border runs through the node
      // An edge of more than two triangles: each names the next, so a manifold one names t back.
      bool manifold = false;
      for (int j = 0; j < 3; ++j) manifold = manifold || target.bvh.neighbor(u, j) == t;
      if (!manifold) return kInf;
      // u must unfold to the other side of the edge (a fold back over t covers nothing new).
      const auto cu = target.bvh.triangle(u);
      const P2 a = flat(c[(k + 1) % 3]), b = flat(c[(k + 2) % 3]);
      double far_side = 0;
      for (const Vec3d& v : cu) {
        const double side = cross2(a, b, flat(v));
        if (std::abs(side) > std::abs(far_side)) far_side = side;
      }
      if (!(cross2(a, b, flat(c[k])) * far_side < 0)) return kInf;
      if (count == kMaxWalk) return kInf;
      if (insert(u)) walked[count++] = u;
    }
  }
  double corner_off = 0;
  for (const Vec3d& p : n.p) corner_off = std::max(corner_off, std::abs(dot(p - t0[0], normal)));
  return corner_off + off_plane + slack / min_sin_half;
}

Bound bound(const Node& n, const SurfaceIndex& target, double flat_slack, double plane_tolerance) {
  const double corner_max = std::max({n.h[0].distance, n.h[1].distance, n.h[2].distance});
  if (n.h[0].triangle != kInvalidIndex && n.h[0].triangle == n.h[1].triangle && n.h[0].triangle == n.h[2].triangle) {
    return {corner_max, corner_max, false};
  }
  const Vec3d g = (n.p[0] + n.p[1] + n.p[2]) * (1.0 / 3.0);
  double r2 = 0;
  for (const Vec3d& c : n.p) r2 = std::max(r2, dot(c - g, c - g));
  const Hit hg = query(target.bvh, g, n.h[0].triangle);
  double upper = hg.distance + std::sqrt(r2);
  // Ties: a corner on an edge or vertex of the target may name any triangle there, so try each triangle
  // named by a corner or the centroid as the common one, alone and with its flat neighbours (a LOD triangle
  // lying on a flat part of the target across its edges).
  const std::uint32_t candidates[] = {n.h[0].triangle, n.h[1].triangle, n.h[2].triangle, hg.triangle};
  std::array<double, 3> corner_d2[std::size(candidates)];
  upper = std::min(upper, corner_bound(n, target, candidates, corner_d2));
  upper = std::min(upper, piecewise_bound(n, target, std::span(corner_d2).first<3>()));
  if (upper > flat_slack && hg.distance <= plane_tolerance && hg.triangle != kInvalidIndex) {
    const auto [a, b, c] = target.bvh.triangle(hg.triangle);
    const Vec3d from = closest_point_on_triangle(g, a, b, c).point;
    upper = std::min(upper, flat_region_bound(n, target, hg.triangle, from, flat_slack, plane_tolerance));
  }
  const double lower = std::max(corner_max, hg.distance);
  return {std::max(std::min(upper, n.cap), lower), lower, true};
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

namespace {

DistanceBound bound_triangles(std::span<const Vec3d> positions, std::span<const std::uint32_t> idx,
                              const SurfaceIndex& target, const DistanceBoundOptions& options) {
  DistanceBound out;
  std::vector<std::uint32_t> triangles;  // first index of each triangle with finite corners
  std::vector<std::uint32_t> corners;    // vertices used by those, ascending
  double settled = 0.0;                  // largest bound of the nodes no longer refined
  {
    std::vector<char> used(positions.size(), 0);
    for (std::uint32_t t = 0; t + 2 < idx.size(); t += 3) {
      bool finite = true;
      for (std::uint32_t k = 0; k < 3; ++k) finite = finite && finite3(positions[idx[t + k]]);
      if (!finite) continue;
      if (options.on_target != nullptr && t / 3 < options.on_target->size() && (*options.on_target)[t / 3]) continue;
      if (options.settle_known && options.known_upper != nullptr && t / 3 < options.known_upper->size()) {
        const double known = (*options.known_upper)[t / 3];
        if (known >= 0 && known <= options.give_up_above) {
          settled = std::max(settled, known);
          continue;
        }
      }
      triangles.push_back(t);
      for (std::uint32_t k = 0; k < 3; ++k) used[idx[t + k]] = 1;
    }
    for (std::size_t v = 0; v < used.size(); ++v) {
      if (used[v]) corners.push_back(static_cast<std::uint32_t>(v));
    }
  }
  if (triangles.empty()) {
    out.upper = settled;
    return out;
  }
  if (target.empty()) {
    out.upper = out.lower = std::numeric_limits<double>::infinity();
    return out;
  }
  const std::size_t max_queries = options.max_queries > 0 ? options.max_queries : 64 * triangles.size() + 1000000;
  // How far a node may reach past a flat region, and how far the region may bend, for the node to count as
  // lying on it (flat_region_bound): small parts of what the caller calls good enough.
  const double flat_slack = options.good_enough > 0 ? kFlatSlack * options.good_enough : 1e-9 * target.bvh.bounds().diagonal();
  const double plane_tolerance = options.good_enough > 0 ? kPlaneTolerance * options.good_enough : flat_slack;
  tbb::task_arena arena(options.threads == 0 ? tbb::task_arena::automatic : static_cast<int>(options.threads));

  // The corners once each.
  std::vector<Hit> vertex_hit(positions.size());
  parallel_ranges(arena, corners.size(), 1024, [&](std::size_t b, std::size_t e) {
    std::uint32_t hint = kInvalidIndex;  // vertices come in mesh order: the last answer is often near the next
    for (std::size_t i = b; i < e; ++i) {
      vertex_hit[corners[i]] = query(target.bvh, positions[corners[i]], hint);
      hint = vertex_hit[corners[i]].triangle;
    }
  });
  for (std::uint32_t v : corners) out.lower = std::max(out.lower, vertex_hit[v].distance);
  out.queries += corners.size();

  std::vector<Node> active(triangles.size());
  for (std::size_t i = 0; i < triangles.size(); ++i) {
    for (std::uint32_t k = 0; k < 3; ++k) {
      const std::uint32_t v = idx[triangles[i] + k];
      active[i].p[k] = positions[v];
      active[i].h[k] = vertex_hit[v];
    }
    const std::size_t t = triangles[i] / 3;
    active[i].source = static_cast<std::uint32_t>(t);
    if (options.known_upper != nullptr && t < options.known_upper->size() && (*options.known_upper)[t] >= 0) {
      active[i].cap = (*options.known_upper)[t];
    }
  }

  std::vector<Bound> bounds;
  std::vector<std::uint32_t> split;
  std::vector<Node> next;
  // Nodes still open from earlier rounds (with their bounds), when the query allowance let only the worst split.
  std::vector<Node> waiting;
  std::vector<Bound> waiting_bounds;
  std::vector<std::uint32_t> over;  // triangles found over give_up_above
  // Gives up with the triangles found over the threshold, each named once in ascending order.
  auto give_up = [&] {
    std::sort(over.begin(), over.end());
    over.erase(std::unique(over.begin(), over.end()), over.end());
    out.over = std::move(over);
    out.gave_up = true;
    out.upper = std::numeric_limits<double>::infinity();
    return out;
  };
  for (int round = 0;; ++round) {
    const std::size_t fresh = active.size();
    bounds.resize(fresh);
    parallel_ranges(arena, fresh, 256, [&](std::size_t b, std::size_t e) {
      for (std::size_t i = b; i < e; ++i) bounds[i] = bound(active[i], target, flat_slack, plane_tolerance);
    });
    for (std::size_t i = 0; i < fresh; ++i) {
      out.lower = std::max(out.lower, bounds[i].lower);
      out.queries += bounds[i].queried;
    }
    active.insert(active.end(), waiting.begin(), waiting.end());
    bounds.insert(bounds.end(), waiting_bounds.begin(), waiting_bounds.end());
    waiting.clear();
    waiting_bounds.clear();
    const std::size_t n = active.size();
    out.rounds = round + 1;
    if (out.lower > options.give_up_above && !options.list_over) {
      for (std::size_t i = 0; i < fresh; ++i) {
        if (bounds[i].lower > options.give_up_above) over.push_back(active[i].source);
      }
      return give_up();
    }
    double enough = std::max({(1.0 + options.tolerance) * out.lower, options.good_enough, options.settle_below});
    // Listing, the largest distance may be one set aside over the threshold: a part settles only below it.
    if (options.list_over) enough = std::min(enough, options.give_up_above);
    split.clear();
    double open = 0.0;  // largest bound among the nodes still to refine
    for (std::size_t i = 0; i < n; ++i) {
      if (options.list_over && bounds[i].lower > options.give_up_above) {
        over.push_back(active[i].source);  // decided: not refined further
        continue;
      }
      if (bounds[i].upper <= enough) {
        settled = std::max(settled, bounds[i].upper);
      } else {
        open = std::max(open, bounds[i].upper);
        split.push_back(static_cast<std::uint32_t>(i));
      }
    }
    const std::size_t affordable = out.queries < max_queries ? (max_queries - out.queries) / 7 : 0;
    if (split.empty() || round + 1 >= options.max_rounds || affordable == 0) {
      out.converged = split.empty();
      out.upper = std::max({settled, open, out.lower});
      return over.empty() ? out : give_up();
    }
    if (split.size() > affordable / kDeepFraction) {
      // A round spends at most a part of what is left, on the worst nodes (ties by position, so the choice is
      // the same on any thread count); the others wait with their bounds. Where the allowance cannot settle
      // every node, the worst, which bound the result, are then split again in the rounds after rather than
      // the allowance spread over nodes that do not decide it.
      const std::size_t take = std::max<std::size_t>(1, affordable / kDeepFraction);
      std::stable_sort(split.begin(), split.end(),
                       [&](std::uint32_t x, std::uint32_t y) { return bounds[x].upper > bounds[y].upper; });
      for (std::size_t k = take; k < split.size(); ++k) {
        waiting.push_back(active[split[k]]);
        waiting_bounds.push_back(bounds[split[k]]);
      }
      split.resize(take);
      std::sort(split.begin(), split.end());
    }
    // Split each into four at its edge midpoints (measured here, once per split).
    next.resize(4 * split.size());
    parallel_ranges(arena, split.size(), 64, [&](std::size_t b, std::size_t e) {
      for (std::size_t s = b; s < e; ++s) {
        const Node& q = active[split[s]];
        Node m;  // the middle child: corners at the midpoints of q's edges 0-1, 1-2, 2-0
        for (int k = 0; k < 3; ++k) {
          m.p[k] = (q.p[k] + q.p[(k + 1) % 3]) * 0.5;
          m.h[k] = query(target.bvh, m.p[k], q.h[k].triangle);
        }
        Node* c = &next[4 * s];
        m.cap = q.cap;
        m.source = q.source;
        c[0] = {{q.p[0], m.p[0], m.p[2]}, {q.h[0], m.h[0], m.h[2]}, q.cap, q.source};
        c[1] = {{m.p[0], q.p[1], m.p[1]}, {m.h[0], q.h[1], m.h[1]}, q.cap, q.source};
        c[2] = {{m.p[2], m.p[1], q.p[2]}, {m.h[2], m.h[1], q.h[2]}, q.cap, q.source};
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

}  // namespace

DistanceBound distance_bound(const Mesh& mesh, const SurfaceIndex& target, const DistanceBoundOptions& options) {
  std::vector<Vec3d> positions;
  positions.reserve(mesh.vertex_count());
  for (const Vec3f& p : mesh.positions) positions.push_back(to_double(p));
  return bound_triangles(positions, triangle_vertex_indices(mesh), target, options);
}

DistanceBound distance_bound(const SurfaceIndex& surface, const SurfaceIndex& target, const DistanceBoundOptions& options) {
  return bound_triangles(surface.positions, surface.indices, target, options);
}

}  // namespace lodforge
