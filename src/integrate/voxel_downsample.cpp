// The only translation unit of the mapper that includes PCL's filter headers.
#include <pcl/filters/voxel_grid.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include "bgkmap/integrate/observations.hpp"

namespace bgkmap {

std::vector<Vec3f> voxel_downsample(const std::vector<Vec3f>& points, double leaf_m) {
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  cloud->resize(points.size());
  for (size_t i = 0; i < points.size(); ++i) (*cloud)[i] = pcl::PointXYZ(points[i].x, points[i].y, points[i].z);
  pcl::VoxelGrid<pcl::PointXYZ> grid;
  grid.setInputCloud(cloud);
  const float leaf = static_cast<float>(leaf_m);
  grid.setLeafSize(leaf, leaf, leaf);
  pcl::PointCloud<pcl::PointXYZ> filtered;
  grid.filter(filtered);
  std::vector<Vec3f> out;
  out.reserve(filtered.size());
  for (const auto& p : filtered) out.push_back({p.x, p.y, p.z});
  return out;
}

}  // namespace bgkmap
