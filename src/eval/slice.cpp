#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <map>
#include <stdexcept>
#include <tuple>
#include <vector>

#include "bgkmap/core/grid.hpp"
#include "bgkmap/eval/plot.hpp"

namespace bgkmap::eval {

SliceImage make_slice(const ScoredMap& map, const Truth* truth, const sim::Box3d& box, double z) {
  const Grid& grid = map.grid();
  const double r = grid.resolution();
  if (!(box.max.x >= box.min.x && box.max.y >= box.min.y))
    throw std::invalid_argument("the slice region is empty (the map has no evidence?)");
  if (!within_key_range(box.min.x, box.min.y, z) || !within_key_range(box.max.x, box.max.y, z)) {
    char what[120];
    std::snprintf(what, sizeof what, "the slice at z = %g m lies beyond the map's key range (|x|, |y|, |z| at most 1e6 m)", z);
    throw std::invalid_argument(what);
  }
  const int32_t x0 = static_cast<int32_t>(std::floor(box.min.x / r)), x1 = static_cast<int32_t>(std::floor(box.max.x / r));
  const int32_t y0 = static_cast<int32_t>(std::floor(box.min.y / r)), y1 = static_cast<int32_t>(std::floor(box.max.y / r));
  const int32_t zc = static_cast<int32_t>(std::floor(z / r));
  if ((int64_t(x1) - x0 + 1) * (int64_t(y1) - y0 + 1) > 16'000'000)
    throw std::invalid_argument("the slice would exceed 16 million cells; use a coarser map");
  SliceImage s;
  s.width = x1 - x0 + 1;
  s.height = y1 - y0 + 1;
  s.z = z;
  s.resolution = r;
  s.x0 = x0;
  s.y0 = y0;
  s.box = box;
  const size_t n = static_cast<size_t>(s.width) * s.height;
  s.mean.resize(n);
  s.has_variance = map.has_variance();
  if (s.has_variance) s.variance.resize(n);
  s.has_truth = truth != nullptr;
  s.truth.assign(n, TruthLabel::kUnknown);
  s.evidence.resize(n);
  for (int j = 0; j < s.height; ++j)
    for (int i = 0; i < s.width; ++i) {
      const CellIndex c{x0 + i, y0 + j, zc};
      const Vec3d p = grid.cell_center_d(c);
      const MapSample sample = map.sample(p.x, p.y, p.z);
      const size_t k = static_cast<size_t>(j) * s.width + i;
      s.mean[k] = sample.score;
      if (s.has_variance) s.variance[k] = sample.variance.value_or(NAN);
      s.evidence[k] = sample.has_evidence;
      if (truth) s.truth[k] = truth->label(c);
    }
  return s;
}

std::optional<double> busiest_layer_z(const ScoredMap& map) {
  std::vector<CellIndex> cells = map.occupied_cells();
  if (cells.empty()) return std::nullopt;
  // Sorted for binary search: 12 bytes a cell, where a hash set would take several times that.
  const auto before = [](const CellIndex& a, const CellIndex& b) { return std::tie(a.x, a.y, a.z) < std::tie(b.x, b.y, b.z); };
  std::sort(cells.begin(), cells.end(), before);
  const auto is_occupied = [&](int32_t x, int32_t y, int32_t z) {
    return std::binary_search(cells.begin(), cells.end(), CellIndex{x, y, z}, before);
  };
  const auto is_free = [&](int32_t x, int32_t y, int32_t z) {
    const Vec3d p = map.grid().cell_center_d(CellIndex{x, y, z});
    const MapSample s = map.sample(p.x, p.y, p.z);
    return s.has_evidence && !(s.score > map.occupied_threshold());
  };
  // A wall cell: occupied above and below, and beside a cell seen free (a vertical surface). A
  // floor or ceiling, however thick, has free space above or below it, not beside it.
  std::map<int32_t, uint64_t> per_layer, walls;
  for (const CellIndex& c : cells) {
    ++per_layer[c.z];
    if (!is_occupied(c.x, c.y, c.z - 1) || !is_occupied(c.x, c.y, c.z + 1)) continue;
    if (is_free(c.x - 1, c.y, c.z) || is_free(c.x + 1, c.y, c.z) || is_free(c.x, c.y - 1, c.z) ||
        is_free(c.x, c.y + 1, c.z))
      ++walls[c.z];
  }
  // A planar map has no walls in this sense: then its layer with the most occupied cells.
  const std::map<int32_t, uint64_t>& layers = walls.empty() ? per_layer : walls;
  // Of equal counts the highest layer: a plane of points at a cell boundary z = k r lies in the
  // cell above it, and a kernel spreads it evenly over the cells on both sides.
  const auto busiest = std::max_element(layers.rbegin(), layers.rend(),
                                        [](const auto& x, const auto& y) { return x.second < y.second; });
  return (busiest->first + 0.5) * map.resolution();
}

}  // namespace bgkmap::eval
