// Writing LOD chains into one glTF file through the MSFT_lod extension.
//
//   io::LodChain chain{.levels = {{lod1_of_mesh0, lod1_of_mesh1}, {lod2_of_mesh0, lod2_of_mesh1}},
//                      .screen_coverage = {0.5, 0.2, 0.0}};
//   io::save_gltf_lods(asset, chain, "out/hero.glb");
//
// What the file holds (MSFT_lod, github.com/KhronosGroup/glTF/tree/main/extensions/2.0/Vendor/MSFT_lod):
// the asset's own document with its meshes as LOD0, exactly as save_asset writes it, plus one new glTF mesh
// per LOD level and asset mesh ("<name>_LOD<k>", same materials and primitive layout), except for levels that
// show the level before's meshes (LodChain::shows_previous). Every node that shows an
// asset mesh gets, per level, a new root-less node showing that mesh's LOD (same transform, skin and morph
// weights where the LOD mesh still has them), listed finest first in the node's `extensions.MSFT_lod.ids`, and
// `extras.MSFT_screencoverage`; `extensionsUsed` names MSFT_lod. Readers without MSFT_lod show LOD0 only, which
// is why the extension is "used" and not "required".
//
// Separate LODs (LodChain::separate: collision hulls, occluders) are no part of MSFT_lod: each gets one glTF mesh
// per asset mesh ("<name><suffix>") and, per node showing that mesh, a node "<node name><suffix>" with the node's
// transform, placed beside it (a child of the same parent, or a root of the same scenes), with no screen coverage
// and `extras.lodforge.output` naming what it is (the suffix without its leading '_': "collision").
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "lodforge/core/mesh.hpp"
#include "lodforge/io/asset.hpp"

namespace lodforge::io {

struct LodChain {
  // levels[k][m] is LOD k+1 of asset.meshes[m]; every level holds one mesh per asset mesh.
  std::vector<std::vector<Mesh>> levels;
  // levels.size() + 1 non-increasing values in [0, 1] (MSFT_screencoverage): entry k is the smallest share of
  // the screen height the object covers while level k (0 = the asset's own meshes) is shown; below the last
  // entry the object is culled, so a last entry of 0 keeps the coarsest level forever.
  std::vector<double> screen_coverage;
  // Per level (empty: none): true when level k shows the meshes of the level before (k = 0: the asset's own)
  // instead of meshes of its own, so that a near-copy of a level is not stored twice; its LOD node is still
  // written, so readers that expect a fixed number of levels get them. levels[k] should then equal them.
  std::vector<bool> shows_previous;

  // Meshes written beside the chain, outside MSFT_lod (collision hulls, occluders): one per asset mesh.
  struct Separate {
    std::string suffix;  // "_collision": appended to the names of its meshes and nodes
    std::vector<Mesh> meshes;
  };
  std::vector<Separate> separate;
};

// Writes `asset` (its meshes as LOD0) and `lods` as one .gltf (+ "<stem>.bin", + copied external images) or
// .glb, chosen by the extension of `path`; every file atomically. Throws IoError for another extension, a
// chain whose shape does not match the asset, or anything save_asset would refuse.
void save_gltf_lods(const Asset& asset, const LodChain& lods, const std::filesystem::path& path,
                    const SaveOptions& options = {});

}  // namespace lodforge::io
