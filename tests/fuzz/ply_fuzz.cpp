// libFuzzer harness: the PLY reader on any bytes, then the PLY writer on what it accepts (fuzz_support.hpp).
#include "fuzz_support.hpp"
#include "lodforge/io/formats.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  lodforge::fuzz::fuzz_reader(
      data, size, "input.ply",
      [](const std::filesystem::path& path, std::string_view bytes) {
        return lodforge::io::read_ply(path, bytes, lodforge::io::LoadOptions{});
      },
      [](const lodforge::io::Asset& asset) { (void)lodforge::io::write_ply(asset, asset.binary); });
  return 0;
}
