// The only translation unit that includes PCL's I/O headers.
#include "bgkmap/io/pcd_io.hpp"

#include <pcl/PCLPointCloud2.h>
#include <pcl/console/print.h>
#include <pcl/io/pcd_io.h>

#include <array>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <new>
#include <string>

#include "bgkmap/io/atomic_file.hpp"
#include "bgkmap/io/errors.hpp"
#include "input_file.hpp"
#include "pcd_header.hpp"

namespace bgkmap {

namespace {
void quiet_pcl() {
  // Failures are reported through InputError; PCL's own console lines would only repeat them.
  pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS);
}

// PCL writes this when a cloud has no sensor pose, so it says nothing about where the scan was taken.
bool is_pcl_default(const std::array<float, 7>& v) { return v == std::array<float, 7>{0, 0, 0, 1, 0, 0, 0}; }

Pose pose_from_viewpoint(const std::array<float, 7>& v) {
  Pose pose;
  pose.position = {v[0], v[1], v[2]};
  // read_header has checked the quaternion is finite and non-zero.
  const double norm = std::sqrt(double(v[3]) * v[3] + double(v[4]) * v[4] + double(v[5]) * v[5] + double(v[6]) * v[6]);
  pose.qw = static_cast<float>(v[3] / norm);
  pose.qx = static_cast<float>(v[4] / norm);
  pose.qy = static_cast<float>(v[5] / norm);
  pose.qz = static_cast<float>(v[6] / norm);
  return pose;
}

// Reads one coordinate of every point from PCL's packed buffer, whichever float width it has.
class CoordinateReader {
 public:
  CoordinateReader(const std::filesystem::path& file, const pcl::PCLPointCloud2& blob, const std::string& name) {
    for (const pcl::PCLPointField& f : blob.fields) {
      if (f.name != name) continue;
      const bool known = f.datatype == pcl::PCLPointField::FLOAT32 || f.datatype == pcl::PCLPointField::FLOAT64;
      width_ = f.datatype == pcl::PCLPointField::FLOAT64 ? 8 : 4;
      if (!known || f.count != 1 || uint64_t(f.offset) + width_ > blob.point_step)
        throw InputError(file, "PCD: field '" + name + "' is not a single float after decoding");
      offset_ = f.offset;
      return;
    }
    throw InputError(file, "PCD: no '" + name + "' field after decoding");
  }

  float operator()(const uint8_t* point) const {
    if (width_ == 4) {
      float v;
      std::memcpy(&v, point + offset_, sizeof v);
      return v;
    }
    double v;
    std::memcpy(&v, point + offset_, sizeof v);
    return static_cast<float>(v);
  }

 private:
  uint32_t offset_ = 0;
  uint32_t width_ = 4;
};

std::string to_text(float v) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, v);  // shortest exact form
  return std::string(buffer, result.ptr);
}
}  // namespace

Scan read_pcd(const std::filesystem::path& file) {
  quiet_pcl();
  const uint64_t file_size = io_detail::input_file_size(file);
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(file, "cannot open for reading");
  const pcd::Header header = pcd::read_header(file, in, file_size);
  pcd::check_body(file, in, file_size, header);
  in.close();

  Scan scan;
  scan.source = file.string();
  scan.pose = pose_from_viewpoint(header.viewpoint);
  scan.has_own_pose = !is_pcl_default(header.viewpoint);
  if (header.points == 0) return scan;
  // PCL's decoded blob, then the points.
  io_detail::require_read_memory(file, header.points, double(header.point_bytes()) + sizeof(Vec3f));

  pcl::PCLPointCloud2 blob;
  Eigen::Vector4f origin;
  Eigen::Quaternionf orientation;
  int version = 0;
  int decoded = -1;
  try {
    decoded = pcl::PCDReader().read(file.string(), blob, origin, orientation, version);
  } catch (const std::bad_alloc&) {
    throw InputError(file, "PCD: out of memory decoding " + std::to_string(header.points) + " points");
  } catch (const std::exception& e) {
    throw InputError(file, std::string("PCD: PCL cannot decode the data (") + e.what() + ")");
  }
  if (decoded < 0) throw InputError(file, "PCD: PCL cannot decode the data (corrupt compressed block?)");
  const uint64_t points = uint64_t(blob.width) * blob.height;
  if (points != header.points || blob.point_step == 0 || blob.data.size() < points * blob.point_step)
    throw InputError(file, "PCD: PCL decoded " + std::to_string(points) + " points, header promises " +
                               std::to_string(header.points));

  const CoordinateReader x(file, blob, "x"), y(file, blob, "y"), z(file, blob, "z");
  scan.points.resize(points);
  for (uint64_t i = 0; i < points; ++i) {
    const uint8_t* p = blob.data.data() + i * blob.point_step;
    scan.points[i] = {x(p), y(p), z(p)};
  }
  return scan;
}

bool pcd_has_viewpoint(const std::filesystem::path& file) {
  const uint64_t file_size = io_detail::input_file_size(file);
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(file, "cannot open for reading");
  return !is_pcl_default(pcd::read_header(file, in, file_size).viewpoint);
}

void write_pcd(const std::filesystem::path& file, const Scan& scan) {
  Pose pose = scan.pose;
  const bool pcl_default = pose.position.x == 0 && pose.position.y == 0 && pose.position.z == 0 && pose.qw == 1 &&
                           pose.qx == 0 && pose.qy == 0 && pose.qz == 0;
  if (scan.has_own_pose && pcl_default)
    pose.qw = -1;  // the same pose, but not PCL's "no pose" default, so it reads back as given
  if (!scan.has_own_pose) pose = Pose{};
  for (float v : {pose.position.x, pose.position.y, pose.position.z, pose.qw, pose.qx, pose.qy, pose.qz}) {
    if (!std::isfinite(v)) throw std::runtime_error(file.string() + ": cannot write PCD with a non-finite pose");
  }
  // Written here rather than by PCL: PCL prints VIEWPOINT with 6 digits, which loses the pose.
  const std::string n = std::to_string(scan.points.size());
  const std::string header = "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\n"
                             "TYPE F F F\nCOUNT 1 1 1\nWIDTH " + n + "\nHEIGHT 1\nVIEWPOINT " +
                             to_text(pose.position.x) + " " + to_text(pose.position.y) + " " +
                             to_text(pose.position.z) + " " + to_text(pose.qw) + " " + to_text(pose.qx) + " " +
                             to_text(pose.qy) + " " + to_text(pose.qz) + "\nPOINTS " + n + "\nDATA binary\n";
  write_file_atomically(file, [&](std::ostream& out) {
    out.write(header.data(), static_cast<std::streamsize>(header.size()));
    std::vector<float> xyz;
    xyz.reserve(3 * scan.points.size());
    for (const Vec3f& p : scan.points) xyz.insert(xyz.end(), {p.x, p.y, p.z});
    out.write(reinterpret_cast<const char*>(xyz.data()), static_cast<std::streamsize>(xyz.size() * sizeof(float)));
  });
}

}  // namespace bgkmap
