// Scoring a dynamic scene: the vacated cells (removed-object and trail cells, seen through or not)
// of a hand-built scene, the per-scan rows of `bgkmap eval --per-scan` against a brute-force count
// of the truth at each scan, and `bgkmap diff` on two hand-made maps against the expected cells.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "bgkmap/eval/dynamic_cells.hpp"
#include "bgkmap/io/map_changes.hpp"
#include "bgkmap/io/native_map.hpp"
#include "bgkmap/sim/spec.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

using sim::Box;

// One beam along +x from (0, 0.05, 1.05) to a wall at x = 4. A crate of four cells (x 20..21,
// y -1..0, z 10) leaves at scan 2; a walker of one cell starts at cell (10, 0, 10) on the beam
// and paces 1 m to +y and back at 0.5 m a scan (on the beam at scans 0 and 4).
sim::SimulationSpec one_beam_spec() {
  sim::SimulationSpec spec;
  spec.scene.primitives.push_back(Box({4, 0, 1}, {0.2, 4, 2}));
  spec.scene.bounds = sim::Box3d{{-1, -2, 0}, {5, 2, 2}};
  spec.scene.dynamic.push_back({"crate", Box({2.1, 0, 1.05}, {0.2, 0.2, 0.1}), 0, 2});
  sim::DynamicObject walker{"walker", Box({1.05, 0.05, 1.05}, {0.1, 0.1, 0.1})};
  walker.path = {{1.05, 0.05, 1.05}, {1.05, 1.05, 1.05}};
  walker.speed_m_per_scan = 0.5;
  spec.scene.dynamic.push_back(walker);
  spec.sensor.kind = sim::SensorKind::kPinhole;
  spec.sensor.width = spec.sensor.height = 1;  // one beam, straight ahead
  spec.sensor.horizontal_fov_deg = spec.sensor.vertical_fov_deg = 10;
  spec.trajectory.waypoints = {{{0, 0.05, 1.05}, 0.0}};
  spec.trajectory.scans = 6;
  spec.validate();
  return spec;
}

Grid grid_of(double resolution) {
  GridParams p;
  p.resolution_m = resolution;
  return Grid(p);
}

TEST(DynamicCells, RemovedAndTrailCellsCountOnlyOnceSeenThrough) {
  const sim::SimulationSpec spec = one_beam_spec();
  const Grid grid = grid_of(0.1);
  eval::DynamicCells cells(spec, grid);
  // Crate: 4 cells; walker: the cells its centre passes at y 0.05, 0.55, 1.05.
  EXPECT_EQ(cells.size(), 4u + 3u);
  EXPECT_TRUE(cells.is_dynamic({20, -1, 10}));
  EXPECT_TRUE(cells.is_dynamic({10, 5, 10}));
  EXPECT_FALSE(cells.is_dynamic({39, 0, 10}));  // the wall
  // Free (0.1) before x = 1.5, occupied (0.9) beyond.
  const eval::MapSampler sample = [](const Vec3d& p) {
    return eval::MapSample{p.x < 1.5 ? 0.1 : 0.9, true, std::nullopt};
  };
  struct Want {
    uint64_t removed, removed_settled, trail, trail_settled;
  };
  // After scan t: the crate's two cells on the beam seen at scan 2 (the other two never); the
  // walker's first cell seen at scan 1, covered again at 4, seen again at 5.
  const Want want[6] = {{0, 0, 0, 0}, {0, 0, 1, 0}, {2, 0, 1, 0}, {2, 0, 1, 0}, {2, 0, 0, 0}, {2, 2, 1, 0}};
  for (int t = 0; t < 6; ++t) {
    cells.advance();
    const eval::DynamicScores s = cells.score(sample, 0.3, 0.7);
    EXPECT_EQ(s.removed.cells, want[t].removed) << "scan " << t;
    EXPECT_EQ(s.removed.settled_cells, want[t].removed_settled) << "scan " << t;
    EXPECT_EQ(s.trail.cells, want[t].trail) << "scan " << t;
    EXPECT_EQ(s.trail.settled_cells, want[t].trail_settled) << "scan " << t;
    EXPECT_EQ(s.removed.read_occupied, s.removed.cells);  // x ~ 2: scored 0.9
    EXPECT_EQ(s.removed.read_free, 0u);
    EXPECT_EQ(s.trail.read_free, s.trail.cells);          // x ~ 1: scored 0.1
  }
  EXPECT_EQ(cells.score(sample, 0.3, 0.7).removed.settled_free, 0u);
  // The static truth leaves every dynamic cell unknown.
  const auto truth = eval::make_scene_truth(sim::scene_at(spec.scene, 0), grid);
  const auto static_truth = eval::static_cells_truth(*truth, cells);
  EXPECT_EQ(truth->label({20, 0, 10}), eval::TruthLabel::kOccupied);
  EXPECT_EQ(static_truth->label({20, 0, 10}), eval::TruthLabel::kUnknown);
  EXPECT_EQ(static_truth->label({39, 0, 10}), eval::TruthLabel::kOccupied);
  EXPECT_EQ(static_truth->label({30, 0, 10}), eval::TruthLabel::kFree);
}

using Result = testing::CommandResult;
Result run(const std::string& args) { return testing::run_command(std::string(BGKMAP_CLI) + " " + args); }

// Truth cells of the region occupied at a scan, all and static-only: the brute force.
std::pair<uint64_t, uint64_t> occupied_truth_cells(const sim::SimulationSpec& spec, const Grid& grid, int scan,
                                                   const eval::DynamicCells& dynamic) {
  const sim::Scene now = sim::scene_at(spec.scene, scan);
  uint64_t all = 0, fixed = 0;
  eval::for_each_cell_in(grid, *spec.scene.bounds, [&](const CellIndex& c) {
    if (!now.contains(grid.cell_center_d(c))) return;
    ++all;
    fixed += !dynamic.is_dynamic(c);
  });
  return {all, fixed};
}

TEST(EvalPerScan, RowsEveryKScansScoreTheTruthAtThatScan) {
  const testing::TempDir dir("eval-per-scan");
  sim::SimulationSpec spec = one_beam_spec();
  spec.sensor = sim::sensor_preset("planar");
  spec.trajectory.scans = 5;
  spec.truth_resolution_m = 0;
  sim::save_spec(dir.path() / "in.yaml", spec);
  const std::string d = dir.path().string();
  ASSERT_EQ(run("simulate -q " + d + "/in.yaml -o " + d + "/sim").status, 0);
  const Result r = run("eval -q " + d + "/sim/scans --truth " + d + "/sim/scene.yaml --per-scan 2 --resolution 0.1 "
                       "--max-range 6 --json " + d + "/rows.json");
  ASSERT_EQ(r.status, 0) << r.output;
  const nlohmann::json report = nlohmann::json::parse(std::ifstream(dir.path() / "rows.json"));
  const nlohmann::json& rows = report["rows"];
  ASSERT_EQ(rows.size(), 3u);
  const Grid grid = grid_of(0.1);
  eval::DynamicCells dynamic(spec, grid);
  const int scans[3] = {1, 3, 4};
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(rows[i]["scan"].get<int>(), scans[i]);
    const auto [all, fixed] = occupied_truth_cells(spec, grid, scans[i], dynamic);
    EXPECT_EQ(rows[i]["all_cells"]["n_positive"].get<uint64_t>(), all) << "scan " << scans[i];
    EXPECT_EQ(rows[i]["static_cells"]["all_cells"]["n_positive"].get<uint64_t>(), fixed) << "scan " << scans[i];
  }
  EXPECT_GT(occupied_truth_cells(spec, grid, 1, dynamic).first, occupied_truth_cells(spec, grid, 3, dynamic).first);
  EXPECT_EQ(rows[0]["removed_cells"]["cells"].get<uint64_t>(), 0u);  // the crate is still there
  EXPECT_GT(rows[1]["removed_cells"]["cells"].get<uint64_t>(), 0u);

  const Result bad = run("eval -q " + d + "/sim/scans --truth " + d + "/sim/scene.yaml --per-scan 2 --holdout 0.5 "
                         "--json " + d + "/x.json");
  EXPECT_NE(bad.status, 0);
  EXPECT_NE(bad.output.find("--per-scan"), std::string::npos) << bad.output;
}

// ---- diff ----

void set_cell(BgkMap& map, const CellIndex& c, float alpha, float beta) {
  const uint32_t slot = map.ensure_slot(map.grid().block_of(c));
  Cell& cell = map.block_cells(slot)[map.grid().local_index(c)];
  cell.alpha = alpha, cell.beta = beta;
}

BgkMap small_map(double resolution) {
  BuildParams p;
  p.grid.resolution_m = resolution;
  return BgkMap(p);
}

// A: (1,1,1) occupied, (2,1,1) free, (3,1,1) occupied, (4,1,1) free; B: (1,1,1) free, (2,1,1)
// occupied, (3,1,1) occupied, (5,1,1) occupied (no evidence in A), (4,1,1) no evidence.
std::pair<BgkMap, BgkMap> hand_made_pair() {
  BgkMap a = small_map(0.5), b = small_map(0.5);
  set_cell(a, {1, 1, 1}, 40, 1), set_cell(b, {1, 1, 1}, 1, 40);
  set_cell(a, {2, 1, 1}, 1, 40), set_cell(b, {2, 1, 1}, 40, 1);
  set_cell(a, {3, 1, 1}, 40, 1), set_cell(b, {3, 1, 1}, 30, 1);
  set_cell(a, {4, 1, 1}, 1, 40);
  set_cell(b, {5, 1, 1}, 40, 1);
  return {std::move(a), std::move(b)};
}

TEST(MapChanges, HandMadeMapsGiveTheExpectedCells) {
  const auto [a, b] = hand_made_pair();
  const MapChanges c = compare_maps(a, b, std::nullopt, std::nullopt);
  EXPECT_EQ(c.compared, 3u);
  ASSERT_EQ(c.cleared.size(), 1u);
  ASSERT_EQ(c.appeared.size(), 1u);
  EXPECT_EQ(c.cleared[0].index, (CellIndex{1, 1, 1}));
  EXPECT_NEAR(c.cleared[0].probability_a, 40.0 / 41, 1e-6);
  EXPECT_NEAR(c.cleared[0].probability_b, 1.0 / 41, 1e-6);
  EXPECT_EQ(c.appeared[0].index, (CellIndex{2, 1, 1}));
  // An occupied threshold of 0.99 for both: 40/41 is no longer occupied, nothing changed.
  const MapChanges strict = compare_maps(a, b, 0.99f, std::nullopt);
  EXPECT_TRUE(strict.cleared.empty() && strict.appeared.empty());
  EXPECT_THROW(compare_maps(a, small_map(0.25), std::nullopt, std::nullopt), std::invalid_argument);
}

TEST(MapChanges, DiffCommandWritesTheCellsAndRefusesAnotherGrid) {
  const testing::TempDir dir("diff");
  const std::string d = dir.path().string();
  const auto [a, b] = hand_made_pair();
  write_native_map(dir.path() / "a.bgk", a);
  write_native_map(dir.path() / "b.bgk", b);
  write_native_map(dir.path() / "fine.bgk", small_map(0.25));
  const Result r = run("diff " + d + "/a.bgk " + d + "/b.bgk -o " + d + "/c.ply -o " + d + "/c.ot -o " + d +
                       "/c.png --json " + d + "/c.json");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("1 cells occupied -> free, 1 free -> occupied, of 3 cells"), std::string::npos) << r.output;
  const nlohmann::json j = nlohmann::json::parse(std::ifstream(dir.path() / "c.json"));
  EXPECT_EQ(j["cleared"][0]["cell"], nlohmann::json({1, 1, 1}));
  EXPECT_EQ(j["appeared"][0]["cell"], nlohmann::json({2, 1, 1}));
  std::ifstream ply(dir.path() / "c.ply", std::ios::binary);
  std::string header((std::istreambuf_iterator<char>(ply)), {});
  EXPECT_NE(header.find("element vertex 2\n"), std::string::npos);
  EXPECT_TRUE(std::filesystem::file_size(dir.path() / "c.png") > 0);
  const Result other = run("diff " + d + "/a.bgk " + d + "/fine.bgk -o " + d + "/x.ply");
  EXPECT_NE(other.status, 0);
  EXPECT_NE(other.output.find("resolutions differ"), std::string::npos) << other.output;
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "x.ply"));
}

}  // namespace
}  // namespace bgkmap
