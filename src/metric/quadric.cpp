// Quadric error metric: Garland & Heckbert 1997 (plane quadrics, boundary constraint planes, optimal
// placement with fallback to the edge), van den Bergen 2021 / meshoptimizer (point quadric regularisation).
#include "lodforge/metric/quadric.hpp"

#include <algorithm>
#include <cmath>

namespace lodforge {

Quadric Quadric::from_triangle(const Vec3d& p0, const Vec3d& p1, const Vec3d& p2) {
  const Vec3d n = cross(p1 - p0, p2 - p0);
  const double len = length(n);
  if (!(len > 0.0) || !std::isfinite(len)) return {};
  const Vec3d unit = n * (1.0 / len);
  const double area = 0.5 * len;
  Quadric q = from_plane(unit, -dot(unit, p0), area);
  q.weight = area;
  return q;
}

Quadric Quadric::from_boundary_edge(const Vec3d& p0, const Vec3d& p1, const Vec3d& face_normal, double w) {
  const Vec3d e = p1 - p0;
  const Vec3d m = cross(e, face_normal);
  const double len = length(m);
  if (!(len > 0.0) || !std::isfinite(len)) return {};
  const Vec3d unit = m * (1.0 / len);
  return from_plane(unit, -dot(unit, p0), w * dot(e, e));
}

Quadric Quadric::from_point(const Vec3d& p, double w) {
  Quadric q;
  q.a00 = q.a11 = q.a22 = w;
  q.b0 = -w * p[0];
  q.b1 = -w * p[1];
  q.b2 = -w * p[2];
  q.c = w * dot(p, p);
  return q;
}

namespace detail {

Placement place_on_segment(const Quadric& q, const Vec3d& p0, const Vec3d& p1) {
  // The best point of the edge. E(p0 + t e) = t² eᵀAe + 2t eᵀ(A p0 + b) + E(p0).
  const Vec3d edge = p1 - p0;
  const Vec3d mid = (p0 + p1) * 0.5;
  Placement best{p0, q.evaluate(p0), false};
  auto consider = [&](const Vec3d& p) {
    const double e = q.evaluate(p);
    if (e < best.error) best = {p, e, false};
  };
  consider(p1);
  consider(mid);
  const double ae0 = q.a00 * edge[0] + q.a01 * edge[1] + q.a02 * edge[2];
  const double ae1 = q.a01 * edge[0] + q.a11 * edge[1] + q.a12 * edge[2];
  const double ae2 = q.a02 * edge[0] + q.a12 * edge[1] + q.a22 * edge[2];
  const double eae = edge[0] * ae0 + edge[1] * ae1 + edge[2] * ae2;
  if (eae > 0.0) {
    // eᵀ(A p0 + b) = (A e)·p0 + e·b, using the symmetry of A.
    const double slope = ae0 * p0[0] + ae1 * p0[1] + ae2 * p0[2] + edge[0] * q.b0 + edge[1] * q.b1 + edge[2] * q.b2;
    const double t = std::clamp(-slope / eae, 0.0, 1.0);
    if (std::isfinite(t)) consider(p0 + edge * t);
  }
  return best;
}

}  // namespace detail

}  // namespace lodforge
