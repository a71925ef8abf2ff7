// ROS 1 bags (.bag, format 2.0, plain, bz2 or lz4 chunks): one scan per message of the chosen
// topics, in bag time order, read one message at a time through Debian's rosbag_storage.
//
// Messages that give scans:
//   sensor_msgs/PointCloud2  the x, y, z fields (float32, one each), any point_step and row_step;
//                            every point of width x height is a reading (NaN ones are dropped and
//                            counted by preprocessing). is_bigendian set is refused.
//   sensor_msgs/LaserScan    planar: beam i at angle_min + i * angle_increment in the sensor's x-y
//                            plane. A reading below range_min (or NaN, or 0) is no measurement (a
//                            NaN point); one at or above range_max, or +inf, is the laser's "no
//                            return", kept along its beam with Scan::no_return_range_m = range_max,
//                            as the CARMEN reader keeps its codes (carmen_log.hpp).
// The points are in the message's header.frame_id; the reader maps them to the world by the
// message's pose, and the scan's origin is that pose's translation. The pose comes from
//   tf        (RosbagPoseSource::tf_frame set): every /tf and /tf_static message of the bag is put
//             in a tf2::BufferCore first, then each message's pose is the transform tf_frame <-
//             header.frame_id at header.stamp (interpolated as tf does);
//   a list    (RosbagPoseSource::poses): the i-th message of the chosen topics takes poses[i].
//
// Errors. A bag that cannot be opened or read (truncated, garbled, an unknown compression), a
// topic the bag does not hold, or a topic of another message type throws InputError naming the
// bag; the reader is then done. A message that cannot be mapped (its transform cannot be looked
// up, a malformed cloud, is_bigendian) throws RosbagMessageError naming the bag, topic, time and
// the flags; the reader stays usable and next() goes on with the following message.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "bgkmap/core/scan.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/pose_list.hpp"

namespace bgkmap {

// One message of a bag that could not be made a scan; the bag's later messages still can.
class RosbagMessageError : public InputError {
 public:
  using InputError::InputError;
};

// True for a file name ending in .bag (case-insensitive).
bool is_rosbag_name(const std::filesystem::path& file);

struct RosbagPoseSource {
  std::string tf_frame;           // the fixed frame of /tf: each message's pose is looked up in it
  std::vector<PoseRecord> poses;  // or one pose per message, in order (a --poses file's lines)
  std::filesystem::path poses_file;  // where `poses` came from, for messages
};

class RosbagReader {
 public:
  // Opens the bag, checks the topics (each present, of type PointCloud2 or LaserScan) and, with a
  // tf frame, reads /tf and /tf_static. Throws InputError naming the bag.
  RosbagReader(const std::filesystem::path& bag, const std::vector<std::string>& topics, RosbagPoseSource poses);
  ~RosbagReader();
  RosbagReader(RosbagReader&&) noexcept;
  RosbagReader& operator=(RosbagReader&&) noexcept;

  // How many messages of `topics` the bag holds (from its index; the messages are not read).
  static uint64_t count_messages(const std::filesystem::path& bag, const std::vector<std::string>& topics);

  // The next message as a world-frame scan; false after the last. Throws as above.
  bool next(Scan& scan);
  // How many messages it reads in all (from the bag's index).
  uint64_t size() const;

  // Messages of the bag not read as scans, by type (the other topics' and /tf's), counted when the
  // bag is opened.
  const std::map<std::string, uint64_t>& skipped_messages() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace bgkmap
