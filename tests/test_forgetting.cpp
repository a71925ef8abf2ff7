// Forgetting (--forget-half-life): the lazily decayed map against eager dense references (every
// cell decayed every scan), the decay's algebra, the .bgk's time stamps, and a map without it
// unchanged. CPU and OpenCL maps with forgetting: the conformance suite; --resume: test_resume.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "bgkmap/integrate/cpu_integrator.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/native_map.hpp"
#include "bgkmap/mapper.hpp"
#include "bgkmap/methods/method.hpp"
#include "bgkmap/methods/method_params.hpp"
#include "integrate/brute_force.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

namespace fs = std::filesystem;

// Scans that leave blocks alone for a while: even scans in one place, odd ones 10 m away, and an
// empty scan (which still moves the time on). Every block of the map is behind at some scan.
std::vector<Scan> scans_in_two_places(uint32_t seed) {
  std::vector<Scan> scans = testing::random_scans(seed, 6, 150, 1.5f);
  for (size_t i = 1; i < scans.size(); i += 2) {
    for (Vec3f& p : scans[i].points) p.x += 10.0f;
    scans[i].pose.position.x += 10.0;
  }
  Scan empty = scans[2];
  empty.points.clear();
  scans.insert(scans.begin() + 3, empty);
  return scans;
}

TEST(Forgetting, OnePowerPerGapIsTheProductOfThePowers) {
  // lambda^a lambda^b = lambda^(a+b): the laziness argument, in double.
  for (const double h : {0.5, 3.0, 40.0})
    for (const uint64_t a : {1u, 2u, 7u})
      for (const uint64_t b : {1u, 5u, 30u})
        EXPECT_NEAR(decay_factor(h, a) * decay_factor(h, b), decay_factor(h, a + b), 1e-15 * decay_factor(h, a + b));
  // And the eager reference's repeated multiplication by lambda, 30 times.
  double repeated = 1;
  for (int i = 0; i < 30; ++i) repeated *= std::pow(2.0, -1.0 / 3.0);
  EXPECT_NEAR(repeated, decay_factor(3.0, 30), 1e-14 * repeated);
  EXPECT_EQ(decay_factor(3.0, 3), 0.5);

  Cell cells[2] = {{5.0f, 0.001f}, {0.001f, 0.001f}};
  decay_cells(cells, 2, Cell{0.001f, 0.001f}, 0.25f);
  EXPECT_EQ(cells[0].alpha, std::fma(0.25f, 5.0f - 0.001f, 0.001f));  // one rounding after the subtraction
  EXPECT_EQ(cells[0].beta, 0.001f);  // at the prior: stays there bit for bit
  EXPECT_EQ(cells[1].alpha, 0.001f);
}

// Every cell of every block against the brute force decayed eagerly, within the back ends' own
// tolerance against it (1e-5 relative: float cells; the decay itself is in double); the map must
// differ from the one without forgetting by far more than that.
TEST(Forgetting, TheLazyMapIsTheEagerDenseReference) {
  const double half_life = 1.5;
  const BuildParams params = testing::small_params(3);
  const std::vector<Scan> scans = scans_in_two_places(3);
  Mapper mapper(params, std::make_unique<CpuIntegrator>(2, false));
  mapper.set_forget_half_life(half_life);
  for (const Scan& s : scans) mapper.insert(s);
  const BgkMap& map = mapper.map();
  EXPECT_EQ(map.forgetting().now, scans.size());
  const std::vector<ScanObservations> obs = testing::observations_of(scans, params);
  const Grid& grid = map.grid();
  size_t forgotten = 0, with_evidence = 0;
  for (uint32_t slot = 0; slot < map.block_count(); ++slot) {
    EXPECT_EQ(map.forgetting().block_time[slot], scans.size());
    for (int local = 0; local < grid.cells_per_block(); ++local) {
      const Vec3d c = grid.cell_center_d(grid.cell_at(map.key_of_slot(slot), local));
      const BruteForcePosterior ref = brute_force_cell(c, obs, params, half_life);
      const Cell& cell = map.block_cells(slot)[local];
      ASSERT_NEAR(cell.alpha, ref.alpha, 1e-5 * ref.alpha) << c.x << "," << c.y << "," << c.z;
      ASSERT_NEAR(cell.beta, ref.beta, 1e-5 * ref.beta) << c.x << "," << c.y << "," << c.z;
      const BruteForcePosterior kept = brute_force_cell(c, obs, params);
      forgotten += kept.alpha + kept.beta > 1.5 * (ref.alpha + ref.beta);
      with_evidence += ref.alpha > params.prior.alpha0 || ref.beta > params.prior.beta0;
    }
  }
  EXPECT_GT(with_evidence, 1000u);
  EXPECT_GT(forgotten, with_evidence / 4);
}

// Counting: the eager reference is each scan's own counting map (no forgetting), summed in
// double with weight lambda^(N - k) for scan k of N.
TEST(Forgetting, CountingIsTheEagerSumOfItsScansMaps) {
  const double half_life = 2.0;
  const BuildParams params = testing::small_params(3);
  const std::vector<Scan> scans = scans_in_two_places(5);
  MethodParams forgetting;
  forgetting.set("forget-half-life", half_life);
  auto lazy = make_method("counting", params, forgetting, testing::cpu_backend());
  std::vector<std::unique_ptr<MappingMethod>> each;
  for (const Scan& s : scans) {
    lazy->insert(s);
    each.push_back(make_method("counting", params, MethodParams(), testing::cpu_backend()));
    each.back()->insert(s);
  }
  const Grid grid(params.grid);
  size_t checked = 0;
  for (int ix = -30; ix < 130; ix += 1) {
    for (int iy = -15; iy < 15; iy += 2) {
      const Vec3d c = grid.cell_center_d(CellIndex{ix, iy, 0});
      double alpha = params.prior.alpha0, beta = params.prior.beta0;
      for (size_t k = 0; k < scans.size(); ++k) {
        const std::optional<CellEstimate> e = each[k]->estimate(c.x, c.y, c.z);
        if (!e) continue;
        const double w = decay_factor(half_life, scans.size() - 1 - k);
        alpha += w * (e->beta->alpha - params.prior.alpha0);
        beta += w * (e->beta->beta - params.prior.beta0);
      }
      const std::optional<CellEstimate> got = lazy->estimate(c.x, c.y, c.z);
      if (!got) {
        EXPECT_EQ(alpha, params.prior.alpha0);
        EXPECT_EQ(beta, params.prior.beta0);
        continue;
      }
      EXPECT_NEAR(got->beta->alpha, alpha, 1e-6 * alpha) << ix << "," << iy;
      EXPECT_NEAR(got->beta->beta, beta, 1e-6 * beta) << ix << "," << iy;
      ++checked;
    }
  }
  EXPECT_GT(checked, 200u);
}

// The .bgk of a forgetting map keeps each block's time: read as stored it is the Mapper's lazy
// map bit for bit (so a resumed build goes on exactly), read for use it is the decayed map.
TEST(Forgetting, TheBgkKeepsTheTimesAndReadsDecayed) {
  const fs::path dir = testing::make_temp_dir("forgetting");
  Mapper mapper(testing::small_params(3), std::make_unique<CpuIntegrator>(2));
  mapper.set_forget_half_life(2.5);
  for (const Scan& s : scans_in_two_places(9)) mapper.insert(s);
  write_native_map(dir / "m.bgk", mapper.lazy_map());
  const NativeMapFile stored = read_native_map_file(dir / "m.bgk", StoredTime::kAsStored);
  EXPECT_EQ(stored.version, kForgettingMapFormatVersion);
  testing::expect_same_cells(mapper.lazy_map(), stored.map);
  EXPECT_EQ(stored.map.forgetting().half_life_scans, 2.5);
  EXPECT_EQ(stored.map.forgetting().now, mapper.lazy_map().forgetting().now);
  EXPECT_EQ(stored.map.forgetting().block_time, mapper.lazy_map().forgetting().block_time);
  bool some_behind = false;
  for (const uint64_t t : stored.map.forgetting().block_time) some_behind |= t < stored.map.forgetting().now;
  EXPECT_TRUE(some_behind);
  testing::expect_same_cells(mapper.map(), read_native_map(dir / "m.bgk"));

  // A header whose block times come after the map's time is refused, naming the file.
  const BgkMap& lazy = mapper.lazy_map();
  Forgetting wrong = lazy.forgetting();
  wrong.now = 1;
  std::string records;
  for (uint32_t slot = 0; slot < lazy.block_count(); ++slot) append_native_map_record(records, lazy, slot);
  testing::write_bytes(dir / "bad.bgk", native_map_head(lazy.params(), lazy.cells_per_block(), lazy.block_count(),
                                                        records.size(), {}, "bgkl", wrong) +
                                            records + native_map_tail(native_map_crc(records.data(), records.size())));
  try {
    read_native_map(dir / "bad.bgk");
    ADD_FAILURE() << "read a map whose blocks are later than its time";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), (dir / "bad.bgk").string() +
                                         ": corrupt .bgk header (\"forget\": a block time is not a scan up to the map's time)");
  }
  fs::remove_all(dir);
}

TEST(Forgetting, OffLeavesNoTimesAndVersionThree) {
  const fs::path dir = testing::make_temp_dir("forgetting_off");
  Mapper mapper(testing::small_params(3), std::make_unique<CpuIntegrator>(2));
  for (const Scan& s : scans_in_two_places(9)) mapper.insert(s);
  EXPECT_FALSE(mapper.map().forgetting().on());
  EXPECT_TRUE(mapper.map().forgetting().block_time.empty());
  EXPECT_EQ(&mapper.map(), &mapper.lazy_map());
  write_native_map(dir / "m.bgk", mapper.map());
  EXPECT_EQ(read_native_map_file(dir / "m.bgk").version, kNativeMapFormatVersion);
  EXPECT_EQ(testing::read_bytes(dir / "m.bgk").find("forget"), std::string::npos);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace bgkmap
