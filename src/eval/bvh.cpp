// Triangle BVH with exact closest-point queries.
//
// Implements:
//   - Ericson, "Real-Time Collision Detection" (2005), 5.1.5 "Closest point on triangle to point": the
//     Voronoi regions of the three vertices, three edges and the face, told apart with six dot products.
//   - Wald, "On fast construction of SAH-based bounding volume hierarchies" (IEEE RT 2007): binned surface
//     area heuristic over triangle centroids.
//   - Ordered depth-first traversal with box-distance pruning (nearer child first; a box not closer than the
//     best triangle so far, by more than rounding, is skipped), as in Metro's AABB-tree queries (Cignoni,
//     Rocchini & Scopigno 1998).
//   - Oriented boxes from the principal axes of a subtree's corners (Gottschalk, Lin & Manocha, "OBBTree",
//     SIGGRAPH 1996), kept beside the axis-aligned ones where they are much tighter; within the plane of the
//     two larger axes turned to the smallest rectangle along a convex hull edge (Freeman & Shapira, "Determining
//     the minimum-area encasing rectangle for an arbitrary closed curve", CACM 1975), tried over the longest
//     edges of Andrew's monotone-chain hull.
//   - Early split clipping (Ernst & Greiner, "Early split clipping for bounding volume hierarchies", IEEE RT
//     2007): long slivers enter the tree as several references, each with the box of one slab of the triangle.
//   - A walk across edges from a start triangle towards the query (Devillers, Pion & Teillaud, "Walking in a
//     triangulation", SoCG 2001) to seed a hinted descent with a tight bound.
#include "lodforge/eval/bvh.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cassert>
#include <limits>

namespace lodforge {
namespace {

constexpr int kBins = 16;
// Leaves this small keep the per-query triangle tests few; the SAH may stop earlier (see build_subtree).
constexpr std::uint32_t kMaxLeafSize = 4;
// Only pathological input (thousands of coincident triangles) nests this deep; a leaf is made instead, so
// the query stack below can have a fixed size.
constexpr int kMaxDepth = 60;
constexpr int kStackSize = kMaxDepth + 2;
// Triangles whose distances differ by less than this fraction of the largest coordinate count as equally close:
// a box is opened only when it is nearer than the best triangle by more than that. Mesh positions are floats,
// good to 2^-24 of their size, so the triangles of one polygon, one plane in the file, come out of rounding that
// far off each other; without the slack a point on a surface many triangles overlap (a fanned non-convex
// polygon, faces written many times) would test every one of them for the smallest rounding error. A box
// around thousands of such triangles must hold every rounded corner, so it is as far off the best of them as
// the rounding itself: a quarter of it (2^-26) left the nested slivers of a turned fan at hundreds of times a
// clean grid's work.
constexpr double kTieFraction = 0x1p-24;
// A hinted query first walks from the hint to the neighbour across the edge its closest point lies on, at most
// this many steps: in a stream of nearby queries the answer is usually the hint or a few triangles away, and a
// tight start prunes the tree at once even where many boxes overlap the query (fans of slivers).
constexpr int kWalkSteps = 8;

// Subtrees of up to this many triangles get an oriented box where it pays: each is fitted by a pass over its
// triangles, so the cap keeps the build near O(n log n) with a small factor; the top of the tree, whose boxes
// are large whatever their orientation, keeps axis-aligned boxes only.
constexpr std::uint32_t kOrientedMaxTriangles = 4096;
// An oriented box is kept when its surface area is below this fraction of the axis-aligned box's: only then
// does it prune clearly more. Clean meshes still keep many (small groups of triangles at an angle), which costs
// them about a fifth more work per query (docs/performance.md).
constexpr double kOrientedKeepRatio = 0.5;
// The wedge cut is kept (and with it the oriented box) where the points' convex hull seen along the normal covers
// less than this fraction of their rectangle: only then does it prune clearly more.
constexpr double kWedgeCutRatio = 0.9;
// A group is elongated, and gets the hull, when its largest principal variance is this many times its middle one.
constexpr double kElongated = 16.0;
constexpr double kWedgeKeepRatio = 0.6;

// A triangle is a sliver for closest_point_on_triangle when the squared sine of its angle at the first corner is
// below this (~0.06 degrees).
constexpr double kSliverSinSq = 1e-6;

// A triangle whose axis-aligned box is much larger than itself (a long sliver at an angle to the axes: the box of
// a needle from one corner of a cube to the other is the cube) is entered into the tree as several pieces, slabs
// across its length, each with its own box and centroid, so that the boxes say where the sliver is. Each piece
// is wanted where its box's half-area is still above kSplitRatio times its own area.
constexpr double kSplitRatio = 8.0;
// At most this many pieces per triangle, and at most kSplitExtra extra pieces per triangle of the mesh in all,
// so that memory stays within a small factor of the unsplit tree's whatever the input.
constexpr std::uint32_t kMaxPieces = 64;
constexpr double kSplitExtra = 1.0;
// Slivers fanned from a corner shared by more than this many triangles stay whole: their centroids already spread
// along the fan, so the tree groups neighbours and their oriented boxes prune, whereas their pieces would all
// start at the shared corner, where the SAH cannot tell them apart (a fanned disk split so ran 40x the work).
constexpr std::uint32_t kFanValence = 16;

double dist_sq(const Vec3d& a, const Vec3d& b) {
  const Vec3d d = a - b;
  return dot(d, d);
}

bool is_finite(const Vec3d& p) { return std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]); }

// Closest point on segment ab, with its parameter along ab (0 at a). Zero-length segments give a.
double closest_on_segment(const Vec3d& p, const Vec3d& a, const Vec3d& b, Vec3d& out) {
  const Vec3d ab = b - a;
  const double len_sq = dot(ab, ab);
  double t = len_sq > 0 ? dot(p - a, ab) / len_sq : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  out = a + ab * t;
  return t;
}

// Degenerate triangle: its points are the union of its three edges.
TrianglePoint closest_on_edges(const Vec3d& p, const Vec3d& a, const Vec3d& b, const Vec3d& c) {
  Vec3d q;
  double t = closest_on_segment(p, a, b, q);
  TrianglePoint best{q, {{1 - t, t, 0}}};
  double best_d = dist_sq(p, q);
  t = closest_on_segment(p, b, c, q);
  if (const double d = dist_sq(p, q); d < best_d) {
    best = {q, {{0, 1 - t, t}}};
    best_d = d;
  }
  t = closest_on_segment(p, c, a, q);
  if (const double d = dist_sq(p, q); d < best_d) best = {q, {{t, 0, 1 - t}}};
  return best;
}

struct Box {
  Vec3d min{{INFINITY, INFINITY, INFINITY}};
  Vec3d max{{-INFINITY, -INFINITY, -INFINITY}};

  void add(const Vec3d& p) {
    for (int i = 0; i < 3; ++i) {
      min[i] = std::min(min[i], p[i]);
      max[i] = std::max(max[i], p[i]);
    }
  }
  void add(const Box& b) {
    add(b.min);
    add(b.max);
  }
  // Half the surface area: the SAH only compares areas.
  double half_area() const {
    if (!(min[0] <= max[0])) return 0.0;
    const Vec3d e = max - min;
    return e[0] * e[1] + e[1] * e[2] + e[2] * e[0];
  }
};

// First and second moments of a set of points, about a fixed origin, so that subtrees' moments add up.
struct Moments {
  double n = 0;
  Vec3d sum{};
  double xx = 0, xy = 0, xz = 0, yy = 0, yz = 0, zz = 0;

  void add(const Vec3d& q) {
    n += 1;
    sum = sum + q;
    xx += q[0] * q[0], xy += q[0] * q[1], xz += q[0] * q[2];
    yy += q[1] * q[1], yz += q[1] * q[2], zz += q[2] * q[2];
  }
  void add(const Moments& o) {
    n += o.n;
    sum = sum + o.sum;
    xx += o.xx, xy += o.xy, xz += o.xz, yy += o.yy, yz += o.yz, zz += o.zz;
  }
};

// The covariance of the points whose moments these are.
Eigen::Matrix3d covariance(const Moments& m) {
  const Vec3d mean = m.sum * (1.0 / m.n);
  Eigen::Matrix3d cov;
  cov << m.xx / m.n - mean[0] * mean[0], m.xy / m.n - mean[0] * mean[1], m.xz / m.n - mean[0] * mean[2],
      m.xy / m.n - mean[0] * mean[1], m.yy / m.n - mean[1] * mean[1], m.yz / m.n - mean[1] * mean[2],
      m.xz / m.n - mean[0] * mean[2], m.yz / m.n - mean[1] * mean[2], m.zz / m.n - mean[2] * mean[2];
  return cov;
}

// The principal axes of the points whose moments these are, as the rows of `frame` (smallest spread first);
// false where they are not defined (fewer than three points, non-finite input).
bool principal_frame(const Moments& m, double frame[3][3], double spread[3]) {
  if (!(m.n >= 3)) return false;
  const Eigen::Matrix3d cov = covariance(m);
  if (!cov.allFinite()) return false;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(cov);
  if (solver.info() != Eigen::Success || !solver.eigenvectors().allFinite()) return false;
  for (int k = 0; k < 3; ++k) {
    for (int j = 0; j < 3; ++j) frame[k][j] = solver.eigenvectors()(j, k);
    spread[k] = solver.eigenvalues()(k);
  }
  return true;
}

// Turns the two larger principal axes (rows 1 and 2 of `frame`) within their plane so that the rectangle around
// the points projected onto it is smallest, trying the directions of the longest edges of their convex hull (the
// smallest rectangle has a side along a hull edge). Principal axes alone leave a wedge of nested slivers (a fan
// from one corner) tilted in its box, whose far corners then overlap points well outside it.
struct PlaneFit {
  double cut[2] = {0, 0};  // unit direction in the plane of the original rows 1 and 2, or 0
  double hull_area = 0, rect_area = 0;
};

PlaneFit turn_to_small_rectangle(double frame[3][3], std::vector<std::array<double, 2>>& pts,
                                 std::vector<std::array<double, 2>>& hull) {
  PlaneFit fit;
  constexpr std::size_t kTried = 16;
  std::sort(pts.begin(), pts.end());
  pts.erase(std::unique(pts.begin(), pts.end()), pts.end());
  if (pts.size() < 3) return fit;
  // Andrew's monotone chain.
  auto turn = [](const std::array<double, 2>& o, const std::array<double, 2>& a, const std::array<double, 2>& b) {
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
  };
  hull.assign(2 * pts.size(), {});
  std::size_t k = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    while (k >= 2 && turn(hull[k - 2], hull[k - 1], pts[i]) <= 0) --k;
    hull[k++] = pts[i];
  }
  for (std::size_t i = pts.size() - 1, lower = k + 1; i-- > 0;) {
    while (k >= lower && turn(hull[k - 2], hull[k - 1], pts[i]) <= 0) --k;
    hull[k++] = pts[i];
  }
  hull.resize(k - 1);  // the last point repeats the first
  if (hull.size() < 3) return fit;
  // Edges by length, longest first (index as tie-break, for determinism).
  std::vector<std::pair<double, std::size_t>> edges(hull.size());
  for (std::size_t i = 0; i < hull.size(); ++i) {
    const auto& a = hull[i];
    const auto& b = hull[(i + 1) % hull.size()];
    edges[i] = {-((b[0] - a[0]) * (b[0] - a[0]) + (b[1] - a[1]) * (b[1] - a[1])), i};
  }
  const std::size_t tried = std::min(kTried, edges.size());
  std::partial_sort(edges.begin(), edges.begin() + static_cast<std::ptrdiff_t>(tried), edges.end());
  auto area_along = [&](double c, double s) {
    double lo0 = INFINITY, hi0 = -INFINITY, lo1 = INFINITY, hi1 = -INFINITY;
    for (const auto& q : hull) {
      const double u = c * q[0] + s * q[1], v = -s * q[0] + c * q[1];
      lo0 = std::min(lo0, u), hi0 = std::max(hi0, u), lo1 = std::min(lo1, v), hi1 = std::max(hi1, v);
    }
    return (hi0 - lo0) * (hi1 - lo1);
  };
  double best_c = 1, best_s = 0, best = area_along(1, 0);
  for (std::size_t e = 0; e < tried; ++e) {
    const auto& a = hull[edges[e].second];
    const auto& b = hull[(edges[e].second + 1) % hull.size()];
    const double dx = b[0] - a[0], dy = b[1] - a[1], len = std::sqrt(dx * dx + dy * dy);
    if (!(len > 0)) continue;
    if (const double area = area_along(dx / len, dy / len); area < 0.999 * best) {
      best = area, best_c = dx / len, best_s = dy / len;
    }
  }
  fit.rect_area = best;
  // The wedge cut: the normal of the longest hull edge at an angle to both sides of the rectangle.
  double longest = 0;
  for (std::size_t i = 0; i < hull.size(); ++i) {
    const auto& a = hull[i];
    const auto& b = hull[(i + 1) % hull.size()];
    fit.hull_area += 0.5 * (a[0] * b[1] - a[1] * b[0]);
    const double dx = b[0] - a[0], dy = b[1] - a[1], len = std::sqrt(dx * dx + dy * dy);
    if (!(len > longest)) continue;
    const double along = (dx * best_c + dy * best_s) / len, across = (dy * best_c - dx * best_s) / len;
    if (std::abs(along) < 1e-4 || std::abs(across) < 1e-4) continue;
    longest = len;
    fit.cut[0] = -dy / len, fit.cut[1] = dx / len;
  }
  fit.hull_area = std::abs(fit.hull_area);
  if (best_s == 0) return fit;
  for (int j = 0; j < 3; ++j) {
    const double e1 = frame[1][j], e2 = frame[2][j];
    frame[1][j] = best_c * e1 + best_s * e2;
    frame[2][j] = -best_s * e1 + best_c * e2;
  }
  return fit;
}

// The corner opposite the shortest edge (the first of equals): where a sliver's pieces start.
int apex_of(const std::array<Vec3d, 3>& t) {
  double shortest = INFINITY;
  int apex = 0;
  for (int k = 0; k < 3; ++k) {
    const double e = dist_sq(t[(k + 1) % 3], t[(k + 2) % 3]);
    if (e < shortest) shortest = e, apex = k;
  }
  return apex;
}

// How far a piece's computed corners may be from the exact slab through rounding, with a wide margin: its box and
// oriented-box extents are widened by this, so that every point of the triangle is inside some piece's boxes.
double piece_margin(const std::array<Vec3d, 3>& t) {
  double m = 0;
  for (const Vec3d& q : t) m = std::max({m, std::abs(q[0]), std::abs(q[1]), std::abs(q[2])});
  return 0x1p-44 * m;
}

// Axis-aligned box of a piece of triangle t, widened by the rounding margin but never beyond t's own box.
Box piece_box(const std::array<Vec3d, 3>& t, BvhPiece piece) {
  Box whole;
  for (const Vec3d& q : t) whole.add(q);
  if (piece.count <= 1) return whole;
  Box b;
  for (const Vec3d& q : triangle_piece(t, piece)) b.add(q);
  const double m = piece_margin(t);
  for (int i = 0; i < 3; ++i) {
    b.min[i] = std::max(b.min[i] - m, whole.min[i]);
    b.max[i] = std::min(b.max[i] + m, whole.max[i]);
  }
  return b;
}

// How many pieces triangle t would like: enough that each piece's box is about kSplitRatio times the piece's
// area where the triangle is a long sliver at an angle (the square root: a slab's box shrinks with the square
// of its length, its area only linearly), 1 for a compact triangle or one lying in an axis plane.
std::uint32_t wanted_pieces(const std::array<Vec3d, 3>& t, const std::array<std::uint32_t, 3>& valence) {
  Box box;
  for (const Vec3d& q : t) box.add(q);
  const Vec3d n = cross(t[1] - t[0], t[2] - t[0]);
  const double area = 0.5 * std::sqrt(dot(n, n));
  const double ratio = box.half_area() / area;  // +inf for a segment at an angle, NaN for a point
  if (!(ratio > kSplitRatio)) return 1;
  if (valence[apex_of(t)] > kFanValence) return 1;
  const double k = std::ceil(std::sqrt(ratio / kSplitRatio));
  return k >= kMaxPieces ? kMaxPieces : static_cast<std::uint32_t>(k);
}

struct Ref {
  Box box;
  Vec3d centroid;
  std::uint32_t triangle;
  BvhPiece piece;
};

float round_down(double x) {
  float f = static_cast<float>(x);
  if (static_cast<double>(f) > x) f = std::nextafter(f, -std::numeric_limits<float>::infinity());
  return f;
}

float round_up(double x) {
  float f = static_cast<float>(x);
  if (static_cast<double>(f) < x) f = std::nextafter(f, std::numeric_limits<float>::infinity());
  return f;
}

// A finished subtree as its parent sees it: a node (count == 0) or a leaf of `count` slots from `index`.
struct Built {
  Box box;
  std::uint32_t index, count;
};

void store_box(const Box& box, float* min, float* max) {
  for (int i = 0; i < 3; ++i) {
    min[i] = round_down(box.min[i]);
    max[i] = round_up(box.max[i]);
  }
}

// Squared distance from p to a box (0 inside).
double box_dist_sq(const float* min, const float* max, const Vec3d& p) {
  double d = 0;
  for (int i = 0; i < 3; ++i) {
    const double below = static_cast<double>(min[i]) - p[i];
    const double above = p[i] - static_cast<double>(max[i]);
    const double t = below > 0 ? below : (above > 0 ? above : 0.0);
    d += t * t;
  }
  return d;
}

// Squared distance from p to an oriented box: a lower bound on the distance to everything inside it.
double oriented_dist_sq(const BvhOrientedBox& o, const Vec3d& p) {
  const double d0 = p[0] - o.origin[0], d1 = p[1] - o.origin[1], d2 = p[2] - o.origin[2];
  double s = 0;
  for (int k = 0; k < 3; ++k) {
    const double t = double{o.axis[k][0]} * d0 + double{o.axis[k][1]} * d1 + double{o.axis[k][2]} * d2;
    const double e = t < o.lo[k] ? o.lo[k] - t : (t > o.hi[k] ? t - o.hi[k] : 0.0);
    s += e * e;
  }
  s *= o.shrink;
  // The wedge cut, with the normal: a second lower bound, on the distance to the box's part between its slabs.
  const double t = double{o.cut[0]} * d0 + double{o.cut[1]} * d1 + double{o.cut[2]} * d2;
  const double e = t < o.cut_lo ? o.cut_lo - t : (t > o.cut_hi ? t - o.cut_hi : 0.0);
  if (e > 0) {
    const double n = double{o.axis[0][0]} * d0 + double{o.axis[0][1]} * d1 + double{o.axis[0][2]} * d2;
    const double en = n < o.lo[0] ? o.lo[0] - n : (n > o.hi[0] ? n - o.hi[0] : 0.0);
    s = std::max(s, (e * e + en * en) * o.cut_shrink);
  }
  return s;
}

int bin_of(double c, double lo, double scale) {
  return std::clamp(static_cast<int>((c - lo) * scale), 0, kBins - 1);
}

// For each triangle in the tree and each corner k, a triangle in the tree sharing the edge opposite corner k
// (the same two vertex indices), or kInvalidIndex. Around an edge of more than two triangles each names the
// next one by number, so that every one of them can be reached.
std::vector<std::array<std::uint32_t, 3>> edge_neighbors(std::span<const std::uint32_t> indices,
                                                         std::span<const std::uint32_t> slot_of) {
  struct Side {
    std::uint64_t edge;  // lower vertex index in the high half
    std::uint32_t triangle;
    std::uint32_t corner;
    bool operator<(const Side& o) const { return edge != o.edge ? edge < o.edge : triangle < o.triangle; }
  };
  std::vector<Side> sides;
  sides.reserve(indices.size());
  for (std::uint32_t t = 0; t < slot_of.size(); ++t) {
    if (slot_of[t] == kInvalidIndex) continue;
    for (std::uint32_t k = 0; k < 3; ++k) {
      const std::uint64_t a = indices[3 * std::size_t{t} + (k + 1) % 3], b = indices[3 * std::size_t{t} + (k + 2) % 3];
      if (a != b) sides.push_back({std::min(a, b) << 32 | std::max(a, b), t, k});
    }
  }
  std::sort(sides.begin(), sides.end());
  std::vector<std::array<std::uint32_t, 3>> neighbor(slot_of.size(), {kInvalidIndex, kInvalidIndex, kInvalidIndex});
  for (std::size_t begin = 0, end = 0; begin < sides.size(); begin = end) {
    while (end < sides.size() && sides[end].edge == sides[begin].edge) ++end;
    if (end - begin < 2) continue;
    for (std::size_t i = begin; i < end; ++i) {
      const Side& next = sides[i + 1 < end ? i + 1 : begin];
      neighbor[sides[i].triangle][sides[i].corner] = next.triangle;
    }
  }
  return neighbor;
}

// Recursive binned-SAH build over refs[begin, end). Nodes are stored parent first. Leaves take the ref
// positions as their slots, so after the build refs is in slot order.
Built build_subtree(std::vector<Ref>& refs, std::vector<BvhNode>& nodes, std::uint32_t begin, std::uint32_t end,
                    int depth) {
  Box box, centroids;
  for (std::uint32_t i = begin; i < end; ++i) {
    box.add(refs[i].box);
    centroids.add(refs[i].centroid);
  }
  const std::uint32_t n = end - begin;
  if (n <= kMaxLeafSize || depth >= kMaxDepth) return {box, begin, n};

  // Bin all three axes in one pass over the refs (the build's hot loop).
  double lo[3], scale[3];
  bool splittable[3];
  for (int axis = 0; axis < 3; ++axis) {
    lo[axis] = centroids.min[axis];
    const double extent = centroids.max[axis] - lo[axis];
    splittable[axis] = extent > 0;
    scale[axis] = splittable[axis] ? kBins / extent : 0.0;
  }
  Box bin_box[3][kBins];
  std::uint32_t bin_count[3][kBins] = {};
  for (std::uint32_t i = begin; i < end; ++i) {
    const Ref& r = refs[i];
    for (int axis = 0; axis < 3; ++axis) {
      const int b = bin_of(r.centroid[axis], lo[axis], scale[axis]);
      bin_box[axis][b].add(r.box);
      ++bin_count[axis][b];
    }
  }

  // Cost of a split, up to constants: sum over both sides of (box half-area x triangle count).
  double best_cost = INFINITY;
  int best_axis = -1, best_split = 0;
  for (int axis = 0; axis < 3; ++axis) {
    if (!splittable[axis]) continue;
    // Sweep from the right for the right-hand sides, then from the left for the costs.
    double right_area[kBins];
    std::uint32_t right_count[kBins];
    Box acc;
    std::uint32_t count = 0;
    for (int b = kBins - 1; b > 0; --b) {
      acc.add(bin_box[axis][b]);
      count += bin_count[axis][b];
      right_area[b] = acc.half_area();
      right_count[b] = count;
    }
    acc = Box{};
    count = 0;
    for (int split = 1; split < kBins; ++split) {  // left = bins [0, split)
      acc.add(bin_box[axis][split - 1]);
      count += bin_count[axis][split - 1];
      if (count == 0 || right_count[split] == 0) continue;
      const double cost = acc.half_area() * count + right_area[split] * right_count[split];
      if (cost < best_cost) {
        best_cost = cost;
        best_axis = axis;
        best_split = split;
      }
    }
  }

  std::uint32_t mid;
  if (best_axis < 0) {
    // All centroids coincide: no spatial split helps, halve by position to keep leaves small.
    mid = begin + n / 2;
  } else {
    // A leaf costs n triangle tests; a split costs one more box test per child plus the expected triangle
    // tests weighted by the chance (area ratio) of entering each child. Stop when splitting does not pay.
    const double parent_area = box.half_area();
    if (n <= 4 * kMaxLeafSize && parent_area > 0 && best_cost / parent_area + 1.0 >= n) return {box, begin, n};
    const auto it = std::partition(refs.begin() + begin, refs.begin() + end, [&](const Ref& r) {
      return bin_of(r.centroid[best_axis], lo[best_axis], scale[best_axis]) < best_split;
    });
    mid = static_cast<std::uint32_t>(it - refs.begin());
    assert(mid > begin && mid < end);
  }
  const auto node = static_cast<std::uint32_t>(nodes.size());
  nodes.emplace_back();
  const Built children[2] = {build_subtree(refs, nodes, begin, mid, depth + 1),
                             build_subtree(refs, nodes, mid, end, depth + 1)};
  for (int i = 0; i < 2; ++i) {
    store_box(children[i].box, nodes[node].min[i], nodes[node].max[i]);
    nodes[node].child[i] = children[i].index;
    nodes[node].count[i] = children[i].count;
  }
  return {box, node, 0};
}

}  // namespace

std::array<Vec3d, 4> triangle_piece(const std::array<Vec3d, 3>& t, BvhPiece piece) {
  if (piece.count <= 1) return {t[0], t[1], t[2], t[2]};
  const int apex = apex_of(t);
  const Vec3d& c = t[apex];
  const Vec3d& a = t[(apex + 1) % 3];
  const Vec3d& b = t[(apex + 2) % 3];
  // The ends are the exact corners; inner cuts are rounded, which piece_margin covers.
  auto at = [&](std::uint32_t k, const Vec3d& end) {
    if (k == 0) return c;
    if (k >= piece.count) return end;
    return c + (end - c) * (static_cast<double>(k) / piece.count);
  };
  return {at(piece.index, a), at(piece.index, b), at(piece.index + 1u, a), at(piece.index + 1u, b)};
}

TrianglePoint closest_point_on_triangle(const Vec3d& p, const Vec3d& a, const Vec3d& b, const Vec3d& c) {
  // Ericson's region tests, in his order and notation. Each early return is one Voronoi region.
  const Vec3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return {a, {{1, 0, 0}}};  // vertex a

  const Vec3d bp = p - b;
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return {b, {{0, 1, 0}}};  // vertex b

  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {  // edge ab
    const double v = d1 / (d1 - d3);
    return {a + ab * v, {{1 - v, v, 0}}};
  }

  const Vec3d cp = p - c;
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return {c, {{0, 0, 1}}};  // vertex c

  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {  // edge ac
    const double w = d2 / (d2 - d6);
    return {a + ac * w, {{1 - w, 0, w}}};
  }

  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {  // edge bc
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {b + (c - b) * w, {{0, 1 - w, w}}};
  }

  // Face region. va, vb, vc are the (scaled) barycentrics; for a non-degenerate triangle all are positive
  // here. A (near-)degenerate triangle can reach this point with a zero or negative one through rounding;
  // its surface is its edges, so measure those instead of dividing by ~0.
  if (!(va > 0 && vb > 0 && vc > 0)) return closest_on_edges(p, a, b, c);
  const double denom = va + vb + vc;
  const double v = vb / denom, w = vc / denom;
  // On a sliver (an angle under ~0.06 degrees at a) v and w are ratios of differences of nearly equal products,
  // and a + ab v + ac w puts a point on a 1:10000 sliver 1e-8 of its size off it. There the point is p moved
  // onto the plane instead, with the normal from the corner opposite the longest edge: its two edges are the
  // shorter ones and at least 60 degrees apart, so the normal keeps full precision. (Elsewhere the formula
  // stays, so that which of two coincident triangles is nearer by an ulp does not change.)
  const Vec3d n = cross(ab, ac);
  const double ab2 = dot(ab, ab), ac2 = dot(ac, ac);
  if (!(dot(n, n) < kSliverSinSq * ab2 * ac2)) return {a + ab * v + ac * w, {{1 - v - w, v, w}}};
  const Vec3d bc = c - b;
  const double bc2 = dot(bc, bc);
  const bool at_a = bc2 >= ab2 && bc2 >= ac2;
  const Vec3d& o = at_a ? a : (ac2 >= ab2 ? b : c);
  const Vec3d m = at_a ? n : (ac2 >= ab2 ? cross(bc, a - b) : cross(a - c, bc));
  const double mm = dot(m, m);
  if (!(mm > 0) || !std::isfinite(mm)) return {a + ab * v + ac * w, {{1 - v - w, v, w}}};  // under/overflow
  return {p - m * (dot(p - o, m) / mm), {{1 - v - w, v, w}}};
}

TriangleBvh::TriangleBvh(std::span<const Vec3d> positions, std::span<const std::uint32_t> indices)
    : positions_(positions.begin(), positions.end()), indices_(indices.begin(), indices.end()) {
  assert(indices.size() % 3 == 0);
  const std::size_t triangles = indices.size() / 3;
  slot_of_.assign(triangles, kInvalidIndex);

  // Pieces wanted per triangle in the tree (0: left out), then the largest per-triangle cap that keeps the extra
  // pieces within the budget, so that the longest slivers are split most.
  std::vector<std::uint32_t> valence(positions.size(), 0);
  for (const std::uint32_t v : indices_) ++valence[v];
  std::vector<std::uint32_t> pieces(triangles, 0);
  std::size_t finite = 0;
  for (std::size_t t = 0; t < triangles; ++t) {
    const std::array<Vec3d, 3> corners = triangle(static_cast<std::uint32_t>(t));
    if (!is_finite(corners[0]) || !is_finite(corners[1]) || !is_finite(corners[2])) continue;
    const std::uint32_t* v = &indices_[3 * t];
    pieces[t] = wanted_pieces(corners, {valence[v[0]], valence[v[1]], valence[v[2]]});
    ++finite;
  }
  const auto budget = static_cast<std::size_t>(kSplitExtra * static_cast<double>(finite));
  auto extra_under = [&](std::uint32_t cap) {
    std::size_t extra = 0;
    for (const std::uint32_t k : pieces) extra += k > 1 ? std::min(k, cap) - 1 : 0;
    return extra;
  };
  std::uint32_t cap = kMaxPieces;
  if (extra_under(cap) > budget) {
    std::uint32_t lo = 1, hi = kMaxPieces;  // extra_under(lo) = 0 fits, extra_under(hi) does not
    while (hi - lo > 1) {
      const std::uint32_t mid = (lo + hi) / 2;
      (extra_under(mid) <= budget ? lo : hi) = mid;
    }
    cap = lo;
  }

  std::vector<Ref> refs;
  refs.reserve(finite + extra_under(cap));
  bool split = false;
  for (std::size_t t = 0; t < triangles; ++t) {
    if (pieces[t] == 0) continue;
    const std::array<Vec3d, 3> corners = triangle(static_cast<std::uint32_t>(t));
    const auto count = static_cast<std::uint16_t>(std::min(pieces[t], cap));
    split = split || count > 1;
    for (std::uint16_t k = 0; k < count; ++k) {
      Ref r;
      r.piece = {k, count};
      r.box = piece_box(corners, r.piece);
      r.centroid = (r.box.min + r.box.max) * 0.5;
      if (count == 1) r.centroid = (corners[0] + corners[1] + corners[2]) * (1.0 / 3.0);
      r.triangle = static_cast<std::uint32_t>(t);
      refs.push_back(r);
    }
  }
  if (refs.empty()) return;

  nodes_.reserve(refs.size() / 2 + 1);
  const Built root = build_subtree(refs, nodes_, 0, static_cast<std::uint32_t>(refs.size()), 0);
  nodes_.shrink_to_fit();
  store_box(root.box, root_.min, root_.max);
  for (int i = 0; i < 3; ++i) scale_ = std::max({scale_, std::abs(root.box.min[i]), std::abs(root.box.max[i])});
  root_.index = root.index;
  root_.count = root.count;

  slot_corners_.reserve(refs.size());
  slot_triangle_.reserve(refs.size());
  if (split) slot_piece_.reserve(refs.size());
  for (std::size_t s = 0; s < refs.size(); ++s) {
    slot_corners_.push_back(triangle(refs[s].triangle));
    slot_triangle_.push_back(refs[s].triangle);
    if (split) slot_piece_.push_back(refs[s].piece);
    if (slot_of_[refs[s].triangle] == kInvalidIndex) slot_of_[refs[s].triangle] = static_cast<std::uint32_t>(s);
  }
  neighbor_ = edge_neighbors(indices_, slot_of_);
  fit_oriented_boxes();
}

void TriangleBvh::fit_oriented_boxes() {
  if (nodes_.empty()) return;
  node_obb_.assign(nodes_.size(), {kInvalidIndex, kInvalidIndex});
  // Moments are taken about the root box's centre, which keeps their cancellation small for meshes far from
  // the origin; the axes only need to be good, the extents are measured exactly along them.
  Vec3d centre;
  for (int i = 0; i < 3; ++i) centre[i] = 0.5 * (double{root_.min[i]} + double{root_.max[i]});

  struct Fitted {
    std::uint32_t begin, end;  // slot range
    Moments moments;
  };
  // The corners of what slot s stands for: its triangle's, or its piece's (then also the rounding margin).
  auto slot_points = [&](std::uint32_t s, auto&& f) {
    const BvhPiece piece = slot_piece(s);
    if (piece.count <= 1) {
      for (const Vec3d& q : slot_corners_[s]) f(q);
      return 0.0;
    }
    for (const Vec3d& q : triangle_piece(slot_corners_[s], piece)) f(q);
    return piece_margin(slot_corners_[s]);
  };
  std::vector<std::array<double, 2>> plane, hull;  // scratch for turn_to_small_rectangle
  // Fits child i of `node` (slots [f.begin, f.end)) an oriented box and keeps it where it pays.
  auto fit = [&](std::uint32_t node, int i, const Fitted& f) {
    if (f.end - f.begin > kOrientedMaxTriangles || f.moments.n < 3) return;
    const Moments& m = f.moments;
    double frame[3][3], spread[3];
    if (!principal_frame(m, frame, spread)) return;
    double e1[3], e2[3];
    for (int j = 0; j < 3; ++j) e1[j] = frame[1][j], e2[j] = frame[2][j];
    PlaneFit pf;
    // Only elongated groups (slivers, wedges of them) are worth the hull; compact patches of a clean surface keep
    // their principal axes, which fit them about as well.
    if (spread[2] > kElongated * spread[1]) {
      plane.clear();
      for (std::uint32_t s = f.begin; s < f.end; ++s) {
        slot_points(s, [&](const Vec3d& q) {
          const Vec3d d = q - centre;
          plane.push_back({frame[1][0] * d[0] + frame[1][1] * d[1] + frame[1][2] * d[2],
                           frame[2][0] * d[0] + frame[2][1] * d[1] + frame[2][2] * d[2]});
        });
      }
      pf = turn_to_small_rectangle(frame, plane, hull);
    }
    const bool wedge = (pf.cut[0] != 0 || pf.cut[1] != 0) && pf.hull_area < kWedgeCutRatio * pf.rect_area;
    const bool wedge_keeps = wedge && pf.hull_area < kWedgeKeepRatio * pf.rect_area;
    double cut[3] = {0, 0, 0};
    if (wedge) {
      for (int j = 0; j < 3; ++j) cut[j] = pf.cut[0] * e1[j] + pf.cut[1] * e2[j];
    }
    BvhOrientedBox box;
    double a[3][3];
    for (int k = 0; k < 3; ++k) {
      for (int j = 0; j < 3; ++j) {
        box.axis[k][j] = static_cast<float>(frame[k][j]);
        a[k][j] = box.axis[k][j];
      }
    }
    const Vec3d mean = m.sum * (1.0 / m.n);
    for (int j = 0; j < 3; ++j) box.origin[j] = static_cast<float>(mean[j] + centre[j]);
    // The float axes are orthonormal only to rounding: |A v|^2 <= (1 + g) |v|^2 with g the largest Gershgorin
    // radius of A A^T - I, so dividing by 1 + g keeps the distance a lower bound.
    double g = 0;
    for (int k = 0; k < 3; ++k) {
      double row = 0;
      for (int j = 0; j < 3; ++j) {
        const double aa = a[k][0] * a[j][0] + a[k][1] * a[j][1] + a[k][2] * a[j][2];
        row += std::abs(aa - (k == j ? 1.0 : 0.0));
      }
      g = std::max(g, row);
    }
    box.shrink = round_down(1.0 / (1.0 + g + 1e-12));
    double c[3];
    for (int j = 0; j < 3; ++j) {
      box.cut[j] = static_cast<float>(cut[j]);
      c[j] = box.cut[j];
    }
    {
      const double a0c = a[0][0] * c[0] + a[0][1] * c[1] + a[0][2] * c[2];
      const double cc = c[0] * c[0] + c[1] * c[1] + c[2] * c[2];
      const double a00 = a[0][0] * a[0][0] + a[0][1] * a[0][1] + a[0][2] * a[0][2];
      const double gc = std::max(std::abs(a00 - 1) + std::abs(a0c), std::abs(cc - 1) + std::abs(a0c));
      box.cut_shrink = round_down(1.0 / (1.0 + gc + 1e-12));
    }
    double cut_lo = wedge ? INFINITY : 0.0, cut_hi = wedge ? -INFINITY : 0.0;

    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    double margin = 0;
    for (std::uint32_t s = f.begin; s < f.end; ++s) {
      margin = std::max(margin, slot_points(s, [&](const Vec3d& q) {
        const double d0 = q[0] - box.origin[0], d1 = q[1] - box.origin[1], d2 = q[2] - box.origin[2];
        for (int k = 0; k < 3; ++k) {
          const double t = a[k][0] * d0 + a[k][1] * d1 + a[k][2] * d2;
          lo[k] = std::min(lo[k], t);
          hi[k] = std::max(hi[k], t);
        }
        if (wedge) {
          const double t = c[0] * d0 + c[1] * d1 + c[2] * d2;
          cut_lo = std::min(cut_lo, t);
          cut_hi = std::max(cut_hi, t);
        }
      }));
    }
    // A point within `margin` of a piece's corners along each axis is within 2 margin along a near-unit axis.
    for (int k = 0; k < 3; ++k) {
      const double r = 2 * margin + 0x1p-48 * std::max(std::abs(lo[k]), std::abs(hi[k]));  // and the projection's
      box.lo[k] = lo[k] - r;
      box.hi[k] = hi[k] + r;
    }
    const double r = 2 * margin + 0x1p-48 * std::max(std::abs(cut_lo), std::abs(cut_hi));
    box.cut_lo = wedge ? cut_lo - r : 0.0;
    box.cut_hi = wedge ? cut_hi + r : 0.0;
    const BvhNode& n = nodes_[node];
    auto half_area = [](double e0, double e1, double e2) { return e0 * e1 + e1 * e2 + e2 * e0; };
    const double oriented = half_area(double{box.hi[0]} - box.lo[0], double{box.hi[1]} - box.lo[1],
                                      double{box.hi[2]} - box.lo[2]);
    const double aligned = half_area(double{n.max[i][0]} - n.min[i][0], double{n.max[i][1]} - n.min[i][1],
                                     double{n.max[i][2]} - n.min[i][2]);
    if (!(oriented < kOrientedKeepRatio * aligned) && !wedge_keeps) return;
    node_obb_[node][i] = static_cast<std::uint32_t>(obbs_.size());
    obbs_.push_back(box);
  };
  // Depth-first over the tree (at most kMaxDepth deep), children before the node that holds their boxes.
  auto visit = [&](auto&& self, std::uint32_t index, std::uint32_t count) -> Fitted {
    Fitted f;
    if (count > 0) {
      f.begin = index;
      f.end = index + count;
      for (std::uint32_t s = index; s < index + count; ++s) slot_points(s, [&](const Vec3d& q) { f.moments.add(q - centre); });
      return f;
    }
    const BvhNode& n = nodes_[index];
    const Fitted c0 = self(self, n.child[0], n.count[0]);
    const Fitted c1 = self(self, n.child[1], n.count[1]);
    fit(index, 0, c0);
    fit(index, 1, c1);
    f.begin = std::min(c0.begin, c1.begin);
    f.end = std::max(c0.end, c1.end);
    f.moments = c0.moments;
    f.moments.add(c1.moments);
    return f;
  };
  visit(visit, root_.index, root_.count);
  obbs_.shrink_to_fit();
  if (obbs_.empty()) node_obb_.clear();
}

double TriangleBvh::child_dist_sq(std::uint32_t node, int i, const Vec3d& p, double limit) const {
  const BvhNode& n = nodes_[node];
  double d = box_dist_sq(n.min[i], n.max[i], p);
  if (d <= limit && !node_obb_.empty()) {
    if (const std::uint32_t k = node_obb_[node][i]; k != kInvalidIndex) d = std::max(d, oriented_dist_sq(obbs_[k], p));
  }
  return d;
}

std::array<Vec3d, 3> TriangleBvh::triangle(std::uint32_t t) const {
  return {positions_[indices_[3 * std::size_t{t}]], positions_[indices_[3 * std::size_t{t} + 1]],
          positions_[indices_[3 * std::size_t{t} + 2]]};
}

Bounds3 TriangleBvh::bounds() const {
  Bounds3 b;
  if (empty()) return b;
  b.add({{root_.min[0], root_.min[1], root_.min[2]}});
  b.add({{root_.max[0], root_.max[1], root_.max[2]}});
  return b;
}

BvhHit TriangleBvh::search(const Vec3d& p, BvhHit best, const BvhHit& known, BvhWork& work) const {
  if (empty()) return best;
  struct Entry {
    std::uint32_t index, count;  // a child reference, as in BvhNode
    double dist_sq;
  };
  Entry stack[kStackSize];
  int top = 0;
  stack[top++] = {root_.index, root_.count, box_dist_sq(root_.min, root_.max, p)};
  // Boxes are opened only when nearer than the best triangle by more than `slack`; see kTieFraction.
  const double slack = kTieFraction * std::max({scale_, std::abs(p[0]), std::abs(p[1]), std::abs(p[2])});
  auto bound_of = [slack](const BvhHit& b) {
    if (!b.found()) return b.distance_sq;  // a caller's limit, not a triangle: exact
    const double d = std::sqrt(b.distance_sq) - slack;
    return d > 0 ? std::min(d * d, b.distance_sq) : 0.0;  // min: never above the exact bound through rounding
  };
  double bound = std::min(bound_of(best), bound_of(known));
  while (top > 0) {
    const Entry e = stack[--top];
    // Re-checked on pop: the best distance may have shrunk since this entry was pushed.
    if (!(e.dist_sq < bound)) continue;
    if (e.count > 0) {
      for (std::uint32_t s = e.index; s < e.index + e.count; ++s) {
        // Neighbouring pieces of one sliver often share a leaf: measured once.
        if (s > e.index && slot_triangle_[s] == slot_triangle_[s - 1]) continue;
        ++work.triangles;
        const std::array<Vec3d, 3>& t = slot_corners_[s];
        const TrianglePoint tp = closest_point_on_triangle(p, t[0], t[1], t[2]);
        const double d = dist_sq(p, tp.point);
        if (d < best.distance_sq) {
          best.distance_sq = d;
          best.point = tp.point;
          best.barycentric = tp.barycentric;
          best.triangle = slot_triangle_[s];
          bound = std::min(bound, bound_of(best));
        }
      }
      continue;
    }
    ++work.nodes;
    const BvhNode& n = nodes_[e.index];
    const Entry c0{n.child[0], n.count[0], child_dist_sq(e.index, 0, p, bound)};
    const Entry c1{n.child[1], n.count[1], child_dist_sq(e.index, 1, p, bound)};
    // Push the farther child first so the nearer one is searched first and shrinks the bound.
    const bool first_nearer = c0.dist_sq <= c1.dist_sq;
    const Entry& near = first_nearer ? c0 : c1;
    const Entry& far = first_nearer ? c1 : c0;
    if (far.dist_sq < bound) stack[top++] = far;
    if (near.dist_sq < bound) stack[top++] = near;
    assert(top <= kStackSize);
  }
  // The descent skipped what it could not beat by more than the slack; `known` is then as good.
  return known.distance_sq < best.distance_sq ? known : best;
}

BvhHit TriangleBvh::closest_point(const Vec3d& p) const {
  BvhWork work;
  return search(p, BvhHit{}, BvhHit{}, work);
}

BvhHit TriangleBvh::closest_point(const Vec3d& p, std::uint32_t hint) const {
  BvhWork work;
  return hinted(p, hint, work);
}

BvhHit TriangleBvh::closest_point(const Vec3d& p, std::uint32_t hint, BvhWork& work) const {
  return hinted(p, hint, work);
}

BvhHit TriangleBvh::measure(const Vec3d& p, std::uint32_t t, BvhWork& work) const {
  const std::array<Vec3d, 3>& c = slot_corners_[slot_of_[t]];
  const TrianglePoint tp = closest_point_on_triangle(p, c[0], c[1], c[2]);
  ++work.triangles;
  return {t, tp.point, tp.barycentric, dist_sq(p, tp.point)};
}

BvhHit TriangleBvh::step_closer(const Vec3d& p, const BvhHit& at, BvhWork& work) const {
  BvhHit next = at;
  for (int k = 0; k < 3; ++k) {
    const std::uint32_t across = neighbor_[at.triangle][k];
    if (at.barycentric[k] != 0 || across == kInvalidIndex) continue;  // not on the edge opposite corner k
    if (const BvhHit h = measure(p, across, work); h.distance_sq < next.distance_sq) next = h;
  }
  return next;
}

BvhHit TriangleBvh::hinted(const Vec3d& p, std::uint32_t hint, BvhWork& work) const {
  if (hint >= slot_of_.size() || slot_of_[hint] == kInvalidIndex) return search(p, BvhHit{}, BvhHit{}, work);
  const BvhHit start = measure(p, hint, work);
  if (!(start.distance_sq < INFINITY)) return search(p, BvhHit{}, BvhHit{}, work);  // NaN or overflow
  // Walk across the edge (or the two edges at the corner) the closest point lies on while that gets closer.
  BvhHit walked = start;
  for (int step = 0; step < kWalkSteps; ++step) {
    const BvhHit next = step_closer(p, walked, work);
    if (next.triangle == walked.triangle) break;
    walked = next;
  }
  // The walk only tightens the pruning: the answer is still the one the descent from the hint finds, so that
  // of several equally close triangles (a shared corner) the same one is returned as without the walk.
  return search(p, start, walked, work);
}

BvhHit TriangleBvh::closest_point_within(const Vec3d& p, double max_distance) const {
  BvhHit start;
  start.distance_sq = max_distance > 0 ? max_distance * max_distance : 0.0;
  BvhWork work;
  return search(p, start, BvhHit{}, work);
}

bool TriangleBvh::any_within(const Vec3d& p, double max_distance, std::uint32_t& hint, BvhWork& work) const {
  if (empty() || !(max_distance >= 0)) return false;
  const double limit_sq = max_distance * max_distance;
  if (hint < slot_of_.size() && slot_of_[hint] != kInvalidIndex) {
    // Walk from the hint across the edge its closest point lies on while that gets closer: a coherent stream
    // of queries then rarely needs the descent, which opens a dozen nodes.
    BvhHit walked = measure(p, hint, work);
    if (walked.distance_sq <= limit_sq) return true;
    for (int step = 0; step < kWalkSteps && walked.distance_sq < INFINITY; ++step) {
      const BvhHit next = step_closer(p, walked, work);
      if (next.triangle == walked.triangle) break;
      walked = next;
      if (walked.distance_sq <= limit_sq) {
        hint = walked.triangle;
        return true;
      }
    }
  }
  // Boxes are opened up to a rounding slack beyond the limit, so that whether a triangle is found does not
  // depend on the order of the descent.
  const double slack = kTieFraction * std::max({scale_, std::abs(p[0]), std::abs(p[1]), std::abs(p[2])});
  const double open_sq = (max_distance + slack) * (max_distance + slack);
  std::uint32_t stack[kStackSize][2];
  int top = 0;
  if (box_dist_sq(root_.min, root_.max, p) <= open_sq) {
    stack[top][0] = root_.index;
    stack[top++][1] = root_.count;
  }
  while (top > 0) {
    --top;
    const std::uint32_t index = stack[top][0], count = stack[top][1];
    if (count > 0) {
      for (std::uint32_t s = index; s < index + count; ++s) {
        if (s > index && slot_triangle_[s] == slot_triangle_[s - 1]) continue;
        ++work.triangles;
        const std::array<Vec3d, 3>& t = slot_corners_[s];
        if (dist_sq(p, closest_point_on_triangle(p, t[0], t[1], t[2]).point) <= limit_sq) {
          hint = slot_triangle_[s];
          return true;
        }
      }
      continue;
    }
    ++work.nodes;
    const BvhNode& n = nodes_[index];
    const double d0 = child_dist_sq(index, 0, p, open_sq), d1 = child_dist_sq(index, 1, p, open_sq);
    const int near = d0 <= d1 ? 0 : 1, far = 1 - near;
    const double near_sq = near == 0 ? d0 : d1, far_sq = near == 0 ? d1 : d0;
    if (far_sq <= open_sq) {
      stack[top][0] = n.child[far];
      stack[top++][1] = n.count[far];
    }
    if (near_sq <= open_sq) {
      stack[top][0] = n.child[near];
      stack[top++][1] = n.count[near];
    }
    assert(top <= kStackSize);
  }
  return false;
}

TriangleBvh make_triangle_bvh(const Mesh& mesh) {
  std::vector<Vec3d> positions;
  positions.reserve(mesh.vertex_count());
  for (const Vec3f& p : mesh.positions) positions.push_back(to_double(p));
  return TriangleBvh(positions, triangle_vertex_indices(mesh));
}

}  // namespace lodforge
