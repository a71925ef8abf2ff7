// XYZ text scans and TUM pose lists (the poses that place them): the same bytes through both.
#include "bgkmap/io/point_text_io.hpp"
#include "bgkmap/io/pose_list.hpp"
#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto file = bgkmap::fuzz::write_input(data, size, ".xyz");
  bgkmap::fuzz::expect_clean([&] { bgkmap::read_xyz(file); });
  bgkmap::fuzz::expect_clean([&] { bgkmap::read_pose_list(file); });
  return 0;
}
