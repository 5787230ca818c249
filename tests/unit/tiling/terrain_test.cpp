// Terrain height maps: reading PNG and raw maps, patch chains with shared walls, skirts that close every
// crack between levels, conservative nesting with the map, holes, partial patches, incremental rebuilds.
#include "lodforge/tiling/terrain.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "lodforge/core/validate.hpp"
#include "lodforge/io/asset.hpp"
#include "lodforge/io/file.hpp"
#include "lodforge/io/heightmap.hpp"
#include "test_support.hpp"

namespace lodforge {
namespace {

// A deterministic rough map: a few octaves of sines with a hashed jitter, heights 0..~4000 samples.
io::HeightMap rough_map(std::size_t w, std::size_t h, double spacing = 2.0) {
  io::HeightMap map;
  map.width = w;
  map.height = h;
  map.layout.spacing_x = map.layout.spacing_z = spacing;
  map.layout.height_scale = 0.01;
  map.samples.resize(w * h);
  for (std::size_t r = 0; r < h; ++r) {
    for (std::size_t c = 0; c < w; ++c) {
      double v = 2000;
      double amp = 900, freq = 0.05;
      for (int o = 0; o < 5; ++o) {
        v += amp * std::sin(freq * static_cast<double>(c) + 1.3 * o) *
             std::cos(freq * 0.8 * static_cast<double>(r) - 0.7 * o);
        amp *= 0.5;
        freq *= 2.1;
      }
      std::uint32_t x = static_cast<std::uint32_t>(c * 73856093u ^ r * 19349663u);
      x ^= x >> 13;
      x *= 0x5bd1e995u;
      x ^= x >> 15;
      v += static_cast<double>(x % 41) - 20.0;
      map.samples[r * w + c] = static_cast<std::uint16_t>(std::clamp(v, 1.0, 65000.0));
    }
  }
  return map;
}

struct Tri {
  Vec3d a, b, c;
};

std::vector<Tri> triangles(const Mesh& m, std::size_t first, std::size_t last) {
  std::vector<Tri> out;
  for (std::size_t f = first; f < last; ++f) {
    const std::uint32_t b = m.face_offsets[f];
    out.push_back({to_double(m.positions[m.corner_vertex(b)]), to_double(m.positions[m.corner_vertex(b + 1)]),
                   to_double(m.positions[m.corner_vertex(b + 2)])});
  }
  return out;
}

// Möller–Trumbore on the segment origin + t * dir, t in [0, 1], with a small tolerance on the edges.
bool hits(const std::vector<Tri>& tris, const Vec3d& origin, const Vec3d& dir) {
  for (const Tri& t : tris) {
    const Vec3d e1 = t.b - t.a, e2 = t.c - t.a;
    const Vec3d p = cross(dir, e2);
    const double det = dot(e1, p);
    if (std::abs(det) < 1e-18) continue;
    const double inv = 1.0 / det;
    const Vec3d s = origin - t.a;
    const double u = dot(s, p) * inv;
    if (u < -1e-7 || u > 1 + 1e-7) continue;
    const Vec3d q = cross(s, e1);
    const double v = dot(dir, q) * inv;
    if (v < -1e-7 || u + v > 1 + 1e-7) continue;
    const double tt = dot(e2, q) * inv;
    if (tt >= -1e-9 && tt <= 1 + 1e-9) return true;
  }
  return false;
}

// The surface polyline of `m` (its first `surface` faces) on the wall `axis` = `line`: position along the
// wall -> height, for every surface vertex on it.
std::map<float, float> wall_polyline(const Mesh& m, std::size_t surface, int axis, float line) {
  std::map<float, float> out;
  const int along = axis == 0 ? 2 : 0;
  for (std::size_t f = 0; f < surface; ++f) {
    for (std::uint32_t i = 0; i < 3; ++i) {
      const Vec3f& p = m.positions[m.corner_vertex(m.face_offsets[f] + i)];
      if (p[axis] == line) out[p[along]] = p[1];
    }
  }
  return out;
}

double interpolate(const std::map<float, float>& poly, double t) {
  auto hi = poly.lower_bound(static_cast<float>(t));
  if (hi == poly.end()) return std::prev(hi)->second;
  if (hi == poly.begin()) return hi->second;
  const auto lo = std::prev(hi);
  const double u = (t - lo->first) / (hi->first - lo->first);
  return lo->second + u * (hi->second - lo->second);
}

// The shared walls of a result: (patch a, patch b, axis, line).
struct SharedWall {
  std::size_t a, b;
  int axis;
  float line;
};
std::vector<SharedWall> shared_walls(const terrain::Result& r, const io::HeightMap& map) {
  std::vector<SharedWall> out;
  for (std::size_t pz = 0; pz < r.patches_z; ++pz) {
    for (std::size_t px = 0; px < r.patches_x; ++px) {
      const std::size_t i = pz * r.patches_x + px;
      const terrain::Patch& p = r.patches[i];
      if (px + 1 < r.patches_x) {
        out.push_back(
            {i, i + 1, 0, static_cast<float>(static_cast<double>(p.first_column + p.columns) * map.layout.spacing_x)});
      }
      if (pz + 1 < r.patches_z) {
        out.push_back({i, i + r.patches_x, 2,
                       static_cast<float>(static_cast<double>(p.first_row + p.rows) * map.layout.spacing_z)});
      }
    }
  }
  return out;
}

TEST(Terrain, NeighboursShareBitIdenticalWallsAtEveryLevel) {
  const io::HeightMap map = rough_map(97, 97);
  terrain::Options o;
  o.patch_cells = 32;
  const terrain::Result r = terrain::build(map, o);
  ASSERT_EQ(r.patches_x, 3u);
  ASSERT_EQ(r.patches_z, 3u);
  for (const SharedWall& w : shared_walls(r, map)) {
    for (std::size_t k = 0; k <= o.levels.size(); ++k) {
      const terrain::Patch& a = r.patches[w.a];
      const terrain::Patch& b = r.patches[w.b];
      const auto pa = wall_polyline(a.lods[k], a.surface_triangles[k], w.axis, w.line);
      const auto pb = wall_polyline(b.lods[k], b.surface_triangles[k], w.axis, w.line);
      EXPECT_EQ(pa, pb) << "patches " << w.a << " and " << w.b << " at level " << k;
      EXPECT_GE(pa.size(), 2u);
      if (k == 0) {
        EXPECT_EQ(pa.size(), 33u);
      } else {
        EXPECT_LT(pa.size(), 33u) << "level " << k << " keeps every wall sample";
      }
    }
  }
}

TEST(Terrain, LevelsReachTheirShareOfTriangles) {
  const io::HeightMap map = rough_map(129, 129);
  terrain::Options o;
  o.patch_cells = 64;
  o.levels = {{0.25, -1}, {0.0625, -1}};
  for (Conservative mode : {Conservative::none, Conservative::occluder, Conservative::bounding}) {
    o.conservative = mode;
    const terrain::Result r = terrain::build(map, o);
    for (const terrain::Patch& p : r.patches) {
      const std::size_t full = 2 * p.columns * p.rows;
      ASSERT_EQ(p.surface_triangles[0], full);
      for (std::size_t k = 1; k <= o.levels.size(); ++k) {
        const double target = o.levels[k - 1].ratio * static_cast<double>(full);
        EXPECT_LE(static_cast<double>(p.surface_triangles[k]), 1.1 * target + 4)
            << conservative_name(mode) << " level " << k;
        EXPECT_LT(p.surface_triangles[k], p.surface_triangles[k - 1]);
        EXPECT_TRUE(validate(p.lods[k]).ok());
      }
    }
  }
}

// Casts, for every pair of neighbours at every pair of levels, rays from the sky on the side whose wall
// polyline is lower through the wall plane between the two polylines: without skirts they go through the
// crack (checked), with skirts every one hits.
std::size_t misses_through_seams(const io::HeightMap& map, const terrain::Options& o, std::size_t* cast) {
  const terrain::Result r = terrain::build(map, o);
  std::size_t missed = 0;
  *cast = 0;
  for (const SharedWall& w : shared_walls(r, map)) {
    const terrain::Patch& pa = r.patches[w.a];
    const terrain::Patch& pb = r.patches[w.b];
    for (std::size_t la = 0; la <= o.levels.size(); ++la) {
      for (std::size_t lb = 0; lb <= o.levels.size(); ++lb) {
        if (la == lb) continue;
        std::vector<Tri> tris = triangles(pa.lods[la], 0, pa.lods[la].face_count());
        const std::vector<Tri> tb = triangles(pb.lods[lb], 0, pb.lods[lb].face_count());
        tris.insert(tris.end(), tb.begin(), tb.end());
        const auto polya = wall_polyline(pa.lods[la], pa.surface_triangles[la], w.axis, w.line);
        const auto polyb = wall_polyline(pb.lods[lb], pb.surface_triangles[lb], w.axis, w.line);
        const double t0 = polya.begin()->first, t1 = std::prev(polya.end())->first;
        for (int s = 1; s < 160; ++s) {
          const double t = t0 + (t1 - t0) * s / 160.0;
          const double ya = interpolate(polya, t), yb = interpolate(polyb, t);
          if (std::abs(ya - yb) < 1e-3) continue;
          // The side whose polyline is lower: a is on the side of smaller coordinates.
          const double side = ya < yb ? -1.0 : 1.0;
          Vec3d target{};
          target[w.axis] = w.line;
          target[w.axis == 0 ? 2 : 0] = t;
          target[1] = 0.5 * (ya + yb);
          Vec3d from = target;
          from[w.axis] += side * 0.05;
          from[1] += 0.05;
          const Vec3d to = target * 2.0 - from;
          ++*cast;
          if (!hits(tris, from, to - from)) ++missed;
        }
      }
    }
  }
  return missed;
}

TEST(Terrain, SkirtsCloseEveryCrackBetweenLevels) {
  const io::HeightMap map = rough_map(65, 65);
  for (Conservative mode : {Conservative::none, Conservative::occluder}) {
    terrain::Options o;
    o.patch_cells = 16;
    o.conservative = mode;
    o.levels = {{0.25, -1}, {0.05, -1}};
    std::size_t cast = 0;
    o.skirts = false;
    const std::size_t without = misses_through_seams(map, o, &cast);
    EXPECT_GT(cast, 100u);
    EXPECT_GT(without, cast / 4) << "the rays do not find the cracks skirts should close";
    o.skirts = true;
    EXPECT_EQ(misses_through_seams(map, o, &cast), 0u) << conservative_name(mode) << ", of " << cast << " rays";
  }
}

// Every LOD triangle lies below (occluder) or above (bounding) the map: checked on a lattice of points per
// triangle against the map's own surface.
double worst_side_violation(const io::HeightMap& map, const terrain::Result& r, bool below) {
  const Mesh full = terrain::full_surface(map);
  double worst = 0;
  const auto surface = [&](double x, double z) {
    const double cx = x / map.layout.spacing_x, cz = z / map.layout.spacing_z;
    const std::size_t c = std::min<std::size_t>(static_cast<std::size_t>(cx), map.width - 2);
    const std::size_t rr = std::min<std::size_t>(static_cast<std::size_t>(cz), map.height - 2);
    const double fx = cx - static_cast<double>(c), fz = cz - static_cast<double>(rr);
    const auto hgt = [&](std::size_t cc, std::size_t r2) {
      return static_cast<double>(static_cast<float>(map.y(cc, r2)));
    };
    if (fx >= fz) return hgt(c, rr) + fx * (hgt(c + 1, rr) - hgt(c, rr)) + fz * (hgt(c + 1, rr + 1) - hgt(c + 1, rr));
    return hgt(c, rr) + fz * (hgt(c, rr + 1) - hgt(c, rr)) + fx * (hgt(c + 1, rr + 1) - hgt(c, rr + 1));
  };
  (void)full;
  for (const terrain::Patch& p : r.patches) {
    for (std::size_t k = 1; k < p.lods.size(); ++k) {
      for (const Tri& t : triangles(p.lods[k], 0, p.surface_triangles[k])) {
        constexpr int n = 12;
        for (int i = 0; i <= n; ++i) {
          for (int j = 0; i + j <= n; ++j) {
            const double u = static_cast<double>(i) / n, v = static_cast<double>(j) / n;
            const Vec3d q = t.a + (t.b - t.a) * u + (t.c - t.a) * v;
            const double d = q[1] - surface(q[0], q[2]);
            worst = std::max(worst, below ? d : -d);
          }
        }
      }
    }
  }
  return worst;
}

TEST(Terrain, ConservativePatchesNestWithTheMap) {
  const io::HeightMap map = rough_map(65, 65, 1.0);
  terrain::Options o;
  o.patch_cells = 32;
  o.levels = {{0.25, -1}, {0.05, -1}};
  o.conservative = Conservative::occluder;
  EXPECT_LE(worst_side_violation(map, terrain::build(map, o), true), 1e-3);
  o.conservative = Conservative::bounding;
  EXPECT_LE(worst_side_violation(map, terrain::build(map, o), false), 1e-3);
  // The check can fail: unconstrained patches cross the map.
  o.conservative = Conservative::none;
  EXPECT_GT(worst_side_violation(map, terrain::build(map, o), true), 0.05);
}

// Faces of `m` (its first `count`) that do not face up.
std::size_t overhangs(const Mesh& m, std::size_t count) {
  std::size_t n = 0;
  for (const Tri& t : triangles(m, 0, count)) n += !(cross(t.b - t.a, t.c - t.a)[1] > 0.0);
  return n;
}

TEST(Terrain, SteepPatchesStayHeightFields) {
  io::HeightMap map = rough_map(65, 65, 0.05);  // slopes up to about 70 degrees
  terrain::Options o;
  o.patch_cells = 32;
  o.levels = {{0.1, -1}, {0.02, -1}};
  for (Conservative mode : {Conservative::none, Conservative::occluder}) {
    o.conservative = mode;
    for (const terrain::Patch& p : terrain::build(map, o).patches) {
      for (std::size_t k = 0; k < p.lods.size(); ++k) {
        EXPECT_EQ(overhangs(p.lods[k], p.surface_triangles[k]), 0u) << conservative_name(mode) << " level " << k;
      }
    }
  }
  // Without the engine's height-field rule the same mesh folds over.
  const Mesh full = terrain::full_surface(map);
  SimplifyOptions so{.target_ratio = 0.02};
  so.border_mode = BorderMode::lock;
  const Mesh folded = simplify(full, so).mesh;
  EXPECT_GT(overhangs(folded, folded.face_count()), 0u);
  so.height_field_axis = 1;
  const Mesh held = simplify(full, so).mesh;
  EXPECT_EQ(overhangs(held, held.face_count()), 0u);
  EXPECT_LT(held.face_count(), full.face_count() / 20);
}

TEST(Terrain, HolesAndPartialPatches) {
  io::HeightMap map = rough_map(71, 53);
  map.layout.nodata = 0;
  for (std::size_t r = 10; r < 25; ++r) {
    for (std::size_t c = 20; c < 40; ++c) map.samples[r * map.width + c] = 0;  // a hole across a wall
  }
  for (std::size_t r = 0; r < 6; ++r) {
    for (std::size_t c = 0; c + r < 8; ++c) map.samples[r * map.width + c] = 0;  // a no-data corner
  }
  terrain::Options o;
  o.patch_cells = 32;
  const terrain::Result r = terrain::build(map, o);
  EXPECT_EQ(r.patches_x, 3u);
  EXPECT_EQ(r.patches_z, 2u);
  EXPECT_EQ(r.patches.back().columns, 70u - 64u);
  EXPECT_EQ(r.patches.back().rows, 52u - 32u);
  for (const terrain::Patch& p : r.patches) {
    for (std::size_t k = 0; k < p.lods.size(); ++k) {
      EXPECT_TRUE(validate(p.lods[k]).ok());
      for (const Vec3f& q : p.lods[k].positions) {
        // No vertex inside the hole (its rim is at samples 19..40 x 9..25).
        const double c = q[0] / map.layout.spacing_x, rr = q[2] / map.layout.spacing_z;
        EXPECT_FALSE(c > 20.5 && c < 38.5 && rr > 10.5 && rr < 23.5) << q[0] << " " << q[2];
      }
    }
  }
  for (const SharedWall& w : shared_walls(r, map)) {
    for (std::size_t k = 0; k <= o.levels.size(); ++k) {
      EXPECT_EQ(wall_polyline(r.patches[w.a].lods[k], r.patches[w.a].surface_triangles[k], w.axis, w.line),
                wall_polyline(r.patches[w.b].lods[k], r.patches[w.b].surface_triangles[k], w.axis, w.line));
    }
  }
}

TEST(Terrain, AChangedRegionRebuildsOnlyThePatchesItTouches) {
  io::HeightMap map = rough_map(129, 129);
  terrain::Options o;
  o.patch_cells = 32;
  o.levels = {{0.25, -1}, {0.0625, -1}};
  const terrain::Result first = terrain::build(map, o);
  EXPECT_EQ(first.rebuilt, 16u);
  // A bump inside patch (1, 1), away from its walls.
  for (std::size_t r = 40; r < 56; ++r) {
    for (std::size_t c = 40; c < 56; ++c) map.samples[r * map.width + c] += 300;
  }
  const terrain::Result again = terrain::build(map, o, &first);
  EXPECT_EQ(again.rebuilt, 1u);
  EXPECT_TRUE(again.patches[5].rebuilt);
  // A change on a wall sample reaches the patches on both sides of it.
  map.samples[64 * map.width + 10] += 500;
  const terrain::Result third = terrain::build(map, o, &again);
  EXPECT_EQ(third.rebuilt, 2u);
  // What was reused is what a full build makes.
  const terrain::Result fresh = terrain::build(map, o);
  ASSERT_EQ(fresh.patches.size(), third.patches.size());
  for (std::size_t i = 0; i < fresh.patches.size(); ++i) EXPECT_EQ(fresh.patches[i].lods, third.patches[i].lods) << i;
  // Other options are not reused.
  o.levels[0].ratio = 0.3;
  EXPECT_EQ(terrain::build(map, o, &fresh).rebuilt, 16u);
}

TEST(Terrain, EncodedResultsDecodeBitForBitAndServeAsPrevious) {
  io::HeightMap map = rough_map(97, 65);
  terrain::Options o;
  o.patch_cells = 32;
  o.levels = {{0.25, -1}, {0.0625, -1}};
  const terrain::Result first = terrain::build(map, o);
  const std::string bytes = terrain::encode_result(first);
  ASSERT_FALSE(bytes.empty());
  const std::optional<terrain::Result> back = terrain::decode_result(bytes);
  ASSERT_TRUE(back);
  EXPECT_EQ(back->patches_x, first.patches_x);
  EXPECT_EQ(back->settings, first.settings);
  ASSERT_EQ(back->patches.size(), first.patches.size());
  for (std::size_t i = 0; i < first.patches.size(); ++i) {
    EXPECT_EQ(back->patches[i].lods, first.patches[i].lods) << i;
    EXPECT_EQ(back->patches[i].inputs, first.patches[i].inputs) << i;
    EXPECT_EQ(back->patches[i].surface_triangles, first.patches[i].surface_triangles) << i;
  }
  // A decoded result is a previous like any: one changed patch rebuilt, the rest the same as a full build.
  for (std::size_t r = 40; r < 56; ++r) {
    for (std::size_t c = 40; c < 56; ++c) map.samples[r * map.width + c] += 300;
  }
  const terrain::Result again = terrain::build(map, o, &*back);
  EXPECT_EQ(again.rebuilt, 1u);
  const terrain::Result fresh = terrain::build(map, o);
  for (std::size_t i = 0; i < fresh.patches.size(); ++i) EXPECT_EQ(fresh.patches[i].lods, again.patches[i].lods) << i;
  // Damaged bytes are no result.
  EXPECT_FALSE(terrain::decode_result(bytes.substr(0, bytes.size() - 3)));
  EXPECT_FALSE(terrain::decode_result(bytes + "x"));
  EXPECT_FALSE(terrain::decode_result("lodforge-terrain-result-0\n"));
  EXPECT_FALSE(terrain::decode_result(""));
  // A mesh with what the format does not keep is not encoded.
  terrain::Result odd = first;
  odd.patches[0].lods[0].normals.assign(odd.patches[0].lods[0].wedge_count(), Vec3f{{0, 1, 0}});
  EXPECT_TRUE(terrain::encode_result(odd).empty());
}

TEST(Terrain, SameOutputForAnyThreadCount) {
  const io::HeightMap map = rough_map(97, 65);
  terrain::Options o;
  o.patch_cells = 32;
  o.threads = 1;
  const terrain::Result one = terrain::build(map, o);
  o.threads = 2;
  const terrain::Result two = terrain::build(map, o);
  for (std::size_t i = 0; i < one.patches.size(); ++i) EXPECT_EQ(one.patches[i].lods, two.patches[i].lods);
}

TEST(Terrain, RejectsBadOptions) {
  const io::HeightMap map = rough_map(9, 9);
  terrain::Options o;
  o.patch_cells = 1;
  EXPECT_THROW(terrain::build(map, o), std::invalid_argument);
  o.patch_cells = 4;
  o.levels = {{0.0, -1}};
  EXPECT_THROW(terrain::build(map, o), std::invalid_argument);
}

// ---- reading ----

void write_raw(const std::filesystem::path& path, const std::vector<std::uint16_t>& v) {
  std::string bytes;
  for (std::uint16_t s : v) {
    bytes.push_back(static_cast<char>(s & 0xff));
    bytes.push_back(static_cast<char>(s >> 8));
  }
  io::write_file_atomic(path, bytes);
}

TEST(HeightMapIo, RawSizeFromNameSidecarOrSquare) {
  const auto dir = testing::temp_dir("heightmap_raw");
  std::vector<std::uint16_t> v(6 * 4);
  for (std::size_t i = 0; i < v.size(); ++i) v[i] = static_cast<std::uint16_t>(1000 + 7 * i);
  write_raw(dir / "hills_6x4.r16", v);
  io::HeightMap m = io::load_heightmap(dir / "hills_6x4.r16");
  EXPECT_EQ(m.width, 6u);
  EXPECT_EQ(m.height, 4u);
  EXPECT_EQ(m.sample(5, 3), v[23]);
  EXPECT_EQ(m.sample(1, 2), v[13]);

  write_raw(dir / "plain.r16", v);
  EXPECT_THROW(io::load_heightmap(dir / "plain.r16"), io::IoError);  // 24 samples: not a square, no size
  io::write_file_atomic(dir / "plain.r16.json",
                        R"({"width": 4, "height": 6, "spacing": [30, 20], "height_scale": 0.5, "nodata": 1000})");
  m = io::load_heightmap(dir / "plain.r16");
  EXPECT_EQ(m.width, 4u);
  EXPECT_EQ(m.layout.spacing_x, 30.0);
  EXPECT_EQ(m.layout.spacing_z, 20.0);
  EXPECT_TRUE(m.hole(0, 0));
  EXPECT_DOUBLE_EQ(m.y(1, 0), 0.5 * 1007);
  EXPECT_DOUBLE_EQ(m.x(2), 60.0);

  write_raw(dir / "square.r16", std::vector<std::uint16_t>(25, 3));
  EXPECT_EQ(io::load_heightmap(dir / "square.r16").width, 5u);

  io::HeightMapLayout wrong;
  wrong.width = 5;
  wrong.height = 5;
  try {
    io::load_heightmap(dir / "hills_6x4.r16", wrong);
    ADD_FAILURE() << "a size that does not match the file was accepted";
  } catch (const io::IoError& e) {
    EXPECT_NE(std::string{e.what()}.find("hills_6x4.r16"), std::string::npos) << e.what();
    EXPECT_NE(std::string{e.what()}.find("the file has 48"), std::string::npos) << e.what();
  }
  io::write_file_atomic(dir / "odd.r16", "abc");
  EXPECT_THROW(io::load_heightmap(dir / "odd.r16"), io::IoError);
  io::write_file_atomic(dir / "hills_6x4.r16.json", R"({"spacing": -1})");
  EXPECT_THROW(io::load_heightmap(dir / "hills_6x4.r16"), io::IoError);
  io::write_file_atomic(dir / "hills_6x4.r16.json", R"({"spacin": 1})");
  EXPECT_THROW(io::load_heightmap(dir / "hills_6x4.r16"), io::IoError);
}

TEST(HeightMapIo, SixteenBitPngRoundTrips) {
  const auto dir = testing::temp_dir("heightmap_png");
  io::HeightMap m = rough_map(37, 23);
  io::save_heightmap_png(m, dir / "map.png");
  const io::HeightMap back = io::load_heightmap(dir / "map.png");
  EXPECT_EQ(back.width, 37u);
  EXPECT_EQ(back.height, 23u);
  EXPECT_EQ(back.samples, m.samples);
  EXPECT_TRUE(back.warnings.empty());
  io::write_file_atomic(dir / "junk.png", "not a png at all");
  EXPECT_THROW(io::load_heightmap(dir / "junk.png"), io::IoError);
  EXPECT_TRUE(io::is_heightmap_path("A.PNG"));
  EXPECT_TRUE(io::is_heightmap_path("a.r16"));
  EXPECT_FALSE(io::is_heightmap_path("a.obj"));
}

TEST(HeightMapIo, CorpusPngAndRawAgree) {
  LODFORGE_REQUIRE_CORPUS(png, "terrain/mount-st-helens_327x466_u16.png");
  LODFORGE_REQUIRE_CORPUS(raw, "terrain/mount-st-helens_327x466_u16le.r16");
  const io::HeightMap a = io::load_heightmap(png);
  const io::HeightMap b = io::load_heightmap(raw);
  EXPECT_EQ(a.width, 327u);
  EXPECT_EQ(a.height, 466u);
  EXPECT_EQ(a.samples, b.samples);
  EXPECT_EQ(std::count(a.samples.begin(), a.samples.end(), 0), 3497);
}

TEST(Terrain, MountStHelensOccluderPatches) {
  LODFORGE_REQUIRE_CORPUS(png, "terrain/mount-st-helens_327x466_u16.png");
  io::HeightMapLayout layout;
  layout.spacing_x = layout.spacing_z = 30.0;
  layout.nodata = 0;
  const io::HeightMap map = io::load_heightmap(png, layout);
  terrain::Options o;
  o.patch_cells = 64;
  const terrain::Result r = terrain::build(map, o);
  EXPECT_EQ(r.patches_x, 6u);
  EXPECT_EQ(r.patches_z, 8u);
  EXPECT_LE(worst_side_violation(map, r, true), 1e-2);
  for (const terrain::Patch& p : r.patches) {
    for (const Mesh& lod : p.lods) EXPECT_TRUE(lod.face_count() == 0 || validate(lod).ok());
  }
}

}  // namespace
}  // namespace lodforge
