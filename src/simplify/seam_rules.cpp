// The seam, attribute, UV and skin rules of the triangle engines' working mesh: corner keys and vertex
// seams, attribute quadrics per wedge and their part of a candidate's cost, which wedges a collapse carries
// over and which it refuses, new UVs and blended skin weights of a moved vertex.
//
// Papers implemented here:
//  - H. Hoppe, "New Quadric Metric for Simplifying Meshes with Appearance Attributes", 1999: attribute
//    quadrics per wedge, reduced to position space for the cost.
//  - M. Garland, P. Heckbert 1998: discontinuity (seam) constraint planes.
#include <algorithm>
#include <array>
#include <cmath>
#include <span>
#include <string>

#include "collapse_mesh.hpp"
#include "lodforge/metric/skin.hpp"

namespace lodforge::collapse {
namespace {

// A UV triangle whose sine at a corner falls below this is a sliver (texels smeared across it): a collapse may
// not make one, though it keeps one the input has. On Duck at 50% this took the L2 stretch ratio (against the
// input's) from 8.7 to 0.8.
constexpr double kUvSliverSine = 1e-3;

// Normals (and tangents) of one vertex closer than this angle's cosine (0.1°) are one direction: well below any
// hard edge a modeller makes, well above float and 16-bit quantisation noise.
constexpr double kSameDirectionCos = 0.9999984769132877;


// Whether two normals (or tangents, xyz) point the same way within kSameDirectionCos. Exporters round the
// normals of one smooth vertex differently per render vertex (CesiumMan: 962 wedge pairs whose normals differ
// only by float noise, under 0.001°); such a split is no hard edge, and treating it as a seam pinned the
// vertex to it (mean distance 0.0088% against 0.0031% of the diagonal at 50%).
bool same_direction(const auto& a, const auto& b) {
  const double d = double{a[0]} * b[0] + double{a[1]} * b[1] + double{a[2]} * b[2];
  const double aa = double{a[0]} * a[0] + double{a[1]} * a[1] + double{a[2]} * a[2];
  const double bb = double{b[0]} * b[0] + double{b[1]} * b[1] + double{b[2]} * b[2];
  if (!(aa > 0.0) || !(bb > 0.0)) return a[0] == b[0] && a[1] == b[1] && a[2] == b[2];
  return d > 0.0 && d * d >= kSameDirectionCos * kSameDirectionCos * aa * bb;
}

}  // namespace

// Wedges and corner keys (see VertexKind). Render vertices of one vertex that are equal in every attribute
// (non-indexed glTF primitives store one per corner), normals and tangents within 0.1° (same_direction), are
// one wedge: corners use the lowest such wedge id, so they are no seam; the others drop out of the output.
// Keys are only materialised when they differ from the wedge ids: with several materials (a wedge used on
// both sides of a material boundary gets one key per side); relax() materialises them for its stages.
void CollapseMesh::setup_keys() {
  const Mesh& m = src_;
  const std::size_t nw = m.wedge_count(), nv = m.vertex_count(), nf = face_slots();
  auto material = [&](std::size_t f) {
    const std::uint32_t sf = source_face(f);
    return sf < m.face_material.size() ? m.face_material[sf] : 0u;
  };
  bool several = false;
  for (std::size_t f = 1; f < nf && !several; ++f) several = material(f) != material(0);

  // Wedges grouped by vertex (counting sort keeps ids ascending); wedges naming no vertex are left out.
  std::vector<std::uint32_t> first(nv + 1, 0), order(nw);
  for (std::uint32_t w = 0; w < nw; ++w) {
    if (m.wedge_vertex[w] < nv) ++first[m.wedge_vertex[w] + 1];
  }
  bool shared = false;
  for (std::size_t v = 0; v < nv; ++v) {
    shared |= first[v + 1] > 1;
    first[v + 1] += first[v];
  }
  std::vector<std::uint32_t> exact;  // class representative of each wedge (identity when empty)
  if (shared) {
    {
      std::vector<std::uint32_t> fill(first.begin(), first.end() - 1);
      for (std::uint32_t w = 0; w < nw; ++w) {
        if (m.wedge_vertex[w] < nv) order[fill[m.wedge_vertex[w]]++] = w;
      }
    }
    auto same = [&](std::uint32_t x, std::uint32_t y, bool with_normals) {
      if (with_normals) {
        if (m.normals.size() == nw && !same_direction(m.normals[x], m.normals[y])) return false;
        if (m.tangents.size() == nw &&
            !(same_direction(m.tangents[x], m.tangents[y]) && (m.tangents[x][3] < 0.0f) == (m.tangents[y][3] < 0.0f))) {
          return false;
        }
        for (const MorphTarget& t : m.morph_targets) {
          if (t.normal_deltas.size() == nw && !(t.normal_deltas[x] == t.normal_deltas[y])) return false;
          if (t.tangent_deltas.size() == nw && !(t.tangent_deltas[x] == t.tangent_deltas[y])) return false;
        }
      }
      for (const MorphTarget& t : m.morph_targets) {
        if (t.position_deltas.size() == nw && !(t.position_deltas[x] == t.position_deltas[y])) return false;
      }
      for (const auto& set : m.uvs) {
        if (set.size() == nw && !(set[x] == set[y])) return false;
      }
      for (const auto& set : m.colors) {
        if (set.size() == nw && !(set[x] == set[y])) return false;
      }
      for (const CustomAttribute& c : m.custom) {
        const auto k = static_cast<std::size_t>(std::max(c.components, 0));
        if (k == 0 || c.values.size() != nw * k) continue;
        for (std::size_t i = 0; i < k; ++i) {
          if (!(c.values[x * k + i] == c.values[y * k + i])) return false;
        }
      }
      return true;
    };
    auto classify = [&](std::vector<std::uint32_t>& cls, bool with_normals) {
      cls.resize(nw);
      for (std::uint32_t w = 0; w < nw; ++w) cls[w] = w;
      for (std::size_t v = 0; v < nv; ++v) {
        for (std::uint32_t i = first[v]; i < first[v + 1]; ++i) {
          for (std::uint32_t j = first[v]; j < i; ++j) {
            if (cls[order[j]] == order[j] && same(order[i], order[j], with_normals)) {
              cls[order[i]] = order[j];
              break;
            }
          }
        }
      }
    };
    classify(exact, true);
    for (std::uint32_t& w : tri_wedge_) w = exact[w];
  }
  if (!several) return;

  // Dense ids for (class, material) pairs.
  std::vector<std::uint64_t> pairs(tri_.size());
  for (std::size_t c = 0; c < tri_.size(); ++c) {
    const std::uint32_t w = corner_wedge(c);
    pairs[c] = (std::uint64_t{w} << 32) | material(c / 3);
  }
  std::vector<std::uint64_t> sorted(pairs);
  std::sort(sorted.begin(), sorted.end());
  sorted.erase(std::unique(sorted.begin(), sorted.end()), sorted.end());
  tri_key_.resize(pairs.size());
  for (std::size_t c = 0; c < pairs.size(); ++c) {
    tri_key_[c] = static_cast<std::uint32_t>(std::lower_bound(sorted.begin(), sorted.end(), pairs[c]) - sorted.begin());
  }
}

// Attribute quadrics (Hoppe 1999) of every wedge: each face's linear attribute functions, weighted by the
// face's area × the corner vertex's painted priority squared (as the surface quadric), summed into the wedge at each corner. Parallel over
// vertices (a wedge belongs to one vertex), each vertex's faces in list order: deterministic.
//
// Units (SimplifyOptions::AttributeWeights): positions are normalised to the unit cube; a normal or colour
// component is scaled by sqrt(λ) × L with L = sqrt(2 × mean face area) (about one mean edge length), a UV set
// by sqrt(λ) × sqrt(Σ 3-D area / Σ UV area) (its texel density), so every scaled attribute is a length.
void CollapseMesh::setup_attributes(Parallel& parallel) {
  const Mesh& m = src_;
  const std::size_t nf = face_slots(), nw = m.wedge_count(), nv = vx_.size();
  const AttributeWeights& aw = options_.attribute_weights;
  bool metric = !normals_.empty() || !skin_.empty();  // anything below that needs the areas
  for (const auto& set : uvs_) metric |= !set.empty();
  for (const auto& set : colors_) metric |= !set.empty();
  if (!metric) {  // geometry only (morph deltas at most): no groups, no skin term
    carry_ = blend_ && !morphs_.empty();
    return;
  }
  double area = 0.0;
  std::vector<double> uv_area(uvs_.size(), 0.0);
  for (std::size_t f = 0; f < nf; ++f) {
    const std::uint32_t* t = &tri_[3 * f];
    const std::uint32_t* w = face_wedges(f);
    const Vec3d p0 = vx_[t[0]].pos, p1 = vx_[t[1]].pos, p2 = vx_[t[2]].pos;
    if (!finite3(p0) || !finite3(p1) || !finite3(p2)) continue;
    area += 0.5 * length(cross(p1 - p0, p2 - p0));
    for (std::size_t set = 0; set < uvs_.size(); ++set) {
      if (uvs_[set].empty()) continue;
      const double ua = uv_triangle_area(uvs_[set][w[0]], uvs_[set][w[1]], uvs_[set][w[2]]);
      if (std::isfinite(ua)) uv_area[set] += ua;
    }
  }
  const double length_unit = attribute_length_unit(area, nf);
  skin_cost_scale_ = skin_.empty() ? 0.0 : aw.skin * length_unit * length_unit;

  std::vector<std::uint8_t> color_sets;
  for (const auto& set : colors_) color_sets.push_back(set.empty() ? 0 : 1);
  layout_ = attribute_layout({.normals = !normals_.empty(),
                              .uv_area = uv_area,
                              .color_sets = color_sets,
                              .area = area,
                              .length_unit = length_unit,
                              .normal_weight = aw.normal,
                              .uv_weight = aw.uv,
                              .color_weight = aw.color});
  bool values = !normals_.empty() || !skin_.empty() || !morphs_.empty();
  for (const auto& set : uvs_) values |= !set.empty();
  for (const auto& set : colors_) values |= !set.empty();
  carry_ = layout_.dims > 0 || (blend_ && values);
  if (layout_.dims == 0) return;  // geometry only: nothing below runs, the engine is exactly the plain QEM one

  const auto dims = static_cast<std::size_t>(layout_.dims);
  wq_.assign(nw, {});
  wg_.assign(nw * dims, {});
  // Scaled attribute vector of wedge w.
  auto scaled = [&](std::uint32_t w, double* out) { layout_.scaled(normals_, uvs_, colors_, w, out); };
  // Per face, the in-plane gradient basis: an attribute with corner values s0, s1, s2 has gradient
  // (s1 − s0) B1 + (s2 − s0) B2 (fit_attribute_gradient's Gram solve, done once per face instead of once per
  // attribute and corner).
  struct FaceBasis {
    Vec3d b1, b2;
    double area = 0;  // 0: degenerate, no attribute functions
  };
  std::vector<FaceBasis> basis(nf);
  parallel.for_ranges(nf, 4096, [&](std::size_t fb, std::size_t fe) {
    for (std::size_t f = fb; f < fe; ++f) {
      const std::uint32_t* t = &tri_[3 * f];
      const Vec3d p0 = vx_[t[0]].pos, e1 = vx_[t[1]].pos - p0, e2 = vx_[t[2]].pos - p0;
      const double g11 = dot(e1, e1), g12 = dot(e1, e2), g22 = dot(e2, e2);
      const double det = g11 * g22 - g12 * g12;
      if (!(det > 1e-12 * g11 * g22) || !std::isfinite(det)) continue;
      basis[f] = {(e1 * g22 - e2 * g12) * (1.0 / det), (e2 * g11 - e1 * g12) * (1.0 / det), 0.5 * std::sqrt(det)};
    }
  });
  parallel.for_ranges(nv, 1024, [&](std::size_t vb, std::size_t ve) {
    std::array<double, 3 * kMaxAttributeDims> corner_values;
    for (std::size_t vi = vb; vi < ve; ++vi) {
      const auto v = static_cast<std::uint32_t>(vi);
      if (kind_[v] == VertexKind::frozen) continue;
      const double paint = v < priority_.size() ? static_cast<double>(priority_[v]) * priority_[v] : 1.0;
      const std::uint32_t* fl = star(v);
      for (std::uint32_t i = 0; i < size_[v]; ++i) {
        const FaceBasis& fb = basis[fl[i]];
        const double weight = fb.area * paint;
        if (!(weight > 0.0) || !std::isfinite(weight)) continue;
        const std::uint32_t* t = &tri_[3 * std::size_t{fl[i]}];
        const std::uint32_t* w = face_wedges(fl[i]);
        double* s0 = corner_values.data();
        double* s1 = s0 + dims;
        double* s2 = s1 + dims;
        scaled(w[0], s0);
        scaled(w[1], s1);
        scaled(w[2], s2);
        const std::uint32_t wc = w[corner_of(t, v)];
        AttributeQuadric& q = wq_[wc];
        AttributeGradient* sums = &wg_[wc * dims];
        const Vec3d& p0 = vx_[t[0]].pos;
        bool any = false;
        for (std::size_t d = 0; d < dims; ++d) {
          AttributeGradient fn;
          fn.g = fb.b1 * (s1[d] - s0[d]) + fb.b2 * (s2[d] - s0[d]);
          fn.d = s0[d] - dot(fn.g, p0);
          if (!std::isfinite(fn.d)) continue;  // NaN attribute values carry no information
          accumulate_attribute(q, sums[d], fn, weight);
          any = true;
        }
        if (any) q.alpha += weight;
      }
    }
  });
}

// The attribute quadrics the merged vertex of edge (u, v) will have, reduced to position space (Hoppe 1999;
// position optimisation with several wedges): the wedge pairs across the edge's faces
// merge, every other wedge of u and v counts alone. The geometric quadric is counted once, by the caller.
void CollapseMesh::add_attribute_quadrics(std::uint32_t u, std::uint32_t v, Quadric& q) const {
  const auto dims = static_cast<std::size_t>(layout_.dims);
  auto grads = [&](std::uint32_t w) { return std::span<const AttributeGradient>(&wg_[w * dims], dims); };
  // Most edges: neither endpoint on a seam, so each has one wedge (one key, and outside permissive mode a key
  // is one wedge), read from its first face; the pair merges. Saves the star scans (a third of the time).
  if (((state_[u] | state_[v]) & kSeam) == 0 && stage_ == SeamStage::strict) {
    auto only_wedge = [&](std::uint32_t x) {
      const std::size_t f3 = 3 * std::size_t{pool_[begin_[x]]};
      return corner_wedge(f3 + corner_of(&tri_[f3], x));
    };
    const std::uint32_t wu = only_wedge(u), wv = only_wedge(v);
    q += reduce_merged_attributes(wq_[wu], grads(wu), wq_[wv], grads(wv));
    return;
  }
  // One pass over each star: the wedge pairs across the edge's faces, and each endpoint's distinct wedges (at
  // most 8 are looked at: more make a complex vertex, which never moves anyway).
  std::uint32_t pu[2] = {kInvalidIndex, kInvalidIndex}, pv[2] = {kInvalidIndex, kInvalidIndex};
  std::uint32_t wu[8], wv[8];
  int k = 0, nu = 0, nv = 0;
  auto note = [](std::uint32_t* list, int& n, std::uint32_t w) {
    if (n < 8 && std::find(list, list + n, w) == list + n) list[n++] = w;
  };
  {
    const std::uint32_t* fl = star(u);
    for (std::uint32_t i = 0; i < size_[u]; ++i) {
      const std::uint32_t* t = &tri_[3 * std::size_t{fl[i]}];
      const std::uint32_t* w = face_wedges(fl[i]);
      const std::uint32_t wc = w[corner_of(t, u)];
      note(wu, nu, wc);
      if (k < 2 && (t[0] == v || t[1] == v || t[2] == v)) {
        pu[k] = wc;
        pv[k] = w[corner_of(t, v)];
        ++k;
      }
    }
    const std::uint32_t* fv = star(v);
    for (std::uint32_t i = 0; i < size_[v]; ++i) {
      const std::uint32_t* t = &tri_[3 * std::size_t{fv[i]}];
      note(wv, nv, corner_wedge(3 * std::size_t{fv[i]} + corner_of(t, v)));
    }
  }
  if (k == 2 && pu[0] == pu[1] && pv[0] == pv[1]) k = 1;
  for (int i = 0; i < k; ++i) q += reduce_merged_attributes(wq_[pu[i]], grads(pu[i]), wq_[pv[i]], grads(pv[i]));
  // The other wedges of each endpoint, each once.
  for (int i = 0; i < nu; ++i) {
    if (wu[i] != pu[0] && wu[i] != pu[1]) q += reduce_attributes(wq_[wu[i]], grads(wu[i]));
  }
  for (int i = 0; i < nv; ++i) {
    if (wv[i] != pv[0] && wv[i] != pv[1]) q += reduce_attributes(wq_[wv[i]], grads(wv[i]));
  }
}


// Soft skinning term: merging two point masses of areas W_u, W_v whose weight vectors differ by Δ costs
// W_u W_v / (W_u + W_v) |Δ|² (the spread about their weighted mean), in the units of a normal change.
double CollapseMesh::skin_cost(std::uint32_t u, std::uint32_t v) const {
  const double wu = vx_[u].quadric.weight, wv = vx_[v].quadric.weight;
  if (!(wu + wv > 0.0)) return 0.0;
  const SkinComparison c = compare_skin(skin_[u], skin_[v], 0.0f);
  return skin_cost_scale_ * wu * wv / (wu + wv) * c.l2sq;
}

double CollapseMesh::edge_t(std::uint32_t a, std::uint32_t b, const Vec3d& x) const {
  const Vec3d e = vx_[b].pos - vx_[a].pos;
  const double len2 = dot(e, e);
  if (!(len2 > 0.0)) return 1.0;
  return std::clamp(dot(x - vx_[a].pos, e) / len2, 0.0, 1.0);
}

// The top influences of (1 − t) × a's weights + t × b's, at most as many as any input vertex used,
// renormalised to sum 1; ties by joint id.
SkinInfluences CollapseMesh::blended_skin(std::uint32_t a, std::uint32_t b, double t) const {
  std::pair<std::uint16_t, double> all[2 * kMaxInfluences];
  int n = 0;
  auto add = [&](const SkinInfluences& s, double f) {
    for (int i = 0; i < kMaxInfluences; ++i) {
      if (!(s.weights[i] > 0.0f) || f <= 0.0) continue;
      int j = 0;
      while (j < n && all[j].first != s.joints[i]) ++j;
      if (j == n) all[n++] = {s.joints[i], 0.0};
      all[j].second += f * static_cast<double>(s.weights[i]);
    }
  };
  add(skin_[a], 1.0 - t);
  add(skin_[b], t);
  std::sort(all, all + n, [](const auto& x, const auto& y) {
    return x.second > y.second || (x.second == y.second && x.first < y.first);
  });
  n = std::min(n, std::max(skin_cap_, 1));
  double sum = 0.0;
  for (int i = 0; i < n; ++i) sum += all[i].second;
  if (!(sum > 0.0)) return skin_[b];
  std::sort(all, all + n);  // joint order in the slots
  SkinInfluences out;
  for (int i = 0; i < n; ++i) {
    out.joints[i] = all[i].first;
    out.weights[i] = static_cast<float>(all[i].second / sum);
  }
  return out;
}

// Whether a's wedges map onto b's without merging distinct ones. The faces of edge ab pair each of their
// a-corner wedges with their b-corner wedge; that pairing must be one-to-one, and every wedge a's other faces
// use must be in it. Otherwise the collapse would have to invent attributes. Seam edges drawn as '=':
//
//   accepted: seam along ab              refused: seam e-a-f (drawn '|') passes through a
//
//        c                                       e
//   w1  / \  v1                                  |    w1     c
//   a ===== b    (w1 -> v1, w2 -> v2)        w2   a ------- b      a's w2 corners have no partner at b
//   w2  \ /  v2                                  |    w1     d
//        d                                       f
bool CollapseMesh::edge_corner_keys(std::uint32_t a, std::uint32_t b, const Check& c, std::uint32_t (&ka)[2],
                                    std::uint32_t (&kb)[2]) const {
  for (std::uint32_t i = 0; i < c.edge_face_count; ++i) {
    const std::size_t f3 = 3 * std::size_t{c.edge_faces[i]};
    const std::uint32_t* t = &tri_[f3];
    ka[i] = key(f3 + corner_of(t, a));
    kb[i] = key(f3 + corner_of(t, b));
  }
  return !(c.edge_face_count == 2 && ((ka[0] == ka[1]) != (kb[0] == kb[1])));
}

bool CollapseMesh::wedges_carry_over(std::uint32_t a, std::uint32_t b, const Check& c) const {
  std::uint32_t ka[2], kb[2];
  if (!edge_corner_keys(a, b, c, ka, kb)) return false;
  if ((state_[a] & kSeam) == 0) return true;  // one key at a: every corner carries ka[0]
  const std::uint32_t* fl = star(a);
  for (std::uint32_t i = 0; i < size_[a]; ++i) {
    const std::size_t f3 = 3 * std::size_t{fl[i]};
    const std::uint32_t k = key(f3 + corner_of(&tri_[f3], a));
    if (k != ka[0] && (c.edge_face_count < 2 || k != ka[1])) return false;
  }
  return true;
}

// SeamStage::uv on, a half-edge collapse a → b whose wedges do not carry over (a is where seams meet): the
// edge faces pair a's wedges with b's as wedges_carry_over() asks, and a's other wedges go to b with their
// corners, values unchanged, so every face keeps the attributes of its own side (no chart-spanning face; the
// UVs of the moved corners do not change, so none flips). Before SeamStage::materials a's faces must all
// have one material: a material boundary holds.
bool CollapseMesh::reattach_ok(std::uint32_t a, std::uint32_t b, const Check& c) const {
  std::uint32_t ka[2], kb[2];
  if (!edge_corner_keys(a, b, c, ka, kb)) return false;
  if (stage_ < SeamStage::materials) {
    const std::uint32_t* fl = star(a);
    for (std::uint32_t i = 1; i < size_[a]; ++i) {
      if (face_material(fl[i]) != face_material(fl[0])) return false;
    }
  }
  return true;
}

int CollapseMesh::count_keys(std::uint32_t v) const {
  std::uint32_t keys[3];
  int n = 0;
  const std::uint32_t* fl = star(v);
  for (std::uint32_t i = 0; i < size_[v] && n < 3; ++i) {
    const std::size_t f3 = 3 * std::size_t{fl[i]};
    const std::uint32_t k = key(f3 + corner_of(&tri_[f3], v));
    if (std::find(keys, keys + n, k) == keys + n) keys[n++] = k;
  }
  return n;
}

void CollapseMesh::reclassify(std::uint32_t v) {
  const VertexKind k = kind_[v];
  if (k == VertexKind::locked || k == VertexKind::frozen || !alive(v) || size_[v] == 0) return;
  const int n = count_keys(v);
  std::uint8_t st = state_[v];
  st = static_cast<std::uint8_t>(n > 1 ? (st | kSeam) : (st & ~kSeam));
  st = static_cast<std::uint8_t>(n >= 3 ? (st & ~kFan) : (st | kFan));
  state_[v] = st;
  kind_[v] = n >= 3         ? VertexKind::complex
             : n == 2       ? VertexKind::seam
             : (st & kOpen) ? VertexKind::border
                            : VertexKind::interior;
}

// Normals of one vertex within this angle count as one from SeamStage::corners on: a crease this soft is a
// smoothing-group split, not a modelled edge (cos 30°).
constexpr double kCompatibleCreaseCos = 0.8660254037844387;

bool CollapseMesh::relax() {
  if (stage_ >= last_stage_) return false;
  stage_ = static_cast<SeamStage>(static_cast<int>(stage_) + 1);
  // From here a collapse may move a wedge to another vertex: corners need wedge ids of their own. Every live
  // corner's wedge is still its vertex (dead faces' wedges are never read).
  if (tri_wedge_.empty()) {
    tri_wedge_.resize(tri_.size());
    std::copy(tri_.begin(), tri_.end(), tri_wedge_.begin());
  }
  const std::size_t nf = face_slots(), nv = vx_.size();
  if (material_faces_.empty()) {
    std::uint32_t most = 0;
    for (std::size_t f = 0; f < nf; ++f) most = std::max(most, face_material(static_cast<std::uint32_t>(f)));
    material_faces_.assign(std::size_t{most} + 1, 0);
    for (std::size_t f = 0; f < nf; ++f) {
      if (tri_[3 * f] != kInvalidIndex) ++material_faces_[face_material(static_cast<std::uint32_t>(f))];
    }
  }
  if (stage_ == SeamStage::uv && wedge_vertex_.empty()) wedge_vertex_ = src_.wedge_vertex;
  if (!seam_q_.empty()) {
    // The planes hold seams to their outline, which the stages give up: left in, they made the order prefer
    // collapses that keep seam lines over those that keep the surface (kenney_cakeBirthday at 50%: a mean
    // distance of 1.7% of the diagonal at 768 triangles, where positions alone give 0.0002%).
    for (std::uint32_t v = 0; v < nv; ++v) {
      if (!alive(v)) continue;
      Quadric minus = seam_q_[v];
      minus *= -1.0;
      vx_[v].quadric += minus;
    }
    std::vector<Quadric>().swap(seam_q_);
  }
  if (stage_ != SeamStage::uv) {  // uv keeps the keys of normals; it changes the rules (rule(), reattach_ok())
    // Class representative of every wedge in use, per vertex, lowest wedge id first (as setup_keys()).
    const Mesh& m = src_;
    const std::size_t nw = m.wedge_count();
    const bool soft = stage_ == SeamStage::corners;
    auto same = [&](std::uint32_t x, std::uint32_t y) {
      if (!normals_.empty()) {
        const Vec3f& p = normals_[x];
        const Vec3f& q = normals_[y];
        const double d = double{p[0]} * q[0] + double{p[1]} * q[1] + double{p[2]} * q[2];
        const double pp = double{p[0]} * p[0] + double{p[1]} * p[1] + double{p[2]} * p[2];
        const double qq = double{q[0]} * q[0] + double{q[1]} * q[1] + double{q[2]} * q[2];
        if (soft && !(d > 0.0 && d * d >= kCompatibleCreaseCos * kCompatibleCreaseCos * pp * qq)) return false;
      }
      if (soft && m.tangents.size() == nw && (m.tangents[x][3] < 0.0f) != (m.tangents[y][3] < 0.0f)) return false;
      for (const MorphTarget& t : morphs_) {
        if (t.position_deltas.size() == nw && !(t.position_deltas[x] == t.position_deltas[y])) return false;
      }
      for (const auto& set : uvs_) {
        if (!set.empty() && !(set[x] == set[y])) return false;
      }
      for (const auto& set : colors_) {
        if (!set.empty() && !(set[x] == set[y])) return false;
      }
      for (const CustomAttribute& ca : m.custom) {
        const auto k = static_cast<std::size_t>(std::max(ca.components, 0));
        if (k == 0 || ca.values.size() != nw * k) continue;
        for (std::size_t i = 0; i < k; ++i) {
          if (!(ca.values[x * k + i] == ca.values[y * k + i])) return false;
        }
      }
      return true;
    };
    std::vector<std::uint32_t> rep(nw, kInvalidIndex), wedges;
    for (std::uint32_t v = 0; v < nv; ++v) {
      if (!alive(v) || size_[v] == 0) continue;
      wedges.clear();
      const std::uint32_t* fl = star(v);
      for (std::uint32_t i = 0; i < size_[v]; ++i) {
        const std::size_t f3 = 3 * std::size_t{fl[i]};
        wedges.push_back(corner_wedge(f3 + corner_of(&tri_[f3], v)));
      }
      std::sort(wedges.begin(), wedges.end());
      wedges.erase(std::unique(wedges.begin(), wedges.end()), wedges.end());
      for (std::size_t i = 0; i < wedges.size(); ++i) {
        rep[wedges[i]] = wedges[i];
        for (std::size_t j = 0; j < i; ++j) {
          if (rep[wedges[j]] == wedges[j] && same(wedges[i], wedges[j])) {
            rep[wedges[i]] = wedges[j];
            break;
          }
        }
      }
    }
    const bool by_material = stage_ < SeamStage::materials;
    std::vector<std::uint64_t> pairs(3 * nf, ~std::uint64_t{0});
    for (std::size_t f = 0; f < nf; ++f) {
      if (tri_[3 * f] == kInvalidIndex) continue;
      const std::uint32_t mat = by_material ? face_material(static_cast<std::uint32_t>(f)) : 0u;
      for (int j = 0; j < 3; ++j) pairs[3 * f + j] = (std::uint64_t{rep[corner_wedge(3 * f + j)]} << 32) | mat;
    }
    std::vector<std::uint64_t> sorted(pairs);
    std::sort(sorted.begin(), sorted.end());
    sorted.erase(std::unique(sorted.begin(), sorted.end()), sorted.end());
    tri_key_.resize(pairs.size());
    for (std::size_t c = 0; c < pairs.size(); ++c) {
      tri_key_[c] =
          static_cast<std::uint32_t>(std::lower_bound(sorted.begin(), sorted.end(), pairs[c]) - sorted.begin());
    }
  }
  for (std::uint32_t v = 0; v < nv; ++v) reclassify(v);
  return true;
}

bool CollapseMesh::removes_last_material(const Check& c) const {
  if (material_faces_.empty()) return false;
  const std::uint32_t m0 = face_material(c.edge_faces[0]);
  if (c.edge_face_count == 2) {
    const std::uint32_t m1 = face_material(c.edge_faces[1]);
    if (m0 == m1) return material_faces_[m0] <= 2;
    if (material_faces_[m1] <= 1) return true;
  }
  return material_faces_[m0] <= 1;
}

const char* CollapseMesh::forbidden_reason(std::uint32_t u, std::uint32_t v) const {
  for (std::uint32_t x : {u, v}) {
    if (kind_[x] == VertexKind::frozen || (kind_[x] == VertexKind::locked && lock_reason_[x] == kLockedTopology)) {
      return "non_manifold";
    }
  }
  if (kind_[u] == VertexKind::locked || kind_[v] == VertexKind::locked) return "locked";
  if (kind_[u] == VertexKind::complex || kind_[v] == VertexKind::complex) {
    return stage_ < last_stage_ || last_stage_ == SeamStage::strict ? "seams_kept" : "materials_kept";
  }
  return "topology";
}

// Every distinct wedge around a with the wedge of b it becomes (apply()'s mapping: by key, across the edge
// faces), as pairs in s.wedge_map, in a's face order.
void CollapseMesh::map_wedges(std::uint32_t a, std::uint32_t b, const Check& c, Scratch& s) const {
  std::uint32_t ka[2] = {kInvalidIndex, kInvalidIndex}, wb[2] = {kInvalidIndex, kInvalidIndex};
  for (std::uint32_t i = 0; i < c.edge_face_count; ++i) {
    const std::size_t f3 = 3 * std::size_t{c.edge_faces[i]};
    const std::uint32_t* t = &tri_[f3];
    ka[i] = key(f3 + corner_of(t, a));
    wb[i] = corner_wedge(f3 + corner_of(t, b));
  }
  s.wedge_map.clear();
  const std::uint32_t* fl = star(a);
  for (std::uint32_t i = 0; i < size_[a]; ++i) {
    const std::size_t f3 = 3 * std::size_t{fl[i]};
    const std::size_t corner = f3 + corner_of(&tri_[f3], a);
    const std::uint32_t wx = corner_wedge(corner);
    const std::uint32_t k = key(corner);
    std::uint32_t wt = (c.edge_face_count == 2 && k == ka[1]) ? wb[1] : wb[0];
    if (c.reattach && k != ka[0] && (c.edge_face_count < 2 || k != ka[1])) wt = wx;  // goes with the corner
    bool seen = false;
    for (std::size_t j = 0; j < s.wedge_map.size(); j += 2) seen |= s.wedge_map[j] == wx;
    if (seen) continue;
    s.wedge_map.push_back(wx);
    s.wedge_map.push_back(wt);
  }
}

Vec2f CollapseMesh::new_uv(int set, std::uint32_t wx, std::uint32_t wt, const Vec3d& x, double t) const {
  const std::vector<Vec2f>& uv = uvs_[static_cast<std::size_t>(set)];
  const Vec2f from = uv[wx], to = uv[wt];
  // The minimiser of the merged quadric where UVs are in the metric, else the point at x's place along the
  // edge; either way projected onto the edge's UV segment, which lies inside the chart away from its outline.
  double s = t;
  const AttributeGroup* g = layout_.find(AttributeGroup::Type::uv, set);
  const double alpha = g != nullptr ? wq_[wx].alpha + wq_[wt].alpha : 0.0;
  if (alpha > 0.0) {
    const auto dims = static_cast<std::size_t>(layout_.dims);
    double opt[2];
    for (int i = 0; i < 2; ++i) {
      const AttributeGradient& gx = wg_[wx * dims + static_cast<std::size_t>(g->dim + i)];
      const AttributeGradient& gt = wg_[wt * dims + static_cast<std::size_t>(g->dim + i)];
      opt[i] = (dot(gx.g + gt.g, x) + gx.d + gt.d) / alpha / g->scale;
    }
    const double ex = double{to[0]} - from[0], ey = double{to[1]} - from[1];
    const double len2 = ex * ex + ey * ey;
    if (len2 > 0.0) s = std::clamp(((opt[0] - from[0]) * ex + (opt[1] - from[1]) * ey) / len2, 0.0, 1.0);
  }
  if (!std::isfinite(s)) s = 1.0;
  // At a seam vertex (either end) the UV takes the nearer end's value. On a UV seam the UV segment is a
  // chord of the chart's outline, which leaves the chart where the outline is concave and may enter a
  // neighbouring chart (FlightHelmet at 25%: 36 triangles reaching into charts stacked in the same UV space);
  // the end's value is one the chart has. On a hard edge or material boundary with continuous UVs, each
  // side's own optimum would tear the UVs apart along it; both sides snap alike. Over the glTF corpus at 50%
  // and 10% this took the geometric mean of the UV stretch ratio (LOD against input) from 1.59 to 1.00, the
  // largest from 648 to 8, at the same UV error; snapping on UV seams only left it at 1.63. Mesh borders keep
  // the interpolated UV: nothing lies beyond them, and snapping there stretches the texture along the border.
  const std::vector<std::uint32_t>& wedge_vertex = wedge_vertex_.empty() ? src_.wedge_vertex : wedge_vertex_;
  const bool seam = kind_[wedge_vertex[wx]] == VertexKind::seam || kind_[wedge_vertex[wt]] == VertexKind::seam;
  if (seam) s = s < 0.5 ? 0.0 : 1.0;
  const auto fs = static_cast<float>(s);
  return {{from[0] + (to[0] - from[0]) * fs, from[1] + (to[1] - from[1]) * fs}};
}

// No face around a or b may turn over (or collapse to zero area) in UV space, in any UV set. Faces keep their
// orientation sign: mirrored charts stay mirrored.
bool CollapseMesh::uv_ok(std::uint32_t a, std::uint32_t b, const Check& c, const Vec3d& x, Scratch& s) const {
  const bool moved = blends(b, x);
  const double t = moved ? edge_t(a, b, x) : 1.0;
  auto target_of = [&](std::uint32_t w) {
    for (std::size_t j = 0; j < s.wedge_map.size(); j += 2) {
      if (s.wedge_map[j] == w) return s.wedge_map[j + 1];
    }
    return kInvalidIndex;
  };
  auto is_target = [&](std::uint32_t w) {
    for (std::size_t j = 1; j < s.wedge_map.size(); j += 2) {
      if (s.wedge_map[j] == w) return true;
    }
    return false;
  };
  auto source_of = [&](std::uint32_t wt) {
    for (std::size_t j = 1; j < s.wedge_map.size(); j += 2) {
      if (s.wedge_map[j] == wt) return s.wedge_map[j - 1];
    }
    return kInvalidIndex;
  };
  auto area2 = [](const Vec2f& p, const Vec2f& q, const Vec2f& r) {
    return (double{q[0]} - p[0]) * (double{r[1]} - p[1]) - (double{r[0]} - p[0]) * (double{q[1]} - p[1]);
  };
  // Whether a UV triangle is a sliver: the sine of its angle at corner 0 below kUvSliverSine.
  auto sliver = [](const Vec2f* c, double a2) {
    const double e1 = (double{c[1][0]} - c[0][0]) * (double{c[1][0]} - c[0][0]) +
                      (double{c[1][1]} - c[0][1]) * (double{c[1][1]} - c[0][1]);
    const double e2 = (double{c[2][0]} - c[0][0]) * (double{c[2][0]} - c[0][0]) +
                      (double{c[2][1]} - c[0][1]) * (double{c[2][1]} - c[0][1]);
    return a2 * a2 <= kUvSliverSine * kUvSliverSine * e1 * e2;
  };
  for (std::size_t set = 0; set < uvs_.size(); ++set) {
    const std::vector<Vec2f>& uv = uvs_[set];
    if (uv.empty()) continue;
    for (std::uint32_t w : {a, b}) {
      const std::uint32_t* fl = star(w);
      for (std::uint32_t i = 0; i < size_[w]; ++i) {
        const std::uint32_t f = fl[i];
        if (f == c.edge_faces[0] || f == c.edge_faces[1]) continue;
        const std::uint32_t* tw = face_wedges(f);
        const int j = corner_of(&tri_[3 * std::size_t{f}], w);
        const std::uint32_t wc = tw[j];
        const std::uint32_t wt = w == a ? target_of(wc) : wc;
        if (w == b && (!moved || !is_target(wc))) continue;  // b's face keeps its UVs
        // A target's new value comes from its first source (as in apply()).
        const Vec2f now = moved ? new_uv(static_cast<int>(set), source_of(wt), wt, x, t) : uv[wt];
        Vec2f corners[3] = {uv[tw[0]], uv[tw[1]], uv[tw[2]]};
        const double before = area2(corners[0], corners[1], corners[2]);
        if (!(before != 0.0)) continue;  // no orientation to keep (or NaN UVs)
        const bool was_sliver = sliver(corners, before);
        corners[j] = now;
        const double after = area2(corners[0], corners[1], corners[2]);
        if (!(after * before > 0.0)) return false;
        if (!was_sliver && sliver(corners, after)) return false;
      }
    }
  }
  return true;
}

// Skinning rule: a and b may merge only when their dominant joints agree or their weight vectors
// are close (the joint's blend band). Checking every face of the merged vertex instead (no new triangle may
// join distant weights) was tried: on the skinned corpus it vetoes so many cheap collapses that the bind-pose
// distance error grows 3-40x (CesiumMan at 25%: 0.25% of the diagonal against 0.04%).
bool CollapseMesh::skin_ok(std::uint32_t a, std::uint32_t b) const {
  return skin_mergeable(skin_[a], skin_[b], options_.skin_weight_threshold, options_.skin_max_distance);
}

// What moves with a collapse besides geometry, before the faces are rewritten: each of a's wedges' attribute
// quadric joins its target's; when the survivor moves (optimal placement) each target gets new values (the
// merged quadric's minimiser, clamped, for attributes in the metric; the point at x's place along the edge
// for the rest; normals renormalised), morph deltas and skin weights blend the same way.
void CollapseMesh::carry_attributes(const Check& c, const Vec3d& x, Scratch& s) {
  const std::uint32_t a = c.victim, b = c.survivor;
  map_wedges(a, b, c, s);
  const bool moved = blends(b, x);
  if (moved) {
    const double t = edge_t(a, b, x);
    const auto ft = static_cast<float>(t);
    const auto dims = static_cast<std::size_t>(layout_.dims);
    for (std::size_t j = 0; j < s.wedge_map.size(); j += 2) {
      const std::uint32_t wx = s.wedge_map[j], wt = s.wedge_map[j + 1];
      bool first = true;  // a target takes its values from its first source only
      for (std::size_t i = 1; i < j; i += 2) first &= s.wedge_map[i] != wt;
      if (!first) continue;
      // Optimal attributes of the merged quadric, scaled units.
      s.attr.assign(dims, 0.0);
      bool optimal = false;
      if (dims > 0) {
        AttributeQuadric merged = wq_[wt];
        std::array<AttributeGradient, kMaxAttributeDims> sums;
        std::copy_n(&wg_[wt * dims], dims, sums.data());
        merge_attribute_quadrics(merged, std::span(sums.data(), dims), wq_[wx],
                                 std::span<const AttributeGradient>(&wg_[wx * dims], dims));
        optimal = optimal_attributes(merged, std::span<const AttributeGradient>(sums.data(), dims), x, s.attr);
      }
      auto group_of = [&](AttributeGroup::Type type, int set) {
        return optimal ? layout_.find(type, set) : nullptr;
      };
      if (!normals_.empty()) {
        Vec3f n = normals_[wx] + (normals_[wt] - normals_[wx]) * ft;
        if (const AttributeGroup* g = group_of(AttributeGroup::Type::normal, 0)) {
          for (int i = 0; i < 3; ++i) n[i] = static_cast<float>(s.attr[static_cast<std::size_t>(g->dim + i)] / g->scale);
        }
        const float len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        normals_[wt] = (len > 1e-6f && std::isfinite(len)) ? n * (1.0f / len) : normals_[wt];
      }
      for (std::size_t set = 0; set < uvs_.size(); ++set) {
        if (!uvs_[set].empty()) uvs_[set][wt] = new_uv(static_cast<int>(set), wx, wt, x, t);
      }
      for (std::size_t set = 0; set < colors_.size(); ++set) {
        if (colors_[set].empty()) continue;
        const Vec4f from = colors_[set][wx], to = colors_[set][wt];
        Vec4f col = from + (to - from) * ft;
        if (const AttributeGroup* g = group_of(AttributeGroup::Type::color, static_cast<int>(set))) {
          for (int i = 0; i < 4; ++i) col[i] = static_cast<float>(s.attr[static_cast<std::size_t>(g->dim + i)] / g->scale);
        }
        // [0, 1], widened to the two sources' own range (HDR colours stay HDR).
        for (int i = 0; i < 4; ++i) {
          const float lo = std::min({0.0f, from[i], to[i]}), hi = std::max({1.0f, from[i], to[i]});
          col[i] = std::isfinite(col[i]) ? std::clamp(col[i], lo, hi) : to[i];
        }
        colors_[set][wt] = col;
      }
      for (MorphTarget& mt : morphs_) {
        for (auto* d : {&mt.position_deltas, &mt.normal_deltas, &mt.tangent_deltas}) {
          if (!d->empty() && d->size() == src_.wedge_count()) (*d)[wt] = (*d)[wx] + ((*d)[wt] - (*d)[wx]) * ft;
        }
      }
    }
    if (!skin_.empty()) skin_[b] = blended_skin(a, b, t);
  }
  if (layout_.dims > 0) {
    const auto dims = static_cast<std::size_t>(layout_.dims);
    for (std::size_t j = 0; j < s.wedge_map.size(); j += 2) {
      const std::uint32_t wx = s.wedge_map[j], wt = s.wedge_map[j + 1];
      if (wx == wt) continue;
      merge_attribute_quadrics(wq_[wt], std::span(&wg_[wt * dims], dims), wq_[wx],
                               std::span<const AttributeGradient>(&wg_[wx * dims], dims));
    }
  }
}

}  // namespace lodforge::collapse
