// `build --config`: the YAML parameter file, read by the command line's own options code (every
// key, the method and its parameters, the back end), then resolved as a build resolves it.
#include <CLI/CLI.hpp>

#include <string>

#include "cli/build_options.hpp"
#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto file = bgkmap::fuzz::write_input(data, size, ".yaml");
  // The options are declared once (most of an input's time was building them); each input is a
  // new parse of the same command line, as CLI11's clear() allows.
  static CLI::App app;
  static bgkmap::cli::BuildOptions options;
  static const bool declared = (options.add_to(app), true);
  (void)declared;
  app.clear();
  app.parse("--config " + file.string(), false);
  bgkmap::fuzz::expect_clean([&] {
    options.resolve_params();
    options.resolve_method_params();
    options.resolve_backend();
    options.method();
  });
  return 0;
}
