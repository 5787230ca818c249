// CollapseMesh: setup (normalise, face lists, vertex kinds, quadrics), evaluation (cost and placement of a
// candidate), the topology and fold checks, the commit of one collapse and the output. The seam, attribute,
// UV and skin rules it calls are in seam_rules.cpp.
//
// Papers and sources implemented here:
//  - M. Garland, P. Heckbert, "Surface Simplification Using Quadric Error Metrics", SIGGRAPH 1997: plane
//    quadrics, full-edge collapse to the optimal position, boundary constraint planes.
//  - T. Dey, H. Edelsbrunner, S. Guha, D. Nekhayev, "Topology Preserving Edge Contraction", 1999: the link
//    condition, with boundaries coned to a virtual vertex (which yields the boundary pinch rule).
//  - G. van den Bergen, "Conservative Mesh Decimation", GDC 2021: the rubber-band point quadric (see metric).
#include "collapse_mesh.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cassert>
#include <cmath>
#include <limits>
#include <memory>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string>

#include "engines.hpp"
#include "lodforge/core/mesh.hpp"
#include "lodforge/eval/bvh.hpp"

namespace lodforge::collapse {
namespace {

// Ordering key: GH97's raw, area-weighted E(x), not E(x)/W. On the bunny the raw key gives about 0.019% / 0.14%
// mean error (of the diagonal) at 10% / 1% against 0.0205% / 0.155% for E/W, which lets vertices that absorbed
// much surface move too easily. The error budget still compares E/W (a distance) and drops what exceeds it.

// A surface quadric whose LDLᵀ pivots all exceed this fraction of its trace pins the placement down by itself
// (corners, where the rubber band would only pull the vertex off); below, the band joins the solve. On the
// bunny any value in [1e-9, 1e-2] gives the same mean error within 3%.
constexpr double kWellConditioned = 1e-4;

// A face whose |n|² is below this fraction of |e1|²|e2|² (sine of its angle below ~1e-6) counts as degenerate.
constexpr double kDegenerateSine2 = 1e-12;

// The ordering key's tie term, kTieLength2 × area × |edge|² (evaluate()): it only decides between exactly equal
// costs. Larger values reach into real (tiny) attribute costs: the colour-gradient test keeps 0.32 of its
// vertices near the step at 0, 0.43 at 1e-20, 0.26 at 1e-16. At 1e-20 scanned meshes' outputs are unchanged.
constexpr double kTieLength2 = 1e-20;

// A list that outgrows its slot moves to the pool's end with this much extra room (in faces), so that a
// vertex which keeps absorbing neighbours is not moved at every collapse.
constexpr std::uint32_t kListSlack = 4;
// check(): stars of two endpoints together larger than this test membership by stamps, not by scans.
constexpr std::size_t kLargeStar = 64;

}  // namespace

// ---- Parallel -----------------------------------------------------------------------------------------------

Parallel::Parallel(unsigned threads)
    : concurrency_(threads == 0 ? static_cast<unsigned>(tbb::this_task_arena::max_concurrency()) : threads),
      arena_(static_cast<int>(threads == 0 ? tbb::task_arena::automatic : threads)) {
  if (concurrency_ == 0) concurrency_ = 1;
}

// ---- CollapseMesh: setup ------------------------------------------------------------------------------------

CollapseMesh::CollapseMesh(const Mesh& m, const SimplifyOptions& options, Parallel& parallel,
                           const CollapsePolicies* policies, const GuardReference* guard)
    : src_(m), options_(options), policies_(policies) {
  const std::size_t nv = m.vertex_count(), nw = m.wedge_count();
  for (std::uint32_t v : options.locked_vertices) {
    if (v >= nv) {
      throw std::invalid_argument("simplify: locked vertex " + std::to_string(v) + " out of range (mesh has " +
                                  std::to_string(nv) + " vertices)");
    }
  }
  // Bounding box of the finite positions (as compute_bounds), reduced over fixed chunks: min and max are
  // exact, so the result does not depend on how the chunks are spread over threads.
  constexpr std::size_t kVertexChunk = 16384;
  std::vector<Bounds3> chunk_bounds((nv + kVertexChunk - 1) / kVertexChunk);
  parallel.for_ranges(chunk_bounds.size(), 1, [&](std::size_t cb, std::size_t ce) {
    for (std::size_t c = cb; c < ce; ++c) {
      for (std::size_t v = c * kVertexChunk; v < std::min(nv, (c + 1) * kVertexChunk); ++v) {
        const Vec3f& p = m.positions[v];
        if (std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2])) chunk_bounds[c].add(to_double(p));
      }
    }
  });
  Bounds3 bounds;
  for (const Bounds3& b : chunk_bounds) {
    if (!b.empty()) {
      bounds.add(b.min);
      bounds.add(b.max);
    }
  }
  diagonal_ = bounds.diagonal();
  if (!bounds.empty()) {
    origin_ = bounds.min;
    const Vec3d ext = bounds.max - bounds.min;
    const double e = std::max({ext[0], ext[1], ext[2]});
    scale_ = e > 0.0 ? e : 1.0;
  }
  cos_max_flip_ = std::cos(options.max_flip_angle_deg * std::numbers::pi / 180.0);
  height_field_axis_ = options.height_field_axis;

  vx_.resize(nv);  // unconstructed: each record is constructed below, in parallel (128 bytes a vertex)
  version_.assign(nv, 0);
  kind_.assign(nv, VertexKind::interior);
  state_.assign(nv, 0);
  const double inv = 1.0 / scale_;
  parallel.for_ranges(nv, 4096, [&](std::size_t b, std::size_t e) {
    for (std::size_t v = b; v < e; ++v) {
      ::new (static_cast<void*>(&vx_[v])) Vertex{};
      vx_[v].pos = (to_double(m.positions[v]) - origin_) * inv;
    }
  });

  // Working triangles: those with valid indices and three distinct vertices. Two parallel passes over fixed
  // chunks of faces (count, then fill at the chunk's prefix offset): input order, whatever the threads.
  const std::size_t nf = m.face_count();
  auto valid = [&](std::size_t f, std::uint32_t* w, std::uint32_t* v) {
    if (m.face_offsets[f + 1] - m.face_offsets[f] != 3) return false;
    const std::uint32_t c = m.face_offsets[f];
    for (int i = 0; i < 3; ++i) {
      w[i] = m.corner_wedge[c + i];
      if (w[i] >= nw) return false;
      v[i] = m.wedge_vertex[w[i]];
      if (v[i] >= nv) return false;
    }
    return v[0] != v[1] && v[1] != v[2] && v[0] != v[2];
  };
  constexpr std::size_t kFaceChunk = 16384;
  const std::size_t chunks = (nf + kFaceChunk - 1) / kFaceChunk;
  std::vector<std::uint32_t> chunk_first(chunks + 1, 0);
  parallel.for_ranges(chunks, 1, [&](std::size_t cb, std::size_t ce) {
    for (std::size_t c = cb; c < ce; ++c) {
      std::uint32_t n = 0, w[3], v[3];
      for (std::size_t f = c * kFaceChunk; f < std::min(nf, (c + 1) * kFaceChunk); ++f) n += valid(f, w, v);
      chunk_first[c] = n;
    }
  });
  std::uint32_t total = 0;
  for (std::size_t c = 0; c <= chunks; ++c) total += std::exchange(chunk_first[c], total);
  // One wedge per vertex, numbered as the vertices: the corners' wedges are their vertices (tri_wedge_ stays
  // empty). All faces valid: each working face is its input face (tri_source_ stays empty).
  bool own_wedges = nw == nv;
  for (std::size_t w = 0; own_wedges && w < nw; ++w) own_wedges = m.wedge_vertex[w] == w;
  tri_.resize(3 * std::size_t{total});
  if (!own_wedges) tri_wedge_.resize(3 * std::size_t{total});
  if (total != nf) tri_source_.resize(total);
  parallel.for_ranges(chunks, 1, [&](std::size_t cb, std::size_t ce) {
    for (std::size_t c = cb; c < ce; ++c) {
      std::uint32_t out = chunk_first[c], w[3], v[3];
      for (std::size_t f = c * kFaceChunk; f < std::min(nf, (c + 1) * kFaceChunk); ++f) {
        if (!valid(f, w, v)) continue;
        std::copy(v, v + 3, &tri_[3 * std::size_t{out}]);
        if (!tri_wedge_.empty()) std::copy(w, w + 3, &tri_wedge_[3 * std::size_t{out}]);
        if (!tri_source_.empty()) tri_source_[out] = static_cast<std::uint32_t>(f);
        ++out;
      }
    }
  });
  alive_faces_ = total;

  // Vertex → faces lists (counting sort: each list in face order).
  size_.assign(nv, 0);
  for (std::uint32_t v : tri_) ++size_[v];
  begin_.resize(nv);
  std::uint32_t acc = 0;
  for (std::size_t v = 0; v < nv; ++v) {
    begin_[v] = acc;
    acc += size_[v];
  }
  capacity_ = size_;
  pool_.reserve(acc + acc / 2);
  pool_.resize(acc);
  {
    std::vector<std::uint32_t> fill(begin_);
    for (std::uint32_t f = 0; f < total; ++f) {
      for (int j = 0; j < 3; ++j) pool_[fill[tri_[3 * std::size_t{f} + j]]++] = f;
    }
  }

  // Working copies of what collapses may change.
  if (m.normals.size() == nw) normals_ = m.normals;
  for (const auto& set : m.uvs) uvs_.push_back(set.size() == nw ? set : std::vector<Vec2f>{});
  for (const auto& set : m.colors) colors_.push_back(set.size() == nw ? set : std::vector<Vec4f>{});
  morphs_ = m.morph_targets;
  if (m.skin.size() == nv) {
    skin_ = m.skin;
    for (const SkinInfluences& s : skin_) {
      int n = 0;
      for (float w : s.weights) n += w > 0.0f;
      skin_cap_ = std::max(skin_cap_, n);
    }
  }
  blend_ = options.attribute_placement == AttributePlacement::optimal;
  const SeamMode seams = options.permissive && options.seams == SeamMode::keep ? SeamMode::relax : options.seams;
  last_stage_ = seams == SeamMode::keep    ? SeamStage::strict
                : seams == SeamMode::relax ? SeamStage::uv
                                           : SeamStage::materials;

  setup_keys();
  setup(parallel);
  setup_conservative();
  setup_attributes(parallel);
  if (guard != nullptr && guard->bvh != nullptr) setup_guard(*guard, parallel);
}

// The painted weight of each vertex (options.priority_channel), 1 where there is none. A per-wedge source
// gives each vertex the largest value of its wedges (a painted seam stays painted on both sides).
void CollapseMesh::setup_priority(std::vector<float>& priority) const {
  const Mesh& m = src_;
  const std::size_t nv = m.vertex_count(), nw = m.wedge_count();
  const std::string& ch = options_.priority_channel;
  priority.clear();
  if (ch.empty() || ch == "none") return;
  if (ch == "_LOD_PRIORITY" && m.priority.size() == nv) {
    priority = m.priority;
  } else {
    const std::size_t dot = ch.find('.');
    const std::string name = ch.substr(0, dot);
    int component = 0;
    if (dot != std::string::npos && dot + 2 == ch.size()) {
      const char c = ch[dot + 1];
      component = (c == 'x' || c == 'r') ? 0 : (c == 'y' || c == 'g') ? 1 : (c == 'z' || c == 'b') ? 2 : 3;
    }
    auto from_wedges = [&](auto&& value) {
      priority.assign(nv, -1.0f);
      for (std::uint32_t w = 0; w < nw; ++w) {
        if (m.wedge_vertex[w] >= nv) continue;
        float& p = priority[m.wedge_vertex[w]];
        p = std::max(p, value(w));
      }
    };
    const bool digits = name.size() > 6 && name.size() < 12 &&
                        std::all_of(name.begin() + 6, name.end(), [](char c) { return c >= '0' && c <= '9'; });
    if (name.starts_with("COLOR_")) {
      // A malformed channel ("COLOR_x") names nothing: no paint (the config rejects it earlier).
      const std::size_t set = digits ? static_cast<std::size_t>(std::stoul(name.substr(6))) : m.colors.size();
      if (set < m.colors.size() && m.colors[set].size() == nw) {
        from_wedges([&](std::uint32_t w) { return m.colors[set][w][component]; });
      }
    } else {
      for (const CustomAttribute& c : m.custom) {
        if (c.name != name || component >= c.components || c.components <= 0) continue;
        const auto k = static_cast<std::size_t>(c.components);
        if (c.values.size() != nw * k) continue;
        from_wedges([&](std::uint32_t w) { return c.values[w * k + static_cast<std::size_t>(component)]; });
        break;
      }
    }
  }
  for (float& p : priority) {
    if (std::isnan(p) || p < 0.0f) p = p < 0.0f ? 0.0f : 1.0f;  // NaN: neutral; negative: don't care
  }
}

// Classifies every vertex from its fan and accumulates its quadric. One pass, parallel over vertices; each
// vertex sums its own faces in list order, so the sums do not depend on the thread count.
void CollapseMesh::setup(Parallel& parallel) {
  const std::size_t nv = vx_.size();
  std::vector<std::uint8_t> user_locked(nv, 0);
  for (std::uint32_t v : options_.locked_vertices) user_locked[v] = 1;
  std::vector<float> priority;
  setup_priority(priority);
  for (std::size_t v = 0; v < priority.size(); ++v) {
    if (priority[v] >= options_.priority_lock) user_locked[v] = 1;
  }
  const bool preserve = options_.border_mode == BorderMode::preserve;
  const bool lock_border = options_.border_mode == BorderMode::lock;
  lock_reason_.assign(nv, 0);

  // Each face's plane quadric is computed at each of its corners as the vertex sums its faces: no per-face
  // array (40 bytes a face at the set-up's peak), and the same arithmetic, so the same bits, at every corner.
  auto face_quadric = [&](std::uint32_t f) {
    const std::uint32_t* t = &tri_[3 * std::size_t{f}];
    return Quadric::from_triangle(vx_[t[0]].pos, vx_[t[1]].pos, vx_[t[2]].pos);
  };

  // Seam constraint planes per vertex as well, where seams may relax and any vertex has several wedges.
  if (last_stage_ != SeamStage::strict && src_.wedge_count() > nv) seam_q_.assign(nv, Quadric{});

  // Each vertex's surface area (its quadric's weight), densely: summed in vertex order below.
  std::vector<double> vertex_area(nv, 0.0);
  tbb::enumerable_thread_specific<Scratch> scratch;
  parallel.for_ranges(nv, 1024, [&](std::size_t vb, std::size_t ve) {
    Scratch& s = scratch.local();
    for (std::size_t vi = vb; vi < ve; ++vi) {
      const auto v = static_cast<std::uint32_t>(vi);
      const std::uint32_t m = size_[v];
      const std::uint32_t* fl = star(v);
      if (!finite3(vx_[v].pos)) {
        kind_[v] = VertexKind::frozen;
        continue;
      }
      if (m == 0) continue;

      // Spokes (v, x) packed as x << 32 | code, code = 2 × face slot + direction (0: v → x in the face), so
      // that sorting groups the faces of each spoke.
      s.spokes.resize(2 * std::size_t{m});
      Quadric q;
      // Distinct corner keys around v, up to three (three or more: complex).
      std::uint32_t keys[3] = {key(3 * std::size_t{fl[0]} + corner_of(&tri_[3 * std::size_t{fl[0]}], v)), 0, 0};
      int nkeys = 1;
      for (std::uint32_t i = 0; i < m; ++i) {
        const std::uint32_t* t = &tri_[3 * std::size_t{fl[i]}];
        const int j = corner_of(t, v);
        s.spokes[2 * i] = (std::uint64_t{t[kNext[j]]} << 32) | (2 * i);
        s.spokes[2 * i + 1] = (std::uint64_t{t[kPrev[j]]} << 32) | (2 * i + 1);
        const std::uint32_t kc = key(3 * std::size_t{fl[i]} + j);
        if (nkeys < 3 && kc != keys[0] && (nkeys < 2 || kc != keys[1])) keys[nkeys++] = kc;
        q += face_quadric(fl[i]);
      }
      if (nkeys > 1) state_[v] |= kSeam;
      const VertexKind seam_kind = nkeys >= 3 ? VertexKind::complex : VertexKind::seam;

      // Fast path, most vertices: one closed, consistently oriented fan. Walk from face 0 to the face that
      // has the next spoke as its previous one; a closed fan comes back to face 0 after exactly m steps,
      // each step finding exactly one face.
      if (m <= 16 && !user_locked[v] && nkeys == 1) {
        std::uint32_t cur = 0;
        bool closed = true;
        for (std::uint32_t step = 1; step <= m && closed; ++step) {
          const auto x = static_cast<std::uint32_t>(s.spokes[2 * cur] >> 32);
          std::uint32_t found = 0, count = 0;
          for (std::uint32_t j = 0; j < m; ++j) {
            if (static_cast<std::uint32_t>(s.spokes[2 * j + 1] >> 32) == x) {
              found = j;
              ++count;
            }
          }
          closed = count == 1 && (found != 0 || step == m);
          cur = found;
        }
        if (closed && cur == 0) {
          vx_[v].quadric = q;
          vertex_area[v] = q.weight;
          kind_[v] = nkeys > 1 ? seam_kind : VertexKind::interior;
          if (kind_[v] != VertexKind::complex) state_[v] |= kFan;
          continue;
        }
      }
      small_sort(s.spokes.data(), s.spokes.size());

      // Fans: union faces across spokes shared by exactly two faces.
      s.parent.resize(m);
      for (std::uint32_t i = 0; i < m; ++i) s.parent[i] = i;
      auto find = [&](std::uint32_t x) {
        while (s.parent[x] != x) x = s.parent[x] = s.parent[s.parent[x]];
        return x;
      };
      bool boundary = false, non_manifold = false, inconsistent = false;
      const std::size_t ns = s.spokes.size();
      for (std::size_t i = 0; i < ns;) {
        const std::uint32_t x = static_cast<std::uint32_t>(s.spokes[i] >> 32);
        std::size_t j = i + 1;
        while (j < ns && static_cast<std::uint32_t>(s.spokes[j] >> 32) == x) ++j;
        const std::size_t run = j - i;
        const auto code0 = static_cast<std::uint32_t>(s.spokes[i]);
        if (run == 1) {
          boundary = true;
          if (preserve) {
            const std::uint32_t* t = &tri_[3 * std::size_t{fl[code0 / 2]}];
            const Vec3d n = cross(vx_[t[1]].pos - vx_[t[0]].pos, vx_[t[2]].pos - vx_[t[0]].pos);
            q += Quadric::from_boundary_edge(vx_[v].pos, vx_[x].pos, n, options_.border_weight);
          }
        } else if (run == 2) {
          const auto code1 = static_cast<std::uint32_t>(s.spokes[i + 1]);
          if ((code0 & 1) == (code1 & 1)) inconsistent = true;
          if (nkeys > 1) {
            // A seam edge (the keys of v or x differ across it) gets the constraint planes of a boundary edge
            // on each side, weighted by border_weight (GH97's discontinuity planes): seam vertices move freely
            // along the seam, both sides together, but hardly off it, so charts and material regions keep
            // their outlines (a material boundary across a bumpy grid stays within 0.002 edge lengths of its
            // line; weight 1 lets it drift 0.05 for a 4% lower corpus distance).
            const std::size_t f0 = 3 * std::size_t{fl[code0 / 2]}, f1 = 3 * std::size_t{fl[code1 / 2]};
            const bool seam_edge = key(f0 + corner_of(&tri_[f0], v)) != key(f1 + corner_of(&tri_[f1], v)) ||
                                   key(f0 + corner_of(&tri_[f0], x)) != key(f1 + corner_of(&tri_[f1], x));
            if (seam_edge) {
              // Within one material the planes are also kept apart, for relax() to take them out again.
              const bool apart = !seam_q_.empty() && face_material(fl[code0 / 2]) == face_material(fl[code1 / 2]);
              for (const std::size_t f3 : {f0, f1}) {
                const std::uint32_t* t = &tri_[f3];
                const Vec3d n = cross(vx_[t[1]].pos - vx_[t[0]].pos, vx_[t[2]].pos - vx_[t[0]].pos);
                const Quadric plane = Quadric::from_boundary_edge(vx_[v].pos, vx_[x].pos, n, options_.border_weight);
                q += plane;
                if (apart) seam_q_[v] += plane;
              }
            }
          }
          const std::uint32_t r0 = find(code0 / 2), r1 = find(code1 / 2);
          if (r0 != r1) s.parent[std::max(r0, r1)] = std::min(r0, r1);
        } else {
          non_manifold = true;
        }
        i = j;
      }
      std::uint32_t fans = 0;
      for (std::uint32_t i = 0; i < m; ++i) fans += find(i) == i;
      if (fans > 1) non_manifold = true;

      vx_[v].quadric = q;
      vertex_area[v] = q.weight;
      if (user_locked[v] || non_manifold || inconsistent || (lock_border && boundary)) {
        kind_[v] = VertexKind::locked;
        lock_reason_[v] = non_manifold || inconsistent ? kLockedTopology : kLockedByUser;
      } else {
        kind_[v] = nkeys > 1 ? seam_kind : boundary ? VertexKind::border : VertexKind::interior;
        // A complex vertex is one manifold fan too: kOpen is kept exact for it (relax() may free it).
        state_[v] |= boundary ? kOpen : 0;
        if (kind_[v] != VertexKind::complex) state_[v] |= kFan;
      }
    }
  });

  // Faces touching a frozen vertex: their other vertices lock too (any collapse would test or move a face
  // with a non-finite corner).
  const bool any_frozen = std::find(kind_.begin(), kind_.end(), VertexKind::frozen) != kind_.end();
  for (std::size_t f = 0; any_frozen && f < face_slots(); ++f) {
    const std::uint32_t* t = &tri_[3 * f];
    if (kind_[t[0]] == VertexKind::frozen || kind_[t[1]] == VertexKind::frozen || kind_[t[2]] == VertexKind::frozen) {
      for (int i = 0; i < 3; ++i) {
        if (kind_[t[i]] == VertexKind::frozen) continue;
        kind_[t[i]] = VertexKind::locked;
        lock_reason_[t[i]] = kLockedTopology;
        state_[t[i]] &= static_cast<std::uint8_t>(~kFan);
      }
    }
  }

  // Rubber band: a point quadric at each vertex, weight relative to the mean face area (each face's area was
  // added to three vertices). Summed in vertex order: deterministic. Kept apart from the surface quadric as
  // (count, sum of positions): it only steers the placement; the cost is the surface error alone.
  double area3 = 0.0;
  for (std::size_t v = 0; v < nv; ++v) area3 += vertex_area[v];
  const double mean_area = alive_faces_ > 0 ? area3 / 3.0 / static_cast<double>(alive_faces_) : 0.0;
  weight_floor_ = std::max(1e-30, 1e-6 * mean_area);
  reg_weight_ = options_.regularization_weight * mean_area;
  mean_area_ = mean_area;
  parallel.for_ranges(nv, 4096, [&](std::size_t b, std::size_t e) {
    for (std::size_t v = b; v < e; ++v) {
      if (size_[v] > 0 && kind_[v] != VertexKind::frozen) {
        vx_[v].anchors = 1.0f;
        vx_[v].anchor_sum = to_float(vx_[v].pos);
      }
      // Painted priority π scales the whole quadric (faces and constraint planes, and its area, so that the
      // error bound E / W stays an unpainted distance): importance propagates into merged vertices and pulls
      // placement towards the painted side. The factor is π², so that π acts on distances:
      // a region painted π is held to about 1/π of the distance error. With π itself the greedy order (E
      // grows like edge length⁶ on a smooth surface) moves the painted share of a sphere half painted 10 only
      // from 50% to 68% at 10% of the triangles; with π², 70% and more. 0 leaves the vertex free.
      if (v < priority.size() && priority[v] != 1.0f) {
        const double pi = static_cast<double>(priority[v]);
        vx_[v].quadric *= pi * pi;
        if (!seam_q_.empty()) seam_q_[v] *= pi * pi;
      }
    }
  });
  priority_.swap(priority);
  // With an error budget, each vertex tracks the input point it absorbed that lies farthest from its fan.
  if (options_.max_error_abs >= 0.0 || options_.max_error_rel >= 0.0) {
    far_.resize(nv);
    for (std::size_t v = 0; v < nv; ++v) far_[v] = vx_[v].pos;
  }
}

// ---- CollapseMesh: evaluation and checks ----------------------------------------------------------------------

Quadric CollapseMesh::with_rubber_band(const Quadric& surface, std::uint32_t u, std::uint32_t v, double weight) const {
  const Vertex& xu = vx_[u];
  const Vertex& xv = vx_[v];
  const double w = weight * (static_cast<double>(xu.anchors) + static_cast<double>(xv.anchors));
  const Vec3f sum = xu.anchor_sum + xv.anchor_sum;
  Quadric q = surface;
  q.a00 += w;
  q.a11 += w;
  q.a22 += w;
  q.b0 -= weight * static_cast<double>(sum[0]);
  q.b1 -= weight * static_cast<double>(sum[1]);
  q.b2 -= weight * static_cast<double>(sum[2]);
  return q;
}

Evaluation CollapseMesh::evaluate(std::uint32_t u, std::uint32_t v, bool with_cost) const {
  const Vertex& xu = vx_[u];
  const Vertex& xv = vx_[v];
  const Quadric surface = xu.quadric + xv.quadric;
  // The cost sees the attribute quadrics too (reduced to position space); the error bound is the surface's
  // alone, and so is the free placement: the reduced attribute quadric is smallest where the faces' linear
  // attribute functions agree, which for a sharp attribute feature lies beside it, not on it. On a flat
  // 40×40 grid with a colour step at x = 12 (10% of the triangles), attribute-driven placement left 22 of 200
  // vertices within 4 units of the step, surface placement 89.
  Quadric q = surface;
  if (layout_.dims > 0 && with_cost) add_attribute_quadrics(u, v, q);
  Evaluation ev;
  switch (rule(u, v)) {
    case EdgeRule::keep_u: ev.position = xu.pos; break;
    case EdgeRule::keep_v: ev.position = xv.pos; break;
    case EdgeRule::either: {
      // The endpoint where the surface error is smaller; on a tie the complex one stays (as keep_u / keep_v).
      const double eu = surface.evaluate(xu.pos), ev_ = surface.evaluate(xv.pos);
      const bool keep_v = ev_ < eu || (ev_ == eu && kind_[v] == VertexKind::complex && kind_[u] != VertexKind::complex);
      ev.position = keep_v ? xv.pos : xu.pos;
      break;
    }
    default: {
      // The surface quadric alone where it pins the point down (corners, creases with a third plane);
      // with the rubber band where it does not (flat and nearly flat patches, where the surface error
      // does not care and the band keeps the vertex inside the region it represents).
      if (cons_side_ != 0.0) {
        // Conservative: the constrained minimiser; where there is none, the midpoint, which check() refuses.
        const std::optional<Vec3d> p = conservative_place(u, v, surface);
        ev.position = p ? *p : (xu.pos + xv.pos) * 0.5;
        if (policies_ != nullptr && policies_->placement) {
          if (const std::optional<Vec3d> pp = policies_->placement(candidate(u, v, ev))) {
            ev.position = output_rounded((*pp - origin_) * (1.0 / scale_));
          }
        }
        break;
      }
      const auto x = surface.minimizer(kWellConditioned);
      const Vec3d edge = xv.pos - xu.pos;
      const Vec3d off = x ? *x - (xu.pos + xv.pos) * 0.5 : Vec3d{};
      if (x && dot(off, off) <= kMaxReachEdgeLengths * kMaxReachEdgeLengths * dot(edge, edge)) {
        ev.position = *x;
      } else {
        ev.position = place_on_edge(with_rubber_band(surface, u, v, reg_weight_), xu.pos, xv.pos).position;
      }
      if (policies_ != nullptr && policies_->placement) {
        if (const std::optional<Vec3d> p = policies_->placement(candidate(u, v, ev))) {
          ev.position = (*p - origin_) * (1.0 / scale_);
        }
      }
    }
  }
  if (layout_.dims == 0) {
    const double e = q.evaluate(ev.position);
    ev.error = e / (q.weight + weight_floor_);
    ev.cost = e;
  } else {
    ev.error = surface.evaluate(ev.position) / (surface.weight + weight_floor_);
    ev.cost = q.evaluate(ev.position);
  }
  // Flat regions aligned with the axes: E is exactly 0 for every edge, and ties would go by vertex id, so the
  // lowest id keeps absorbing its neighbours (a fan of slivers that every later round walks: quadratic). A
  // length term far below any real error or rounding noise orders such exact ties shortest edge first.
  ev.cost += kTieLength2 * (surface.weight + weight_floor_) * dot(xv.pos - xu.pos, xv.pos - xu.pos);
  if (!far_.empty()) {
    // A collapse that leaves an absorbed input point far from the new fan (a thin part shortened: the quadric
    // sees no error in moving along it) costs that distance: such parts go last, not first.
    const std::array<double, 2> d2 = far_distances(u, v, ev.position, ev.error);
    const double reach = std::max(d2[0], d2[1]);
    if (reach > ev.error) {
      ev.cost += (surface.weight + weight_floor_) * (reach - ev.error);
      ev.error = reach;
    }
  }
  if (cons_volume_weight_ > 0.0) {  // bounding: the volume it adds (setup_conservative())
    const double dv = std::abs(volume_change(u, v, ev.position)) / (scale_ * scale_ * scale_);
    ev.cost += cons_volume_weight_ * std::sqrt(mean_area_) * dv;
  }
  if (skin_cost_scale_ > 0.0 && with_cost) ev.cost += skin_cost(u, v);
  if (policies_ != nullptr && policies_->cost && with_cost) ev.cost = std::max(0.0, policies_->cost(candidate(u, v, ev)));
  return ev;
}

std::array<double, 2> CollapseMesh::far_distances(std::uint32_t u, std::uint32_t v, const Vec3d& x,
                                                  double enough) const {
  std::array<double, 2> best = {std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity()};
  const Vec3d points[2] = {far_[u], far_[v]};
  bool done[2] = {false, false};
  for (const std::uint32_t w : {u, v}) {
    const std::uint32_t* fl = star(w);
    for (std::uint32_t i = 0; i < size_[w]; ++i) {
      const std::uint32_t* t = &tri_[3 * std::size_t{fl[i]}];
      const bool has_u = t[0] == u || t[1] == u || t[2] == u, has_v = t[0] == v || t[1] == v || t[2] == v;
      if (has_u && has_v) continue;  // collapses away
      if (w == v && has_u) continue;  // seen from u
      Vec3d c[3];
      for (int k = 0; k < 3; ++k) c[k] = t[k] == u || t[k] == v ? x : vx_[t[k]].pos;
      for (int j = 0; j < 2; ++j) {
        if (done[j]) continue;
        const Vec3d q = closest_point_on_triangle(points[j], c[0], c[1], c[2]).point;
        best[j] = std::min(best[j], dot(points[j] - q, points[j] - q));
        done[j] = best[j] <= enough;
      }
      if (done[0] && done[1]) return best;
    }
  }
  for (double& b : best) {
    if (!std::isfinite(b)) b = 0.0;  // no face left around the pair
  }
  return best;
}

CollapseCandidate CollapseMesh::candidate(std::uint32_t u, std::uint32_t v, const Evaluation& ev) const {
  return {.u = u,
          .v = v,
          .position_u = model_position(vx_[u].pos),
          .position_v = model_position(vx_[v].pos),
          .position = model_position(ev.position),
          .cost = ev.cost,
          .error = model_error(ev.error)};
}

bool CollapseMesh::flip_ok(const Vec3d& old_p, const Vec3d& x, const Vec3d& p, const Vec3d& q) const {
  const Vec3d e1n = p - x, e2n = q - x;
  const Vec3d nn = cross(e1n, e2n);
  const double nn2 = dot(nn, nn);
  if (!(nn2 > kDegenerateSine2 * dot(e1n, e1n) * dot(e2n, e2n))) return false;  // also false on NaN
  if (height_field_axis_ >= 0 && !(nn[height_field_axis_] > 0.0)) return false;  // an overhang
  const Vec3d e1o = p - old_p, e2o = q - old_p;
  const Vec3d no = cross(e1o, e2o);
  const double no2 = dot(no, no);
  // An already degenerate face has no orientation to keep; the test above made it proper.
  if (!(no2 > kDegenerateSine2 * dot(e1o, e1o) * dot(e2o, e2o))) return true;
  const double d = dot(no, nn);
  return d > 0.0 && d * d > cos_max_flip_ * cos_max_flip_ * no2 * nn2;
}

// Link condition with boundaries coned to a virtual vertex ω (ω is a neighbour of every boundary vertex and
// an apex of every boundary edge). For edge ab with apexes c (and d), Lk(a) ∩ Lk(b) must equal Lk(ab):
//
//   vertices: the common neighbours of a and b are exactly the apexes ............ Veto::link_condition
//             (ω common, i.e. both boundary, only if ab is a boundary edge) ....... Veto::boundary_pinch
//   edges:    c-ω in both links (a-c and b-c both boundary edges) ................ Veto::dangling_face
//             c-d in both links (faces a-c-d and b-c-d both exist) ............... Veto::tetrahedron
//
//   boundary pinch:   a ------- b   both on the boundary loop, ab interior:
//                     \  ...   /    collapsing makes the loop touch itself at one vertex
Check CollapseMesh::check(std::uint32_t u, std::uint32_t v, const Vec3d& x, Scratch& s) const {
  Check c;
  const EdgeRule r = rule(u, v);
  // Default survivor: the lower id (u), so survivors keep input order; wedges may swap it below.
  std::uint32_t a = v, b = u;
  if (r == EdgeRule::keep_v || (r == EdgeRule::either && vx_[v].pos == x && !(vx_[u].pos == x))) std::swap(a, b);

  // Stars: s.na = [neighbour after a in each face | neighbour before a in each face], s.nb likewise.
  const std::uint32_t ma = size_[a], mb = size_[b];
  if (std::size_t{ma} + mb > kLargeStar && (state_[a] & state_[b] & (kFan | kOpen)) == (kFan | kOpen)) {
    // An interior edge between two border vertices is refused (boundary_pinch below); on large stars that is
    // told from the smaller star alone, since the tests before it walk both (O(valence) for every spoke of a
    // high-valence border vertex). Where one of them would refuse it too, it is counted as boundary_pinch.
    const std::uint32_t small = ma <= mb ? a : b, other = small == a ? b : a;
    const std::uint32_t* fl = star(small);
    std::uint32_t edge_faces = 0, apex0 = kInvalidIndex;
    bool same_apex = false;
    for (std::uint32_t i = 0; i < size_[small]; ++i) {
      const std::uint32_t* t = &tri_[3 * std::size_t{fl[i]}];
      if (t[0] != other && t[1] != other && t[2] != other) continue;
      const std::uint32_t apex = t[0] ^ t[1] ^ t[2] ^ small ^ other;
      same_apex = edge_faces == 1 && apex == apex0;
      apex0 = apex;
      ++edge_faces;
    }
    s.work += size_[small];
    if (edge_faces == 2) {
      c.veto = same_apex ? Veto::link_condition : Veto::boundary_pinch;
      return c;
    }
  }
  s.na.resize(2 * std::size_t{ma});
  s.nb.resize(2 * std::size_t{mb});
  std::uint32_t* const next_a = s.na.data();
  std::uint32_t* const prev_a = next_a + ma;
  std::uint32_t* const next_b = s.nb.data();
  std::uint32_t* const prev_b = next_b + mb;
  std::uint32_t apex[2] = {kInvalidIndex, kInvalidIndex};
  std::uint32_t k = 0;
  s.work += 2 * (std::size_t{ma} + mb);  // the star scans here and the fold test below
  for (std::uint32_t w : {a, b}) {
    const std::uint32_t* fl = star(w);
    for (std::uint32_t i = 0; i < size_[w]; ++i) __builtin_prefetch(&tri_[3 * std::size_t{fl[i]}]);
  }
  {
    const std::uint32_t* fl = star(a);
    for (std::uint32_t i = 0; i < ma; ++i) {
      const std::uint32_t* t = &tri_[3 * std::size_t{fl[i]}];
      const int j = corner_of(t, a);
      const std::uint32_t p = t[kNext[j]], q = t[kPrev[j]];
      next_a[i] = p;
      prev_a[i] = q;
      if (p == b || q == b) {
        if (k < 2) {
          c.edge_faces[k] = fl[i];
          apex[k] = p == b ? q : p;
        }
        ++k;
      }
    }
  }
  if (k == 0 || k > 2) {
    c.veto = Veto::not_an_edge;
    return c;
  }
  c.edge_face_count = k;
  if (k == 2 && apex[0] == apex[1]) {
    c.veto = Veto::link_condition;
    return c;
  }
  {
    const std::uint32_t* fl = star(b);
    for (std::uint32_t i = 0; i < mb; ++i) {
      const std::uint32_t* t = &tri_[3 * std::size_t{fl[i]}];
      const int j = corner_of(t, b);
      next_b[i] = t[kNext[j]];
      prev_b[i] = t[kPrev[j]];
    }
  }
  for (std::uint32_t i = 0; i < 2 * ma; ++i) prefetch(s.na[i]);  // positions for the fold test below
  for (std::uint32_t i = 0; i < 2 * mb; ++i) prefetch(s.nb[i]);
  if (k == 2) {
    auto has_face_cd = [&](const std::uint32_t* nx, const std::uint32_t* pv, std::uint32_t m) {
      for (std::uint32_t i = 0; i < m; ++i) {
        if ((nx[i] == apex[0] && pv[i] == apex[1]) || (nx[i] == apex[1] && pv[i] == apex[0])) return true;
      }
      return false;
    };
    if (has_face_cd(next_a, prev_a, ma) && has_face_cd(next_b, prev_b, mb)) {
      c.veto = Veto::tetrahedron;
      return c;
    }
  }

  std::uint32_t common = 0;
  bool a_boundary = false, b_boundary = false, dangling = false;
  if (state_[b] & kFan) {
    // Both stars are single, consistently oriented fans whose kind is kept exact by commit(): the
    // neighbours are the "after" list plus, on a border vertex, the one "before" neighbour that is never
    // "after" (the fan's first spoke). Border spokes are that one and the "after" that is never "before".
    // Membership: a scan of the list on ordinary stars; past kLargeStar, stamps on a per-thread vertex array,
    // since a scan per neighbour is quadratic in the valence (a 20,000-spoke fan took minutes).
    const bool large = std::size_t{ma} + mb > kLargeStar;
    auto stamp = [&](const std::uint32_t* l, std::uint32_t n) {
      if (s.mark.size() < vx_.size()) s.mark.resize(vx_.size(), 0);
      if (++s.stamp == 0) {  // wrapped: clear once
        std::fill(s.mark.begin(), s.mark.end(), 0);
        s.stamp = 1;
      }
      for (std::uint32_t i = 0; i < n; ++i) s.mark[l[i]] = s.stamp;
      s.work += n;
    };
    // `l` must be the list stamped last when the star is large.
    auto contains = [&](const std::uint32_t* l, std::uint32_t n, std::uint32_t x) {
      if (large) return s.mark[x] == s.stamp;
      s.work += n;
      bool f = false;
      for (std::uint32_t i = 0; i < n; ++i) f |= l[i] == x;
      return f;
    };
    auto lone = [&](const std::uint32_t* from, const std::uint32_t* other, std::uint32_t m) {
      if (large) stamp(other, m);
      for (std::uint32_t i = 0; i < m; ++i) {
        if (!contains(other, m, from[i])) return from[i];
      }
      return kInvalidIndex;
    };
    a_boundary = (state_[a] & kOpen) != 0;
    b_boundary = (state_[b] & kOpen) != 0;
    const std::uint32_t first_a = a_boundary ? lone(prev_a, next_a, ma) : kInvalidIndex;
    const std::uint32_t first_b = b_boundary ? lone(prev_b, next_b, mb) : kInvalidIndex;
    if (large) stamp(next_b, mb);
    for (std::uint32_t i = 0; i < ma; ++i) {
      const std::uint32_t x = next_a[i];
      common += x != b && (contains(next_b, mb, x) || x == first_b);
    }
    if (first_a != kInvalidIndex && first_a != b) common += contains(next_b, mb, first_a) || first_a == first_b;
    if (k == 1 && a_boundary && b_boundary) {
      const std::uint32_t last_a = lone(next_a, prev_a, ma), last_b = lone(next_b, prev_b, mb);
      dangling = (apex[0] == first_a || apex[0] == last_a) && (apex[0] == first_b || apex[0] == last_b);
    }
  } else {
    // b is locked (possibly non-manifold): count multiplicities on sorted multisets. A spoke with one face
    // is a boundary edge.
    small_sort(s.na.data(), s.na.size());
    small_sort(s.nb.data(), s.nb.size());
    std::size_t i = 0, j = 0;
    const std::size_t ni = s.na.size(), nj = s.nb.size();
    while (i < ni || j < nj) {
      const std::uint32_t xa = i < ni ? s.na[i] : kInvalidIndex;
      const std::uint32_t xb = j < nj ? s.nb[j] : kInvalidIndex;
      const std::uint32_t xm = std::min(xa, xb);
      std::size_t ca = 0, cb = 0;
      while (i < ni && s.na[i] == xm) ++i, ++ca;
      while (j < nj && s.nb[j] == xm) ++j, ++cb;
      if (ca == 1) a_boundary = true;
      if (cb == 1) b_boundary = true;
      if (ca > 0 && cb > 0) ++common;  // a and b themselves appear only in the other's list
      if (ca == 1 && cb == 1 && (xm == apex[0] || xm == apex[1])) dangling = true;
    }
  }
  if (common != k) {
    c.veto = Veto::link_condition;
    return c;
  }
  if (a_boundary && b_boundary && k == 2) {
    c.veto = Veto::boundary_pinch;
    return c;
  }
  if (dangling) {
    c.veto = Veto::dangling_face;
    return c;
  }
  c.boundary = a_boundary || b_boundary;

  // Conservative modes: the side of every face plane around a and b (an infeasible edge was given a placement
  // that fails here, and a neighbour's collapse may have moved a plane since the evaluation).
  // On a rim, only a straight rim vertex may go, and only onto a rim neighbour that stays where it is.
  if (cons_side_ != 0.0 &&
      (!conservative_ok(a, b, x) ||
       (!rim_.empty() && ((rim_[a] != 0 && (rim_[a] != kRimStraight || rim_[b] == 0 || !(vx_[b].pos == x))) ||
                          (rim_[b] != 0 && !(vx_[b].pos == x)))))) {
    c.veto = Veto::conservative;
    return c;
  }

  // Folds and degenerate faces: every face that survives around a or b, with its corner moved to x.
  for (std::uint32_t w : {a, b}) {
    if (vx_[w].pos == x) continue;  // half-edge collapse: the survivor's own faces do not move
    const std::uint32_t other = w == a ? b : a;
    const std::uint32_t* fl = star(w);
    for (std::uint32_t i = 0; i < size_[w]; ++i) {
      const std::uint32_t* t = &tri_[3 * std::size_t{fl[i]}];
      const int j = corner_of(t, w);
      const std::uint32_t p = t[kNext[j]], q = t[kPrev[j]];
      if (p == other || q == other) continue;
      if (!flip_ok(vx_[w].pos, x, vx_[p].pos, vx_[q].pos)) {
        const Vec3d nn = cross(vx_[p].pos - x, vx_[q].pos - x);
        c.veto = dot(nn, nn) > 0.0 ? Veto::fold : Veto::degenerate;
        return c;
      }
    }
  }

  // Wedges: try the default survivor, then (if the rule allows either) the other one.
  if ((state_[a] | state_[b]) & kSeam) {
    if (!wedges_carry_over(a, b, c)) {
      if (r == EdgeRule::optimal && wedges_carry_over(b, a, c)) {
        std::swap(a, b);
      } else if (r == EdgeRule::either && reattach_ok(a, b, c)) {
        c.reattach = true;
      } else {
        c.veto = Veto::seam;
        return c;
      }
    }
  }
  if (!uvs_.empty()) {
    map_wedges(a, b, c, s);
    if (!uv_ok(a, b, c, x, s)) {
      c.veto = Veto::uv_flip;
      return c;
    }
  }
  if (!skin_.empty() && !skin_ok(a, b)) {
    c.veto = Veto::skin;
    return c;
  }
  if (policies_ != nullptr && policies_->filter) {
    Evaluation at;
    at.position = x;
    if (!policies_->filter(candidate(u, v, at))) {
      c.veto = Veto::filter;
      return c;
    }
  }
  c.victim = a;
  c.survivor = b;
  if (guard_bvh_ != nullptr && !guard_ok(a, b, c, x, s)) {  // the costliest test: last
    c.veto = Veto::error_budget;
    c.victim = c.survivor = kInvalidIndex;
    return c;
  }
  return c;
}

// ---- CollapseMesh: commit ------------------------------------------------------------------------------------

void CollapseMesh::reserve(Check& c) {
  const std::uint32_t a = c.victim, b = c.survivor;
  const std::uint32_t n = size_[a] + size_[b] - 2 * c.edge_face_count;
  if (n <= capacity_[b]) {
    c.list_begin = begin_[b];
    c.list_capacity = capacity_[b];
  } else if (n <= capacity_[a]) {  // a's slot is free after the collapse
    c.list_begin = begin_[a];
    c.list_capacity = capacity_[a];
  } else {
    c.list_begin = static_cast<std::uint32_t>(pool_.size());
    c.list_capacity = n + kListSlack;
    pool_.resize(pool_.size() + c.list_capacity);
  }
  alive_faces_ -= c.edge_face_count;
  if (!material_faces_.empty()) {
    for (std::uint32_t i = 0; i < c.edge_face_count; ++i) --material_faces_[face_material(c.edge_faces[i])];
  }
}

std::size_t CollapseMesh::list_room(const Check& c) const {
  return std::size_t{size_[c.victim]} + size_[c.survivor] + kListSlack;
}

// Packs the live face lists to the front of the pool, in pool order, each to its size (a list that grows
// later moves to the end again). Contents and order of every list are unchanged, so nothing else notices.
void CollapseMesh::make_room(std::size_t entries) {
  if (pool_.size() + entries <= pool_.capacity()) return;
  // Where the live lists start, as one bit per pool entry (no list of (begin, vertex) pairs to sort).
  std::vector<std::uint64_t> starts((pool_.size() + 63) / 64, 0);
  for (std::uint32_t v = 0; v < size_.size(); ++v) {
    if (size_[v] > 0) {
      starts[begin_[v] / 64] |= std::uint64_t{1} << (begin_[v] % 64);
    } else {
      capacity_[v] = 0;  // dead or bare: never gets faces again
    }
  }
  std::uint32_t out = 0;
  for (std::size_t word = 0; word < starts.size(); ++word) {
    for (std::uint64_t bits = starts[word]; bits != 0; bits &= bits - 1) {
      const auto begin = static_cast<std::uint32_t>(64 * word + std::countr_zero(bits));
      // The list's owner is the corner of its first face whose live list starts here (live lists are disjoint).
      const std::uint32_t* t = &tri_[3 * std::size_t{pool_[begin]}];
      std::uint32_t v = t[0];
      for (int j = 1; j < 3; ++j) {
        if (size_[t[j]] > 0 && begin_[t[j]] == begin) v = t[j];
      }
      std::copy(pool_.begin() + begin, pool_.begin() + begin + size_[v], pool_.begin() + out);  // out <= begin
      begin_[v] = out;
      capacity_[v] = size_[v];
      out += size_[v];
    }
  }
  pool_.resize(out);
}

void CollapseMesh::apply(const Check& c, const Vec3d& x, Scratch& s) {
  const std::uint32_t a = c.victim, b = c.survivor, k = c.edge_face_count;
  for (std::uint32_t w : {a, b}) {
    const std::uint32_t* fl = star(w);
    for (std::uint32_t i = 0; i < size_[w]; ++i) __builtin_prefetch(&tri_[3 * std::size_t{fl[i]}]);
  }
  if (carry_) carry_attributes(c, x, s);
  std::uint32_t ka[2] = {kInvalidIndex, kInvalidIndex}, wb[2] = {kInvalidIndex, kInvalidIndex};
  std::uint32_t kb[2] = {kInvalidIndex, kInvalidIndex};
  for (std::uint32_t i = 0; i < k; ++i) {
    const std::uint32_t f = c.edge_faces[i];
    std::uint32_t* t = &tri_[3 * std::size_t{f}];
    const std::uint32_t* w = face_wedges(f);
    const int ja = corner_of(t, a), jb = corner_of(t, b);
    ka[i] = key(3 * std::size_t{f} + ja);
    wb[i] = w[jb];
    kb[i] = key(3 * std::size_t{f} + jb);
    // Remove the dying face from its apex's list (order kept).
    const std::uint32_t apex = t[3 - ja - jb];
    std::uint32_t* fl = star(apex);
    std::uint32_t* end = fl + size_[apex];
    std::uint32_t* it = std::find(fl, end, f);
    std::copy(it + 1, end, it);
    --size_[apex];
    t[0] = kInvalidIndex;
  }

  // b's new list: its own surviving faces, then a's (renamed to b, wedges carried over).
  s.ring.clear();
  {
    const std::uint32_t* fl = star(b);
    for (std::uint32_t i = 0; i < size_[b]; ++i) {
      if (tri_[3 * std::size_t{fl[i]}] != kInvalidIndex) s.ring.push_back(fl[i]);
    }
  }
  const std::size_t b_kept = s.ring.size();
  {
    // Without a seam every corner of a carries ka[0] == ka[1]: no need to read the keys.
    const bool seam = (state_[a] & kSeam) != 0;
    const std::uint32_t* fl = star(a);
    for (std::uint32_t i = 0; i < size_[a]; ++i) {
      const std::uint32_t f = fl[i];
      std::uint32_t* t = &tri_[3 * std::size_t{f}];
      if (t[0] == kInvalidIndex) continue;
      const int j = corner_of(t, a);
      t[j] = b;
      const std::size_t corner = 3 * std::size_t{f} + j;
      if (c.reattach && key(corner) != ka[0] && (k < 2 || key(corner) != ka[1])) {
        wedge_vertex_[tri_wedge_[corner]] = b;  // the corner's wedge goes with it, values and key unchanged
      } else {
        const int side = (k == 2 && (!seam || key(corner) == ka[1])) ? 1 : 0;
        assert(!tri_wedge_.empty() || wb[side] == b);
        if (!tri_wedge_.empty()) tri_wedge_[corner] = wb[side];  // else wb[side] is b: the vertex is the wedge
        if (!tri_key_.empty()) tri_key_[corner] = kb[side];
      }
      s.ring.push_back(f);
    }
  }
  std::copy(s.ring.begin(), s.ring.end(), pool_.begin() + c.list_begin);
  if (c.list_begin != begin_[b]) capacity_[a] = 0;  // b took a's slot, or moved to a new one
  begin_[b] = c.list_begin;
  capacity_[b] = c.list_capacity;
  size_[b] = static_cast<std::uint32_t>(s.ring.size());
  size_[a] = 0;

  vx_[b].quadric += vx_[a].quadric;
  if (!seam_q_.empty()) seam_q_[b] += seam_q_[a];
  vx_[b].anchors += vx_[a].anchors;
  vx_[b].anchor_sum = vx_[b].anchor_sum + vx_[a].anchor_sum;
  // Keep the kind of a free survivor exact (ring() and check() rely on it): it is on the boundary when
  // either endpoint was.
  if (state_[b] & kFan) {
    state_[b] = static_cast<std::uint8_t>(c.boundary ? (state_[b] | kOpen) : (state_[b] & ~kOpen));
    if (kind_[b] == VertexKind::interior || kind_[b] == VertexKind::border) {
      kind_[b] = c.boundary ? VertexKind::border : VertexKind::interior;
    }
  } else if (kind_[b] == VertexKind::complex) {
    state_[b] = static_cast<std::uint8_t>(c.boundary ? (state_[b] | kOpen) : (state_[b] & ~kOpen));
  }
  if (c.reattach) {
    reattached_ = true;
    reclassify(b);  // b gained a's unpaired keys
  }
  const bool b_moved = !(vx_[b].pos == x);
  if (b_moved) {
    vx_[b].pos = x;
    state_[b] |= kMoved;
  }
  state_[a] |= kDead;
  ++version_[a];
  ++version_[b];
  if (guard_bvh_ != nullptr) guard_reattach(c, s, b_moved, b_kept);
}

void CollapseMesh::commit(Check c, const Vec3d& x, Scratch& s) {
  Vec3d far{};
  if (!far_.empty()) {
    const std::array<double, 2> d2 = far_distances(c.victim, c.survivor, x);
    far = d2[0] >= d2[1] ? far_[c.victim] : far_[c.survivor];
  }
  make_room(list_room(c));
  reserve(c);
  apply(c, x, s);
  if (!far_.empty()) far_[c.survivor] = far;
}

void CollapseMesh::ring(std::uint32_t v, std::vector<std::uint32_t>& out) const {
  const std::uint32_t m = size_[v];
  out.resize(2 * std::size_t{m});
  std::uint32_t* o = out.data();
  const std::uint32_t* fl = star(v);
  for (std::uint32_t i = 0; i < m; ++i) __builtin_prefetch(&tri_[3 * std::size_t{fl[i]}]);
  for (std::uint32_t i = 0; i < m; ++i) {
    const std::uint32_t* t = &tri_[3 * std::size_t{fl[i]}];
    const int j = corner_of(t, v);
    o[i] = t[kNext[j]];      // neighbours that follow v in a face
    o[m + i] = t[kPrev[j]];  // neighbours that precede v in a face
  }
  std::uint32_t n = 0;
  const bool fan = (state_[v] & kFan) != 0, open = (state_[v] & kOpen) != 0;
  if (fan && !open) {
    n = m;  // a closed fan: every neighbour follows v in exactly one face
  } else if (fan && m <= 32) {
    // An open fan: the neighbours that follow v, plus the one that only precedes it (the first spoke).
    n = m;
    for (std::uint32_t i = m; i < 2 * m; ++i) {
      bool seen = false;
      for (std::uint32_t j = 0; j < m; ++j) seen |= o[j] == o[i];
      if (!seen) o[n++] = o[i];
    }
  } else {
    small_sort(o, 2 * std::size_t{m});
    for (std::uint32_t i = 0; i < 2 * m; ++i) {
      if (n == 0 || o[n - 1] != o[i]) o[n++] = o[i];
    }
  }
  out.resize(n);
}

// ---- CollapseMesh: output --------------------------------------------------------------------------------------

Mesh CollapseMesh::output() const {
  const Mesh& m = src_;
  std::vector<std::uint32_t> wedge_map(m.wedge_count(), kInvalidIndex), vertices;
  for (std::size_t f = 0; f < face_slots(); ++f) {
    if (tri_[3 * f] == kInvalidIndex) continue;
    for (int j = 0; j < 3; ++j) wedge_map[corner_wedge(3 * f + j)] = 0;
  }
  Mesh out = compact_vertices_and_wedges(m, wedge_map, vertices,
                                         {.wedge_vertex = reattached_ ? &wedge_vertex_ : nullptr,
                                          .skin = skin_.empty() ? nullptr : &skin_,
                                          .normals = normals_.empty() ? nullptr : &normals_,
                                          .uvs = &uvs_,
                                          .colors = &colors_,
                                          .morph_targets = &morphs_});
  for (std::size_t i = 0; i < vertices.size(); ++i) {
    const std::uint32_t v = vertices[i];
    if (state_[v] & kMoved) out.positions[i] = to_float(origin_ + vx_[v].pos * scale_);
  }

  out.face_offsets.reserve(alive_faces_ + 1);
  out.corner_wedge.reserve(3 * alive_faces_);
  out.face_material.reserve(alive_faces_);
  const bool groups = m.face_group.size() == m.face_count();
  for (std::size_t f = 0; f < face_slots(); ++f) {
    if (tri_[3 * f] == kInvalidIndex) continue;
    const std::uint32_t* fw = face_wedges(f);
    const std::uint32_t w[3] = {wedge_map[fw[0]], wedge_map[fw[1]], wedge_map[fw[2]]};
    const std::uint32_t sf = source_face(f);
    out.add_face(w, 3, sf < m.face_material.size() ? m.face_material[sf] : 0);
    if (groups) out.face_group.push_back(m.face_group[sf]);
  }
  if (blend_ && !out.tangents.empty()) recompute_tangents(out);
  return out;
}

}  // namespace lodforge::collapse
