#include "bgkmap/map/bgk_map.hpp"

#include "core/key_table.hpp"

namespace bgkmap {

const char* to_string(CellState state) {
  switch (state) {
    case CellState::kUnknown: return "unknown";
    case CellState::kFree: return "free";
    case CellState::kOccupied: return "occupied";
  }
  return "?";
}

double CellPosterior::mode() const {
  if (alpha > 1 && beta > 1) return (alpha - 1) / (alpha + beta - 2);
  if (alpha > beta) return 1.0;  // density grows towards 1
  if (beta > alpha) return 0.0;
  return 0.5;  // symmetric U or flat: no single mode, report the centre
}

CellState CellPosterior::state(const ClassifyParams& classify) const {
  if (!has_evidence || variance() > classify.var_threshold) return CellState::kUnknown;
  const double m = mean();
  if (m > classify.occupied_threshold) return CellState::kOccupied;
  if (m < classify.free_threshold) return CellState::kFree;
  return CellState::kUnknown;
}

BgkMap::BgkMap(const BuildParams& params) : params_(params), grid_(params.grid) {
  key_table::reset(slot_table_, 1024);
}

int64_t BgkMap::find_slot(const BlockKey& key) const {
  const uint32_t slot = key_table::find(slot_table_, keys_, key);
  return slot == key_table::kEmpty ? -1 : static_cast<int64_t>(slot);
}

uint32_t BgkMap::ensure_slot(const BlockKey& key) {
  const size_t at = key_table::position(slot_table_, keys_, key);
  if (slot_table_[at] != key_table::kEmpty) return slot_table_[at];
  // The cells first: if they cannot be had, the map is as before.
  cells_.append(static_cast<size_t>(cells_per_block()), Cell{params_.prior.alpha0, params_.prior.beta0});
  const uint32_t slot = static_cast<uint32_t>(keys_.size());
  keys_.push_back(key);
  slot_table_[at] = slot;
  key_table::grow_for(slot_table_, keys_, keys_.size());
  return slot;
}

CellPosterior BgkMap::posterior(const Cell& cell) const {
  CellPosterior p;
  p.alpha = cell.alpha;
  p.beta = cell.beta;
  p.has_evidence = cell.alpha != params_.prior.alpha0 || cell.beta != params_.prior.beta0;
  return p;
}

CellPosterior BgkMap::query(double x, double y, double z) const {
  const CellIndex c = grid_.cell_of(x, y, z);
  const int64_t slot = find_slot(grid_.block_of(c));
  if (slot < 0) return posterior(Cell{params_.prior.alpha0, params_.prior.beta0});
  return posterior(block_cells(static_cast<uint32_t>(slot))[grid_.local_index(c)]);
}

size_t BgkMap::cells_with_evidence() const {
  size_t n = 0;
  for (const Cell& c : cells_) n += (c.alpha != params_.prior.alpha0 || c.beta != params_.prior.beta0);
  return n;
}

}  // namespace bgkmap
