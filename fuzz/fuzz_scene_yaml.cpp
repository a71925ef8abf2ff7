// simulate's scene files: YAML parsing, the schema and SimulationSpec::validate.
#include <string>

#include "bgkmap/sim/spec.hpp"
#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  bgkmap::fuzz::expect_clean([&] { bgkmap::sim::parse_spec(text, "fuzz.yaml"); });
  return 0;
}
