#include "bgkmap/dist/partition.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace bgkmap {

namespace {

// Spreads the low 21 bits of v so that bit i lands at bit 3i.
uint64_t spread_bits(uint64_t v) {
  v &= 0x1fffff;
  v = (v | v << 32) & 0x1f00000000ffffULL;
  v = (v | v << 16) & 0x1f0000ff0000ffULL;
  v = (v | v << 8) & 0x100f00f00f00f00fULL;
  v = (v | v << 4) & 0x10c30c30c30c30c3ULL;
  v = (v | v << 2) & 0x1249249249249249ULL;
  return v;
}

uint64_t biased(int32_t tile) {
  const int64_t b = int64_t(tile) + (int64_t(1) << 20);
  return static_cast<uint64_t>(std::clamp<int64_t>(b, 0, (int64_t(1) << 21) - 1));
}

}  // namespace

uint64_t tile_code_of_tile(int32_t tx, int32_t ty, int32_t tz) {
  return spread_bits(biased(tx)) | spread_bits(biased(ty)) << 1 | spread_bits(biased(tz)) << 2;
}

uint64_t tile_code(const BlockKey& k) {
  return tile_code_of_tile(floor_div(k.x, kTileBlocks), floor_div(k.y, kTileBlocks), floor_div(k.z, kTileBlocks));
}

void TileCosts::add_scan(const Grid& grid, const ScanObservations& obs) {
  for (const Vec3f& p : obs.hits) add(tile_code(grid.block_of(p.x, p.y, p.z)), 1.0);
  // A segment is sampled once per tile length, each sample weighing the block lengths it stands for.
  const double block = grid.block_size(), step = block * kTileBlocks;
  const Vec3f& o = obs.origin;
  for (const Vec3f& e : obs.free_ends) {
    const double v[3] = {double(e.x) - o.x, double(e.y) - o.y, double(e.z) - o.z};
    const double length = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    const int samples = 1 + static_cast<int>(length / step);
    const double weight = (1.0 + length / block) / samples;
    for (int s = 0; s < samples; ++s) {
      const double t = (s + 0.5) / samples;
      const Vec3f p{static_cast<float>(o.x + t * v[0]), static_cast<float>(o.y + t * v[1]),
                    static_cast<float>(o.z + t * v[2])};
      add(tile_code(grid.block_of(p.x, p.y, p.z)), weight);
    }
  }
}

std::vector<std::pair<uint64_t, double>> TileCosts::sorted() const {
  std::vector<std::pair<uint64_t, double>> out(sums_.begin(), sums_.end());
  std::sort(out.begin(), out.end());
  return out;
}

SpatialPartition::SpatialPartition(int ranks, const std::vector<std::pair<uint64_t, double>>& costs)
    : first_(static_cast<size_t>(std::max(ranks, 1)), 0), cost_(first_.size(), 0.0) {
  if (ranks < 1) throw std::invalid_argument("a partition needs at least one rank");
  double total = 0;
  for (const auto& c : costs) total += c.second;
  // Rank r starts at the first tile where the cost before it reaches r / ranks of the total;
  // ranks that would start on the same tile get an empty run.
  double before = 0;
  size_t rank = 1;
  for (size_t i = 0; i < costs.size(); ++i) {
    while (rank < first_.size() && before >= total * double(rank) / ranks && costs[i].first > first_[rank - 1]) {
      first_[rank++] = costs[i].first;
    }
    cost_[rank - 1] += costs[i].second;
    before += costs[i].second;
  }
  for (; rank < first_.size(); ++rank) first_[rank] = ~uint64_t(0);  // nothing left: empty runs at the end
}

SpatialPartition::SpatialPartition(std::vector<uint64_t> first_codes) : first_(std::move(first_codes)) {
  if (first_.empty() || first_[0] != 0 || !std::is_sorted(first_.begin(), first_.end()))
    throw std::invalid_argument("a partition's first codes start at 0 and do not decrease");
}

int SpatialPartition::owner_of_code(uint64_t code) const {
  return static_cast<int>(std::upper_bound(first_.begin(), first_.end(), code) - first_.begin()) - 1;
}

}  // namespace bgkmap
