// The only translation unit of the mapper that includes PCL's filter headers.
#include <pcl/filters/voxel_grid.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <tuple>

#include "bgkmap/integrate/observations.hpp"

namespace bgkmap {

namespace {

std::vector<Vec3f> filter_chunk(const pcl::PointCloud<pcl::PointXYZ>::Ptr& cloud, float leaf) {
  pcl::VoxelGrid<pcl::PointXYZ> grid;
  grid.setInputCloud(cloud);
  grid.setLeafSize(leaf, leaf, leaf);
  pcl::PointCloud<pcl::PointXYZ> filtered;
  grid.filter(filtered);
  std::vector<Vec3f> out;
  out.reserve(filtered.size());
  for (const auto& p : filtered) out.push_back({p.x, p.y, p.z});
  return out;
}

}  // namespace

std::vector<Vec3f> voxel_downsample(const std::vector<Vec3f>& points, double leaf_m) {
  // PCL's voxel grid refuses (and returns its input unchanged) when the cloud's extent needs more
  // than 2^31 leaves, as a 100 m lidar scan at 0.1 m does. Its leaves are aligned to multiples of
  // the leaf size, so filtering chunks aligned to multiples of it gives the same leaves: split
  // the cloud into cubes of kChunkLeaves^3 leaves and filter each.
  constexpr int64_t kChunkLeaves = 1024;
  const double chunk_m = leaf_m * kChunkLeaves;
  std::map<std::tuple<int64_t, int64_t, int64_t>, pcl::PointCloud<pcl::PointXYZ>::Ptr> chunks;
  for (const Vec3f& p : points) {
    const auto key = std::make_tuple(static_cast<int64_t>(std::floor(p.x / chunk_m)),
                                     static_cast<int64_t>(std::floor(p.y / chunk_m)),
                                     static_cast<int64_t>(std::floor(p.z / chunk_m)));
    auto& cloud = chunks[key];
    if (!cloud) cloud.reset(new pcl::PointCloud<pcl::PointXYZ>);
    cloud->push_back(pcl::PointXYZ(p.x, p.y, p.z));
  }
  std::vector<Vec3f> out;
  out.reserve(points.size());
  for (const auto& [key, cloud] : chunks) {
    const std::vector<Vec3f> kept = filter_chunk(cloud, static_cast<float>(leaf_m));
    out.insert(out.end(), kept.begin(), kept.end());
  }
  return out;
}

}  // namespace bgkmap
