#include "test_support.hpp"

#include "lodforge/core/topology.hpp"

#include <sys/wait.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numbers>
#include <set>
#include <system_error>
#include <utility>

namespace lodforge::testing {

std::filesystem::path corpus_path(const std::string& relative) {
  std::filesystem::path p = std::filesystem::path(LODFORGE_CORPUS_DIR) / relative;
  std::error_code ec;
  return std::filesystem::exists(p, ec) ? p : std::filesystem::path{};
}

std::string test_name_of(const std::string& path) {
  std::string name = std::filesystem::path(path).stem().string();
  for (char& c : name) {
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  }
  return name;
}

std::filesystem::path temp_dir(const std::string& name) {
  std::filesystem::path p = std::filesystem::path(LODFORGE_BINARY_DIR) / "test-tmp" / name;
  std::filesystem::remove_all(p);
  std::filesystem::create_directories(p);
  return p;
}

CommandResult run_command(const std::string& command) {
  CommandResult r;
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  if (!pipe) return r;
  char buf[4096];
  std::size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, pipe)) > 0) r.output.append(buf, n);
  const int status = pclose(pipe);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

std::string shell_quote(const std::filesystem::path& p) {
  std::string s = "'";
  for (const char c : p.string()) {
    if (c == '\'') {
      s += "'\\''";
    } else {
      s += c;
    }
  }
  return s + "'";
}

CommandResult run_cli(const std::string& args) { return run_command(std::string(LODFORGE_CLI) + " " + args); }

namespace {
std::filesystem::path gltf_validator_module() {
  if (const char* env = std::getenv("LODFORGE_GLTF_VALIDATOR")) return env;
  return std::filesystem::path(LODFORGE_SOURCE_DIR) / "tools" / "node" / "node_modules" / "gltf-validator";
}
}  // namespace

std::string gltf_validator_unavailable() {
  if (std::system("node --version > /dev/null 2>&1") != 0) return "node is not installed";
  std::error_code ec;
  if (!std::filesystem::exists(gltf_validator_module() / "package.json", ec)) {
    return "gltf-validator not found at " + gltf_validator_module().string() + " (scripts/test.sh installs it)";
  }
  return {};
}

CommandResult validate_gltf(const std::vector<std::filesystem::path>& files, const std::filesystem::path& baseline) {
  std::string cmd = "node " + shell_quote(std::filesystem::path(LODFORGE_SOURCE_DIR) / "tests" / "support" /
                                          "validate_gltf.mjs");
  if (!baseline.empty()) {
    cmd += " --baseline ";
    cmd += shell_quote(baseline);
  }
  for (const std::filesystem::path& f : files) {
    cmd += ' ';
    cmd += shell_quote(f);
  }
  return run_command(cmd);
}

namespace {
Mesh with_default_material(Mesh m) {
  if (m.materials.empty()) m.materials.push_back(MaterialSlot{.name = "default"});
  return m;
}
}  // namespace

Mesh make_tetrahedron() {
  Mesh m;
  m.add_vertex_with_wedge({{0, 0, 0}});
  m.add_vertex_with_wedge({{1, 0, 0}});
  m.add_vertex_with_wedge({{0, 1, 0}});
  m.add_vertex_with_wedge({{0, 0, 1}});
  m.add_face({0, 2, 1});
  m.add_face({0, 1, 3});
  m.add_face({0, 3, 2});
  m.add_face({1, 2, 3});
  return with_default_material(std::move(m));
}

Mesh make_cube_quads() {
  Mesh m;
  for (int i = 0; i < 8; ++i) {
    m.add_vertex_with_wedge({{float(i & 1), float((i >> 1) & 1), float((i >> 2) & 1)}});
  }
  // Outward orientation (counter-clockwise seen from outside).
  m.add_face({0, 2, 3, 1});  // z = 0
  m.add_face({4, 5, 7, 6});  // z = 1
  m.add_face({0, 1, 5, 4});  // y = 0
  m.add_face({2, 6, 7, 3});  // y = 1
  m.add_face({0, 4, 6, 2});  // x = 0
  m.add_face({1, 3, 7, 5});  // x = 1
  return with_default_material(std::move(m));
}

Mesh with_repeated_faces(const Mesh& mesh, std::size_t every) {
  Mesh m = mesh;
  for (std::size_t f = 0; f < mesh.face_count(); f += every) {
    const std::uint32_t begin = mesh.face_offsets[f], k = mesh.face_size(f);
    std::vector<std::uint32_t> corners;
    for (std::uint32_t i = 0; i < k; ++i) corners.push_back(mesh.corner_wedge[begin + (i + 1) % k]);
    m.add_face(corners.data(), corners.size(), mesh.face_material.empty() ? 0 : mesh.face_material[f]);
    if (!m.face_group.empty()) m.face_group.push_back(mesh.face_group[f]);
  }
  return m;
}

Mesh make_grid(int nx, int ny, bool quads) {
  Mesh m;
  for (int y = 0; y <= ny; ++y) {
    for (int x = 0; x <= nx; ++x) m.add_vertex_with_wedge({{float(x), float(y), 0.0f}});
  }
  auto id = [&](int x, int y) { return static_cast<std::uint32_t>(y * (nx + 1) + x); };
  for (int y = 0; y < ny; ++y) {
    for (int x = 0; x < nx; ++x) {
      if (quads) {
        m.add_face({id(x, y), id(x + 1, y), id(x + 1, y + 1), id(x, y + 1)});
      } else {
        m.add_face({id(x, y), id(x + 1, y), id(x + 1, y + 1)});
        m.add_face({id(x, y), id(x + 1, y + 1), id(x, y + 1)});
      }
    }
  }
  return with_default_material(std::move(m));
}

Mesh make_zigzag_fan(int corners, float amplitude) {
  Mesh m;
  std::vector<std::uint32_t> face;
  for (int i = 0; i < corners; ++i) {
    const float x = static_cast<float>(i) / static_cast<float>(corners - 1);
    face.push_back(m.add_vertex_with_wedge({{x, i % 2 ? amplitude : 0.0f, 0.0f}}));
  }
  m.add_face(face.data(), face.size());
  return with_default_material(std::move(m));
}

Mesh make_fanned_disk(int corners) {
  Mesh m;
  std::vector<std::uint32_t> face;
  for (int i = 0; i < corners; ++i) {
    const double a = 2.0 * std::numbers::pi * i / corners;
    face.push_back(m.add_vertex_with_wedge({{float(std::cos(a)), float(std::sin(a)), 0.0f}}));
  }
  m.add_face(face.data(), face.size());
  return with_default_material(std::move(m));
}

Mesh make_cone(int segments) {
  Mesh m;
  const std::uint32_t apex = m.add_vertex_with_wedge({{0.0f, 0.0f, 1.0f}});
  for (int i = 0; i < segments; ++i) {
    const double a = 2.0 * std::numbers::pi * i / segments;
    m.add_vertex_with_wedge({{float(std::cos(a)), float(std::sin(a)), 0.0f}});
  }
  for (int i = 0; i < segments; ++i) {
    m.add_face({apex, 1 + static_cast<std::uint32_t>(i), 1 + static_cast<std::uint32_t>((i + 1) % segments)});
  }
  return with_default_material(std::move(m));
}

Mesh make_needle_strip(int triangles) {
  // Across the strip along (1, -1, 0), along the needles (1, 1, 1): both diagonal, so no box is flat.
  const double s2 = 1.0 / std::sqrt(2.0), s3 = 1.0 / std::sqrt(3.0);
  const Vec3d across{{s2, -s2, 0}}, along{{s3, s3, s3}};
  const int columns = std::max(1, triangles / 2);
  Mesh m;
  for (int i = 0; i <= columns; ++i) {
    const Vec3d base = across * (static_cast<double>(i) / columns);
    m.add_vertex_with_wedge(to_float(base));
    m.add_vertex_with_wedge(to_float(base + along));
  }
  for (std::uint32_t i = 0; i < static_cast<std::uint32_t>(columns); ++i) {
    m.add_face({2 * i, 2 * i + 2, 2 * i + 1});
    m.add_face({2 * i + 1, 2 * i + 2, 2 * i + 3});
  }
  return with_default_material(std::move(m));
}

Mesh make_stacked_grid(int triangles, int copies) {
  const int cells = std::max(1, triangles / (2 * copies));
  const int n = std::max(1, static_cast<int>(std::sqrt(static_cast<double>(cells))));
  Mesh m = make_grid(n, std::max(1, cells / n), false);
  const std::size_t faces = m.face_count();
  for (int c = 1; c < copies; ++c) {
    for (std::size_t f = 0; f < faces; ++f) {
      const std::uint32_t b = m.face_offsets[f];
      m.add_face({m.corner_wedge[b], m.corner_wedge[b + 1], m.corner_wedge[b + 2]});
    }
  }
  return m;
}

Mesh translated(Mesh mesh, const Vec3f& offset) {
  for (Vec3f& p : mesh.positions) p = p + offset;
  return mesh;
}

Mesh tilted(Mesh mesh) {
  const double cx = std::cos(0.5), sx = std::sin(0.5), cy = std::cos(0.7), sy = std::sin(0.7);
  for (Vec3f& p : mesh.positions) {
    const Vec3d q = to_double(p);
    const double y = q[1] * cx - q[2] * sx, z = q[1] * sx + q[2] * cx;
    p = to_float(Vec3d{{q[0] * cy + z * sy, y, -q[0] * sy + z * cy}});
  }
  return mesh;
}

Mesh make_uv_sphere(int rings, int segments, float radius) {
  Mesh m;
  const double pi = std::numbers::pi;
  m.add_vertex_with_wedge({{0, 0, radius}});  // north pole
  for (int r = 1; r < rings; ++r) {
    const double theta = pi * r / rings;
    for (int s = 0; s < segments; ++s) {
      const double phi = 2 * pi * s / segments;
      m.add_vertex_with_wedge({{static_cast<float>(radius * std::sin(theta) * std::cos(phi)),
                                static_cast<float>(radius * std::sin(theta) * std::sin(phi)),
                                static_cast<float>(radius * std::cos(theta))}});
    }
  }
  const auto south = m.add_vertex_with_wedge({{0, 0, -radius}});
  auto ring = [&](int r, int s) { return static_cast<std::uint32_t>(1 + (r - 1) * segments + (s % segments)); };
  for (int s = 0; s < segments; ++s) m.add_face({0, ring(1, s), ring(1, s + 1)});
  for (int r = 1; r + 1 < rings; ++r) {
    for (int s = 0; s < segments; ++s) {
      m.add_face({ring(r, s), ring(r + 1, s), ring(r + 1, s + 1)});
      m.add_face({ring(r, s), ring(r + 1, s + 1), ring(r, s + 1)});
    }
  }
  for (int s = 0; s < segments; ++s) m.add_face({ring(rings - 1, s), south, ring(rings - 1, s + 1)});
  return with_default_material(std::move(m));
}

Mesh make_two_bone_cylinder(int rings, int segments, float band_start, float band_width) {
  Mesh m;
  for (int i = 0; i <= rings; ++i) {
    const float z = 4.0f * float(i) / float(rings);
    for (int j = 0; j < segments; ++j) {
      const float a = 2.0f * 3.14159265f * float(j) / float(segments);
      m.add_vertex_with_wedge({{std::cos(a), std::sin(a), z}});
      const float w1 = std::clamp((z - band_start) / band_width, 0.0f, 1.0f);
      SkinInfluences s;
      s.joints = {0, 1};
      s.weights = {1.0f - w1, w1};
      m.skin.push_back(s);
    }
  }
  for (int i = 0; i < rings; ++i) {
    for (int j = 0; j < segments; ++j) {
      const auto a = static_cast<std::uint32_t>(i * segments + j);
      const auto b = static_cast<std::uint32_t>(i * segments + (j + 1) % segments);
      const auto c = b + static_cast<std::uint32_t>(segments), d = a + static_cast<std::uint32_t>(segments);
      m.add_face({a, b, c});
      m.add_face({a, c, d});
    }
  }
  return with_default_material(std::move(m));
}

double mirror_paired_fraction(const Mesh& mesh, double plane_x, double tol) {
  const Topology topo = build_topology(mesh);
  std::vector<std::uint32_t> image(mesh.vertex_count(), kInvalidIndex);
  for (std::uint32_t v = 0; v < mesh.vertex_count(); ++v) {
    Vec3f p = mesh.positions[v];
    p[0] = static_cast<float>(2.0 * plane_x - p[0]);
    for (std::uint32_t w = 0; w < mesh.vertex_count(); ++w) {
      const Vec3f d = mesh.positions[w] - p;
      if (std::sqrt(static_cast<double>(dot(d, d))) <= tol) {
        image[v] = w;
        break;
      }
    }
  }
  std::set<std::pair<std::uint32_t, std::uint32_t>> edges;
  for (const auto& e : topo.edges) edges.insert(std::minmax(e[0], e[1]));
  std::size_t paired = 0;
  for (const auto& e : topo.edges) {
    const std::uint32_t a = image[e[0]], b = image[e[1]];
    paired += a != kInvalidIndex && b != kInvalidIndex && a != b && edges.count(std::minmax(a, b)) > 0;
  }
  return topo.edges.empty() ? 1.0 : static_cast<double>(paired) / static_cast<double>(topo.edges.size());
}

}  // namespace lodforge::testing
