#include "bgkmap/io/rosbag_reader.hpp"

#include <console_bridge/console.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/LaserScan.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2/buffer_core.h>
#include <tf2/exceptions.h>
#include <tf2_msgs/TFMessage.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>
#include <limits>
#include <new>
#include <optional>
#include <set>
#include <utility>

#include "bgkmap/core/memory_limit.hpp"
#include "rosbag_check.hpp"

namespace bgkmap {

namespace {

constexpr const char* kPointCloud2 = "sensor_msgs/PointCloud2";
constexpr const char* kLaserScan = "sensor_msgs/LaserScan";
// A no-return reading is kept this much beyond range_max, so that float rounding of the world
// point never brings it under Scan::no_return_range_m (preprocessing then takes only its direction).
constexpr double kNoReturnMargin = 1e-4;

// Rotation and translation, in double: the pose a message's points are mapped by.
struct RigidTransform {
  double qw = 1, qx = 0, qy = 0, qz = 0;
  double t[3] = {0, 0, 0};

  Vec3f apply(double x, double y, double z) const {
    // v + 2w (u x v) + 2 u x (u x v), u = (qx, qy, qz), as Pose::rotate.
    const double tx = 2 * (qy * z - qz * y), ty = 2 * (qz * x - qx * z), tz = 2 * (qx * y - qy * x);
    return {static_cast<float>(x + qw * tx + (qy * tz - qz * ty) + t[0]),
            static_cast<float>(y + qw * ty + (qz * tx - qx * tz) + t[1]),
            static_cast<float>(z + qw * tz + (qx * ty - qy * tx) + t[2])};
  }
  Pose pose() const {
    Pose p;
    p.position = {static_cast<float>(t[0]), static_cast<float>(t[1]), static_cast<float>(t[2])};
    p.qw = static_cast<float>(qw), p.qx = static_cast<float>(qx), p.qy = static_cast<float>(qy), p.qz = static_cast<float>(qz);
    return p;
  }
};

// False for a quaternion that is not finite or far from unit length; else normalises it.
bool normalise(RigidTransform& r) {
  const double n = std::sqrt(r.qw * r.qw + r.qx * r.qx + r.qy * r.qy + r.qz * r.qz);
  if (!std::isfinite(n) || std::abs(n - 1) > 1e-3 || !std::isfinite(r.t[0] + r.t[1] + r.t[2])) return false;
  r.qw /= n, r.qx /= n, r.qy /= n, r.qz /= n;
  return true;
}

// tf2 names frames without a leading slash; ROS 1 bags of tf's days often carry one.
std::string frame_name(const std::string& frame) {
  return !frame.empty() && frame.front() == '/' ? frame.substr(1) : frame;
}

// Names and library messages from a bag may hold any bytes: control and non-ASCII ones shown as
// '?', so the error stays one plain line.
std::string one_line(std::string text) {
  for (char& c : text)
    if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) >= 0x7f) c = c == '\n' ? ' ' : '?';
  return text;
}

std::string time_text(const ros::Time& t) {
  char text[32];
  std::snprintf(text, sizeof text, "%u.%09u", t.sec, t.nsec);
  return text;
}

std::string joined(const std::vector<std::string>& names) {
  std::string out;
  for (const std::string& n : names) out += (out.empty() ? "" : ", ") + n;
  return out;
}

const sensor_msgs::PointField* find_field(const sensor_msgs::PointCloud2& cloud, const char* name) {
  for (const sensor_msgs::PointField& f : cloud.fields)
    if (f.name == name) return &f;
  return nullptr;
}

}  // namespace

bool is_rosbag_name(const std::filesystem::path& file) {
  std::string ext = file.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == ".bag";
}

struct RosbagReader::State {
  std::filesystem::path file;
  RosbagPoseSource poses;
  rosbag::Bag bag;
  std::optional<rosbag::View> view;
  rosbag::View::iterator it;
  std::optional<tf2::BufferCore> tf;
  std::map<std::string, uint64_t> skipped;
  uint64_t next_message = 0;  // index among the chosen topics' messages
  bool done = false;

  InputError bag_error(const std::string& what) const { return InputError(file, one_line(what)); }

  RosbagMessageError message_error(const rosbag::MessageInstance& m, const std::string& what) const {
    return RosbagMessageError(file, one_line(m.getTopic() + " at bag time " + time_text(m.getTime()) + " (message " +
                                             std::to_string(next_message + 1) + " of the --topic messages): " + what));
  }

  void open(const std::vector<std::string>& topics) {
    io_detail::check_rosbag_structure(file);  // before rosbag_storage trusts its offsets
    bag.open(file.string(), rosbag::bagmode::Read);
    if (topics.empty())
      throw bag_error("a ROS bag needs the topics to map: give --topic NAME (PointCloud2 or LaserScan) for each");
    rosbag::View all(bag);
    std::map<std::string, std::string> type_of;  // topic -> message type
    for (const rosbag::ConnectionInfo* c : all.getConnections()) type_of[c->topic] = c->datatype;
    std::vector<std::string> present;  // the first few, for the message
    for (const auto& [topic, type] : type_of)
      if (present.size() < 12) present.push_back(topic + " (" + type + ")");
    if (type_of.size() > present.size()) present.push_back("... (" + std::to_string(type_of.size()) + " topics)");
    for (const std::string& topic : topics) {
      const auto found = type_of.find(topic);
      if (found == type_of.end())
        throw bag_error("no topic " + topic + " in the bag; it holds " + (present.empty() ? "none" : joined(present)) +
                        " (--topic)");
      if (found->second != kPointCloud2 && found->second != kLaserScan)
        throw bag_error("topic " + topic + " is " + found->second + ", not sensor_msgs/PointCloud2 or "
                        "sensor_msgs/LaserScan (--topic)");
    }
    const std::set<std::string> chosen(topics.begin(), topics.end());
    for (const auto& [topic, type] : type_of)
      if (!chosen.count(topic)) skipped[type] += rosbag::View(bag, rosbag::TopicQuery(topic)).size();
    if (!poses.tf_frame.empty()) read_tf();
    view.emplace(bag, rosbag::TopicQuery(topics));
    it = view->begin();
  }

  // Every /tf and /tf_static transform, into a buffer that keeps them all.
  void read_tf() {
    std::vector<std::pair<geometry_msgs::TransformStamped, bool>> transforms;  // and whether static
    rosbag::View tf_view(bag, rosbag::TopicQuery(std::vector<std::string>{"/tf", "/tf_static"}));
    for (const rosbag::MessageInstance& m : tf_view) {
      const tf2_msgs::TFMessage::ConstPtr msg = m.instantiate<tf2_msgs::TFMessage>();
      if (!msg) throw bag_error(m.getTopic() + " is " + m.getDataType() + ", not tf2_msgs/TFMessage");
      for (const geometry_msgs::TransformStamped& t : msg->transforms) transforms.emplace_back(t, m.getTopic() == "/tf_static");
    }
    double first = std::numeric_limits<double>::infinity(), last = -first;
    for (const auto& [t, is_static] : transforms) {
      first = std::min(first, t.header.stamp.toSec());
      last = std::max(last, t.header.stamp.toSec());
    }
    // Long enough that no transform of the bag is pruned; within ros::Time's range beyond `last`.
    const double keep = transforms.empty() ? 10.0 : std::min(last - first + 1.0, double(UINT32_MAX) - last - 1.0);
    tf.emplace(ros::Duration(std::max(keep, 1.0)));
    for (auto& [t, is_static] : transforms) {
      t.header.frame_id = frame_name(t.header.frame_id);
      t.child_frame_id = frame_name(t.child_frame_id);
      tf->setTransform(t, "bag", is_static);  // a malformed one is refused by tf2; lookups then fail
    }
  }

  RigidTransform pose_of(const rosbag::MessageInstance& m, const std_msgs::Header& header, uint64_t index) const {
    RigidTransform r;
    if (poses.tf_frame.empty()) {
      if (index >= poses.poses.size())
        throw InputError(poses.poses_file, std::to_string(poses.poses.size()) + " poses, but " + file.string() +
                                               " holds more messages (one pose a message, in order)");
      const Pose& p = poses.poses[index].pose;
      r.qw = p.qw, r.qx = p.qx, r.qy = p.qy, r.qz = p.qz;
      r.t[0] = p.position.x, r.t[1] = p.position.y, r.t[2] = p.position.z;
      return r;
    }
    const std::string frame = frame_name(header.frame_id);
    const std::string flags = "; check --tf-frame, give --poses, or pass such messages over with --skip-bad-inputs";
    if (header.stamp.isZero()) throw message_error(m, "header.stamp is 0, no time to look its pose up at" + flags);
    if (frame.empty()) throw message_error(m, "header.frame_id is empty" + flags);
    geometry_msgs::TransformStamped found;
    try {
      found = tf->lookupTransform(poses.tf_frame, frame, header.stamp);
    } catch (const tf2::TransformException& e) {
      throw message_error(m, "no transform " + poses.tf_frame + " <- " + frame + " at " + time_text(header.stamp) +
                                 " in /tf, /tf_static (" + e.what() + ")" + flags);
    }
    const geometry_msgs::Transform& t = found.transform;
    r.qw = t.rotation.w, r.qx = t.rotation.x, r.qy = t.rotation.y, r.qz = t.rotation.z;
    r.t[0] = t.translation.x, r.t[1] = t.translation.y, r.t[2] = t.translation.z;
    if (!normalise(r)) throw message_error(m, "the transform " + poses.tf_frame + " <- " + frame + " is not a rigid motion");
    return r;
  }

  void cloud_scan(const rosbag::MessageInstance& m, const sensor_msgs::PointCloud2& cloud, const RigidTransform& pose,
                  Scan& scan) const {
    if (cloud.is_bigendian) throw message_error(m, "a big-endian PointCloud2 (is_bigendian), which is not read");
    const sensor_msgs::PointField* axes[3] = {find_field(cloud, "x"), find_field(cloud, "y"), find_field(cloud, "z")};
    for (const sensor_msgs::PointField* f : axes)
      if (!f || f->datatype != sensor_msgs::PointField::FLOAT32 || f->count != 1 || uint64_t(f->offset) + 4 > cloud.point_step)
        throw message_error(m, "PointCloud2 needs fields x, y, z of one float32 each within point_step " +
                                   std::to_string(cloud.point_step));
    const uint64_t width = cloud.width, height = cloud.height, row = cloud.row_step, step = cloud.point_step;
    if (width * height > 0 && (width * step > row || height * row > cloud.data.size()))
      throw message_error(m, "PointCloud2 of " + std::to_string(width) + " x " + std::to_string(height) +
                                 " points (point_step " + std::to_string(step) + ", row_step " + std::to_string(row) +
                                 ") does not fit its " + std::to_string(cloud.data.size()) + " bytes of data");
    scan.points.clear();
    scan.points.reserve(width * height);
    const uint8_t* data = cloud.data.data();
    for (uint64_t v = 0; v < height; ++v)
      for (uint64_t u = 0; u < width; ++u) {
        const uint8_t* p = data + v * row + u * step;
        float xyz[3];
        for (int k = 0; k < 3; ++k) std::memcpy(&xyz[k], p + axes[k]->offset, 4);
        scan.points.push_back(pose.apply(xyz[0], xyz[1], xyz[2]));  // NaN stays NaN
      }
  }

  void laser_scan(const rosbag::MessageInstance& m, const sensor_msgs::LaserScan& laser, const RigidTransform& pose,
                  Scan& scan) const {
    const double range_max = laser.range_max, range_min = laser.range_min;
    if (!(range_max > 0) || !std::isfinite(range_max) || !std::isfinite(laser.angle_min) ||
        !std::isfinite(laser.angle_increment))
      throw message_error(m, "LaserScan with a range_max, angle_min or angle_increment that is not a positive finite number");
    scan.points.clear();
    scan.points.reserve(laser.ranges.size());
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (size_t i = 0; i < laser.ranges.size(); ++i) {
      double r = laser.ranges[i];
      if (std::isnan(r) || r <= 0 || r < range_min) {  // no measurement: dropped and counted by preprocessing
        scan.points.push_back({nan, nan, nan});
        continue;
      }
      if (r >= range_max) r = std::max(std::isfinite(r) ? r : 0.0, range_max) * (1 + kNoReturnMargin);
      const double a = double(laser.angle_min) + double(i) * double(laser.angle_increment);
      scan.points.push_back(pose.apply(r * std::cos(a), r * std::sin(a), 0.0));
    }
    scan.no_return_range_m = static_cast<float>(range_max);
  }

  // Before instantiating (its records were bounds-checked with the bag): a large message must fit
  // --max-memory, with its points, at most as many floats again as it has bytes.
  void check_size(const rosbag::MessageInstance& m) const {
    const double bytes = m.size();
    require_memory(2 * bytes, "a " + m.getTopic() + " message of " + file.string() + " (" + format_bytes(bytes) + ")",
                   "give a larger --max-memory");
  }

  bool next(Scan& scan) {
    if (done || it == view->end()) return false;
    const rosbag::MessageInstance& m = *it;
    const uint64_t index = next_message;
    struct Advance {  // the next call reads the next message, whatever this one gives
      State& s;
      ~Advance() {
        ++s.next_message;
        try {
          ++s.it;
        } catch (...) {
          s.pending = std::current_exception();
        }
      }
    } advance{*this};
    check_size(m);
    scan = Scan{};
    scan.source = file.string();
    RigidTransform pose;
    if (m.getDataType() == kPointCloud2) {
      const sensor_msgs::PointCloud2::ConstPtr cloud = m.instantiate<sensor_msgs::PointCloud2>();
      if (!cloud) throw bag_error(m.getTopic() + ": not a readable sensor_msgs/PointCloud2 (its definition differs)");
      pose = pose_of(m, cloud->header, index);
      cloud_scan(m, *cloud, pose, scan);
    } else {
      const sensor_msgs::LaserScan::ConstPtr laser = m.instantiate<sensor_msgs::LaserScan>();
      if (!laser) throw bag_error(m.getTopic() + ": not a readable sensor_msgs/LaserScan (its definition differs)");
      pose = pose_of(m, laser->header, index);
      laser_scan(m, *laser, pose, scan);
    }
    scan.pose = pose.pose();
    scan.points_in_world_frame = true;
    if (poses.tf_frame.empty() && poses.poses[index].covariance) {
      scan.pose_covariance = poses.poses[index].covariance;
      scan.pose_covariance_source = poses.poses_file.string() + " line " + std::to_string(poses.poses[index].line);
    }
    return true;
  }

  std::exception_ptr pending;  // a failure moving to the next message, thrown by the next call
};

RosbagReader::RosbagReader(const std::filesystem::path& bag, const std::vector<std::string>& topics,
                           RosbagPoseSource poses)
    : state_(std::make_unique<State>()) {
  // rosbag and tf2 log through console_bridge; their failures reach us as exceptions instead.
  console_bridge::setLogLevel(console_bridge::CONSOLE_BRIDGE_LOG_NONE);
  state_->file = bag;
  state_->poses = std::move(poses);
  state_->poses.tf_frame = frame_name(state_->poses.tf_frame);
  try {
    state_->open(topics);
  } catch (const InputError&) {
    throw;
  } catch (const MemoryLimitExceeded&) {
    throw;
  } catch (const std::bad_alloc&) {
    throw InputError(bag, "corrupt ROS bag (a record claims more memory than there is)");
  } catch (const std::exception& e) {
    throw InputError(bag, "cannot read as a ROS bag: " + one_line(e.what()));
  }
}

RosbagReader::~RosbagReader() = default;
RosbagReader::RosbagReader(RosbagReader&&) noexcept = default;
RosbagReader& RosbagReader::operator=(RosbagReader&&) noexcept = default;

uint64_t RosbagReader::count_messages(const std::filesystem::path& bag, const std::vector<std::string>& topics) {
  const std::map<std::string, uint64_t> messages = io_detail::check_rosbag_structure(bag);
  uint64_t count = 0;
  for (const std::string& topic : std::set<std::string>(topics.begin(), topics.end()))
    count += messages.count(topic) ? messages.at(topic) : 0;
  return count;
}

const std::map<std::string, uint64_t>& RosbagReader::skipped_messages() const { return state_->skipped; }

uint64_t RosbagReader::size() const { return state_->view ? state_->view->size() : 0; }

bool RosbagReader::next(Scan& scan) {
  State& s = *state_;
  try {
    if (s.pending) std::rethrow_exception(std::exchange(s.pending, nullptr));
    return s.next(scan);
  } catch (const InputError& e) {
    if (!dynamic_cast<const RosbagMessageError*>(&e)) s.done = true;
    throw;
  } catch (const MemoryLimitExceeded&) {
    s.done = true;
    throw;
  } catch (const std::bad_alloc&) {
    s.done = true;
    throw InputError(s.file, "corrupt ROS bag (a record claims more memory than there is)");
  } catch (const std::exception& e) {
    s.done = true;
    throw InputError(s.file, "cannot read as a ROS bag: " + one_line(e.what()));
  }
}

}  // namespace bgkmap
