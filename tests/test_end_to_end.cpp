// End to end on the shared sim_structured scans: the mapper through the library and the bgkmap
// command (build -> .bgk -> query) against an independent double-precision brute force.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <random>
#include <sstream>

#include "integrate/brute_force.hpp"
#include "bgkmap/integrate/cpu_integrator.hpp"
#include "bgkmap/io/scan_source.hpp"
#include "bgkmap/mapper.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

// The reference settings: no downsampling (so observations are the raw points), max
// range 8 m, no end margin, la3dm's kernel.
BuildParams reference_params() {
  BuildParams p;
  p.preprocess.downsample_m = 0;
  p.preprocess.max_range_m = 8;
  p.preprocess.end_margin_m = 0;
  p.grid.resolution_m = 0.1;
  p.kernel.ell_m = 0.2f;
  p.kernel.sigma0 = 0.1f;
  return p;
}

std::vector<Scan> read_all(const std::filesystem::path& dir) {
  ScanSource source({dir});
  std::vector<Scan> scans;
  Scan s;
  while (source.next(s)) scans.push_back(s);
  return scans;
}

TEST(EndToEnd, SimStructuredEveryCellOfSampledBlocksEqualsBruteForce) {
  BGKMAP_REQUIRE_DATASETS(datasets);
  const BuildParams params = reference_params();
  const auto scans = read_all(datasets / "sim_structured");
  ASSERT_EQ(scans.size(), 12u);
  Mapper mapper(params, std::make_unique<CpuIntegrator>(2));
  for (const Scan& scan : scans) mapper.insert(scan);
  const std::vector<ScanObservations> obs = testing::observations_of(scans, params);
  const BgkMap& map = mapper.map();
  ASSERT_GT(map.block_count(), 100u);
  // Every cell of one block in 40 (the whole map would take minutes of brute force).
  const Grid& grid = map.grid();
  size_t cells = 0;
  for (uint32_t slot = 0; slot < map.block_count(); slot += 40) {
    for (int local = 0; local < grid.cells_per_block(); ++local) {
      const Vec3d c = grid.cell_center_d(grid.cell_at(map.key_of_slot(slot), local));
      const BruteForcePosterior ref = brute_force_cell(c, obs, params);
      const Cell& got = map.block_cells(slot)[local];
      ASSERT_NEAR(got.alpha, ref.alpha, 1e-5 * ref.alpha) << c.x << " " << c.y << " " << c.z;
      ASSERT_NEAR(got.beta, ref.beta, 1e-5 * ref.beta) << c.x << " " << c.y << " " << c.z;
      ++cells;
    }
  }
  EXPECT_GT(cells, 1000u);
}

std::string run(const std::string& command) {
  std::string output;
  FILE* pipe = popen(command.c_str(), "r");
  if (!pipe) return output;
  char buffer[4096];
  size_t n;
  while ((n = fread(buffer, 1, sizeof buffer, pipe)) > 0) output.append(buffer, n);
  const int status = pclose(pipe);
  EXPECT_EQ(status, 0) << command;
  return output;
}

TEST(EndToEnd, CliBuildThenQueryMatchesBruteForce) {
  BGKMAP_REQUIRE_DATASETS(datasets);
  const auto dir = testing::make_temp_dir("e2e");
  const std::string map_file = (dir / "m.bgk").string();
  run(std::string(BGKMAP_CLI) + " build -q " + (datasets / "sim_structured").string() + " -o " + map_file + " -o " +
      (dir / "m.ot").string() + " --report " + (dir / "r.json").string() +
      " --ds 0 --max-range 8 --end-margin 0 --resolution 0.1 --ell 0.2 --sigma0 0.1 --backend cpu");
  ASSERT_TRUE(std::filesystem::exists(dir / "m.ot"));

  const BuildParams params = reference_params();
  const auto scans = read_all(datasets / "sim_structured");
  const std::vector<ScanObservations> obs = testing::observations_of(scans, params);

  // Query points: near surfaces (hits), along beams, and random points in the scene's box.
  std::mt19937 rng(17);
  std::vector<Vec3f> points;
  for (int i = 0; i < 150; ++i) {
    const ScanObservations& s = obs[rng() % obs.size()];
    const Vec3f h = s.hits[rng() % s.hits.size()];
    const Vec3f e = s.free_ends[rng() % s.free_ends.size()];
    const float t = std::uniform_real_distribution<float>(0, 1)(rng);
    points.push_back(h);
    points.push_back({s.origin.x + t * (e.x - s.origin.x), s.origin.y + t * (e.y - s.origin.y), s.origin.z + t * (e.z - s.origin.z)});
  }
  std::uniform_real_distribution<float> u(-2, 12);
  for (int i = 0; i < 100; ++i) points.push_back({u(rng), u(rng), u(rng) * 0.3f});
  {
    std::ofstream q(dir / "points.txt");
    q.precision(9);
    for (const Vec3f& p : points) q << p.x << " " << p.y << " " << p.z << "\n";
  }
  std::istringstream lines(run(std::string(BGKMAP_CLI) + " query " + map_file + " --points " + (dir / "points.txt").string()));
  size_t checked = 0, with_evidence = 0;
  double cx, cy, cz, alpha, beta, mean, variance;
  std::string state;
  while (lines >> cx >> cy >> cz >> alpha >> beta >> mean >> variance >> state) {
    const BruteForcePosterior ref = brute_force_cell({cx, cy, cz}, obs, params);
    EXPECT_NEAR(alpha, ref.alpha, 1e-4 * ref.alpha) << cx << " " << cy << " " << cz;
    EXPECT_NEAR(beta, ref.beta, 1e-4 * ref.beta) << cx << " " << cy << " " << cz;
    EXPECT_NEAR(mean, ref.alpha / (ref.alpha + ref.beta), 1e-4);
    with_evidence += ref.alpha > params.prior.alpha0 || ref.beta > params.prior.beta0;
    ++checked;
  }
  EXPECT_EQ(checked, points.size());
  EXPECT_GT(with_evidence, points.size() / 2);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace bgkmap
