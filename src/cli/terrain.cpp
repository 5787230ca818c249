// `lodforge terrain MAP OUT`: a height map cut into patches, each with its LOD chain, stitched without cracks
// (tiling/terrain.hpp, docs/terrain.md).
#include "lodforge/tiling/terrain.hpp"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "commands.hpp"
#include "lodforge/io/asset.hpp"
#include "lodforge/io/file.hpp"
#include "lodforge/io/heightmap.hpp"
#include "lodforge/io/lods.hpp"
#include "lodforge/io/picture.hpp"

namespace lodforge::cli {

namespace {

// "a,b,c" as numbers; false when one is not a number.
bool parse_list(const std::string& text, std::vector<double>& out) {
  out.clear();
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    try {
      std::size_t used = 0;
      out.push_back(std::stod(item, &used));
      if (used != item.size()) return false;
    } catch (const std::exception&) {
      return false;
    }
  }
  return !out.empty();
}

std::vector<double> terrain_screen_coverage(std::size_t levels) {
  // Level k shown from half the screen's height down by halves; the coarsest is kept.
  std::vector<double> coverage;
  double c = 0.5;
  for (std::size_t k = 0; k < levels; ++k, c *= 0.5) coverage.push_back(c);
  coverage.push_back(0.0);
  return coverage;
}

void write_terrain(const terrain::Result& result, const std::filesystem::path& source, const std::filesystem::path& out,
                   bool per_patch) {
  const std::size_t levels = result.patches.empty() ? 0 : result.patches.front().lods.size() - 1;
  const auto write = [&](const std::vector<const terrain::Patch*>& patches, const std::filesystem::path& path) {
    io::Asset asset;
    asset.source = source;
    asset.format = io::Format::obj;
    io::LodChain chain;
    chain.levels.resize(levels);
    chain.screen_coverage = terrain_screen_coverage(levels);
    for (const terrain::Patch* p : patches) {
      asset.meshes.push_back(p->lods[0]);
      for (std::size_t k = 0; k < levels; ++k) chain.levels[k].push_back(p->lods[k + 1]);
    }
    io::save_gltf_lods(asset, chain, path);
  };
  std::vector<const terrain::Patch*> all;
  for (const terrain::Patch& p : result.patches) {
    if (p.lods[0].face_count() > 0) all.push_back(&p);  // a patch that is all hole has nothing to show
  }
  if (!per_patch) {
    write(all, out);
    return;
  }
  std::filesystem::create_directories(out);
  for (const terrain::Patch* p : all) {
    write({p},
          out / (source.stem().string() + "_" + std::to_string(p->column) + "_" + std::to_string(p->row) + ".glb"));
  }
}

}  // namespace

void register_terrain(CLI::App& app) {
  struct Args {
    std::string in, out, ratios = "0.25,0.0625,0.015625", conservative = "occluder", spacing, picture;
    double max_error = -1, height_scale = 0, height_offset = 0;
    int nodata = -1;
    std::size_t width = 0, height = 0, patch_cells = 64;
    std::vector<std::size_t> picture_levels;
    int picture_size = 1024;
    bool no_skirts = false, files = false;
    unsigned threads = 0;
  };
  auto a = std::make_shared<Args>();
  CLI::App* cmd = app.add_subcommand(
      "terrain",
      "Cut a height map (16-bit PNG or raw .r16) into patches, give each a LOD chain (conservative occluders by "
      "default) with shared walls and skirts, and write one glTF with a node per patch (MSFT_lod) or a file per "
      "patch.");
  cmd->add_option("input", a->in, "height map: .png (grey, 16 or 8 bit) or .r16 (raw little-endian)")->required();
  cmd->add_option("output", a->out, "output .glb or .gltf; with --files a folder")->required();
  cmd->add_option("--patch-cells", a->patch_cells, "cells per patch side (64: 65 x 65 samples a patch)")
      ->default_val(64);
  cmd->add_option("--ratios", a->ratios, "each level's share of a patch's triangles, finest first")
      ->default_val(a->ratios);
  cmd->add_option("--max-error", a->max_error, "also stop each level at this distance, in model units");
  add_conservative_option(cmd, a->conservative,
                          "occluder (below the map: occlusion culling) | bounding (above it) | none");
  cmd->add_option("--spacing", a->spacing, "distance between samples: X or X,Z (default 1, or the sidecar's)");
  cmd->add_option("--height-scale", a->height_scale, "model units per sample step (default 1, or the sidecar's)");
  cmd->add_option("--height-offset", a->height_offset, "height of sample 0 (default 0, or the sidecar's)");
  cmd->add_option("--nodata", a->nodata, "sample value that marks a hole (default none, or the sidecar's)");
  cmd->add_option("--width", a->width, "raw maps: columns (else the sidecar's, the file name's WxH, or square)");
  cmd->add_option("--height", a->height, "raw maps: rows");
  cmd->add_flag("--no-skirts", a->no_skirts, "no vertical skirts under the patch walls");
  cmd->add_flag("--files", a->files, "a .glb per patch in the output folder instead of one file");
  cmd->add_option("--picture", a->picture,
                  "also write a top-down picture per level in --picture-levels: PATH_LOD<k>.png, patches coloured "
                  "by their triangle count");
  cmd->add_option("--picture-levels", a->picture_levels, "levels to picture, comma-separated (default: 1 and the last)")
      ->delimiter(',');
  cmd->add_option("--picture-size", a->picture_size, "picture width and height in pixels (default 1024)")
      ->check(CLI::Range(64, 8192));
  cmd->add_option("--threads", a->threads, "worker threads (0 = all cores)")->default_val(0);
  cmd->callback([a] {
    terrain::Options o;
    o.patch_cells = a->patch_cells;
    o.threads = a->threads;
    o.skirts = !a->no_skirts;
    o.conservative = conservative_mode(a->conservative);
    std::vector<double> ratios;
    if (!parse_list(a->ratios, ratios)) {
      std::fprintf(stderr, "error: --ratios: expected numbers separated by commas, got '%s'\n", a->ratios.c_str());
      set_exit_code(2);
      return;
    }
    o.levels.clear();
    for (double r : ratios) o.levels.push_back({r, a->max_error});
    io::HeightMapLayout layout;
    layout.width = a->width;
    layout.height = a->height;
    std::vector<double> spacing;
    if (!a->spacing.empty()) {
      if (!parse_list(a->spacing, spacing) || spacing.size() > 2) {
        std::fprintf(stderr, "error: --spacing: expected X or X,Z, got '%s'\n", a->spacing.c_str());
        set_exit_code(2);
        return;
      }
      layout.spacing_x = spacing[0];
      layout.spacing_z = spacing.back();
    }
    if (a->height_scale != 0) layout.height_scale = a->height_scale;
    layout.height_offset = a->height_offset;
    if (a->nodata >= 0) {
      if (a->nodata > 65535) {
        std::fprintf(stderr, "error: --nodata must be a sample value from 0 to 65535\n");
        set_exit_code(2);
        return;
      }
      layout.nodata = static_cast<std::uint16_t>(a->nodata);
    }
    std::vector<std::string> problems = o.validate();
    for (const std::string& p : layout.validate()) problems.push_back(p);
    if (!problems.empty()) {
      for (const std::string& p : problems) std::fprintf(stderr, "error: %s\n", p.c_str());
      set_exit_code(2);
      return;
    }
    try {
      const io::HeightMap map = io::load_heightmap(a->in, layout);
      for (const std::string& w : map.warnings) std::fprintf(stderr, "warning: %s: %s\n", a->in.c_str(), w.c_str());
      const auto start = std::chrono::steady_clock::now();
      const terrain::Result result = terrain::build(map, o);
      const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      write_terrain(result, a->in, a->out, a->files);
      std::printf("%s: %zu x %zu samples, %zu x %zu patches of %zu cells, %s, %.3f s\n", a->in.c_str(), map.width,
                  map.height, result.patches_x, result.patches_z, o.patch_cells, conservative_name(o.conservative),
                  seconds);
      for (std::size_t k = 0; k <= o.levels.size(); ++k) {
        std::size_t tris = 0, skirts = 0;
        for (const terrain::Patch& p : result.patches) {
          tris += p.surface_triangles[k];
          skirts += p.lods[k].face_count() - p.surface_triangles[k];
        }
        std::printf("  LOD%zu: %zu triangles (+%zu in skirts)\n", k, tris, skirts);
      }
      if (!a->picture.empty()) {
        std::vector<std::size_t> levels = a->picture_levels;
        if (levels.empty()) levels = {std::min<std::size_t>(1, o.levels.size()), o.levels.size()};
        for (std::size_t k : levels) {
          if (k > o.levels.size()) {
            std::fprintf(stderr, "error: --picture-levels: there is no level %zu\n", k);
            set_exit_code(2);
            return;
          }
          std::vector<std::array<std::uint8_t, 3>> colours;
          const Mesh surface = terrain::level_surface(result, k, o.patch_cells, &colours);
          const io::PictureFrame frame = io::frame_mesh(surface, *io::find_picture_view("top"));
          std::filesystem::path path = a->picture;
          path.replace_extension();
          path += "_LOD" + std::to_string(k) + ".png";
          io::write_file_atomic(path, io::encode_png(io::render_picture(surface, frame, a->picture_size, colours)));
          std::printf("  picture of LOD%zu: %s\n", k, path.string().c_str());
        }
      }
      std::printf("wrote %s\n", a->out.c_str());
    } catch (const io::IoError& e) {
      std::fprintf(stderr, "error: %s\n", e.what());
      set_exit_code(2);
    }
  });
}

}  // namespace lodforge::cli
