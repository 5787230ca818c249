// Private helpers shared by the OBJ, PLY, OFF and STL readers and writers (not installed, not public API):
// line and token iteration over the whole file held in memory, exact number parsing with std::from_chars,
// byte-order aware binary loads and stores, the checks every reader applies to untrusted counts and values,
// and the common last step that turns what a reader collected into a welded lodforge::Mesh.
//
// Why no iostreams: the corpus holds 1-4 MB text meshes and parsing must stay well above 50 MB/s; from_chars on
// a string_view is both exact (correctly rounded, so write -> read is bit-identical with to_chars) and fast.
#pragma once

#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "lodforge/core/mesh.hpp"
#include "lodforge/core/weld.hpp"
#include "lodforge/io/asset.hpp"

namespace lodforge::io::parse {

// ---------------------------------------------------------------------------------------------------------
// Errors

// Error reporting with the current line (text formats) so that a message points at the offending statement.
struct ErrorContext {
  const std::filesystem::path& path;
  std::size_t line = 0;  // 1-based; 0 = no line to report (binary data, whole-file problems)

  [[noreturn]] void fail(const std::string& problem) const {
    if (line == 0) throw IoError(path, problem);
    throw IoError(path, "line " + std::to_string(line) + ": " + problem);
  }
};

// Shortens untrusted text quoted in an error message, so that a binary file read as text cannot produce a
// multi-kilobyte or multi-line message.
inline std::string quote(std::string_view s) {
  constexpr std::size_t kMaxQuoted = 32;
  std::string out = "'";
  for (char c : s.substr(0, kMaxQuoted)) {
    const auto u = static_cast<unsigned char>(c);
    out.push_back(u >= 0x20 && u < 0x7f ? c : '?');
  }
  if (s.size() > kMaxQuoted) out += "...";
  out += "'";
  return out;
}

// The mesh model indexes with uint32 and reserves kInvalidIndex, so no count may exceed this, whatever
// LoadOptions.max_elements allows.
inline constexpr std::uint64_t kMaxIndexableElements = 0xfffffffeull;

// Rejects a declared element count before anything is allocated for it: above the caller's cap, or more records
// than the remaining bytes could hold even if every record had its smallest possible encoding.
inline void check_declared_count(const ErrorContext& ctx, std::string_view what, std::uint64_t count,
                                 std::uint64_t min_record_bytes, std::uint64_t remaining_bytes,
                                 const LoadOptions& options) {
  if (count > options.max_elements) {
    ctx.fail("header declares " + std::to_string(count) + " " + std::string(what) + ", more than the limit of " +
             std::to_string(options.max_elements) + " that one file may hold");
  }
  if (count > kMaxIndexableElements) {
    ctx.fail("header declares " + std::to_string(count) + " " + std::string(what) +
             ", more than 32-bit indices can address");
  }
  if (min_record_bytes > 0 && count > remaining_bytes / min_record_bytes) {
    ctx.fail("header declares " + std::to_string(count) + " " + std::string(what) + " but only " +
             std::to_string(remaining_bytes) + " bytes remain (at least " + std::to_string(min_record_bytes) +
             " bytes each): the file is truncated or the header is wrong");
  }
}

// Formats without a header (OBJ, ASCII STL) grow arrays as they read; this cap keeps a hostile file from
// growing them past LoadOptions.max_elements.
inline void check_element_cap(const ErrorContext& ctx, std::string_view what, std::size_t count,
                              const LoadOptions& options) {
  if (count > options.max_elements) {
    ctx.fail("more than " + std::to_string(options.max_elements) + " " + std::string(what) +
             ", the most one file may hold");
  }
  if (count > kMaxIndexableElements) ctx.fail("more " + std::string(what) + " than 32-bit indices can address");
}

inline bool is_finite(const Vec3f& p) { return std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]); }

// Non-finite positions poison every later stage (quadrics, bounds, BVH), so readers reject them outright.
inline void check_finite_position(const ErrorContext& ctx, const Vec3f& p, std::size_t vertex) {
  if (!is_finite(p)) ctx.fail("vertex " + std::to_string(vertex) + " has a non-finite coordinate");
}

// ---------------------------------------------------------------------------------------------------------
// Text iteration

inline bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; }
inline bool is_space(char c) { return is_blank(c) || c == '\n'; }

inline std::string_view trim(std::string_view s) {
  while (!s.empty() && is_blank(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_blank(s.back())) s.remove_suffix(1);
  return s;
}

// Splits off the next blank-separated token of `rest` (empty when none is left).
inline std::string_view next_token(std::string_view& rest) {
  std::size_t i = 0;
  while (i < rest.size() && is_blank(rest[i])) ++i;
  std::size_t j = i;
  while (j < rest.size() && !is_blank(rest[j])) ++j;
  const std::string_view token = rest.substr(i, j - i);
  rest.remove_prefix(j);
  return token;
}

// Iterates the lines of a text; a line excludes its "\n" or "\r\n" terminator.
class LineCursor {
 public:
  explicit LineCursor(std::string_view text) : text_(text) {}

  bool next(std::string_view& line) {
    if (pos_ >= text_.size()) return false;
    const char* begin = text_.data() + pos_;
    const std::size_t left = text_.size() - pos_;
    const void* nl = std::memchr(begin, '\n', left);
    std::size_t len = nl ? static_cast<std::size_t>(static_cast<const char*>(nl) - begin) : left;
    pos_ += nl ? len + 1 : len;
    if (len > 0 && begin[len - 1] == '\r') --len;
    ++line_;
    line = std::string_view(begin, len);
    return true;
  }
  std::size_t line_number() const { return line_; }  // of the line last returned
  std::size_t offset() const { return pos_; }        // byte offset just past the line last returned

 private:
  std::string_view text_;
  std::size_t pos_ = 0;
  std::size_t line_ = 0;
};

// Iterates whitespace-separated tokens across lines (ASCII PLY and STL bodies), keeping the line number.
class TokenCursor {
 public:
  TokenCursor(std::string_view text, std::size_t first_line) : text_(text), line_(first_line) {}

  // The next token, or empty at the end of the text.
  std::string_view next() {
    while (pos_ < text_.size() && is_space(text_[pos_])) {
      if (text_[pos_] == '\n') ++line_;
      ++pos_;
    }
    const std::size_t begin = pos_;
    while (pos_ < text_.size() && !is_space(text_[pos_])) ++pos_;
    return text_.substr(begin, pos_ - begin);
  }
  // Skips the rest of the current line (free text such as an STL solid name).
  void skip_line() {
    while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
  }
  std::size_t line_number() const { return line_; }
  std::size_t remaining() const { return text_.size() - pos_; }

 private:
  std::string_view text_;
  std::size_t pos_ = 0;
  std::size_t line_;
};

// ---------------------------------------------------------------------------------------------------------
// Numbers

// Parses a number prefix of [p, end) into `out`; returns the end of the number, or nullptr if there is none.
// Accepts a leading '+', which from_chars does not. Out-of-range values become ±inf or a (sub)normal/zero as
// strtod would give, so that the caller's finiteness check reports them rather than a vague parse error.
template <typename T>
const char* parse_real_prefix(const char* p, const char* end, T& out) {
  static_assert(std::is_floating_point_v<T>);
  if (p < end && *p == '+' && p + 1 < end && *(p + 1) != '-') ++p;
  auto [next, ec] = std::from_chars(p, end, out);
  if (ec == std::errc()) return next;
  if (ec != std::errc::result_out_of_range) return nullptr;
  // Rare path: over- or underflow. from_chars leaves `out` unset; strtod gives the IEEE result.
  const std::string copy(p, next);
  out = static_cast<T>(std::strtod(copy.c_str(), nullptr));
  return next;
}

template <typename T>
const char* parse_int_prefix(const char* p, const char* end, T& out) {
  static_assert(std::is_integral_v<T>);
  if (p < end && *p == '+' && p + 1 < end && *(p + 1) != '-') ++p;
  auto [next, ec] = std::from_chars(p, end, out);
  return ec == std::errc() ? next : nullptr;
}

// Whole-token parses: false unless all of `token` is exactly one number.
template <typename T>
bool parse_real(std::string_view token, T& out) {
  const char* end = token.data() + token.size();
  return !token.empty() && parse_real_prefix(token.data(), end, out) == end;
}

template <typename T>
bool parse_int(std::string_view token, T& out) {
  const char* end = token.data() + token.size();
  return !token.empty() && parse_int_prefix(token.data(), end, out) == end;
}

// Parses up to `max_count` blank-separated reals from `rest`; returns how many, or throws naming the bad token.
template <typename T>
int parse_reals(const ErrorContext& ctx, std::string_view rest, T* out, int max_count, std::string_view what) {
  int n = 0;
  for (std::string_view token = next_token(rest); !token.empty(); token = next_token(rest)) {
    if (n == max_count) ctx.fail("too many values in " + std::string(what) + " (at most " + std::to_string(max_count) + ")");
    if (!parse_real(token, out[n])) ctx.fail("malformed number " + quote(token) + " in " + std::string(what));
    ++n;
  }
  return n;
}

// ---------------------------------------------------------------------------------------------------------
// Binary data

template <typename T>
T byteswap_bits(T x) {
  static_assert(std::is_unsigned_v<T>);
  T r = 0;
  for (std::size_t i = 0; i < sizeof(T); ++i) {
    r = static_cast<T>((r << 8) | (x & 0xff));
    x = static_cast<T>(x >> 8);
  }
  return r;
}

template <std::size_t N> struct UintOfSize;
template <> struct UintOfSize<1> { using type = std::uint8_t; };
template <> struct UintOfSize<2> { using type = std::uint16_t; };
template <> struct UintOfSize<4> { using type = std::uint32_t; };
template <> struct UintOfSize<8> { using type = std::uint64_t; };

// Loads a T stored at `p` (no alignment needed) in the given byte order.
template <typename T>
T load(const char* p, bool big_endian) {
  using U = typename UintOfSize<sizeof(T)>::type;
  U bits;
  std::memcpy(&bits, p, sizeof(T));
  if (big_endian != (std::endian::native == std::endian::big)) bits = byteswap_bits(bits);
  return std::bit_cast<T>(bits);
}

template <typename T>
T load_le(const char* p) { return load<T>(p, false); }

template <typename T>
void append_le(std::string& out, T x) {
  using U = typename UintOfSize<sizeof(T)>::type;
  U bits = std::bit_cast<U>(x);
  if constexpr (std::endian::native == std::endian::big) bits = byteswap_bits(bits);
  char buf[sizeof(T)];
  std::memcpy(buf, &bits, sizeof(T));
  out.append(buf, sizeof(T));
}

// ---------------------------------------------------------------------------------------------------------
// Text output

// Shortest representation that reads back to the same float (std::to_chars), so write -> read is bit-exact.
inline void append_real(std::string& out, float x) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof(buf), x);
  out.append(buf, r.ptr);
}

inline void append_uint(std::string& out, std::uint64_t x) {
  char buf[24];
  const auto r = std::to_chars(buf, buf + sizeof(buf), x);
  out.append(buf, r.ptr);
}

// ---------------------------------------------------------------------------------------------------------
// Mesh assembly

// Attribute streams a writer can rely on: present and one value per wedge.
inline bool has_normals(const Mesh& m) { return m.wedge_count() > 0 && m.normals.size() == m.wedge_count(); }
inline bool has_uvs(const Mesh& m) { return m.wedge_count() > 0 && !m.uvs.empty() && m.uvs[0].size() == m.wedge_count(); }
inline bool has_colors(const Mesh& m) {
  return m.wedge_count() > 0 && !m.colors.empty() && m.colors[0].size() == m.wedge_count();
}

namespace detail {

template <typename T>
bool same_bits(const std::vector<T>& v, std::uint32_t a, std::uint32_t b) {
  return v.empty() || std::memcmp(&v[a], &v[b], sizeof(T)) == 0;
}

template <typename T>
void compact(std::vector<T>& v, const std::vector<std::uint32_t>& kept) {
  if (v.empty()) return;
  for (std::size_t i = 0; i < kept.size(); ++i) v[i] = v[kept[i]];
  v.resize(kept.size());
}

}  // namespace detail

// After welding, wedges of one vertex that carry bit-identical attributes are the same render vertex (a PLY or
// STL file repeats a position; an OBJ file repeats a `v` line): merging them keeps fake seams out of the
// simplifier. Wedges keep their first-occurrence order. Meshes with custom or morph streams are left alone
// (these readers never produce them).
inline void merge_identical_wedges(Mesh& mesh) {
  if (!mesh.custom.empty() || !mesh.morph_targets.empty()) return;
  const std::size_t nw = mesh.wedge_count(), nv = mesh.vertex_count();
  auto same = [&](std::uint32_t a, std::uint32_t b) {
    if (!detail::same_bits(mesh.normals, a, b) || !detail::same_bits(mesh.tangents, a, b)) return false;
    for (const auto& s : mesh.uvs) {
      if (!detail::same_bits(s, a, b)) return false;
    }
    for (const auto& s : mesh.colors) {
      if (!detail::same_bits(s, a, b)) return false;
    }
    return true;
  };
  // Kept wedges of each vertex form a short chain (one entry per distinct attribute tuple at that vertex).
  std::vector<std::uint32_t> head(nv, kInvalidIndex), next(nw, kInvalidIndex), remap(nw), kept;
  kept.reserve(nw);
  for (std::uint32_t w = 0; w < nw; ++w) {
    const std::uint32_t v = mesh.wedge_vertex[w];
    std::uint32_t found = kInvalidIndex;
    for (std::uint32_t k = v < nv ? head[v] : kInvalidIndex; k != kInvalidIndex; k = next[k]) {
      if (same(kept[k], w)) {
        found = k;
        break;
      }
    }
    if (found == kInvalidIndex) {
      found = static_cast<std::uint32_t>(kept.size());
      kept.push_back(w);
      if (v < nv) {
        next[found] = head[v];
        head[v] = found;
      }
    }
    remap[w] = found;
  }
  if (kept.size() == nw) return;
  for (std::uint32_t& w : mesh.corner_wedge) w = remap[w];
  detail::compact(mesh.wedge_vertex, kept);
  detail::compact(mesh.normals, kept);
  detail::compact(mesh.tangents, kept);
  for (auto& s : mesh.uvs) detail::compact(s, kept);
  for (auto& s : mesh.colors) detail::compact(s, kept);
}

// The common last step of every reader: a material slot for every face (one default slot "" at least), then
// vertices welded by position (the formats here split vertices at attribute seams or not at all; lodforge
// keeps seams as wedges of one vertex), then identical wedges merged.
inline void finish_mesh(Mesh& mesh) {
  if (mesh.materials.empty()) mesh.materials.push_back(MaterialSlot{});
  mesh.face_material.resize(mesh.face_count(), 0);
  if (weld_by_position(mesh) > 0) merge_identical_wedges(mesh);
}

inline Asset make_asset(const std::filesystem::path& path, Format format, Mesh mesh) {
  Asset asset;
  asset.source = path;
  asset.format = format;
  mesh.name = path.stem().string();
  asset.meshes.push_back(std::move(mesh));
  return asset;
}

// Writers of single-mesh formats write all meshes of an asset as one (asset.hpp): returns meshes[0] itself when
// there is one, otherwise their concatenation built in `storage`. Streams missing from some meshes are filled
// with neutral values (zero normal and UV, white colour); material slots and groups are appended per mesh.
inline const Mesh& single_mesh(const Asset& asset, Mesh& storage) {
  if (asset.meshes.size() == 1) return asset.meshes[0];
  storage = Mesh{};
  bool any_normals = false, any_uvs = false, any_colors = false, any_groups = false;
  for (const Mesh& m : asset.meshes) {
    any_normals |= has_normals(m);
    any_uvs |= has_uvs(m);
    any_colors |= has_colors(m);
    any_groups |= m.face_group.size() == m.face_count() && m.face_count() > 0;
  }
  if (any_uvs) storage.uvs.resize(1);
  if (any_colors) {
    storage.colors.resize(1);
    storage.color_components.push_back(4);
  }
  if (!asset.meshes.empty()) storage.formats = asset.meshes[0].formats;
  for (const Mesh& m : asset.meshes) {
    const auto v0 = static_cast<std::uint32_t>(storage.positions.size());
    const auto w0 = static_cast<std::uint32_t>(storage.wedge_vertex.size());
    const auto m0 = static_cast<std::uint32_t>(storage.materials.size());
    const auto g0 = static_cast<std::uint32_t>(storage.groups.size());
    storage.positions.insert(storage.positions.end(), m.positions.begin(), m.positions.end());
    for (std::uint32_t v : m.wedge_vertex) storage.wedge_vertex.push_back(v + v0);
    const std::size_t nw = m.wedge_count();
    if (any_normals) {
      if (has_normals(m)) storage.normals.insert(storage.normals.end(), m.normals.begin(), m.normals.end());
      else storage.normals.resize(storage.normals.size() + nw, Vec3f{});
    }
    if (any_uvs) {
      if (has_uvs(m)) storage.uvs[0].insert(storage.uvs[0].end(), m.uvs[0].begin(), m.uvs[0].end());
      else storage.uvs[0].resize(storage.uvs[0].size() + nw, Vec2f{});
    }
    if (any_colors) {
      if (has_colors(m)) storage.colors[0].insert(storage.colors[0].end(), m.colors[0].begin(), m.colors[0].end());
      else storage.colors[0].resize(storage.colors[0].size() + nw, Vec4f{{1, 1, 1, 1}});
    }
    const auto c0 = static_cast<std::uint32_t>(storage.corner_wedge.size());
    for (std::size_t f = 0; f < m.face_count(); ++f) storage.face_offsets.push_back(c0 + m.face_offsets[f + 1]);
    for (std::uint32_t w : m.corner_wedge) storage.corner_wedge.push_back(w + w0);
    std::vector<MaterialSlot> slots = m.materials;
    if (slots.empty()) slots.push_back(MaterialSlot{.name = m.name});
    storage.materials.insert(storage.materials.end(), slots.begin(), slots.end());
    for (std::size_t f = 0; f < m.face_count(); ++f) {
      storage.face_material.push_back(m0 + (f < m.face_material.size() ? m.face_material[f] : 0));
    }
    if (any_groups) {
      const bool own = m.face_group.size() == m.face_count() && m.face_count() > 0;
      if (own) storage.groups.insert(storage.groups.end(), m.groups.begin(), m.groups.end());
      else storage.groups.push_back(m.name);
      for (std::size_t f = 0; f < m.face_count(); ++f) storage.face_group.push_back(g0 + (own ? m.face_group[f] : 0));
    }
  }
  return storage;
}

// Output vertex order for formats that store attributes per vertex (PLY): one output vertex per wedge (wedge w
// is output vertex w), then the vertices no wedge references, kept so that positions survive a round trip.
// Returns the position index of each output vertex.
inline std::vector<std::uint32_t> per_wedge_vertex_order(const Mesh& m) {
  std::vector<std::uint32_t> order(m.wedge_vertex.begin(), m.wedge_vertex.end());
  std::vector<char> referenced(m.vertex_count(), 0);
  for (std::uint32_t v : m.wedge_vertex) referenced[v] = 1;
  for (std::uint32_t v = 0; v < m.vertex_count(); ++v) {
    if (!referenced[v]) order.push_back(v);
  }
  return order;
}

// First wedge of each vertex (kInvalidIndex for none): where formats with per-vertex attributes only (OBJ and
// OFF colours) take a seam vertex's value from.
inline std::vector<std::uint32_t> first_wedge_of_vertex(const Mesh& m) {
  std::vector<std::uint32_t> first(m.vertex_count(), kInvalidIndex);
  for (std::uint32_t w = static_cast<std::uint32_t>(m.wedge_count()); w-- > 0;) first[m.wedge_vertex[w]] = w;
  return first;
}

// A 0..1 colour channel as the byte it was read from (k / 255 -> k).
inline std::uint32_t to_unorm8(float c) {
  return static_cast<std::uint32_t>(std::lround(std::clamp(c, 0.0f, 1.0f) * 255.0f));
}

// Writers index arrays without further checks, so a mesh with indices out of range is refused up front.
inline void check_writable(const Mesh& m, const std::filesystem::path& path) {
  for (std::uint32_t v : m.wedge_vertex) {
    if (v >= m.vertex_count()) throw IoError(path, "cannot write: a wedge refers to a vertex out of range");
  }
  for (std::uint32_t w : m.corner_wedge) {
    if (w >= m.wedge_count()) throw IoError(path, "cannot write: a face corner refers to a wedge out of range");
  }
  if (m.face_offsets.empty() || m.face_offsets.front() != 0 || m.face_offsets.back() != m.corner_count()) {
    throw IoError(path, "cannot write: face offsets do not match the corners");
  }
}

}  // namespace lodforge::io::parse
