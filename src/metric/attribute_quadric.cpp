// Hoppe 1999 attribute quadrics (see the header for the formulation).
#include "lodforge/metric/attribute_quadric.hpp"

#include <cmath>

namespace lodforge {

bool fit_attribute_gradient(const Vec3d& p0, const Vec3d& p1, const Vec3d& p2, double s0, double s1, double s2,
                            AttributeGradient& out) {
  // g = a e1 + b e2 (in the plane) with g·e1 = s1 − s0 and g·e2 = s2 − s0: a 2×2 Gram system.
  const Vec3d e1 = p1 - p0, e2 = p2 - p0;
  const double g11 = dot(e1, e1), g12 = dot(e1, e2), g22 = dot(e2, e2);
  const double det = g11 * g22 - g12 * g12;
  // Relative test: det is |e1 × e2|², compared with |e1|²|e2|² (the sine of the corner angle squared).
  if (!(det > 1e-12 * g11 * g22) || !std::isfinite(det)) return false;
  const double r1 = s1 - s0, r2 = s2 - s0;
  const double a = (r1 * g22 - r2 * g12) / det;
  const double b = (r2 * g11 - r1 * g12) / det;
  const Vec3d g = e1 * a + e2 * b;
  const double d = s0 - dot(g, p0);
  if (!std::isfinite(d) || !std::isfinite(g[0]) || !std::isfinite(g[1]) || !std::isfinite(g[2])) return false;
  out.g = g;
  out.d = d;
  return true;
}

void accumulate_attribute(AttributeQuadric& q, AttributeGradient& sum, const AttributeGradient& f, double w) {
  const Vec3d& g = f.g;
  q.pos.a00 += w * g[0] * g[0];
  q.pos.a01 += w * g[0] * g[1];
  q.pos.a02 += w * g[0] * g[2];
  q.pos.a11 += w * g[1] * g[1];
  q.pos.a12 += w * g[1] * g[2];
  q.pos.a22 += w * g[2] * g[2];
  q.pos.b0 += w * f.d * g[0];
  q.pos.b1 += w * f.d * g[1];
  q.pos.b2 += w * f.d * g[2];
  q.pos.c += w * f.d * f.d;
  sum.g = sum.g + g * w;
  sum.d += w * f.d;
}

void merge_attribute_quadrics(AttributeQuadric& q, std::span<AttributeGradient> sums, const AttributeQuadric& r,
                              std::span<const AttributeGradient> other) {
  q.pos += r.pos;
  q.alpha += r.alpha;
  for (std::size_t j = 0; j < sums.size(); ++j) {
    sums[j].g = sums[j].g + other[j].g;
    sums[j].d += other[j].d;
  }
}

namespace {

// Eliminates one attribute from the position quadric (Hoppe 1999): subtracts (g, d)(g, d)^T / alpha, with
// inv = 1 / alpha.
void subtract_gradient(Quadric& r, const Vec3d& g, double d, double inv) {
  r.a00 -= inv * g[0] * g[0];
  r.a01 -= inv * g[0] * g[1];
  r.a02 -= inv * g[0] * g[2];
  r.a11 -= inv * g[1] * g[1];
  r.a12 -= inv * g[1] * g[2];
  r.a22 -= inv * g[2] * g[2];
  r.b0 -= inv * d * g[0];
  r.b1 -= inv * d * g[1];
  r.b2 -= inv * d * g[2];
  r.c -= inv * d * d;
}

}  // namespace

Quadric reduce_attributes(const AttributeQuadric& q, std::span<const AttributeGradient> sums) {
  Quadric r;
  if (!(q.alpha > 0.0)) return r;
  r = q.pos;
  r.weight = 0.0;
  const double inv = 1.0 / q.alpha;
  for (const AttributeGradient& s : sums) subtract_gradient(r, s.g, s.d, inv);
  return r;
}

Quadric reduce_merged_attributes(const AttributeQuadric& a, std::span<const AttributeGradient> ga,
                                 const AttributeQuadric& b, std::span<const AttributeGradient> gb) {
  Quadric r;
  const double alpha = a.alpha + b.alpha;
  if (!(alpha > 0.0)) return r;
  r = a.pos + b.pos;
  r.weight = 0.0;
  const double inv = 1.0 / alpha;
  for (std::size_t j = 0; j < ga.size(); ++j) {
    subtract_gradient(r, ga[j].g + gb[j].g, ga[j].d + gb[j].d, inv);
  }
  return r;
}

bool optimal_attributes(const AttributeQuadric& q, std::span<const AttributeGradient> sums, const Vec3d& p,
                        std::span<double> out) {
  if (!(q.alpha > 0.0)) return false;
  const double inv = 1.0 / q.alpha;
  for (std::size_t j = 0; j < sums.size() && j < out.size(); ++j) out[j] = (dot(sums[j].g, p) + sums[j].d) * inv;
  return true;
}

const AttributeGroup* AttributeLayout::find(AttributeGroup::Type type, int set) const {
  for (const AttributeGroup& g : groups) {
    if (g.type == type && g.set == set) return &g;
  }
  return nullptr;
}

void AttributeLayout::scaled(const std::vector<Vec3f>& normals, const std::vector<std::vector<Vec2f>>& uvs,
                             const std::vector<std::vector<Vec4f>>& colors, std::uint32_t w, double* out) const {
  for (const AttributeGroup& g : groups) {
    double* o = out + g.dim;
    switch (g.type) {
      case AttributeGroup::Type::normal:
        for (int i = 0; i < 3; ++i) o[i] = normals[w][i] * g.scale;
        break;
      case AttributeGroup::Type::uv:
        for (int i = 0; i < 2; ++i) o[i] = uvs[static_cast<std::size_t>(g.set)][w][i] * g.scale;
        break;
      case AttributeGroup::Type::color:
        for (int i = 0; i < 4; ++i) o[i] = colors[static_cast<std::size_t>(g.set)][w][i] * g.scale;
        break;
    }
  }
}

AttributeLayout attribute_layout(const AttributeLayoutInput& in) {
  AttributeLayout out;
  auto add_group = [&](AttributeGroup::Type type, int set, int dims, double scale) {
    if (!(scale > 0.0) || !std::isfinite(scale) || out.dims + dims > kMaxAttributeDims) return;
    out.groups.push_back({type, set, out.dims, dims, scale});
    out.dims += dims;
  };
  if (in.normals) add_group(AttributeGroup::Type::normal, 0, 3, std::sqrt(in.normal_weight) * in.length_unit);
  for (std::size_t set = 0; set < in.uv_area.size(); ++set) {
    if (in.uv_area[set] > 0.0) {
      add_group(AttributeGroup::Type::uv, static_cast<int>(set), 2,
                std::sqrt(in.uv_weight) * std::sqrt(in.area / in.uv_area[set]));
    }
  }
  for (std::size_t set = 0; set < in.color_sets.size(); ++set) {
    if (in.color_sets[set] != 0) {
      add_group(AttributeGroup::Type::color, static_cast<int>(set), 4, std::sqrt(in.color_weight) * in.length_unit);
    }
  }
  return out;
}

}  // namespace lodforge
