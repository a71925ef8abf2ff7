// The distributed build's pieces without MPI: the partition, the routing of observations to
// the ranks owning the blocks they reach, and shards merged back into one map. K mappers fed
// what the router sends them, in scan order, must give the single-process map byte for byte.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <memory>

#include "bgkmap/dist/partition.hpp"
#include "bgkmap/dist/routing.hpp"
#include "bgkmap/dist/shards.hpp"
#include "bgkmap/integrate/bucketing.hpp"
#include "bgkmap/integrate/cpu_integrator.hpp"
#include "integrate/box_distance.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/map_io.hpp"
#include "bgkmap/io/native_map.hpp"
#include "bgkmap/mapper.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

TEST(Partition, TileCodesInterleaveTileCoordinates) {
  // Blocks of one tile share its code; neighbouring tiles along x, y, z differ in bits 0, 1, 2.
  EXPECT_EQ(tile_code({0, 0, 0}), tile_code({kTileBlocks - 1, kTileBlocks - 1, kTileBlocks - 1}));
  const uint64_t base = tile_code({0, 0, 0});
  EXPECT_EQ(tile_code({kTileBlocks, 0, 0}), base | 1u);
  EXPECT_EQ(tile_code({0, kTileBlocks, 0}), base | 2u);
  EXPECT_EQ(tile_code({0, 0, kTileBlocks}), base | 4u);
  EXPECT_EQ(tile_code({kTileBlocks, kTileBlocks, kTileBlocks}), base | 7u);
  // Tile -1 is just below tile 0 on the biased axis.
  EXPECT_LT(tile_code({-1, 0, 0}), base);
}

TEST(Partition, RunsAreContiguousBalancedAndCoverEveryCode) {
  std::vector<std::pair<uint64_t, double>> costs;
  for (uint64_t c = 10; c < 1010; ++c) costs.emplace_back(c * 3, 1.0 + double(c % 7));
  double total = 0, largest = 0;
  for (const auto& c : costs) total += c.second, largest = std::max(largest, c.second);
  for (int ranks : {1, 2, 3, 4, 7}) {
    const SpatialPartition p(ranks, costs);
    ASSERT_EQ(p.ranks(), ranks);
    double sum = 0;
    for (int r = 0; r < ranks; ++r) {
      EXPECT_NEAR(p.estimated_costs()[r], total / ranks, largest + 1e-9) << ranks << " ranks, rank " << r;
      sum += p.estimated_costs()[r];
    }
    EXPECT_DOUBLE_EQ(sum, total);
    // Owners never decrease along the curve, and codes outside the estimate have owners too.
    int last = 0;
    for (uint64_t code = 0; code < 3100; ++code) {
      const int owner = p.owner_of_code(code);
      ASSERT_GE(owner, last);
      ASSERT_LT(owner, ranks);
      last = owner;
    }
    EXPECT_EQ(p.owner_of_code(0), 0);
    EXPECT_EQ(p.owner_of_code(~uint64_t(0) >> 1), ranks - 1);
  }
  // More ranks than tiles: the extra ranks own nothing, and every code still has an owner.
  const SpatialPartition few(5, {{7, 1.0}, {9, 1.0}});
  for (uint64_t code = 0; code < 20; ++code) EXPECT_LT(few.owner_of_code(code), 5);
}

// K "ranks" in one process: the router's share of each scan, mapped onto each rank's blocks in
// scan order, written as shards and merged.
std::string distributed_bytes(const std::vector<Scan>& scans, const BuildParams& params, int ranks,
                              const std::filesystem::path& dir) {
  BgkMap probe(params);
  const Grid& grid = probe.grid();
  TileCosts costs;
  ScanObservations obs;
  PreprocessCounts counts;
  for (const Scan& scan : scans) {
    preprocess_scan(scan, params.preprocess, obs, counts);
    costs.add_scan(grid, obs);
  }
  const SpatialPartition partition(ranks, costs.sorted());
  std::vector<std::unique_ptr<Mapper>> mappers;
  std::vector<std::vector<uint32_t>> created(static_cast<size_t>(ranks));
  for (int r = 0; r < ranks; ++r) mappers.push_back(std::make_unique<Mapper>(params, std::make_unique<CpuIntegrator>(1)));
  ObservationRouter router;
  std::vector<std::vector<uint32_t>> hits, ends;
  ScanObservations share;
  for (size_t s = 0; s < scans.size(); ++s) {
    preprocess_scan(scans[s], params.preprocess, obs, counts);
    router.route(grid, params.kernel.support_radius_m(params.grid.resolution_m), obs, partition, hits, ends);
    for (int r = 0; r < ranks; ++r) {
      if (hits[r].empty() && ends[r].empty()) continue;
      select_observations(obs, hits[r], ends[r], share);
      mappers[r]->insert_observations(share, [&](const BlockKey& k) { return partition.owner(k) == r; });
      created[r].resize(mappers[r]->block_count(), static_cast<uint32_t>(s));
    }
  }
  ShardManifest manifest;
  manifest.ranks = ranks;
  manifest.scans = scans.size();
  manifest.partition = partition.first_codes();
  for (int r = 0; r < ranks; ++r) {
    write_shard(dir, r, mappers[r]->map(), created[r]);
    manifest.shard_maps.push_back(shard_map_name(r));
    manifest.shard_orders.push_back(shard_order_name(r));
  }
  write_manifest(dir / kShardManifestName, manifest);
  write_native_map(dir / "merged.bgk", merge_shards(dir));
  return testing::read_bytes(dir / "merged.bgk");
}

std::string single_bytes(const std::vector<Scan>& scans, const BuildParams& params, const std::filesystem::path& dir) {
  Mapper mapper(params, std::make_unique<CpuIntegrator>(1));
  for (const Scan& scan : scans) mapper.insert(scan);
  write_native_map(dir / "single.bgk", mapper.map());
  return testing::read_bytes(dir / "single.bgk");
}

// The merged map of each rank count against the single-process one.
void expect_single_process_map(const std::vector<Scan>& scans, const BuildParams& params, const std::string& tag,
                               std::initializer_list<int> rank_counts) {
  const std::filesystem::path dir = testing::make_temp_dir(tag);
  const std::string single = single_bytes(scans, params, dir);
  ASSERT_GT(single.size(), 100000u);
  for (int ranks : rank_counts) {
    const std::filesystem::path k = dir / std::to_string(ranks);
    std::filesystem::create_directories(k);
    EXPECT_TRUE(distributed_bytes(scans, params, ranks, k) == single) << ranks << " ranks";
  }
  std::filesystem::remove_all(dir);
}

TEST(Distributed, RoutedSharesMergeToTheSingleProcessMapOnSimStructured) {
  BGKMAP_REQUIRE_DATASETS(datasets);
  const std::vector<Scan> scans = testing::read_all_scans({datasets / "sim_structured"});
  ASSERT_EQ(scans.size(), 12u);
  BuildParams params;
  params.grid.resolution_m = 0.1;
  params.preprocess.max_range_m = 8;
  expect_single_process_map(scans, params, "distributed_sim", {1, 2, 3, 5});
}

TEST(Distributed, RoutedSharesMergeToTheSingleProcessMapOnRandomScans) {
  BuildParams params;
  params.grid.resolution_m = 0.1;
  expect_single_process_map(testing::random_scans(7, 6, 3000, 6.0f), params, "distributed_random", {2, 4});
}

// `bgkmap merge SHARDS -o M.ot [--ot-values mean]`: the single-process map's trees, byte for byte.
TEST(Distributed, MergeCommandWritesTheSingleProcessTreesOfEitherValues) {
  BuildParams params;
  params.grid.resolution_m = 0.1;
  const std::vector<Scan> scans = testing::random_scans(11, 3, 1000, 4.0f);
  const testing::TempDir dir("distributed_merge_trees");
  Mapper single(params, std::make_unique<CpuIntegrator>(1));
  for (const Scan& scan : scans) single.insert(scan);
  write_map(dir / "single.ot", single.map());
  write_map(dir / "single_mean.ot", single.map(), "bgkl", TreeValues::kMean);
  std::filesystem::create_directories(dir / "shards");
  distributed_bytes(scans, params, 2, dir / "shards");
  const std::string merge = std::string(BGKMAP_CLI) + " merge " + (dir / "shards").string();
  testing::CommandResult r = testing::run_command(merge + " -o " + (dir / "merged.ot").string());
  ASSERT_EQ(r.status, 0) << r.output;
  r = testing::run_command(merge + " --ot-values mean -o " + (dir / "merged_mean.ot").string());
  ASSERT_EQ(r.status, 0) << r.output;
  const std::string classified = testing::read_bytes(dir / "single.ot"), mean = testing::read_bytes(dir / "single_mean.ot");
  EXPECT_TRUE(testing::read_bytes(dir / "merged.ot") == classified);
  EXPECT_TRUE(testing::read_bytes(dir / "merged_mean.ot") == mean);
  EXPECT_LT(classified.size(), mean.size());  // the cells the map calls unknown are left out
}

TEST(Distributed, RouterSendsEachObservationToEveryOwnerItReachesAndFewOthers) {
  const std::vector<Scan> scans = testing::random_scans(3, 1, 4000, 6.0f);
  BuildParams params;
  params.grid.resolution_m = 0.1;
  ScanObservations obs;
  PreprocessCounts counts;
  preprocess_scan(scans[0], params.preprocess, obs, counts);
  BgkMap probe(params);
  TileCosts costs;
  costs.add_scan(probe.grid(), obs);
  const SpatialPartition partition(3, costs.sorted());
  const float l = params.kernel.support_radius_m(params.grid.resolution_m);
  ObservationRouter router;
  std::vector<std::vector<uint32_t>> hits, ends;
  router.route(probe.grid(), l, obs, partition, hits, ends);
  // Reference: every hit against every block near it, by the plain point-box distance.
  std::vector<std::vector<bool>> expected(3, std::vector<bool>(obs.hits.size(), false));
  const Grid& grid = probe.grid();
  for (size_t i = 0; i < obs.hits.size(); ++i) {
    const BlockKey c = grid.block_of(obs.hits[i].x, obs.hits[i].y, obs.hits[i].z);
    for (int dz = -2; dz <= 2; ++dz)
      for (int dy = -2; dy <= 2; ++dy)
        for (int dx = -2; dx <= 2; ++dx) {
          const BlockKey k{c.x + dx, c.y + dy, c.z + dz};
          if (point_box_dist2(obs.hits[i], grid.block_center_box(k)) < double(l) * l)
            expected[static_cast<size_t>(partition.owner(k))][i] = true;
        }
  }
  size_t to_two_or_more = 0, needed = 0, sent = 0;
  std::vector<int> owners(obs.hits.size(), 0);
  for (int r = 0; r < 3; ++r) {
    std::vector<bool> got(obs.hits.size(), false);
    for (uint32_t id : hits[r]) got[id] = true, ++owners[id];
    EXPECT_TRUE(std::is_sorted(hits[r].begin(), hits[r].end()));
    for (size_t i = 0; i < obs.hits.size(); ++i) {
      EXPECT_TRUE(got[i] || !expected[static_cast<size_t>(r)][i]) << "hit " << i << " does not reach rank " << r;
      needed += expected[static_cast<size_t>(r)][i];
      sent += got[i];
    }
  }
  for (int n : owners) to_two_or_more += n >= 2;
  EXPECT_GT(to_two_or_more, 0u);  // the scene straddles the partition's cuts
  EXPECT_LT(double(sent), 1.5 * double(needed)) << "the router sends far more than the reach test asks";
}

TEST(Shards, CorruptOrderFileAndMissingShardAreInputErrors) {
  const std::filesystem::path dir = testing::make_temp_dir("shards_bad");
  testing::write_bytes(dir / "x.order", "BGKORD1\n\x05\0\0\0\0\0\0\0abc");
  testing::expect_input_error(dir / "x.order", [&] { read_shard_order(dir / "x.order"); }, "truncated order");
  testing::write_bytes(dir / kShardManifestName, "{\"format\": \"something else\"}");
  testing::expect_input_error(dir / kShardManifestName, [&] { merge_shards(dir); }, "not a manifest");
  ShardManifest m;
  m.ranks = 1;
  m.partition = {0};
  m.shard_maps = {shard_map_name(0)};
  m.shard_orders = {shard_order_name(0)};
  write_manifest(dir / kShardManifestName, m);
  testing::expect_input_error(dir / shard_map_name(0), [&] { merge_shards(dir); }, "missing shard");
  m.partition = {0, 0};  // a partition of two ranks in a manifest of one
  write_manifest(dir / kShardManifestName, m);
  testing::expect_input_error(dir / kShardManifestName, [&] { merge_shards(dir); }, "corrupt shard manifest");
  std::filesystem::remove_all(dir);
}

// Shards swapped between ranks (or copied from another run) are refused where they are read,
// rather than merged into a map that repeats blocks or answering queries from the wrong shard.
TEST(Shards, AShardHoldingAnotherRanksBlocksIsRefused) {
  const std::filesystem::path dir = testing::make_temp_dir("shards_swapped");
  BuildParams params;
  params.preprocess.max_range_m = 5;
  distributed_bytes(testing::random_scans(7, 3, 2000, 6.0f), params, 2, dir);
  for (const auto& name : {shard_map_name(0), shard_order_name(0)}) {
    const std::string other = name == shard_map_name(0) ? shard_map_name(1) : shard_order_name(1);
    std::filesystem::rename(dir / name, dir / "tmp");
    std::filesystem::rename(dir / other, dir / name);
    std::filesystem::rename(dir / "tmp", dir / other);
  }
  testing::expect_input_error(dir / shard_map_name(0), [&] { merge_shards(dir); }, "holds a block of rank 1's part");
  testing::expect_input_error(dir / shard_map_name(0), [&] { ShardedMapReader reader(dir); }, "holds a block of rank 1's part");
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace bgkmap
