// `build --config`: the YAML parameter file, read by the command line's own options code (every
// key, the method and its parameters, the back end), then resolved as a build resolves it.
#include <CLI/CLI.hpp>

#include <string>

#include "cli/build_options.hpp"
#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto file = bgkmap::fuzz::write_input(data, size, ".yaml");
  bgkmap::fuzz::expect_clean([&] {
    CLI::App app;
    bgkmap::cli::BuildOptions options;
    options.add_to(app);
    app.parse("--config " + file.string(), false);
    options.resolve_params();
    options.resolve_method_params();
    options.resolve_backend();
    options.method();
  });
  return 0;
}
