// Small pictures of meshes without a GPU: an orthographic, z-buffered, flat-shaded software render with the
// polygon edges drawn darker, written as PNG. Used by the batch report (a picture per LOD) and by
// `lodforge render-wire`, which shares the views.
//
//   const PictureFrame frame = frame_mesh(source, *find_picture_view("iso"));  // one frame for every LOD
//   const std::string png = encode_png(render_picture(lod, frame, 160));
//
// Deterministic: the same mesh, frame and size give the same bytes, on any thread (one picture is one thread).
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "lodforge/core/mesh.hpp"

namespace lodforge::io {

// A fixed direction to look at an asset from. Y is up in OBJ, glTF and most game assets.
struct PictureView {
  const char* name;
  Vec3d forward;  // from the viewer into the scene
  Vec3d up;
};

// front, back, left, right, top, bottom, iso (from the front, right and above).
std::span<const PictureView> picture_views();
const PictureView* find_picture_view(std::string_view name);  // nullptr when there is none of that name

// The square of the view plane that a picture shows, and the view's basis.
struct PictureFrame {
  Vec3d right{}, up{}, forward{};
  double x0 = 0, y0 = 0, extent = 1;  // lower left corner and side, in view-plane units
};

// The square around the vertices that faces of `mesh` use, seen from `view`, with a margin of 4% each side.
// Framing every LOD of an asset with its source's frame keeps them at one scale and place.
PictureFrame frame_mesh(const Mesh& mesh, const PictureView& view);

struct Image {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgb;  // rows top to bottom, 3 bytes a pixel
};

// A size x size render of `mesh` on white: faces shaded by how much they face the viewer (faces turned away
// darker), quads grey-blue, triangles orange, n-gons green, as render-wire colours them; pixels within about
// half a pixel of a polygon edge darkened where the triangle covers at least 6 square pixels (denser edges would
// hide the shading), so coarse LODs show their wireframe. size must be in [1, 4096]. `face_colours`, one per
// face, replaces the colours by kind (the terrain picture colours patches by their triangle count).
Image render_picture(const Mesh& mesh, const PictureFrame& frame, int size,
                     std::span<const std::array<std::uint8_t, 3>> face_colours = {});

// The image as PNG bytes (8-bit RGB, no metadata): identical bytes for identical images.
std::string encode_png(const Image& image);

// A 16-bit grey PNG of width x height samples, rows top to bottom (height maps; io/heightmap.hpp reads it).
std::string encode_png_grey16(int width, int height, std::span<const std::uint16_t> samples);

}  // namespace lodforge::io
