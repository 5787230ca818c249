// What the cluster test scripts need from the C++ test support, as a command (they cannot include a header):
//   cluster_test_tool write-library DIR COUNT   the batch tests' generated library (library_fixture.hpp) in
//                                               DIR/lib and its test config in DIR/batch_config.json
//   cluster_test_tool same-report A.json B.json exit 0 when two report.json files of the same work agree,
//                                               1 (printing the differences) when they do not, 2 on bad input
#include <cstdio>
#include <exception>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "../unit/batch/library_fixture.hpp"
#include "lodforge/batch/report.hpp"
#include "lodforge/io/file.hpp"

namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;
namespace testlib = lodforge::batch::testlib;

// A report less what legitimately differs between two runs of the same work: timings ("seconds" anywhere,
// without_timings), the job count, and the folders a run names (input_dir and output_dir: an unsharded run names
// its own, a merged report none). Everything else (each asset's record, LODs, errors, outputs, the summary's
// counts, "changes" and its absence) must match.
Json comparable(const fs::path& file) {
  Json j = Json::parse(lodforge::io::read_file(file));
  j["jobs"] = 0;
  j.erase("input_dir");
  j.erase("output_dir");
  return lodforge::batch::without_timings(std::move(j));
}

int usage() {
  std::fprintf(stderr,
               "usage: cluster_test_tool write-library DIR COUNT\n"
               "       cluster_test_tool same-report A.json B.json\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 4) return usage();
  const std::string command = argv[1];
  try {
    if (command == "write-library") {
      const fs::path dir = argv[2];
      const testlib::Library lib = testlib::write_library(dir / "lib", std::stoi(argv[3]));
      testlib::write_config(dir);
      std::printf("%zu assets in %s, config %s\n", lib.files.size(), lib.root.c_str(),
                  (dir / "batch_config.json").c_str());
      return 0;
    }
    if (command == "same-report") {
      const Json a = comparable(argv[2]), b = comparable(argv[3]);
      if (a == b) return 0;
      const Json patch = Json::diff(a, b);
      std::printf("%s and %s differ (beyond timings, job count, folders) in %zu place(s):\n", argv[2], argv[3],
                  patch.size());
      for (std::size_t i = 0; i < patch.size() && i < 20; ++i) std::printf("  %s\n", patch[i].dump().c_str());
      return 1;
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 2;
  }
  return usage();
}
