// PCD scans through read_pcd: the strict header check, the body check of each encoding (ascii,
// binary, binary_compressed) and PCL's decoder behind them.
#include "bgkmap/io/pcd_io.hpp"
#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto file = bgkmap::fuzz::write_input(data, size, ".pcd");
  bgkmap::fuzz::expect_clean([&] { bgkmap::read_pcd(file); });
  return 0;
}
