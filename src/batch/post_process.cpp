// Vertex-cache and vertex-fetch ordering of a Mesh through meshoptimizer (Kapoulkine, meshoptimizer
// src/vcacheoptimizer.cpp, after Forsyth 2006 "Linear-speed vertex cache optimisation"). meshoptimizer works on
// an index buffer over one vertex stream; here the "vertices" it sees are the Mesh's wedges (render vertices),
// and the resulting orders are applied to the face, wedge and vertex arrays of the Mesh.
#include "lodforge/batch/post_process.hpp"

#include <meshoptimizer.h>

#include <algorithm>
#include <numeric>
#include <vector>

namespace lodforge::batch {
namespace {

using Order = std::vector<std::uint32_t>;  // new position -> old index

// Fan triangles of face f (as Mesh::triangulated does) appended as wedge indices.
void append_fan(const Mesh& mesh, std::size_t f, std::vector<std::uint32_t>& indices) {
  const std::uint32_t first = mesh.face_offsets[f], end = mesh.face_offsets[f + 1];
  for (std::uint32_t c = first + 1; c + 1 < end; ++c) {
    indices.push_back(mesh.corner_wedge[first]);
    indices.push_back(mesh.corner_wedge[c]);
    indices.push_back(mesh.corner_wedge[c + 1]);
  }
}

// Pass 1: the new face order. Faces are grouped by (material, group) so that each material is one contiguous
// run (one draw call, one `usemtl`), and inside a run meshoptimizer orders the triangles; a polygon goes where
// its first triangle lands, so polygons stay whole.
Order face_order(const Mesh& mesh) {
  const std::size_t nf = mesh.face_count();
  const bool has_material = mesh.face_material.size() == nf, has_group = mesh.face_group.size() == nf;
  Order by_group(nf);
  std::iota(by_group.begin(), by_group.end(), 0u);
  std::stable_sort(by_group.begin(), by_group.end(), [&](std::uint32_t a, std::uint32_t b) {
    const std::uint32_t ma = has_material ? mesh.face_material[a] : 0, mb = has_material ? mesh.face_material[b] : 0;
    if (ma != mb) return ma < mb;
    return has_group && mesh.face_group[a] < mesh.face_group[b];
  });

  Order out;
  out.reserve(nf);
  std::vector<std::uint32_t> indices, optimized, triangle_face;
  std::vector<char> placed(nf, 0);
  for (std::size_t begin = 0; begin < nf;) {
    std::size_t end = begin + 1;
    auto key = [&](std::uint32_t f) {
      return std::pair(has_material ? mesh.face_material[f] : 0u, has_group ? mesh.face_group[f] : 0u);
    };
    while (end < nf && key(by_group[end]) == key(by_group[begin])) ++end;

    indices.clear();
    triangle_face.clear();
    for (std::size_t i = begin; i < end; ++i) {
      const std::size_t before = indices.size();
      append_fan(mesh, by_group[i], indices);
      triangle_face.insert(triangle_face.end(), (indices.size() - before) / 3, by_group[i]);
    }
    // Which face each optimised triangle came from: meshoptimizer returns triangles, not their ids, so tag each
    // triangle by its position and find it again through a (wedge triple -> triangles) lookup.
    optimized.resize(indices.size());
    meshopt_optimizeVertexCache(optimized.data(), indices.data(), indices.size(), mesh.wedge_count());
    std::vector<std::uint32_t> by_triple(triangle_face.size());
    std::iota(by_triple.begin(), by_triple.end(), 0u);
    auto triple = [](const std::vector<std::uint32_t>& ix, std::uint32_t t) {
      return std::tuple(ix[3 * t], ix[3 * t + 1], ix[3 * t + 2]);
    };
    std::sort(by_triple.begin(), by_triple.end(), [&](std::uint32_t a, std::uint32_t b) {
      return std::pair(triple(indices, a), a) < std::pair(triple(indices, b), b);
    });
    std::vector<char> taken(triangle_face.size(), 0);
    for (std::uint32_t t = 0; t < triangle_face.size(); ++t) {
      // meshoptimizer keeps each triangle's corner order, so the triple is found exactly; duplicates of a
      // triangle are taken in turn.
      const auto want = triple(optimized, t);
      auto it = std::lower_bound(by_triple.begin(), by_triple.end(), want,
                                 [&](std::uint32_t a, const auto& w) { return triple(indices, a) < w; });
      while (it != by_triple.end() && taken[*it] && triple(indices, *it) == want) ++it;
      if (it == by_triple.end() || triple(indices, *it) != want) return by_group;  // not expected; keep grouping
      taken[*it] = 1;
      const std::uint32_t f = triangle_face[*it];
      if (!placed[f]) {
        placed[f] = 1;
        out.push_back(f);
      }
    }
    // Faces without triangles (fewer than 3 corners) keep their relative order at the end of the run.
    for (std::size_t i = begin; i < end; ++i) {
      if (!placed[by_group[i]]) {
        placed[by_group[i]] = 1;
        out.push_back(by_group[i]);
      }
    }
    begin = end;
  }
  return out;
}

// Pass 2: first-use order of `count` items over `uses`, unused items after in their old order.
Order first_use_order(const std::vector<std::uint32_t>& uses, std::size_t count) {
  Order out;
  out.reserve(count);
  std::vector<char> seen(count, 0);
  for (const std::uint32_t x : uses) {
    if (x < count && !seen[x]) {
      seen[x] = 1;
      out.push_back(x);
    }
  }
  for (std::uint32_t x = 0; x < count; ++x) {
    if (!seen[x]) out.push_back(x);
  }
  return out;
}

Order inverse(const Order& order) {
  Order inv(order.size());
  for (std::uint32_t i = 0; i < order.size(); ++i) inv[order[i]] = i;
  return inv;
}

template <class T>
void permute(std::vector<T>& values, const Order& order, std::size_t width = 1) {
  if (values.size() != order.size() * width) return;  // an absent (empty) or malformed stream stays as it is
  std::vector<T> out(values.size());
  for (std::size_t i = 0; i < order.size(); ++i) {
    std::copy_n(values.begin() + static_cast<std::ptrdiff_t>(order[i] * width), width,
                out.begin() + static_cast<std::ptrdiff_t>(i * width));
  }
  values = std::move(out);
}

}  // namespace

Mesh optimize_for_gpu(const Mesh& mesh) {
  Mesh out = mesh;
  const std::size_t nf = mesh.face_count();
  if (nf == 0) return out;

  // Faces.
  const Order faces = face_order(mesh);
  out.face_offsets.assign(1, 0);
  out.corner_wedge.clear();
  out.corner_wedge.reserve(mesh.corner_count());
  for (const std::uint32_t f : faces) {
    out.corner_wedge.insert(out.corner_wedge.end(), mesh.corner_wedge.begin() + mesh.face_offsets[f],
                            mesh.corner_wedge.begin() + mesh.face_offsets[f + 1]);
    out.face_offsets.push_back(static_cast<std::uint32_t>(out.corner_wedge.size()));
  }
  permute(out.face_material, faces);
  permute(out.face_group, faces);

  // Wedges, in order of first use by the new corners.
  const Order wedges = first_use_order(out.corner_wedge, mesh.wedge_count());
  const Order new_wedge = inverse(wedges);
  for (std::uint32_t& w : out.corner_wedge) w = new_wedge[w];
  permute(out.wedge_vertex, wedges);
  permute(out.normals, wedges);
  permute(out.tangents, wedges);
  for (auto& set : out.uvs) permute(set, wedges);
  for (auto& set : out.colors) permute(set, wedges);
  for (CustomAttribute& c : out.custom) permute(c.values, wedges, static_cast<std::size_t>(c.components));
  for (MorphTarget& t : out.morph_targets) {
    permute(t.position_deltas, wedges);
    permute(t.normal_deltas, wedges);
    permute(t.tangent_deltas, wedges);
  }

  // Vertices, in order of first use by the new wedges.
  const Order vertices = first_use_order(out.wedge_vertex, mesh.vertex_count());
  const Order new_vertex = inverse(vertices);
  for (std::uint32_t& v : out.wedge_vertex) {
    if (v < new_vertex.size()) v = new_vertex[v];
  }
  permute(out.positions, vertices);
  permute(out.skin, vertices);
  permute(out.priority, vertices);
  return out;
}

double average_cache_miss_ratio(const Mesh& mesh, unsigned cache_size) {
  std::vector<std::uint32_t> indices;
  for (std::size_t f = 0; f < mesh.face_count(); ++f) append_fan(mesh, f, indices);
  if (indices.empty()) return 0.0;
  return meshopt_analyzeVertexCache(indices.data(), indices.size(), mesh.wedge_count(), cache_size, 0, 0).acmr;
}

}  // namespace lodforge::batch
