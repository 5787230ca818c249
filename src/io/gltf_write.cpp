// glTF 2.0 writer (.gltf + "<stem>.bin", or .glb): replaces the data of the primitives the reader turned into
// MaterialSlots and keeps the rest of the source document as it was.
//
// How the source document survives: the writer patches the source JSON. Each converted primitive gets new
// accessors (indices, attributes, morph targets) built from its MaterialSlot's faces; accessors and bufferViews
// that only converted primitives used are garbage-collected. Everything else keeps its index, so references the
// writer does not understand (unknown extensions) still point at the same objects: new accessors and bufferViews
// first fill the freed indices (ascending), then append; a freed index that is neither refilled nor at the end
// becomes a tiny placeholder. All kept bufferViews and the new data go into one buffer, each kept view at the same
// offset modulo 4 as before, so every accessor keeps its alignment.
//
// Output is deterministic: every order is derived from the input (mesh, slot, attribute order of the source
// primitive), JSON objects keep their source key order, and numbers are printed by nlohmann::json's shortest
// round-trip formatter.
//
// LOD chains (save_gltf_lods, lods.hpp): each LOD level of each mesh becomes a new glTF mesh written the same way
// as its LOD0 (over the source primitives, so materials and attribute layout match), appended after the source
// meshes, and each node showing a mesh gets one appended LOD node per level, named in its MSFT_lod extension.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <set>
#include <system_error>

#include "gltf_internal.hpp"
#include "lodforge/io/file.hpp"
#include "lodforge/io/formats.hpp"
#include "lodforge/io/lods.hpp"

namespace lodforge::io {
namespace {

using gltf::Semantic;

// Unit-length tolerance below the validator's (5e-5): vectors it accepts are written bit-exactly.
constexpr double kUnitTolerance = 4e-5;

int json_index(const OrderedJson& o, const char* key) {
  const auto it = o.find(key);
  if (it == o.end() || !it->is_number_unsigned()) return -1;
  const std::uint64_t v = it->get<std::uint64_t>();
  return v > static_cast<std::uint64_t>(std::numeric_limits<int>::max()) ? -1 : static_cast<int>(v);
}

const OrderedJson& json_array(const OrderedJson& o, const char* key) {
  static const OrderedJson kEmpty = OrderedJson::array();
  const auto it = o.find(key);
  return it != o.end() && it->is_array() ? *it : kEmpty;
}

// ---------------------------------------------------------------------------------------------------------------
// Which source accessors and bufferViews the rewritten primitives free.

struct Freed {
  std::vector<char> accessors;  // per source accessor: referenced only by converted primitives
  std::vector<char> views;      // per source bufferView: referenced only by freed accessors
};

Freed find_freed(const OrderedJson& doc, const std::vector<std::vector<char>>& converted) {
  const OrderedJson& accessors = json_array(doc, "accessors");
  const OrderedJson& views = json_array(doc, "bufferViews");
  std::vector<char> by_converted(accessors.size(), 0), elsewhere(accessors.size(), 0);
  auto mark = [&](std::vector<char>& used, int a) {
    if (a >= 0 && static_cast<std::size_t>(a) < used.size()) used[static_cast<std::size_t>(a)] = 1;
  };
  auto mark_object = [&](std::vector<char>& used, const OrderedJson& o) {
    if (!o.is_object()) return;
    for (const auto& [key, value] : o.items()) mark(used, json_index(o, key.c_str()));
  };

  const OrderedJson& meshes = json_array(doc, "meshes");
  for (std::size_t m = 0; m < meshes.size(); ++m) {
    const OrderedJson& prims = json_array(meshes[m], "primitives");
    for (std::size_t p = 0; p < prims.size(); ++p) {
      const bool conv = m < converted.size() && p < converted[m].size() && converted[m][p];
      std::vector<char>& used = conv ? by_converted : elsewhere;
      if (const auto it = prims[p].find("attributes"); it != prims[p].end()) mark_object(used, *it);
      mark(used, json_index(prims[p], "indices"));
      for (const OrderedJson& t : json_array(prims[p], "targets")) mark_object(used, t);
    }
  }
  for (const OrderedJson& skin : json_array(doc, "skins")) mark(elsewhere, json_index(skin, "inverseBindMatrices"));
  for (const OrderedJson& anim : json_array(doc, "animations")) {
    for (const OrderedJson& s : json_array(anim, "samplers")) {
      mark(elsewhere, json_index(s, "input"));
      mark(elsewhere, json_index(s, "output"));
    }
  }
  for (const OrderedJson& node : json_array(doc, "nodes")) {
    const auto ext = node.find("extensions");
    if (ext == node.end() || !ext->is_object()) continue;
    const auto inst = ext->find("EXT_mesh_gpu_instancing");
    if (inst != ext->end() && inst->is_object()) {
      if (const auto a = inst->find("attributes"); a != inst->end()) mark_object(elsewhere, *a);
    }
  }

  Freed freed;
  freed.accessors.assign(accessors.size(), 0);
  // Accessors no one references are kept: an extension lodforge does not know may use them.
  for (std::size_t a = 0; a < accessors.size(); ++a)
    freed.accessors[a] = static_cast<char>(by_converted[a] && !elsewhere[a]);

  std::vector<char> by_freed(views.size(), 0), kept(views.size(), 0);
  auto mark_view = [&](std::vector<char>& used, int v) {
    if (v >= 0 && static_cast<std::size_t>(v) < used.size()) used[static_cast<std::size_t>(v)] = 1;
  };
  for (std::size_t a = 0; a < accessors.size(); ++a) {
    std::vector<char>& used = freed.accessors[a] ? by_freed : kept;
    mark_view(used, json_index(accessors[a], "bufferView"));
    if (const auto sparse = accessors[a].find("sparse"); sparse != accessors[a].end() && sparse->is_object()) {
      for (const char* part : {"indices", "values"}) {
        if (const auto it = sparse->find(part); it != sparse->end()) mark_view(used, json_index(*it, "bufferView"));
      }
    }
  }
  for (const OrderedJson& image : json_array(doc, "images")) mark_view(kept, json_index(image, "bufferView"));
  freed.views.assign(views.size(), 0);
  for (std::size_t v = 0; v < views.size(); ++v) freed.views[v] = static_cast<char>(by_freed[v] && !kept[v]);
  return freed;
}

// Hands out final indices: freed source indices first (ascending), then new ones past the end.
class IndexAllocator {
 public:
  IndexAllocator(std::size_t source_count, const std::vector<char>& freed) : source_count_(source_count) {
    for (std::size_t i = 0; i < freed.size(); ++i) {
      if (freed[i]) free_.push_back(static_cast<int>(i));
    }
  }
  int next() {
    if (next_free_ < free_.size()) return free_[next_free_++];
    return static_cast<int>(source_count_ + appended_++);
  }
  // Final array size: freed indices left unused at the end are dropped.
  std::size_t final_count() const {
    std::size_t n = source_count_ + appended_;
    if (appended_ == 0) {
      std::size_t k = free_.size();
      while (k > next_free_ && n > 0 && static_cast<std::size_t>(free_[k - 1]) == n - 1) {
        --k;
        --n;
      }
    }
    return n;
  }

 private:
  std::size_t source_count_;
  std::vector<int> free_;
  std::size_t next_free_ = 0;
  std::size_t appended_ = 0;
};

// ---------------------------------------------------------------------------------------------------------------
// New accessor data.

struct NewView {
  std::string bytes;
  int target = 0;
  std::size_t stride = 0;  // 0: tightly packed (no byteStride)
};

std::int64_t clamp_round(double x, double lo, double hi) {
  return static_cast<std::int64_t>(std::round(std::clamp(x, lo, hi)));
}

class DataBuilder {
 public:
  DataBuilder(IndexAllocator& accessors, IndexAllocator& views) : accessor_index_(accessors), view_index_(views) {}

  // `values` holds count * components floats; stored as `format` (normalized integers by round(x * max)).
  int add_attribute(const std::vector<float>& values, int components, AttributeFormat format, bool min_max) {
    const int ct = format.component_type;
    const std::size_t size = static_cast<std::size_t>(gltf::component_size(ct));
    const std::size_t count = values.size() / static_cast<std::size_t>(components);
    const std::size_t element = size * static_cast<std::size_t>(components);
    // Each vertex attribute element starts on a 4-byte boundary (spec 3.6.2.4), hence the padded stride.
    const std::size_t stride = (element + 3) & ~std::size_t{3};
    NewView view;
    view.target = gltf::kArrayBuffer;
    view.stride = stride != element ? stride : 0;
    view.bytes.assign(count * stride, '\0');
    std::vector<double> lo(static_cast<std::size_t>(components), std::numeric_limits<double>::infinity());
    std::vector<double> hi(static_cast<std::size_t>(components), -std::numeric_limits<double>::infinity());
    for (std::size_t i = 0; i < count; ++i) {
      char* dst = view.bytes.data() + i * stride;
      for (std::size_t c = 0; c < static_cast<std::size_t>(components); ++c) {
        const double stored = store(dst + c * size, values[i * static_cast<std::size_t>(components) + c], format);
        lo[c] = std::min(lo[c], stored);
        hi[c] = std::max(hi[c], stored);
      }
    }
    OrderedJson acc = OrderedJson::object();
    acc["bufferView"] = add_view(std::move(view));
    acc["componentType"] = ct;
    if (format.normalized) acc["normalized"] = true;
    acc["count"] = count;
    acc["type"] = gltf::type_name(components);
    if (min_max) {
      acc["min"] = bounds_json(lo, ct);
      acc["max"] = bounds_json(hi, ct);
    }
    return add_accessor(std::move(acc));
  }

  int add_indices(const std::vector<std::uint32_t>& indices, std::size_t vertex_count) {
    // 16-bit when every index fits below the primitive-restart value 65535, which glTF forbids as an index.
    const bool small = vertex_count <= 65535;
    NewView view;
    view.target = gltf::kElementArrayBuffer;
    view.bytes.resize(indices.size() * (small ? 2 : 4));
    for (std::size_t i = 0; i < indices.size(); ++i) {
      if (small) {
        const auto v = static_cast<std::uint16_t>(indices[i]);
        std::memcpy(view.bytes.data() + 2 * i, &v, 2);
      } else {
        std::memcpy(view.bytes.data() + 4 * i, &indices[i], 4);
      }
    }
    OrderedJson acc = OrderedJson::object();
    acc["bufferView"] = add_view(std::move(view));
    acc["componentType"] = small ? gltf::kUnsignedShort : gltf::kUnsignedInt;
    acc["count"] = indices.size();
    acc["type"] = "SCALAR";
    return add_accessor(std::move(acc));
  }

  std::map<int, OrderedJson> accessors;  // final index -> JSON
  std::map<int, NewView> views;          // final index -> data

 private:
  // Writes one component; returns the stored value (what min/max describe: the raw stored number).
  static double store(char* dst, float x, AttributeFormat f) {
    switch (f.component_type) {
      case gltf::kFloat:
        std::memcpy(dst, &x, 4);
        return x;
      case gltf::kUnsignedByte: {
        const auto v =
            static_cast<std::uint8_t>(f.normalized ? clamp_round(double(x) * 255.0, 0, 255) : clamp_round(x, 0, 255));
        std::memcpy(dst, &v, 1);
        return v;
      }
      case gltf::kByte: {
        const auto v = static_cast<std::int8_t>(f.normalized ? clamp_round(double(x) * 127.0, -127, 127)
                                                             : clamp_round(x, -128, 127));
        std::memcpy(dst, &v, 1);
        return v;
      }
      case gltf::kUnsignedShort: {
        const auto v = static_cast<std::uint16_t>(f.normalized ? clamp_round(double(x) * 65535.0, 0, 65535)
                                                               : clamp_round(x, 0, 65535));
        std::memcpy(dst, &v, 2);
        return v;
      }
      case gltf::kShort: {
        const auto v = static_cast<std::int16_t>(f.normalized ? clamp_round(double(x) * 32767.0, -32767, 32767)
                                                              : clamp_round(x, -32768, 32767));
        std::memcpy(dst, &v, 2);
        return v;
      }
      case gltf::kUnsignedInt: {
        const auto v = static_cast<std::uint32_t>(clamp_round(x, 0, 4294967295.0));
        std::memcpy(dst, &v, 4);
        return v;
      }
      default:
        return 0;
    }
  }

  static OrderedJson bounds_json(const std::vector<double>& values, int component_type) {
    OrderedJson a = OrderedJson::array();
    for (const double v : values) {
      if (component_type == gltf::kFloat) {
        a.push_back(v);
      } else {
        a.push_back(static_cast<std::int64_t>(v));
      }
    }
    return a;
  }

  int add_view(NewView view) {
    const int index = view_index_.next();
    views.emplace(index, std::move(view));
    return index;
  }
  int add_accessor(OrderedJson acc) {
    const int index = accessor_index_.next();
    accessors.emplace(index, std::move(acc));
    return index;
  }

  IndexAllocator& accessor_index_;
  IndexAllocator& view_index_;
};

// ---------------------------------------------------------------------------------------------------------------
// Mesh -> primitives.

// The faces of one material slot as triangles over the slot's own vertex list (its wedges in ascending order,
// which is the source vertex order for a primitive that was read and not changed).
struct SlotGeometry {
  std::vector<std::uint32_t> wedges;
  std::vector<std::uint32_t> indices;  // local, 3 per triangle
};

std::vector<SlotGeometry> split_by_slot(const Mesh& mesh, std::size_t mesh_index, const std::filesystem::path& path) {
  const std::size_t nf = mesh.face_count(), nw = mesh.wedge_count();
  std::size_t slots = mesh.materials.size();
  for (const std::uint32_t s : mesh.face_material) slots = std::max<std::size_t>(slots, std::size_t{s} + 1);
  if (nf > 0) slots = std::max<std::size_t>(slots, 1);
  const std::string where = "mesh " + std::to_string(mesh_index);
  if (mesh.face_offsets.size() != nf + 1 || mesh.face_offsets.back() != mesh.corner_count()) {
    throw IoError(path, where + ": face offsets do not match the corner list");
  }
  if (mesh.positions.empty() && nw > 0) throw IoError(path, where + ": wedges without vertices");
  for (const std::uint32_t v : mesh.wedge_vertex) {
    if (v >= mesh.vertex_count()) throw IoError(path, where + ": a wedge refers to a vertex past the vertex count");
  }

  std::vector<std::vector<std::uint32_t>> faces(slots);
  for (std::size_t f = 0; f < nf; ++f) {
    const std::size_t s = mesh.face_material.size() == nf ? mesh.face_material[f] : 0;
    if (mesh.face_size(f) >= 3) faces[s].push_back(static_cast<std::uint32_t>(f));
  }
  std::vector<SlotGeometry> out(slots);
  std::vector<std::uint32_t> local(nw, 0);
  for (std::size_t s = 0; s < slots; ++s) {
    SlotGeometry& g = out[s];
    for (const std::uint32_t f : faces[s]) {
      for (std::uint32_t c = mesh.face_offsets[f]; c < mesh.face_offsets[f + 1]; ++c) {
        const std::uint32_t w = mesh.corner_wedge[c];
        if (w >= nw) throw IoError(path, where + ": a corner refers to a wedge past the wedge count");
        g.wedges.push_back(w);
      }
    }
    std::sort(g.wedges.begin(), g.wedges.end());
    g.wedges.erase(std::unique(g.wedges.begin(), g.wedges.end()), g.wedges.end());
    for (std::size_t i = 0; i < g.wedges.size(); ++i) local[g.wedges[i]] = static_cast<std::uint32_t>(i);
    for (const std::uint32_t f : faces[s]) {
      // Quads along their shorter diagonal, as Mesh::triangulated() does.
      for_each_face_triangle(mesh, f, [&](std::uint32_t c0, std::uint32_t c1, std::uint32_t c2) {
        g.indices.push_back(local[mesh.corner_wedge[c0]]);
        g.indices.push_back(local[mesh.corner_wedge[c1]]);
        g.indices.push_back(local[mesh.corner_wedge[c2]]);
      });
    }
  }
  return out;
}

AttributeFormat default_format(Semantic kind) {
  if (kind == Semantic::joints) return {gltf::kUnsignedShort, false};
  return {gltf::kFloat, false};
}

void unitize(float* v) {
  const double l = std::sqrt(double(v[0]) * v[0] + double(v[1]) * v[1] + double(v[2]) * v[2]);
  if (l == 0.0 || !std::isfinite(l)) {
    v[0] = 0.0f, v[1] = 0.0f, v[2] = 1.0f;  // no direction to keep; a unit vector keeps the file valid
  } else if (std::abs(l - 1.0) > kUnitTolerance) {
    for (int i = 0; i < 3; ++i) v[i] = static_cast<float>(v[i] / l);
  }
}

class PrimitiveWriter {
 public:
  PrimitiveWriter(const Mesh& mesh, const GltfDocument* doc, std::size_t mesh_index, DataBuilder& data,
                  const std::filesystem::path& path)
      : mesh_(mesh), doc_(doc), mesh_index_(mesh_index), data_(data), path_(path) {}

  // `source`: the source primitive's JSON (nullptr for a slot that has none). Returns the new primitive JSON.
  OrderedJson write(const MaterialSlot* slot, const SlotGeometry& g, const OrderedJson* source, int material) {
    slot_ = slot;
    geometry_ = &g;
    source_ = source;
    OrderedJson prim = source ? *source : OrderedJson::object();
    const std::vector<std::string> semantics = attribute_list();
    OrderedJson attributes = OrderedJson::object();
    written_.clear();
    for (const std::string& s : semantics) {
      attributes[s] = write_attribute(s);
      written_.insert(s);
    }
    prim["attributes"] = std::move(attributes);
    prim["indices"] = data_.add_indices(g.indices, g.wedges.size());
    OrderedJson targets = write_targets();
    if (targets.empty()) {
      prim.erase("targets");
    } else {
      prim["targets"] = std::move(targets);
    }
    if (prim.contains("mode")) prim["mode"] = TINYGLTF_MODE_TRIANGLES;
    if (material >= 0) {
      prim["material"] = material;
    } else {
      prim.erase("material");
    }
    return prim;
  }

 private:
  bool flag_allows(Semantic kind, int set) const {
    const bool all = slot_ == nullptr;
    switch (kind) {
      case Semantic::normal:
        return all || slot_->has_normals;
      case Semantic::tangent:
        return all || slot_->has_tangents;
      case Semantic::texcoord:
        return all || slot_->uv_sets < 0 || set < slot_->uv_sets;
      case Semantic::color:
        return all || slot_->color_sets < 0 || set < slot_->color_sets;
      case Semantic::custom:
        return all || slot_->has_custom;
      default:
        return true;
    }
  }

  const CustomAttribute* custom(const std::string& name) const {
    for (const CustomAttribute& c : mesh_.custom) {
      if (c.name == name) return &c;
    }
    return nullptr;
  }

  bool available(const std::string& semantic) const {
    const gltf::SemanticInfo info = gltf::classify_semantic(semantic);
    if (!flag_allows(info.kind == Semantic::joints || info.kind == Semantic::weights
                         ? (info.set <= 1 ? info.kind : Semantic::custom)
                         : info.kind,
                     info.set)) {
      return false;
    }
    const auto set = static_cast<std::size_t>(info.set);
    switch (info.kind) {
      case Semantic::position:
        return true;
      case Semantic::normal:
        return mesh_.normals.size() == mesh_.wedge_count();
      case Semantic::tangent:
        return mesh_.tangents.size() == mesh_.wedge_count();
      case Semantic::texcoord:
        return set < mesh_.uvs.size() && mesh_.uvs[set].size() == mesh_.wedge_count();
      case Semantic::color:
        return set < mesh_.colors.size() && mesh_.colors[set].size() == mesh_.wedge_count();
      case Semantic::joints:
      case Semantic::weights:
        if (info.set > 1) return custom(semantic) != nullptr;
        return mesh_.skin.size() == mesh_.vertex_count();
      case Semantic::priority:
        return mesh_.priority.size() == mesh_.vertex_count();
      case Semantic::custom:
        return custom(semantic) != nullptr;
    }
    return false;
  }

  // The source primitive's attributes (in its order) that still have data, then streams the slot carries and
  // the source lacked. A slot without a source gets every stream of the mesh.
  std::vector<std::string> attribute_list() const {
    std::vector<std::string> out;
    auto add = [&](const std::string& s) {
      if (std::find(out.begin(), out.end(), s) == out.end() && available(s)) out.push_back(s);
    };
    add("POSITION");
    if (source_) {
      if (const auto it = source_->find("attributes"); it != source_->end() && it->is_object()) {
        for (const auto& [name, value] : it->items()) add(name);
      }
    }
    add("NORMAL");
    add("TANGENT");
    for (std::size_t k = 0; k < mesh_.uvs.size(); ++k) add("TEXCOORD_" + std::to_string(k));
    for (std::size_t k = 0; k < mesh_.colors.size(); ++k) add("COLOR_" + std::to_string(k));
    if (!source_) {
      // Skin, priority and custom streams belong to particular primitives; only a new primitive takes them all.
      add("JOINTS_0");
      add("WEIGHTS_0");
      if (uses_second_influence_set()) {
        add("JOINTS_1");
        add("WEIGHTS_1");
      }
      add("_LOD_PRIORITY");
      for (const CustomAttribute& c : mesh_.custom) add(c.name);
    }
    return out;
  }

  bool uses_second_influence_set() const {
    if (mesh_.skin.size() != mesh_.vertex_count()) return false;
    for (const std::uint32_t w : geometry_->wedges) {
      const SkinInfluences& s = mesh_.skin[mesh_.wedge_vertex[w]];
      for (std::size_t k = 4; k < 8; ++k) {
        if (s.weights[k] != 0.0f) return true;
      }
    }
    return false;
  }

  // The source accessor of `semantic` in the source primitive (or its morph target `target`), if any.
  const tinygltf::Accessor* source_accessor(const std::string& semantic, int target = -1) const {
    if (!source_ || !doc_) return nullptr;
    const OrderedJson* holder = nullptr;
    if (target < 0) {
      const auto it = source_->find("attributes");
      if (it != source_->end()) holder = &*it;
    } else {
      const OrderedJson& targets = json_array(*source_, "targets");
      if (static_cast<std::size_t>(target) < targets.size()) holder = &targets[static_cast<std::size_t>(target)];
    }
    if (!holder || !holder->is_object()) return nullptr;
    const int a = json_index(*holder, semantic.c_str());
    if (a < 0 || static_cast<std::size_t>(a) >= doc_->model.accessors.size()) return nullptr;
    return &doc_->model.accessors[static_cast<std::size_t>(a)];
  }

  // The source primitive's own format, unless the caller changed the mesh-wide format since loading; then the
  // mesh-wide one; then the default. Formats glTF does not allow for the semantic fall back to the default.
  AttributeFormat choose_format(const std::string& semantic, Semantic kind, int components, bool morph,
                                const tinygltf::Accessor* src) const {
    AttributeFormat f = default_format(kind);
    const auto mesh_it = morph ? mesh_.formats.end() : mesh_.formats.find(semantic);
    bool changed = false;
    if (mesh_it != mesh_.formats.end() && doc_ && mesh_index_ < doc_->loaded_formats.size()) {
      const auto& loaded = doc_->loaded_formats[mesh_index_];
      const auto it = loaded.find(semantic);
      changed = it == loaded.end() || !(it->second == mesh_it->second);
    }
    if (src && !changed) {
      f = AttributeFormat{src->componentType, src->normalized};
    } else if (mesh_it != mesh_.formats.end()) {
      f = mesh_it->second;
    }
    if (!gltf::attribute_format_allowed(kind, morph, components, f.component_type, f.normalized)) {
      f = default_format(kind);
    }
    return f;
  }

  int components_of(const std::string& semantic, Semantic kind, std::size_t set, const tinygltf::Accessor* src) const {
    switch (kind) {
      case Semantic::position:
      case Semantic::normal:
        return 3;
      case Semantic::texcoord:
        return 2;
      case Semantic::priority:
        return 1;
      case Semantic::color: {
        // RGB or RGBA as the source primitive stored it, else as the mesh-wide colour set says.
        const int stored = set < mesh_.color_components.size() ? mesh_.color_components[set] : 4;
        const int c = src ? gltf::type_components(src->type) : stored;
        return c == 3 ? 3 : 4;
      }
      case Semantic::custom:
        return custom(semantic)->components;
      default:
        return 4;  // TANGENT, JOINTS_n, WEIGHTS_n
    }
  }

  int write_attribute(const std::string& semantic) {
    const gltf::SemanticInfo info = gltf::classify_semantic(semantic);
    const Semantic kind = (info.kind == Semantic::joints || info.kind == Semantic::weights) && info.set > 1
                              ? Semantic::custom
                              : info.kind;
    const tinygltf::Accessor* src = source_accessor(semantic);
    const auto set = static_cast<std::size_t>(info.set);
    const int components = components_of(semantic, kind, set, src);
    AttributeFormat format = choose_format(semantic, kind, components, false, src);
    if (kind == Semantic::custom && !src) {
      const CustomAttribute* c = custom(semantic);
      if (gltf::attribute_format_allowed(kind, false, components, c->format.component_type, c->format.normalized)) {
        format = c->format;
      }
    }
    // Quantized normals/tangents are written back as they were read; only float ones are re-unitized (the
    // validator requires unit length, and blended vectors may have drifted).
    const bool unit = format.component_type == gltf::kFloat;

    const std::vector<std::uint32_t>& wedges = geometry_->wedges;
    const std::size_t n = wedges.size();
    std::vector<float> values;
    values.reserve(n * static_cast<std::size_t>(components));
    auto vertex_of = [&](std::size_t i) { return mesh_.wedge_vertex[wedges[i]]; };
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint32_t w = wedges[i];
      switch (kind) {
        case Semantic::position: {
          const Vec3f& p = mesh_.positions[vertex_of(i)];
          if (!(std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]))) {
            throw IoError(path_, "mesh " + std::to_string(mesh_index_) + ": vertex " + std::to_string(vertex_of(i)) +
                                     " has a NaN or infinite position");
          }
          values.insert(values.end(), {p[0], p[1], p[2]});
          break;
        }
        case Semantic::normal: {
          float v[3] = {mesh_.normals[w][0], mesh_.normals[w][1], mesh_.normals[w][2]};
          if (unit) unitize(v);
          values.insert(values.end(), {v[0], v[1], v[2]});
          break;
        }
        case Semantic::tangent: {
          const Vec4f& t = mesh_.tangents[w];
          float v[3] = {t[0], t[1], t[2]};
          if (unit) unitize(v);
          values.insert(values.end(), {v[0], v[1], v[2], t[3] < 0.0f ? -1.0f : 1.0f});
          break;
        }
        case Semantic::texcoord:
          values.insert(values.end(), {mesh_.uvs[set][w][0], mesh_.uvs[set][w][1]});
          break;
        case Semantic::color:
          // Colours are 0..1 (validator: ACCESSOR_NON_CLAMPED); in-range values pass unchanged.
          for (int k = 0; k < components; ++k) values.push_back(std::clamp(mesh_.colors[set][w][k], 0.0f, 1.0f));
          break;
        case Semantic::joints:
        case Semantic::weights: {
          const SkinInfluences& s = mesh_.skin[vertex_of(i)];
          for (std::size_t k = 4 * set; k < 4 * set + 4; ++k) {
            values.push_back(kind == Semantic::joints ? static_cast<float>(s.joints[k]) : s.weights[k]);
          }
          break;
        }
        case Semantic::priority:
          values.push_back(mesh_.priority[vertex_of(i)]);
          break;
        case Semantic::custom: {
          const CustomAttribute& c = *custom(semantic);
          const auto k = static_cast<std::size_t>(c.components);
          const float* v = c.values.data() + static_cast<std::size_t>(w) * k;
          values.insert(values.end(), v, v + k);
          break;
        }
      }
    }
    if (kind == Semantic::joints && format.component_type == gltf::kUnsignedByte &&
        std::any_of(values.begin(), values.end(), [](float j) { return j > 255.0f; })) {
      format = {gltf::kUnsignedShort, false};
    }
    return data_.add_attribute(values, components, format, kind == Semantic::position);
  }

  OrderedJson write_targets() {
    OrderedJson targets = OrderedJson::array();
    const std::vector<std::uint32_t>& wedges = geometry_->wedges;
    for (std::size_t t = 0; t < mesh_.morph_targets.size(); ++t) {
      const MorphTarget& target = mesh_.morph_targets[t];
      auto deltas_of = [&](const std::string& s) -> const std::vector<Vec3f>* {
        const std::vector<Vec3f>* d = s == "POSITION"  ? &target.position_deltas
                                      : s == "NORMAL"  ? &target.normal_deltas
                                      : s == "TANGENT" ? &target.tangent_deltas
                                                       : nullptr;
        if (!d || d->size() != mesh_.wedge_count()) return nullptr;
        // A NORMAL/TANGENT delta needs the primitive's own NORMAL/TANGENT (validator: NO_BASE_ACCESSOR).
        if (s != "POSITION" && !written_.count(s)) return nullptr;
        return d;
      };
      std::vector<std::string> keys;
      static const OrderedJson kNoTargets = OrderedJson::array();
      const OrderedJson& source_targets = source_ ? json_array(*source_, "targets") : kNoTargets;
      if (t < source_targets.size() && source_targets[t].is_object()) {
        for (const auto& [name, value] : source_targets[t].items()) {
          if (deltas_of(name)) keys.push_back(name);
        }
      } else {
        for (const char* s : {"POSITION", "NORMAL", "TANGENT"}) {
          if (deltas_of(s)) keys.emplace_back(s);
        }
      }
      OrderedJson out = OrderedJson::object();
      for (const std::string& key : keys) {
        const std::vector<Vec3f>& d = *deltas_of(key);
        std::vector<float> values;
        values.reserve(3 * wedges.size());
        for (const std::uint32_t w : wedges) values.insert(values.end(), {d[w][0], d[w][1], d[w][2]});
        const tinygltf::Accessor* src = source_accessor(key, static_cast<int>(t));
        const gltf::SemanticInfo info = gltf::classify_semantic(key);
        const AttributeFormat format = choose_format(key, info.kind, 3, true, src);
        out[key] = data_.add_attribute(values, 3, format, key == "POSITION");
      }
      if (out.empty()) {
        // Every primitive of a mesh has the same number of targets; a target needs at least one attribute.
        out["POSITION"] = data_.add_attribute(std::vector<float>(3 * wedges.size(), 0.0f), 3,
                                              AttributeFormat{gltf::kFloat, false}, true);
      }
      targets.push_back(std::move(out));
    }
    return targets;
  }

  const Mesh& mesh_;
  const GltfDocument* doc_;
  std::size_t mesh_index_;
  DataBuilder& data_;
  const std::filesystem::path& path_;
  const MaterialSlot* slot_ = nullptr;
  const SlotGeometry* geometry_ = nullptr;
  const OrderedJson* source_ = nullptr;
  std::set<std::string> written_;
};

bool weights_equal(const OrderedJson& json, const std::vector<double>& weights) {
  if (!json.is_array() || json.size() != weights.size()) return false;
  for (std::size_t i = 0; i < weights.size(); ++i) {
    if (!json[i].is_number() || json[i].get<double>() != weights[i]) return false;
  }
  return true;
}

void set_morph_weights(OrderedJson& jmesh, const Mesh& mesh) {
  const std::size_t targets = mesh.morph_targets.size();
  if (targets == 0) {
    jmesh.erase("weights");
    return;
  }
  if (mesh.morph_default_weights.size() == targets) {
    if (!weights_equal(jmesh.value("weights", OrderedJson()), mesh.morph_default_weights)) {
      jmesh["weights"] = mesh.morph_default_weights;
    }
  } else if (jmesh.contains("weights") && jmesh["weights"].size() != targets) {
    jmesh.erase("weights");
  }
}

// ---------------------------------------------------------------------------------------------------------------
// Documents.

// For an asset without a glTF source (OBJ, PLY, ...): one scene, a node and a mesh per non-empty Mesh, a
// primitive per material slot, a default material per distinct slot name.
// `json_mesh` receives, per asset mesh, the index of the glTF mesh written for it (-1 for one without faces).
// Index of the material named `name` in `materials` (the "materials" array of a document written without a glTF
// source, where a material is named after its mesh slot), appended when missing.
int material_by_name(OrderedJson& materials, const std::string& name) {
  for (std::size_t i = 0; i < materials.size(); ++i) {
    if (materials[i].value("name", std::string()) == name) return static_cast<int>(i);
  }
  // Not metallic: glTF's default metallicFactor 1 renders an untextured mesh black.
  materials.push_back({{"name", name}, {"pbrMetallicRoughness", {{"metallicFactor", 0.0}}}});
  return static_cast<int>(materials.size() - 1);
}

// The primitives of asset mesh m written without a glTF source: one per slot with faces (none when no slot has
// faces), each with the material named after its slot.
OrderedJson built_primitives(const Mesh& mesh, std::size_t m, OrderedJson& materials, DataBuilder& data,
                             const std::filesystem::path& path) {
  const std::vector<SlotGeometry> geometry = split_by_slot(mesh, m, path);
  PrimitiveWriter writer(mesh, nullptr, m, data, path);
  OrderedJson prims = OrderedJson::array();
  for (std::size_t s = 0; s < geometry.size(); ++s) {
    if (geometry[s].indices.empty()) continue;
    const MaterialSlot* slot = s < mesh.materials.size() ? &mesh.materials[s] : nullptr;
    const std::string name = slot && !slot->name.empty() ? slot->name : "default";
    prims.push_back(writer.write(slot, geometry[s], nullptr, material_by_name(materials, name)));
  }
  return prims;
}

OrderedJson build_document(const Asset& asset, DataBuilder& data, const std::filesystem::path& path,
                           std::vector<int>& json_mesh) {
  json_mesh.assign(asset.meshes.size(), -1);
  OrderedJson doc = OrderedJson::object();
  doc["asset"] = {{"version", "2.0"}, {"generator", "lodforge"}};
  OrderedJson nodes = OrderedJson::array(), meshes = OrderedJson::array(), materials = OrderedJson::array();
  for (std::size_t m = 0; m < asset.meshes.size(); ++m) {
    const Mesh& mesh = asset.meshes[m];
    OrderedJson prims = built_primitives(mesh, m, materials, data, path);
    if (prims.empty()) continue;
    json_mesh[m] = static_cast<int>(meshes.size());
    OrderedJson jmesh = OrderedJson::object();
    if (!mesh.name.empty()) jmesh["name"] = mesh.name;
    jmesh["primitives"] = std::move(prims);
    set_morph_weights(jmesh, mesh);
    if (std::any_of(mesh.morph_targets.begin(), mesh.morph_targets.end(), [](auto& t) { return !t.name.empty(); })) {
      OrderedJson names = OrderedJson::array();
      for (const MorphTarget& t : mesh.morph_targets) names.push_back(t.name);
      jmesh["extras"] = {{"targetNames", std::move(names)}};
    }
    OrderedJson node = OrderedJson::object();
    if (!mesh.name.empty()) node["name"] = mesh.name;
    node["mesh"] = meshes.size();
    nodes.push_back(std::move(node));
    meshes.push_back(std::move(jmesh));
  }
  if (meshes.empty()) throw IoError(path, "nothing to write: no mesh has faces");
  OrderedJson roots = OrderedJson::array();
  for (std::size_t i = 0; i < nodes.size(); ++i) roots.push_back(i);
  doc["scene"] = 0;
  doc["scenes"] = OrderedJson::array({{{"nodes", std::move(roots)}}});
  doc["nodes"] = std::move(nodes);
  doc["meshes"] = std::move(meshes);
  doc["materials"] = std::move(materials);
  return doc;
}

// The primitives of `mesh` written over the source mesh's primitives `old` (those of glTF mesh `m` as loaded):
// converted primitives are rewritten from the slot read from them, others are carried unchanged, and slots
// without a source primitive are appended.
OrderedJson write_primitives(const Mesh& mesh, const GltfDocument& source, std::size_t m, const OrderedJson& old,
                             const OrderedJson& doc, DataBuilder& data, const std::filesystem::path& path) {
  const std::vector<SlotGeometry> geometry = split_by_slot(mesh, m, path);
  PrimitiveWriter writer(mesh, &source, m, data, path);
  const std::vector<char>& converted = source.converted[m];
  std::vector<char> slot_done(geometry.size(), 0);
  OrderedJson prims = OrderedJson::array();
  for (std::size_t p = 0; p < old.size(); ++p) {
    if (p >= converted.size() || !converted[p]) {
      prims.push_back(old[p]);  // points, lines, primitives without positions: carried unchanged
      continue;
    }
    // The slot read from this primitive; none (removed by the caller) or no faces left drops the primitive.
    for (std::size_t s = 0; s < mesh.materials.size() && s < geometry.size(); ++s) {
      if (slot_done[s] || mesh.materials[s].source_primitive != static_cast<int>(p)) continue;
      slot_done[s] = 1;
      if (!geometry[s].indices.empty()) {
        prims.push_back(writer.write(&mesh.materials[s], geometry[s], &old[p], mesh.materials[s].gltf_material));
      }
      break;
    }
  }
  for (std::size_t s = 0; s < geometry.size(); ++s) {
    if (slot_done[s] || geometry[s].indices.empty()) continue;
    const MaterialSlot* slot = s < mesh.materials.size() ? &mesh.materials[s] : nullptr;
    const int material = slot && slot->gltf_material >= 0 &&
                                 static_cast<std::size_t>(slot->gltf_material) < json_array(doc, "materials").size()
                             ? slot->gltf_material
                             : -1;
    prims.push_back(writer.write(slot, geometry[s], nullptr, material));
  }
  if (prims.empty()) {
    throw IoError(path, "mesh " + std::to_string(m) + (mesh.name.empty() ? "" : " '" + mesh.name + "'") +
                            " has no faces left; a glTF mesh needs at least one primitive");
  }
  return prims;
}

// Replaces the converted primitives of the source document's meshes.
void patch_meshes(const Asset& asset, const GltfDocument& source, OrderedJson& doc, DataBuilder& data,
                  const std::filesystem::path& path) {
  if (asset.meshes.empty()) return;
  OrderedJson& meshes = doc["meshes"];
  for (std::size_t m = 0; m < asset.meshes.size(); ++m) {
    OrderedJson& jmesh = meshes[m];
    const OrderedJson old = json_array(jmesh, "primitives");
    jmesh["primitives"] = write_primitives(asset.meshes[m], source, m, old, doc, data, path);
    set_morph_weights(jmesh, asset.meshes[m]);
  }
}

// ---------------------------------------------------------------------------------------------------------------
// MSFT_lod: LOD meshes and the LOD nodes that show them (see lods.hpp for the layout).

// `json_mesh[m]`: the glTF mesh index showing asset mesh m (-1 when it has none, e.g. a mesh without faces).
void add_lods(const Asset& asset, const LodChain& lods, const std::vector<int>& json_mesh, OrderedJson& doc,
              DataBuilder& data, const std::filesystem::path& path) {
  const GltfDocument* source = asset.gltf.get();
  OrderedJson& meshes = doc["meshes"];
  // A new glTF mesh showing `lod` in place of asset mesh m, named with `suffix`; returns its index.
  auto add_mesh = [&](const Mesh& lod, std::size_t m, const std::string& suffix, const std::string& what) {
    const OrderedJson& base = meshes[static_cast<std::size_t>(json_mesh[m])];
    OrderedJson jmesh = OrderedJson::object();
    if (base.contains("name") && base["name"].is_string()) jmesh["name"] = base["name"].get<std::string>() + suffix;
    if (source) {
      const OrderedJson& old = json_array(json_array(source->json, "meshes")[m], "primitives");
      jmesh["primitives"] = write_primitives(lod, *source, m, old, doc, data, path);
    } else {
      jmesh["primitives"] = built_primitives(lod, m, doc["materials"], data, path);
      if (jmesh["primitives"].empty()) {
        throw IoError(path, what + " of mesh " + std::to_string(m) + " has no faces; a glTF mesh needs at least one "
                                   "primitive");
      }
    }
    if (base.contains("weights")) jmesh["weights"] = base["weights"];
    set_morph_weights(jmesh, lod);
    if (base.contains("extras") && !lod.morph_targets.empty()) jmesh["extras"] = base["extras"];
    const int index = static_cast<int>(meshes.size());
    meshes.push_back(std::move(jmesh));
    return index;
  };
  // lod_mesh[k][m]: glTF mesh index of LOD k+1 of asset mesh m.
  std::vector<std::vector<int>> lod_mesh(lods.levels.size(), std::vector<int>(asset.meshes.size(), -1));
  for (std::size_t k = 0; k < lods.levels.size(); ++k) {
    for (std::size_t m = 0; m < asset.meshes.size(); ++m) {
      if (json_mesh[m] < 0) continue;
      if (k < lods.shows_previous.size() && lods.shows_previous[k]) {
        lod_mesh[k][m] = k == 0 ? json_mesh[m] : lod_mesh[k - 1][m];
        continue;
      }
      lod_mesh[k][m] = add_mesh(lods.levels[k][m], m, "_LOD" + std::to_string(k + 1), "LOD " + std::to_string(k + 1));
    }
  }
  // separate_mesh[s][m]: glTF mesh index of separate output s of asset mesh m.
  std::vector<std::vector<int>> separate_mesh(lods.separate.size(), std::vector<int>(asset.meshes.size(), -1));
  for (std::size_t s = 0; s < lods.separate.size(); ++s) {
    for (std::size_t m = 0; m < asset.meshes.size(); ++m) {
      if (json_mesh[m] >= 0) separate_mesh[s][m] = add_mesh(lods.separate[s].meshes[m], m, lods.separate[s].suffix,
                                                            "the " + lods.separate[s].suffix.substr(1) + " LOD");
    }
  }

  std::vector<int> asset_mesh_of(meshes.size(), -1);
  for (std::size_t m = 0; m < json_mesh.size(); ++m) {
    if (json_mesh[m] >= 0) asset_mesh_of[static_cast<std::size_t>(json_mesh[m])] = static_cast<int>(m);
  }
  OrderedJson& nodes = doc["nodes"];
  const std::size_t source_nodes = nodes.size();
  // Where each source node hangs: its parent, or -1 for a root.
  std::vector<int> parent(source_nodes, -1);
  for (std::size_t p = 0; p < source_nodes; ++p) {
    if (!nodes[p].contains("children") || !nodes[p]["children"].is_array()) continue;
    for (const OrderedJson& c : nodes[p]["children"]) {
      if (c.is_number_unsigned() && c.get<std::size_t>() < source_nodes) parent[c.get<std::size_t>()] = static_cast<int>(p);
    }
  }
  for (std::size_t n = 0; n < source_nodes; ++n) {
    const int jm = json_index(nodes[n], "mesh");
    if (jm < 0 || static_cast<std::size_t>(jm) >= asset_mesh_of.size() || asset_mesh_of[jm] < 0) continue;
    const auto m = static_cast<std::size_t>(asset_mesh_of[static_cast<std::size_t>(jm)]);
    OrderedJson ids = OrderedJson::array();
    for (std::size_t k = 0; k < lods.levels.size(); ++k) {
      const Mesh& lod = lods.levels[k][m];
      const OrderedJson& node = nodes[n];
      // A LOD node replaces its node where it stands: same transform (it is nobody's child), no children.
      OrderedJson lod_node = OrderedJson::object();
      if (node.contains("name") && node["name"].is_string()) {
        lod_node["name"] = node["name"].get<std::string>() + "_LOD" + std::to_string(k + 1);
      }
      for (const auto& [key, value] : node.items()) {
        if (key == "matrix" || key == "rotation" || key == "scale" || key == "translation") lod_node[key] = value;
      }
      lod_node["mesh"] = lod_mesh[k][m];
      // Skin and morph weights only where the LOD mesh still has them (the validator rejects a skin on a mesh
      // without JOINTS_0, and weights whose count differs from the mesh's targets).
      if (node.contains("skin") && lod.skin.size() == lod.vertex_count() && !lod.skin.empty()) {
        lod_node["skin"] = node["skin"];
      }
      if (node.contains("weights") && node["weights"].is_array() &&
          node["weights"].size() == lod.morph_targets.size() && !lod.morph_targets.empty()) {
        lod_node["weights"] = node["weights"];
      }
      ids.push_back(nodes.size());
      nodes.push_back(std::move(lod_node));
    }
    OrderedJson& node = nodes[n];
    if (!node.contains("extensions") || !node["extensions"].is_object()) node["extensions"] = OrderedJson::object();
    node["extensions"]["MSFT_lod"] = {{"ids", std::move(ids)}};
    if (!node.contains("extras") || !node["extras"].is_object()) node["extras"] = OrderedJson::object();
    node["extras"]["MSFT_screencoverage"] = lods.screen_coverage;

    // Separate outputs: beside the node, so that they share its world transform, outside its MSFT_lod.
    for (std::size_t s = 0; s < lods.separate.size(); ++s) {
      const Mesh& mesh = lods.separate[s].meshes[m];
      const OrderedJson& base = nodes[n];
      OrderedJson extra = OrderedJson::object();
      if (base.contains("name") && base["name"].is_string()) {
        extra["name"] = base["name"].get<std::string>() + lods.separate[s].suffix;
      }
      for (const auto& [key, value] : base.items()) {
        if (key == "matrix" || key == "rotation" || key == "scale" || key == "translation") extra[key] = value;
      }
      extra["mesh"] = separate_mesh[s][m];
      if (base.contains("skin") && mesh.skin.size() == mesh.vertex_count() && !mesh.skin.empty()) {
        extra["skin"] = base["skin"];
      }
      if (base.contains("weights") && base["weights"].is_array() &&
          base["weights"].size() == mesh.morph_targets.size() && !mesh.morph_targets.empty()) {
        extra["weights"] = base["weights"];
      }
      extra["extras"] = {{"lodforge", {{"output", lods.separate[s].suffix.substr(1)}}}};
      const std::size_t index = nodes.size();
      nodes.push_back(std::move(extra));
      if (parent[n] >= 0) {
        nodes[static_cast<std::size_t>(parent[n])]["children"].push_back(index);
      } else if (doc.contains("scenes") && doc["scenes"].is_array()) {
        for (OrderedJson& scene : doc["scenes"]) {
          if (!scene.contains("nodes") || !scene["nodes"].is_array()) continue;
          const bool holds = std::any_of(scene["nodes"].begin(), scene["nodes"].end(), [&](const OrderedJson& r) {
            return r.is_number_unsigned() && r.get<std::size_t>() == n;
          });
          if (holds) scene["nodes"].push_back(index);
        }
      }
    }
  }

  OrderedJson& used = doc["extensionsUsed"];
  if (!used.is_array()) used = OrderedJson::array();
  if (std::find(used.begin(), used.end(), OrderedJson("MSFT_lod")) == used.end()) used.push_back("MSFT_lod");
}

void put_u32(std::string& out, std::uint32_t v) {
  out.append(reinterpret_cast<const char*>(&v), 4);
}

bool same_folder(const std::filesystem::path& a, const std::filesystem::path& b) {
  std::error_code ec1, ec2;
  const auto ca = std::filesystem::weakly_canonical(a.empty() ? "." : a, ec1);
  const auto cb = std::filesystem::weakly_canonical(b.empty() ? "." : b, ec2);
  return !ec1 && !ec2 && ca == cb;
}

// write_gltf, and save_gltf_lods when `lods` is set.
// RFC 4648 base64 with padding, for data: URIs.
std::string base64(std::string_view bytes) {
  static constexpr char kDigits[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  for (std::size_t i = 0; i < bytes.size(); i += 3) {
    const std::size_t n = std::min<std::size_t>(3, bytes.size() - i);
    std::uint32_t v = 0;
    for (std::size_t k = 0; k < 3; ++k) v = v << 8 | (k < n ? static_cast<unsigned char>(bytes[i + k]) : 0u);
    for (std::size_t k = 0; k < 4; ++k) out.push_back(k <= n ? kDigits[(v >> (18 - 6 * k)) & 63] : '=');
  }
  return out;
}

void write_gltf_document(const Asset& asset, const LodChain* lods, const std::filesystem::path& path,
                         const SaveOptions& options) {
  check_output_path(path);
  const bool glb = format_from_path(path) == Format::glb;
  const GltfDocument* source = asset.gltf.get();
  if (source && asset.meshes.size() != source->converted.size()) {
    throw IoError(path, "the asset has " + std::to_string(asset.meshes.size()) + " meshes but its glTF document has " +
                            std::to_string(source->converted.size()));
  }

  // Indices the new data may take.
  OrderedJson doc = source ? source->json : OrderedJson::object();
  const Freed freed = source ? find_freed(doc, source->converted) : Freed{};
  const std::size_t source_accessors = json_array(doc, "accessors").size();
  const std::size_t source_views = json_array(doc, "bufferViews").size();
  IndexAllocator accessor_index(source_accessors, freed.accessors);
  IndexAllocator view_index(source_views, freed.views);
  DataBuilder data(accessor_index, view_index);

  std::vector<int> json_mesh;
  if (source) {
    patch_meshes(asset, *source, doc, data, path);
    for (std::size_t m = 0; m < asset.meshes.size(); ++m) json_mesh.push_back(static_cast<int>(m));
  } else {
    doc = build_document(asset, data, path, json_mesh);
  }
  if (lods) add_lods(asset, *lods, json_mesh, doc, data, path);

  // Accessors: kept ones in place, new ones at their allocated indices, placeholders in unused holes.
  const OrderedJson old_accessors = json_array(doc, "accessors");
  OrderedJson accessors = OrderedJson::array();
  for (std::size_t a = 0; a < accessor_index.final_count(); ++a) {
    if (const auto it = data.accessors.find(static_cast<int>(a)); it != data.accessors.end()) {
      accessors.push_back(it->second);
    } else if (a < source_accessors && !freed.accessors[a]) {
      accessors.push_back(old_accessors[a]);
    } else {
      accessors.push_back({{"componentType", gltf::kFloat}, {"count", 1}, {"type", "SCALAR"}});
    }
  }

  // One buffer: kept bufferViews (same offset modulo 4 as before) and new data, in bufferView index order.
  const OrderedJson old_views = json_array(doc, "bufferViews");
  OrderedJson views = OrderedJson::array();
  std::string bin;
  auto pad_to = [&](std::size_t modulo4) {
    while (bin.size() % 4 != 0) bin.push_back('\0');
    bin.append(modulo4, '\0');
  };
  for (std::size_t v = 0; v < view_index.final_count(); ++v) {
    OrderedJson view;
    if (const auto it = data.views.find(static_cast<int>(v)); it != data.views.end()) {
      pad_to(0);
      view = OrderedJson::object();
      view["buffer"] = 0;
      view["byteOffset"] = bin.size();
      view["byteLength"] = it->second.bytes.size();
      if (it->second.stride) view["byteStride"] = it->second.stride;
      view["target"] = it->second.target;
      bin += it->second.bytes;
    } else if (v < source_views && !freed.views[v]) {
      const tinygltf::BufferView& src = source->model.bufferViews[v];
      const std::vector<unsigned char>& data_src = source->model.buffers[static_cast<std::size_t>(src.buffer)].data;
      pad_to(src.byteOffset % 4);
      view = old_views[v];
      view["buffer"] = 0;
      view["byteOffset"] = bin.size();
      bin.append(reinterpret_cast<const char*>(data_src.data()) + src.byteOffset, src.byteLength);
    } else {
      pad_to(0);
      view = {{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", 4}};
      bin.append(4, '\0');
    }
    views.push_back(std::move(view));
  }
  pad_to(0);

  auto set_or_erase = [&](const char* key, OrderedJson value) {
    if (value.empty()) {
      doc.erase(key);
    } else {
      doc[key] = std::move(value);
    }
  };
  set_or_erase("accessors", std::move(accessors));
  set_or_erase("bufferViews", std::move(views));
  const std::string bin_name = path.stem().string() + ".bin";
  const bool embed = !glb && source && source->embedded_buffers;  // an embedded source stays self-contained
  if (!bin.empty()) {
    OrderedJson buffer = OrderedJson::object();
    if (const OrderedJson& old = json_array(doc, "buffers"); !old.empty() && old[0].is_object()) {
      for (const char* key : {"name", "extras", "extensions"}) {
        if (old[0].contains(key)) buffer[key] = old[0][key];
      }
    }
    buffer["byteLength"] = bin.size();
    if (!glb) buffer["uri"] = embed ? "data:application/octet-stream;base64," + base64(bin) : gltf::uri_encode(bin_name);
    doc["buffers"] = OrderedJson::array({std::move(buffer)});
  } else {
    doc.erase("buffers");
  }

  // External images travel with the file when it goes to another folder (same relative path, same bytes).
  const std::filesystem::path out_folder = path.parent_path();
  if (source && !same_folder(out_folder, source->folder)) {
    for (std::size_t i = 0; i < source->images.size(); ++i) {
      if (source->images[i].kind != GltfImageKind::external) continue;
      const std::filesystem::path dest = out_folder / source->images[i].relative;
      std::error_code ec;
      std::filesystem::create_directories(dest.parent_path().empty() ? "." : dest.parent_path(), ec);
      if (ec) throw IoError(dest, "cannot create the folder: " + ec.message());
      const std::vector<unsigned char>& bytes = source->model.images[i].image;
      write_file_atomic(dest, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
    }
  }

  const auto handler = OrderedJson::error_handler_t::replace;
  if (!glb) {
    if (!bin.empty() && !embed) write_file_atomic(out_folder / bin_name, bin);
    std::string json = doc.dump(options.pretty_json ? 2 : -1, ' ', false, handler);
    json.push_back('\n');
    write_file_atomic(path, json);
    return;
  }
  std::string json = doc.dump(-1, ' ', false, handler);
  while (json.size() % 4 != 0) json.push_back(' ');  // the JSON chunk is padded with spaces (spec 4.4.3.1)
  const std::uint64_t total = 12 + 8 + json.size() + (bin.empty() ? 0 : 8 + bin.size());
  if (total > UINT32_MAX) throw IoError(path, "too large for a GLB (over 4 GiB); write .gltf instead");
  std::string out;
  out.reserve(static_cast<std::size_t>(total));
  out.append("glTF", 4);
  put_u32(out, 2);
  put_u32(out, static_cast<std::uint32_t>(total));
  put_u32(out, static_cast<std::uint32_t>(json.size()));
  put_u32(out, 0x4E4F534Au);  // "JSON"
  out += json;
  if (!bin.empty()) {
    put_u32(out, static_cast<std::uint32_t>(bin.size()));
    put_u32(out, 0x004E4942u);  // "BIN\0"
    out += bin;
  }
  write_file_atomic(path, out);
}

}  // namespace

void write_gltf(const Asset& asset, const std::filesystem::path& path, const SaveOptions& options) {
  write_gltf_document(asset, nullptr, path, options);
}

void save_gltf_lods(const Asset& asset, const LodChain& lods, const std::filesystem::path& path,
                    const SaveOptions& options) {
  const Format format = format_from_path(path);
  if (format != Format::gltf && format != Format::glb) {
    throw IoError(path, "MSFT_lod output needs a .gltf or .glb file name");
  }
  for (std::size_t k = 0; k < lods.levels.size(); ++k) {
    if (lods.levels[k].size() != asset.meshes.size()) {
      throw IoError(path, "LOD " + std::to_string(k + 1) + " has " + std::to_string(lods.levels[k].size()) +
                              " meshes but the asset has " + std::to_string(asset.meshes.size()));
    }
  }
  if (lods.screen_coverage.size() != lods.levels.size() + 1) {
    throw IoError(path, "MSFT_screencoverage needs " + std::to_string(lods.levels.size() + 1) +
                            " values (one per level including LOD0), got " +
                            std::to_string(lods.screen_coverage.size()));
  }
  for (const LodChain::Separate& s : lods.separate) {
    if (s.meshes.size() != asset.meshes.size() || s.suffix.size() < 2 || s.suffix[0] != '_') {
      throw IoError(path, "separate output \"" + s.suffix + "\" needs a suffix \"_name\" and one mesh per asset mesh");
    }
  }
  for (std::size_t k = 0; k < lods.screen_coverage.size(); ++k) {
    const double c = lods.screen_coverage[k];
    if (!(c >= 0.0 && c <= 1.0) || (k > 0 && c > lods.screen_coverage[k - 1])) {
      throw IoError(path, "MSFT_screencoverage must be non-increasing values in [0, 1]");
    }
  }
  write_gltf_document(asset, &lods, path, options);
}

}  // namespace lodforge::io
