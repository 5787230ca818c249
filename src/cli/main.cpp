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
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "commands.hpp"

namespace {

// One line on stderr, whatever the exception's text holds.
void internal_error(std::string what) {
  std::replace(what.begin(), what.end(), '\n', ' ');
  std::fflush(stdout);
  std::fprintf(stderr, "internal error: %s\n", what.c_str());
}

// Edits (insert, delete, substitute, swap two neighbours) between two words.
std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::vector<std::size_t>> d(a.size() + 1, std::vector<std::size_t>(b.size() + 1));
  for (std::size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    for (std::size_t j = 1; j <= b.size(); ++j) {
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  }
  return d[a.size()][b.size()];
}

// The known word closest to a typo, when close enough to be what was meant (first of ties).
std::optional<std::string> closest(std::string_view word, const std::vector<std::string>& known) {
  const std::size_t limit = word.size() <= 4 ? 1 : 2;
  std::optional<std::string> best;
  std::size_t best_distance = limit + 1;
  for (const std::string& k : known) {
    const std::size_t distance = edit_distance(word, k);
    if (distance < best_distance) best = k, best_distance = distance;
  }
  return best;
}

// Unknown commands and options, named with a guess, before CLI11 parses: CLI11 would report a missing
// required option first, or list the unknown word among "arguments not expected".
std::optional<std::string> unknown_word(const CLI::App& app, int argc, char** argv) {
  std::vector<std::string> commands;
  for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; })) {
    commands.push_back(sub->get_name());
  }
  int first = 1;
  while (first < argc && argv[first][0] == '-') {
    const std::string_view a = argv[first];
    if (a == "--help" || a == "-h" || a == "--version") return std::nullopt;
    ++first;
  }
  if (first >= argc) return std::nullopt;
  const std::string name = argv[first];
  const CLI::App* sub = nullptr;
  for (const CLI::App* s : app.get_subcommands([](const CLI::App*) { return true; })) {
    if (s->get_name() == name) sub = s;
  }
  if (sub == nullptr) {
    std::string message = "unknown command " + name;
    if (const auto guess = closest(name, commands)) {
      message += " (did you mean " + *guess + "?)";
    } else {
      std::string list;
      for (const std::string& c : commands) list += (list.empty() ? "" : ", ") + c;
      message += " (commands: " + list + ")";
    }
    return message;
  }
  std::vector<std::string> options;
  for (const CLI::Option* o : sub->get_options()) {
    for (const std::string& l : o->get_lnames()) options.push_back("--" + l);
  }
  for (int i = first + 1; i < argc; ++i) {
    const std::string_view a = argv[i];
    if (a == "--") break;
    if (a.size() < 3 || a.substr(0, 2) != "--") continue;
    const std::string option(a.substr(0, a.find('=')));
    if (option == "--help" || std::find(options.begin(), options.end(), option) != options.end()) continue;
    std::string message = "unknown option " + option + " for " + name;
    if (const auto guess = closest(option, options)) message = "unknown option " + option + " (did you mean " + *guess + "?)";
    return message + "; see lodforge " + name + " --help";
  }
  return std::nullopt;
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
  lodforge::cli::register_diff_reports(app);
  lodforge::cli::register_bench(app);
  lodforge::cli::register_terrain(app);

  if (const auto problem = unknown_word(app, argc, argv)) {
    std::fprintf(stderr, "error: %s\n", problem->c_str());
    return 2;
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) return app.exit(e);  // --help, --version
    std::string what = e.what();
    std::replace(what.begin(), what.end(), '\n', ' ');
    std::fprintf(stderr, "error: %s (see lodforge --help)\n", what.c_str());
    return 2;
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
