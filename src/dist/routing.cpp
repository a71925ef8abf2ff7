#include "bgkmap/dist/routing.hpp"

#include <algorithm>
#include <cmath>

namespace bgkmap {

namespace {

struct TileBox {
  int32_t lo[3], hi[3];
};

// Appends the owners of every tile of the box. Codes grow with each coordinate, so the box's
// tiles lie between its corners' codes; a range of one owner settles it, else the box is halved
// along its longest side (down to single tiles, whose owner is exact).
void owners_of(const SpatialPartition& partition, const TileBox& box, std::vector<int>& out) {
  const int first = partition.owner_of_code(tile_code_of_tile(box.lo[0], box.lo[1], box.lo[2]));
  const int last = partition.owner_of_code(tile_code_of_tile(box.hi[0], box.hi[1], box.hi[2]));
  if (first == last) {
    out.push_back(first);
    return;
  }
  int axis = 0;
  for (int a = 1; a < 3; ++a)
    if (box.hi[a] - box.lo[a] > box.hi[axis] - box.lo[axis]) axis = a;
  const int32_t mid = box.lo[axis] + (box.hi[axis] - box.lo[axis]) / 2;
  TileBox low = box, high = box;
  low.hi[axis] = mid;
  high.lo[axis] = mid + 1;
  owners_of(partition, low, out);
  owners_of(partition, high, out);
}

// The tiles meeting the axis-aligned box of points a and b grown by `margin` metres.
TileBox tiles_around(const Grid& grid, const double a[3], const double b[3], double margin) {
  const double tile = grid.block_size() * kTileBlocks;
  TileBox box;
  for (int k = 0; k < 3; ++k) {
    box.lo[k] = static_cast<int32_t>(std::floor((std::min(a[k], b[k]) - margin) / tile));
    box.hi[k] = static_cast<int32_t>(std::floor((std::max(a[k], b[k]) + margin) / tile));
  }
  return box;
}

// Adds observation `id` to the list of each rank in `owners` (once each).
void send_to(std::vector<int>& owners, uint32_t id, std::vector<std::vector<uint32_t>>& lists) {
  std::sort(owners.begin(), owners.end());
  owners.erase(std::unique(owners.begin(), owners.end()), owners.end());
  for (const int r : owners) lists[static_cast<size_t>(r)].push_back(id);
}

}  // namespace

void ObservationRouter::route(const Grid& grid, float support_radius_m, const ScanObservations& obs,
                              const SpatialPartition& partition, std::vector<std::vector<uint32_t>>& hits,
                              std::vector<std::vector<uint32_t>>& ends) {
  const size_t ranks = static_cast<size_t>(partition.ranks());
  hits.resize(ranks);
  ends.resize(ranks);
  for (size_t r = 0; r < ranks; ++r) hits[r].clear(), ends[r].clear();
  if (ranks == 1) {  // everything goes to rank 0: its bucketing decides, as in one process
    hits[0].resize(obs.hits.size());
    ends[0].resize(obs.free_ends.size());
    for (uint32_t i = 0; i < hits[0].size(); ++i) hits[0][i] = i;
    for (uint32_t i = 0; i < ends[0].size(); ++i) ends[0][i] = i;
    return;
  }
  // One cell beyond l: a block is reached through the box of its cell centres, which lies inside
  // the block, and the margin absorbs rounding at tile borders.
  const double margin = double(support_radius_m) + grid.resolution();
  const double tile = grid.block_size() * kTileBlocks;
  for (uint32_t i = 0; i < obs.hits.size(); ++i) {
    const Vec3f& h = obs.hits[i];
    const double p[3] = {h.x, h.y, h.z};
    owners_.clear();
    owners_of(partition, tiles_around(grid, p, p, margin), owners_);
    send_to(owners_, i, hits);
  }
  const double o[3] = {obs.origin.x, obs.origin.y, obs.origin.z};
  for (uint32_t i = 0; i < obs.free_ends.size(); ++i) {
    const Vec3f& e = obs.free_ends[i];
    const double v[3] = {double(e.x) - o[0], double(e.y) - o[1], double(e.z) - o[2]};
    const double length = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    const int pieces = 1 + static_cast<int>(length / tile);
    owners_.clear();
    for (int s = 0; s < pieces; ++s) {
      const double t0 = double(s) / pieces, t1 = double(s + 1) / pieces;
      const double a[3] = {o[0] + t0 * v[0], o[1] + t0 * v[1], o[2] + t0 * v[2]};
      const double b[3] = {o[0] + t1 * v[0], o[1] + t1 * v[1], o[2] + t1 * v[2]};
      owners_of(partition, tiles_around(grid, a, b, margin), owners_);
    }
    send_to(owners_, i, ends);
  }
}

void select_observations(const ScanObservations& obs, const std::vector<uint32_t>& hits,
                         const std::vector<uint32_t>& ends, ScanObservations& out) {
  out.origin = obs.origin;
  out.hits.resize(hits.size());
  out.free_ends.resize(ends.size());
  for (size_t i = 0; i < hits.size(); ++i) out.hits[i] = obs.hits[hits[i]];
  for (size_t i = 0; i < ends.size(); ++i) out.free_ends[i] = obs.free_ends[ends[i]];
}

}  // namespace bgkmap
