// OctoMap scan graphs (.graph): the layout check, then every node decoded and transformed.
#include "bgkmap/io/scan_graph_io.hpp"
#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto file = bgkmap::fuzz::write_input(data, size, ".graph");
  bgkmap::fuzz::expect_clean([&] { bgkmap::fuzz::read_every_scan<bgkmap::ScanGraphReader>(file); });
  return 0;
}
