// CARMEN laser logs: every line through the reader, every scan it gives.
#include "bgkmap/io/carmen_log.hpp"
#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto file = bgkmap::fuzz::write_input(data, size, ".log");
  bgkmap::fuzz::expect_clean([&] { bgkmap::fuzz::read_every_scan<bgkmap::CarmenLogReader>(file); });
  return 0;
}
