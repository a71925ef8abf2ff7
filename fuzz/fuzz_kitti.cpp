// KITTI sequence folders. The first byte picks the file the rest becomes (calib.txt, poses.txt
// or velodyne/000001.bin); the other files of the two-scan folder stay valid, so each file's
// checks are reached on their own.
#include <filesystem>
#include <fstream>
#include <string>

#include "bgkmap/io/kitti_io.hpp"
#include "fuzz_support.hpp"

namespace {

const char kCalib[] = "P0: 1 0 0 0 0 1 0 0 0 0 1 0\nTr: 0 -1 0 0 0 0 -1 0 1 0 0 0\n";
const char kPoses[] = "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0.5 0 1 0 0 0 0 1 1\n";
const float kPoints[] = {1, 0, 0, 0.5f, 2, 1, -0.5f, 0.25f};

void write(const std::filesystem::path& file, const void* bytes, size_t size) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out.write(static_cast<const char*>(bytes), static_cast<std::streamsize>(size));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  static const std::filesystem::path folder = [] {
    const std::filesystem::path dir = bgkmap::fuzz::scratch_path(".kitti");
    std::filesystem::create_directories(dir / "velodyne");
    return dir;
  }();
  write(folder / "calib.txt", kCalib, sizeof kCalib - 1);
  write(folder / "poses.txt", kPoses, sizeof kPoses - 1);
  write(folder / "velodyne" / "000000.bin", kPoints, sizeof kPoints);
  write(folder / "velodyne" / "000001.bin", kPoints, sizeof kPoints);
  static const char* const kTargets[] = {"calib.txt", "poses.txt", "velodyne/000001.bin"};
  write(folder / kTargets[data[0] % 3], data + 1, size - 1);
  bgkmap::fuzz::expect_clean([&] { bgkmap::fuzz::read_every_scan<bgkmap::KittiSequenceReader>(folder); });
  return 0;
}
