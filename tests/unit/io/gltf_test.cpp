// glTF reader/writer: corpus round trips (meshes identical, everything else in the document unchanged, output
// deterministic) and hand-made documents for primitive modes and accessor encodings.

#include <gtest/gtest.h>
#include <tiny_gltf.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numeric>
#include <sstream>
#include <string>
#include <vector>

#include "lodforge/core/validate.hpp"
#include "lodforge/io/asset.hpp"
#include "lodforge/io/file.hpp"
#include "test_support.hpp"

namespace lodforge::io::gltf_test {
namespace {

using ::lodforge::testing::temp_dir;
using nlohmann::json;
namespace fs = std::filesystem;

// ---------------------------------------------------------------------------------------------------------------
// Helpers: tiny documents, an independent tinygltf load, model comparison.

std::string base64(std::string_view bytes) {
  static const char* k = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  std::size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const unsigned v = (unsigned char)bytes[i] << 16 | (unsigned char)bytes[i + 1] << 8 | (unsigned char)bytes[i + 2];
    out += {k[v >> 18], k[(v >> 12) & 63], k[(v >> 6) & 63], k[v & 63]};
  }
  if (i + 1 == bytes.size()) {
    const unsigned v = (unsigned char)bytes[i] << 16;
    out += {k[v >> 18], k[(v >> 12) & 63], '=', '='};
  } else if (i + 2 == bytes.size()) {
    const unsigned v = (unsigned char)bytes[i] << 16 | (unsigned char)bytes[i + 1] << 8;
    out += {k[v >> 18], k[(v >> 12) & 63], k[(v >> 6) & 63], '='};
  }
  return out;
}

template <class T>
std::string raw(const std::vector<T>& v) {
  return std::string(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
}

// A glTF document being built: JSON plus one buffer stored as a base64 data URI.
struct TinyDoc {
  json j = {{"asset", {{"version", "2.0"}}},
            {"scene", 0},
            {"scenes", {{{"nodes", {0}}}}},
            {"nodes", {{{"mesh", 0}}}},
            {"meshes", {{{"primitives", json::array()}}}}};
  std::string bin;

  int view(const std::string& bytes, int target = 0, int stride = 0) {
    while (bin.size() % 4) bin.push_back('\0');
    json v = {{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", bytes.size()}};
    if (stride) v["byteStride"] = stride;
    if (target) v["target"] = target;
    bin += bytes;
    j["bufferViews"].push_back(v);
    return static_cast<int>(j["bufferViews"].size() - 1);
  }
  int accessor(json a) {
    j["accessors"].push_back(std::move(a));
    return static_cast<int>(j["accessors"].size() - 1);
  }
  // Float VEC3 positions with exact min/max.
  int positions(const std::vector<float>& p) {
    json lo = {p[0], p[1], p[2]}, hi = lo;
    for (std::size_t i = 0; i < p.size(); ++i) {
      lo[i % 3] = std::min(lo[i % 3].get<float>(), p[i]);
      hi[i % 3] = std::max(hi[i % 3].get<float>(), p[i]);
    }
    return accessor({{"bufferView", view(raw(p), 34962)},
                     {"componentType", 5126},
                     {"count", p.size() / 3},
                     {"type", "VEC3"},
                     {"min", lo},
                     {"max", hi}});
  }
  int indices16(const std::vector<std::uint16_t>& i) {
    return accessor(
        {{"bufferView", view(raw(i), 34963)}, {"componentType", 5123}, {"count", i.size()}, {"type", "SCALAR"}});
  }
  void primitive(json p) { j["meshes"][0]["primitives"].push_back(std::move(p)); }
  std::string text() const {
    json out = j;
    out["buffers"] = {{{"byteLength", bin.size()}, {"uri", "data:application/octet-stream;base64," + base64(bin)}}};
    return out.dump();
  }
};

fs::path write_text(const fs::path& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
  return path;
}

std::string slurp(const fs::path& path) {
  return read_file(path);
}

bool keep_image_bytes(tinygltf::Image* image, const int, std::string*, std::string*, int, int,
                      const unsigned char* bytes, int size, void*) {
  image->image.assign(bytes, bytes + size);
  image->as_is = true;
  return true;
}

// An independent load (tinygltf's own file access, no lodforge code) of what the writer produced.
tinygltf::Model load_model(const fs::path& path) {
  tinygltf::TinyGLTF loader;
  loader.SetImageLoader(&keep_image_bytes, nullptr);
  tinygltf::Model model;
  std::string err, warn;
  const bool ok = path.extension() == ".glb" ? loader.LoadBinaryFromFile(&model, &err, &warn, path.string())
                                             : loader.LoadASCIIFromFile(&model, &err, &warn, path.string());
  EXPECT_TRUE(ok) << path << ": " << err;
  return model;
}

// Decoded accessor values (normalized integers as floats), sparse applied.
std::vector<double> values(const tinygltf::Model& m, int index) {
  const tinygltf::Accessor& a = m.accessors.at(static_cast<std::size_t>(index));
  const int comps = tinygltf::GetNumComponentsInType(static_cast<std::uint32_t>(a.type));
  const int size = tinygltf::GetComponentSizeInBytes(static_cast<std::uint32_t>(a.componentType));
  auto decode = [&](const unsigned char* p) -> double {
    switch (a.componentType) {
      case 5126: {
        float f;
        std::memcpy(&f, p, 4);
        return f;
      }
      case 5121:
        return a.normalized ? p[0] / 255.0 : p[0];
      case 5120:
        return a.normalized ? std::max((std::int8_t)p[0] / 127.0, -1.0) : (std::int8_t)p[0];
      case 5123: {
        std::uint16_t v;
        std::memcpy(&v, p, 2);
        return a.normalized ? v / 65535.0 : v;
      }
      case 5122: {
        std::int16_t v;
        std::memcpy(&v, p, 2);
        return a.normalized ? std::max(v / 32767.0, -1.0) : v;
      }
      case 5125: {
        std::uint32_t v;
        std::memcpy(&v, p, 4);
        return v;
      }
    }
    return NAN;
  };
  std::vector<double> out(a.count * static_cast<std::size_t>(comps), 0.0);
  if (a.bufferView >= 0) {
    const tinygltf::BufferView& v = m.bufferViews.at(static_cast<std::size_t>(a.bufferView));
    const unsigned char* base =
        m.buffers.at(static_cast<std::size_t>(v.buffer)).data.data() + v.byteOffset + a.byteOffset;
    const std::size_t stride = v.byteStride ? v.byteStride : static_cast<std::size_t>(comps * size);
    for (std::size_t i = 0; i < a.count; ++i) {
      for (int c = 0; c < comps; ++c) out[i * comps + c] = decode(base + i * stride + c * size);
    }
  }
  if (a.sparse.isSparse) {
    const auto& iv = m.bufferViews.at(static_cast<std::size_t>(a.sparse.indices.bufferView));
    const auto& vv = m.bufferViews.at(static_cast<std::size_t>(a.sparse.values.bufferView));
    const unsigned char* ip = m.buffers[iv.buffer].data.data() + iv.byteOffset + a.sparse.indices.byteOffset;
    const unsigned char* vp = m.buffers[vv.buffer].data.data() + vv.byteOffset + a.sparse.values.byteOffset;
    const int isize = tinygltf::GetComponentSizeInBytes(static_cast<std::uint32_t>(a.sparse.indices.componentType));
    for (int k = 0; k < a.sparse.count; ++k) {
      std::uint32_t at = 0;
      std::memcpy(&at, ip + k * isize, static_cast<std::size_t>(isize));
      for (int c = 0; c < comps; ++c) out[at * comps + c] = decode(vp + (k * comps + c) * size);
    }
  }
  return out;
}

// Everything but the data of converted (triangle) primitives must survive a write unchanged.
void expect_same_document(const tinygltf::Model& a, const tinygltf::Model& b, const std::string& label) {
  SCOPED_TRACE(label);
  EXPECT_EQ(a.asset.version, b.asset.version);
  EXPECT_EQ(a.asset.generator, b.asset.generator);
  EXPECT_EQ(a.asset.copyright, b.asset.copyright);
  EXPECT_TRUE(a.asset.extras == b.asset.extras);
  EXPECT_EQ(a.extensionsUsed, b.extensionsUsed);
  EXPECT_EQ(a.extensionsRequired, b.extensionsRequired);
  EXPECT_TRUE(a.extensions == b.extensions);
  EXPECT_TRUE(a.extras == b.extras);
  EXPECT_EQ(a.defaultScene, b.defaultScene);
  EXPECT_TRUE(a.scenes == b.scenes);
  EXPECT_TRUE(a.nodes == b.nodes);
  EXPECT_TRUE(a.materials == b.materials);
  EXPECT_TRUE(a.textures == b.textures);
  EXPECT_TRUE(a.samplers == b.samplers);
  EXPECT_TRUE(a.cameras == b.cameras);
  EXPECT_TRUE(a.lights == b.lights);
  ASSERT_EQ(a.skins.size(), b.skins.size());
  for (std::size_t s = 0; s < a.skins.size(); ++s) {
    EXPECT_EQ(a.skins[s].name, b.skins[s].name);
    EXPECT_EQ(a.skins[s].joints, b.skins[s].joints);
    EXPECT_EQ(a.skins[s].skeleton, b.skins[s].skeleton);
    EXPECT_TRUE(a.skins[s].extras == b.skins[s].extras);
    ASSERT_EQ(a.skins[s].inverseBindMatrices >= 0, b.skins[s].inverseBindMatrices >= 0);
    if (a.skins[s].inverseBindMatrices >= 0) {
      EXPECT_EQ(values(a, a.skins[s].inverseBindMatrices), values(b, b.skins[s].inverseBindMatrices)) << "skin " << s;
    }
  }
  ASSERT_EQ(a.animations.size(), b.animations.size());
  for (std::size_t n = 0; n < a.animations.size(); ++n) {
    const auto &x = a.animations[n], &y = b.animations[n];
    EXPECT_EQ(x.name, y.name);
    EXPECT_TRUE(x.channels == y.channels);
    ASSERT_EQ(x.samplers.size(), y.samplers.size());
    for (std::size_t s = 0; s < x.samplers.size(); ++s) {
      EXPECT_EQ(x.samplers[s].interpolation, y.samplers[s].interpolation);
      EXPECT_EQ(values(a, x.samplers[s].input), values(b, y.samplers[s].input))
          << "animation " << n << " sampler " << s;
      EXPECT_EQ(values(a, x.samplers[s].output), values(b, y.samplers[s].output))
          << "animation " << n << " sampler " << s;
    }
  }
  ASSERT_EQ(a.images.size(), b.images.size());
  for (std::size_t i = 0; i < a.images.size(); ++i) {
    EXPECT_EQ(a.images[i].name, b.images[i].name);
    EXPECT_EQ(a.images[i].uri, b.images[i].uri);
    EXPECT_EQ(a.images[i].mimeType, b.images[i].mimeType);
    EXPECT_EQ(a.images[i].bufferView >= 0, b.images[i].bufferView >= 0);
    EXPECT_TRUE(a.images[i].image == b.images[i].image) << "image " << i << " bytes differ";
    EXPECT_TRUE(a.images[i].extensions == b.images[i].extensions);
  }
  ASSERT_EQ(a.meshes.size(), b.meshes.size());
  for (std::size_t m = 0; m < a.meshes.size(); ++m) {
    const auto &x = a.meshes[m], &y = b.meshes[m];
    EXPECT_EQ(x.name, y.name);
    EXPECT_EQ(x.weights, y.weights);
    EXPECT_TRUE(x.extras == y.extras);
    EXPECT_TRUE(x.extensions == y.extensions);
    ASSERT_EQ(x.primitives.size(), y.primitives.size()) << "mesh " << m;
    for (std::size_t p = 0; p < x.primitives.size(); ++p) {
      const auto &u = x.primitives[p], &v = y.primitives[p];
      EXPECT_EQ(u.material, v.material);
      EXPECT_TRUE(u.extras == v.extras);
      EXPECT_TRUE(u.extensions == v.extensions);
      std::vector<std::string> ku, kv;
      for (const auto& [k, i] : u.attributes) ku.push_back(k);
      for (const auto& [k, i] : v.attributes) kv.push_back(k);
      EXPECT_EQ(ku, kv) << "mesh " << m << " primitive " << p;
      ASSERT_EQ(u.targets.size(), v.targets.size());
      for (std::size_t t = 0; t < u.targets.size(); ++t) EXPECT_EQ(u.targets[t].size(), v.targets[t].size());
      const int mode = u.mode < 0 ? 4 : u.mode;
      if (mode < 4) {  // carried unchanged: same data
        EXPECT_EQ(u.mode, v.mode);
        for (const auto& [k, i] : u.attributes) EXPECT_EQ(values(a, i), values(b, v.attributes.at(k))) << k;
        if (u.indices >= 0) {
          EXPECT_EQ(values(a, u.indices), values(b, v.indices));
        }
      } else {
        // Converted primitives are compared through lodforge meshes; for their accessors the format stays.
        for (const auto& [k, i] : u.attributes) {
          const auto& sa = a.accessors[static_cast<std::size_t>(i)];
          const auto& sb = b.accessors[static_cast<std::size_t>(v.attributes.at(k))];
          EXPECT_EQ(sa.componentType, sb.componentType) << k;
          EXPECT_EQ(sa.normalized, sb.normalized) << k;
          EXPECT_EQ(sa.type, sb.type) << k;
        }
      }
    }
  }
}

std::string first_mesh_difference(const Mesh& a, const Mesh& b) {
  auto check = [](const char* what, const auto& x, const auto& y) -> std::string {
    if (x.size() != y.size())
      return std::string(what) + " sizes " + std::to_string(x.size()) + " vs " + std::to_string(y.size());
    for (std::size_t i = 0; i < x.size(); ++i) {
      if (!(x[i] == y[i])) return std::string(what) + " differ at " + std::to_string(i);
    }
    return {};
  };
  for (const std::string& d :
       {check("positions", a.positions, b.positions), check("skin", a.skin, b.skin),
        check("priority", a.priority, b.priority), check("wedge_vertex", a.wedge_vertex, b.wedge_vertex),
        check("normals", a.normals, b.normals), check("tangents", a.tangents, b.tangents), check("uvs", a.uvs, b.uvs),
        check("colors", a.colors, b.colors), check("color_components", a.color_components, b.color_components),
        check("custom", a.custom, b.custom), check("morph_targets", a.morph_targets, b.morph_targets),
        check("morph_default_weights", a.morph_default_weights, b.morph_default_weights),
        check("face_offsets", a.face_offsets, b.face_offsets), check("corner_wedge", a.corner_wedge, b.corner_wedge),
        check("face_material", a.face_material, b.face_material), check("materials", a.materials, b.materials)}) {
    if (!d.empty()) return d;
  }
  if (a.formats != b.formats) return "formats differ";
  if (a.name != b.name) return "names differ";
  return a == b ? "" : "meshes differ";
}

std::size_t total_triangles(const Asset& a) {
  std::size_t n = 0;
  for (const Mesh& m : a.meshes) n += m.triangle_count();
  return n;
}

// ---------------------------------------------------------------------------------------------------------------
// Corpus round trips.

struct CorpusCase {
  const char* file;
  std::size_t meshes, primitives, triangles, stored_vertices;  // from ../shared/corpus/MANIFEST.md
  bool shared_vertex_buffers;   // primitives share POSITION accessors: wedges < stored vertices
  std::size_t welded_vertices;  // single mesh without skin/morphs: MANIFEST "welded V", else 0
};

const CorpusCase kCorpus[] = {
    {"gltf/Duck.glb", 1, 1, 4212, 2399, false, 2108},
    {"gltf/CesiumMilkTruck.glb", 2, 4, 2856, 2978, false, 0},
    {"gltf/MorphStressTest.gltf", 1, 2, 2412, 1528, false, 0},
    {"gltf/armor-knight.gltf", 2, 2, 19217, 15843, false, 0},
    {"gltf/Avocado/Avocado.gltf", 1, 1, 682, 406, false, 363},
    {"gltf/AnisotropyBarnLamp/AnisotropyBarnLamp.gltf", 3, 3, 10203, 7712, false, 0},
    {"gltf/FlightHelmet/FlightHelmet.gltf", 5, 5, 94722, 60366, false, 0},
    {"skinned/CesiumMan.glb", 1, 1, 4672, 3273, false, 0},
    {"skinned/Fox.glb", 1, 1, 576, 1728, false, 0},
    {"skinned/RiggedFigure.glb", 1, 1, 256, 370, false, 0},
    {"skinned/RiggedSimple.glb", 1, 1, 188, 160, false, 0},
    {"hardsurface/kenney_alien.glb", 6, 18, 292, 637, false, 0},
    {"hardsurface/kenney_cakeBirthday.glb", 6, 42, 1332, 14616, true, 0},
    {"hardsurface/kenney_craft_speederD/craft_speederD.gltf", 1, 4, 322, 2032, true, 0},
};

class GltfCorpus : public ::testing::TestWithParam<CorpusCase> {};

std::string case_name(const ::testing::TestParamInfo<CorpusCase>& info) {
  return ::lodforge::testing::test_name_of(info.param.file);
}

TEST_P(GltfCorpus, LoadsWithManifestCounts) {
  const CorpusCase& c = GetParam();
  LODFORGE_REQUIRE_CORPUS(src, c.file);
  const Asset a = load_asset(src);
  ASSERT_EQ(a.meshes.size(), c.meshes);
  std::size_t slots = 0, wedges = 0;
  for (const Mesh& m : a.meshes) {
    slots += m.materials.size();
    wedges += m.wedge_count();
    const ValidationReport r = validate(m);
    EXPECT_EQ(r.out_of_range_indices, 0u);
    EXPECT_EQ(r.attribute_size_errors, 0u);
    EXPECT_EQ(r.nonfinite_positions, 0u);
  }
  EXPECT_EQ(slots, c.primitives);
  EXPECT_EQ(total_triangles(a), c.triangles);
  if (c.shared_vertex_buffers) {
    EXPECT_LT(wedges, c.stored_vertices);
  } else {
    EXPECT_EQ(wedges, c.stored_vertices);
  }
  if (c.welded_vertices) {
    EXPECT_EQ(a.meshes[0].vertex_count(), c.welded_vertices);
  }
}

TEST_P(GltfCorpus, RoundTripKeepsMeshesAndDocument) {
  const CorpusCase& c = GetParam();
  LODFORGE_REQUIRE_CORPUS(src, c.file);
  const Asset a = load_asset(src);
  const fs::path dir = temp_dir("gltf_roundtrip_" + fs::path(c.file).stem().string());
  const tinygltf::Model source = load_model(src);
  for (const char* name : {"out.glb", "out.gltf"}) {
    SCOPED_TRACE(name);
    const fs::path out = dir / name;
    save_asset(a, out);
    const Asset b = load_asset(out);
    ASSERT_EQ(b.meshes.size(), a.meshes.size());
    for (std::size_t m = 0; m < a.meshes.size(); ++m) {
      EXPECT_EQ(first_mesh_difference(a.meshes[m], b.meshes[m]), "") << "mesh " << m;
    }
    expect_same_document(source, load_model(out), std::string(c.file) + " -> " + name);
  }
}

TEST_P(GltfCorpus, OutputIsDeterministic) {
  const CorpusCase& c = GetParam();
  LODFORGE_REQUIRE_CORPUS(src, c.file);
  const fs::path dir = temp_dir("gltf_determinism_" + fs::path(c.file).stem().string());
  save_asset(load_asset(src), dir / "a.glb");
  save_asset(load_asset(src), dir / "b.glb");
  EXPECT_TRUE(slurp(dir / "a.glb") == slurp(dir / "b.glb"));
  save_asset(load_asset(src), dir / "a.gltf");
  save_asset(load_asset(src), dir / "b.gltf");
  if (fs::exists(dir / "a.bin")) {
    EXPECT_TRUE(slurp(dir / "a.bin") == slurp(dir / "b.bin"));
  } else {  // an embedded source is written embedded: the buffer is inside the .gltf
    EXPECT_FALSE(fs::exists(dir / "b.bin"));
    EXPECT_TRUE(slurp(dir / "a.gltf") == slurp(dir / "b.gltf"));
  }
  // A written file is a fixed point: reading and writing it again gives the same bytes.
  save_asset(load_asset(dir / "a.glb"), dir / "c.glb");
  EXPECT_TRUE(slurp(dir / "a.glb") == slurp(dir / "c.glb"));
}

INSTANTIATE_TEST_SUITE_P(Corpus, GltfCorpus, ::testing::ValuesIn(kCorpus), case_name);

// ---------------------------------------------------------------------------------------------------------------
// Hand-made documents.

const std::vector<float> kQuad = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0};  // strip order: 0 1 2 3

std::vector<std::array<std::uint32_t, 3>> triangles_by_vertex_position(const Mesh& m) {
  // Faces as triples of source vertex numbers (recovered from x + 2y of the test positions).
  std::vector<std::array<std::uint32_t, 3>> out;
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    std::array<std::uint32_t, 3> t{};
    for (int k = 0; k < 3; ++k) {
      const Vec3f& p = m.positions[m.corner_vertex(m.face_offsets[f] + static_cast<std::uint32_t>(k))];
      t[static_cast<std::size_t>(k)] = static_cast<std::uint32_t>(p[0] + 2 * p[1] + 4 * p[2]);
    }
    out.push_back(t);
  }
  return out;
}

bool has_warning(const Asset& a, const std::string& needle) {
  for (const std::string& w : a.warnings) {
    if (w.find(needle) != std::string::npos) return true;
  }
  return false;
}

TEST(GltfModes, TriangleStripIsConvertedWithAWarning) {
  TinyDoc d;
  d.primitive({{"attributes", {{"POSITION", d.positions(kQuad)}}}, {"mode", 5}});
  const fs::path dir = temp_dir("gltf_strip");
  const Asset a = load_asset(write_text(dir / "strip.gltf", d.text()));
  ASSERT_EQ(a.meshes.size(), 1u);
  // p_i = {v_i, v_{i+(1+i%2)}, v_{i+(2-i%2)}}: (0,1,2), (1,3,2).
  using T = std::array<std::uint32_t, 3>;
  EXPECT_EQ(triangles_by_vertex_position(a.meshes[0]), (std::vector<T>{{0, 1, 2}, {1, 3, 2}}));
  EXPECT_TRUE(has_warning(a, "triangle strip converted to 2 triangles"));
  save_asset(a, dir / "out.glb");
  const tinygltf::Model out = load_model(dir / "out.glb");
  ASSERT_EQ(out.meshes[0].primitives.size(), 1u);
  EXPECT_EQ(out.meshes[0].primitives[0].mode, 4);
}

TEST(GltfModes, TriangleFanIsConvertedWithAWarning) {
  TinyDoc d;
  // Fan around vertex 0 over vertices 1, 3, 2 (a quad), non-indexed and then indexed.
  const std::vector<float> fan = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};  // numbers 0 1 3 2
  d.primitive({{"attributes", {{"POSITION", d.positions(fan)}}}, {"mode", 6}});
  const fs::path dir = temp_dir("gltf_fan");
  const Asset a = load_asset(write_text(dir / "fan.gltf", d.text()));
  // p_i = {v_{i+1}, v_{i+2}, v_0}.
  using T = std::array<std::uint32_t, 3>;
  EXPECT_EQ(triangles_by_vertex_position(a.meshes[0]), (std::vector<T>{{1, 3, 0}, {3, 2, 0}}));
  EXPECT_TRUE(has_warning(a, "triangle fan converted to 2 triangles"));
}

TEST(GltfWrite, QuadsAreWrittenAlongTheirShorterDiagonal) {
  // Quad 0 1 7 2 (numbers x + 2y + 4z): the diagonal 1-2 (length^2 2) is shorter than 0-7 (length^2 3), so the
  // triangles are (1, 7, 2) and (1, 2, 0), not the fan (0, 1, 7), (0, 7, 2) from the first corner.
  Asset a;
  a.format = Format::obj;
  Mesh& m = a.meshes.emplace_back();
  const Vec3f corners[4] = {{{0, 0, 0}}, {{1, 0, 0}}, {{1, 1, 1}}, {{0, 1, 0}}};
  std::uint32_t w[4];
  for (int i = 0; i < 4; ++i) w[i] = m.add_vertex_with_wedge(corners[i]);
  m.add_face(w, 4);
  m.materials.push_back({});
  const fs::path dir = temp_dir("gltf_quad_diagonal");
  save_asset(a, dir / "quad.glb");
  const Asset back = load_asset(dir / "quad.glb");
  ASSERT_EQ(back.meshes.size(), 1u);
  using T = std::array<std::uint32_t, 3>;
  EXPECT_EQ(triangles_by_vertex_position(back.meshes[0]), (std::vector<T>{{1, 7, 2}, {1, 2, 0}}));
}

TEST(GltfModes, PointsPrimitiveIsCarriedUnchanged) {
  TinyDoc d;
  d.primitive({{"attributes", {{"POSITION", d.positions(kQuad)}}}, {"indices", d.indices16({0, 1, 2, 2, 1, 3})}});
  const std::vector<float> points = {5, 5, 5, 6, 6, 6};
  d.primitive({{"attributes", {{"POSITION", d.positions(points)}}}, {"mode", 0}});
  const fs::path dir = temp_dir("gltf_points");
  const fs::path src = write_text(dir / "points.gltf", d.text());
  const Asset a = load_asset(src);
  ASSERT_EQ(a.meshes[0].materials.size(), 1u);
  EXPECT_EQ(a.meshes[0].face_count(), 2u);
  EXPECT_TRUE(has_warning(a, "points primitive carried unchanged"));
  for (const char* name : {"out.glb", "out.gltf"}) {
    save_asset(a, dir / name);
    const tinygltf::Model out = load_model(dir / name);
    ASSERT_EQ(out.meshes[0].primitives.size(), 2u);
    const auto& p = out.meshes[0].primitives[1];
    EXPECT_EQ(p.mode, 0);
    EXPECT_EQ(values(out, p.attributes.at("POSITION")), (std::vector<double>{5, 5, 5, 6, 6, 6}));
    expect_same_document(load_model(src), out, name);
  }
}

TEST(GltfModes, AccessorSharedWithACarriedPrimitiveIsKept) {
  TinyDoc d;
  const int pos = d.positions(kQuad);
  d.primitive({{"attributes", {{"POSITION", pos}}}, {"indices", d.indices16({0, 1, 2, 2, 1, 3})}});
  d.primitive({{"attributes", {{"POSITION", pos}}}, {"mode", 0}});
  const fs::path dir = temp_dir("gltf_shared_points");
  const fs::path src = write_text(dir / "shared.gltf", d.text());
  const Asset a = load_asset(src);
  save_asset(a, dir / "out.glb");
  const tinygltf::Model out = load_model(dir / "out.glb");
  ASSERT_EQ(out.meshes[0].primitives.size(), 2u);
  EXPECT_EQ(out.meshes[0].primitives[1].attributes.at("POSITION"), pos);  // kept in place
  EXPECT_EQ(values(out, pos), (std::vector<double>(kQuad.begin(), kQuad.end())));
  expect_same_document(load_model(src), out, "shared");
  EXPECT_EQ(first_mesh_difference(a.meshes[0], load_asset(dir / "out.glb").meshes[0]), "");
}

TEST(GltfAccessors, IndexComponentTypesAllLoad) {
  for (const int ct : {5121, 5123, 5125}) {
    SCOPED_TRACE(ct);
    TinyDoc d;
    std::string bytes;
    for (const std::uint32_t i : {0u, 1u, 2u, 2u, 1u, 3u})
      bytes.append(reinterpret_cast<const char*>(&i), ct == 5121 ? 1 : ct == 5123 ? 2 : 4);
    const int idx =
        d.accessor({{"bufferView", d.view(bytes, 34963)}, {"componentType", ct}, {"count", 6}, {"type", "SCALAR"}});
    d.primitive({{"attributes", {{"POSITION", d.positions(kQuad)}}}, {"indices", idx}});
    const fs::path dir = temp_dir("gltf_indices");
    const Asset a = load_asset(write_text(dir / "i.gltf", d.text()));
    using T = std::array<std::uint32_t, 3>;
    EXPECT_EQ(triangles_by_vertex_position(a.meshes[0]), (std::vector<T>{{0, 1, 2}, {2, 1, 3}}));
  }
}

TEST(GltfAccessors, InterleavedBufferViewLoads) {
  TinyDoc d;
  // POSITION (12 bytes) + NORMAL (12) + TEXCOORD_0 (8) per vertex, stride 32.
  std::vector<float> inter;
  for (int v = 0; v < 4; ++v) {
    inter.insert(inter.end(),
                 {kQuad[3 * v], kQuad[3 * v + 1], kQuad[3 * v + 2], 0, 0, 1, float(v) / 4, 1 - float(v) / 4});
  }
  const int view = d.view(raw(inter), 34962, 32);
  const int pos = d.accessor({{"bufferView", view},
                              {"componentType", 5126},
                              {"count", 4},
                              {"type", "VEC3"},
                              {"min", {0, 0, 0}},
                              {"max", {1, 1, 0}}});
  const int nrm =
      d.accessor({{"bufferView", view}, {"byteOffset", 12}, {"componentType", 5126}, {"count", 4}, {"type", "VEC3"}});
  const int uv =
      d.accessor({{"bufferView", view}, {"byteOffset", 24}, {"componentType", 5126}, {"count", 4}, {"type", "VEC2"}});
  d.primitive({{"attributes", {{"POSITION", pos}, {"NORMAL", nrm}, {"TEXCOORD_0", uv}}},
               {"indices", d.indices16({0, 1, 2, 2, 1, 3})}});
  const fs::path dir = temp_dir("gltf_interleaved");
  const Asset a = load_asset(write_text(dir / "i.gltf", d.text()));
  const Mesh& m = a.meshes[0];
  ASSERT_EQ(m.wedge_count(), 4u);
  for (std::uint32_t w = 0; w < 4; ++w) {
    EXPECT_EQ(m.positions[m.wedge_vertex[w]], (Vec3f{{kQuad[3 * w], kQuad[3 * w + 1], kQuad[3 * w + 2]}}));
    EXPECT_EQ(m.normals[w], (Vec3f{{0, 0, 1}}));
    EXPECT_EQ(m.uvs[0][w], (Vec2f{{float(w) / 4, 1 - float(w) / 4}}));
  }
  // Written back tightly packed, then read back identical.
  save_asset(a, dir / "out.glb");
  EXPECT_EQ(first_mesh_difference(m, load_asset(dir / "out.glb").meshes[0]), "");
}

TEST(GltfAccessors, SparseAccessorsLoad) {
  TinyDoc d;
  // Base positions with vertex 3 moved by a sparse substitution, and a bufferView-less sparse UV set.
  std::vector<float> base = kQuad;
  base[9] = 9;  // replaced below by 1
  const int view = d.view(raw(base), 34962);
  const int idx_view = d.view(raw(std::vector<std::uint16_t>{3, 0}));
  const int val_view = d.view(raw(std::vector<float>{1, 1, 0}));
  const int pos = d.accessor({{"bufferView", view},
                              {"componentType", 5126},
                              {"count", 4},
                              {"type", "VEC3"},
                              {"min", {0, 0, 0}},
                              {"max", {1, 1, 0}},
                              {"sparse",
                               {{"count", 1},
                                {"indices", {{"bufferView", idx_view}, {"componentType", 5123}}},
                                {"values", {{"bufferView", val_view}}}}}});
  const int uv_idx = d.view(raw(std::vector<std::uint8_t>{1, 2, 0, 0}));
  const int uv_val = d.view(raw(std::vector<float>{0.5f, 0.25f, 0.75f, 1}));
  const int uv = d.accessor({{"componentType", 5126},
                             {"count", 4},
                             {"type", "VEC2"},
                             {"sparse",
                              {{"count", 2},
                               {"indices", {{"bufferView", uv_idx}, {"componentType", 5121}}},
                               {"values", {{"bufferView", uv_val}}}}}});
  d.primitive({{"attributes", {{"POSITION", pos}, {"TEXCOORD_0", uv}}}, {"indices", d.indices16({0, 1, 2, 2, 1, 3})}});
  const fs::path dir = temp_dir("gltf_sparse");
  const Asset a = load_asset(write_text(dir / "s.gltf", d.text()));
  const Mesh& m = a.meshes[0];
  EXPECT_EQ(m.positions[m.wedge_vertex[3]], (Vec3f{{1, 1, 0}}));
  EXPECT_EQ(m.uvs[0][0], (Vec2f{{0, 0}}));
  EXPECT_EQ(m.uvs[0][1], (Vec2f{{0.5f, 0.25f}}));
  EXPECT_EQ(m.uvs[0][2], (Vec2f{{0.75f, 1}}));
  EXPECT_EQ(m.uvs[0][3], (Vec2f{{0, 0}}));
}

TEST(GltfAccessors, NormalizedIntegersUseTheSpecFormulasAndRoundTrip) {
  TinyDoc d;
  // Tightly packed (the reader accepts it; the writer pads each element to 4 bytes as the spec asks).
  const std::vector<std::uint8_t> uv8 = {0, 255, 128, 64, 255, 0, 1, 254};                                // VEC2 x 4
  const std::vector<std::uint8_t> rgba = {255, 0, 0, 255, 0, 255, 0, 128, 0, 0, 255, 0, 10, 20, 30, 40};  // VEC4 x 4
  const std::vector<std::int8_t> uv1 = {-128, -127, 127, 0, 64, -64, 1, -1};                              // VEC2 x 4
  const int t0 = d.accessor({{"bufferView", d.view(raw(uv8), 34962)},
                             {"componentType", 5121},
                             {"normalized", true},
                             {"count", 4},
                             {"type", "VEC2"}});
  const int c0 = d.accessor({{"bufferView", d.view(raw(rgba), 34962)},
                             {"componentType", 5121},
                             {"normalized", true},
                             {"count", 4},
                             {"type", "VEC4"}});
  const int t1 = d.accessor({{"bufferView", d.view(raw(uv1), 34962)},
                             {"componentType", 5120},
                             {"normalized", true},
                             {"count", 4},
                             {"type", "VEC2"}});
  d.primitive(
      {{"attributes", {{"POSITION", d.positions(kQuad)}, {"TEXCOORD_0", t0}, {"COLOR_0", c0}, {"TEXCOORD_1", t1}}},
       {"indices", d.indices16({0, 1, 2, 2, 1, 3})}});
  const fs::path dir = temp_dir("gltf_normalized");
  const Asset a = load_asset(write_text(dir / "n.gltf", d.text()));
  const Mesh& m = a.meshes[0];
  // Every stored value is a multiple of 1/255 (uint8 c / 255) or max(c / 127, -1) (int8).
  EXPECT_EQ(m.uvs[0][1], (Vec2f{{128 / 255.0f, 64 / 255.0f}}));
  EXPECT_EQ(m.colors[0][3], (Vec4f{{10 / 255.0f, 20 / 255.0f, 30 / 255.0f, 40 / 255.0f}}));
  EXPECT_EQ(m.color_components[0], 4);
  EXPECT_EQ(m.uvs[1][0], (Vec2f{{-1.0f, -1.0f}}));
  EXPECT_EQ(m.uvs[1][1], (Vec2f{{1.0f, 0.0f}}));
  EXPECT_EQ(m.uvs[1][2], (Vec2f{{64 / 127.0f, -64 / 127.0f}}));
  EXPECT_EQ(m.formats.at("TEXCOORD_0"), (AttributeFormat{5121, true}));
  EXPECT_EQ(m.formats.at("COLOR_0"), (AttributeFormat{5121, true}));
  EXPECT_EQ(m.formats.at("TEXCOORD_1"), (AttributeFormat{5120, true}));

  // Written back in the same formats with the same stored integers (int8 -128 comes back as -127 = -1.0).
  save_asset(a, dir / "out.glb");
  const tinygltf::Model out = load_model(dir / "out.glb");
  const auto& prim = out.meshes[0].primitives[0];
  const auto& ca = out.accessors[static_cast<std::size_t>(prim.attributes.at("COLOR_0"))];
  EXPECT_EQ(ca.componentType, 5121);
  EXPECT_TRUE(ca.normalized);
  std::vector<double> expect;
  for (const std::uint8_t c : rgba) expect.push_back(c / 255.0);
  EXPECT_EQ(values(out, prim.attributes.at("COLOR_0")), expect);
  expect.clear();
  for (const std::uint8_t c : uv8) expect.push_back(c / 255.0);
  EXPECT_EQ(values(out, prim.attributes.at("TEXCOORD_0")), expect);
  EXPECT_EQ(first_mesh_difference(m, load_asset(dir / "out.glb").meshes[0]), "");
}

TEST(GltfAccessors, RgbColoursKeepThreeComponents) {
  TinyDoc d;
  const std::vector<float> rgb = {1, 0, 0, 0, 1, 0, 0, 0, 1, 0.5f, 0.5f, 0.5f};
  const int c0 =
      d.accessor({{"bufferView", d.view(raw(rgb), 34962)}, {"componentType", 5126}, {"count", 4}, {"type", "VEC3"}});
  d.primitive({{"attributes", {{"POSITION", d.positions(kQuad)}, {"COLOR_0", c0}}},
               {"indices", d.indices16({0, 1, 2, 2, 1, 3})}});
  const fs::path dir = temp_dir("gltf_rgb");
  const Asset a = load_asset(write_text(dir / "c.gltf", d.text()));
  EXPECT_EQ(a.meshes[0].color_components[0], 3);
  EXPECT_EQ(a.meshes[0].colors[0][1], (Vec4f{{0, 1, 0, 1}}));
  save_asset(a, dir / "out.gltf");
  const tinygltf::Model out = load_model(dir / "out.gltf");
  EXPECT_EQ(out.accessors[static_cast<std::size_t>(out.meshes[0].primitives[0].attributes.at("COLOR_0"))].type,
            TINYGLTF_TYPE_VEC3);
}

TEST(GltfAccessors, SkinCustomAndPriorityStreamsRoundTrip) {
  TinyDoc d;
  const std::vector<std::uint8_t> joints = {0, 1, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0, 0, 2, 1, 0};
  const std::vector<float> weights = {0.5f, 0.5f, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 0.25f, 0.5f, 0.25f, 0};
  const std::vector<float> batch = {7, 7, 8, 9};
  const std::vector<std::uint16_t> prio = {0, 65535, 32768, 65535};
  const int j0 =
      d.accessor({{"bufferView", d.view(raw(joints), 34962)}, {"componentType", 5121}, {"count", 4}, {"type", "VEC4"}});
  const int w0 = d.accessor(
      {{"bufferView", d.view(raw(weights), 34962)}, {"componentType", 5126}, {"count", 4}, {"type", "VEC4"}});
  const int b0 = d.accessor(
      {{"bufferView", d.view(raw(batch), 34962)}, {"componentType", 5126}, {"count", 4}, {"type", "SCALAR"}});
  const int p0 = d.accessor({{"bufferView", d.view(raw(prio), 34962)},
                             {"componentType", 5123},
                             {"normalized", true},
                             {"count", 4},
                             {"type", "SCALAR"}});
  d.primitive({{"attributes",
                {{"POSITION", d.positions(kQuad)},
                 {"JOINTS_0", j0},
                 {"WEIGHTS_0", w0},
                 {"_BATCHID", b0},
                 {"_LOD_PRIORITY", p0}}},
               {"indices", d.indices16({0, 1, 2, 2, 1, 3})}});
  const fs::path dir = temp_dir("gltf_streams");
  const Asset a = load_asset(write_text(dir / "s.gltf", d.text()));
  const Mesh& m = a.meshes[0];
  ASSERT_EQ(m.skin.size(), 4u);
  EXPECT_EQ(m.skin[m.wedge_vertex[3]].joints[1], 2);
  EXPECT_EQ(m.skin[m.wedge_vertex[3]].weights[1], 0.5f);
  ASSERT_EQ(m.custom.size(), 1u);
  EXPECT_EQ(m.custom[0].name, "_BATCHID");
  EXPECT_EQ(m.custom[0].values, batch);
  EXPECT_EQ(m.priority[m.wedge_vertex[1]], 1.0f);
  save_asset(a, dir / "out.glb");
  const tinygltf::Model out = load_model(dir / "out.glb");
  const auto& prim = out.meshes[0].primitives[0];
  EXPECT_EQ(out.accessors[static_cast<std::size_t>(prim.attributes.at("JOINTS_0"))].componentType, 5121);
  EXPECT_EQ(out.accessors[static_cast<std::size_t>(prim.attributes.at("_LOD_PRIORITY"))].componentType, 5123);
  EXPECT_EQ(first_mesh_difference(m, load_asset(dir / "out.glb").meshes[0]), "");
}

TEST(GltfAccessors, QuantizedAttributesRoundTripExactly) {
  TinyDoc d;
  d.j["extensionsUsed"] = {"KHR_mesh_quantization"};
  d.j["extensionsRequired"] = {"KHR_mesh_quantization"};
  // int16 positions (padded to 8 bytes), int8 normalized normals (padded to 4), uint16 normalized UVs.
  const std::vector<std::int16_t> pos = {0, 0, 0, 0, 100, 0, 0, 0, 0, 100, 0, 0, 100, 100, 0, 0};
  const std::vector<std::int8_t> nrm = {0, 0, 127, 0, 0, 90, 90, 0, 90, 0, 90, 0, -127, 0, 0, 0};
  const std::vector<std::uint16_t> uv = {0, 0, 65535, 0, 0, 65535, 12345, 54321};
  const int p = d.accessor({{"bufferView", d.view(raw(pos), 34962, 8)},
                            {"componentType", 5122},
                            {"count", 4},
                            {"type", "VEC3"},
                            {"min", {0, 0, 0}},
                            {"max", {100, 100, 0}}});
  const int n = d.accessor({{"bufferView", d.view(raw(nrm), 34962, 4)},
                            {"componentType", 5120},
                            {"normalized", true},
                            {"count", 4},
                            {"type", "VEC3"}});
  const int t = d.accessor({{"bufferView", d.view(raw(uv), 34962)},
                            {"componentType", 5123},
                            {"normalized", true},
                            {"count", 4},
                            {"type", "VEC2"}});
  d.primitive({{"attributes", {{"POSITION", p}, {"NORMAL", n}, {"TEXCOORD_0", t}}},
               {"indices", d.indices16({0, 1, 2, 2, 1, 3})}});
  const fs::path dir = temp_dir("gltf_quantized");
  const fs::path src = write_text(dir / "q.gltf", d.text());
  const Asset a = load_asset(src);
  EXPECT_EQ(a.meshes[0].positions[a.meshes[0].wedge_vertex[3]], (Vec3f{{100, 100, 0}}));
  EXPECT_EQ(a.meshes[0].normals[1], (Vec3f{{0, 90 / 127.0f, 90 / 127.0f}}));
  save_asset(a, dir / "out.glb");
  const tinygltf::Model out = load_model(dir / "out.glb");
  const auto& prim = out.meshes[0].primitives[0];
  EXPECT_EQ(values(out, prim.attributes.at("NORMAL")), values(load_model(src), n));
  EXPECT_EQ(values(out, prim.attributes.at("POSITION")), values(load_model(src), p));
  EXPECT_EQ(out.accessors[static_cast<std::size_t>(prim.attributes.at("POSITION"))].maxValues,
            (std::vector<double>{100, 100, 0}));
  expect_same_document(load_model(src), out, "quantized");
  EXPECT_EQ(first_mesh_difference(a.meshes[0], load_asset(dir / "out.glb").meshes[0]), "");
}

TEST(GltfImages, ExternalImagesAreCopiedDataUrisAndBufferViewsKept) {
  const fs::path dir = temp_dir("gltf_images");
  fs::create_directories(dir / "src" / "tex");
  const std::string png = std::string("\x89PNG\r\n\x1a\n", 8) + "not really a png";
  std::ofstream(dir / "src" / "tex" / "a b.png", std::ios::binary) << png;
  TinyDoc d;
  d.primitive({{"attributes", {{"POSITION", d.positions(kQuad)}}}, {"indices", d.indices16({0, 1, 2, 2, 1, 3})}});
  const int image_view = d.view("JPEGBYTES!");
  d.j["images"] = {{{"uri", "tex/a%20b.png"}},
                   {{"uri", "data:image/png;base64," + base64("data-uri image")}},
                   {{"bufferView", image_view}, {"mimeType", "image/jpeg"}},
                   {{"uri", "missing.png"}}};
  const fs::path src = write_text(dir / "src" / "scene.gltf", d.text());
  const Asset a = load_asset(src);
  EXPECT_TRUE(has_warning(a, "missing.png"));
  for (const char* name : {"out/o.gltf", "out2/o.glb"}) {
    fs::create_directories((dir / name).parent_path());
    save_asset(a, dir / name);
    EXPECT_EQ(slurp((dir / name).parent_path() / "tex" / "a b.png"), png);
    const tinygltf::Model out = load_model(dir / name);
    ASSERT_EQ(out.images.size(), 4u);
    EXPECT_EQ(out.images[0].uri, "tex/a%20b.png");
    EXPECT_EQ(std::string(out.images[1].image.begin(), out.images[1].image.end()), "data-uri image");
    EXPECT_EQ(std::string(out.images[2].image.begin(), out.images[2].image.end()), "JPEGBYTES!");
    EXPECT_EQ(out.images[3].uri, "missing.png");
    expect_same_document(load_model(src), out, name);
  }
}

TEST(GltfWrite, MeshWithoutSourceDocumentBuildsAMinimalDocument) {
  Asset a;
  a.format = Format::obj;
  a.meshes.push_back(testing::make_cube_quads());
  a.meshes.back().name = "cube";
  Mesh tet = testing::make_tetrahedron();
  tet.materials[0].name = "stone";
  a.meshes.push_back(tet);
  const fs::path dir = temp_dir("gltf_minimal");
  for (const char* name : {"m.gltf", "m.glb"}) {
    save_asset(a, dir / name);
    const Asset b = load_asset(dir / name);
    ASSERT_EQ(b.meshes.size(), 2u);
    EXPECT_EQ(b.meshes[0].triangle_count(), 12u);
    EXPECT_EQ(b.meshes[0].vertex_count(), 8u);
    EXPECT_EQ(b.meshes[0].name, "cube");
    EXPECT_EQ(b.meshes[1].triangle_count(), 4u);
    EXPECT_EQ(b.meshes[1].materials[0].name, "stone");
    const tinygltf::Model out = load_model(dir / name);
    EXPECT_EQ(out.nodes.size(), 2u);
    EXPECT_EQ(out.materials.size(), 2u);
    EXPECT_EQ(out.scenes.size(), 1u);
  }
}

TEST(GltfWrite, EditedMeshReplacesOnlyItsPrimitiveData) {
  LODFORGE_REQUIRE_CORPUS(src, "gltf/CesiumMilkTruck.glb");
  Asset a = load_asset(src);
  // Keep every other face of mesh 0 (a stand-in for simplification).
  Mesh& m = a.meshes[0];
  Mesh kept = m;
  kept.face_offsets = {0};
  kept.corner_wedge.clear();
  kept.face_material.clear();
  for (std::size_t f = 0; f < m.face_count(); f += 2) {
    kept.add_face(m.corner_wedge.data() + m.face_offsets[f], m.face_size(f), m.face_material[f]);
  }
  const std::size_t faces = kept.face_count();
  m = kept;
  const fs::path dir = temp_dir("gltf_edited");
  save_asset(a, dir / "t.glb");
  const Asset b = load_asset(dir / "t.glb");
  EXPECT_EQ(b.meshes[0].face_count(), faces);
  EXPECT_EQ(first_mesh_difference(a.meshes[1], b.meshes[1]), "");
  expect_same_document(load_model(src), load_model(dir / "t.glb"), "edited");
  EXPECT_LT(fs::file_size(dir / "t.glb"), fs::file_size(src));
}

TEST(GltfWrite, DroppedAndAddedSlotsBecomePrimitives) {
  LODFORGE_REQUIRE_CORPUS(src, "gltf/CesiumMilkTruck.glb");
  Asset a = load_asset(src);
  Mesh& m = a.meshes[0];
  ASSERT_EQ(m.materials.size(), 3u);
  // Slot 1's faces move to a new slot without a source primitive; slot 2 loses all its faces.
  MaterialSlot added = m.materials[1];
  added.source_primitive = -1;
  m.materials.push_back(added);
  Mesh edited = m;
  edited.face_offsets = {0};
  edited.corner_wedge.clear();
  edited.face_material.clear();
  std::size_t moved = 0;
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    std::uint32_t slot = m.face_material[f];
    if (slot == 2) continue;
    if (slot == 1) {
      slot = 3;
      ++moved;
    }
    edited.add_face(m.corner_wedge.data() + m.face_offsets[f], m.face_size(f), slot);
  }
  m = edited;
  const fs::path dir = temp_dir("gltf_slots");
  save_asset(a, dir / "s.glb");
  const tinygltf::Model out = load_model(dir / "s.glb");
  ASSERT_EQ(out.meshes[0].primitives.size(), 2u);
  EXPECT_EQ(out.meshes[0].primitives[0].material, 0);
  EXPECT_EQ(out.meshes[0].primitives[1].material, 1);
  const Asset b = load_asset(dir / "s.glb");
  EXPECT_EQ(b.meshes[0].face_count(), m.face_count());
  EXPECT_EQ(b.meshes[0].materials[1].source_primitive, 1);
  std::size_t in_second = 0;
  for (const std::uint32_t s : b.meshes[0].face_material) in_second += s == 1;
  EXPECT_EQ(in_second, moved);
  EXPECT_EQ(first_mesh_difference(a.meshes[1], b.meshes[1]), "");
  // Animations and the embedded texture are untouched.
  const tinygltf::Model source = load_model(src);
  ASSERT_EQ(out.animations.size(), source.animations.size());
  EXPECT_EQ(values(out, out.animations[0].samplers[0].output), values(source, source.animations[0].samplers[0].output));
  EXPECT_TRUE(out.images[0].image == source.images[0].image);
}

TEST(GltfWrite, MeshWithNoFacesLeftIsAnError) {
  LODFORGE_REQUIRE_CORPUS(src, "skinned/RiggedSimple.glb");
  Asset a = load_asset(src);
  a.meshes[0].face_offsets = {0};
  a.meshes[0].corner_wedge.clear();
  a.meshes[0].face_material.clear();
  const fs::path dir = temp_dir("gltf_no_faces");
  EXPECT_THROW(save_asset(a, dir / "x.glb"), IoError);
  EXPECT_FALSE(fs::exists(dir / "x.glb"));
}

}  // namespace
}  // namespace lodforge::io::gltf_test
