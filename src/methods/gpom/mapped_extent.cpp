#include "methods/gpom/mapped_extent.hpp"

#include <algorithm>

namespace bgkmap::gpom {

void MappedExtent::add(const ScanObservations& obs) {
  const auto take = [&](const Vec3f& p) {
    lo_ = {std::min(lo_.x, double(p.x)), std::min(lo_.y, double(p.y)), std::min(lo_.z, double(p.z))};
    hi_ = {std::max(hi_.x, double(p.x)), std::max(hi_.y, double(p.y)), std::max(hi_.z, double(p.z))};
  };
  if (obs.hits.empty() && obs.free_ends.empty()) return;
  take(obs.origin);
  for (const Vec3f& p : obs.hits) take(p);
  for (const Vec3f& p : obs.free_ends) take(p);
}

std::vector<BlockKey> MappedExtent::blocks(const Grid& grid, const CellQueries& queries, double margin_m) const {
  std::vector<BlockKey> keys;
  if (empty()) return keys;
  const BlockKey lo = grid.block_of(lo_.x - margin_m, lo_.y - margin_m, lo_.z - margin_m);
  const BlockKey hi = grid.block_of(hi_.x + margin_m, hi_.y + margin_m, hi_.z + margin_m);
  for (int32_t x = lo.x; x <= hi.x; ++x)
    for (int32_t y = lo.y; y <= hi.y; ++y)
      for (int32_t z = lo.z; z <= hi.z; ++z) {
        const BlockKey key{x, y, z};
        if (!queries.planar() || queries.block_holds_plane(key)) keys.push_back(key);
      }
  return keys;
}

void fill_unreached_blocks(const std::vector<BlockKey>& keys, const CellQueries& queries, const CellSolver& solver,
                           BlockStore<GpomCell>& cells) {
  for (const BlockKey& key : keys) {
    if (cells.find_slot(key) != BlockIndex::kAbsent) continue;  // dirty once, or filled before
    GpomCell* block = cells.block(cells.ensure_slot(key));
    queries.for_each_query(key, 1, [&](int local, const Vec3d& q) { block[local] = solver.unreached(q); });
  }
}

}  // namespace bgkmap::gpom
