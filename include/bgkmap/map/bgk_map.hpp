// The BGK occupancy map: a hash of blocks, each holding the Beta posterior (alpha, beta) of its
// cells. Blocks live in one pool of fixed-size slots so that a device back end can mirror the
// pool slot for slot; the hash maps block keys to slots.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "bgkmap/core/grid.hpp"
#include "bgkmap/core/params.hpp"
#include "bgkmap/map/forgetting.hpp"
#include "bgkmap/map/internal/cell_pool.hpp"

namespace bgkmap {

class BlockIndex;  // src/map/block_store.hpp

enum class CellState { kUnknown = 0, kFree = 1, kOccupied = 2 };
const char* to_string(CellState state);

// A probability's class by the thresholds alone: occupied above classify.occupied_threshold, free
// below classify.free_threshold, else unknown. The classification of the methods without a Beta
// posterior (gpoctomap, gpom, wgpom, bhm), whose variances are not a Beta's.
CellState state_of_probability(double probability, const ClassifyParams& classify);

// Posterior summaries of one cell.
struct CellPosterior {
  double alpha = 0, beta = 0;
  bool has_evidence = false;  // some observation changed alpha or beta from the prior

  double mean() const { return alpha / (alpha + beta); }
  double variance() const {
    const double s = alpha + beta;
    return alpha * beta / (s * s * (s + 1.0));
  }
  // (alpha-1)/(alpha+beta-2) where the Beta density has an interior mode (alpha, beta > 1);
  // otherwise the end the density grows towards (docs/ALGORITHM.md).
  double mode() const;
  // Unknown without evidence or with variance above classify.var_threshold, else
  // state_of_probability of the mean.
  CellState state(const ClassifyParams& classify) const;
};

class BgkMap {
 public:
  explicit BgkMap(const BuildParams& params);
  BgkMap(const BgkMap& other);
  BgkMap& operator=(const BgkMap& other);
  BgkMap(BgkMap&&) noexcept;
  BgkMap& operator=(BgkMap&&) noexcept;
  ~BgkMap();

  const BuildParams& params() const { return params_; }
  // Thresholds only classify cells (outputs, queries); they may change after a build.
  void set_classify(const ClassifyParams& classify) { params_.classify = classify; }
  const Grid& grid() const { return grid_; }
  int cells_per_block() const { return grid_.cells_per_block(); }

  size_t block_count() const;
  // Slot of a block, or -1 if the block was never touched.
  int64_t find_slot(const BlockKey& key) const;
  // Slot of a block, creating it (every cell at the prior) when absent.
  uint32_t ensure_slot(const BlockKey& key);
  const BlockKey& key_of_slot(uint32_t slot) const;

  Cell* block_cells(uint32_t slot) { return cells_.data() + static_cast<size_t>(slot) * cells_per_block(); }
  const Cell* block_cells(uint32_t slot) const {
    return cells_.data() + static_cast<size_t>(slot) * cells_per_block();
  }
  // The whole pool: slot s occupies [s * cells_per_block, (s+1) * cells_per_block).
  CellPool& cell_pool() { return cells_; }
  const CellPool& cell_pool() const { return cells_; }

  // Posterior at a world point; cells of untouched blocks return the prior. A planar map answers
  // for its layer whatever z is.
  CellPosterior query(double x, double y, double z) const;
  // The cell a world point falls in: a planar map's layer cell below or above it.
  CellIndex cell_of(double x, double y, double z) const;
  // A planar map's layer: the z index of its blocks, and of its cells inside them.
  int32_t layer_block_z() const;
  int layer_local_z() const;
  CellPosterior posterior(const Cell& cell) const;

  // Cells whose alpha or beta moved away from the prior.
  size_t cells_with_evidence() const;

  // Forgetting (map/forgetting.hpp). The half-life is set on a new map, or by its .bgk.
  const Forgetting& forgetting() const { return forgetting_; }
  void set_forget_half_life(double half_life_scans);
  // A new scan: the map's time moves on by one (the scan's blocks decay to it when touched).
  void advance_time() { ++forgetting_.now; }
  // Whether the block's cells were last decayed to an earlier time than now.
  bool block_behind(uint32_t slot) const { return forgetting_.on() && forgetting_.block_time[slot] < forgetting_.now; }
  // A block that is behind: its factor to now (decay_factor as a float), its time set to now; the
  // caller decays its cells by it (decay_cells, or a back end's copy of them).
  float take_decay(uint32_t slot);
  // Decays a block that is behind to the map's time, on the host; nothing otherwise.
  void catch_up_block(uint32_t slot);
  // The map as a read sees it: every block decayed to now (a plain copy when forgetting is off).
  BgkMap settled() const;
  // A .bgk's time and per-slot times (read after its blocks, in slot order).
  void restore_time(uint64_t now, std::vector<uint64_t> block_time);

  // Calls visit(const CellIndex&, const CellPosterior&) for every cell with evidence, block by
  // block in slot order and cell by cell in local order (the order of the .bgk file).
  template <typename Visit>
  void for_each_cell_with_evidence(Visit&& visit) const {
    const int n = cells_per_block();
    for (uint32_t slot = 0; slot < block_count(); ++slot) {
      const Cell* cells = block_cells(slot);
      const BlockKey& key = key_of_slot(slot);
      for (int local = 0; local < n; ++local) {
        const CellPosterior p = posterior(cells[local]);
        if (p.has_evidence) visit(grid_.cell_at(key, local), p);
      }
    }
  }

 private:
  BuildParams params_;
  Grid grid_;
  std::unique_ptr<BlockIndex> blocks_;  // key -> slot
  CellPool cells_;
  Forgetting forgetting_;
};

// What a read of `map` sees: the map itself, or with forgetting its settled() copy in `cache`
// (made again once the map's time moved on).
const BgkMap& read_view(const BgkMap& map, std::optional<BgkMap>& cache);

}  // namespace bgkmap
