// OctoMap's tools read bgkmap's .ot and .bt as bgkmap classifies: the trees are read back with
// liboctomap (AbstractOcTree::read, OcTree::readBinary), and every cell's class there (no node:
// unknown; isNodeOccupied at OctoMap's default 0.5) is checked against the map's own
// (CellPosterior::state of the .bgk, or the method's state_of_probability), on the shared
// sim_structured scans and the Intel log, and on a small planar scene for every method.
#include <gtest/gtest.h>
#include <octomap/AbstractOcTree.h>
#include <octomap/OcTree.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "bgkmap/io/map_io.hpp"
#include "bgkmap/io/native_map.hpp"
#include "bgkmap/map/bgk_map.hpp"
#include "bgkmap/methods/method.hpp"
#include "io/probability_tree.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

namespace fs = std::filesystem;
using testing::TempDir;

// A cell as the map classifies it: its centre, its probability and its class.
struct ClassifiedCell {
  Vec3d centre;
  double probability;
  CellState state;
};

std::unique_ptr<octomap::OcTree> read_tree(const fs::path& file) {
  std::unique_ptr<octomap::AbstractOcTree> tree(octomap::AbstractOcTree::read(file.string()));
  auto* octree = dynamic_cast<octomap::OcTree*>(tree.get());
  if (!octree) return nullptr;
  tree.release();
  return std::unique_ptr<octomap::OcTree>(octree);
}

std::unique_ptr<octomap::OcTree> read_binary_tree(const fs::path& file) {
  auto tree = std::make_unique<octomap::OcTree>(0.1);
  if (!tree->readBinary(file.string())) return nullptr;
  return tree;
}

// Finest-level cells the tree's leaves cover (a pruned leaf at depth d covers 8^(16-d)).
uint64_t covered_cells(const octomap::OcTree& tree) {
  uint64_t n = 0;
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it)
    n += uint64_t{1} << (3 * (tree.getTreeDepth() - it.getDepth()));
  return n;
}

struct ClassCounts {
  uint64_t occupied = 0, free = 0, unknown = 0;
};

// Every cell's class in `tree` is the map's: unknown cells have no node, the others a node that
// isNodeOccupied calls occupied exactly when the map does; and the tree holds no other cell.
// `values_kept`: the node's probability is the cell's (to float log-odds) wherever it is known.
ClassCounts expect_classes(const octomap::OcTree& tree, const std::vector<ClassifiedCell>& cells, bool values_kept,
                           const std::string& what) {
  ClassCounts counts;
  uint64_t mismatched = 0;
  for (const ClassifiedCell& cell : cells) {
    const octomap::OcTreeNode* node = tree.search(cell.centre.x, cell.centre.y, cell.centre.z);
    if (cell.state == CellState::kUnknown) {
      ++counts.unknown;
      mismatched += node != nullptr;
      continue;
    }
    ++(cell.state == CellState::kOccupied ? counts.occupied : counts.free);
    if (!node || tree.isNodeOccupied(node) != (cell.state == CellState::kOccupied)) {
      ++mismatched;
      continue;
    }
    if (values_kept) {
      EXPECT_NEAR(node->getOccupancy(), std::clamp(cell.probability, 1e-6, 1 - 1e-6), 1e-6)
          << what << " at " << cell.centre.x << " " << cell.centre.y << " " << cell.centre.z;
    }
  }
  EXPECT_EQ(mismatched, 0u) << what << ": cells whose class in the tree differs from the map's";
  EXPECT_EQ(covered_cells(tree), counts.occupied + counts.free) << what << ": the tree holds other cells";
  return counts;
}

std::vector<ClassifiedCell> cells_of(const BgkMap& map) {
  std::vector<ClassifiedCell> cells;
  map.for_each_cell_with_evidence([&](const CellIndex& c, const CellPosterior& p) {
    cells.push_back({map.grid().cell_center_d(c), p.mean(), p.state(map.params().classify)});
  });
  return cells;
}

testing::CommandResult run_cli(const std::string& args) {
  return testing::run_command(std::string(BGKMAP_CLI) + " " + args);
}

// Builds `input` with `flags` to m.bgk, m.ot, m.bt and mean.ot (--ot-values mean) in `dir`, and
// checks both trees' classes against the .bgk's; returns the .bgk's counts.
ClassCounts check_dataset(const fs::path& dir, const std::string& input, const std::string& flags) {
  const std::string d = dir.string() + "/";
  testing::CommandResult r = run_cli("build -q " + input + " " + flags + " -o " + d + "m.bgk -o " + d + "m.ot -o " + d + "m.bt");
  EXPECT_EQ(r.status, 0) << r.output;
  r = run_cli("build -q " + input + " " + flags + " --ot-values mean -o " + d + "mean.ot");
  EXPECT_EQ(r.status, 0) << r.output;
  const BgkMap map = read_native_map(dir / "m.bgk");
  const std::vector<ClassifiedCell> cells = cells_of(map);
  const std::unique_ptr<octomap::OcTree> ot = read_tree(dir / "m.ot");
  const std::unique_ptr<octomap::OcTree> bt = read_binary_tree(dir / "m.bt");
  const std::unique_ptr<octomap::OcTree> mean = read_tree(dir / "mean.ot");
  if (!ot || !bt || !mean) {
    ADD_FAILURE() << "liboctomap could not read the trees in " << dir;
    return {};
  }
  const ClassifyParams& classify = map.params().classify;
  const bool means_classify_right = classify.occupied_threshold >= 0.5 && classify.free_threshold <= 0.5;
  const ClassCounts counts = expect_classes(*ot, cells, means_classify_right, input + " .ot");
  expect_classes(*bt, cells, false, input + " .bt");
  // --ot-values mean: every cell with evidence, at its posterior mean.
  uint64_t far = 0;
  for (const ClassifiedCell& cell : cells) {
    const octomap::OcTreeNode* node = mean->search(cell.centre.x, cell.centre.y, cell.centre.z);
    far += !node || std::abs(node->getOccupancy() - std::clamp(cell.probability, 1e-6, 1 - 1e-6)) > 1e-6;
  }
  EXPECT_EQ(far, 0u) << input << " mean.ot: cells missing or not at their posterior mean";
  EXPECT_EQ(covered_cells(*mean), cells.size());
  return counts;
}

TEST(OctomapClasses, SimStructuredTreesClassifyEveryCellAsTheMap) {
  BGKMAP_REQUIRE_DATASETS(datasets);
  TempDir dir("octomap_classes_sim");
  const ClassCounts counts = check_dataset(dir.path(), (datasets / "sim_structured").string(),
                                           "--ds 0.1 --max-range 8 --resolution 0.1 --ell 0.2 --sigma0 0.1 --threads 2");
  EXPECT_GT(counts.occupied, 1000u);
  EXPECT_GT(counts.free, 10000u);
  EXPECT_GT(counts.unknown, 10000u);  // cells with evidence the map does not decide: left out of the .ot
}

TEST(OctomapClasses, IntelLogPlanarTreesClassifyEveryCellAsTheMap) {
  BGKMAP_REQUIRE_DATASETS(datasets);
  TempDir dir("octomap_classes_intel");
  const ClassCounts counts =
      check_dataset(dir.path(), (datasets / "carmen" / "intel-corrected.log.gz").string(), "--max-range 20 --2d --threads 2");
  EXPECT_GT(counts.occupied, 1000u);
  EXPECT_GT(counts.unknown, 1000u);
}

// Thresholds on the wrong side of 0.5: the classes still agree, and the stored probabilities keep
// the cells' order by posterior mean.
TEST(OctomapClasses, ThresholdsAcrossOneHalfKeepClassesAndOrder) {
  BGKMAP_REQUIRE_DATASETS(datasets);
  for (const std::string thresholds : {"--occupied-threshold 0.45 --free-threshold 0.2",
                                       "--occupied-threshold 0.8 --free-threshold 0.6"}) {
    SCOPED_TRACE(thresholds);
    TempDir dir("octomap_classes_thresholds");
    const ClassCounts counts = check_dataset(
        dir.path(), (datasets / "sim_structured").string(),
        "--ds 0.1 --max-range 8 --resolution 0.1 --ell 0.2 --sigma0 0.1 --threads 2 " + thresholds);
    EXPECT_GT(counts.occupied, 1000u);
    EXPECT_GT(counts.free, 1000u);
    const BgkMap map = read_native_map(dir.path() / "m.bgk");
    std::vector<ClassifiedCell> cells = cells_of(map);
    std::sort(cells.begin(), cells.end(),
              [](const ClassifiedCell& a, const ClassifiedCell& b) { return a.probability < b.probability; });
    const std::unique_ptr<octomap::OcTree> ot = read_tree(dir.path() / "m.ot");
    ASSERT_TRUE(ot);
    float previous = -std::numeric_limits<float>::infinity();
    uint64_t out_of_order = 0, moved = 0;
    for (const ClassifiedCell& cell : cells) {
      if (cell.state == CellState::kUnknown) continue;
      const octomap::OcTreeNode* node = ot->search(cell.centre.x, cell.centre.y, cell.centre.z);
      ASSERT_NE(node, nullptr);
      out_of_order += node->getLogOdds() < previous;
      previous = node->getLogOdds();
      moved += std::abs(node->getOccupancy() - cell.probability) > 1e-6;
    }
    EXPECT_EQ(out_of_order, 0u);
    EXPECT_GT(moved, 0u);  // one class was rescaled onto OctoMap's side
  }
}

TEST(ClassifiedLogOdds, KeepsTheProbabilityWhereItClassifiesRight) {
  const ClassifyParams classify;  // 0.7 / 0.3
  for (const double p : {0.7000001, 0.75, 0.9, 0.999, 1.0})
    EXPECT_EQ(classified_log_odds(p, CellState::kOccupied, classify), octomap::logodds(std::min(p, 1 - 1e-6))) << p;
  for (const double p : {0.0, 1e-9, 0.01, 0.2, 0.2999999})
    EXPECT_EQ(classified_log_odds(p, CellState::kFree, classify), octomap::logodds(std::max(p, 1e-6))) << p;
}

TEST(ClassifiedLogOdds, RescalesAClassWhoseThresholdIsOnTheWrongSide) {
  ClassifyParams low;
  low.occupied_threshold = 0.4f, low.free_threshold = 0.2f;
  // (0.4, 1] onto (0.5, 1]: 0.7 -> 0.5 + 0.5 * 0.3 / 0.6 = 0.75.
  EXPECT_NEAR(octomap::probability(classified_log_odds(0.7, CellState::kOccupied, low)), 0.75, 1e-6);
  EXPECT_GE(classified_log_odds(std::nextafter(double(low.occupied_threshold), 1.0), CellState::kOccupied, low), 0.0f);
  EXPECT_EQ(classified_log_odds(0.1, CellState::kFree, low), octomap::logodds(0.1));  // free side unchanged
  ClassifyParams high;
  high.occupied_threshold = 0.8f, high.free_threshold = 0.6f;
  // [0, 0.6) onto [0, 0.5): 0.3 -> 0.25.
  EXPECT_NEAR(octomap::probability(classified_log_odds(0.3, CellState::kFree, high)), 0.25, 1e-6);
  EXPECT_LT(classified_log_odds(std::nextafter(double(high.free_threshold), 0.0), CellState::kFree, high), 0.0f);
  EXPECT_EQ(classified_log_odds(0.9, CellState::kOccupied, high), octomap::logodds(0.9));
}

// Every method that writes trees, on a small planar scene: each cell of the layer (around the
// scans, beyond where any method maps) has the method's own class in the .ot and the .bt.
TEST(OctomapClasses, EveryMethodsTreesClassifyAsTheMethod) {
  BuildParams params;
  params.grid.resolution_m = 0.1;
  params.preprocess.max_range_m = 1.5;
  params.set_planar(0.27);
  const std::vector<Scan> scans = testing::random_scans(31, 2, 120, 1.2f);
  for (const std::string& name : method_names()) {
    if (name == "octomap") continue;  // liboctomap's own tree (test_methods: leaf for leaf)
    SCOPED_TRACE(name);
    auto method = make_method(name, params, MethodParams{}, testing::cpu_backend());
    for (const Scan& scan : scans) method->insert(scan);
    method->finish();
    TempDir dir("octomap_classes_methods");
    method->write(dir / "m.ot");
    method->write(dir / "m.bt");
    std::vector<ClassifiedCell> cells;
    const double r = params.grid.resolution_m, z = (params.planar_layer() + 0.5) * r;
    for (int i = -40; i < 60; ++i)
      for (int j = -40; j < 60; ++j) {
        const Vec3d c{(i + 0.5) * r, (j + 0.5) * r, z};
        const std::optional<CellEstimate> e = method->estimate(c.x, c.y, c.z);
        if (!e) {
          cells.push_back({c, 0.5, CellState::kUnknown});
          continue;
        }
        const CellState state = e->beta ? e->beta->state(params.classify) : state_of_probability(e->occupancy, params.classify);
        cells.push_back({c, e->occupancy, state});
      }
    const std::unique_ptr<octomap::OcTree> ot = read_tree(dir / "m.ot");
    const std::unique_ptr<octomap::OcTree> bt = read_binary_tree(dir / "m.bt");
    ASSERT_TRUE(ot && bt);
    const ClassCounts counts = expect_classes(*ot, cells, true, name + " .ot");
    expect_classes(*bt, cells, false, name + " .bt");
    EXPECT_GT(counts.occupied + counts.free, 20u);
  }
}

// eval scores probabilities of every cell: a classified .ot is refused, naming the file and the
// flag; the same map written with --ot-values mean is scored.
TEST(OctomapClasses, EvalRefusesAClassifiedTree) {
  TempDir dir("octomap_classes_eval");
  const std::string d = dir.path().string() + "/";
  testing::CommandResult r = run_cli("simulate structured -o " + d + "sim --scans 2 -q");
  ASSERT_EQ(r.status, 0) << r.output;
  r = run_cli("build -q " + d + "sim/scans --max-range 14 --threads 2 -o " + d + "c.ot");
  ASSERT_EQ(r.status, 0) << r.output;
  r = run_cli("build -q " + d + "sim/scans --max-range 14 --threads 2 --ot-values mean -o " + d + "m.ot");
  ASSERT_EQ(r.status, 0) << r.output;
  r = run_cli("eval " + d + "c.ot --truth " + d + "sim/scene.yaml --json " + d + "c.json");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find(d + "c.ot"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("--ot-values mean"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "c.json"));
  r = run_cli("eval " + d + "m.ot --truth " + d + "sim/scene.yaml --json " + d + "m.json");
  EXPECT_EQ(r.status, 0) << r.output;
  r = run_cli("build -q " + d + "sim/scans --ot-values median -o " + d + "x.ot");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("--ot-values"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace bgkmap
