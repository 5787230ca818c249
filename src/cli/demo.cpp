// `lodforge demo OUT_DIR`: writes the small sample library (samples/library in the repository is its output).
// Every asset is generated here, so the repository carries no third-party meshes.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <numbers>
#include <string>

#include "commands.hpp"
#include "lodforge/core/mesh.hpp"
#include "lodforge/core/weld.hpp"
#include "lodforge/io/asset.hpp"

namespace lodforge::cli {
namespace {

constexpr double kPi = std::numbers::pi;

// Quad torus with a UV chart that has seams along u = 0 and v = 0 (wedges carry the seam).
Mesh make_torus(int nu, int nv, double major, double minor) {
  Mesh m;
  m.uvs.resize(1);
  for (int j = 0; j <= nv; ++j) {
    for (int i = 0; i <= nu; ++i) {
      const double u = 2 * kPi * (i % nu) / nu, v = 2 * kPi * (j % nv) / nv;
      const double r = major + minor * std::cos(v);
      m.add_vertex_with_wedge({{static_cast<float>(r * std::cos(u)), static_cast<float>(minor * std::sin(v)),
                                static_cast<float>(r * std::sin(u))}});
      m.uvs[0].push_back({{static_cast<float>(i) / nu, static_cast<float>(j) / nv}});
    }
  }
  auto id = [&](int i, int j) { return static_cast<std::uint32_t>(j * (nu + 1) + i); };
  for (int j = 0; j < nv; ++j) {
    for (int i = 0; i < nu; ++i) m.add_face({id(i, j), id(i, j + 1), id(i + 1, j + 1), id(i + 1, j)});
  }
  m.materials.push_back(MaterialSlot{.name = "ring"});
  weld_by_position(m);
  m.name = "torus";
  return m;
}

// A sphere with a bumpy surface (sum of sines), triangles, one wedge per vertex.
Mesh make_bumpy_sphere(int rings, int segments) {
  Mesh m;
  m.add_vertex_with_wedge({{0, 1, 0}});
  for (int r = 1; r < rings; ++r) {
    const double t = kPi * r / rings;
    for (int s = 0; s < segments; ++s) {
      const double p = 2 * kPi * s / segments;
      const double rad = 1.0 + 0.05 * std::sin(5 * t) * std::cos(7 * p);
      m.add_vertex_with_wedge({{static_cast<float>(rad * std::sin(t) * std::cos(p)),
                                static_cast<float>(rad * std::cos(t)),
                                static_cast<float>(rad * std::sin(t) * std::sin(p))}});
    }
  }
  const std::uint32_t south = m.add_vertex_with_wedge({{0, -1, 0}});
  auto ring = [&](int r, int s) { return static_cast<std::uint32_t>(1 + (r - 1) * segments + s % segments); };
  for (int s = 0; s < segments; ++s) m.add_face({0, ring(1, s + 1), ring(1, s)});
  for (int r = 1; r + 1 < rings; ++r) {
    for (int s = 0; s < segments; ++s) {
      m.add_face({ring(r, s), ring(r, s + 1), ring(r + 1, s + 1)});
      m.add_face({ring(r, s), ring(r + 1, s + 1), ring(r + 1, s)});
    }
  }
  for (int s = 0; s < segments; ++s) m.add_face({ring(rings - 1, s), ring(rings - 1, s + 1), south});
  m.materials.push_back(MaterialSlot{.name = "stone"});
  m.name = "rock";
  return m;
}

// A terrain patch: a height field over a regular grid (open surface with one boundary loop).
Mesh make_terrain(int n) {
  Mesh m;
  for (int y = 0; y <= n; ++y) {
    for (int x = 0; x <= n; ++x) {
      const double h = 0.15 * std::sin(x * 0.35) * std::cos(y * 0.27) + 0.05 * std::sin(x * 1.3 + y * 0.9);
      m.add_vertex_with_wedge({{static_cast<float>(x) / n, static_cast<float>(h), static_cast<float>(y) / n}});
    }
  }
  auto id = [&](int x, int y) { return static_cast<std::uint32_t>(y * (n + 1) + x); };
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      m.add_face({id(x, y), id(x, y + 1), id(x + 1, y + 1)});
      m.add_face({id(x, y), id(x + 1, y + 1), id(x + 1, y)});
    }
  }
  m.materials.push_back(MaterialSlot{.name = "ground"});
  m.name = "terrain";
  return m;
}

// A twisted, subdivided box (hard-surface-like part with creases).
Mesh make_twisted_box(int n) {
  Mesh m;
  m.materials.push_back(MaterialSlot{.name = "metal"});
  // Six faces, each an n x n grid; welded afterwards.
  const int axes[6][3] = {{0, 1, 2}, {0, 1, 2}, {1, 2, 0}, {1, 2, 0}, {2, 0, 1}, {2, 0, 1}};
  for (int face = 0; face < 6; ++face) {
    const float side = (face % 2 == 0) ? -1.0f : 1.0f;
    const auto base = static_cast<std::uint32_t>(m.vertex_count());
    for (int j = 0; j <= n; ++j) {
      for (int i = 0; i <= n; ++i) {
        float p[3];
        p[axes[face][0]] = -1.0f + 2.0f * i / n;
        p[axes[face][1]] = -1.0f + 2.0f * j / n;
        p[axes[face][2]] = side;
        const double twist = 0.4 * p[1];
        const double x = p[0] * std::cos(twist) - p[2] * std::sin(twist);
        const double z = p[0] * std::sin(twist) + p[2] * std::cos(twist);
        m.add_vertex_with_wedge({{static_cast<float>(x), p[1] * 1.5f, static_cast<float>(z)}});
      }
    }
    auto id = [&](int i, int j) { return base + static_cast<std::uint32_t>(j * (n + 1) + i); };
    for (int j = 0; j < n; ++j) {
      for (int i = 0; i < n; ++i) {
        if (side > 0) {
          m.add_face({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
          m.add_face({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
        } else {
          m.add_face({id(i, j), id(i + 1, j + 1), id(i + 1, j)});
          m.add_face({id(i, j), id(i, j + 1), id(i + 1, j + 1)});
        }
      }
    }
  }
  weld_by_position(m);
  remove_unreferenced(m);
  m.name = "bracket";
  return m;
}

io::Asset single(Mesh m, io::Format f, bool binary) {
  io::Asset a;
  a.format = f;
  a.binary = binary;
  a.meshes.push_back(std::move(m));
  return a;
}

}  // namespace

void register_demo(CLI::App& app) {
  auto out = std::make_shared<std::string>();
  CLI::App* cmd = app.add_subcommand("demo", "Write the small sample library (generated meshes) into a folder.");
  cmd->add_option("output_dir", *out, "folder to create or fill")->required();
  cmd->callback([out] {
    try {
      const std::filesystem::path dir(*out);
      std::filesystem::create_directories(dir / "props");
      std::filesystem::create_directories(dir / "environment");
      std::filesystem::create_directories(dir / "characters");
      const Mesh torus = make_torus(48, 24, 1.0, 0.3);
      io::save_asset(single(torus, io::Format::obj, false), dir / "props/torus_quads.obj");
      io::save_asset(single(torus, io::Format::obj, false), dir / "characters/torus_ring.gltf");
      io::save_asset(single(make_bumpy_sphere(40, 64), io::Format::ply, true), dir / "environment/rock.ply");
      io::save_asset(single(make_terrain(48), io::Format::off, false), dir / "environment/terrain_patch.off");
      io::save_asset(single(make_twisted_box(12), io::Format::stl, true), dir / "props/bracket.stl");
      std::printf("wrote the sample library to %s\n", dir.string().c_str());
    } catch (const std::exception& e) {
      std::fprintf(stderr, "error: %s\n", e.what());
      set_exit_code(2);
    }
  });
}

}  // namespace lodforge::cli
