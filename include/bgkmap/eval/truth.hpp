// Scoring a map against analytic truth: a simulator scene (scene.yaml, exact inside test at each
// cell centre) or a truth OctoMap (.bt, e.g. the simulator's truth.bt) at the map's resolution.
//
// Cells scored: the truth's cells whose centre lies in the truth region and in the maps' observed
// bounds (the box around every cell with evidence). Two protocols:
//   all_cells       every such cell; a cell the map has no evidence for scores kUnknownScore (0.5)
//   observed_cells  only the cells the map has evidence for
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>

#include "bgkmap/core/grid.hpp"
#include "bgkmap/core/progress.hpp"
#include "bgkmap/eval/metrics.hpp"
#include "bgkmap/eval/scored_map.hpp"
#include "bgkmap/sim/vec_math.hpp"

namespace bgkmap::sim {
struct Scene;
}

namespace bgkmap::eval {

enum class TruthLabel { kUnknown = -1, kFree = 0, kOccupied = 1 };

class Truth {
 public:
  virtual ~Truth() = default;
  // Metres; only cells whose centre lies in it have a label.
  virtual sim::Box3d region() const = 0;
  // Label of the cell of `grid` (the map's grid) at index c.
  virtual TruthLabel label(const CellIndex& c) const = 0;
};

// scene.yaml (a `bgkmap simulate` output or any scene file) or a .bt truth map. Throws InputError
// naming the file when it cannot be read, or when a .bt's resolution differs from `resolution`.
// A scene with dynamic objects is taken as it is at scan `at_scan`, by default its last scan;
// at_scan with a .bt is an InputError (a .bt holds one time).
std::unique_ptr<Truth> load_truth(const std::filesystem::path& file, const Grid& grid,
                                  std::optional<int> at_scan = std::nullopt);
// The truth of a scene's static solids (sim::Scene::contains) on `grid`.
std::unique_ptr<Truth> make_scene_truth(const sim::Scene& scene, const Grid& grid);

struct TruthScores {
  LabelledScores all_cells;
  LabelledScores observed_cells;
};

// Scores the map on every truth cell whose centre lies in `box` (see the protocols above).
// Throws std::invalid_argument when the box holds more than kMaxScoredCells cells. `progress`
// hears of the box's cells scored.
constexpr double kMaxScoredCells = 4e8;
TruthScores score_against_truth(const ScoredMap& map, const Truth& truth, const sim::Box3d& box,
                                const ProgressCallback& progress = {});
// The same for a map seen through `sample` (a world point in, its sample out) on `grid`.
using MapSampler = std::function<MapSample(const Vec3d& point)>;
TruthScores score_against_truth(const MapSampler& sample, const Grid& grid, const Truth& truth, const sim::Box3d& box,
                                const ProgressCallback& progress = {});

// Calls visit(cell) for every cell of `grid` whose centre lies in `box`.
void for_each_cell_in(const Grid& grid, const sim::Box3d& box, const std::function<void(const CellIndex&)>& visit);
// How many cells for_each_cell_in visits.
uint64_t cell_count_in(const Grid& grid, const sim::Box3d& box);

}  // namespace bgkmap::eval
