// The cells of a BgkMap whose centres lie in a box: the blocks the box overlaps, then their cells.
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <utility>

#include "bgkmap/map/map_queries.hpp"

namespace bgkmap {

namespace {

// Cell indices [lo, hi] per axis whose centres (Grid::cell_center_d's arithmetic) lie in the box.
struct CellRange {
  int32_t lo[3], hi[3];
  bool empty() const { return lo[0] > hi[0] || lo[1] > hi[1] || lo[2] > hi[2]; }
};

double centre(int64_t i, double r) { return (static_cast<double>(i) + 0.5) * r; }

int32_t first_centred_at_or_above(double v, double r) {
  int64_t i = static_cast<int64_t>(std::ceil(v / r - 0.5));
  while (centre(i - 1, r) >= v) --i;
  while (centre(i, r) < v) ++i;
  return static_cast<int32_t>(i);
}

int32_t last_centred_at_or_below(double v, double r) {
  int64_t i = static_cast<int64_t>(std::floor(v / r - 0.5));
  while (centre(i + 1, r) <= v) ++i;
  while (centre(i, r) > v) --i;
  return static_cast<int32_t>(i);
}

// A centre within 1e-9 cells of a bound counts as inside: a bound written as a centre (0.35 at
// 0.1 m, below the computed 3.5 * 0.1) holds that centre.
CellRange cells_of(const BgkMap& map, const CellBox& box) {
  const double r = map.grid().resolution(), slack = 1e-9 * r;
  const double lo[3] = {box.min.x, box.min.y, box.min.z}, hi[3] = {box.max.x, box.max.y, box.max.z};
  CellRange range;
  for (int i = 0; i < 3; ++i) {
    range.lo[i] = first_centred_at_or_above(lo[i] - slack, r);
    range.hi[i] = last_centred_at_or_below(hi[i] + slack, r);
  }
  if (map.params().preprocess.planar) range.lo[2] = range.hi[2] = map.params().planar_layer();
  return range;
}

bool key_before(const BlockKey& a, const BlockKey& b) {
  return a.z != b.z ? a.z < b.z : (a.y != b.y ? a.y < b.y : a.x < b.x);
}

// The blocks to visit, in key order (z, y, x), with their slots (-1: never touched).
std::vector<std::pair<BlockKey, int64_t>> blocks_to_visit(const BgkMap& map, const CellRange* range,
                                                         CellSelection selection) {
  std::vector<std::pair<BlockKey, int64_t>> blocks;
  const int n = map.grid().cells_per_side();
  BlockKey lo, hi;
  double in_range = 0;
  if (range) {
    lo = {floor_div(range->lo[0], n), floor_div(range->lo[1], n), floor_div(range->lo[2], n)};
    hi = {floor_div(range->hi[0], n), floor_div(range->hi[1], n), floor_div(range->hi[2], n)};
    in_range = (hi.x - lo.x + 1.0) * (hi.y - lo.y + 1.0) * (hi.z - lo.z + 1.0);
  }
  // Every block of the range when the untouched ones count or when there are fewer than the map's.
  if (range && (selection == CellSelection::kAll || in_range <= static_cast<double>(map.block_count()))) {
    for (int32_t z = lo.z; z <= hi.z; ++z)
      for (int32_t y = lo.y; y <= hi.y; ++y)
        for (int32_t x = lo.x; x <= hi.x; ++x) {
          const BlockKey key{x, y, z};
          const int64_t slot = map.find_slot(key);
          if (slot >= 0 || selection == CellSelection::kAll) blocks.emplace_back(key, slot);
        }
    return blocks;
  }
  for (uint32_t slot = 0; slot < map.block_count(); ++slot) {
    const BlockKey& k = map.key_of_slot(slot);
    if (!range || (k.x >= lo.x && k.x <= hi.x && k.y >= lo.y && k.y <= hi.y && k.z >= lo.z && k.z <= hi.z))
      blocks.emplace_back(k, slot);
  }
  std::sort(blocks.begin(), blocks.end(), [](const auto& a, const auto& b) { return key_before(a.first, b.first); });
  return blocks;
}

bool selected(const MapCell& cell, CellSelection selection) {
  switch (selection) {
    case CellSelection::kWithEvidence: return cell.posterior.has_evidence;
    case CellSelection::kAll: return true;
    case CellSelection::kOccupied: return cell.state == CellState::kOccupied;
  }
  return false;
}

void visit_block(const BgkMap& map, const BlockKey& key, int64_t slot, const CellRange* range, CellSelection selection,
                 const std::function<void(const MapCell&)>& visit) {
  const Grid& grid = map.grid();
  const int n = grid.cells_per_side();
  const int32_t first[3] = {key.x * n, key.y * n, key.z * n};
  int32_t lo[3], hi[3];
  for (int i = 0; i < 3; ++i) {
    lo[i] = range ? std::max(first[i], range->lo[i]) : first[i];
    hi[i] = range ? std::min(first[i] + n - 1, range->hi[i]) : first[i] + n - 1;
  }
  const Cell prior{map.params().prior.alpha0, map.params().prior.beta0};
  const Cell* cells = slot >= 0 ? map.block_cells(static_cast<uint32_t>(slot)) : nullptr;
  MapCell cell;
  for (int32_t z = lo[2]; z <= hi[2]; ++z)
    for (int32_t y = lo[1]; y <= hi[1]; ++y)
      for (int32_t x = lo[0]; x <= hi[0]; ++x) {
        cell.index = {x, y, z};
        cell.posterior = map.posterior(cells ? cells[grid.local_index(cell.index)] : prior);
        cell.state = cell.posterior.state(map.params().classify);
        if (!selected(cell, selection)) continue;
        cell.center = grid.cell_center_d(cell.index);
        visit(cell);
      }
}

}  // namespace

void check_cell_box(const CellBox& box) {
  const double v[6] = {box.min.x, box.min.y, box.min.z, box.max.x, box.max.y, box.max.z};
  for (double x : v)
    if (!std::isfinite(x)) throw std::invalid_argument("the box's bounds must be finite");
  if (!within_key_range(box.min.x, box.min.y, box.min.z) || !within_key_range(box.max.x, box.max.y, box.max.z))
    throw std::invalid_argument("the box lies beyond the map's key range (|x|, |y|, |z| at most 1e6 m)");
  if (box.min.x > box.max.x || box.min.y > box.max.y || box.min.z > box.max.z)
    throw std::invalid_argument("the box's minimum must not exceed its maximum on any axis");
}

double cells_centred_in(const BgkMap& map, const CellBox& box) {
  check_cell_box(box);
  const CellRange range = cells_of(map, box);
  if (range.empty()) return 0;
  return (range.hi[0] - range.lo[0] + 1.0) * (range.hi[1] - range.lo[1] + 1.0) * (range.hi[2] - range.lo[2] + 1.0);
}

void for_each_cell_in_box(const BgkMap& map, const CellBox* box, CellSelection selection,
                          const std::function<void(const MapCell&)>& visit) {
  if (!box && selection == CellSelection::kAll)
    throw std::invalid_argument("every cell, observed or not, needs a box");
  CellRange range{};
  if (box) {
    check_cell_box(*box);
    range = cells_of(map, *box);
    if (range.empty()) return;
  }
  const CellRange* limits = box ? &range : nullptr;
  for (const auto& [key, slot] : blocks_to_visit(map, limits, selection))
    visit_block(map, key, slot, limits, selection, visit);
}

std::vector<MapCell> cells_in_box(const BgkMap& map, const CellBox& box, bool include_unobserved) {
  std::vector<MapCell> cells;
  for_each_cell_in_box(map, &box, include_unobserved ? CellSelection::kAll : CellSelection::kWithEvidence,
                       [&](const MapCell& c) { cells.push_back(c); });
  return cells;
}

std::vector<MapCell> occupied_cells(const BgkMap& map, const CellBox* box) {
  std::vector<MapCell> cells;
  for_each_cell_in_box(map, box, CellSelection::kOccupied, [&](const MapCell& c) { cells.push_back(c); });
  return cells;
}

}  // namespace bgkmap
