// Meshes with attributes and the chart / UV-flip checks shared by the attribute-aware simplifier tests.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <map>
#include <tuple>
#include <vector>

#include "lodforge/core/mesh.hpp"
#include "lodforge/eval/attribute_eval.hpp"

namespace lodforge::attribute_test {

inline constexpr const char* kChartAttribute = "_CHART";

// UV chart id of every wedge (eval's definition: the wedges of one face, and the wedges of one vertex with equal
// UVs in every set, share a chart); ids dense in order of first wedge.
using ::lodforge::uv_charts;

// Adds the custom attribute _CHART (the wedge's chart id), which the simplifier carries unchanged: after
// simplification it names the input chart of every surviving wedge.
inline void tag_charts(Mesh& m) {
  const std::vector<std::uint32_t> charts = uv_charts(m);
  CustomAttribute a{kChartAttribute, 1, {}, {}};
  for (std::uint32_t c : charts) a.values.push_back(static_cast<float>(c));
  m.custom.push_back(std::move(a));
}

inline const std::vector<float>& chart_tags(const Mesh& m) {
  for (const CustomAttribute& a : m.custom) {
    if (a.name == kChartAttribute) return a.values;
  }
  static const std::vector<float> none;
  return none;
}

// Twice the signed UV area of triangle f in set `set`.
inline double uv_area2(const Mesh& m, std::size_t set, std::size_t f) {
  const std::uint32_t* w = &m.corner_wedge[m.face_offsets[f]];
  const Vec2f a = m.uvs[set][w[0]], b = m.uvs[set][w[1]], c = m.uvs[set][w[2]];
  return (double{b[0]} - a[0]) * (double{c[1]} - a[1]) - (double{c[0]} - a[0]) * (double{b[1]} - a[1]);
}

struct ChartReport {
  std::size_t charts = 0;           // distinct chart tags among the triangles
  std::size_t spanning = 0;         // triangles whose wedges carry different chart tags
  std::size_t flipped = 0;          // triangles whose UV sign (any set) differs from their chart's in the input
};

// The input chart orientation: the sign of the summed signed UV area of each chart, per set.
inline std::vector<std::vector<int>> chart_orientation(const Mesh& tagged) {
  const std::vector<float>& tag = chart_tags(tagged);
  std::size_t n = 0;
  for (float t : tag) n = std::max(n, static_cast<std::size_t>(t) + 1);
  std::vector<std::vector<int>> sign(tagged.uvs.size(), std::vector<int>(n, 0));
  for (std::size_t s = 0; s < tagged.uvs.size(); ++s) {
    std::vector<double> sum(n, 0.0);
    for (std::size_t f = 0; f < tagged.face_count(); ++f) {
      sum[static_cast<std::size_t>(tag[tagged.corner_wedge[tagged.face_offsets[f]]])] += uv_area2(tagged, s, f);
    }
    for (std::size_t c = 0; c < n; ++c) sign[s][c] = sum[c] > 0 ? 1 : (sum[c] < 0 ? -1 : 0);
  }
  return sign;
}

inline ChartReport chart_report(const Mesh& out, const std::vector<std::vector<int>>& orientation) {
  ChartReport r;
  const std::vector<float>& tag = chart_tags(out);
  std::vector<bool> seen;
  for (std::size_t f = 0; f < out.face_count(); ++f) {
    const std::uint32_t* w = &out.corner_wedge[out.face_offsets[f]];
    const auto c = static_cast<std::size_t>(tag[w[0]]);
    if (seen.size() <= c) seen.resize(c + 1, false);
    if (!seen[c]) ++r.charts;
    seen[c] = true;
    if (tag[w[1]] != tag[w[0]] || tag[w[2]] != tag[w[0]]) ++r.spanning;
    bool flip = false;
    for (std::size_t s = 0; s < out.uvs.size(); ++s) {
      const int o = orientation[s][c];
      const double a = uv_area2(out, s, f);
      flip |= o != 0 && !(a * o > 0);
    }
    r.flipped += flip;
  }
  return r;
}

// A cube [0, n]³, each side an n×n grid with its own wedges (a UV chart laid out in its own cell of a 3×2
// atlas, and the side's flat normal): 6 charts, seams along the 12 cube edges, 3 wedges at each corner.
inline Mesh make_charted_cube(int n) {
  Mesh m;
  std::map<std::tuple<int, int, int>, std::uint32_t> vid;
  m.uvs.resize(1);
  struct Side {
    int o[3], u[3], v[3];
    float nrm[3];
  };
  const Side sides[6] = {
      {{0, 0, 0}, {0, 1, 0}, {1, 0, 0}, {0, 0, -1}},  {{0, 0, n}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}},
      {{0, 0, 0}, {1, 0, 0}, {0, 0, 1}, {0, -1, 0}},  {{0, n, 0}, {0, 0, 1}, {1, 0, 0}, {0, 1, 0}},
      {{0, 0, 0}, {0, 0, 1}, {0, 1, 0}, {-1, 0, 0}},  {{n, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 0}},
  };
  for (int si = 0; si < 6; ++si) {
    const Side& s = sides[si];
    std::map<std::pair<int, int>, std::uint32_t> wedge;
    auto at = [&](int i, int j) {
      auto it = wedge.find({i, j});
      if (it != wedge.end()) return it->second;
      const int x = s.o[0] + i * s.u[0] + j * s.v[0], y = s.o[1] + i * s.u[1] + j * s.v[1],
                z = s.o[2] + i * s.u[2] + j * s.v[2];
      auto [vit, fresh] = vid.emplace(std::make_tuple(x, y, z), static_cast<std::uint32_t>(m.positions.size()));
      if (fresh) m.positions.push_back({{float(x), float(y), float(z)}});
      const auto w = static_cast<std::uint32_t>(m.wedge_vertex.size());
      m.wedge_vertex.push_back(vit->second);
      m.normals.push_back({{s.nrm[0], s.nrm[1], s.nrm[2]}});
      // Cell (si % 3, si / 3) of the atlas, with a margin.
      m.uvs[0].push_back({{(float(si % 3) + 0.05f + 0.9f * float(i) / float(n)) / 3.0f,
                           (float(si / 3) + 0.05f + 0.9f * float(j) / float(n)) / 2.0f}});
      wedge.emplace(std::make_pair(i, j), w);
      return w;
    };
    for (int i = 0; i < n; ++i) {
      for (int j = 0; j < n; ++j) {
        m.add_face({at(i, j), at(i + 1, j), at(i + 1, j + 1)});
        m.add_face({at(i, j), at(i + 1, j + 1), at(i, j + 1)});
      }
    }
  }
  m.materials.push_back(MaterialSlot{.name = "default"});
  return m;
}

}  // namespace lodforge::attribute_test
