// Out-of-core tiled simplification (stream.hpp; docs/tiling.md, "Out of core").
#include "lodforge/tiling/stream.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <numeric>
#include <unordered_map>

#include "lodforge/core/weld.hpp"
#include "lodforge/io/asset.hpp"
#include "lodforge/tiling/tiling.hpp"
#include "tiles.hpp"

namespace lodforge::tiling {
namespace {

using detail::TileRun;

// Triangles buffered per tile before they are appended to its file (three ids each).
constexpr std::size_t kFlushTriangles = std::size_t{1} << 13;
constexpr std::uint32_t kShared = kInvalidIndex - 1;  // owner of a vertex used by two or more tiles
constexpr std::uint64_t kMaxVertexHint = std::uint64_t{1} << 32;  // a hint above 32-bit ids is not believed

std::filesystem::path tile_path(const std::filesystem::path& scratch, std::size_t tile) {
  return scratch / ("tile-" + std::to_string(tile) + ".bin");
}

void append_ids(const std::filesystem::path& path, const std::vector<std::uint32_t>& ids) {
  std::FILE* f = std::fopen(path.c_str(), "ab");
  if (f == nullptr) throw io::IoError(path, std::string("cannot write a tile: ") + std::strerror(errno));
  const bool written = std::fwrite(ids.data(), sizeof(std::uint32_t), ids.size(), f) == ids.size();
  const bool closed = std::fclose(f) == 0;
  if (!written || !closed) throw io::IoError(path, "cannot write a tile (disk full?)");
}

std::vector<std::uint32_t> read_ids(const std::filesystem::path& path, std::size_t count) {
  std::vector<std::uint32_t> ids(count);
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f == nullptr) throw io::IoError(path, std::string("cannot read a tile back: ") + std::strerror(errno));
  const bool read = std::fread(ids.data(), sizeof(std::uint32_t), count, f) == count;
  std::fclose(f);
  if (!read) throw io::IoError(path, "a tile file is shorter than written");
  return ids;
}

struct TileFile {
  std::uint64_t key = 0;
  std::uint64_t triangles = 0;
  std::vector<std::uint32_t> pending;
};

// Each vertex to the first vertex at the same position, compared as the loaders' weld compares it
// (weld_bits: −0 is +0). A sort rather than weld_by_position()'s hash table: 4 bytes a vertex, not 8-16.
std::vector<std::uint32_t> weld(const std::vector<Vec3f>& positions) {
  std::vector<std::uint32_t> order(positions.size());
  std::iota(order.begin(), order.end(), 0u);
  auto bits = [&](std::uint32_t v) {
    const Vec3f& p = positions[v];
    return std::array<std::uint32_t, 3>{weld_bits(p[0]), weld_bits(p[1]), weld_bits(p[2])};
  };
  tbb::parallel_sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
    const auto ka = bits(a), kb = bits(b);
    return ka != kb ? ka < kb : a < b;
  });
  std::vector<std::uint32_t> canon(positions.size());
  for (std::size_t i = 0; i < order.size(); ++i) {
    canon[order[i]] = i > 0 && bits(order[i]) == bits(order[i - 1]) ? canon[order[i - 1]] : order[i];
  }
  return canon;
}

// One tile: its triangles (global ids) read back, made a mesh of its own, simplified with the vertices it
// shares with other tiles locked.
TileRun run_tile(const std::vector<std::uint32_t>& ids, const std::vector<Vec3f>& positions,
                 const std::vector<std::uint32_t>& owner, const SimplifyOptions& options, std::size_t tile) {
  std::vector<std::uint32_t> vertices = ids;
  std::sort(vertices.begin(), vertices.end());
  vertices.erase(std::unique(vertices.begin(), vertices.end()), vertices.end());
  Mesh sub;
  sub.positions.reserve(vertices.size());
  std::vector<std::uint32_t> locked;
  for (std::uint32_t i = 0; i < vertices.size(); ++i) {
    sub.add_vertex_with_wedge(positions[vertices[i]]);
    if (owner[vertices[i]] == kShared) locked.push_back(i);
  }
  auto local = [&](std::uint32_t g) {
    return static_cast<std::uint32_t>(std::lower_bound(vertices.begin(), vertices.end(), g) - vertices.begin());
  };
  for (std::size_t k = 0; k + 2 < ids.size(); k += 3) sub.add_face({local(ids[k]), local(ids[k + 1]), local(ids[k + 2])});
  SimplifyOptions o = options;
  o.locked_vertices = locked;
  TileRun run;
  run.result = simplify(sub, o);
  detail::track_locked(run, sub, locked, vertices, tile);
  return run;
}

}  // namespace

StreamPlan plan_stream(const std::filesystem::path& path, const SimplifyOptions& options, std::size_t limit,
                       unsigned workers) {
  StreamPlan p;
  p.counts = io::stream_counts(path);
  const std::size_t v = p.counts.vertices, n = p.counts.triangles;
  std::error_code ec;
  const std::size_t file = static_cast<std::size_t>(std::filesystem::file_size(path, ec));
  const std::size_t slots = std::max<std::size_t>(workers, 1);
  // Loaded whole: the file's bytes while it is parsed, the mesh (16 bytes a vertex, 20 a triangle), the tiled
  // path's arrays, and tiles of kMinStreamTile triangles at least (plan_memory() refuses smaller ones than
  // that; below it, streaming's larger tiles make the better LOD).
  p.whole_bytes = file + 16 * v + 20 * n + kTiledBytesPerTriangle * n +
                  (kUntiledBytesPerTriangle + 30) * std::min(n, kMinStreamTile) * (slots + kFinalTiles);
  p.stream = p.counts.readable && p.whole_bytes > limit - limit / 8;
  const std::size_t reserved = limit / 8 + kProgramBytes + io::kStreamBufferBytes;
  const std::size_t usable = limit > reserved ? limit - reserved : 0;
  // Streamed: the per-vertex arrays, the tile outputs (about kOversample x the target, 60 bytes a triangle
  // with the stitch's arrays), a write buffer per tile, and `workers` tiles at a time (each its mesh and its
  // engine's working set).
  const std::size_t target = detail::global_target(options, std::max<std::size_t>(n, 1));
  const std::size_t fixed = kStreamBytesPerVertex * v + 60 * kOversample * target;
  const std::size_t per_tile_triangle = kUntiledBytesPerTriangle + 30;
  std::size_t tile = 0;
  for (int round = 0; round < 2; ++round) {  // the buffers depend on the tile count, which depends on the size
    const std::size_t tiles = tile > 0 ? n / tile + 1 : 1;
    const std::size_t buffers = tiles * kFlushTriangles * 12;
    tile = fixed + buffers < usable ? (usable - fixed - buffers) / (per_tile_triangle * slots) : 0;
    tile = std::min(tile, options.tile_triangles);
    if (tile == 0) break;
  }
  p.tile_triangles = tile;
  p.fits = tile >= kMinStreamTile;
  const std::size_t tiles = tile > 0 ? n / tile + 1 : 1;
  p.stream_bytes = fixed + tiles * kFlushTriangles * 12 + per_tile_triangle * slots * tile;
  return p;
}

StreamedRun simplify_streamed(const std::filesystem::path& path, const SimplifyOptions& options,
                              std::size_t tile_triangles, const std::filesystem::path& scratch,
                              std::size_t memory_limit, std::uint64_t vertices_hint) {
  StreamedRun run;
  if (!detail::may_tile(options)) {
    throw std::invalid_argument("simplify: these options cannot tile (engine, verified error budget or volume budget), "
                                "so the file cannot be simplified out of core");
  }
  // Vertex ids given by the caller (locks, a mirror map) name a loaded mesh's vertices, which a stream never
  // builds.
  if (!options.locked_vertices.empty() || options.vertex_mirror != nullptr) {
    throw std::invalid_argument("simplify: locked vertices and a vertex mirror map need the mesh loaded whole, "
                                "not streamed out of core");
  }
  {
    std::error_code ec;
    std::filesystem::create_directories(scratch, ec);
    if (ec) throw io::IoError(scratch, "cannot create the scratch folder for tiles: " + ec.message());
  }

  // First pass: positions, the triangle count and the surface area.
  std::string material;
  std::vector<Vec3f> positions;
  std::uint64_t triangles = 0;
  double area = 0;
  Bounds3 box;
  if (vertices_hint <= kMaxVertexHint) positions.reserve(static_cast<std::size_t>(vertices_hint));
  {
    io::StreamSinks sinks;
    sinks.vertex = [&](const Vec3f& p) {
      positions.push_back(p);
      box.add(to_double(p));
    };
    sinks.face = [&](std::span<const std::uint32_t> f) {
      const Vec3d a = to_double(positions[f[0]]);
      for (std::size_t k = 1; k + 1 < f.size(); ++k) {
        area += 0.5 * length(cross(to_double(positions[f[k]]) - a, to_double(positions[f[k + 1]]) - a));
        ++triangles;
      }
    };
    io::StreamResult read = io::stream_mesh(path, sinks);
    run.warnings = std::move(read.warnings);
    run.mtllibs = std::move(read.mtllibs);
    material = std::move(read.material);
  }
  positions.shrink_to_fit();
  run.input_vertices = positions.size();
  std::vector<std::uint32_t> canon = weld(positions);

  // Cells as the in-memory cut makes them, about tile_triangles of surface each (a tile may hold more where
  // the surface is denser; the batches below keep the tiles in memory at once within the plan). Cells of half
  // that made the 16.8M-triangle terrain's LOD 1.39x the RMS distance at 1% (more locked cut vertices in the
  // first pass), for 0.7x the time.
  const double diagonal = box.empty() ? 0.0 : box.diagonal();
  const double cell = detail::cell_size(area, triangles, tile_triangles, diagonal);
  const Vec3d origin = box.empty() ? Vec3d{} : box.min;

  // Second pass: each triangle to the file of its centroid's cell; which vertices more than one tile uses.
  std::vector<std::uint32_t> owner(positions.size(), kInvalidIndex);
  std::vector<TileFile> tiles;
  std::unordered_map<std::uint64_t, std::uint32_t> tile_of_key;
  {
    io::StreamSinks sinks;
    sinks.vertex = [](const Vec3f&) {};
    sinks.face = [&](std::span<const std::uint32_t> f) {
      for (std::size_t k = 1; k + 1 < f.size(); ++k) {
        const std::uint32_t c[3] = {canon[f[0]], canon[f[k]], canon[f[k + 1]]};
        if (c[0] == c[1] || c[1] == c[2] || c[0] == c[2]) {
          ++run.degenerate_dropped;
          continue;
        }
        const Vec3d g = (to_double(positions[c[0]]) + to_double(positions[c[1]]) + to_double(positions[c[2]])) * (1.0 / 3.0);
        const std::uint64_t key = detail::cell_key(g, origin, cell);
        auto [it, fresh] = tile_of_key.try_emplace(key, static_cast<std::uint32_t>(tiles.size()));
        if (fresh) tiles.emplace_back().key = key;
        const std::uint32_t t = it->second;
        TileFile& tile = tiles[t];
        for (const std::uint32_t v : c) {
          owner[v] = owner[v] == kInvalidIndex || owner[v] == t ? t : kShared;
          tile.pending.push_back(v);
        }
        if (++tile.triangles % kFlushTriangles == 0) {
          append_ids(tile_path(scratch, t), tile.pending);
          tile.pending.clear();
        }
      }
    };
    io::stream_mesh(path, sinks);
  }
  for (std::size_t t = 0; t < tiles.size(); ++t) {
    if (!tiles[t].pending.empty()) append_ids(tile_path(scratch, t), tiles[t].pending);
    std::vector<std::uint32_t>().swap(tiles[t].pending);
  }
  std::vector<std::uint32_t>().swap(canon);
  const std::size_t kept = triangles - run.degenerate_dropped;
  run.tiles = tiles.size();
  if (run.degenerate_dropped > 0) {
    run.warnings.push_back("dropped " + std::to_string(run.degenerate_dropped) +
                           " triangle(s) with a repeated corner (after welding equal positions)");
  }

  // The tiles in cell order, each to its share of kOversample x the target (as the in-memory first pass).
  std::vector<std::uint32_t> order(tiles.size());
  std::iota(order.begin(), order.end(), 0u);
  std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) { return tiles[a].key < tiles[b].key; });
  const std::size_t target = detail::global_target(options, triangles);
  const std::size_t pass_target = detail::first_pass_target(target, kept);
  SimplifyOptions base = detail::tile_base_options(options, diagonal);
  base.threads = detail::tile_threads(options, tiles.size());
  const unsigned concurrency = detail::concurrency(options);
  tbb::task_arena arena(options.threads ? static_cast<int>(options.threads) : tbb::task_arena::automatic);
  std::vector<TileRun> runs(tiles.size());
  // Tiles run in batches of at most `concurrency` x tile_triangles (a larger tile alone), so that the tiles in
  // memory at once stay within what the plan gave them; each tile's result is the same in any batch.
  std::size_t batch_begin = 0;
  while (batch_begin < order.size()) {
    std::size_t batch_end = batch_begin + 1, held = tiles[order[batch_begin]].triangles;
    while (batch_end < order.size() && batch_end - batch_begin < concurrency &&
           held + tiles[order[batch_end]].triangles <= std::size_t{concurrency} * tile_triangles) {
      held += tiles[order[batch_end++]].triangles;
    }
    arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(batch_begin, batch_end, 1), [&](const tbb::blocked_range<std::size_t>& r) {
      for (std::size_t i = r.begin(); i != r.end(); ++i) {
        const TileFile& tile = tiles[order[i]];
        const std::filesystem::path file = tile_path(scratch, order[i]);
        const std::vector<std::uint32_t> ids = read_ids(file, 3 * tile.triangles);
        std::error_code ec;
        std::filesystem::remove(file, ec);
        SimplifyOptions o = base;
        o.target_triangles = detail::tile_share(pass_target, tile.triangles, kept);
        runs[i] = run_tile(ids, positions, owner, o, i);
      }
    });
    });
    batch_begin = batch_end;
  }

  SimplifyResult first;
  for (const TileRun& r : runs) detail::add_stats(first, r.result);
  // The whole-file arrays go before the stitch and the finishing run need their memory.
  const std::size_t vertex_count = positions.size();
  std::vector<Vec3f>().swap(positions);
  std::vector<std::uint32_t>().swap(owner);
  std::vector<std::uint8_t> locked(vertex_count, 0);
  Mesh like;  // one material slot, as the loaders give every mesh ("" where the file names none)
  like.materials.push_back({.name = material});
  Mesh stitched = detail::stitch(like, vertex_count, runs, locked, options);
  std::vector<TileRun>().swap(runs);
  std::vector<std::uint8_t>().swap(locked);
  stitched.name = path.stem().string();

  SimplifyOptions finish = options;
  finish.target_ratio = 1.0;
  finish.target_triangles = target;
  if (options.max_error_rel >= 0.0) {
    finish.max_error_abs = base.max_error_abs;
    finish.max_error_rel = -1.0;
  }
  if (memory_limit > 0) {
    plan_memory(stitched, finish, memory_limit, concurrency).apply(finish);
  }
  SimplifyResult r = simplify_maybe_tiled(stitched, finish);
  r.triangles_before = triangles;
  detail::add_stats(r, first);
  r.qem_error_rel = diagonal > 0.0 ? r.qem_error_abs / diagonal : 0.0;
  r.tiling_passes += 1;
  r.tile_runs += tiles.size();
  run.result = std::move(r);
  return run;
}

}  // namespace lodforge::tiling
