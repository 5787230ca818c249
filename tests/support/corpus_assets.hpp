// Lists of corpus files (../shared/corpus, see its MANIFEST.md) that several test suites and benchmarks run
// over. Header-only and free of GoogleTest, so benchmarks can include it too.
#pragma once

namespace lodforge::testing {

// The glTF and skinned assets with attributes (UV seams, normals, tangents, materials, skins, morphs): the
// attribute-aware simplification tests and benchmark and the glTF validator tests run over these.
inline constexpr const char* kGltfAttributeAssets[] = {
    "gltf/Duck.glb",
    "gltf/CesiumMilkTruck.glb",
    "gltf/MorphStressTest.gltf",
    "gltf/armor-knight.gltf",
    "gltf/Avocado/Avocado.gltf",
    "gltf/AnisotropyBarnLamp/AnisotropyBarnLamp.gltf",
    "gltf/FlightHelmet/FlightHelmet.gltf",
    "skinned/CesiumMan.glb",
    "skinned/Fox.glb",
    "skinned/RiggedFigure.glb",
    "skinned/RiggedSimple.glb",
};

}  // namespace lodforge::testing
