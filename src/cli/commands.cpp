#include "cli/commands.hpp"

#include <string>

namespace bgkmap::cli {

namespace {
// --help then says "TEXT (repeatable)" where CLI11 says "TEXT ...", values one after another.
void one_value_per_use(CLI::App& cmd) {
  for (CLI::Option* opt : cmd.get_options()) {
    if (!opt->nonpositional() || opt->get_items_expected_max() < CLI::detail::expected_max_vector_size) continue;
    opt->allow_extra_args(false);
    std::string text = opt->get_type_name();
    if (!opt->get_default_str().empty()) text += "=" + opt->get_default_str();
    text += opt->get_delimiter() == ',' ? " (repeatable, or A,B)" : " (repeatable)";
    if (opt->get_required()) text += " REQUIRED";
    opt->option_text(text);
  }
}
}  // namespace

void add_commands(CLI::App& app) {
  add_build_command(app);
  add_query_command(app);
  add_info_command(app);
  add_devices_command(app);
  add_simulate_command(app);
  add_eval_command(app);
  add_station_keeping_command(app);
  add_render_command(app);
  add_merge_command(app);
  add_view_command(app);
  add_export_command(app);
  add_diff_command(app);
  add_tune_command(app);
  for (CLI::App* cmd : app.get_subcommands([](CLI::App*) { return true; })) one_value_per_use(*cmd);
}

}  // namespace bgkmap::cli
