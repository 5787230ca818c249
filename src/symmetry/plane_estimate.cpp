// Mirror-plane estimation. Candidates come from the principal axes of the surface (global bilateral symmetry
// is the common case for LOD inputs), the coordinate axes, and votes of vertex pairs whose neighbourhoods are
// combinatorially alike (Weisfeiler-Lehman style hashing, as in topology-mirror tools), which finds the plane of
// a partly symmetric mesh whose centroid has moved off it. Each candidate is scored by how far the mirror image
// of a vertex sample lands from the nearest vertex; the best ones are refined by iterated closest-vertex
// fitting with a robust (Geman-McClure) weight, after Simari, Kalogerakis and Singh 2006.
#include "plane_estimate.hpp"

#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <tuple>

namespace lodforge::symmetry::detail {
namespace {

constexpr std::size_t kScoreSamples = 4096;   // enough to rank candidates; the walk checks every vertex later
constexpr std::size_t kRefineSamples = 8192;
constexpr int kRefineIterations = 10;
constexpr std::size_t kRefinedCandidates = 3;  // only the best few are worth refining
constexpr std::size_t kVotePlanes = 4;
constexpr std::size_t kMinVotes = 8;  // fewer agreeing pairs are coincidence
constexpr int kWlRounds = 3;

Vec3d axis(int a) {
  Vec3d n{};
  n[a] = 1;
  return n;
}

// Normal with its largest component positive, so equal planes compare equal.
Plane canonical(Plane p) {
  int big = 0;
  for (int a = 1; a < 3; ++a) {
    if (std::abs(p.normal[a]) > std::abs(p.normal[big])) big = a;
  }
  if (p.normal[big] < 0) {
    p.normal = p.normal * -1.0;
    p.offset = -p.offset;
  }
  return p;
}

Plane through(const Vec3d& n, const Vec3d& point) { return canonical(Plane{n, -dot(n, point)}); }

std::vector<std::uint32_t> strided(const std::vector<std::uint32_t>& all, std::size_t limit) {
  const std::size_t stride = std::max<std::size_t>(1, (all.size() + limit - 1) / limit);
  std::vector<std::uint32_t> out;
  out.reserve(all.size() / stride + 1);
  for (std::size_t i = 0; i < all.size(); i += stride) out.push_back(all[i]);
  return out;
}

std::uint64_t mix(std::uint64_t h) {  // splitmix64 finaliser
  h += 0x9e3779b97f4a7c15ull;
  h = (h ^ (h >> 30)) * 0xbf58476d1ce4e5b9ull;
  h = (h ^ (h >> 27)) * 0x94d049bb133111ebull;
  return h ^ (h >> 31);
}

// Area-weighted centroid and principal axes of the surface (triangles integrated exactly).
struct Moments {
  Vec3d centroid{};
  std::array<Vec3d, 3> axes{axis(0), axis(1), axis(2)};
};

Moments surface_moments(const Mesh& mesh, const MeshGeometry& g) {
  Moments m;
  double area = 0;
  Vec3d first{};
  Eigen::Matrix3d second = Eigen::Matrix3d::Zero();
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    if (mesh.face_size(f) < 3 || !face_indices_in_range(mesh, f)) continue;
    for_each_face_triangle(mesh, f, [&](std::uint32_t c0, std::uint32_t c1, std::uint32_t c2) {
      const Vec3d& a = g.position[mesh.corner_vertex(c0)];
      const Vec3d& b = g.position[mesh.corner_vertex(c1)];
      const Vec3d& c = g.position[mesh.corner_vertex(c2)];
      const double t = 0.5 * length(cross(b - a, c - a));
      if (!(t > 0)) return;
      const Vec3d s = a + b + c;
      area += t;
      first = first + s * (t / 3.0);
      // The integral of x xT over a triangle: area / 12 (a aT + b bT + c cT + s sT).
      for (const Vec3d* v : {&a, &b, &c, &s}) {
        const Eigen::Vector3d e((*v)[0], (*v)[1], (*v)[2]);
        second += (t / 12.0) * e * e.transpose();
      }
    });
  }
  if (!(area > 0)) {  // no area: the vertices' mean, axes of the coordinate frame
    for (std::uint32_t v : g.vertices) m.centroid = m.centroid + g.position[v];
    if (!g.vertices.empty()) m.centroid = m.centroid * (1.0 / static_cast<double>(g.vertices.size()));
    return m;
  }
  m.centroid = first * (1.0 / area);
  const Eigen::Vector3d c(m.centroid[0], m.centroid[1], m.centroid[2]);
  const Eigen::Matrix3d cov = second - area * c * c.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  if (eig.info() == Eigen::Success) {
    for (int i = 0; i < 3; ++i) {
      const Eigen::Vector3d e = eig.eigenvectors().col(i);
      m.axes[static_cast<std::size_t>(i)] = canonical(Plane{{{e[0], e[1], e[2]}}, 0}).normal;
    }
  }
  return m;
}

// Planes voted for by pairs of vertices whose neighbourhoods hash alike and no other vertex shares the hash.
std::vector<Plane> vote_planes(const MeshGeometry& g) {
  const std::size_t nv = g.position.size();
  std::vector<std::uint64_t> hash(nv, 0), next(nv, 0);
  for (std::uint32_t v : g.vertices) hash[v] = mix(g.neighbour_offsets[v + 1] - g.neighbour_offsets[v]);
  std::vector<std::uint64_t> around;
  for (int round = 0; round < kWlRounds; ++round) {
    for (std::uint32_t v : g.vertices) {
      around.clear();
      for (std::uint32_t i = g.neighbour_offsets[v]; i < g.neighbour_offsets[v + 1]; ++i) {
        around.push_back(hash[g.neighbours[i]]);
      }
      std::sort(around.begin(), around.end());
      std::uint64_t h = mix(hash[v] ^ 0x5851f42d4c957f2dull);
      for (std::uint64_t a : around) h = mix(h ^ a);
      next[v] = h;
    }
    std::swap(hash, next);
  }
  std::vector<std::pair<std::uint64_t, std::uint32_t>> keyed;
  keyed.reserve(g.vertices.size());
  for (std::uint32_t v : g.vertices) keyed.emplace_back(hash[v], v);
  std::sort(keyed.begin(), keyed.end());

  const double diagonal = std::max(g.bounds.diagonal(), 1e-30);
  struct Bin {
    std::size_t votes = 0;
    Vec3d normal{};
    double offset = 0;
  };
  std::map<std::array<long long, 4>, Bin> bins;
  for (std::size_t i = 0; i < keyed.size();) {
    std::size_t j = i;
    while (j < keyed.size() && keyed[j].first == keyed[i].first) ++j;
    if (j - i == 2) {
      const Vec3d& p = g.position[keyed[i].second];
      const Vec3d& q = g.position[keyed[i + 1].second];
      const double len = length(p - q);
      if (len > 1e-9 * diagonal) {
        const Plane vote = through((p - q) * (1.0 / len), (p + q) * 0.5);
        // Bins of about 3.5 degrees and 3% of the diagonal.
        const std::array<long long, 4> key = {std::llround(vote.normal[0] * 16), std::llround(vote.normal[1] * 16),
                                              std::llround(vote.normal[2] * 16),
                                              std::llround(vote.offset / diagonal * 32)};
        Bin& b = bins[key];
        ++b.votes;
        b.normal = b.normal + vote.normal;
        b.offset += vote.offset;
      }
    }
    i = j;
  }
  std::vector<std::pair<std::size_t, Plane>> ranked;
  for (const auto& [key, b] : bins) {
    if (b.votes < kMinVotes) continue;
    const double len = length(b.normal);
    if (!(len > 0)) continue;
    ranked.emplace_back(b.votes, canonical(Plane{b.normal * (1.0 / len), b.offset / static_cast<double>(b.votes)}));
  }
  std::stable_sort(ranked.begin(), ranked.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  std::vector<Plane> out;
  for (std::size_t i = 0; i < ranked.size() && i < kVotePlanes; ++i) out.push_back(ranked[i].second);
  return out;
}

// The vertex nearest the mirror image of each sample, within `radius` of its edge length.
std::vector<PointTree::Nearest> mirror_nearest(const MeshGeometry& g, const PointTree& tree,
                                               const std::vector<std::uint32_t>& samples, const Plane& plane,
                                               double radius) {
  std::vector<PointTree::Nearest> out(samples.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, samples.size(), 256), [&](const auto& r) {
    for (std::size_t i = r.begin(); i != r.end(); ++i) {
      const std::uint32_t v = samples[i];
      out[i] = tree.nearest(plane.reflect(g.position[v]), radius * g.edge_length[v]);
    }
  });
  return out;
}

// Mean over the samples of the distance from a mirrored vertex to the nearest vertex, in units of the
// vertex's edge length and capped at 1: 0 for an exact mirror, near 1 for a plane that mirrors nothing.
double score(const MeshGeometry& g, const PointTree& tree, const std::vector<std::uint32_t>& samples,
             const Plane& plane) {
  const std::vector<PointTree::Nearest> near = mirror_nearest(g, tree, samples, plane, 1.0);
  double sum = 0;  // in sample order, whatever the thread count
  for (std::size_t i = 0; i < samples.size(); ++i) {
    sum += near[i].id == kInvalidIndex ? 1.0 : std::sqrt(near[i].distance2) / g.edge_length[samples[i]];
  }
  return samples.empty() ? 1.0 : sum / static_cast<double>(samples.size());
}

struct WeightedPair {
  std::uint32_t a, b;
  double weight;
};

Plane fit_weighted(const MeshGeometry& g, const std::vector<WeightedPair>& pairs, const Plane& previous,
                   bool fixed_normal) {
  Eigen::Matrix3d spread = Eigen::Matrix3d::Zero();
  Vec3d mid{};
  double total = 0;
  for (const WeightedPair& p : pairs) {
    const Vec3d& a = g.position[p.a];
    const Vec3d& b = g.position[p.b];
    const Vec3d d = a - b;
    const Eigen::Vector3d e(d[0], d[1], d[2]);
    spread += p.weight * e * e.transpose();
    mid = mid + (a + b) * (0.5 * p.weight);
    total += p.weight;
  }
  if (!(total > 0)) return previous;
  Vec3d n = previous.normal;
  if (!fixed_normal && spread.trace() > 0) {
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(spread);
    if (eig.info() == Eigen::Success) {
      const Eigen::Vector3d e = eig.eigenvectors().col(2);  // the largest eigenvalue comes last
      n = {{e[0], e[1], e[2]}};
      if (dot(n, previous.normal) < 0) n = n * -1.0;
      n = n * (1.0 / length(n));
    }
  }
  return Plane{n, -dot(n, mid * (1.0 / total))};
}

// Iterated closest-vertex fitting: pair each sample with the vertex nearest its mirror image, refit the plane.
Plane refine(const MeshGeometry& g, const PointTree& tree, const std::vector<std::uint32_t>& samples, Plane plane,
             bool fixed_normal) {
  const double diagonal = std::max(g.bounds.diagonal(), 1e-30);
  std::vector<WeightedPair> pairs;
  for (int it = 0; it < kRefineIterations; ++it) {
    pairs.clear();
    const std::vector<PointTree::Nearest> near = mirror_nearest(g, tree, samples, plane, 1.0);
    for (std::size_t i = 0; i < samples.size(); ++i) {
      if (near[i].id == kInvalidIndex) continue;
      const double r = std::sqrt(near[i].distance2) / (0.25 * g.edge_length[samples[i]]);
      pairs.push_back({samples[i], near[i].id, 1.0 / ((1 + r * r) * (1 + r * r))});
    }
    const Plane next = fit_weighted(g, pairs, plane, fixed_normal);
    // Closer than float positions can tell: the walk's refit finishes the job.
    const bool settled = length(next.normal - plane.normal) < 1e-9 && std::abs(next.offset - plane.offset) < 1e-9 * diagonal;
    plane = next;
    if (settled) break;
  }
  return plane;
}

bool same_plane(const Plane& a, const Plane& b, double diagonal) {
  return std::abs(dot(a.normal, b.normal)) > 0.9995 && std::abs(a.offset - b.offset) < 1e-3 * diagonal;
}

}  // namespace

MeshGeometry analyse_geometry(const Mesh& mesh, const Topology& topo) {
  MeshGeometry g;
  const std::size_t nv = mesh.vertex_count();
  g.position.resize(nv);
  for (std::size_t v = 0; v < nv; ++v) g.position[v] = to_double(mesh.positions[v]);
  g.edge_length.assign(nv, 0.0);
  std::vector<std::uint32_t> degree(nv, 0);
  for (const auto& e : topo.edges) {
    const double len = length(g.position[e[0]] - g.position[e[1]]);
    for (std::uint32_t v : e) {
      g.edge_length[v] += len;
      ++degree[v];
    }
  }
  g.neighbour_offsets.assign(nv + 1, 0);
  for (std::size_t v = 0; v < nv; ++v) {
    g.neighbour_offsets[v + 1] = g.neighbour_offsets[v] + degree[v];
    if (degree[v] == 0) continue;
    g.edge_length[v] /= degree[v];
    // A vertex whose edges all have zero length cannot be told from its neighbours: leave it out.
    if (g.edge_length[v] > 0 && std::isfinite(g.edge_length[v])) {
      g.vertices.push_back(static_cast<std::uint32_t>(v));
      g.bounds.add(g.position[v]);
    }
  }
  g.neighbours.resize(g.neighbour_offsets[nv]);
  std::vector<std::uint32_t> fill(g.neighbour_offsets.begin(), g.neighbour_offsets.end() - 1);
  for (const auto& e : topo.edges) {  // edges are sorted, so each list comes out ascending but for the merge below
    g.neighbours[fill[e[0]]++] = e[1];
    g.neighbours[fill[e[1]]++] = e[0];
  }
  for (std::size_t v = 0; v < nv; ++v) {
    std::sort(g.neighbours.begin() + g.neighbour_offsets[v], g.neighbours.begin() + g.neighbour_offsets[v + 1]);
  }
  return g;
}

Plane estimate_plane(const Mesh& mesh, const MeshGeometry& g, const PointTree& tree, PlaneMode mode) {
  const Moments m = surface_moments(mesh, g);
  const Vec3d box_centre = (g.bounds.min + g.bounds.max) * 0.5;
  const double diagonal = std::max(g.bounds.diagonal(), 1e-30);
  const bool fixed = mode != PlaneMode::automatic;

  std::vector<Plane> candidates;
  const std::vector<Plane> votes = vote_planes(g);
  if (fixed) {
    const Vec3d n = axis(mode == PlaneMode::x ? 0 : mode == PlaneMode::y ? 1 : 2);
    candidates = {through(n, m.centroid), through(n, box_centre)};
    for (const Plane& v : votes) {
      if (std::abs(dot(v.normal, n)) > 0.985) candidates.push_back(through(n, v.normal * -v.offset));  // within 10 degrees
    }
  } else {
    for (const Vec3d& a : m.axes) candidates.push_back(through(a, m.centroid));
    for (int a = 0; a < 3; ++a) {
      candidates.push_back(through(axis(a), m.centroid));
      candidates.push_back(through(axis(a), box_centre));
    }
    candidates.insert(candidates.end(), votes.begin(), votes.end());
  }

  const std::vector<std::uint32_t> score_samples = strided(g.vertices, kScoreSamples);
  std::vector<std::pair<double, std::size_t>> ranked;
  for (std::size_t i = 0; i < candidates.size(); ++i) ranked.emplace_back(score(g, tree, score_samples, candidates[i]), i);
  std::stable_sort(ranked.begin(), ranked.end(), [](const auto& a, const auto& b) { return a.first < b.first; });

  const std::vector<std::uint32_t> refine_samples = strided(g.vertices, kRefineSamples);
  std::vector<Plane> refined;
  Plane best = candidates.front();
  double best_score = INFINITY;
  for (const auto& [s, i] : ranked) {
    if (refined.size() == kRefinedCandidates) break;
    const Plane& candidate = candidates[i];  // a structured binding cannot be captured before C++20's P1091 in clang
    if (std::any_of(refined.begin(), refined.end(), [&](const Plane& r) { return same_plane(r, candidate, diagonal); })) {
      continue;
    }
    refined.push_back(candidates[i]);
    const Plane p = canonical(refine(g, tree, refine_samples, candidates[i], fixed));
    const double ps = score(g, tree, score_samples, p);
    if (ps < best_score) {
      best_score = ps;
      best = p;
    }
  }
  return best;
}

Plane fit_plane(const MeshGeometry& g, std::span<const std::pair<std::uint32_t, std::uint32_t>> pairs,
                const Plane& previous, bool fixed_normal) {
  std::vector<WeightedPair> weighted;
  weighted.reserve(pairs.size());
  for (const auto& [a, b] : pairs) weighted.push_back({a, b, 1.0});
  return fit_weighted(g, weighted, previous, fixed_normal);
}

}  // namespace lodforge::symmetry::detail
