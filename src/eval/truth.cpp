#include "bgkmap/eval/truth.hpp"

#include <octomap/OcTree.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <utility>

#include "bgkmap/io/errors.hpp"
#include "bgkmap/sim/spec.hpp"
#include "core/progress_counter.hpp"
#include "eval/octree_file.hpp"

namespace bgkmap::eval {

namespace {

class SceneTruth : public Truth {
 public:
  SceneTruth(sim::Scene scene, const Grid& grid) : scene_(std::move(scene)), grid_(grid), region_(sim::truth_region(scene_)) {}
  sim::Box3d region() const override { return region_; }
  TruthLabel label(const CellIndex& c) const override {
    const Vec3d p = grid_.cell_center_d(c);
    if (!region_.contains(p)) return TruthLabel::kUnknown;
    return scene_.contains(p) ? TruthLabel::kOccupied : TruthLabel::kFree;
  }

 private:
  sim::Scene scene_;
  Grid grid_;
  sim::Box3d region_;
};

class OctreeTruth : public Truth {
 public:
  OctreeTruth(std::unique_ptr<octomap::OcTree> tree, const Grid& grid) : tree_(std::move(tree)), grid_(grid) {
    double x0, y0, z0, x1, y1, z1;
    tree_->getMetricMin(x0, y0, z0);
    tree_->getMetricMax(x1, y1, z1);
    region_ = {{x0, y0, z0}, {x1, y1, z1}};
  }
  sim::Box3d region() const override { return region_; }
  TruthLabel label(const CellIndex& c) const override {
    const Vec3d p = grid_.cell_center_d(c);
    const octomap::OcTreeNode* node = tree_->search(p.x, p.y, p.z);
    if (!node) return TruthLabel::kUnknown;
    return tree_->isNodeOccupied(node) ? TruthLabel::kOccupied : TruthLabel::kFree;
  }

 private:
  std::unique_ptr<octomap::OcTree> tree_;
  Grid grid_;
  sim::Box3d region_;
};

std::string lower_extension(const std::filesystem::path& file) {
  std::string ext = file.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext;
}

}  // namespace

std::unique_ptr<Truth> make_scene_truth(const sim::Scene& scene, const Grid& grid) {
  return std::make_unique<SceneTruth>(scene, grid);
}

std::unique_ptr<Truth> load_truth(const std::filesystem::path& file, const Grid& grid, std::optional<int> at_scan) {
  if (!std::filesystem::is_regular_file(file)) throw InputError(file, "truth file not found");
  const std::string ext = lower_extension(file);
  if (ext == ".yaml" || ext == ".yml") {
    sim::SimulationSpec spec = sim::load_spec(file);
    const int last = spec.trajectory.scans - 1;
    if (at_scan && (*at_scan < 0 || *at_scan > last))
      throw InputError(file, "--truth-at " + std::to_string(*at_scan) + " is outside the scene's scans 0.." +
                                 std::to_string(last));
    try {
      return std::make_unique<SceneTruth>(sim::scene_at(spec.scene, at_scan.value_or(last)), grid);
    } catch (const std::invalid_argument& e) {
      throw InputError(file, e.what());
    }
  }
  if (at_scan) throw InputError(file, "--truth-at needs a scene file (.yaml): a .bt holds the truth at one time");
  if (ext != ".bt") throw InputError(file, "truth must be a scene file (.yaml) or an OctoMap binary tree (.bt)");
  std::unique_ptr<octomap::OcTree> tree = read_octree_file(file, OctreeFile::kBinary);
  if (std::abs(tree->getResolution() - grid.resolution()) > 1e-9 * grid.resolution()) {
    std::ostringstream msg;
    msg << "truth resolution " << tree->getResolution() << " m differs from the map's " << grid.resolution()
        << " m; use a truth at the map's resolution, or the scene file";
    throw InputError(file, msg.str());
  }
  if (tree->size() == 0) throw InputError(file, "the truth tree is empty");
  return std::make_unique<OctreeTruth>(std::move(tree), grid);
}

namespace {
// The first and last cell index whose centre (i + 0.5) r lies in [lo, hi].
std::pair<int32_t, int32_t> cells_between(double lo, double hi, double r) {
  return {static_cast<int32_t>(std::ceil(lo / r - 0.5)), static_cast<int32_t>(std::floor(hi / r - 0.5))};
}
}  // namespace

void for_each_cell_in(const Grid& grid, const sim::Box3d& box, const std::function<void(const CellIndex&)>& visit) {
  if (box.min.x > box.max.x || box.min.y > box.max.y || box.min.z > box.max.z) return;
  const double r = grid.resolution();
  const auto [x0, x1] = cells_between(box.min.x, box.max.x, r);
  const auto [y0, y1] = cells_between(box.min.y, box.max.y, r);
  const auto [z0, z1] = cells_between(box.min.z, box.max.z, r);
  for (int32_t z = z0; z <= z1; ++z)
    for (int32_t y = y0; y <= y1; ++y)
      for (int32_t x = x0; x <= x1; ++x) visit({x, y, z});
}

uint64_t cell_count_in(const Grid& grid, const sim::Box3d& box) {
  if (box.min.x > box.max.x || box.min.y > box.max.y || box.min.z > box.max.z) return 0;
  uint64_t count = 1;
  for (const auto& [lo, hi] : {cells_between(box.min.x, box.max.x, grid.resolution()),
                               cells_between(box.min.y, box.max.y, grid.resolution()),
                               cells_between(box.min.z, box.max.z, grid.resolution())})
    count *= hi >= lo ? static_cast<uint64_t>(int64_t(hi) - lo + 1) : 0;
  return count;
}

TruthScores score_against_truth(const ScoredMap& map, const Truth& truth, const sim::Box3d& box,
                                const ProgressCallback& progress) {
  return score_against_truth([&map](const Vec3d& p) { return map.sample(p.x, p.y, p.z); }, map.grid(), truth, box,
                             progress);
}

TruthScores score_against_truth(const MapSampler& sample_at, const Grid& grid, const Truth& truth,
                                const sim::Box3d& box, const ProgressCallback& progress) {
  TruthScores out;
  // Every cell's score is kept for the exact, tie-aware metrics: refuse boxes that would not fit.
  const double r = grid.resolution();
  const double cells = std::max(0.0, (box.max.x - box.min.x) / r + 1) * std::max(0.0, (box.max.y - box.min.y) / r + 1) *
                       std::max(0.0, (box.max.z - box.min.z) / r + 1);
  if (cells > kMaxScoredCells) {
    std::ostringstream msg;
    msg << "the evaluated box holds about " << cells << " cells, more than the " << kMaxScoredCells
        << " that scoring keeps in memory; score a smaller scene or a coarser map";
    throw std::invalid_argument(msg.str());
  }
  ProgressCounter counter(progress, "score", "cells", cell_count_in(grid, box));
  for_each_cell_in(grid, box, [&](const CellIndex& c) {
    counter.add();
    const TruthLabel label = truth.label(c);
    if (label == TruthLabel::kUnknown) return;
    const Vec3d p = grid.cell_center_d(c);
    const MapSample sample = sample_at(p);
    const bool occupied = label == TruthLabel::kOccupied;
    (occupied ? out.all_cells.positive : out.all_cells.negative).push_back(sample.score);
    if (sample.has_evidence)
      (occupied ? out.observed_cells.positive : out.observed_cells.negative).push_back(sample.score);
  });
  counter.finish();
  return out;
}

}  // namespace bgkmap::eval
