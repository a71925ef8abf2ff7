#include "bgkmap/map/bgk_map.hpp"

#include <stdexcept>
#include <utility>

#include "map/block_store.hpp"

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

CellState state_of_probability(double probability, const ClassifyParams& classify) {
  if (probability > classify.occupied_threshold) return CellState::kOccupied;
  if (probability < classify.free_threshold) return CellState::kFree;
  return CellState::kUnknown;
}

CellState CellPosterior::state(const ClassifyParams& classify) const {
  if (!has_evidence || variance() > classify.var_threshold) return CellState::kUnknown;
  return state_of_probability(mean(), classify);
}

BgkMap::BgkMap(const BuildParams& params)
    : params_(params), grid_(params.grid), blocks_(std::make_unique<BlockIndex>()) {}
BgkMap::BgkMap(const BgkMap& other)
    : params_(other.params_), grid_(other.grid_), blocks_(std::make_unique<BlockIndex>(*other.blocks_)),
      cells_(other.cells_), forgetting_(other.forgetting_) {}
BgkMap& BgkMap::operator=(const BgkMap& other) {
  if (this != &other) *this = BgkMap(other);
  return *this;
}
BgkMap::BgkMap(BgkMap&&) noexcept = default;
BgkMap& BgkMap::operator=(BgkMap&&) noexcept = default;
BgkMap::~BgkMap() = default;

size_t BgkMap::block_count() const { return blocks_->size(); }
const BlockKey& BgkMap::key_of_slot(uint32_t slot) const { return blocks_->key(slot); }

int64_t BgkMap::find_slot(const BlockKey& key) const {
  const uint32_t slot = blocks_->find(key);
  return slot == BlockIndex::kAbsent ? -1 : static_cast<int64_t>(slot);
}

uint32_t BgkMap::ensure_slot(const BlockKey& key) {
  // The cells first: if they cannot be had, the map is as before.
  return blocks_->find_or_insert(key, [&] {
    cells_.append(static_cast<size_t>(cells_per_block()), Cell{params_.prior.alpha0, params_.prior.beta0});
    if (forgetting_.on()) forgetting_.block_time.push_back(forgetting_.now);  // prior cells: nothing to decay yet
  });
}

void BgkMap::set_forget_half_life(double half_life_scans) {
  if (block_count() != 0 || forgetting_.now != 0)
    throw std::logic_error("the forgetting half-life is set on a new map");
  forgetting_.half_life_scans = half_life_scans;
}

float BgkMap::take_decay(uint32_t slot) {
  uint64_t& time = forgetting_.block_time[slot];
  const float factor = static_cast<float>(decay_factor(forgetting_.half_life_scans, forgetting_.now - time));
  time = forgetting_.now;
  return factor;
}

void BgkMap::catch_up_block(uint32_t slot) {
  if (!block_behind(slot)) return;
  decay_cells(block_cells(slot), static_cast<size_t>(cells_per_block()), Cell{params_.prior.alpha0, params_.prior.beta0},
              take_decay(slot));
}

BgkMap BgkMap::settled() const {
  BgkMap out(*this);
  for (uint32_t slot = 0; slot < out.block_count(); ++slot) out.catch_up_block(slot);
  return out;
}

const BgkMap& read_view(const BgkMap& map, std::optional<BgkMap>& cache) {
  if (!map.forgetting().on()) return map;
  if (!cache || cache->forgetting().now != map.forgetting().now) cache = map.settled();
  return *cache;
}

void BgkMap::restore_time(uint64_t now, std::vector<uint64_t> block_time) {
  if (!forgetting_.on() || block_time.size() != block_count())
    throw std::logic_error("restore_time needs a forgetting map's time for each of its blocks");
  forgetting_.now = now;
  forgetting_.block_time = std::move(block_time);
}

CellPosterior BgkMap::posterior(const Cell& cell) const {
  CellPosterior p;
  p.alpha = cell.alpha;
  p.beta = cell.beta;
  p.has_evidence = cell.alpha != params_.prior.alpha0 || cell.beta != params_.prior.beta0;
  return p;
}

int32_t BgkMap::layer_block_z() const { return floor_div(params_.planar_layer(), grid_.cells_per_side()); }

int BgkMap::layer_local_z() const { return params_.planar_layer() - layer_block_z() * grid_.cells_per_side(); }

CellIndex BgkMap::cell_of(double x, double y, double z) const {
  return grid_.cell_of(x, y, params_.preprocess.planar ? params_.preprocess.plane_z_m : z);
}

CellPosterior BgkMap::query(double x, double y, double z) const {
  const CellIndex c = cell_of(x, y, z);
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
