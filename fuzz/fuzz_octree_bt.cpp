// eval's .bt reader: its byte check, then liboctomap's OcTree::readBinary behind it.
#include "eval/octree_file.hpp"
#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto file = bgkmap::fuzz::write_input(data, size, ".bt");
  bgkmap::fuzz::expect_clean([&] { bgkmap::eval::read_octree_file(file, bgkmap::eval::OctreeFile::kBinary); });
  return 0;
}
