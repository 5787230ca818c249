#include "lodforge/core/weld.hpp"

#include <bit>
#include <cstring>

namespace lodforge {
namespace {

// The weld key of every vertex as a flat array of 32-bit words (`words` per vertex): position, then skin,
// priority and the morph position deltas of its first wedge, when the mesh has them.
std::vector<std::uint32_t> weld_keys(const Mesh& mesh, std::size_t& words) {
  const std::size_t nv = mesh.vertex_count();
  std::vector<std::uint32_t> first_wedge(nv, kInvalidIndex);
  std::size_t morphs = 0;
  for (const MorphTarget& t : mesh.morph_targets) morphs += t.position_deltas.empty() ? 0 : 1;
  if (morphs > 0) {
    for (std::uint32_t w = 0; w < mesh.wedge_count(); ++w) {
      const std::uint32_t v = mesh.wedge_vertex[w];
      if (v < nv && first_wedge[v] == kInvalidIndex) first_wedge[v] = w;
    }
  }
  words = 3 + (mesh.skin.empty() ? 0 : 2 * kMaxInfluences) + (mesh.priority.empty() ? 0 : 1) + 3 * morphs;
  std::vector<std::uint32_t> keys(nv * words);
  for (std::size_t v = 0; v < nv; ++v) {
    std::uint32_t* k = &keys[v * words];
    for (int i = 0; i < 3; ++i) *k++ = weld_bits(mesh.positions[v][i]);
    if (!mesh.skin.empty()) {
      for (std::size_t i = 0; i < kMaxInfluences; ++i) {
        *k++ = mesh.skin[v].joints[i];
        *k++ = weld_bits(mesh.skin[v].weights[i]);
      }
    }
    if (!mesh.priority.empty()) *k++ = weld_bits(mesh.priority[v]);
    for (const MorphTarget& t : mesh.morph_targets) {
      if (t.position_deltas.empty()) continue;
      const std::uint32_t w = first_wedge[v];
      for (int i = 0; i < 3; ++i) *k++ = w == kInvalidIndex ? 0u : weld_bits(t.position_deltas[w][i]);
    }
  }
  return keys;
}

std::uint64_t hash_words(const std::uint32_t* k, std::size_t n) {
  std::uint64_t h = 0x9E3779B97F4A7C15ull;
  for (std::size_t i = 0; i < n; ++i) {
    h = (h ^ k[i]) * 0xff51afd7ed558ccdull;
    h ^= h >> 32;
  }
  return h;
}

}  // namespace

std::size_t weld_by_position(Mesh& mesh) {
  const std::size_t nv = mesh.vertex_count();
  if (nv == 0) return 0;
  std::size_t words = 0;
  const std::vector<std::uint32_t> keys = weld_keys(mesh, words);
  // Open addressing, load factor <= 1/2; slots hold the old id of the first vertex with that key.
  std::size_t capacity = 16;
  while (capacity < 2 * nv) capacity *= 2;
  std::vector<std::uint32_t> table(capacity, kInvalidIndex);
  std::vector<std::uint32_t> remap(nv), kept;  // kept: old id of each new vertex, in first-occurrence order
  kept.reserve(nv);
  for (std::uint32_t v = 0; v < nv; ++v) {
    const std::uint32_t* k = &keys[v * words];
    std::size_t slot = hash_words(k, words) & (capacity - 1);
    while (table[slot] != kInvalidIndex &&
           std::memcmp(&keys[std::size_t{table[slot]} * words], k, words * sizeof(std::uint32_t)) != 0) {
      slot = (slot + 1) & (capacity - 1);
    }
    if (table[slot] == kInvalidIndex) {
      table[slot] = v;
      remap[v] = static_cast<std::uint32_t>(kept.size());
      kept.push_back(v);
    } else {
      remap[v] = remap[table[slot]];
    }
  }
  const std::size_t next = kept.size();
  const std::size_t removed = nv - next;
  if (removed == 0) return 0;
  auto gather = [&](auto& arr) {
    if (arr.empty()) return;
    for (std::size_t n = 0; n < next; ++n) arr[n] = arr[kept[n]];  // kept[n] >= n: in-place is safe
    arr.resize(next);
  };
  gather(mesh.positions);
  gather(mesh.skin);
  gather(mesh.priority);
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
