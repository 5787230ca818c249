// libFuzzer harness: the glob matcher (batch/glob.hpp). Input: the pattern, a newline, then the path (the rest
// of the input). compile() must throw std::invalid_argument exactly when problem() names a problem, with that
// message; matching never throws; a pattern without special characters matches only the same path.
#include <stdexcept>

#include "fuzz_support.hpp"
#include "lodforge/batch/glob.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace batch = lodforge::batch;
  namespace fuzz = lodforge::fuzz;
  const std::string_view input = fuzz::as_text(data, size);
  const std::size_t newline = input.find('\n');
  const std::string_view pattern = input.substr(0, newline);
  const std::string_view path = newline == std::string_view::npos ? std::string_view() : input.substr(newline + 1);

  const std::string problem = batch::Glob::problem(pattern);
  try {
    const batch::Glob glob = batch::Glob::compile(pattern);
    if (!problem.empty()) fuzz::fail("compile() accepts a pattern problem() rejects: " + problem);
    const bool matched = glob.matches(path);
    if (batch::Glob(glob).matches(path) != matched) fuzz::fail("a copy of the glob matches differently");
    if (batch::glob_match(pattern, path) != matched) fuzz::fail("glob_match() disagrees with Glob::matches()");
    if (pattern.find_first_of("*?[]{},\\") == std::string_view::npos && matched != (pattern == path)) {
      fuzz::fail("a pattern without special characters must match exactly itself");
    }
  } catch (const std::invalid_argument& e) {
    if (problem != e.what()) fuzz::fail("compile() throws '" + std::string(e.what()) + "', problem() says '" + problem + "'");
  }
  return 0;
}
