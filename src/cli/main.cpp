// The `lodforge` command. Subcommands: info, convert, simplify, eval, demo, render-wire, run,
// validate-config, merge-reports, bench.
//
// Exit codes (documented in --help and README):
//   0  success
//   1  some inputs failed while others succeeded (batch commands)
//   2  usage error, or bad input (a file that cannot be read or is invalid); nothing is written
//   3  internal error
//   130  `run` stopped by Ctrl-C or SIGTERM (assets in flight finished, report written; a re-run resumes)
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <new>
#include <string>
#include <vector>

#include "commands.hpp"

namespace {

// One line on stderr, whatever the exception's text holds.
void internal_error(std::string what) {
  std::replace(what.begin(), what.end(), '\n', ' ');
  std::fflush(stdout);
  std::fprintf(stderr, "internal error: %s\n", what.c_str());
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "lodforge - regenerates level-of-detail chains of game assets.\n"
      "Exit codes: 0 success, 1 some inputs failed, 2 usage error or bad input (nothing written), 3 internal error,\n"
      "130 `run` interrupted (Ctrl-C or SIGTERM: finished assets kept, report written; a re-run resumes)."};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("lodforge ") + lodforge::cli::version());

  lodforge::cli::register_info(app);
  lodforge::cli::register_convert(app);
  lodforge::cli::register_simplify(app);
  lodforge::cli::register_eval(app);
  lodforge::cli::register_demo(app);
  lodforge::cli::register_render_wire(app);
  lodforge::cli::register_run(app);
  lodforge::cli::register_validate_config(app);
  lodforge::cli::register_merge_reports(app);
  lodforge::cli::register_bench(app);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);
    return rc == 0 ? 0 : 2;
  } catch (const std::bad_alloc&) {
    internal_error("out of memory");
    return 3;
  } catch (const std::exception& e) {
    // Commands catch bad input where they read it (exit 2); whatever else escapes is ours. Outputs are written
    // atomically, so nothing half-written is left.
    internal_error(e.what());
    return 3;
  } catch (...) {
    internal_error("unknown exception");
    return 3;
  }
  return lodforge::cli::exit_code();
}
