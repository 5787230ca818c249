// An error budget held while the engine runs (GuardReference, collapse_mesh.hpp).
//
// Every sample point of the reference (its vertices and triangle centroids) is attached to one working face
// within the budget of it. A collapse rewrites only the faces around its edge, so only the samples attached
// there can move away from the surface: check() asks whether each of them is within the budget of some face
// the collapse leaves around the new vertex, and whether the new vertex and the new faces' sample points are
// within 0.7 of the budget of the reference; apply() attaches those samples to their nearest new face. The
// distance to the attached face is at least the distance to the whole mesh, so the output passes the
// measurement's samples both ways by construction, at a cost linear in the collapses. Output → reference is
// held below the budget at the samples, on a grid twice as fine as the measurement's, because the engine,
// refused only where a sample fails, pushes every face to the limit, and the surface between samples may lie
// farther (docs/budgets.md, "The guarded engine").
#include <algorithm>
#include <cfloat>
#include <cmath>
#include <limits>
#include <vector>

#include "collapse_mesh.hpp"

namespace lodforge::collapse {
namespace {

// The largest distance from a point of triangle pqr to its nearest corner: the circumradius where the triangle
// is acute (the circumcentre is that point), else at most half the longest edge (the farthest point lies on an
// edge).
double cover_radius(const Vec3d& p, const Vec3d& q, const Vec3d& r) {
  const Vec3d e0 = q - p, e1 = r - q, e2 = p - r;
  const double l0 = dot(e0, e0), l1 = dot(e1, e1), l2 = dot(e2, e2);
  double cover = 0.5 * std::sqrt(std::max({l0, l1, l2}));
  if (dot(e0, r - p) > 0 && dot(e1, p - q) > 0 && dot(e2, q - r) > 0) {
    const Vec3d n = cross(e0, r - p);
    const double twice_area = std::sqrt(dot(n, n));
    if (twice_area > 0) cover = std::max(cover, std::sqrt(l0 * l1 * l2) / (2.0 * twice_area));
  }
  return cover;
}

double distance_sq(const Vec3d& p, const std::array<Vec3d, 3>& t) {
  const Vec3d q = closest_point_on_triangle(p, t[0], t[1], t[2]).point;
  return dot(p - q, p - q);
}

// A face's sample points must lie this much closer than the budget: the surface may be farther between them.
constexpr double kSampleReach = 0.7;
// Faces are also sampled on a grid this much finer than the measurement's.
constexpr double kDenseSpacing = 0.5;

// In a dense region, faces are also tested on a grid of this spacing (in budgets), at most kMaxFineGrid steps
// per edge: 0.7 of the budget at the grid points plus a cell's cover (at most 0.58 of its longest edge) stays
// under the budget.
constexpr double kFineSpacing = 0.5;
constexpr int kMaxFineGrid = 64;

bool overlaps(const Bounds3& a, const Bounds3& b) {
  for (int k = 0; k < 3; ++k) {
    if (a.max[k] < b.min[k] || b.max[k] < a.min[k]) return false;
  }
  return true;
}

// Samples whose attached face keeps them this close (in budgets) stay where they are when the face changes.
constexpr double kStayFraction = 0.25;

// Triangle t's unit normal and offset: |n·p - offset| is p's distance to its plane, which no point of t is
// nearer than. Zero (no pruning) where t has no normal it can trust: on a sliver (an angle under about 1e-6)
// the cross product's direction carries the rounding of its edges divided by that angle.
std::array<double, 4> plane_of(const std::array<Vec3d, 3>& t) {
  const Vec3d e1 = t[1] - t[0], e2 = t[2] - t[0];
  const Vec3d n = cross(e1, e2);
  const double nn = dot(n, n);
  if (!(nn > 1e-12 * dot(e1, e1) * dot(e2, e2)) || !std::isfinite(nn)) return {0, 0, 0, 0};
  const double length = std::sqrt(nn);
  const Vec3d u = n * (1.0 / length);
  return {u[0], u[1], u[2], dot(u, t[0])};
}

// Whether triangle t, whose plane is `plane`, cannot be strictly nearer p than `best_sq`: its plane is
// farther, by a margin far above the rounding of either distance (normalised coordinates are about 1).
bool plane_beyond(const Vec3d& p, const std::array<double, 4>& plane, double best_sq) {
  const double h = std::abs(plane[0] * p[0] + plane[1] * p[1] + plane[2] * p[2] - plane[3]);
  return h > std::sqrt(best_sq) + 1e-9;
}

}  // namespace

// Whether the sample points of triangle pqr (model units; for_each_face_sample, the measurement's own) lie
// within kSampleReach of the guard's budget of the reference.
bool CollapseMesh::face_within(const Vec3d& p, const Vec3d& q, const Vec3d& r, std::uint32_t& hint) const {
  const double reach = kSampleReach * guard_budget_;
  auto near = [&](const Vec3d& y) { return guard_bvh_->any_within(y, reach, hint); };
  // The dense grid skips the points of the measurement's grid that it shares (the same u, v: the same point).
  if (!for_each_face_sample(p, q, r, guard_spacing_, near) ||
      !for_each_grid_point(p, q, r, kDenseSpacing * guard_spacing_, near, grid_steps(p, q, r, guard_spacing_))) {
    return false;
  }
  return !in_dense_region(p, q, r) ||
         for_each_grid_point(p, q, r, kFineSpacing * guard_budget_, near, 0, kMaxFineGrid);
}

bool CollapseMesh::in_dense_region(const Vec3d& p, const Vec3d& q, const Vec3d& r) const {
  if (guard_dense_.empty()) return false;
  Bounds3 box;
  box.add(p);
  box.add(q);
  box.add(r);
  return std::any_of(guard_dense_.begin(), guard_dense_.end(), [&](const Bounds3& d) { return overlaps(box, d); });
}

int CollapseMesh::guard_steps(const Vec3d& p, const Vec3d& q, const Vec3d& r) const {
  // The edge midpoints where the triangle is too small for a grid: a lattice of 2 steps.
  const int steps = std::max(grid_steps(p, q, r, kDenseSpacing * guard_spacing_), guard_spacing_ > 0 ? 2 : 1);
  if (!in_dense_region(p, q, r)) return steps;
  return std::max(steps, grid_steps(p, q, r, kFineSpacing * guard_budget_, kMaxFineGrid));
}

double CollapseMesh::guarded_face_bound(const Vec3d& p, const Vec3d& q, const Vec3d& r, double corners) const {
  // Every point of the triangle is within cover(pqr) / steps of a point of a lattice the guard tested (its
  // corners included), and the distance to a surface is 1-Lipschitz.
  const int steps = guard_steps(p, q, r);
  return std::max(corners, kSampleReach * guard_budget_) + cover_radius(p, q, r) / steps + guard_rounding_;
}

void CollapseMesh::store_guard_outputs() const {
  if (guard_bounds_out_ != nullptr) {
    guard_bounds_out_->clear();
    for (std::size_t f = 0; f < guard_face_bound_.size(); ++f) {
      if (tri_[3 * f] != kInvalidIndex) guard_bounds_out_->push_back(guard_face_bound_[f]);
    }
  }
  if (guard_sample_faces_out_ != nullptr) {
    std::vector<std::uint32_t>& out = *guard_sample_faces_out_;
    out.assign(guard_samples_.size(), kInvalidIndex);
    std::uint32_t at = 0;  // output() keeps the alive faces in slot order
    for (std::size_t f = 0; f < guard_head_.size(); ++f) {
      if (tri_[3 * f] == kInvalidIndex) continue;
      for (std::uint32_t smp = guard_head_[f]; smp != kInvalidIndex; smp = guard_next_[smp]) out[smp] = at;
      ++at;
    }
  }
}

void CollapseMesh::setup_guard(const GuardReference& g, Parallel& parallel) {
  // The output's positions are rounded to float; a margin of a few float steps of the largest coordinate keeps
  // the rounded output within the budget.
  double largest = 0.0;
  const Bounds3 rb = g.bvh->bounds();
  if (!rb.empty()) {
    for (int k = 0; k < 3; ++k) largest = std::max({largest, std::abs(rb.min[k]), std::abs(rb.max[k])});
  }
  for (int k = 0; k < 3; ++k) {
    largest = std::max({largest, std::abs(origin_[k]), std::abs(origin_[k] + scale_)});
  }
  guard_budget_ = g.budget - 8.0 * FLT_EPSILON * largest;
  if (!(guard_budget_ > 0.0)) guard_budget_ = 0.0;
  guard_budget2_ = (guard_budget_ / scale_) * (guard_budget_ / scale_);
  guard_spacing_ = g.grid_spacing;
  guard_bvh_ = g.bvh;
  guard_dense_.assign(g.dense_regions.begin(), g.dense_regions.end());

  // Each sample to a working face: where the reference is the input, the face it lies on (its own triangle, or
  // one around its vertex); the rest to the nearest face (a BVH over the faces as they are now).
  const std::size_t nf = tri_.size() / 3;
  const double inv = 1.0 / scale_;
  const std::size_t ns = g.samples.size();
  guard_samples_.resize(ns);
  std::vector<std::uint32_t> face_of(ns, kInvalidIndex);
  std::vector<std::uint32_t> slot_of;
  const bool start_faces = g.origins.size() != ns && !g.start_faces.empty() && g.start_faces.size() <= ns;
  if (g.origins.size() == ns || start_faces) {
    slot_of.assign(src_.face_count(), kInvalidIndex);
    for (std::size_t f = 0; f < nf; ++f) slot_of[source_face(f)] = static_cast<std::uint32_t>(f);
  }
  if (g.origins.size() == ns) {
    for (std::size_t i = 0; i < ns; ++i) {
      const std::uint32_t o = g.origins[i];
      if (o & kCentroidOrigin) {
        const std::uint32_t t = o & ~kCentroidOrigin;
        face_of[i] = t < slot_of.size() ? slot_of[t] : kInvalidIndex;
      } else if (o < size_.size() && size_[o] > 0) {
        face_of[i] = star(o)[0];
      }
    }
  }
  for (std::size_t i = 0; i < ns; ++i) guard_samples_[i] = (g.samples[i] - origin_) * inv;
  if (start_faces) {
    // Kept only where within the budget, as every attachment is. (Lattice points a rerun added have none.)
    parallel.for_ranges(g.start_faces.size(), 4096, [&](std::size_t b, std::size_t e) {
      for (std::size_t i = b; i < e; ++i) {
        const std::uint32_t t = g.start_faces[i];
        if (t >= slot_of.size() || slot_of[t] == kInvalidIndex) continue;
        const std::uint32_t* c = &tri_[3 * std::size_t{slot_of[t]}];
        if (distance_sq(guard_samples_[i], {vx_[c[0]].pos, vx_[c[1]].pos, vx_[c[2]].pos}) <= guard_budget2_) {
          face_of[i] = slot_of[t];
        }
      }
    });
  }
  std::vector<std::size_t> unplaced;
  for (std::size_t i = 0; i < ns; ++i) {
    if (face_of[i] == kInvalidIndex && finite3(guard_samples_[i])) unplaced.push_back(i);
  }
  if (!unplaced.empty()) {
    std::vector<Vec3d> positions(vx_.size());
    for (std::size_t v = 0; v < vx_.size(); ++v) positions[v] = vx_[v].pos;
    const TriangleBvh faces(positions, tri_);
    constexpr std::size_t kChunk = 1024;
    const std::size_t nu = unplaced.size();
    parallel.for_ranges((nu + kChunk - 1) / kChunk, 1, [&](std::size_t cb, std::size_t ce) {
      for (std::size_t c = cb; c < ce; ++c) {
        std::uint32_t hint = kInvalidIndex;  // samples come in surface order: the last answer is near the next
        for (std::size_t k = c * kChunk; k < std::min(nu, (c + 1) * kChunk); ++k) {
          const std::size_t i = unplaced[k];
          const BvhHit h = faces.closest_point(guard_samples_[i], hint);
          if (h.found()) hint = face_of[i] = h.triangle;
        }
      }
    });
  }
  guard_head_.assign(nf, kInvalidIndex);
  guard_next_.assign(ns, kInvalidIndex);
  for (std::size_t i = ns; i-- > 0;) {  // each face's list in sample order
    const std::uint32_t f = face_of[i];
    if (f == kInvalidIndex) continue;
    guard_next_[i] = guard_head_[f];
    guard_head_[f] = static_cast<std::uint32_t>(i);
  }
  guard_hint_.assign(vx_.size(), kInvalidIndex);

  // Bounds on the distances as they start: zero where the reference is the input (its own triangles);
  // otherwise each vertex measured, and each face within its farthest corner's distance plus its cover.
  guard_rounding_ = 2.0 * FLT_EPSILON * largest;
  guard_bounds_out_ = g.face_bounds;
  guard_sample_faces_out_ = g.sample_faces;
  guard_vertex_bound_.assign(vx_.size(), 0.0);
  guard_face_bound_.assign(nf, 0.0);
  if (g.origins.size() != ns) {
    parallel.for_ranges(vx_.size(), 1024, [&](std::size_t b, std::size_t e) {
      for (std::size_t v = b; v < e; ++v) {
        if (size_[v] == 0) continue;
        guard_vertex_bound_[v] = g.bvh->closest_point(model_position(vx_[v].pos)).distance() + guard_rounding_;
      }
    });
    for (std::size_t f = 0; f < nf; ++f) {
      const std::uint32_t* t = &tri_[3 * f];
      if (t[0] == kInvalidIndex) continue;
      const Vec3d p = model_position(vx_[t[0]].pos), q = model_position(vx_[t[1]].pos), r = model_position(vx_[t[2]].pos);
      guard_face_bound_[f] = std::max({guard_vertex_bound_[t[0]], guard_vertex_bound_[t[1]], guard_vertex_bound_[t[2]]}) +
                             cover_radius(p, q, r) + guard_rounding_;
    }
  }
}

bool CollapseMesh::guard_ok(std::uint32_t a, std::uint32_t b, const Check& c, const Vec3d& x, Scratch& s) const {
  auto is_edge_face = [&](std::uint32_t f) { return f == c.edge_faces[0] || f == c.edge_faces[1]; };
  // The faces the collapse leaves around the new vertex, with a and b at x.
  s.fan.clear();
  for (const std::uint32_t w : {a, b}) {
    const std::uint32_t* fl = star(w);
    for (std::uint32_t i = 0; i < size_[w]; ++i) {
      if (is_edge_face(fl[i])) continue;
      const std::uint32_t* t = &tri_[3 * std::size_t{fl[i]}];
      std::array<Vec3d, 3> corners;
      for (int k = 0; k < 3; ++k) corners[k] = t[k] == a || t[k] == b ? x : vx_[t[k]].pos;
      s.fan.push_back(corners);
    }
  }
  // Output → reference: the new vertex, then every new face.
  std::uint32_t hint = guard_hint_[b] != kInvalidIndex ? guard_hint_[b] : guard_hint_[a];
  if (!guard_bvh_->any_within(model_position(x), kSampleReach * guard_budget_, hint)) return false;
  for (const std::array<Vec3d, 3>& t : s.fan) {
    if (!face_within(model_position(t[0]), model_position(t[1]), model_position(t[2]), hint)) return false;
  }
  const bool b_stays = vx_[b].pos == x;
  // Reference → output: the samples attached to every face that changes or dies (a's, the edge faces among
  // them; a half-edge collapse leaves the survivor's other faces where they are).
  std::size_t last = 0;
  for (const std::uint32_t w : {a, b}) {
    if (w == b && b_stays) continue;
    const std::uint32_t* fl = star(w);
    for (std::uint32_t i = 0; i < size_[w]; ++i) {
      const std::uint32_t f = fl[i];
      if (w == b && is_edge_face(f)) continue;  // seen from a
      for (std::uint32_t smp = guard_head_[f]; smp != kInvalidIndex; smp = guard_next_[smp]) {
        const Vec3d& p = guard_samples_[smp];
        // A face's samples lie close together: the face that held the last one is tried first.
        bool within = false;
        for (std::size_t n = 0, k = last; n < s.fan.size(); ++n, k = k + 1 == s.fan.size() ? 0 : k + 1) {
          if (distance_sq(p, s.fan[k]) <= guard_budget2_) {
            within = true;
            last = k;
            break;
          }
        }
        if (!within) return false;
      }
    }
  }
  return true;
}

void CollapseMesh::guard_reattach(const Check& c, Scratch& s, bool b_moved, std::size_t kept) {
  const std::uint32_t b = c.survivor;
  // The survivor's faces as they are now.
  s.fan.clear();
  s.fan_face.clear();
  const std::uint32_t* fl = star(b);
  for (std::uint32_t i = 0; i < size_[b]; ++i) {
    const std::uint32_t* t = &tri_[3 * std::size_t{fl[i]}];
    s.fan.push_back({vx_[t[0]].pos, vx_[t[1]].pos, vx_[t[2]].pos});
    s.fan_face.push_back(fl[i]);
  }
  s.fan_plane.clear();
  for (const std::array<Vec3d, 3>& t : s.fan) s.fan_plane.push_back(plane_of(t));
  // Detach the samples of the dead faces and of every face around b; a sample still close to its own
  // (surviving) face stays on it.
  const double stay2 = kStayFraction * kStayFraction * guard_budget2_;
  s.moved.clear();
  for (std::uint32_t e = 0; e < c.edge_face_count; ++e) {
    std::uint32_t& head = guard_head_[c.edge_faces[e]];
    for (std::uint32_t smp = head; smp != kInvalidIndex; smp = guard_next_[smp]) s.moved.push_back(smp);
    head = kInvalidIndex;
  }
  for (std::size_t k = 0; k < s.fan.size(); ++k) {
    std::uint32_t& head = guard_head_[s.fan_face[k]];
    std::uint32_t kept = kInvalidIndex;
    for (std::uint32_t smp = head, next; smp != kInvalidIndex; smp = next) {
      next = guard_next_[smp];
      const Vec3d& p = guard_samples_[smp];
      if (!plane_beyond(p, s.fan_plane[k], stay2) && distance_sq(p, s.fan[k]) <= stay2) {
        guard_next_[smp] = kept;
        kept = smp;
      } else {
        s.moved.push_back(smp);
      }
    }
    head = kept;
  }
  std::size_t last = 0;
  for (const std::uint32_t smp : s.moved) {
    const Vec3d& p = guard_samples_[smp];
    // The nearest face, the first of equals: the last sample's face gives a bound to start from, and a face
    // whose plane lies beyond the best so far cannot beat it.
    double best = s.fan.empty() ? std::numeric_limits<double>::infinity() : distance_sq(p, s.fan[last]);
    std::size_t at = last;
    for (std::size_t k = 0; k < s.fan.size(); ++k) {
      if (k == last || plane_beyond(p, s.fan_plane[k], best)) continue;
      const double d2 = distance_sq(p, s.fan[k]);
      if (d2 < best || (d2 == best && k < at)) {
        best = d2;
        at = k;
      }
    }
    last = at;
    if (s.fan.empty()) continue;  // no face left around the survivor: nothing to attach to
    std::uint32_t& head = guard_head_[s.fan_face[at]];
    guard_next_[smp] = head;
    head = smp;
  }
  std::uint32_t hint = guard_hint_[b] != kInvalidIndex ? guard_hint_[b] : guard_hint_[c.victim];
  if (guard_bvh_->any_within(model_position(vx_[b].pos), guard_budget_, hint)) guard_hint_[b] = hint;

  // guard_ok() tested b's position and every face now around b: their bounds follow from its samples. Where b
  // did not move, its own faces (the first `kept` of its list) are unchanged and keep the better bound.
  const double reach = kSampleReach * guard_budget_ + guard_rounding_;
  double& vb = guard_vertex_bound_[b];
  vb = b_moved ? reach : std::min(vb, reach);
  for (std::size_t k = 0; k < s.fan.size(); ++k) {
    const std::uint32_t* t = &tri_[3 * std::size_t{s.fan_face[k]}];
    const double corners = std::max({guard_vertex_bound_[t[0]], guard_vertex_bound_[t[1]], guard_vertex_bound_[t[2]]});
    const std::array<Vec3d, 3>& face = s.fan[k];
    const double bound =
        guarded_face_bound(model_position(face[0]), model_position(face[1]), model_position(face[2]), corners);
    double& fb = guard_face_bound_[s.fan_face[k]];
    fb = !b_moved && k < kept ? std::min(fb, bound) : bound;
  }
}

}  // namespace lodforge::collapse
