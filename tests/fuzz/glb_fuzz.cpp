// libFuzzer harness: load_asset on a GLB (binary container) file, then save_asset to the same format if it was
// accepted (fuzz_support.hpp, fuzz_asset_file: the glTF reader takes a path, so the input is written first).
#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  lodforge::fuzz::fuzz_asset_file(data, size, "glb");
  return 0;
}
