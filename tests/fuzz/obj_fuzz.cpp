// libFuzzer harness: the OBJ reader on any bytes, then the OBJ writer on what it accepts (fuzz_support.hpp).
#include "fuzz_support.hpp"
#include "lodforge/io/formats.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  lodforge::fuzz::fuzz_reader(
      data, size, "input.obj",
      [](const std::filesystem::path& path, std::string_view bytes) {
        return lodforge::io::read_obj(path, bytes, lodforge::io::LoadOptions{});
      },
      [](const lodforge::io::Asset& asset) { (void)lodforge::io::write_obj(asset, "input.obj"); });
  return 0;
}
