// The bgkmap command: one file per subcommand, each registering its options and action here.
#pragma once

#include <CLI/CLI.hpp>

namespace bgkmap::cli {

void add_build_command(CLI::App& app);     // build_command.cpp
void add_query_command(CLI::App& app);     // query_command.cpp
void add_info_command(CLI::App& app);      // info_command.cpp
void add_devices_command(CLI::App& app);   // devices_command.cpp
void add_simulate_command(CLI::App& app);  // simulate_command.cpp
void add_eval_command(CLI::App& app);      // eval_command.cpp
void add_station_keeping_command(CLI::App& app);  // station_keeping_command.cpp
void add_render_command(CLI::App& app);    // render_command.cpp
void add_merge_command(CLI::App& app);     // merge_command.cpp
void add_view_command(CLI::App& app);      // view_command.cpp
void add_export_command(CLI::App& app);    // export_command.cpp
void add_diff_command(CLI::App& app);      // diff_command.cpp
void add_tune_command(CLI::App& app);      // tune_command.cpp

// Every subcommand above (commands.cpp), each flag taking one value per use (-o a.bgk -o a.ot):
// a flag of several values would take the next input as one more (`build -o a.bgk scans/ ...`).
void add_commands(CLI::App& app);

}  // namespace bgkmap::cli
