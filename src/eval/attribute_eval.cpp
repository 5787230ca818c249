// Attribute, UV and skinning quality (see the header). Sources: Sander, Snyder, Gortler & Hoppe, "Texture
// Mapping Progressive Meshes", SIGGRAPH 2001 (L2 / L∞ stretch); Cignoni, Rocchini & Scopigno 1998 (Metro
// sampling, through evaluate()).
#include "lodforge/eval/attribute_eval.hpp"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <numeric>
#include <optional>

#include "lodforge/eval/bvh.hpp"
#include "lodforge/eval/eval.hpp"

namespace lodforge {
namespace {

std::uint64_t mix64(std::uint64_t x) {
  x ^= x >> 30;
  x *= 0xbf58476d1ce4e5b9ull;
  x ^= x >> 27;
  x *= 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}
double unit_double(std::uint64_t x) { return static_cast<double>(x >> 11) * 0x1.0p-53; }

// Runs f(begin, end) over [0, n) in fixed chunks inside an arena of `threads` workers; outputs are per index.
template <typename F>
void parallel_chunks(unsigned threads, std::size_t n, F&& f) {
  constexpr std::size_t kChunk = 1024;
  const std::size_t chunks = (n + kChunk - 1) / kChunk;
  tbb::task_arena arena(threads == 0 ? tbb::task_arena::automatic : static_cast<int>(threads));
  arena.execute([&] {
    tbb::parallel_for(std::size_t{0}, chunks, [&](std::size_t c) { f(c * kChunk, std::min(n, (c + 1) * kChunk)); });
  });
}

struct Triangles {
  const Mesh* mesh = nullptr;
  std::vector<Vec3d> positions;
  std::vector<std::uint32_t> vertex_index;  // 3 per triangle (vertices)
  std::vector<std::uint32_t> wedge_index;   // 3 per triangle (wedges)
  std::vector<double> cumulative_area;      // prefix sums, size triangles + 1
  std::size_t count() const { return wedge_index.size() / 3; }
};

Triangles make_triangles(const Mesh& m) {
  Triangles t;
  t.mesh = &m;
  t.positions.reserve(m.vertex_count());
  for (const Vec3f& p : m.positions) t.positions.push_back(to_double(p));
  t.cumulative_area.push_back(0.0);
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    if (m.face_size(f) != 3) continue;
    const std::uint32_t* w = &m.corner_wedge[m.face_offsets[f]];
    // Out-of-range indices (validate() reports them): the face carries no surface here.
    bool ok = true;
    for (int i = 0; i < 3; ++i) ok = ok && w[i] < m.wedge_count() && m.wedge_vertex[w[i]] < m.vertex_count();
    if (!ok) continue;
    for (int i = 0; i < 3; ++i) {
      t.wedge_index.push_back(w[i]);
      t.vertex_index.push_back(m.wedge_vertex[w[i]]);
    }
    const std::uint32_t* v = &t.vertex_index[t.vertex_index.size() - 3];
    const double a = 0.5 * length(cross(t.positions[v[1]] - t.positions[v[0]], t.positions[v[2]] - t.positions[v[0]]));
    t.cumulative_area.push_back(t.cumulative_area.back() + (std::isfinite(a) ? a : 0.0));
  }
  return t;
}

// Attribute streams both meshes carry: a name and how to read a wedge's value as up to 4 doubles.
struct Stream {
  std::string name;
  int components = 0;
  enum class Kind { normal, uv, color } kind;
  int set = 0;
};

std::vector<Stream> common_streams(const Mesh& a, const Mesh& b) {
  std::vector<Stream> s;
  if (a.normals.size() == a.wedge_count() && b.normals.size() == b.wedge_count() && a.wedge_count() > 0) {
    s.push_back({"NORMAL", 3, Stream::Kind::normal, 0});
  }
  for (std::size_t i = 0; i < std::min(a.uvs.size(), b.uvs.size()); ++i) {
    if (a.uvs[i].size() == a.wedge_count() && b.uvs[i].size() == b.wedge_count()) {
      s.push_back({"TEXCOORD_" + std::to_string(i), 2, Stream::Kind::uv, static_cast<int>(i)});
    }
  }
  for (std::size_t i = 0; i < std::min(a.colors.size(), b.colors.size()); ++i) {
    if (a.colors[i].size() == a.wedge_count() && b.colors[i].size() == b.wedge_count()) {
      s.push_back({"COLOR_" + std::to_string(i), 4, Stream::Kind::color, static_cast<int>(i)});
    }
  }
  return s;
}

std::array<double, 4> read(const Mesh& m, const Stream& s, std::uint32_t w) {
  std::array<double, 4> v{};
  switch (s.kind) {
    case Stream::Kind::normal:
      for (int i = 0; i < 3; ++i) v[i] = m.normals[w][i];
      break;
    case Stream::Kind::uv:
      for (int i = 0; i < 2; ++i) v[i] = m.uvs[static_cast<std::size_t>(s.set)][w][i];
      break;
    case Stream::Kind::color:
      for (int i = 0; i < 4; ++i) v[i] = m.colors[static_cast<std::size_t>(s.set)][w][i];
      break;
  }
  return v;
}

std::array<double, 4> interpolate(const Triangles& t, const Stream& s, std::uint32_t tri, const Vec3d& bary) {
  std::array<double, 4> r{};
  for (int c = 0; c < 3; ++c) {
    const std::array<double, 4> v = read(*t.mesh, s, t.wedge_index[3 * std::size_t{tri} + c]);
    for (int i = 0; i < s.components; ++i) r[i] += bary[c] * v[i];
  }
  if (s.kind == Stream::Kind::normal) {
    const double len = std::sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
    if (len > 0.0) {
      for (int i = 0; i < 3; ++i) r[i] /= len;
    }
  }
  return r;
}

// ---- UV charts of the original and the lookup of a UV point in them ----

double uv_area2(const Vec2f& a, const Vec2f& b, const Vec2f& c) {
  return (double{b[0]} - a[0]) * (double{c[1]} - a[1]) - (double{c[0]} - a[0]) * (double{b[1]} - a[1]);
}

// A uniform grid over the original's UV layout of one set: which charts contain a UV point.
class UvLocator {
 public:
  UvLocator(const Triangles& t, const std::vector<Vec2f>& uv, const std::vector<std::uint32_t>& chart) : uv_(uv) {
    const std::size_t n = t.count();
    for (std::size_t i = 0; i < n; ++i) {
      for (int c = 0; c < 3; ++c) {
        const Vec2f p = uv[t.wedge_index[3 * i + c]];
        if (!std::isfinite(p[0]) || !std::isfinite(p[1])) continue;
        lo_[0] = std::min(lo_[0], double{p[0]});
        lo_[1] = std::min(lo_[1], double{p[1]});
        hi_[0] = std::max(hi_[0], double{p[0]});
        hi_[1] = std::max(hi_[1], double{p[1]});
      }
    }
    if (!(hi_[0] >= lo_[0])) return;
    cells_ = std::clamp<std::size_t>(static_cast<std::size_t>(std::sqrt(static_cast<double>(n) / 2.0)), 1, 512);
    bins_.resize(cells_ * cells_);
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint32_t* w = &t.wedge_index[3 * i];
      Triangle tri{{uv[w[0]], uv[w[1]], uv[w[2]]}, chart[w[0]]};
      if (!(uv_area2(tri.p[0], tri.p[1], tri.p[2]) != 0.0)) {
        if (std::isfinite(uv_area2(tri.p[0], tri.p[1], tri.p[2]))) {
          if (unoriented_by_chart_.size() <= tri.chart) unoriented_by_chart_.resize(std::size_t{tri.chart} + 1);
          unoriented_by_chart_[tri.chart].push_back(tri);
        }
        continue;
      }
      int x0 = 1 << 30, y0 = 1 << 30, x1 = -1, y1 = -1;
      for (const Vec2f& p : tri.p) {
        const auto [cx, cy] = cell(p[0], p[1]);
        x0 = std::min(x0, cx), y0 = std::min(y0, cy), x1 = std::max(x1, cx), y1 = std::max(y1, cy);
      }
      const auto id = static_cast<std::uint32_t>(tris_.size());
      tris_.push_back(tri);
      if (by_chart_.size() <= tri.chart) by_chart_.resize(std::size_t{tri.chart} + 1);
      by_chart_[tri.chart].push_back(id);
      for (int y = y0; y <= y1; ++y) {
        for (int x = x0; x <= x1; ++x) bins_[static_cast<std::size_t>(y) * cells_ + static_cast<std::size_t>(x)].push_back(id);
      }
    }
  }

  // Charts whose triangles contain p (within a small tolerance), sorted, unique.
  void charts_at(const Vec2f& p, std::vector<std::uint32_t>& out) const {
    out.clear();
    for_containing(p, [&](const Triangle& t) { out.push_back(t.chart); });
    std::sort(out.begin(), out.end());
    out.erase(std::unique(out.begin(), out.end()), out.end());
  }
  // The UV orientation (+1 or -1) of the original triangle of one of `charts` (sorted) nearest to p in UV
  // space (ties: the lowest triangle id); 0 when those charts have no triangle with UV area. For a point no
  // triangle of the charts contains (a chord across a concave outline, a strip of zero-area UV triangles).
  double nearest_orientation(const Vec2f& p, const std::vector<std::uint32_t>& charts) const {
    double best = INFINITY, sign = 0.0;
    for (std::uint32_t c : charts) {
      if (c >= by_chart_.size()) continue;
      for (std::uint32_t id : by_chart_[c]) {
        const double d = distance2(tris_[id], p);
        if (d < best) {
          best = d;
          sign = uv_area2(tris_[id].p[0], tris_[id].p[1], tris_[id].p[2]) > 0.0 ? 1.0 : -1.0;
        }
      }
    }
    return sign;
  }
  // Whether an original triangle of one of `charts` with zero UV area (a segment or a point in UV space)
  // passes within `radius` of p.
  bool near_unoriented(const Vec2f& p, const std::vector<std::uint32_t>& charts, double radius) const {
    for (std::uint32_t c : charts) {
      if (c >= unoriented_by_chart_.size()) continue;
      for (const Triangle& t : unoriented_by_chart_[c]) {
        if (distance2(t, p) <= radius * radius) return true;
      }
    }
    return false;
  }
  // Whether some original triangle of one of `charts` (sorted) containing p has UV orientation `sign`, and
  // whether any of them contains p at all.
  std::pair<bool, bool> orientation_at(const Vec2f& p, const std::vector<std::uint32_t>& charts, double sign) const {
    bool found = false, agrees = false;
    for_containing(p, [&](const Triangle& t) {
      if (!std::binary_search(charts.begin(), charts.end(), t.chart)) return;
      found = true;
      agrees |= uv_area2(t.p[0], t.p[1], t.p[2]) * sign > 0.0;
    });
    return {found, agrees};
  }

 private:
  struct Triangle {
    Vec2f p[3];
    std::uint32_t chart;
  };
  std::pair<int, int> cell(double u, double v) const {
    const double sx = (u - lo_[0]) / std::max(hi_[0] - lo_[0], 1e-30) * static_cast<double>(cells_);
    const double sy = (v - lo_[1]) / std::max(hi_[1] - lo_[1], 1e-30) * static_cast<double>(cells_);
    const int m = static_cast<int>(cells_) - 1;
    return {std::clamp(static_cast<int>(sx), 0, m), std::clamp(static_cast<int>(sy), 0, m)};
  }
  template <typename F>
  void for_containing(const Vec2f& p, F&& f) const {
    if (bins_.empty() || !std::isfinite(p[0]) || !std::isfinite(p[1])) return;
    const double tol = 1e-6 * std::max({hi_[0] - lo_[0], hi_[1] - lo_[1], 1e-12});
    if (p[0] < lo_[0] - tol || p[0] > hi_[0] + tol || p[1] < lo_[1] - tol || p[1] > hi_[1] + tol) return;
    const auto [cx, cy] = cell(p[0], p[1]);
    for (std::uint32_t id : bins_[static_cast<std::size_t>(cy) * cells_ + static_cast<std::size_t>(cx)]) {
      if (contains(tris_[id], p, tol)) f(tris_[id]);
    }
  }
  // Squared distance from p to triangle t in UV space (0 inside).
  static double distance2(const Triangle& t, const Vec2f& p) {
    const double a = uv_area2(t.p[0], t.p[1], t.p[2]);
    bool inside = true;
    double best = INFINITY;
    for (int i = 0; i < 3; ++i) {
      const Vec2f& q = t.p[i];
      const Vec2f& r = t.p[(i + 1) % 3];
      inside &= a != 0.0 && uv_area2(q, r, p) * a >= 0.0;
      const double ex = double{r[0]} - q[0], ey = double{r[1]} - q[1];
      const double px = double{p[0]} - q[0], py = double{p[1]} - q[1];
      const double len2 = ex * ex + ey * ey;
      const double u = len2 > 0.0 ? std::clamp((px * ex + py * ey) / len2, 0.0, 1.0) : 0.0;
      const double dx = px - u * ex, dy = py - u * ey;
      best = std::min(best, dx * dx + dy * dy);
    }
    return inside ? 0.0 : best;
  }
  static bool contains(const Triangle& t, const Vec2f& p, double tol) {
    const double a = uv_area2(t.p[0], t.p[1], t.p[2]);
    const double s = a > 0 ? 1.0 : -1.0;
    // Signed distances to the three edges, scaled by edge length: within tol outside counts as inside.
    for (int i = 0; i < 3; ++i) {
      const Vec2f& q = t.p[i];
      const Vec2f& r = t.p[(i + 1) % 3];
      const double e = std::hypot(double{r[0]} - q[0], double{r[1]} - q[1]);
      if (s * uv_area2(q, r, p) < -tol * e) return false;
    }
    return true;
  }

  const std::vector<Vec2f>& uv_;
  double lo_[2] = {INFINITY, INFINITY}, hi_[2] = {-INFINITY, -INFINITY};
  std::size_t cells_ = 0;
  std::vector<std::vector<std::uint32_t>> bins_;
  std::vector<Triangle> tris_;
  std::vector<std::vector<std::uint32_t>> by_chart_;  // triangle ids of each chart
  std::vector<std::vector<Triangle>> unoriented_by_chart_;  // zero-area UV triangles of each chart
};

double longest_edge(const Vec2f& a, const Vec2f& b, const Vec2f& c) {
  auto len = [](const Vec2f& p, const Vec2f& q) { return std::hypot(double{q[0]} - p[0], double{q[1]} - p[1]); };
  return std::max({len(a, b), len(b, c), len(c, a)});
}

// Sander 2001 stretch of triangle (q, uv); empty when its UV area is zero.
struct Stretch {
  double l2sq = 0, linf = 0, area3 = 0, area_uv = 0;
};
std::optional<Stretch> triangle_stretch(const Vec3d q[3], const Vec2f uv[3]) {
  const double s1 = uv[0][0], t1 = uv[0][1], s2 = uv[1][0], t2 = uv[1][1], s3 = uv[2][0], t3 = uv[2][1];
  const double a_uv = ((s2 - s1) * (t3 - t1) - (s3 - s1) * (t2 - t1)) / 2.0;
  if (!(std::abs(a_uv) > 0.0) || !std::isfinite(a_uv)) return std::nullopt;
  const Vec3d ss = (q[0] * (t2 - t3) + q[1] * (t3 - t1) + q[2] * (t1 - t2)) * (1.0 / (2.0 * a_uv));
  const Vec3d st = (q[0] * (s3 - s2) + q[1] * (s1 - s3) + q[2] * (s2 - s1)) * (1.0 / (2.0 * a_uv));
  const double a = dot(ss, ss), b = dot(ss, st), c = dot(st, st);
  Stretch r;
  r.l2sq = (a + c) / 2.0;
  r.linf = std::sqrt(std::max(0.0, ((a + c) + std::sqrt((a - c) * (a - c) + 4 * b * b)) / 2.0));
  r.area3 = 0.5 * length(cross(q[1] - q[0], q[2] - q[0]));
  r.area_uv = std::abs(a_uv);
  return r;
}

// Normalised L2 stretch of a whole mesh in one set (1 = isometric up to a global scale), and its largest
// normalised L∞.
std::pair<double, double> mesh_stretch(const Triangles& t, const std::vector<Vec2f>& uv) {
  double num = 0, a3 = 0, auv = 0, linf = 0;
  for (std::size_t i = 0; i < t.count(); ++i) {
    const Vec3d q[3] = {t.positions[t.vertex_index[3 * i]], t.positions[t.vertex_index[3 * i + 1]],
                        t.positions[t.vertex_index[3 * i + 2]]};
    const Vec2f p[3] = {uv[t.wedge_index[3 * i]], uv[t.wedge_index[3 * i + 1]], uv[t.wedge_index[3 * i + 2]]};
    const auto s = triangle_stretch(q, p);
    if (!s || !std::isfinite(s->l2sq)) continue;
    num += s->l2sq * s->area3;
    a3 += s->area3;
    auv += s->area_uv;
    linf = std::max(linf, s->linf);
  }
  if (!(a3 > 0.0) || !(auv > 0.0)) return {0.0, 0.0};
  const double norm = std::sqrt(auv / a3);  // undoes the global UV-per-length scale
  return {std::sqrt(num / a3) * norm, linf * norm};
}

// ---- skinning poses ----

Mesh posed(const Mesh& m, std::uint16_t joint, const Vec3d& centre, const Vec3d& axis, double angle) {
  Mesh out = m;
  const double c = std::cos(angle), s = std::sin(angle);
  for (std::size_t v = 0; v < m.vertex_count() && v < m.skin.size(); ++v) {
    double w = 0;
    for (int i = 0; i < kMaxInfluences; ++i) {
      if (m.skin[v].joints[i] == joint) w += m.skin[v].weights[i];
    }
    if (w <= 0.0) continue;
    const Vec3d p = to_double(m.positions[v]) - centre;
    // Rodrigues' rotation.
    const Vec3d r = p * c + cross(axis, p) * s + axis * (dot(axis, p) * (1.0 - c));
    out.positions[v] = to_float(to_double(m.positions[v]) * (1.0 - w) + (r + centre) * w);
  }
  return out;
}

}  // namespace

std::size_t AttributeEvalResult::uv_flipped() const {
  std::size_t n = 0;
  for (const UvSetReport& u : uv_sets) n += u.flipped;
  return n;
}
std::size_t AttributeEvalResult::uv_spanning() const {
  std::size_t n = 0;
  for (const UvSetReport& u : uv_sets) n += u.spanning;
  return n;
}

AttributeEvalResult evaluate_attributes(const Mesh& original_in, const Mesh& simplified_in,
                                        const AttributeEvalOptions& options) {
  AttributeEvalResult result;
  const Mesh original = triangulated(original_in);
  const Mesh simplified = triangulated(simplified_in);
  const Triangles a = make_triangles(original), b = make_triangles(simplified);
  if (a.count() == 0 || b.count() == 0) return result;

  // Attribute error and normal deviation at closest points.
  const std::vector<Stream> streams = common_streams(original, simplified);
  const std::size_t n = options.samples > 0 ? options.samples
                                            : std::clamp<std::size_t>(4 * a.count(), 20000, 400000);
  result.samples = n;
  if (!streams.empty() && a.cumulative_area.back() > 0.0) {
    const TriangleBvh bvh(b.positions, b.vertex_index);
    const std::size_t ns = streams.size();
    std::vector<double> sq(n * ns, 0.0), angle(n, -1.0);
    const double total = a.cumulative_area.back();
    std::atomic<bool> stopped = false;
    parallel_chunks(options.threads, n, [&](std::size_t begin, std::size_t end) {
      if (stopped.load(std::memory_order_relaxed)) return;
      if (options.stop.requested()) {
        stopped = true;
        return;
      }
      std::uint32_t hint = 0;
      for (std::size_t i = begin; i < end; ++i) {
        const std::uint64_t h = mix64(options.seed ^ mix64(i + 1));
        const double target = (static_cast<double>(i) + unit_double(h)) / static_cast<double>(n) * total;
        const auto it = std::upper_bound(a.cumulative_area.begin() + 1, a.cumulative_area.end(), target);
        const auto t = static_cast<std::uint32_t>(std::min<std::size_t>(
            static_cast<std::size_t>(it - a.cumulative_area.begin() - 1), a.count() - 1));
        double r1 = unit_double(mix64(h + 1)), r2 = unit_double(mix64(h + 2));
        if (r1 + r2 > 1.0) r1 = 1.0 - r1, r2 = 1.0 - r2;
        const Vec3d bary{{1.0 - r1 - r2, r1, r2}};
        const std::uint32_t* v = &a.vertex_index[3 * std::size_t{t}];
        const Vec3d p = a.positions[v[0]] * bary[0] + a.positions[v[1]] * bary[1] + a.positions[v[2]] * bary[2];
        const BvhHit hit = bvh.closest_point(p, hint);
        if (!hit.found()) continue;
        hint = hit.triangle;
        for (std::size_t k = 0; k < ns; ++k) {
          const std::array<double, 4> x = interpolate(a, streams[k], t, bary);
          const std::array<double, 4> y = interpolate(b, streams[k], hit.triangle, hit.barycentric);
          double d = 0;
          for (int c = 0; c < streams[k].components; ++c) d += (x[c] - y[c]) * (x[c] - y[c]);
          sq[i * ns + k] = std::isfinite(d) ? d : 0.0;
          if (streams[k].kind == Stream::Kind::normal) {
            const double cosine = std::clamp(x[0] * y[0] + x[1] * y[1] + x[2] * y[2], -1.0, 1.0);
            angle[i] = std::acos(cosine) * 180.0 / std::numbers::pi;
          }
        }
      }
    });
    result.stopped = stopped;
    for (std::size_t k = 0; k < ns; ++k) {
      double s = 0;
      for (std::size_t i = 0; i < n; ++i) s += sq[i * ns + k];
      result.attributes.push_back({streams[k].name, std::sqrt(s / static_cast<double>(n))});
    }
    std::vector<double> angles;
    for (double x : angle) {
      if (x >= 0.0) angles.push_back(x);
    }
    if (!angles.empty()) {
      result.normal_deviation_mean_deg = std::accumulate(angles.begin(), angles.end(), 0.0) / double(angles.size());
      const std::size_t k = std::min(angles.size() - 1, static_cast<std::size_t>(0.95 * double(angles.size())));
      std::nth_element(angles.begin(), angles.begin() + static_cast<std::ptrdiff_t>(k), angles.end());
      result.normal_deviation_p95_deg = angles[k];
    }
  }

  // UV stretch, flips and chart spans, per set both meshes have.
  const std::vector<std::uint32_t> chart = uv_charts(original);
  std::optional<TriangleBvh> original_bvh;  // built when a triangle first needs its surface place
  for (std::size_t set = 0; set < std::min(original.uvs.size(), simplified.uvs.size()); ++set) {
    const std::vector<Vec2f>& ua = original.uvs[set];
    const std::vector<Vec2f>& ub = simplified.uvs[set];
    if (ua.size() != original.wedge_count() || ub.size() != simplified.wedge_count()) continue;
    UvSetReport rep;
    rep.set = static_cast<int>(set);
    rep.stretch_original = mesh_stretch(a, ua).first;
    const auto [l2, linf] = mesh_stretch(b, ub);
    rep.stretch_simplified = l2;
    rep.stretch_max_linf = linf;
    rep.stretch_ratio = rep.stretch_original > 0.0 ? l2 / rep.stretch_original : 0.0;

    // Exact UV matches name their charts directly (vertices that never moved keep their UVs bit for bit).
    std::map<std::pair<float, float>, std::vector<std::uint32_t>> exact;
    for (std::uint32_t w = 0; w < original.wedge_count(); ++w) exact[{ua[w][0], ua[w][1]}].push_back(chart[w]);
    for (auto& [uv, list] : exact) {
      std::sort(list.begin(), list.end());
      list.erase(std::unique(list.begin(), list.end()), list.end());
    }
    const UvLocator locator(a, ua, chart);
    std::vector<std::vector<std::uint32_t>> at(simplified.wedge_count());
    for (std::uint32_t w = 0; w < simplified.wedge_count(); ++w) {
      const auto it = exact.find({ub[w][0], ub[w][1]});
      if (it != exact.end()) {
        at[w] = it->second;
      } else {
        locator.charts_at(ub[w], at[w]);
      }
    }
    // A corner whose UV lies in no original chart (possible after interpolation along a chord of a concave
    // chart outline) constrains nothing: it is counted in `outside`, not as a chart span.
    std::vector<std::uint32_t> common, tmp;
    for (std::uint32_t w = 0; w < simplified.wedge_count(); ++w) rep.outside += at[w].empty();
    for (std::size_t i = 0; i < a.count(); ++i) {
      const std::uint32_t* w = &a.wedge_index[3 * i];
      rep.degenerate_original += !(uv_area2(ua[w[0]], ua[w[1]], ua[w[2]]) != 0.0);
    }
    for (std::size_t i = 0; i < b.count(); ++i) {
      const std::uint32_t* w = &b.wedge_index[3 * i];
      bool any = false;
      for (int c = 0; c < 3; ++c) {
        if (at[w[c]].empty()) continue;
        if (!any) {
          common = at[w[c]];
          any = true;
          continue;
        }
        tmp.clear();
        std::set_intersection(common.begin(), common.end(), at[w[c]].begin(), at[w[c]].end(), std::back_inserter(tmp));
        common.swap(tmp);
      }
      if (!any) continue;
      if (common.empty()) {
        ++rep.spanning;
        continue;
      }
      // Flipped: the original triangles of those charts under the LOD triangle's UV centroid all have the
      // other orientation (charts may hold mirrored parts, so the chart's overall sign is not enough); where
      // none lies under it, the nearest one in UV space has, unless the centroid lies on a strip of
      // zero-area UV triangles of those charts (within a quarter of the triangle's longest UV edge): the
      // original has no orientation there, so the triangle counts as unoriented.
      const double area = uv_area2(ub[w[0]], ub[w[1]], ub[w[2]]);
      const Vec2f centroid{{(ub[w[0]][0] + ub[w[1]][0] + ub[w[2]][0]) / 3.0f, (ub[w[0]][1] + ub[w[1]][1] + ub[w[2]][1]) / 3.0f}};
      if (!(area != 0.0)) {
        ++rep.degenerate;
        continue;
      }
      const auto [found, agrees] = locator.orientation_at(centroid, common, area);
      bool flipped = false;
      if (found) {
        flipped = !agrees;
      } else if (locator.near_unoriented(centroid, common, 0.25 * longest_edge(ub[w[0]], ub[w[1]], ub[w[2]]))) {
        ++rep.unoriented;
      } else {
        flipped = locator.nearest_orientation(centroid, common) * area < 0.0;
      }
      if (!flipped) continue;
      // Where a chart is folded onto itself (mirrored halves that meet), a LOD triangle beside the fold may
      // have its UV centroid just across it while its place on the surface has its winding: the original
      // triangle nearest to its 3-D centroid, in the shared charts, with that winding clears it.
      if (!original_bvh) original_bvh.emplace(a.positions, a.vertex_index);
      const std::uint32_t* v = &b.vertex_index[3 * i];
      const BvhHit hit =
          original_bvh->closest_point((b.positions[v[0]] + b.positions[v[1]] + b.positions[v[2]]) * (1.0 / 3.0));
      bool surface_agrees = false;
      if (hit.triangle != kInvalidIndex) {
        const std::uint32_t* wo = &a.wedge_index[3 * std::size_t{hit.triangle}];
        surface_agrees = std::binary_search(common.begin(), common.end(), chart[wo[0]]) &&
                         uv_area2(ua[wo[0]], ua[wo[1]], ua[wo[2]]) * area > 0.0;
      }
      if (surface_agrees) {
        ++rep.fold;
      } else {
        ++rep.flipped;
      }
    }
    result.uv_sets.push_back(rep);
  }

  // Skinned: Metro distance in the bind pose and a few synthetic poses.
  if (!result.stopped && original.skin.size() == original.vertex_count() &&
      simplified.skin.size() == simplified.vertex_count() && original.vertex_count() > 0) {
    const EvalOptions eo{
        .samples = options.pose_samples, .seed = options.seed, .threads = options.threads, .stop = options.stop};
    const double diagonal = compute_bounds(original).diagonal();
    auto add = [&](std::string name, const Mesh& x, const Mesh& y) {
      const EvalResult e = evaluate(x, y, eo);
      result.stopped = result.stopped || e.stopped;
      const double d = diagonal > 0.0 ? diagonal : 1.0;
      result.poses.push_back({std::move(name), e.hausdorff / d, e.mean / d, e.rms / d});
      result.pose_max_hausdorff_rel = std::max(result.pose_max_hausdorff_rel, e.hausdorff / d);
    };
    add("bind", original, simplified);
    std::map<std::uint16_t, std::pair<double, Vec3d>> joints;  // total weight, weighted position sum
    Vec3d centre{};
    for (std::size_t v = 0; v < original.vertex_count(); ++v) {
      const Vec3d p = to_double(original.positions[v]);
      centre = centre + p;
      for (int i = 0; i < kMaxInfluences; ++i) {
        const double w = original.skin[v].weights[i];
        if (!(w > 0.0)) continue;
        auto& [sum, pos] = joints[original.skin[v].joints[i]];
        sum += w;
        pos = pos + p * w;
      }
    }
    centre = centre * (1.0 / static_cast<double>(original.vertex_count()));
    std::vector<std::pair<double, std::uint16_t>> ranked;
    for (const auto& [j, sw] : joints) ranked.emplace_back(-sw.first, j);
    std::sort(ranked.begin(), ranked.end());
    const double angle = options.pose_angle_deg * std::numbers::pi / 180.0;
    for (int k = 0; k < options.poses && k < static_cast<int>(ranked.size()); ++k) {
      const std::uint16_t j = ranked[static_cast<std::size_t>(k)].second;
      const Vec3d jc = joints[j].second * (1.0 / joints[j].first);
      Vec3d axis = cross(jc - centre, Vec3d{{0.0, 1.0, 0.0}});
      const double len = length(axis);
      axis = len > 1e-9 * std::max(diagonal, 1e-30) ? axis * (1.0 / len) : Vec3d{{1.0, 0.0, 0.0}};
      add("joint " + std::to_string(j), posed(original, j, jc, axis, angle), posed(simplified, j, jc, axis, angle));
    }
  }
  return result;
}

std::vector<std::uint32_t> uv_charts(const Mesh& m) {
  const std::size_t nw = m.wedge_count();
  std::vector<std::uint32_t> parent(nw);
  std::iota(parent.begin(), parent.end(), 0u);
  auto find = [&](std::uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  auto unite = [&](std::uint32_t a, std::uint32_t b) {
    a = find(a);
    b = find(b);
    if (a != b) parent[std::max(a, b)] = std::min(a, b);
  };
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    const std::uint32_t w0 = m.corner_wedge[m.face_offsets[f]];
    for (std::uint32_t c = m.face_offsets[f] + 1; c < m.face_offsets[f + 1]; ++c) {
      if (w0 < nw && m.corner_wedge[c] < nw) unite(w0, m.corner_wedge[c]);
    }
  }
  std::map<std::pair<std::uint32_t, std::vector<float>>, std::uint32_t> same;
  for (std::uint32_t w = 0; w < nw; ++w) {
    std::vector<float> key;
    for (const auto& set : m.uvs) {
      if (set.size() == nw) key.insert(key.end(), {set[w][0], set[w][1]});
    }
    auto [it, fresh] = same.emplace(std::make_pair(m.wedge_vertex[w], std::move(key)), w);
    if (!fresh) unite(it->second, w);
  }
  std::vector<std::uint32_t> id(nw), dense(nw, std::numeric_limits<std::uint32_t>::max());
  std::uint32_t next = 0;
  for (std::uint32_t w = 0; w < nw; ++w) {
    const std::uint32_t root = find(w);
    if (dense[root] == std::numeric_limits<std::uint32_t>::max()) dense[root] = next++;
    id[w] = dense[root];
  }
  return id;
}

}  // namespace lodforge
