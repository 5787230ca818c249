// glTF helpers shared by the reader and the writer: component/accessor type tables, normalized-integer decoding,
// attribute semantic classification and the table of formats glTF 2.0 allows per semantic.
//
// Spec: glTF 2.0, sections 3.6.2 (accessors, "Data alignment", "Animations"/"Meshes" attribute tables) and
// 3.11 (normalized integer conversion); KHR_mesh_quantization for the widened attribute formats.
#include <algorithm>
#include <charconv>
#include <cstring>
#include <optional>

#include "gltf_internal.hpp"

namespace lodforge::io::gltf {

int component_size(int component_type) {
  switch (component_type) {
    case kByte:
    case kUnsignedByte:
      return 1;
    case kShort:
    case kUnsignedShort:
      return 2;
    case kUnsignedInt:
    case kFloat:
      return 4;
    default:
      return 0;
  }
}

const char* component_name(int component_type) {
  switch (component_type) {
    case kByte:
      return "BYTE";
    case kUnsignedByte:
      return "UNSIGNED_BYTE";
    case kShort:
      return "SHORT";
    case kUnsignedShort:
      return "UNSIGNED_SHORT";
    case 5124:
      return "INT";
    case kUnsignedInt:
      return "UNSIGNED_INT";
    case kFloat:
      return "FLOAT";
    case 5130:
      return "DOUBLE";
    default:
      return "unknown";
  }
}

int type_components(int tinygltf_type) {
  switch (tinygltf_type) {
    case TINYGLTF_TYPE_SCALAR:
      return 1;
    case TINYGLTF_TYPE_VEC2:
      return 2;
    case TINYGLTF_TYPE_VEC3:
      return 3;
    case TINYGLTF_TYPE_VEC4:
    case TINYGLTF_TYPE_MAT2:
      return 4;
    case TINYGLTF_TYPE_MAT3:
      return 9;
    case TINYGLTF_TYPE_MAT4:
      return 16;
    default:
      return 0;
  }
}

const char* type_name(int components) {
  switch (components) {
    case 1:
      return "SCALAR";
    case 2:
      return "VEC2";
    case 3:
      return "VEC3";
    case 4:
      return "VEC4";
    case 16:
      return "MAT4";
    default:
      return nullptr;
  }
}

namespace {

// Rows of a matrix type (its column length), 0 for vectors and scalars.
int matrix_rows(int tinygltf_type) {
  if (tinygltf_type == TINYGLTF_TYPE_MAT2) return 2;
  if (tinygltf_type == TINYGLTF_TYPE_MAT3) return 3;
  if (tinygltf_type == TINYGLTF_TYPE_MAT4) return 4;
  return 0;
}

// Matrix columns start on 4-byte boundaries (spec 3.6.2.4), so 1-byte MAT2 and 1-/2-byte MAT3 are padded.
std::size_t column_stride(int component_type, int rows) {
  const std::size_t bytes = static_cast<std::size_t>(component_size(component_type)) * static_cast<std::size_t>(rows);
  return (bytes + 3) & ~std::size_t{3};
}

}  // namespace

std::size_t element_size(int component_type, int tinygltf_type) {
  const int rows = matrix_rows(tinygltf_type);
  if (rows > 0) return column_stride(component_type, rows) * static_cast<std::size_t>(rows);
  return static_cast<std::size_t>(component_size(component_type)) *
         static_cast<std::size_t>(type_components(tinygltf_type));
}

std::size_t component_offset(int component_type, int tinygltf_type, int i) {
  const std::size_t size = static_cast<std::size_t>(component_size(component_type));
  const int rows = matrix_rows(tinygltf_type);
  if (rows == 0) return size * static_cast<std::size_t>(i);
  return column_stride(component_type, rows) * static_cast<std::size_t>(i / rows) +
         size * static_cast<std::size_t>(i % rows);
}

float decode_component(const unsigned char* p, int component_type, bool normalized) {
  switch (component_type) {
    case kFloat: {
      float f;
      std::memcpy(&f, p, 4);
      return f;
    }
    case kUnsignedByte: {
      const float c = static_cast<float>(p[0]);
      return normalized ? c / 255.0f : c;
    }
    case kByte: {
      const float c = static_cast<float>(static_cast<std::int8_t>(p[0]));
      return normalized ? std::max(c / 127.0f, -1.0f) : c;
    }
    case kUnsignedShort: {
      std::uint16_t v;
      std::memcpy(&v, p, 2);
      return normalized ? static_cast<float>(v) / 65535.0f : static_cast<float>(v);
    }
    case kShort: {
      std::int16_t v;
      std::memcpy(&v, p, 2);
      return normalized ? std::max(static_cast<float>(v) / 32767.0f, -1.0f) : static_cast<float>(v);
    }
    case kUnsignedInt: {
      std::uint32_t v;
      std::memcpy(&v, p, 4);
      return static_cast<float>(v);
    }
    default:
      return 0.0f;
  }
}

SemanticInfo classify_semantic(std::string_view name) {
  // "TEXCOORD_12" -> {texcoord, 12}; a malformed suffix ("TEXCOORD_x", "TEXCOORD_01") is a custom attribute.
  auto indexed = [&](std::string_view prefix, Semantic kind) -> std::optional<SemanticInfo> {
    if (name.substr(0, prefix.size()) != prefix) return std::nullopt;
    const std::string_view digits = name.substr(prefix.size());
    if (digits.empty() || digits.size() > 4 || (digits.size() > 1 && digits[0] == '0')) return std::nullopt;
    int n = 0;
    const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), n);
    if (ec != std::errc{} || end != digits.data() + digits.size()) return std::nullopt;
    return SemanticInfo{kind, n};
  };
  if (name == "POSITION") return {Semantic::position, 0};
  if (name == "NORMAL") return {Semantic::normal, 0};
  if (name == "TANGENT") return {Semantic::tangent, 0};
  if (name == "_LOD_PRIORITY") return {Semantic::priority, 0};
  if (auto s = indexed("TEXCOORD_", Semantic::texcoord)) return *s;
  if (auto s = indexed("COLOR_", Semantic::color)) return *s;
  if (auto s = indexed("JOINTS_", Semantic::joints)) return *s;
  if (auto s = indexed("WEIGHTS_", Semantic::weights)) return *s;
  return {Semantic::custom, 0};
}

bool attribute_format_allowed(Semantic kind, bool morph_target, int components, int component_type, bool normalized) {
  const int size = component_size(component_type);
  if (size == 0) return false;
  // Only 8- and 16-bit integers can be normalized (validator: ACCESSOR_NORMALIZED_INVALID).
  if (normalized && (component_type == kFloat || component_type == kUnsignedInt)) return false;
  const bool small_int = size <= 2;
  const bool is_float = component_type == kFloat;
  if (morph_target) {
    // POSITION/NORMAL/TANGENT deltas: float, or 8/16-bit integers (KHR_mesh_quantization).
    return components == 3 && (is_float || small_int);
  }
  switch (kind) {
    case Semantic::position:
    case Semantic::normal:
      return components == 3 && (is_float || small_int);
    case Semantic::tangent:
      return components == 4 && (is_float || small_int);
    case Semantic::texcoord:
      return components == 2 && (is_float || small_int);
    case Semantic::color:
      return (components == 3 || components == 4) &&
             (is_float || ((component_type == kUnsignedByte || component_type == kUnsignedShort) && normalized));
    case Semantic::joints:
      return components == 4 && (component_type == kUnsignedByte || component_type == kUnsignedShort) && !normalized;
    case Semantic::weights:
      return components == 4 &&
             (is_float || ((component_type == kUnsignedByte || component_type == kUnsignedShort) && normalized));
    case Semantic::priority:
      return components == 1 && (is_float || small_int);
    case Semantic::custom:
      return components >= 1 && (components <= 4 || components == 16);
  }
  return false;
}

std::string uri_encode(std::string_view path) {
  static const char* kHex = "0123456789ABCDEF";
  std::string out;
  for (const char ch : path) {
    const auto c = static_cast<unsigned char>(ch);
    const bool keep = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '-' ||
                      c == '_' || c == '.' || c == '~' || c == '/';
    if (keep) {
      out.push_back(ch);
    } else {
      out.push_back('%');
      out.push_back(kHex[c >> 4]);
      out.push_back(kHex[c & 15]);
    }
  }
  return out;
}

}  // namespace lodforge::io::gltf
