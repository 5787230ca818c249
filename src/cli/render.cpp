// `lodforge render-wire IN OUT.svg`: an SVG wireframe of an asset, so a reader can see edge flow (quads drawn
// as quads, triangles tinted) without a 3D viewer. Orthographic projection along one of a few fixed views;
// faces turned away from the viewer are culled (or drawn dimmed); the rest are painted far to near, so nearer
// faces hide the edges behind them (painter's algorithm: exact enough for closed, mostly convex shapes).
// `OUT.png` gives the z-buffered picture the batch report shows for each LOD (io/picture.hpp), same views.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "commands.hpp"
#include "lodforge/core/mesh.hpp"
#include "lodforge/io/asset.hpp"
#include "lodforge/io/file.hpp"
#include "lodforge/io/picture.hpp"

namespace lodforge::cli {
namespace {

using View = io::PictureView;

Vec3d normalized(const Vec3d& v) {
  const double l = length(v);
  return l > 0 ? v * (1.0 / l) : v;
}

struct Polygon {
  std::vector<std::array<double, 2>> points;
  double depth = 0;       // mean distance along the view direction (larger = farther)
  double shade = 0;       // 0..1 facing ratio
  bool back = false;
  std::uint32_t corners = 0;
  std::size_t order = 0;  // input order, for a stable sort
};

std::string render_svg(const std::vector<Mesh>& meshes, const View& view, int size, bool dim_back) {
  const Vec3d f = normalized(view.forward);
  const Vec3d right = normalized(cross(f, view.up));
  const Vec3d up = cross(right, f);
  std::vector<Polygon> polys;
  double min_x = INFINITY, min_y = INFINITY, max_x = -INFINITY, max_y = -INFINITY;
  for (const Mesh& m : meshes) {
    for (std::size_t face = 0; face < m.face_count(); ++face) {
      const std::uint32_t n = m.face_size(face), b = m.face_offsets[face];
      if (n < 3) continue;
      Polygon p;
      p.corners = n;
      p.order = polys.size();
      bool ok = true;
      for (std::uint32_t i = 0; i < n && ok; ++i) {
        const std::uint32_t w = m.corner_wedge[b + i];
        ok = w < m.wedge_count() && m.wedge_vertex[w] < m.vertex_count();
        if (!ok) break;
        const Vec3d x = to_double(m.positions[m.wedge_vertex[w]]);
        p.points.push_back({dot(x, right), dot(x, up)});
        p.depth += dot(x, f);
      }
      if (!ok) continue;
      p.depth /= n;
      const Vec3d normal = normalized(face_normal_newell(m, face));
      p.shade = -dot(normal, f);
      p.back = !(p.shade > 0);
      if (p.back && !dim_back) continue;
      for (const auto& q : p.points) {
        min_x = std::min(min_x, q[0]);
        max_x = std::max(max_x, q[0]);
        min_y = std::min(min_y, q[1]);
        max_y = std::max(max_y, q[1]);
      }
      polys.push_back(std::move(p));
    }
  }
  std::stable_sort(polys.begin(), polys.end(), [](const Polygon& a, const Polygon& b) {
    if (a.back != b.back) return a.back;  // back faces first, so front faces cover them
    return a.depth > b.depth;
  });
  const double extent = std::max({max_x - min_x, max_y - min_y, 1e-12});
  const double margin = 0.02 * size, scale = (size - 2 * margin) / extent;
  const double width = (max_x - min_x) * scale + 2 * margin, height = (max_y - min_y) * scale + 2 * margin;

  std::string svg;
  char buf[160];
  std::snprintf(buf, sizeof buf,
                "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%.0f\" height=\"%.0f\" viewBox=\"0 0 %.0f %.0f\">\n",
                width, height, width, height);
  svg += buf;
  svg += "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  // Quads grey-blue, triangles orange, n-gons green; lighter where the face looks at the viewer.
  svg += "<g stroke=\"#1a1a1a\" stroke-width=\"0.5\" stroke-linejoin=\"round\">\n";
  for (const Polygon& p : polys) {
    const double light = p.back ? 0.35 : 0.55 + 0.45 * p.shade;
    int r = 150, g = 170, b = 200;
    if (p.corners == 3) r = 240, g = 160, b = 90;
    if (p.corners > 4) r = 140, g = 200, b = 140;
    std::snprintf(buf, sizeof buf, "<polygon fill=\"#%02x%02x%02x\"%s points=\"", static_cast<int>(r * light),
                  static_cast<int>(g * light), static_cast<int>(b * light), p.back ? " stroke-opacity=\"0.25\"" : "");
    svg += buf;
    for (std::size_t i = 0; i < p.points.size(); ++i) {
      const double x = margin + (p.points[i][0] - min_x) * scale;
      const double y = margin + (max_y - p.points[i][1]) * scale;
      std::snprintf(buf, sizeof buf, "%s%.1f,%.1f", i ? " " : "", x, y);
      svg += buf;
    }
    svg += "\"/>\n";
  }
  svg += "</g>\n</svg>\n";
  return svg;
}

}  // namespace

void register_render_wire(CLI::App& app) {
  struct Args {
    std::string in, out, view = "front";
    int size = 800;
    bool dim_back = false;
  };
  auto a = std::make_shared<Args>();
  CLI::App* cmd = app.add_subcommand(
      "render-wire",
      "Write an SVG wireframe of an asset (orthographic; quads drawn as quads, triangles tinted), or with OUT.png "
      "the shaded picture the batch report shows.");
  cmd->add_option("input", a->in, "input asset")->required();
  cmd->add_option("output", a->out, "output .svg or .png (written atomically)")->required();
  cmd->add_option("--view", a->view, "front | back | left | right | top | bottom | iso")->default_val("front");
  cmd->add_option("--size", a->size, "largest side of the picture, in pixels")->default_val(800);
  cmd->add_flag("--dim-back", a->dim_back, "draw faces turned away from the viewer dimmed instead of culling them");
  cmd->callback([a] {
    const View* view = io::find_picture_view(a->view);
    if (!view) {
      std::fprintf(stderr, "error: --view: unknown view '%s' (front | back | left | right | top | bottom | iso)\n",
                   a->view.c_str());
      set_exit_code(2);
      return;
    }
    if (a->size < 16 || a->size > 16384) {
      std::fprintf(stderr, "error: --size must be in [16, 16384], got %d\n", a->size);
      set_exit_code(2);
      return;
    }
    try {
      const bool png = std::filesystem::path(a->out).extension() == ".png";
      if (png && a->size > 4096) {
        std::fprintf(stderr, "error: --size must be in [16, 4096] for a .png, got %d\n", a->size);
        set_exit_code(2);
        return;
      }
      const io::Asset asset = io::load_asset(a->in);
      std::string bytes;
      if (png) {
        const Mesh world = io::world_surface(asset);
        bytes = io::encode_png(io::render_picture(world, io::frame_mesh(world, *view), a->size));
      } else {
        bytes = render_svg(asset.meshes, *view, a->size, a->dim_back);
      }
      io::write_file_atomic(a->out, bytes);
      std::printf("wrote %s (%zu bytes)\n", a->out.c_str(), bytes.size());
    } catch (const io::IoError& e) {
      std::fprintf(stderr, "error: %s\n", e.what());
      set_exit_code(2);
    }
  });
}

}  // namespace lodforge::cli
