// The only translation unit that reads OctoMap scan graphs (with liboctomap's record readers).
#include "bgkmap/io/scan_graph_io.hpp"

#include <octomap/math/Pose6D.h>
#include <octomap/octomap_types.h>

#include <cmath>
#include <cstring>
#include <string>
#include <unordered_set>

#include "bgkmap/io/errors.hpp"
#include "input_file.hpp"

namespace bgkmap {

namespace {

// Byte layout written by liboctomap's ScanGraph::writeBinary (host byte order):
//   uint32 node_count, then per node:
//     uint32 n, n points of (int32 3, 3 x float64)          -- Pointcloud::writeBinary
//     int32 3, 3 x float64 translation                      -- Pose6D: Vector3::writeBinary
//     int32 4, 4 x float64 rotation (w x y z)               --         Quaternion::writeBinary
//     uint32 id
//   uint32 edge_count, then per edge:
//     uint32 first_id, uint32 second_id, pose (as above), float64 weight
constexpr uint64_t kPointBytes = 4 + 3 * 8;
constexpr uint64_t kPoseBytes = (4 + 3 * 8) + (4 + 4 * 8);
constexpr uint64_t kNodeOverheadBytes = 4 + kPoseBytes + 4;
constexpr uint64_t kEdgeBytes = 4 + 4 + kPoseBytes + 8;
constexpr double kUnitQuaternionTolerance = 1e-4;

template <typename T>
T load(const char* bytes) {
  T v;
  std::memcpy(&v, bytes, sizeof v);
  return v;
}

// Walks the file's layout with small reads and seeks, never allocating by a count it has not
// checked against the bytes that are left.
class LayoutChecker {
 public:
  LayoutChecker(const std::filesystem::path& file, std::ifstream& in, uint64_t size)
      : file_(file), in_(in), size_(size) {}

  std::vector<uint32_t> check() {
    const uint32_t nodes = read_u32("the node count");
    if (uint64_t(nodes) * kNodeOverheadBytes > left())
      fail(std::to_string(nodes) + " nodes cannot fit in a file of " + std::to_string(size_) + " bytes");
    std::vector<uint32_t> point_counts;
    point_counts.reserve(nodes);
    std::unordered_set<uint32_t> ids;
    for (uint32_t k = 0; k < nodes; ++k) {
      const uint32_t points = read_u32("the point count of node " + std::to_string(k));
      const uint64_t need = uint64_t(points) * kPointBytes + kPoseBytes + 4;
      if (need > left())
        fail("node " + std::to_string(k) + " claims " + std::to_string(points) + " points, only " +
             std::to_string(left()) + " bytes left");
      skip(uint64_t(points) * kPointBytes);
      check_pose("node " + std::to_string(k) + " pose", true);
      ids.insert(read_u32("the id of node " + std::to_string(k)));
      point_counts.push_back(points);
    }
    const uint32_t edges = read_u32("the edge count");
    if (uint64_t(edges) * kEdgeBytes != left())
      fail(std::to_string(edges) + " edges need " + std::to_string(uint64_t(edges) * kEdgeBytes) + " bytes, " +
           std::to_string(left()) + " are left");
    for (uint32_t e = 0; e < edges; ++e) {
      const std::string what = "edge " + std::to_string(e);
      for (const char* end : {"first", "second"}) {
        const uint32_t id = read_u32(what + " " + end + " node id");
        if (!ids.count(id)) fail(what + " refers to node id " + std::to_string(id) + ", which is not in the graph");
      }
      check_pose(what + " constraint", false);
      skip(8);  // weight
    }
    return point_counts;
  }

 private:
  [[noreturn]] void fail(const std::string& what) const { throw InputError(file_, "scan graph: " + what); }

  uint64_t left() const { return size_ - offset_; }

  void read(char* bytes, uint64_t n, const std::string& what) {
    if (n > left()) fail("truncated in " + what);
    if (!in_.read(bytes, static_cast<std::streamsize>(n))) fail("read error in " + what);
    offset_ += n;
  }

  uint32_t read_u32(const std::string& what) {
    char bytes[4];
    read(bytes, 4, what);
    return load<uint32_t>(bytes);
  }

  void skip(uint64_t n) {
    offset_ += n;  // callers have checked n <= left()
    in_.seekg(static_cast<std::streamoff>(offset_));
  }

  // Node poses must be usable: finite, with a unit quaternion, since liboctomap rotates by
  // q v q* without normalising. Edge constraints are only checked for their markers.
  void check_pose(const std::string& what, bool check_values) {
    char bytes[kPoseBytes];
    read(bytes, kPoseBytes, what);
    if (load<int32_t>(bytes) != 3 || load<int32_t>(bytes + 28) != 4)
      fail(what + " is not a pose record (corrupt file or wrong point count)");
    if (!check_values) return;
    double norm2 = 0;
    for (int i = 0; i < 7; ++i) {
      const double v = load<double>(bytes + (i < 3 ? 4 + 8 * i : 32 + 8 * (i - 3)));
      if (!std::isfinite(static_cast<float>(v))) fail(what + " has a non-finite value");
      if (i >= 3) norm2 += v * v;
    }
    if (std::abs(std::sqrt(norm2) - 1.0) > kUnitQuaternionTolerance)
      fail(what + " rotation is not a unit quaternion (norm " + std::to_string(std::sqrt(norm2)) + ")");
  }

  const std::filesystem::path& file_;
  std::ifstream& in_;
  uint64_t size_;
  uint64_t offset_ = 0;
};

}  // namespace

ScanGraphReader::ScanGraphReader(const std::filesystem::path& file) : file_(file) {
  const uint64_t size = io_detail::input_file_size(file);
  if (size == 0) throw InputError(file, "scan graph: empty file");
  in_.open(file, std::ios::binary);
  if (!in_) throw InputError(file, "cannot open for reading");
  point_counts_ = LayoutChecker(file_, in_, size).check();
  in_.clear();
  in_.seekg(4);  // the first node
}

bool ScanGraphReader::next(Scan& scan) {
  if (next_node_ >= point_counts_.size()) return false;
  const size_t k = next_node_++;
  // ScanNode::readBinary, step by step: its Pointcloud::readBinary prints a debug line per node
  // in Debian's liboctomap build, so the record readers it calls are called here directly.
  char count[4];
  in_.read(count, sizeof count);
  const uint32_t n = load<uint32_t>(count);
  std::vector<octomap::point3d> sensor(n);
  for (octomap::point3d& p : sensor) p.readBinary(in_);
  octomap::pose6d pose;
  pose.readBinary(in_);
  char id[4];
  in_.read(id, sizeof id);
  if (in_.fail() || n != point_counts_[k])
    throw InputError(file_, "scan graph: cannot decode node " + std::to_string(k) + " (file changed while reading?)");

  scan.points.clear();
  scan.points.reserve(n);
  for (const octomap::point3d& p : sensor) {
    const octomap::point3d w = pose.transform(p);  // what ScanGraph::transformScans computes
    scan.points.push_back({w.x(), w.y(), w.z()});
  }
  const octomath::Vector3& t = pose.trans();
  const octomath::Quaternion& q = pose.rot();
  scan.pose.position = {t.x(), t.y(), t.z()};
  scan.pose.qw = q.u();
  scan.pose.qx = q.x();
  scan.pose.qy = q.y();
  scan.pose.qz = q.z();
  scan.source = file_.string() + " (node " + std::to_string(k) + ")";
  scan.points_in_world_frame = true;
  return true;
}

std::vector<Scan> read_scan_graph(const std::filesystem::path& file) {
  ScanGraphReader reader(file);
  std::vector<Scan> scans(reader.node_count());
  for (Scan& scan : scans) reader.next(scan);
  return scans;
}

}  // namespace bgkmap
