// ROS 1 bags: the record check (rosbag_check.cpp), Debian's rosbag_storage behind it, tf2 and the
// PointCloud2 / LaserScan decoding. The first byte picks the poses: even, /tf in frame "map";
// odd, a list of two poses (one a message). A message refused on its own is passed over, as
// --skip-bad-inputs does, so the bag's later messages are read too.
#include "bgkmap/io/rosbag_reader.hpp"
#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const auto file = bgkmap::fuzz::write_input(data + 1, size - 1, ".bag");
  const std::vector<std::string> topics = {"/points", "/scan"};
  bgkmap::RosbagPoseSource poses;
  if (data[0] % 2 == 0) {
    poses.tf_frame = "map";
  } else {
    bgkmap::PoseRecord p;
    p.pose.position = {1.5f, 3.3f, 1.0f};
    poses.poses = {p, p};
    poses.poses_file = "poses.txt";
  }
  bgkmap::fuzz::expect_clean([&] { bgkmap::RosbagReader::count_messages(file, topics); });
  bgkmap::fuzz::expect_clean([&] {
    bgkmap::RosbagReader reader(file, topics, poses);
    bgkmap::Scan scan;
    for (;;) {
      try {
        if (!reader.next(scan)) break;
      } catch (const bgkmap::RosbagMessageError&) {
      }
    }
  });
  return 0;
}
