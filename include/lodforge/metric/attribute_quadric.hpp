// Attribute quadrics in the memory-efficient form of H. Hoppe, "New Quadric Metric for Simplifying Meshes
// with Appearance Attributes", IEEE Visualization 1999 (the same layout as meshoptimizer's
// Quadric + QuadricGrad, and the O(m) reduction of Hoppe & Marschner 2000).
//
// For each face and attribute j, s_j(p) = g_j·p + d_j is the linear function over the face's plane that takes
// the corner values (g_j in the plane). The face error at (p, s) is
//   w [ (n·p + d)² + Σ_j (g_j·p + d_j − s_j)² ].
// Summed over the faces of one wedge this needs, besides the geometric plane quadric (kept per vertex):
//   pos   = Σ w (g_j g_jᵀ, d_j g_j, d_j²)    as a Quadric over p (its `weight` unused)
//   G_j   = Σ w g_j,   β_j = Σ w d_j         (4 values per attribute: AttributeGradient)
//   α     = Σ w
// that is 11 + 4m scalars for m attributes. Minimising over s gives s_j* = (G_j·p + β_j) / α, and what is left
// is a quadric over p alone (reduce()): pos − Σ_j (G_j·p + β_j)² / α. Adding it to the geometric quadric
// gives the combined cost whose minimiser is the joint optimum (Schur complement), so the usual 3×3 placement
// machinery works unchanged.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "lodforge/core/vec.hpp"
#include "lodforge/metric/quadric.hpp"

namespace lodforge {

// s(p) = g·p + d over one face, or the weighted sums G, β of such functions.
struct AttributeGradient {
  Vec3d g{};
  double d = 0;
};

// The wedge-level accumulator header (the per-attribute gradients live in a separate span of m entries).
struct AttributeQuadric {
  Quadric pos;       // Σ w (g·p + d)² over attributes and faces, as a quadric over p
  double alpha = 0;  // Σ w
};

// The linear function over triangle (p0, p1, p2) that takes values s0, s1, s2 at the corners, with its
// gradient in the triangle's plane. False (output untouched) for a degenerate triangle.
bool fit_attribute_gradient(const Vec3d& p0, const Vec3d& p1, const Vec3d& p2, double s0, double s1, double s2,
                            AttributeGradient& out);

// Adds face function `f` with weight w to one attribute's accumulators.
void accumulate_attribute(AttributeQuadric& q, AttributeGradient& sum, const AttributeGradient& f, double w);

// q += r and sums[j] += other[j] (merging two wedges).
void merge_attribute_quadrics(AttributeQuadric& q, std::span<AttributeGradient> sums, const AttributeQuadric& r,
                              std::span<const AttributeGradient> other);

// The quadric over p left after minimising over the attributes: q.pos − Σ_j (G_j·p + β_j)² / α.
// Zero when α is 0. Its `weight` is 0 (attribute error is not surface).
Quadric reduce_attributes(const AttributeQuadric& q, std::span<const AttributeGradient> sums);

// reduce_attributes of the merge of (a, ga) and (b, gb), without building the merged sums.
Quadric reduce_merged_attributes(const AttributeQuadric& a, std::span<const AttributeGradient> ga,
                                 const AttributeQuadric& b, std::span<const AttributeGradient> gb);

// s_j* = (G_j·p + β_j) / α for every attribute; false (out untouched) when α is 0.
bool optimal_attributes(const AttributeQuadric& q, std::span<const AttributeGradient> sums, const Vec3d& p,
                        std::span<double> out);

// ---- Which attributes take part, and in which units (shared by the triangle and polychord engines) ----------

// Attribute dimensions beyond this are left out of the metric (a mesh would need 5 colour sets).
inline constexpr int kMaxAttributeDims = 24;

// One attribute stream taking part in the metric: dims [dim, dim + dims) of the scaled attribute vector,
// scaled = raw × scale.
struct AttributeGroup {
  enum class Type : std::uint8_t { normal, uv, color } type;
  int set = 0;
  int dim = 0, dims = 0;
  double scale = 0;
};

struct AttributeLayout {
  std::vector<AttributeGroup> groups;
  int dims = 0;  // total, at most kMaxAttributeDims

  // The group of `type` and `set`, or nullptr.
  const AttributeGroup* find(AttributeGroup::Type type, int set) const;
  // Scaled attribute vector of wedge w (dims values) from per-wedge streams laid out as Mesh's.
  void scaled(const std::vector<Vec3f>& normals, const std::vector<std::vector<Vec2f>>& uvs,
              const std::vector<std::vector<Vec4f>>& colors, std::uint32_t w, double* out) const;
};

// What the layout is made from: whether there are normals, the UV area of each set (0: no usable set) and
// which colour sets exist, beside the surface area; weights λ as in SimplifyOptions::AttributeWeights.
// Units: a normal or colour component is scaled by sqrt(λ) × length_unit (about one mean
// edge length: sqrt(2 × mean triangle area)), a UV set by sqrt(λ) × sqrt(area / UV area) (its texel density),
// so every scaled attribute is a length. Groups with a zero or non-finite scale, or past kMaxAttributeDims,
// are left out. Order: normal, UV sets, colour sets.
struct AttributeLayoutInput {
  bool normals = false;
  std::vector<double> uv_area;           // per UV set
  std::vector<std::uint8_t> color_sets;  // per colour set: non-zero when present
  double area = 0, length_unit = 0;
  double normal_weight = 1, uv_weight = 1, color_weight = 1;
};
AttributeLayout attribute_layout(const AttributeLayoutInput& in);

// AttributeLayoutInput::length_unit of a surface of `area` made of `triangles` triangles: sqrt(2 × mean
// triangle area), about one mean edge length (0 without triangles). Both engines weigh attributes by it.
inline double attribute_length_unit(double area, std::size_t triangles) {
  return triangles > 0 ? std::sqrt(2.0 * area / static_cast<double>(triangles)) : 0.0;
}

// Unsigned area of the UV triangle (a, b, c) in double precision (what AttributeLayoutInput::uv_area sums).
inline double uv_triangle_area(const Vec2f& a, const Vec2f& b, const Vec2f& c) {
  return 0.5 * std::abs((double{b[0]} - a[0]) * (double{c[1]} - a[1]) - (double{c[0]} - a[0]) * (double{b[1]} - a[1]));
}

}  // namespace lodforge
