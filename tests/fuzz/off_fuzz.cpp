// libFuzzer harness: the OFF reader on any bytes, then the OFF writer on what it accepts (fuzz_support.hpp).
#include "fuzz_support.hpp"
#include "lodforge/io/formats.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  lodforge::fuzz::fuzz_reader(
      data, size, "input.off",
      [](const std::filesystem::path& path, std::string_view bytes) {
        return lodforge::io::read_off(path, bytes, lodforge::io::LoadOptions{});
      },
      [](const lodforge::io::Asset& asset) { (void)lodforge::io::write_off(asset); });
  return 0;
}
