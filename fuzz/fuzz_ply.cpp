// PLY scans: the header check and PCL's decoder behind it (ascii and both binary byte orders).
#include "bgkmap/io/point_text_io.hpp"
#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto file = bgkmap::fuzz::write_input(data, size, ".ply");
  bgkmap::fuzz::expect_clean([&] { bgkmap::read_ply(file); });
  return 0;
}
