// The only translation unit that includes PCL's I/O headers.
#include "bgkmap/io/pcd_io.hpp"

#include <pcl/PCLPointCloud2.h>
#include <pcl/console/print.h>
#include <pcl/conversions.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <algorithm>

#include "bgkmap/io/atomic_file.hpp"
#include "bgkmap/io/errors.hpp"

namespace bgkmap {

namespace {
void quiet_pcl() {
  // Failures are reported through InputError; PCL's own console lines would only repeat them.
  pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS);
}

bool has_field(const pcl::PCLPointCloud2& cloud, const std::string& name) {
  return std::any_of(cloud.fields.begin(), cloud.fields.end(), [&](const pcl::PCLPointField& f) { return f.name == name; });
}
}  // namespace

Scan read_pcd(const std::filesystem::path& file) {
  quiet_pcl();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) throw InputError(file, "no such file");
  pcl::PCLPointCloud2 blob;
  Eigen::Vector4f origin;
  Eigen::Quaternionf orientation;
  int version = 0;
  pcl::PCDReader reader;
  int status = -1;
  try {
    status = reader.read(file.string(), blob, origin, orientation, version);
  } catch (const std::exception& e) {
    throw InputError(file, std::string("not a readable PCD file (") + e.what() + ")");
  }
  if (status < 0) throw InputError(file, "not a readable PCD file (bad header or truncated data)");
  if (!has_field(blob, "x") || !has_field(blob, "y") || !has_field(blob, "z"))
    throw InputError(file, "PCD file has no x/y/z fields");
  pcl::PointCloud<pcl::PointXYZ> cloud;
  pcl::fromPCLPointCloud2(blob, cloud);

  Scan scan;
  scan.source = file.string();
  scan.points.reserve(cloud.size());
  for (const auto& p : cloud) scan.points.push_back({p.x, p.y, p.z});
  scan.pose.position = {origin.x(), origin.y(), origin.z()};
  const Eigen::Quaternionf q = orientation.normalized();
  scan.pose.qw = q.w();
  scan.pose.qx = q.x();
  scan.pose.qy = q.y();
  scan.pose.qz = q.z();
  return scan;
}

void write_pcd(const std::filesystem::path& file, const Scan& scan) {
  quiet_pcl();
  pcl::PointCloud<pcl::PointXYZ> cloud;
  cloud.resize(scan.points.size());
  for (size_t i = 0; i < scan.points.size(); ++i) cloud[i] = pcl::PointXYZ(scan.points[i].x, scan.points[i].y, scan.points[i].z);
  cloud.width = static_cast<uint32_t>(cloud.size());
  cloud.height = 1;
  cloud.is_dense = false;
  cloud.sensor_origin_ = Eigen::Vector4f(scan.pose.position.x, scan.pose.position.y, scan.pose.position.z, 0.0f);
  cloud.sensor_orientation_ = Eigen::Quaternionf(scan.pose.qw, scan.pose.qx, scan.pose.qy, scan.pose.qz);
  write_path_atomically(file, [&](const std::filesystem::path& tmp) {
    if (pcl::io::savePCDFileBinary(tmp.string(), cloud) < 0) throw std::runtime_error(file.string() + ": cannot write PCD");
  });
}

}  // namespace bgkmap
