// Conservative collapses (SimplifyOptions::conservative): the half-space rule, the constrained placement and
// the volume bookkeeping of CollapseMesh.
//
// Collapsing a, b → x replaces the star S of a and b by a fan over the same link. The difference of the two
// surfaces bounds the tetrahedra conv(x, f), f in S, each counted with the sign of x against f's plane; so when
// x is in front of (bounding) or behind (occluder) every plane of S, the winding number of every point can only
// grow (or only shrink) and the new solid contains (or lies in) the old one. By induction the LOD nests with
// the input. Placement minimises the quadric plus the rubber band (positive definite) over that polyhedron with
// a small dual active-set method; the optimum has at most three active planes (G. van den Bergen, "Conservative
// Mesh Decimation for Collision Detection and Occlusion Culling", GDC 2021).
#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>

#include "collapse_mesh.hpp"

namespace lodforge::collapse {
namespace {

// Weight of the volume a bounding collapse adds in its cost (setup_conservative()).
constexpr double kVolumeCostWeight = 100.0;
// Planes whose unit normals and offsets agree this closely count as one (flat regions repeat their plane).
constexpr double kSamePlane = 1e-12;

// The KKT systems of the placement: three coordinates and at most three active planes (no heap).
using KktMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 6, 6>;
using KktVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 6, 1>;
// A KKT pivot this small against the largest counts as zero: the active planes are (nearly) dependent.
constexpr double kSingularPivot = 1e-14;

struct HalfSpace {
  Vec3d g;   // unit normal pointing to the allowed side
  double h;  // allowed: dot(g, x) >= h
};

}  // namespace

Vec3d CollapseMesh::output_rounded(const Vec3d& x) const {
  const Vec3f f = to_float(origin_ + x * scale_);
  return (to_double(f) - origin_) * (1.0 / scale_);
}

// Faces of a and b once each (the edge faces are in both stars), as f(face id, its three corners).
template <typename F>
static void for_each_star_face(const std::uint32_t* tri, const std::uint32_t* star_a, std::uint32_t na,
                               const std::uint32_t* star_b, std::uint32_t nb, std::uint32_t a, F&& f) {
  for (std::uint32_t i = 0; i < na; ++i) {
    const std::uint32_t* t = &tri[3 * std::size_t{star_a[i]}];
    f(t);
  }
  for (std::uint32_t i = 0; i < nb; ++i) {
    const std::uint32_t* t = &tri[3 * std::size_t{star_b[i]}];
    if (t[0] == a || t[1] == a || t[2] == a) continue;  // an edge face, seen from a
    f(t);
  }
}

bool CollapseMesh::conservative_ok(std::uint32_t a, std::uint32_t b, const Vec3d& x) const {
  if (cons_side_ == 0.0) return true;
  bool ok = true;
  for_each_star_face(tri_.data(), star(a), size_[a], star(b), size_[b], a, [&](const std::uint32_t* t) {
    if (!ok) return;
    const Vec3d& p0 = vx_[t[0]].pos;
    const Vec3d& p1 = vx_[t[1]].pos;
    const Vec3d& p2 = vx_[t[2]].pos;
    // A face with a corner at x spans no volume with x (the survivor stays put, or the face dies).
    if (p0 == x || p1 == x || p2 == x) return;
    const Vec3d n = cross(p1 - p0, p2 - p0);
    const double len = length(n);
    if (!(len > 0.0)) return;  // a degenerate face encloses nothing
    const double side = cons_side_ * dot(n, x - p0) / len;
    ok = side >= cons_slack_;  // also false on NaN
  });
  return ok;
}

double CollapseMesh::volume_change(std::uint32_t a, std::uint32_t b, const Vec3d& x) const {
  double v = 0.0;
  for_each_star_face(tri_.data(), star(a), size_[a], star(b), size_[b], a, [&](const std::uint32_t* t) {
    const Vec3d& p0 = vx_[t[0]].pos;
    v += dot(cross(vx_[t[1]].pos - p0, vx_[t[2]].pos - p0), x - p0);
  });
  return v / 6.0 * scale_ * scale_ * scale_;
}

std::optional<Vec3d> CollapseMesh::conservative_place(std::uint32_t u, std::uint32_t v, const Quadric& surface) const {
  // The allowed side of every face plane around u and v, moved inward by the margin.
  std::array<HalfSpace, 64> small_planes;
  std::vector<HalfSpace> big_planes;
  std::size_t k = 0;
  const std::size_t cap = small_planes.size();
  auto add = [&](const HalfSpace& hs) {
    const HalfSpace* existing = k <= cap ? small_planes.data() : big_planes.data();
    for (std::size_t i = 0; i < k; ++i) {
      const HalfSpace& e = existing[i];
      if (std::abs(e.h - hs.h) < kSamePlane && dot(e.g, hs.g) > 1.0 - kSamePlane) {
        if (hs.h > e.h) (k <= cap ? small_planes[i] : big_planes[i]).h = hs.h;
        return;
      }
    }
    if (k < cap) {
      small_planes[k++] = hs;
      return;
    }
    if (k == cap) big_planes.assign(small_planes.begin(), small_planes.end());
    big_planes.push_back(hs);
    ++k;
  };
  for_each_star_face(tri_.data(), star(u), size_[u], star(v), size_[v], u, [&](const std::uint32_t* t) {
    const Vec3d& p0 = vx_[t[0]].pos;
    const Vec3d n = cross(vx_[t[1]].pos - p0, vx_[t[2]].pos - p0);
    const double len = length(n);
    if (!(len > 0.0) || !std::isfinite(len)) return;
    const Vec3d g = n * (cons_side_ / len);
    add({g, dot(g, p0) + cons_margin_});
  });
  const HalfSpace* planes = k <= cap ? small_planes.data() : big_planes.data();

  // E(x) = xᵀAx + 2bᵀx + c: the surface quadric and the rubber band.
  const Quadric q = with_rubber_band(surface, u, v, cons_band_);
  const double A[3][3] = {{q.a00, q.a01, q.a02}, {q.a01, q.a11, q.a12}, {q.a02, q.a12, q.a22}};
  const double bvec[3] = {q.b0, q.b1, q.b2};
  // Energy for ranking feasible points (the constant c does not matter).
  auto energy = [&](const Vec3d& x) {
    double e = 0.0;
    for (int i = 0; i < 3; ++i) {
      e += x[i] * (A[i][0] * x[0] + A[i][1] * x[1] + A[i][2] * x[2] + 2.0 * bvec[i]);
    }
    return e;
  };
  // Tolerance of the solve's own feasibility test: half the margin (the rounded point is tested exactly).
  const double tol = 0.5 * cons_margin_;

  // Goldfarb and Idnani's dual active-set method (Math. Programming 27, 1983), n = 3: start at the
  // unconstrained minimiser and add the most violated plane, dropping planes whose multipliers reach zero on the
  // way, until none is violated; the KKT systems of at most three active planes are solved afresh each step.
  // A violated plane that no step can satisfy proves the polyhedron empty.
  // With A positive definite (the rubber band makes it so) the system reduces to the m x m Schur complement
  // S = Nᵀ A⁻¹ N of the active normals N: x = A⁻¹ (rhs_x + N μ), S μ = rhs_c − Nᵀ A⁻¹ rhs_x. Otherwise the whole
  // KKT matrix is factored.
  const Eigen::Matrix3d a_matrix{{A[0][0], A[0][1], A[0][2]}, {A[1][0], A[1][1], A[1][2]}, {A[2][0], A[2][1], A[2][2]}};
  const Eigen::LLT<Eigen::Matrix3d> a_llt(a_matrix);
  const bool schur =
      a_llt.info() == Eigen::Success &&
      a_llt.matrixLLT().diagonal().minCoeff() > std::sqrt(kSingularPivot) * a_llt.matrixLLT().diagonal().maxCoeff();
  const Eigen::Matrix3d a_inverse =
      schur ? Eigen::Matrix3d(a_llt.solve(Eigen::Matrix3d::Identity())) : Eigen::Matrix3d();
  auto kkt_schur = [&](const std::size_t* act, int m, const Vec3d& rhs_x, const double* rhs_c, Vec3d& x, double* mu) {
    const Eigen::Vector3d rx(rhs_x[0], rhs_x[1], rhs_x[2]);
    const Eigen::Vector3d x0 = a_inverse * rx;
    if (m == 0) {
      x = Vec3d{{x0(0), x0(1), x0(2)}};
      return x0.allFinite();
    }
    Eigen::Matrix<double, 3, 3> n = Eigen::Matrix3d::Zero();
    for (int c = 0; c < m; ++c) {
      const HalfSpace& p = planes[act[c]];
      n.col(c) = Eigen::Vector3d(p.g[0], p.g[1], p.g[2]);
    }
    const Eigen::Matrix3d ain = a_inverse * n;
    Eigen::Vector3d mu_v = Eigen::Vector3d::Zero();
    if (m == 1) {
      const double s = n.col(0).dot(ain.col(0));
      if (!(s > kSingularPivot * a_inverse.diagonal().maxCoeff())) return false;
      mu_v(0) = (rhs_c[0] - n.col(0).dot(x0)) / s;
    } else {
      Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 3, 3> sm = n.leftCols(m).transpose() * ain.leftCols(m);
      Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 3, 1> rs(m);
      for (int c = 0; c < m; ++c) rs(c) = rhs_c[c] - n.col(c).dot(x0);
      const Eigen::LLT<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 3, 3>> s_llt(sm);
      if (s_llt.info() != Eigen::Success) return false;
      const auto d = s_llt.matrixLLT().diagonal();
      if (!(d.minCoeff() * d.minCoeff() > kSingularPivot * sm.diagonal().maxCoeff())) return false;
      const auto sol = s_llt.solve(rs);
      for (int c = 0; c < m; ++c) mu_v(c) = sol(c);
    }
    const Eigen::Vector3d xs = x0 + ain.leftCols(m) * mu_v.head(m);
    if (!xs.allFinite() || !mu_v.allFinite()) return false;
    x = Vec3d{{xs(0), xs(1), xs(2)}};
    for (int c = 0; c < m; ++c) mu[c] = mu_v(c);
    return true;
  };
  auto kkt = [&](const std::size_t* act, int m, const Vec3d& rhs_x, const double* rhs_c, Vec3d& x, double* mu) {
    if (schur) return kkt_schur(act, m, rhs_x, rhs_c, x, mu);
    KktMatrix M = KktMatrix::Zero(3 + m, 3 + m);
    KktVector r(3 + m);
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) M(i, j) = A[i][j];
      r(i) = rhs_x[i];
    }
    for (int c = 0; c < m; ++c) {
      const HalfSpace& p = planes[act[c]];
      for (int i = 0; i < 3; ++i) {
        M(i, 3 + c) = -p.g[i];
        M(3 + c, i) = p.g[i];
      }
      r(3 + c) = rhs_c[c];
    }
    Eigen::FullPivLU<KktMatrix> lu(M);
    lu.setThreshold(kSingularPivot);
    if (!lu.isInvertible()) return false;
    const KktVector y = lu.solve(r);
    if (!y.allFinite()) return false;
    x = Vec3d{{y(0), y(1), y(2)}};
    for (int c = 0; c < m; ++c) mu[c] = y(3 + c);
    return true;
  };
  std::optional<Vec3d> best;
  {
    std::size_t act[3];
    double mu[3] = {0, 0, 0};
    int na = 0;
    Vec3d x;
    const double zero[3] = {0, 0, 0};
    bool ok = kkt(act, 0, Vec3d{{-bvec[0], -bvec[1], -bvec[2]}}, zero, x, mu);
    const int max_steps = 4 * static_cast<int>(k) + 16;
    for (int step = 0; ok && step < max_steps; ++step) {
      std::size_t p = k;
      double worst = -tol;
      for (std::size_t i = 0; i < k; ++i) {
        const double sl = dot(planes[i].g, x) - planes[i].h;
        if (sl < worst) {
          worst = sl;
          p = i;
        }
      }
      if (p == k) {
        best = x;
        break;
      }
      double mu_p = 0.0;
      bool added = false;
      for (; ok && !added && step < max_steps; ++step) {
        const Vec3d& gp = planes[p].g;
        bool dependent = na == 3;
        if (na == 1) dependent = length(cross(gp, planes[act[0]].g)) < 1e-9;
        if (na == 2) dependent = std::abs(dot(gp, cross(planes[act[0]].g, planes[act[1]].g))) < 1e-9;
        Vec3d z;
        double rk[3] = {0, 0, 0};
        if (!kkt(act, na, gp, zero, z, rk)) {
          ok = false;
          break;
        }
        // Along the step, the active multipliers change by −t r with r = −rk.
        double t1 = std::numeric_limits<double>::infinity();
        int drop = -1;
        for (int j = 0; j < na; ++j) {
          const double r = -rk[j];
          if (r > 1e-14 && mu[j] / r < t1) {
            t1 = mu[j] / r;
            drop = j;
          }
        }
        double t2 = std::numeric_limits<double>::infinity();
        if (!dependent) {
          const double zn = dot(z, gp);
          if (zn > 0.0) t2 = (planes[p].h - dot(gp, x)) / zn;
        }
        if (!std::isfinite(t1) && !std::isfinite(t2)) {
          ok = false;  // empty: no allowed point
          break;
        }
        const double t = std::min(t1, t2);
        if (std::isfinite(t2)) x = x + z * t;
        for (int j = 0; j < na; ++j) mu[j] += t * rk[j];
        mu_p += t;
        if (t2 <= t1) {
          act[na] = p;
          mu[na] = mu_p;
          ++na;
          added = true;
        } else {
          for (int j = drop; j + 1 < na; ++j) {
            act[j] = act[j + 1];
            mu[j] = mu[j + 1];
          }
          --na;
        }
      }
    }
  }
  if (best) {
    const Vec3d x = output_rounded(*best);
    if (conservative_ok(u, v, x)) return x;
  }
  // Cheap fallbacks: the endpoints (exact already) and the midpoint, the one with the least energy.
  std::optional<Vec3d> fallback;
  double fallback_e = std::numeric_limits<double>::infinity();
  const Vec3d& pu = vx_[u].pos;
  const Vec3d& pv = vx_[v].pos;
  for (const Vec3d& p : {pu, pv, output_rounded((pu + pv) * 0.5)}) {
    const double e = energy(p);
    if (e < fallback_e && conservative_ok(u, v, p)) {
      fallback_e = e;
      fallback = p;
    }
  }
  return fallback;
}

// An open rim has no inside to nest: its vertices stay where they are. Seen along the axis closest to the
// mesh's mean normal (up, for a terrain), a rim vertex whose two rim edges continue each other in a straight line
// may still be removed onto a neighbour on the rim: the rim's outline is then unchanged (a terrain tile keeps
// its straight sides) and the half-space rule on the faces around it keeps the surface on its side.
void CollapseMesh::setup_rim() {
  const std::size_t nv = vx_.size();
  std::vector<std::uint32_t> ends;  // per vertex: neighbours met once (rim edges), as collected
  Vec3d normal{};
  for (std::size_t f = 0; f < face_slots(); ++f) {
    const std::uint32_t* t = &tri_[3 * f];
    const Vec3d n = cross(vx_[t[1]].pos - vx_[t[0]].pos, vx_[t[2]].pos - vx_[t[0]].pos);
    if (finite3(n)) normal = normal + n;
  }
  int up = 0;
  for (int i = 1; i < 3; ++i) {
    if (std::abs(normal[i]) > std::abs(normal[up])) up = i;
  }
  const int i0 = (up + 1) % 3, i1 = (up + 2) % 3;
  bool any = false;
  std::vector<std::uint8_t> rim(nv, 0);
  std::vector<std::uint32_t> nb;
  for (std::uint32_t v = 0; v < nv; ++v) {
    if (size_[v] == 0 || kind_[v] == VertexKind::frozen) continue;
    nb.clear();
    const std::uint32_t* fl = star(v);
    for (std::uint32_t i = 0; i < size_[v]; ++i) {
      const std::uint32_t* t = &tri_[3 * std::size_t{fl[i]}];
      for (int j = 0; j < 3; ++j) {
        if (t[j] != v) nb.push_back(t[j]);
      }
    }
    std::sort(nb.begin(), nb.end());
    ends.clear();
    for (std::size_t i = 0; i < nb.size();) {
      std::size_t j = i;
      while (j < nb.size() && nb[j] == nb[i]) ++j;
      if (j - i == 1) ends.push_back(nb[i]);
      i = j;
    }
    if (ends.empty()) continue;
    any = true;
    rim[v] = kRimFixed;
    if (ends.size() != 2 || kind_[v] == VertexKind::locked) continue;
    const Vec3d& p = vx_[ends[0]].pos;
    const Vec3d& q = vx_[ends[1]].pos;
    const Vec3d& a = vx_[v].pos;
    const double e0 = a[i0] - p[i0], e1 = a[i1] - p[i1], f0 = q[i0] - a[i0], f1 = q[i1] - a[i1];
    const double cr = e0 * f1 - e1 * f0, dt = e0 * f0 + e1 * f1;
    const double len2 = (e0 * e0 + e1 * e1) * (f0 * f0 + f1 * f1);
    if (dt > 0.0 && cr * cr <= 1e-24 * len2) rim[v] = kRimStraight;
  }
  if (any) rim_.swap(rim);
}

void CollapseMesh::setup_conservative() {
  if (options_.conservative == Conservative::none) return;
  cons_side_ = options_.conservative == Conservative::bounding ? 1.0 : -1.0;
  // Rounding a coordinate to float moves it by at most 2⁻²⁴ of its magnitude; a LOD may reach about one
  // extent beyond the input's box. The placement aims that far (and the slack) inside the allowed side, and
  // the rounded point is then tested with the slack alone.
  double magnitude = 0.0;
  for (int i = 0; i < 3; ++i) magnitude = std::max(magnitude, std::abs(origin_[i]) + 2.0 * scale_);
  const double rounding = std::sqrt(3.0) * std::ldexp(magnitude, -24) / scale_;
  cons_slack_ = 1e-9;
  // Bounding hulls grow where the quadric sees little error (thin parts, saddles): the volume a collapse adds
  // joins its cost, as a length (the input's mean edge scale) times the volume. On the closed scanned corpus at
  // 2% (lodforge_bench_conservative), weight 100 lowers the volume overhead of dragon from 21.7% to 17.7% and of
  // lucy from 17.1% to 15.4% (1 and 10 gain less, 100000 orders by volume alone and loses: dragon 36.8%).
  // Occluders keep the quadric alone: the term cost them silhouette (dragon 93.6% -> 91.4%).
  if (options_.conservative == Conservative::bounding) cons_volume_weight_ = kVolumeCostWeight;
  cons_margin_ = 1.5 * rounding + 2.0 * cons_slack_;
  cons_band_ = reg_weight_ > 0.0 ? reg_weight_ : 1e-3 * mean_area_;
  if (!(cons_band_ > 0.0)) cons_band_ = 1e-12;
  setup_rim();
  double vol = 0.0;
  for (std::size_t f = 0; f < face_slots(); ++f) {
    const std::uint32_t* t = &tri_[3 * f];
    vol += dot(cross(vx_[t[0]].pos, vx_[t[1]].pos), vx_[t[2]].pos);
  }
  input_volume_ = vol / 6.0 * scale_ * scale_ * scale_;
}

}  // namespace lodforge::collapse
