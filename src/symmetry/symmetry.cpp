// Bilateral symmetry detection: a mirror-plane estimate (plane_estimate.cpp), then a correspondence grown face by
// face from mirrored seed faces, in the spirit of the region-growing verification of Mitra, Guibas and Pauly
// 2006 and the per-edge symmetry map of Frostbite's quad LOD tool (Bioware characters are only partly
// symmetric, so the map must hold only where symmetry exists). A reflection reverses orientation, so a face
// and its mirror run the corresponding corners in opposite directions; the walk does not rely on that (it
// reads the direction off each shared edge), so meshes with inconsistent winding are matched too.
#include "lodforge/symmetry/symmetry.hpp"

#include <algorithm>
#include <cmath>
#include <deque>
#include <numeric>
#include <optional>

#include <tbb/parallel_for.h>

#include "plane_estimate.hpp"
#include "point_tree.hpp"

namespace lodforge::symmetry {
namespace {

using detail::MeshGeometry;
using detail::PointTree;

// Seeds start regions, so they must not be guesses: a seed vertex's mirror lies within this fraction of the
// walk's tolerance, and the next nearest vertex is kSeedMargin times as far and at least kSeedApart edge
// lengths away. (No more apart than that: Suzanne's eyes sit a fifth of an edge from their sockets.)
constexpr double kSeedTightening = 0.25;
constexpr double kSeedMargin = 4.0;
constexpr double kSeedApart = 0.1;

// Face f's corner i corresponds to face `mirror`'s corner (start + step * i) mod size.
struct Alignment {
  std::uint32_t start = 0;
  int step = -1;
};

class Walk {
 public:
  Walk(const Mesh& mesh, const Topology& topo, const MeshGeometry& g, const SymmetryOptions& options)
      : mesh_(mesh), topo_(topo), g_(g), options_(options) {
    const std::size_t nf = mesh.face_count();
    corner_face_.assign(mesh.corner_count(), kInvalidIndex);
    usable_.assign(nf, 0);
    std::vector<std::uint32_t> seen;
    for (std::uint32_t f = 0; f < nf; ++f) {
      for (std::uint32_t c = mesh.face_offsets[f]; c < mesh.face_offsets[f + 1]; ++c) corner_face_[c] = f;
      usable_[f] = usable(f, seen);
    }
    component_faces();
    index_vertex_faces();
  }

  // Grows regions from every seed face in id order under `plane`; the maps start empty.
  void run(const Plane& plane, const std::vector<std::uint32_t>& seed_mirror) {
    plane_ = plane;
    vertex_mirror_.assign(mesh_.vertex_count(), kInvalidIndex);
    face_mirror_.assign(mesh_.face_count(), kInvalidIndex);
    for (std::uint32_t f = 0; f < mesh_.face_count(); ++f) {
      if (face_mirror_[f] != kInvalidIndex || !usable_[f]) continue;
      const auto seed = seed_pair(f, seed_mirror);
      if (!seed) continue;
      grow(f, seed->first, seed->second);
    }
  }

  const std::vector<std::uint32_t>& vertex_mirror() const { return vertex_mirror_; }
  const std::vector<std::uint32_t>& face_mirror() const { return face_mirror_; }

 private:
  // Faces the walk can match: indices in range, at least 3 corners, no vertex twice, every side an edge.
  bool usable(std::uint32_t f, std::vector<std::uint32_t>& seen) const {
    const std::uint32_t k = mesh_.face_size(f);
    if (k < 3 || !face_indices_in_range(mesh_, f)) return false;
    seen.clear();
    for (std::uint32_t i = 0; i < k; ++i) {
      const std::uint32_t c = mesh_.face_offsets[f] + i;
      if (topo_.corner_edge[c] == kInvalidIndex) return false;
      seen.push_back(mesh_.corner_vertex(c));
    }
    std::sort(seen.begin(), seen.end());
    return std::adjacent_find(seen.begin(), seen.end()) == seen.end();
  }

  // Faces per vertex-connected part, so that a small part matched whole is not dropped as a coincidence.
  void component_faces() {
    const std::size_t nv = mesh_.vertex_count();
    std::vector<std::uint32_t> parent(nv);
    std::iota(parent.begin(), parent.end(), 0u);
    auto find = [&](std::uint32_t x) {
      while (parent[x] != x) x = parent[x] = parent[parent[x]];
      return x;
    };
    for (std::uint32_t f = 0; f < mesh_.face_count(); ++f) {
      if (!usable_[f]) continue;
      for (std::uint32_t i = 1; i < mesh_.face_size(f); ++i) {
        const std::uint32_t a = find(vertex(f, 0)), b = find(vertex(f, i));
        if (a != b) parent[std::max(a, b)] = std::min(a, b);
      }
    }
    std::vector<std::uint32_t> count(nv, 0);
    face_root_.assign(mesh_.face_count(), kInvalidIndex);
    for (std::uint32_t f = 0; f < mesh_.face_count(); ++f) {
      if (!usable_[f]) continue;
      face_root_[f] = find(vertex(f, 0));
      ++count[face_root_[f]];
    }
    root_faces_ = std::move(count);
  }

  std::uint32_t vertex(std::uint32_t f, std::uint32_t i) const {
    return mesh_.corner_vertex(mesh_.face_offsets[f] + i % mesh_.face_size(f));
  }
  std::uint32_t index_of(std::uint32_t f, std::uint32_t v) const {
    for (std::uint32_t i = 0; i < mesh_.face_size(f); ++i) {
      if (vertex(f, i) == v) return i;
    }
    return kInvalidIndex;
  }
  static std::uint32_t wrap(long long i, std::uint32_t k) {
    const long long m = i % static_cast<long long>(k);
    return static_cast<std::uint32_t>(m < 0 ? m + k : m);
  }
  std::uint32_t mapped_index(const Alignment& a, std::uint32_t i, std::uint32_t k) const {
    return wrap(static_cast<long long>(a.start) + static_cast<long long>(a.step) * i, k);
  }

  double tolerance(std::uint32_t a, std::uint32_t b) const {
    return options_.tolerance * 0.5 * (g_.edge_length[a] + g_.edge_length[b]);
  }
  // Whether b may be a's mirror under the current plane (a == b: a on the plane).
  bool close(std::uint32_t a, std::uint32_t b) const {
    if (a == b) return std::abs(plane_.signed_distance(g_.position[a])) <= tolerance(a, a);
    return length(plane_.reflect(g_.position[a]) - g_.position[b]) <= tolerance(a, b);
  }

  // The face whose corners are the seed mirrors of f's corners, with its alignment; none if f is no seed.
  std::optional<std::pair<std::uint32_t, Alignment>> seed_pair(std::uint32_t f,
                                                               const std::vector<std::uint32_t>& seed_mirror) const {
    const std::uint32_t k = mesh_.face_size(f);
    for (std::uint32_t i = 0; i < k; ++i) {
      if (seed_mirror[vertex(f, i)] == kInvalidIndex) return std::nullopt;
    }
    // Candidate faces: those around the mirror of f's first corner.
    const std::uint32_t m0 = seed_mirror[vertex(f, 0)];
    for (std::uint32_t j = vertex_face_offsets_[m0]; j < vertex_face_offsets_[m0 + 1]; ++j) {
      const std::uint32_t h = vertex_faces_[j];
      if (mesh_.face_size(h) != k || !usable_[h] || face_mirror_[h] != kInvalidIndex) continue;
      const std::uint32_t start = index_of(h, m0);
      for (int step : {-1, 1}) {
        const Alignment a{start, step};
        bool all = true;
        for (std::uint32_t i = 1; i < k && all; ++i) all = vertex(h, mapped_index(a, i, k)) == seed_mirror[vertex(f, i)];
        if (all && (h != f || step == -1)) return std::pair{h, a};
      }
    }
    return std::nullopt;
  }

  // Matches f with h under `a` if every corner pair fits the plane and the maps so far; records the change.
  bool try_match(std::uint32_t f, std::uint32_t h, const Alignment& a) {
    const std::uint32_t k = mesh_.face_size(f);
    if (!usable_[f] || !usable_[h] || mesh_.face_size(h) != k) return false;
    if (face_mirror_[f] != kInvalidIndex || face_mirror_[h] != kInvalidIndex) return false;
    for (std::uint32_t i = 0; i < k; ++i) {
      const std::uint32_t x = vertex(f, i), y = vertex(h, mapped_index(a, i, k));
      if (vertex_mirror_[x] != kInvalidIndex && vertex_mirror_[x] != y) return false;
      if (vertex_mirror_[y] != kInvalidIndex && vertex_mirror_[y] != x) return false;
      if (!close(x, y)) return false;
    }
    if (f == h) {  // a face on the plane maps onto itself: the alignment must be its own inverse
      for (std::uint32_t i = 0; i < k; ++i) {
        if (mapped_index(a, mapped_index(a, i, k), k) != i) return false;
      }
    }
    for (std::uint32_t i = 0; i < k; ++i) {
      const std::uint32_t x = vertex(f, i), y = vertex(h, mapped_index(a, i, k));
      for (const auto& [from, to] : {std::pair{x, y}, std::pair{y, x}}) {
        if (vertex_mirror_[from] == kInvalidIndex) {
          vertex_mirror_[from] = to;
          region_vertices_.push_back(from);
        }
      }
    }
    face_mirror_[f] = h;
    face_mirror_[h] = f;
    region_faces_.push_back(f);
    if (h != f) region_faces_.push_back(h);
    queue_.push_back({f, h, a});
    return true;
  }

  // The face across side i of f (corner i to corner i + 1), or none at a boundary or non-manifold edge.
  std::uint32_t across(std::uint32_t f, std::uint32_t i) const {
    const std::uint32_t c = mesh_.face_offsets[f] + i;
    const std::uint32_t e = topo_.corner_edge[c];
    if (topo_.edge_valence(e) != 2) return kInvalidIndex;
    const std::uint32_t c0 = topo_.edge_corner[topo_.edge_corner_offsets[e]];
    const std::uint32_t c1 = topo_.edge_corner[topo_.edge_corner_offsets[e] + 1];
    const std::uint32_t other = c0 == c ? c1 : c0;
    const std::uint32_t g = corner_face_[other];
    return g == f ? kInvalidIndex : g;
  }

  // From a matched pair (f, h): each neighbour of f across an edge pairs with h's neighbour across the mirror
  // edge; the shared edge fixes how their corners correspond.
  void expand(std::uint32_t f, std::uint32_t h, const Alignment& a) {
    const std::uint32_t k = mesh_.face_size(f);
    for (std::uint32_t i = 0; i < k; ++i) {
      const std::uint32_t nf = across(f, i);
      if (nf == kInvalidIndex || face_mirror_[nf] != kInvalidIndex) continue;
      const std::uint32_t j0 = mapped_index(a, i, k), j1 = mapped_index(a, i + 1, k);
      // h's side between corners j0 and j1 starts at the smaller one cyclically.
      const std::uint32_t side = wrap(static_cast<long long>(j1) + 1, k) == j0 ? j1 : j0;
      const std::uint32_t nh = across(h, side);
      if (nh == kInvalidIndex || mesh_.face_size(nh) != mesh_.face_size(nf)) continue;
      const std::uint32_t u = vertex(f, i), v = vertex(f, i + 1);
      const std::uint32_t mu = vertex(h, j0), mv = vertex(h, j1);
      const std::uint32_t n = mesh_.face_size(nf);
      const std::uint32_t au = index_of(nf, u), amu = index_of(nh, mu);
      if (au == kInvalidIndex || amu == kInvalidIndex) continue;
      const int s = vertex(nf, au + 1) == v ? 1 : -1;
      const int ms = vertex(nh, amu + 1) == mv ? 1 : -1;
      const int step = s * ms;
      try_match(nf, nh, Alignment{wrap(static_cast<long long>(amu) - static_cast<long long>(step) * au, n), step});
    }
  }

  void grow(std::uint32_t f, std::uint32_t h, const Alignment& a) {
    region_faces_.clear();
    region_vertices_.clear();
    queue_.clear();
    if (!try_match(f, h, a)) return;
    while (!queue_.empty()) {
      const auto [pf, ph, pa] = queue_.front();
      queue_.pop_front();
      expand(pf, ph, pa);
    }
    // A few faces that happen to mirror each other are a coincidence, unless they are whole parts.
    std::size_t whole = root_faces_[face_root_[f]];
    if (face_root_[h] != face_root_[f]) whole += root_faces_[face_root_[h]];
    if (region_faces_.size() >= std::min(options_.min_region_faces, whole)) return;
    for (std::uint32_t x : region_faces_) face_mirror_[x] = kInvalidIndex;
    for (std::uint32_t v : region_vertices_) vertex_mirror_[v] = kInvalidIndex;
  }

  void index_vertex_faces() {
    const std::size_t nv = mesh_.vertex_count();
    vertex_face_offsets_.assign(nv + 1, 0);
    for (std::uint32_t f = 0; f < mesh_.face_count(); ++f) {
      if (!usable_[f]) continue;
      for (std::uint32_t i = 0; i < mesh_.face_size(f); ++i) ++vertex_face_offsets_[vertex(f, i) + 1];
    }
    std::partial_sum(vertex_face_offsets_.begin(), vertex_face_offsets_.end(), vertex_face_offsets_.begin());
    vertex_faces_.resize(vertex_face_offsets_[nv]);
    std::vector<std::uint32_t> fill(vertex_face_offsets_.begin(), vertex_face_offsets_.end() - 1);
    for (std::uint32_t f = 0; f < mesh_.face_count(); ++f) {
      if (!usable_[f]) continue;
      for (std::uint32_t i = 0; i < mesh_.face_size(f); ++i) vertex_faces_[fill[vertex(f, i)]++] = f;
    }
  }

 private:
  struct Pair {
    std::uint32_t f, h;
    Alignment a;
  };
  const Mesh& mesh_;
  const Topology& topo_;
  const MeshGeometry& g_;
  const SymmetryOptions& options_;
  Plane plane_;
  std::vector<std::uint32_t> corner_face_;
  std::vector<char> usable_;
  std::vector<std::uint32_t> face_root_, root_faces_;
  std::vector<std::uint32_t> vertex_face_offsets_, vertex_faces_;
  std::vector<std::uint32_t> vertex_mirror_, face_mirror_;
  std::vector<std::uint32_t> region_faces_, region_vertices_;
  std::deque<Pair> queue_;
};

// Per vertex: the vertex nearest its mirror image when that one is unambiguous and close, else none.
std::vector<std::uint32_t> seed_mirrors(const MeshGeometry& g, const PointTree& tree, const Plane& plane,
                                        double tolerance) {
  std::vector<std::uint32_t> out(g.position.size(), kInvalidIndex);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, g.vertices.size(), 256), [&](const auto& r) {
    for (std::size_t i = r.begin(); i != r.end(); ++i) {
      const std::uint32_t v = g.vertices[i];
      const double len = g.edge_length[v];
      const double near = kSeedTightening * tolerance * len;
      const double radius = std::max(kSeedMargin * near, kSeedApart * len);
      const PointTree::Nearest n = tree.nearest(plane.reflect(g.position[v]), radius);
      if (n.id == kInvalidIndex || n.distance2 > near * near) continue;
      const double apart = std::max(kSeedMargin * std::sqrt(n.distance2), kSeedApart * len);
      if (n.second_distance2 >= apart * apart) out[v] = n.id;
    }
  });
  // Only pairs that choose each other.
  for (std::uint32_t v : g.vertices) {
    if (out[v] != kInvalidIndex && out[out[v]] != v) out[v] = kInvalidIndex;
  }
  return out;
}

std::vector<std::pair<std::uint32_t, std::uint32_t>> matched_pairs(const std::vector<std::uint32_t>& mirror) {
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
  for (std::uint32_t v = 0; v < mirror.size(); ++v) {
    if (mirror[v] != kInvalidIndex && v <= mirror[v]) pairs.emplace_back(v, mirror[v]);
  }
  return pairs;
}

std::uint32_t find_edge(const Topology& topo, std::uint32_t a, std::uint32_t b) {
  const std::array<std::uint32_t, 2> key{std::min(a, b), std::max(a, b)};
  const auto it = std::lower_bound(topo.edges.begin(), topo.edges.end(), key);
  return it != topo.edges.end() && *it == key ? static_cast<std::uint32_t>(it - topo.edges.begin()) : kInvalidIndex;
}

}  // namespace

const char* plane_mode_name(PlaneMode mode) {
  switch (mode) {
    case PlaneMode::automatic: return "auto";
    case PlaneMode::x: return "x";
    case PlaneMode::y: return "y";
    case PlaneMode::z: return "z";
    case PlaneMode::none: return "none";
  }
  return "auto";
}

std::optional<PlaneMode> parse_plane_mode(std::string_view name) {
  for (PlaneMode m : {PlaneMode::automatic, PlaneMode::x, PlaneMode::y, PlaneMode::z, PlaneMode::none}) {
    if (name == plane_mode_name(m)) return m;
  }
  return std::nullopt;
}

SymmetryMap detect_symmetry(const Mesh& mesh, const Topology& topo, const SymmetryOptions& options) {
  SymmetryMap out;
  out.edges = topo.edge_count();
  out.edge_mirror.assign(topo.edge_count(), kInvalidIndex);
  out.vertex_mirror.assign(mesh.vertex_count(), kInvalidIndex);
  out.face_mirror.assign(mesh.face_count(), kInvalidIndex);
  if (options.plane == PlaneMode::none || topo.edge_count() == 0) return out;

  const MeshGeometry g = detail::analyse_geometry(mesh, topo);
  if (g.vertices.empty()) return out;
  std::vector<Vec3d> points;
  points.reserve(g.vertices.size());
  for (std::uint32_t v : g.vertices) points.push_back(g.position[v]);
  const PointTree tree(std::move(points), g.vertices);

  Plane plane = detail::estimate_plane(mesh, g, tree, options.plane);
  const bool fixed_normal = options.plane != PlaneMode::automatic;
  Walk walk(mesh, topo, g, options);
  // Twice: the plane refitted to the first walk's pairs is exact up to rounding for an exact mirror, and the
  // second walk then checks every vertex against that plane.
  for (int round = 0; round < 2; ++round) {
    walk.run(plane, seed_mirrors(g, tree, plane, options.tolerance));
    const auto pairs = matched_pairs(walk.vertex_mirror());
    if (pairs.empty()) break;
    plane = detail::fit_plane(g, pairs, plane, fixed_normal);
  }
  out.plane = plane;
  out.vertex_mirror = walk.vertex_mirror();
  out.face_mirror = walk.face_mirror();
  for (std::uint32_t f = 0; f < mesh.face_count(); ++f) {
    if (out.face_mirror[f] == kInvalidIndex) continue;
    const std::uint32_t k = mesh.face_size(f);
    for (std::uint32_t i = 0; i < k; ++i) {
      const std::uint32_t c = mesh.face_offsets[f] + i;
      const std::uint32_t e = topo.corner_edge[c];
      const std::uint32_t a = mesh.corner_vertex(c), b = mesh.corner_vertex(mesh.face_offsets[f] + (i + 1) % k);
      out.edge_mirror[e] = find_edge(topo, out.vertex_mirror[a], out.vertex_mirror[b]);
    }
  }
  out.symmetric_edges = static_cast<std::size_t>(
      std::count_if(out.edge_mirror.begin(), out.edge_mirror.end(), [](std::uint32_t e) { return e != kInvalidIndex; }));
  return out;
}

SymmetryMap detect_symmetry(const Mesh& mesh, const SymmetryOptions& options) {
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    if (mesh.face_size(f) < 3 || !face_indices_in_range(mesh, f)) {  // build_topology() cannot take such faces
      SymmetryMap out;
      out.vertex_mirror.assign(mesh.vertex_count(), kInvalidIndex);
      out.face_mirror.assign(mesh.face_count(), kInvalidIndex);
      return out;
    }
  }
  return detect_symmetry(mesh, build_topology(mesh), options);
}

std::optional<Plane> plane_of_pairs(const Mesh& mesh, const std::vector<std::uint32_t>& mirror) {
  Vec3d sum{}, first{}, mid{};
  std::size_t pairs = 0;
  const std::size_t n = std::min(mirror.size(), mesh.vertex_count());
  for (std::uint32_t v = 0; v < n; ++v) {
    const std::uint32_t m = mirror[v];
    if (m >= n || m <= v) continue;
    const Vec3d a = to_double(mesh.positions[v]), b = to_double(mesh.positions[m]);
    Vec3d d = a - b;
    if (pairs == 0) first = d;
    if (dot(d, first) < 0) d = d * -1.0;  // each pair's difference on the same side of the plane
    sum = sum + d;
    mid = mid + (a + b) * 0.5;
    ++pairs;
  }
  const double length = std::sqrt(dot(sum, sum));
  if (pairs == 0 || !(length > 0) || !std::isfinite(length)) return std::nullopt;
  Plane plane;
  plane.normal = sum * (1.0 / length);
  plane.offset = -dot(plane.normal, mid * (1.0 / static_cast<double>(pairs)));
  return plane;
}

}  // namespace lodforge::symmetry
