// A bounding volume hierarchy over triangles with exact closest-point queries in double precision.
//
//   TriangleBvh bvh(positions, indices);         // three indices per triangle
//   BvhHit hit = bvh.closest_point(p);           // hit.triangle, hit.point, hit.barycentric, hit.distance_sq
//
// Used by the Metro-style evaluator (eval.hpp) and meant for every "closest point on the other surface" query
// (attribute and UV deviation, conservative error checks). Queries are const and allocation-free, so any
// number of threads may query one BVH at once.
//
// Hostile input stays cheap where the geometry allows: distances within 2^-24 of the largest coordinate of the
// best one (the precision of float positions) count as ties, so a point on a surface that many triangles overlap
// (a fanned non-convex polygon, faces written many times over) stops at the first; and a hinted query walks from
// the hint across the mesh's edges first, so it starts from the answer even where many boxes overlap.
// Children whose triangles are slivers at an angle to the axes also get an oriented box (BvhOrientedBox), turned
// to the smallest rectangle around them and, where they form a wedge (slivers fanned from one corner), cut along
// the wedge's side too, so that a query off the surface next to a fine cone, or next to thousands of nested
// slivers, opens about what it would on a clean grid. Long slivers at an angle that are not fanned from a shared
// corner (parallel needles) enter the tree as several pieces, each with its own box (BvhPiece).
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

#include "lodforge/core/mesh.hpp"
#include "lodforge/core/vec.hpp"

namespace lodforge {

struct TrianglePoint {
  Vec3d point{};
  Vec3d barycentric{};  // weights of corners a, b, c: point = wa a + wb b + wc c, weights >= 0, sum 1
};

// Exact closest point of triangle abc to p (Ericson, Real-Time Collision Detection, 5.1.5). Degenerate
// triangles (collinear corners, repeated corners) are handled: the answer is the closest point of the segment
// or point they collapse to, never NaN.
TrianglePoint closest_point_on_triangle(const Vec3d& p, const Vec3d& a, const Vec3d& b, const Vec3d& c);

// Which part of its triangle a slot of a TriangleBvh covers: piece `index` of `count` slabs cut across the
// triangle's length (see triangle_piece); {0, 1} is the whole triangle.
struct BvhPiece {
  std::uint16_t index = 0, count = 1;
};

// Corners of `piece` of triangle t: the slab between the fractions index/count and (index + 1)/count of the way
// from the corner opposite the shortest edge (the apex) to that edge, as {p, q, r, s} with p, r on the edge from
// the apex to the next corner and q, s on the edge to the one after (p = q at the apex). The whole triangle
// ({0, 1}) is {t0, t1, t2, t2}. Every point of t lies in one of its pieces (up to the rounding of the cuts, which
// the tree's boxes allow for).
std::array<Vec3d, 4> triangle_piece(const std::array<Vec3d, 3>& t, BvhPiece piece);

struct BvhHit {
  std::uint32_t triangle = kInvalidIndex;  // triangle number as given to the constructor; kInvalidIndex: none
  Vec3d point{};
  Vec3d barycentric{};
  double distance_sq = INFINITY;

  bool found() const { return triangle != kInvalidIndex; }
  double distance() const { return std::sqrt(distance_sq); }
};

// Work done by queries: a cost measure that does not depend on the machine (for tests and benchmarks).
struct BvhWork {
  std::uint64_t nodes = 0;      // internal nodes opened (their two child boxes measured)
  std::uint64_t triangles = 0;  // point-triangle closest-point computations

  BvhWork& operator+=(const BvhWork& o) {
    nodes += o.nodes;
    triangles += o.triangles;
    return *this;
  }
};

// One internal node of a TriangleBvh: the boxes of both children side by side, so that one 64-byte line
// gives everything needed to decide where to descend. Boxes are floats rounded outward, so they always contain
// their triangles. Child i is the node child[i] when count[i] == 0, else a leaf holding the triangle slots
// [child[i], child[i] + count[i]).
struct alignas(64) BvhNode {
  float min[2][3], max[2][3];
  std::uint32_t child[2], count[2];
};

// An oriented box around one child of a node, kept beside the node where it is much tighter than the child's
// axis-aligned box: slivers and thin slabs at an angle to the axes, whose axis-aligned boxes overlap far and
// wide. The child's corners q satisfy lo[k] <= axis[k] . (q - origin) <= hi[k]; `shrink` (<= 1) scales the
// squared distance so that it stays a lower bound although the float axes are only nearly orthonormal.
// Where the points seen along the box's normal (axis 0) form a wedge, as slivers fanned from one corner do, one
// more direction `cut` in the box's plane bounds them too: cut_lo <= cut . (q - origin) <= cut_hi, with
// `cut_shrink` for the pair (axis 0, cut) as `shrink` is for the three axes; cut = 0 where none is kept.
struct BvhOrientedBox {
  float axis[3][3];
  float origin[3];
  float shrink;
  float cut[3];
  float cut_shrink;
  // Extents in double: float ones, rounded outward by up to 2^-24 of their size, would make a corner that
  // thousands of slivers share (a fan's apex) look nearer than it is by more than the search's tie slack.
  double lo[3], hi[3];
  double cut_lo, cut_hi;
};

class TriangleBvh {
 public:
  // An empty hierarchy: every query returns no hit.
  TriangleBvh() = default;
  // `indices` holds three vertex indices per triangle, each < positions.size(). Triangles with a non-finite
  // corner are left out of the tree (never hit) but keep their numbers. Built with a binned surface area
  // heuristic; the tree depends only on the input (deterministic).
  TriangleBvh(std::span<const Vec3d> positions, std::span<const std::uint32_t> indices);

  std::size_t triangle_count() const { return slot_of_.size(); }  // as given, including left-out ones
  std::size_t node_count() const { return nodes_.size(); }  // internal nodes
  bool empty() const { return root_.count == 0 && nodes_.empty(); }  // no triangle with finite corners
  Bounds3 bounds() const;

  // The closest point on any triangle: the exact closest point (up to rounding) of a triangle no other one is
  // closer than by more than 2^-24 (6e-8) of the largest coordinate of the tree or p. Among equally close
  // triangles, which one is returned is unspecified (but the same for the same query).
  BvhHit closest_point(const Vec3d& p) const;
  // The same distance, with triangle `hint` (for example the previous answer of a spatially coherent stream of
  // queries) measured first, and its neighbours across the edges the closest point lies on while they are
  // closer, so that most of the tree is pruned at once. May name a different triangle only when several are
  // equally close. An out-of-range or left-out hint is ignored.
  BvhHit closest_point(const Vec3d& p, std::uint32_t hint) const;
  // The same, adding the query's work to `work` (what tests and benchmarks count instead of time).
  BvhHit closest_point(const Vec3d& p, std::uint32_t hint, BvhWork& work) const;
  // The closest point strictly closer than `max_distance`, or no hit. Cheap when nothing is near.
  BvhHit closest_point_within(const Vec3d& p, double max_distance) const;
  // Whether some triangle lies within `max_distance` of p (its distance as closest_point measures it).
  // Triangle `hint` first, then a walk from it across the edges its closest point lies on while that gets
  // closer, then the descent, which stops at the first triangle within; `hint` becomes the triangle found. The answer depends only on the tree, never on the hint, and
  // costs about one triangle where a coherent stream of queries all pass.
  bool any_within(const Vec3d& p, double max_distance, std::uint32_t& hint, BvhWork& work) const;
  bool any_within(const Vec3d& p, double max_distance, std::uint32_t& hint) const {
    BvhWork work;
    return any_within(p, max_distance, hint, work);
  }

  // Corners of triangle t (t < triangle_count()) as given.
  std::array<Vec3d, 3> triangle(std::uint32_t t) const;
  // A triangle in the tree sharing the edge of t opposite its corner k (the same two vertex indices), or
  // kInvalidIndex; around an edge of more than two triangles, each names the next.
  std::uint32_t neighbor(std::uint32_t t, int k) const { return neighbor_[t][k]; }

  // The tree (for tests and debugging). The root is a child reference like those inside nodes: node
  // root().index when root().count == 0 (then node 0), else a single leaf. Slot s is piece slot_piece(s) of
  // triangle slot_triangle(s); the boxes above a slot contain its piece, and a leaf measures the whole triangle.
  struct Root {
    float min[3] = {}, max[3] = {};  // rounded outward like node boxes
    std::uint32_t index = 0, count = 0;
  };
  const Root& root() const { return root_; }
  std::span<const BvhNode> nodes() const { return nodes_; }
  // The oriented box of child i of node `node`, or nullptr where only the axis-aligned box is kept.
  const BvhOrientedBox* oriented_box(std::uint32_t node, int i) const {
    const std::uint32_t k = node_obb_.empty() ? kInvalidIndex : node_obb_[node][i];
    return k == kInvalidIndex ? nullptr : &obbs_[k];
  }
  std::size_t oriented_box_count() const { return obbs_.size(); }
  // Leaf slots: one per triangle in the tree, more for long slivers entered as several pieces.
  std::size_t slot_count() const { return slot_triangle_.size(); }
  std::uint32_t slot_triangle(std::uint32_t slot) const { return slot_triangle_[slot]; }
  // The part of its triangle slot `slot` stands for in the boxes above it (the leaf test measures the whole
  // triangle).
  BvhPiece slot_piece(std::uint32_t slot) const { return slot_piece_.empty() ? BvhPiece{} : slot_piece_[slot]; }

 private:
  // Ordered depth-first descent (nearer child first, boxes not nearer than the best so far by more than a
  // rounding slack skipped), keeping `best` unless something strictly closer is found. `known` (a triangle
  // measured already, or none) only tightens the pruning, and is returned when the descent found nothing as
  // close.
  BvhHit search(const Vec3d& p, BvhHit best, const BvhHit& known, BvhWork& work) const;
  BvhHit hinted(const Vec3d& p, std::uint32_t hint, BvhWork& work) const;
  BvhHit measure(const Vec3d& p, std::uint32_t triangle, BvhWork& work) const;  // one triangle in the tree
  // The edge neighbour of at.triangle across the edge (or either edge at a corner) its closest point lies on,
  // where that is closer to p; else `at`.
  BvhHit step_closer(const Vec3d& p, const BvhHit& at, BvhWork& work) const;
  // Squared distance from p to child i of node `node`: its axis-aligned box, raised to its oriented box where
  // one is kept and the axis-aligned one is nearer than `limit`.
  double child_dist_sq(std::uint32_t node, int i, const Vec3d& p, double limit) const;
  void fit_oriented_boxes();

  Root root_;
  double scale_ = 0;  // largest absolute coordinate of a triangle in the tree
  std::vector<BvhNode> nodes_;
  std::vector<std::array<std::uint32_t, 2>> node_obb_;  // per node and child: index into obbs_ or kInvalidIndex
  std::vector<BvhOrientedBox> obbs_;
  std::vector<std::array<Vec3d, 3>> slot_corners_;  // triangles in leaf order, for locality
  std::vector<std::uint32_t> slot_triangle_;        // slot -> triangle number
  std::vector<BvhPiece> slot_piece_;                // slot -> piece of its triangle; empty where none is split
  std::vector<std::uint32_t> slot_of_;              // triangle number -> its first slot, kInvalidIndex if left out
  std::vector<std::array<std::uint32_t, 3>> neighbor_;  // triangle -> one across the edge opposite corner k
  std::vector<Vec3d> positions_;                    // as given, for triangle()
  std::vector<std::uint32_t> indices_;
};

// A BVH over the mesh's faces fan-triangulated from their first corner; triangle numbers match the order of
// triangulated(mesh).
TriangleBvh make_triangle_bvh(const Mesh& mesh);

}  // namespace lodforge
