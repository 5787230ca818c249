// Quadric error metric (Garland & Heckbert, "Surface Simplification Using Quadric Error Metrics",
// SIGGRAPH 1997), with the rubber-band point quadric of van den Bergen (GDC 2021, the same idea meshoptimizer
// uses as regularisation) and the perpendicular boundary constraint planes of GH97 section 6.
//
// A quadric Q = (A, b, c) measures E(x) = xᵀAx + 2bᵀx + c. A plane n·x + d = 0 with weight w gives
// A = w n nᵀ, b = w d n, c = w d², so E(x) = w (n·x + d)² is the weighted squared distance to the plane.
// Quadrics add; the minimiser of E solves A x = −b.
//
// All arithmetic is double: c = d² loses precision quickly in float, even after the simplifier has rescaled
// positions to the unit cube.
#pragma once

#include <array>
#include <cmath>
#include <optional>

#include "lodforge/core/vec.hpp"

namespace lodforge {

struct Quadric {
  // Symmetric A stored as its upper triangle.
  double a00 = 0, a01 = 0, a02 = 0, a11 = 0, a12 = 0, a22 = 0;
  double b0 = 0, b1 = 0, b2 = 0;
  double c = 0;
  // Accumulated surface area behind the quadric (plane weights of faces only). E(x) / weight is a weighted
  // mean squared distance, which is what a user tolerance in model units compares against. Boundary
  // constraint planes and point quadrics do not add to it: they are penalties, not surface.
  double weight = 0;

  // w (n·x + d)² for the plane n·x + d = 0 (n of unit length). Adds nothing to `weight`.
  static Quadric from_plane(const Vec3d& n, double d, double w);
  // Area-weighted plane quadric of a triangle; zero (all fields 0) for a degenerate triangle.
  // weight = area.
  static Quadric from_triangle(const Vec3d& p0, const Vec3d& p1, const Vec3d& p2);
  // The plane that contains the edge p0-p1 and is perpendicular to the face with (unnormalised, non-zero)
  // normal `face_normal`, weighted by `w` × |p1 − p0|² so that it scales like an area-weighted face quadric.
  // Zero when the edge or the normal is degenerate.
  static Quadric from_boundary_edge(const Vec3d& p0, const Vec3d& p1, const Vec3d& face_normal, double w);
  // w |x − p|²: pulls a vertex towards p ("rubber band"); makes A positive definite.
  static Quadric from_point(const Vec3d& p, double w);

  Quadric& operator+=(const Quadric& q);
  friend Quadric operator+(Quadric a, const Quadric& b) { return a += b; }
  Quadric& operator*=(double s);

  // E(x), clamped at 0 (rounding can make it slightly negative).
  double evaluate(const Vec3d& x) const;

  // The minimiser of E when A is well conditioned: LDLᵀ of the 3×3 system without pivoting, accepted when
  // every pivot exceeds min_pivot_relative × trace(A) (A is positive semi-definite, so a small pivot means a
  // nearly flat direction in which the minimiser would run off along roundoff; kMinPivotRelative is the
  // numerical floor). Empty otherwise.
  std::optional<Vec3d> minimizer(double min_pivot_relative = 1e-9) const;
};

// A pivot below this fraction of trace(A) means the quadric is numerically flat in some direction: planar
// patches (rank 1) and creases (rank 2), up to roundoff. 1e-9 keeps regularised quadrics (smallest eigenvalue
// ~1e-4 of the largest with a typical point weight) well inside the accepted range.
inline constexpr double kMinPivotRelative = 1e-9;
// How far from the edge midpoint, in edge lengths, an accepted minimiser may lie. Real corners put the
// minimiser within about one edge length; farther means an ill-conditioned direction the pivot test missed.
inline constexpr double kMaxReachEdgeLengths = 4.0;

// Where to put the vertex that replaces edge (p0, p1), and its error.
struct Placement {
  Vec3d position{};
  double error = 0;  // E(position), unnormalised
  bool optimal = false;  // true when the unconstrained minimiser was used
};

// Optimal placement with fallbacks, never NaN for finite input:
//  1. the minimiser of Q when it is well conditioned and not farther than kMaxReachEdgeLengths edge lengths
//     from the edge midpoint (a far minimiser of an almost-flat quadric moves the vertex along a direction
//     the error does not see, which folds triangles);
//  2. otherwise the best of p0, p1, the midpoint and the minimiser of E restricted to the segment p0-p1.
Placement place_on_edge(const Quadric& q, const Vec3d& p0, const Vec3d& p1);

namespace detail {
Placement place_on_segment(const Quadric& q, const Vec3d& p0, const Vec3d& p1);  // step 2 above
}  // namespace detail

// ---- inline definitions: these run several times per candidate evaluation ----

inline Quadric Quadric::from_plane(const Vec3d& n, double d, double w) {
  Quadric q;
  q.a00 = w * n[0] * n[0];
  q.a01 = w * n[0] * n[1];
  q.a02 = w * n[0] * n[2];
  q.a11 = w * n[1] * n[1];
  q.a12 = w * n[1] * n[2];
  q.a22 = w * n[2] * n[2];
  q.b0 = w * d * n[0];
  q.b1 = w * d * n[1];
  q.b2 = w * d * n[2];
  q.c = w * d * d;
  return q;
}

inline Quadric& Quadric::operator+=(const Quadric& q) {
  a00 += q.a00;
  a01 += q.a01;
  a02 += q.a02;
  a11 += q.a11;
  a12 += q.a12;
  a22 += q.a22;
  b0 += q.b0;
  b1 += q.b1;
  b2 += q.b2;
  c += q.c;
  weight += q.weight;
  return *this;
}

inline Quadric& Quadric::operator*=(double s) {
  a00 *= s;
  a01 *= s;
  a02 *= s;
  a11 *= s;
  a12 *= s;
  a22 *= s;
  b0 *= s;
  b1 *= s;
  b2 *= s;
  c *= s;
  weight *= s;
  return *this;
}

inline double Quadric::evaluate(const Vec3d& x) const {
  const double ax0 = a00 * x[0] + a01 * x[1] + a02 * x[2];
  const double ax1 = a01 * x[0] + a11 * x[1] + a12 * x[2];
  const double ax2 = a02 * x[0] + a12 * x[1] + a22 * x[2];
  const double e = x[0] * (ax0 + 2.0 * b0) + x[1] * (ax1 + 2.0 * b1) + x[2] * (ax2 + 2.0 * b2) + c;
  return e > 0.0 ? e : 0.0;
}

inline std::optional<Vec3d> Quadric::minimizer(double min_pivot_relative) const {
  const double trace = a00 + a11 + a22;
  if (!(trace > 0.0) || !std::isfinite(trace)) return std::nullopt;
  const double eps = min_pivot_relative * trace;
  // A = L D Lᵀ with unit lower-triangular L.
  const double d0 = a00;
  if (!(d0 > eps)) return std::nullopt;
  const double i0 = 1.0 / d0;
  const double l10 = a01 * i0, l20 = a02 * i0;
  const double d1 = a11 - l10 * a01;
  if (!(d1 > eps)) return std::nullopt;
  const double i1 = 1.0 / d1;
  const double l21 = (a12 - l20 * a01) * i1;
  const double d2 = a22 - l20 * a02 - l21 * l21 * d1;
  if (!(d2 > eps)) return std::nullopt;
  // Solve L y = −b, D z = y, Lᵀ x = z.
  const double y0 = -b0;
  const double y1 = -b1 - l10 * y0;
  const double y2 = -b2 - l20 * y0 - l21 * y1;
  const double x2 = y2 / d2;
  const double x1 = y1 * i1 - l21 * x2;
  const double x0 = y0 * i0 - l10 * x1 - l20 * x2;
  if (!(std::isfinite(x0) && std::isfinite(x1) && std::isfinite(x2))) return std::nullopt;
  return Vec3d{{x0, x1, x2}};
}

inline Placement place_on_edge(const Quadric& q, const Vec3d& p0, const Vec3d& p1) {
  if (const auto x = q.minimizer(kMinPivotRelative)) {
    const Vec3d edge = p1 - p0;
    const Vec3d off = *x - (p0 + p1) * 0.5;
    if (dot(off, off) <= kMaxReachEdgeLengths * kMaxReachEdgeLengths * dot(edge, edge)) {
      return {*x, q.evaluate(*x), true};
    }
  }
  return detail::place_on_segment(q, p0, p1);
}

}  // namespace lodforge
