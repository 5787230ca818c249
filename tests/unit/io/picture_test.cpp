// The report's LOD pictures: size, framing, colours, PNG bytes, and the same bytes on every thread.

#include "lodforge/io/picture.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "test_support.hpp"

namespace lodforge::io {
namespace {

const PictureView& iso() {
  const PictureView* v = find_picture_view("iso");
  EXPECT_NE(v, nullptr);
  return *v;
}

std::uint32_t big_endian(const std::string& s, std::size_t at) {
  std::uint32_t v = 0;
  for (std::size_t i = 0; i < 4; ++i) v = (v << 8) | static_cast<unsigned char>(s[at + i]);
  return v;
}

bool white(const Image& im, int x, int y) {
  const std::size_t p =
      3 * (static_cast<std::size_t>(y) * static_cast<std::size_t>(im.width) + static_cast<std::size_t>(x));
  return im.rgb[p] == 255 && im.rgb[p + 1] == 255 && im.rgb[p + 2] == 255;
}

std::size_t drawn_pixels(const Image& im) {
  std::size_t n = 0;
  for (int y = 0; y < im.height; ++y) {
    for (int x = 0; x < im.width; ++x) n += !white(im, x, y);
  }
  return n;
}

TEST(Picture, ViewsAreTheRenderWireViews) {
  std::vector<std::string> names;
  for (const PictureView& v : picture_views()) names.push_back(v.name);
  EXPECT_EQ(names, (std::vector<std::string>{"front", "back", "left", "right", "top", "bottom", "iso"}));
  EXPECT_EQ(find_picture_view("sideways"), nullptr);
}

TEST(Picture, PngIsTheSizeAskedForAndAtMost256Pixels) {
  const Mesh sphere = testing::make_uv_sphere(16, 24);
  const PictureFrame frame = frame_mesh(sphere, iso());
  for (const int size : {1, 64, 160, 256}) {
    const Image im = render_picture(sphere, frame, size);
    ASSERT_EQ(im.width, size);
    ASSERT_EQ(im.height, size);
    ASSERT_EQ(im.rgb.size(), 3u * size * size);
    const std::string png = encode_png(im);
    ASSERT_GT(png.size(), 33u);
    EXPECT_EQ(png.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
    EXPECT_EQ(png.substr(12, 4), "IHDR");
    EXPECT_EQ(big_endian(png, 16), static_cast<std::uint32_t>(size));  // width
    EXPECT_EQ(big_endian(png, 20), static_cast<std::uint32_t>(size));  // height
    EXPECT_EQ(png[24], 8);                                             // bit depth
    EXPECT_EQ(png[25], 2);                                             // RGB
  }
  EXPECT_THROW(render_picture(sphere, frame, 0), std::invalid_argument);
  EXPECT_THROW(render_picture(sphere, frame, 4097), std::invalid_argument);
  EXPECT_THROW(encode_png(Image{.width = 2, .height = 2, .rgb = std::vector<std::uint8_t>(5)}), std::invalid_argument);
}

// The frame holds the whole mesh with a margin: the border stays white, the middle is drawn.
TEST(Picture, FrameFitsTheMeshWithAMargin) {
  const Mesh sphere = testing::make_uv_sphere(16, 24, 37.0f);
  for (const PictureView& view : picture_views()) {
    const Image im = render_picture(sphere, frame_mesh(sphere, view), 100);
    for (int i = 0; i < 100; ++i) {
      EXPECT_TRUE(white(im, i, 0) && white(im, i, 99) && white(im, 0, i) && white(im, 99, i)) << view.name << " " << i;
    }
    EXPECT_FALSE(white(im, 50, 50)) << view.name;
    // A sphere filling 92% of the side covers about pi/4 of that square.
    EXPECT_NEAR(double(drawn_pixels(im)) / (92.0 * 92.0), std::acos(-1.0) / 4, 0.05) << view.name;
  }
}

// Quads grey-blue, triangles orange, as render-wire colours them; and an LOD framed by its source keeps its scale.
TEST(Picture, ColoursQuadsAndTrianglesAndKeepsTheSourceFrame) {
  const Mesh cube = testing::make_cube_quads();
  const Image quads = render_picture(cube, frame_mesh(cube, iso()), 64);
  const std::size_t mid = 3 * (32 * 64 + 32);
  EXPECT_GT(quads.rgb[mid + 2], quads.rgb[mid]);  // blue over red

  const Mesh tet = testing::make_tetrahedron();
  const PictureFrame frame = frame_mesh(tet, iso());
  const Image triangles = render_picture(tet, frame, 64);
  std::size_t orange = 0;
  for (std::size_t p = 0; p < triangles.rgb.size(); p += 3) orange += triangles.rgb[p] > triangles.rgb[p + 2] + 40;
  EXPECT_GT(orange, 200u);

  // The same tetrahedron scaled down to half, drawn in the big one's frame, covers about a quarter of the pixels.
  Mesh small = tet;
  for (Vec3f& p : small.positions) p = p * 0.5f;
  const double ratio =
      double(drawn_pixels(render_picture(small, frame, 128))) / double(drawn_pixels(render_picture(tet, frame, 128)));
  EXPECT_NEAR(ratio, 0.25, 0.05);
}

TEST(Picture, EmptyAndBrokenMeshesGiveWhitePicturesNotCrashes) {
  const Mesh empty;
  EXPECT_EQ(drawn_pixels(render_picture(empty, frame_mesh(empty, iso()), 32)), 0u);
  Mesh broken = testing::make_tetrahedron();
  broken.positions[0] = {{std::numeric_limits<float>::quiet_NaN(), 0, 0}};
  broken.corner_wedge[1] = 1000;  // a corner naming no wedge: that face is left out
  const Image im = render_picture(broken, frame_mesh(broken, iso()), 32);
  EXPECT_EQ(im.rgb.size(), 3u * 32 * 32);
  EXPECT_FALSE(encode_png(im).empty());
}

// Identical bytes every time, and from any number of threads drawing at once.
TEST(Picture, BytesAreDeterministicOnAnyThread) {
  const Mesh sphere = testing::make_uv_sphere(40, 60);
  const PictureFrame frame = frame_mesh(sphere, iso());
  const std::string reference = encode_png(render_picture(sphere, frame, 160));
  EXPECT_EQ(reference, encode_png(render_picture(sphere, frame, 160)));
  std::vector<std::string> results(8);
  std::vector<std::thread> threads;
  for (std::size_t t = 0; t < results.size(); ++t) {
    threads.emplace_back([&, t] { results[t] = encode_png(render_picture(sphere, frame, 160)); });
  }
  for (std::thread& t : threads) t.join();
  for (const std::string& r : results) EXPECT_EQ(r, reference);
}

}  // namespace
}  // namespace lodforge::io
