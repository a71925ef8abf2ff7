// The candidate cells of a map for the viewer. Includes OctoMap (for .ot / .bt).
#include <octomap/OcTree.h>

#include "bgkmap/io/map_io.hpp"
#include "bgkmap/map/bgk_map.hpp"
#include "bgkmap/viz/viewer.hpp"
#include "eval/octree_file.hpp"

namespace bgkmap::viz {

namespace {

ViewMap from_bgk(const std::filesystem::path& file) {
  const BgkMap map = read_native_map(file);
  const ClassifyParams& classify = map.params().classify;
  ViewMap view;
  view.resolution_m = map.grid().resolution();
  view.occupied_threshold = classify.occupied_threshold;
  view.has_variance = true;
  map.for_each_cell_with_evidence([&](const CellIndex& c, const CellPosterior& p) {
    const double mean = p.mean();
    if (mean < kMinViewProbability) return;
    view.cells.push_back({c.x, c.y, c.z, 0, static_cast<float>(mean), p.variance() > classify.var_threshold,
                          p.state(classify) == CellState::kOccupied});
  });
  return view;
}

ViewMap from_octree(const std::filesystem::path& file, eval::OctreeFile kind) {
  const std::unique_ptr<octomap::OcTree> tree = eval::read_octree_file(file, kind);
  ViewMap view;
  view.resolution_m = tree->getResolution();
  view.occupied_threshold = static_cast<float>(tree->getOccupancyThres());
  const int max_depth = static_cast<int>(tree->getTreeDepth());
  for (auto it = tree->begin_leafs(), end = tree->end_leafs(); it != end; ++it) {
    const double p = it->getOccupancy();
    if (p < kMinViewProbability) continue;
    const int level = max_depth - static_cast<int>(it.getDepth());
    // A leaf's key lies inside it; OctoMap's keys are cell indices + 32768, a multiple of 2^level.
    const octomap::OcTreeKey key = it.getKey();
    constexpr int32_t offset = 32768;
    ViewCell c;
    c.x = (static_cast<int32_t>(key[0]) - offset) >> level;
    c.y = (static_cast<int32_t>(key[1]) - offset) >> level;
    c.z = (static_cast<int32_t>(key[2]) - offset) >> level;
    c.level = static_cast<uint8_t>(level);
    c.probability = static_cast<float>(p);
    c.occupied = tree->isNodeOccupied(*it);
    view.cells.push_back(c);
  }
  return view;
}

}  // namespace

ViewMap read_view_map(const std::filesystem::path& file) {
  ViewMap view;
  switch (readable_map_format_from_path(file)) {
    case MapFormat::kNative: view = from_bgk(file); break;
    case MapFormat::kOctomapTree: view = from_octree(file, eval::OctreeFile::kTree); break;
    case MapFormat::kOctomapBinary: view = from_octree(file, eval::OctreeFile::kBinary); break;
    case MapFormat::kRosMap:
    case MapFormat::kPlyCloud:
    case MapFormat::kPcdCloud: break;  // refused by readable_map_format_from_path
  }
  view.source = file.filename().string();
  return view;
}

}  // namespace bgkmap::viz
