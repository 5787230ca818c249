// A static kd-tree over a point set: the nearest and second-nearest point to a query. Private to the
// symmetry part (mirror images of vertices are looked up among the vertices).
#pragma once

#include <cstdint>
#include <vector>

#include "lodforge/core/vec.hpp"

namespace lodforge::symmetry::detail {

class PointTree {
 public:
  // `ids` names the points (vertex ids); queries answer with them. Ties break towards the smaller id.
  PointTree(std::vector<Vec3d> points, std::vector<std::uint32_t> ids);

  struct Nearest {
    std::uint32_t id = 0xffffffffu;  // none when the tree is empty
    double distance2 = INFINITY;
    double second_distance2 = INFINITY;  // the next nearest point's squared distance
  };
  // Only points closer than `radius` count (the search stays local): farther ones leave `id` none and the
  // distances at radius squared.
  Nearest nearest(const Vec3d& q, double radius = INFINITY) const;
  bool empty() const { return points_.empty(); }

 private:
  struct Node {
    std::uint32_t begin = 0, end = 0;  // leaf: point range; inner: both children follow
    std::uint32_t left = 0, right = 0;
    int axis = -1;  // -1 = leaf
    double split = 0;
  };
  std::uint32_t build(std::uint32_t begin, std::uint32_t end);
  void search(std::uint32_t node, const Vec3d& q, Nearest& best) const;

  std::vector<Vec3d> points_;  // reordered so that each leaf is a contiguous range
  std::vector<std::uint32_t> ids_;
  std::vector<Node> nodes_;
};

}  // namespace lodforge::symmetry::detail
