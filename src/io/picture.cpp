#include "lodforge/io/picture.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

// The PNG writer is stb's; STATIC keeps its symbols in this file, so no other copy in the process can clash.
#define STB_IMAGE_WRITE_IMPLEMENTATION
#define STB_IMAGE_WRITE_STATIC
#define STBI_WRITE_NO_STDIO
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpedantic"
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#pragma GCC diagnostic ignored "-Wsign-compare"
#pragma GCC diagnostic ignored "-Wunused-variable"
#include <stb_image_write.h>
#pragma GCC diagnostic pop

namespace lodforge::io {
namespace {

constexpr PictureView kViews[] = {
    {"front", {{0, 0, -1}}, {{0, 1, 0}}}, {"back", {{0, 0, 1}}, {{0, 1, 0}}},  {"left", {{1, 0, 0}}, {{0, 1, 0}}},
    {"right", {{-1, 0, 0}}, {{0, 1, 0}}}, {"top", {{0, -1, 0}}, {{0, 0, -1}}}, {"bottom", {{0, 1, 0}}, {{0, 0, 1}}},
    {"iso", {{-1, -1, -1}}, {{0, 1, 0}}},
};

constexpr double kMargin = 0.04;      // of the frame's side, each side
constexpr double kEdgePixels = 0.6;   // how close to a polygon edge a pixel centre is drawn as edge
constexpr double kEdgeMinArea = 6.0;  // square pixels: smaller triangles are drawn without their edges

Vec3d normalized(const Vec3d& v) {
  const double l = length(v);
  return l > 0 ? v * (1.0 / l) : v;
}

// The corners' vertex indices of face f, or false when a corner names a wedge or vertex that does not exist.
bool face_vertices(const Mesh& m, std::size_t f, std::vector<std::uint32_t>& out) {
  out.clear();
  const std::uint32_t b = m.face_offsets[f], n = m.face_size(f);
  for (std::uint32_t i = 0; i < n; ++i) {
    const std::uint32_t w = m.corner_wedge[b + i];
    if (w >= m.wedge_count() || m.wedge_vertex[w] >= m.vertex_count()) return false;
    out.push_back(m.wedge_vertex[w]);
  }
  return true;
}

struct Projected {
  double x, y, z;  // pixels (y down), depth along the view (larger = farther)
};

struct Raster {
  int size;
  Image& image;
  std::vector<double>& depth;

  // Fills triangle abc; `edges` bit 0: ab, bit 1: bc, bit 2: ca are polygon edges (drawn darker).
  void triangle(const Projected& a, const Projected& b, const Projected& c, unsigned edges,
                const std::array<std::uint8_t, 3>& fill, const std::array<std::uint8_t, 3>& edge) {
    const double min_x = std::min({a.x, b.x, c.x}), max_x = std::max({a.x, b.x, c.x});
    const double min_y = std::min({a.y, b.y, c.y}), max_y = std::max({a.y, b.y, c.y});
    // Pixel (px, py) has its centre at (px + 0.5, py + 0.5). Most triangles of a dense mesh hold no centre at
    // all: they cost these few comparisons (NaN coordinates fail them too).
    if (!(min_x < size && max_x > 0 && min_y < size && max_y > 0)) return;
    const double cx0 = std::ceil(min_x - 0.5), cx1 = std::floor(max_x - 0.5);
    const double cy0 = std::ceil(min_y - 0.5), cy1 = std::floor(max_y - 0.5);
    if (cx0 > cx1 || cy0 > cy1) return;
    const double area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    if (!(std::abs(area) > 1e-12) || !std::isfinite(area)) return;  // edge-on, degenerate or not finite
    const double s = area > 0 ? 1.0 : -1.0, inv = 1.0 / std::abs(area);
    if (std::abs(area) < 2 * kEdgeMinArea) edges = 0;  // edges that close together would hide the shading
    const auto len = [](const Projected& p, const Projected& q) {
      return std::sqrt((q.x - p.x) * (q.x - p.x) + (q.y - p.y) * (q.y - p.y));
    };
    const double lab = len(a, b), lbc = len(b, c), lca = len(c, a);
    const int x0 = static_cast<int>(std::max(0.0, cx0)), x1 = static_cast<int>(std::min(size - 1.0, cx1));
    const int y0 = static_cast<int>(std::max(0.0, cy0)), y1 = static_cast<int>(std::min(size - 1.0, cy1));
    for (int py = y0; py <= y1; ++py) {
      const double y = py + 0.5;
      for (int px = x0; px <= x1; ++px) {
        const double x = px + 0.5;
        const double eab = s * ((b.x - a.x) * (y - a.y) - (b.y - a.y) * (x - a.x));
        const double ebc = s * ((c.x - b.x) * (y - b.y) - (c.y - b.y) * (x - b.x));
        const double eca = s * ((a.x - c.x) * (y - c.y) - (a.y - c.y) * (x - c.x));
        if (eab < 0 || ebc < 0 || eca < 0) continue;
        const double z = (ebc * a.z + eca * b.z + eab * c.z) * inv;
        const std::size_t p =
            static_cast<std::size_t>(py) * static_cast<std::size_t>(size) + static_cast<std::size_t>(px);
        if (!(z < depth[p])) continue;
        depth[p] = z;
        const bool on_edge = ((edges & 1u) && eab < kEdgePixels * lab) || ((edges & 2u) && ebc < kEdgePixels * lbc) ||
                             ((edges & 4u) && eca < kEdgePixels * lca);
        const auto& colour = on_edge ? edge : fill;
        std::copy(colour.begin(), colour.end(), image.rgb.begin() + static_cast<std::ptrdiff_t>(3 * p));
      }
    }
  }
};

std::uint8_t channel(double v) {
  return static_cast<std::uint8_t>(std::clamp(std::lround(v), 0L, 255L));
}

}  // namespace

std::span<const PictureView> picture_views() {
  return kViews;
}

const PictureView* find_picture_view(std::string_view name) {
  for (const PictureView& v : kViews) {
    if (name == v.name) return &v;
  }
  return nullptr;
}

PictureFrame frame_mesh(const Mesh& mesh, const PictureView& view) {
  PictureFrame frame;
  frame.forward = normalized(view.forward);
  frame.right = normalized(cross(frame.forward, view.up));
  frame.up = cross(frame.right, frame.forward);
  double min_x = INFINITY, min_y = INFINITY, max_x = -INFINITY, max_y = -INFINITY;
  std::vector<std::uint32_t> corners;
  std::vector<bool> used(mesh.vertex_count(), false);
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    if (mesh.face_size(f) < 3 || !face_vertices(mesh, f, corners)) continue;
    for (const std::uint32_t v : corners) used[v] = true;
  }
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    if (!used[v]) continue;
    const Vec3d x = to_double(mesh.positions[v]);
    const double px = dot(x, frame.right), py = dot(x, frame.up);
    if (!std::isfinite(px) || !std::isfinite(py)) continue;
    min_x = std::min(min_x, px), max_x = std::max(max_x, px);
    min_y = std::min(min_y, py), max_y = std::max(max_y, py);
  }
  if (!(min_x <= max_x)) return frame;  // nothing to show: the unit square at the origin
  const double side = std::max({max_x - min_x, max_y - min_y, 1e-12});
  frame.extent = side / (1.0 - 2.0 * kMargin);
  frame.x0 = 0.5 * (min_x + max_x) - 0.5 * frame.extent;
  frame.y0 = 0.5 * (min_y + max_y) - 0.5 * frame.extent;
  return frame;
}

Image render_picture(const Mesh& mesh, const PictureFrame& frame, int size,
                     std::span<const std::array<std::uint8_t, 3>> face_colours) {
  if (size < 1 || size > 4096) throw std::invalid_argument("render_picture: size must be in [1, 4096]");
  if (!face_colours.empty() && face_colours.size() != mesh.face_count()) {
    throw std::invalid_argument("render_picture: one colour per face, or none");
  }
  Image image;
  image.width = image.height = size;
  const std::size_t pixels = static_cast<std::size_t>(size) * static_cast<std::size_t>(size);
  image.rgb.assign(3 * pixels, 255);
  std::vector<double> depth(pixels, std::numeric_limits<double>::infinity());
  const double scale = size / frame.extent;
  std::vector<Projected> projected(mesh.vertex_count());
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    const Vec3d x = to_double(mesh.positions[v]);
    projected[v] = {(dot(x, frame.right) - frame.x0) * scale, size - (dot(x, frame.up) - frame.y0) * scale,
                    dot(x, frame.forward)};
  }
  Raster raster{size, image, depth};
  std::vector<std::uint32_t> corners;
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    const std::uint32_t n = mesh.face_size(f);
    if (n < 3 || !face_vertices(mesh, f, corners)) continue;
    Vec3d normal;
    if (n == 3) {
      const Vec3d p0 = to_double(mesh.positions[corners[0]]);
      normal = cross(to_double(mesh.positions[corners[1]]) - p0, to_double(mesh.positions[corners[2]]) - p0);
    } else {
      normal = face_normal_newell(mesh, f);
    }
    const double facing = -dot(normalized(normal), frame.forward);
    const double light = facing > 0 ? 0.55 + 0.45 * facing : 0.35 + 0.2 * std::min(1.0, -facing);
    std::array<double, 3> base = {150, 170, 200};  // quads
    if (n == 3) base = {240, 160, 90};             // triangles
    if (n > 4) base = {140, 200, 140};             // n-gons
    if (!face_colours.empty()) base = {face_colours[f][0] * 1.0, face_colours[f][1] * 1.0, face_colours[f][2] * 1.0};
    std::array<std::uint8_t, 3> fill{}, edge{};
    for (int i = 0; i < 3; ++i) {
      fill[i] = channel(base[i] * light);
      edge[i] = channel(base[i] * light * 0.55);
    }
    // A fan from the first corner; only the polygon's own sides are edges, not the fan's diagonals.
    for (std::uint32_t i = 1; i + 1 < n; ++i) {
      const unsigned edges = (i == 1 ? 1u : 0u) | 2u | (i + 2 == n ? 4u : 0u);
      raster.triangle(projected[corners[0]], projected[corners[i]], projected[corners[i + 1]], edges, fill, edge);
    }
  }
  return image;
}

std::string encode_png(const Image& image) {
  if (image.width < 1 || image.height < 1 ||
      image.rgb.size() != 3 * static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.height)) {
    throw std::invalid_argument("encode_png: the image's size does not match its pixels");
  }
  std::string out;
  // Rows unfiltered: the pictures are mostly flat colour, which compresses best and fastest that way.
  static const bool configured = [] {
    stbi_write_force_png_filter = 0;
    stbi_write_png_compression_level = 5;
    return true;
  }();
  (void)configured;
  const auto append = [](void* context, void* data, int size) {
    static_cast<std::string*>(context)->append(static_cast<const char*>(data), static_cast<std::size_t>(size));
  };
  if (!stbi_write_png_to_func(append, &out, image.width, image.height, 3, image.rgb.data(), 3 * image.width)) {
    throw std::runtime_error("encode_png: the PNG encoder failed");
  }
  return out;
}

namespace {

std::uint32_t png_crc(const std::string& bytes, std::size_t begin) {
  static const auto table = [] {
    std::array<std::uint32_t, 256> t{};
    for (std::uint32_t n = 0; n < 256; ++n) {
      std::uint32_t c = n;
      for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xedb88320u ^ (c >> 1) : c >> 1;
      t[n] = c;
    }
    return t;
  }();
  std::uint32_t c = 0xffffffffu;
  for (std::size_t i = begin; i < bytes.size(); ++i)
    c = table[(c ^ static_cast<std::uint8_t>(bytes[i])) & 0xff] ^ (c >> 8);
  return c ^ 0xffffffffu;
}

void put_u32(std::string& out, std::uint32_t v) {
  for (int s = 24; s >= 0; s -= 8) out.push_back(static_cast<char>((v >> s) & 0xff));
}

void put_chunk(std::string& out, const char* type, const std::string& data) {
  put_u32(out, static_cast<std::uint32_t>(data.size()));
  const std::size_t begin = out.size();
  out.append(type, 4);
  out += data;
  put_u32(out, png_crc(out, begin));
}

}  // namespace

std::string encode_png_grey16(int width, int height, std::span<const std::uint16_t> samples) {
  if (width < 1 || height < 1 || samples.size() != static_cast<std::size_t>(width) * static_cast<std::size_t>(height)) {
    throw std::invalid_argument("encode_png_grey16: the image's size does not match its samples");
  }
  std::string rows;
  rows.reserve(static_cast<std::size_t>(height) * (1 + 2 * static_cast<std::size_t>(width)));
  for (int r = 0; r < height; ++r) {
    rows.push_back(0);  // filter: none
    for (int c = 0; c < width; ++c) {
      const std::uint16_t v =
          samples[static_cast<std::size_t>(r) * static_cast<std::size_t>(width) + static_cast<std::size_t>(c)];
      rows.push_back(static_cast<char>(v >> 8));  // PNG samples are big-endian
      rows.push_back(static_cast<char>(v & 0xff));
    }
  }
  int packed_size = 0;
  unsigned char* packed =
      stbi_zlib_compress(reinterpret_cast<unsigned char*>(rows.data()), static_cast<int>(rows.size()), &packed_size, 5);
  if (!packed) throw std::runtime_error("encode_png_grey16: the compressor failed");
  const std::string idat(reinterpret_cast<const char*>(packed), static_cast<std::size_t>(packed_size));
  STBIW_FREE(packed);
  std::string header;
  put_u32(header, static_cast<std::uint32_t>(width));
  put_u32(header, static_cast<std::uint32_t>(height));
  header += std::string{"\x10\x00\x00\x00\x00", 5};  // 16 bits, grey, deflate, no filter set, no interlace
  std::string out = "\x89PNG\r\n\x1a\n";
  put_chunk(out, "IHDR", header);
  put_chunk(out, "IDAT", idat);
  put_chunk(out, "IEND", "");
  return out;
}

}  // namespace lodforge::io
