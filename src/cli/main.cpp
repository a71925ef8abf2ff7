// bgkmap: BGK-L occupancy maps from range scans. Subcommands live in their own files.
#include <cstdio>
#include <exception>
#include <optional>
#include <string>
#include <vector>

#include "bgkmap/io/errors.hpp"
#include "bgkmap/methods/param_error.hpp"
#include "cli/commands.hpp"
#include "cli/did_you_mean.hpp"
#include "cli/omp_wait_policy.hpp"

namespace {

// Messages quote bytes of files and flags: their control bytes (a newline, a terminal escape)
// are shown as '?', so that every error stays one plain line.
std::string printable(const char* message) {
  std::string line(message);
  for (char& c : line)
    if ((static_cast<unsigned char>(c) < 0x20 && c != '\t') || c == 0x7f) c = '?';
  return line;
}

}  // namespace

int main(int argc, char** argv) {
  bgkmap::cli::restart_with_passive_waiting(argc, argv);
  CLI::App app{"bgkmap: Bayesian generalized kernel (BGK-L) occupancy maps from range scans, on OpenCL or OpenMP"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "bgkmap " BGKMAP_VERSION);
  bgkmap::cli::add_commands(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) return app.exit(e);  // --help, --version
    // A usage error: one line in the style of every other error, exit 2 (input errors exit 1).
    // A mistyped name is the likeliest cause of any of them, so it is named first.
    if (const std::optional<std::string> unknown = bgkmap::cli::unknown_name_error(app)) {
      std::fprintf(stderr, "bgkmap: error: %s\n", printable(unknown->c_str()).c_str());
      return 2;
    }
    const std::vector<CLI::App*> parsed = app.get_subcommands();
    const std::string help = parsed.empty() ? "bgkmap --help" : "bgkmap " + parsed.front()->get_name() + " --help";
    std::fprintf(stderr, "bgkmap: error: %s (see %s)\n", printable(e.what()).c_str(), help.c_str());
    return 2;
  } catch (const bgkmap::ParamError& e) {
    // Parameters the library refuses after the options were read (--ell's reach): named as flags.
    std::fprintf(stderr, "bgkmap: error: %s\n", printable(e.as_flags().c_str()).c_str());
    return 1;
  } catch (const std::exception& e) {
    // Subcommand actions run inside parse(); their errors end up here as one line.
    std::fprintf(stderr, "bgkmap: error: %s\n", printable(e.what()).c_str());
    return 1;
  }
  return 0;
}
