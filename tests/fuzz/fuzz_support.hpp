// What the libFuzzer harnesses share: a scratch folder for the inputs of readers that take a path, the checks
// every loaded asset must pass, and the failure report.
//
// A failure is anything but the documented outcome. A reader either returns an asset or throws io::IoError
// (io/asset.hpp); any other exception leaves LLVMFuzzerTestOneInput uncaught, so std::terminate aborts with the
// throw site still on the stack, and libFuzzer saves the input as a crash. Checks that fail call fail().
#pragma once

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <system_error>

#include "lodforge/core/validate.hpp"
#include "lodforge/io/asset.hpp"

namespace lodforge::fuzz {

[[noreturn]] inline void fail(const std::string& what) {
  std::fprintf(stderr, "fuzz check failed: %s\n", what.c_str());
  std::abort();  // libFuzzer saves the input that got here
}

inline std::string_view as_text(const std::uint8_t* data, std::size_t size) {
  return {reinterpret_cast<const char*>(data), size};
}

// One folder per process (libFuzzer's -jobs and -fork run several), removed at a normal exit.
class ScratchDir {
 public:
  ScratchDir() : path_(std::filesystem::temp_directory_path() / ("lodforge-fuzz-" + std::to_string(::getpid()))) {
    std::filesystem::create_directories(path_);
  }
  ~ScratchDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

inline const std::filesystem::path& scratch_dir() {
  static const ScratchDir dir;
  return dir.path();
}

// Writes the input to scratch_dir()/in/name, for the readers that take a path (glTF, load_config). URIs in it
// resolve inside in/, never to what output_path() files earlier inputs left, so each input runs the same alone.
inline std::filesystem::path write_input(std::string_view name, std::string_view bytes) {
  const std::filesystem::path path = scratch_dir() / "in" / name;
  std::filesystem::create_directories(path.parent_path());
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  out.close();
  if (!out) fail("cannot write " + path.string());
  return path;
}

// Where a harness writes what it accepted (scratch_dir()/out/name).
inline std::filesystem::path output_path(std::string_view name) {
  const std::filesystem::path path = scratch_dir() / "out" / name;
  std::filesystem::create_directories(path.parent_path());
  return path;
}

// What every accepted file must give: the readers range-check what they read (io/formats.hpp), and every later
// stage indexes by these arrays unchecked.
inline void check_asset(const io::Asset& asset) {
  for (std::size_t m = 0; m < asset.meshes.size(); ++m) {
    const ValidationReport report = validate(asset.meshes[m]);
    if (report.out_of_range_indices > 0 || report.attribute_size_errors > 0) {
      std::string messages;
      for (const std::string& line : report.messages) messages += "\n  " + line;
      fail("mesh " + std::to_string(m) + " of an accepted file is inconsistent:" + messages);
    }
  }
}

// The harness of a reader that takes the bytes in memory (OBJ, PLY, OFF, STL): read, check, write back the
// same format. `name` is the path the messages name; its extension is the format's.
template <class Read, class Write>
void fuzz_reader(const std::uint8_t* data, std::size_t size, const char* name, Read&& read, Write&& write) {
  if (size == 0) return;  // load_asset refuses an empty file before any reader sees it
  io::Asset asset;
  try {
    asset = read(std::filesystem::path(name), as_text(data, size));
  } catch (const io::IoError&) {
    return;  // the documented rejection
  }
  check_asset(asset);
  try {
    write(asset);
  } catch (const io::IoError&) {
    // save_asset's documented error
  }
}

// The harness of a reader that takes a path (glTF, GLB: the JSON may name other files beside it): the bytes go
// to scratch_dir()/input.EXT, load_asset reads them, and what it accepts is checked and saved as output.EXT.
inline void fuzz_asset_file(const std::uint8_t* data, std::size_t size, std::string_view extension) {
  const std::filesystem::path path = write_input("input." + std::string(extension), as_text(data, size));
  io::Asset asset;
  try {
    asset = io::load_asset(path);
  } catch (const io::IoError&) {
    return;  // the documented rejection
  }
  check_asset(asset);
  try {
    io::save_asset(asset, output_path("output." + std::string(extension)));
  } catch (const io::IoError&) {
    // save_asset's documented error
  }
}

}  // namespace lodforge::fuzz
