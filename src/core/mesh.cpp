#include "lodforge/core/mesh.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cassert>
#include <optional>

namespace lodforge {

std::size_t Mesh::triangle_count() const {
  std::size_t n = 0;
  for (std::size_t f = 0; f < face_count(); ++f) {
    const std::uint32_t k = face_size(f);
    if (k >= 3) n += k - 2;
  }
  return n;
}

std::uint32_t Mesh::add_face(const std::uint32_t* wedges, std::size_t n, std::uint32_t material) {
  if (face_offsets.empty()) face_offsets.push_back(0);
  corner_wedge.insert(corner_wedge.end(), wedges, wedges + n);
  face_offsets.push_back(static_cast<std::uint32_t>(corner_wedge.size()));
  face_material.push_back(material);
  return static_cast<std::uint32_t>(face_offsets.size() - 2);
}

std::uint32_t Mesh::add_face(std::initializer_list<std::uint32_t> wedges, std::uint32_t material) {
  return add_face(wedges.begin(), wedges.size(), material);
}

std::uint32_t Mesh::add_vertex_with_wedge(const Vec3f& p) {
  positions.push_back(p);
  wedge_vertex.push_back(static_cast<std::uint32_t>(positions.size() - 1));
  return static_cast<std::uint32_t>(wedge_vertex.size() - 1);
}

FaceKindCounts count_face_kinds(const Mesh& mesh) {
  FaceKindCounts c;
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    const std::uint32_t k = mesh.face_size(f);
    if (k == 3) ++c.triangles;
    else if (k == 4) ++c.quads;
    else if (k > 4) ++c.polygons;
  }
  return c;
}

Bounds3 compute_bounds(const Mesh& mesh) {
  Bounds3 b;
  for (const Vec3f& p : mesh.positions) {
    if (std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2])) b.add(to_double(p));
  }
  return b;
}

Vec3d face_normal_newell(const Mesh& mesh, std::size_t f) {
  const std::uint32_t begin = mesh.face_offsets[f];
  return newell_normal(mesh.face_size(f), [&](std::size_t i) {
    return to_double(mesh.positions[mesh.corner_vertex(begin + i)]);
  });
}

Mesh triangulated(const Mesh& mesh, std::vector<std::uint32_t>* triangle_face) {
  Mesh out = mesh;
  out.face_offsets.assign(1, 0);
  out.corner_wedge.clear();
  out.face_material.clear();
  out.face_group.clear();
  const std::size_t tris = mesh.triangle_count();
  out.face_offsets.reserve(tris + 1);
  out.corner_wedge.reserve(tris * 3);
  out.face_material.reserve(tris);
  if (!mesh.face_group.empty()) out.face_group.reserve(tris);
  if (triangle_face) {
    triangle_face->clear();
    triangle_face->reserve(tris);
  }
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    for_each_face_triangle(mesh, f, [&](std::uint32_t c0, std::uint32_t c1, std::uint32_t c2) {
      const std::uint32_t tri[3] = {mesh.corner_wedge[c0], mesh.corner_wedge[c1], mesh.corner_wedge[c2]};
      out.add_face(tri, 3, mesh.face_material.empty() ? 0 : mesh.face_material[f]);
      if (!mesh.face_group.empty()) out.face_group.push_back(mesh.face_group[f]);
      if (triangle_face) triangle_face->push_back(static_cast<std::uint32_t>(f));
    });
  }
  return out;
}

std::vector<std::uint32_t> repeated_faces(const Mesh& mesh, unsigned threads) {
  // Each face's corner vertices from its smallest one: equal sequences (and materials) are repeats. Faces are
  // hashed by that sequence in parallel, bucketed by the hash's top bits into partitions small enough for
  // their open-addressing tables to stay in cache, and each partition inserts its faces in ascending order, so
  // a repeat is found when its earlier twin is already there (equal faces hash alike: same partition).
  auto canonical_start = [&](std::uint32_t f) {
    const std::uint32_t begin = mesh.face_offsets[f], k = mesh.face_size(f);
    std::uint32_t s = 0;
    for (std::uint32_t i = 1; i < k; ++i) {
      if (mesh.corner_vertex(begin + i) < mesh.corner_vertex(begin + s)) s = i;
    }
    return s;
  };
  auto material = [&](std::uint32_t f) { return f < mesh.face_material.size() ? mesh.face_material[f] : 0u; };
  // Whether no corner repeats (large faces sorted: pairwise tests are quadratic).
  auto simple = [&](std::uint32_t f, std::vector<std::uint32_t>& corners) {
    const std::uint32_t begin = mesh.face_offsets[f], k = mesh.face_size(f);
    if (k > 32) {
      corners.resize(k);
      for (std::uint32_t i = 0; i < k; ++i) corners[i] = mesh.corner_vertex(begin + i);
      std::sort(corners.begin(), corners.end());
      return std::adjacent_find(corners.begin(), corners.end()) == corners.end();
    }
    for (std::uint32_t i = 0; i < k; ++i) {
      for (std::uint32_t j = i + 1; j < k; ++j) {
        if (mesh.corner_vertex(begin + i) == mesh.corner_vertex(begin + j)) return false;
      }
    }
    return true;
  };
  auto same = [&](std::uint32_t f, std::uint32_t g) {
    const std::uint32_t k = mesh.face_size(f);
    if (mesh.face_size(g) != k || material(f) != material(g)) return false;
    const std::uint32_t bf = mesh.face_offsets[f], bg = mesh.face_offsets[g], sf = canonical_start(f),
                        sg = canonical_start(g);
    for (std::uint32_t i = 0; i < k; ++i) {
      if (mesh.corner_vertex(bf + (sf + i) % k) != mesh.corner_vertex(bg + (sg + i) % k)) return false;
    }
    return true;
  };
  const std::size_t faces = mesh.face_count();
  constexpr std::size_t kPartitionFaces = std::size_t{1} << 14;  // a 32k-slot table: 384 KB
  int bits = 0;
  while (bits < 12 && (faces >> bits) > kPartitionFaces) ++bits;
  const std::size_t partitions = std::size_t{1} << bits;
  constexpr std::uint32_t kSkipped = ~std::uint32_t{0};  // partition of a face that cannot repeat another
  std::vector<std::uint64_t> hash(faces);
  std::vector<std::uint32_t> partition(faces);
  const bool parallel = threads != 1 && faces >= 2 * kPartitionFaces;
  std::optional<tbb::task_arena> arena;
  if (parallel) arena.emplace(threads == 0 ? tbb::task_arena::automatic : static_cast<int>(threads));
  auto for_ranges = [&](std::size_t n, std::size_t grain, auto&& body) {
    if (!parallel) return body(std::size_t{0}, n);
    arena->execute([&] {
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, grain),
                        [&](const tbb::blocked_range<std::size_t>& r) { body(r.begin(), r.end()); });
    });
  };
  for_ranges(faces, 4096, [&](std::size_t b, std::size_t e) {
    std::vector<std::uint32_t> corners;
    for (std::size_t i = b; i < e; ++i) {
      const auto f = static_cast<std::uint32_t>(i);
      const std::uint32_t k = mesh.face_size(f);
      if (k < 3 || !face_indices_in_range(mesh, f) || !simple(f, corners)) {
        partition[f] = kSkipped;
        continue;
      }
      const std::uint32_t begin = mesh.face_offsets[f], s = canonical_start(f);
      std::uint64_t h = 0x9E3779B97F4A7C15ull ^ (std::uint64_t{k} << 32 | material(f));
      for (std::uint32_t c = 0; c < k; ++c) {
        h = (h ^ mesh.corner_vertex(begin + (s + c) % k)) * 0x100000001B3ull;
        h ^= h >> 29;
      }
      hash[f] = h;
      partition[f] = bits == 0 ? 0u : static_cast<std::uint32_t>(h >> (64 - bits));
    }
  });
  // Faces by partition, ascending within each (a counting sort).
  std::vector<std::uint32_t> first(partitions + 1, 0);
  for (std::uint32_t p : partition) {
    if (p != kSkipped) ++first[p + 1];
  }
  for (std::size_t p = 0; p < partitions; ++p) first[p + 1] += first[p];
  std::vector<std::uint32_t> order(first[partitions]);
  {
    std::vector<std::uint32_t> at(first.begin(), first.end() - 1);
    for (std::uint32_t f = 0; f < faces; ++f) {
      if (partition[f] != kSkipped) order[at[partition[f]]++] = f;
    }
  }
  std::vector<std::vector<std::uint32_t>> found(partitions);
  for_ranges(partitions, 1, [&](std::size_t b, std::size_t e) {
    std::vector<std::uint32_t> slot_face;
    std::vector<std::uint64_t> slot_hash;
    for (std::size_t p = b; p < e; ++p) {
      const std::size_t n = first[p + 1] - first[p];
      std::size_t capacity = 16;
      while (capacity < 2 * n) capacity *= 2;
      slot_face.assign(capacity, kInvalidIndex);
      slot_hash.resize(capacity);
      for (std::size_t j = first[p]; j < first[p + 1]; ++j) {
        const std::uint32_t f = order[j];
        const std::uint64_t h = hash[f];
        for (std::size_t i = h & (capacity - 1);; i = (i + 1) & (capacity - 1)) {
          if (slot_face[i] == kInvalidIndex) {
            slot_face[i] = f;
            slot_hash[i] = h;
            break;
          }
          if (slot_hash[i] == h && same(slot_face[i], f)) {
            found[p].push_back(f);
            break;
          }
        }
      }
    }
  });
  std::vector<std::uint32_t> repeats;
  for (const std::vector<std::uint32_t>& list : found) repeats.insert(repeats.end(), list.begin(), list.end());
  std::sort(repeats.begin(), repeats.end());
  return repeats;
}

Mesh without_faces(const Mesh& mesh, std::span<const std::uint32_t> faces) {
  Mesh out = mesh;
  out.face_offsets.assign(1, 0);
  out.corner_wedge.clear();
  out.face_material.clear();
  out.face_group.clear();
  std::size_t next = 0;
  for (std::uint32_t f = 0; f < mesh.face_count(); ++f) {
    if (next < faces.size() && faces[next] == f) {
      ++next;
      continue;
    }
    out.add_face(mesh.corner_wedge.data() + mesh.face_offsets[f], mesh.face_size(f),
                 mesh.face_material.empty() ? 0 : mesh.face_material[f]);
    if (!mesh.face_group.empty()) out.face_group.push_back(mesh.face_group[f]);
  }
  if (mesh.face_material.empty()) out.face_material.clear();
  return out;
}

Mesh compact_vertices_and_wedges(const Mesh& m, std::vector<std::uint32_t>& wedge_map,
                                 std::vector<std::uint32_t>& vertices, const AttributeOverrides& overrides) {
  const std::size_t nw = m.wedge_count(), nv = m.vertex_count();
  const std::vector<std::uint32_t>& wedge_vertex = overrides.wedge_vertex ? *overrides.wedge_vertex : m.wedge_vertex;
  std::vector<std::uint32_t> vertex_map(nv, kInvalidIndex);
  std::vector<std::uint32_t> wedges;  // kept ids, ascending
  for (std::uint32_t w = 0; w < nw; ++w) {
    if (wedge_map[w] == kInvalidIndex) continue;
    wedge_map[w] = static_cast<std::uint32_t>(wedges.size());
    wedges.push_back(w);
    vertex_map[wedge_vertex[w]] = 0;
  }
  vertices.clear();
  for (std::uint32_t v = 0; v < nv; ++v) {
    if (vertex_map[v] == kInvalidIndex) continue;
    vertex_map[v] = static_cast<std::uint32_t>(vertices.size());
    vertices.push_back(v);
  }

  Mesh out;
  out.name = m.name;
  out.materials = m.materials;
  out.groups = m.groups;
  out.formats = m.formats;
  out.morph_default_weights = m.morph_default_weights;
  out.positions.reserve(vertices.size());
  for (std::uint32_t v : vertices) out.positions.push_back(m.positions[v]);
  auto per_vertex = [&](const auto& in, auto& dst) {
    if (in.size() != nv) return;
    dst.reserve(vertices.size());
    for (std::uint32_t v : vertices) dst.push_back(in[v]);
  };
  per_vertex(overrides.skin ? *overrides.skin : m.skin, out.skin);
  per_vertex(m.priority, out.priority);
  auto per_wedge = [&](const auto& in, auto& dst, std::size_t components) {
    if (in.size() != nw * components) return;
    dst.reserve(wedges.size() * components);
    for (std::uint32_t w : wedges) {
      for (std::size_t i = 0; i < components; ++i) dst.push_back(in[w * components + i]);
    }
  };
  // The override of set i when there is one.
  auto set_of = [](const auto* sets, const auto& own, std::size_t i) -> const auto& {
    return sets && i < sets->size() && !(*sets)[i].empty() ? (*sets)[i] : own[i];
  };
  out.wedge_vertex.reserve(wedges.size());
  for (std::uint32_t w : wedges) out.wedge_vertex.push_back(vertex_map[wedge_vertex[w]]);
  per_wedge(overrides.normals ? *overrides.normals : m.normals, out.normals, 1);
  per_wedge(m.tangents, out.tangents, 1);
  out.uvs.resize(m.uvs.size());
  for (std::size_t i = 0; i < m.uvs.size(); ++i) per_wedge(set_of(overrides.uvs, m.uvs, i), out.uvs[i], 1);
  out.colors.resize(m.colors.size());
  for (std::size_t i = 0; i < m.colors.size(); ++i) per_wedge(set_of(overrides.colors, m.colors, i), out.colors[i], 1);
  out.color_components = m.color_components;
  out.custom.reserve(m.custom.size());
  for (const CustomAttribute& a : m.custom) {
    CustomAttribute c{a.name, a.components, a.format, {}};
    per_wedge(a.values, c.values, static_cast<std::size_t>(std::max(a.components, 0)));
    out.custom.push_back(std::move(c));
  }
  const std::vector<MorphTarget>& morphs = overrides.morph_targets ? *overrides.morph_targets : m.morph_targets;
  out.morph_targets.reserve(morphs.size());
  for (const MorphTarget& t : morphs) {
    MorphTarget o{t.name, {}, {}, {}};
    per_wedge(t.position_deltas, o.position_deltas, 1);
    per_wedge(t.normal_deltas, o.normal_deltas, 1);
    per_wedge(t.tangent_deltas, o.tangent_deltas, 1);
    out.morph_targets.push_back(std::move(o));
  }
  return out;
}

std::vector<std::uint32_t> triangle_vertex_indices(const Mesh& mesh) {
  std::vector<std::uint32_t> indices;
  indices.reserve(3 * mesh.triangle_count());
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    for_each_face_triangle(mesh, f, [&](std::uint32_t c0, std::uint32_t c1, std::uint32_t c2) {
      indices.push_back(mesh.corner_vertex(c0));
      indices.push_back(mesh.corner_vertex(c1));
      indices.push_back(mesh.corner_vertex(c2));
    });
  }
  return indices;
}

bool face_indices_in_range(const Mesh& mesh, std::size_t f) {
  for (std::uint32_t c = mesh.face_offsets[f]; c < mesh.face_offsets[f + 1]; ++c) {
    if (!(c < mesh.corner_count() && mesh.corner_wedge[c] < mesh.wedge_count() &&
          mesh.wedge_vertex[mesh.corner_wedge[c]] < mesh.vertex_count())) {
      return false;
    }
  }
  return true;
}

std::uint32_t triangulation_start(const Mesh& mesh, std::size_t f) {
  if (mesh.face_size(f) != 4) return 0;
  const std::uint32_t c = mesh.face_offsets[f];
  auto at = [&](std::uint32_t i) { return to_double(mesh.positions[mesh.corner_vertex(c + i)]); };
  return quad_triangulation_start(at(0), at(1), at(2), at(3));
}

}  // namespace lodforge
