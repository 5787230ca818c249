// libFuzzer harness: load_asset on a GLB (binary container) file, then save_asset to the
// same format if it was accepted (fuzz_support.hpp). The glTF reader takes a path, so each input is written to
// a scratch folder first (fuzz_support.hpp, write_input).
#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace io = lodforge::io;
  namespace fuzz = lodforge::fuzz;
  const std::filesystem::path path = fuzz::write_input("input.glb", fuzz::as_text(data, size));
  io::Asset asset;
  try {
    asset = io::load_asset(path);
  } catch (const io::IoError&) {
    return 0;  // the documented rejection
  }
  fuzz::check_asset(asset);
  try {
    io::save_asset(asset, fuzz::output_path("output.glb"));
  } catch (const io::IoError&) {
    // save_asset's documented error
  }
  return 0;
}
