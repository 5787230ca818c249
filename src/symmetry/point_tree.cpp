#include "point_tree.hpp"

#include <algorithm>
#include <numeric>

namespace lodforge::symmetry::detail {
namespace {

constexpr std::uint32_t kLeafSize = 8;

}  // namespace

PointTree::PointTree(std::vector<Vec3d> points, std::vector<std::uint32_t> ids)
    : points_(std::move(points)), ids_(std::move(ids)) {
  if (points_.empty()) return;
  nodes_.reserve(2 * points_.size() / kLeafSize + 2);
  build(0, static_cast<std::uint32_t>(points_.size()));
}

std::uint32_t PointTree::build(std::uint32_t begin, std::uint32_t end) {
  const auto index = static_cast<std::uint32_t>(nodes_.size());
  nodes_.push_back(Node{.begin = begin, .end = end});
  if (end - begin <= kLeafSize) return index;
  Bounds3 box;
  for (std::uint32_t i = begin; i < end; ++i) box.add(points_[i]);
  int axis = 0;
  for (int a = 1; a < 3; ++a) {
    if (box.max[a] - box.min[a] > box.max[axis] - box.min[axis]) axis = a;
  }
  // Sort a permutation so that points and ids move together; (coordinate, id) is a total order.
  std::vector<std::uint32_t> order(end - begin);
  std::iota(order.begin(), order.end(), begin);
  const std::uint32_t mid = (end - begin) / 2;
  std::nth_element(order.begin(), order.begin() + mid, order.end(), [&](std::uint32_t a, std::uint32_t b) {
    if (points_[a][axis] != points_[b][axis]) return points_[a][axis] < points_[b][axis];
    return ids_[a] < ids_[b];
  });
  std::vector<Vec3d> p(order.size());
  std::vector<std::uint32_t> id(order.size());
  for (std::size_t i = 0; i < order.size(); ++i) {
    p[i] = points_[order[i]];
    id[i] = ids_[order[i]];
  }
  std::copy(p.begin(), p.end(), points_.begin() + begin);
  std::copy(id.begin(), id.end(), ids_.begin() + begin);
  const double split = points_[begin + mid][axis];
  const std::uint32_t left = build(begin, begin + mid);
  const std::uint32_t right = build(begin + mid, end);
  Node& n = nodes_[index];
  n.axis = axis;
  n.split = split;
  n.left = left;
  n.right = right;
  return index;
}

void PointTree::search(std::uint32_t node, const Vec3d& q, Nearest& best) const {
  const Node& n = nodes_[node];
  if (n.axis < 0) {
    for (std::uint32_t i = n.begin; i < n.end; ++i) {
      const Vec3d d = points_[i] - q;
      const double d2 = dot(d, d);
      if (d2 < best.distance2 || (d2 == best.distance2 && best.id != 0xffffffffu && ids_[i] < best.id)) {
        best.second_distance2 = best.distance2;
        best.distance2 = d2;
        best.id = ids_[i];
      } else if (d2 < best.second_distance2) {
        best.second_distance2 = d2;
      }
    }
    return;
  }
  const double delta = q[n.axis] - n.split;
  const std::uint32_t near_child = delta < 0 ? n.left : n.right;
  const std::uint32_t far_child = delta < 0 ? n.right : n.left;
  search(near_child, q, best);
  // Both the nearest and the second nearest must be exact, so prune against the second.
  if (delta * delta <= best.second_distance2) search(far_child, q, best);
}

PointTree::Nearest PointTree::nearest(const Vec3d& q, double radius) const {
  Nearest best;
  best.distance2 = best.second_distance2 = radius * radius;
  if (!nodes_.empty()) search(0, q, best);
  return best;
}

}  // namespace lodforge::symmetry::detail
