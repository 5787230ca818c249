#include "lodforge/core/weld.hpp"

#include <cstring>
#include <unordered_map>

namespace lodforge {
namespace {

// Hash of a byte string (FNV-1a, 64 bit). Only used for bucketing; equality is checked exactly.
std::uint64_t fnv1a(const void* data, std::size_t n, std::uint64_t h = 1469598103934665603ull) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < n; ++i) h = (h ^ p[i]) * 1099511628211ull;
  return h;
}

float canonical(float x) { return x == 0.0f ? 0.0f : x; }  // -0 and +0 weld together

}  // namespace

std::size_t weld_by_position(Mesh& mesh) {
  const std::size_t nv = mesh.vertex_count();
  if (nv == 0) return 0;
  // Morph position deltas live on wedges; give each vertex the deltas of its first wedge.
  std::vector<std::uint32_t> first_wedge(nv, kInvalidIndex);
  for (std::uint32_t w = 0; w < mesh.wedge_count(); ++w) {
    const std::uint32_t v = mesh.wedge_vertex[w];
    if (v < nv && first_wedge[v] == kInvalidIndex) first_wedge[v] = w;
  }
  auto key_bytes = [&](std::uint32_t v, std::vector<float>& out) {
    out.clear();
    for (int i = 0; i < 3; ++i) out.push_back(canonical(mesh.positions[v][i]));
    if (!mesh.skin.empty()) {
      for (int i = 0; i < kMaxInfluences; ++i) {
        out.push_back(static_cast<float>(mesh.skin[v].joints[static_cast<std::size_t>(i)]));
        out.push_back(canonical(mesh.skin[v].weights[static_cast<std::size_t>(i)]));
      }
    }
    if (!mesh.priority.empty()) out.push_back(canonical(mesh.priority[v]));
    for (const MorphTarget& t : mesh.morph_targets) {
      if (t.position_deltas.empty()) continue;
      const std::uint32_t w = first_wedge[v];
      for (int i = 0; i < 3; ++i) out.push_back(w == kInvalidIndex ? 0.0f : canonical(t.position_deltas[w][i]));
    }
  };

  std::unordered_map<std::uint64_t, std::vector<std::uint32_t>> buckets;
  buckets.reserve(nv);
  std::vector<std::uint32_t> remap(nv);
  std::vector<float> key, other;
  std::uint32_t next = 0;
  std::vector<std::uint32_t> kept;  // old id of each new vertex
  kept.reserve(nv);
  for (std::uint32_t v = 0; v < nv; ++v) {
    key_bytes(v, key);
    auto& bucket = buckets[fnv1a(key.data(), key.size() * sizeof(float))];
    std::uint32_t found = kInvalidIndex;
    for (std::uint32_t cand : bucket) {
      key_bytes(kept[cand], other);
      if (other == key) {
        found = cand;
        break;
      }
    }
    if (found == kInvalidIndex) {
      found = next++;
      bucket.push_back(found);
      kept.push_back(v);
    }
    remap[v] = found;
  }
  const std::size_t removed = nv - next;
  if (removed == 0) return 0;
  std::vector<Vec3f> positions(next);
  for (std::uint32_t n = 0; n < next; ++n) positions[n] = mesh.positions[kept[n]];
  mesh.positions = std::move(positions);
  if (!mesh.skin.empty()) {
    std::vector<SkinInfluences> skin(next);
    for (std::uint32_t n = 0; n < next; ++n) skin[n] = mesh.skin[kept[n]];
    mesh.skin = std::move(skin);
  }
  if (!mesh.priority.empty()) {
    std::vector<float> pr(next);
    for (std::uint32_t n = 0; n < next; ++n) pr[n] = mesh.priority[kept[n]];
    mesh.priority = std::move(pr);
  }
  for (std::uint32_t& v : mesh.wedge_vertex) {
    if (v < nv) v = remap[v];
  }
  return removed;
}

std::pair<std::size_t, std::size_t> remove_unreferenced(Mesh& mesh) {
  const std::size_t nw = mesh.wedge_count(), nv = mesh.vertex_count();
  std::vector<std::uint32_t> wedge_map(nw, kInvalidIndex);
  std::uint32_t next_w = 0;
  // Keep the original order: a wedge's new id follows its old id order.
  std::vector<char> used_w(nw, 0);
  for (std::uint32_t w : mesh.corner_wedge) {
    if (w < nw) used_w[w] = 1;
  }
  for (std::uint32_t w = 0; w < nw; ++w) {
    if (used_w[w]) wedge_map[w] = next_w++;
  }
  std::vector<char> used_v(nv, 0);
  for (std::uint32_t w = 0; w < nw; ++w) {
    if (used_w[w] && mesh.wedge_vertex[w] < nv) used_v[mesh.wedge_vertex[w]] = 1;
  }
  std::vector<std::uint32_t> vertex_map(nv, kInvalidIndex);
  std::uint32_t next_v = 0;
  for (std::uint32_t v = 0; v < nv; ++v) {
    if (used_v[v]) vertex_map[v] = next_v++;
  }
  auto compact = [](auto& arr, const std::vector<std::uint32_t>& map, std::size_t stride = 1) {
    if (arr.empty()) return;
    std::size_t out = 0;
    for (std::size_t i = 0; i < map.size(); ++i) {
      if (map[i] == kInvalidIndex) continue;
      for (std::size_t k = 0; k < stride; ++k) arr[out * stride + k] = arr[i * stride + k];
      ++out;
    }
    arr.resize(out * stride);
  };
  if (next_w != nw) {
    compact(mesh.wedge_vertex, wedge_map);
    compact(mesh.normals, wedge_map);
    compact(mesh.tangents, wedge_map);
    for (auto& s : mesh.uvs) compact(s, wedge_map);
    for (auto& s : mesh.colors) compact(s, wedge_map);
    for (auto& a : mesh.custom) compact(a.values, wedge_map, static_cast<std::size_t>(a.components));
    for (auto& t : mesh.morph_targets) {
      compact(t.position_deltas, wedge_map);
      compact(t.normal_deltas, wedge_map);
      compact(t.tangent_deltas, wedge_map);
    }
    for (std::uint32_t& w : mesh.corner_wedge) {
      if (w < nw) w = wedge_map[w];
    }
  }
  if (next_v != nv) {
    compact(mesh.positions, vertex_map);
    compact(mesh.skin, vertex_map);
    compact(mesh.priority, vertex_map);
    for (std::uint32_t& v : mesh.wedge_vertex) {
      if (v < nv) v = vertex_map[v];
    }
  }
  return {nv - next_v, nw - next_w};
}

}  // namespace lodforge
