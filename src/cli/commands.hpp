// Subcommand registration for the lodforge CLI; each command records its exit code.
#pragma once

#include <CLI/CLI.hpp>
#include <string>

#include "lodforge/simplify/simplify.hpp"

namespace lodforge::cli {

const char* version();
int exit_code();
void set_exit_code(int code);  // keeps the most severe code seen

// `--conservative none|bounding|occluder` into `name` (simplify and terrain spell it the same), and the mode
// it names.
CLI::Option* add_conservative_option(CLI::App* cmd, std::string& name, const std::string& help);
Conservative conservative_mode(const std::string& name);

void register_info(CLI::App& app);
void register_convert(CLI::App& app);
void register_simplify(CLI::App& app);
void register_eval(CLI::App& app);
void register_demo(CLI::App& app);
// render.cpp: SVG wireframes.
void register_render_wire(CLI::App& app);
// run.cpp: the batch commands.
void register_run(CLI::App& app);
void register_validate_config(CLI::App& app);
void register_merge_reports(CLI::App& app);
void register_diff_reports(CLI::App& app);
void register_bench(CLI::App& app);
// terrain.cpp: height maps to stitched patch chains.
void register_terrain(CLI::App& app);

}  // namespace lodforge::cli
