// --method gpoctomap: GPOctoMap (T-RO 2019 appendix). Observations as for bgk (hits labelled +1,
// free points sampled every --free-resolution along each beam labelled -1). Per scan, each
// test-data block (the map's blocks) runs GP regression on the points within the kernel's reach
// of its cells (sparse kernel: l = --ell, signal variance = --sigma0, noise --gp-noise), and each
// cell fuses its prediction into its BCM state. Blocks run in parallel (OpenMP, --threads).
// With --ds > 0 the free points are voxel downsampled as the scan's points are (see insert()).
// Occupancy is the logistic squashing of the variance-weighted mean; .ot / .bt are written, .bgk
// is refused (there is no Beta posterior).
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "bgkmap/core/memory_limit.hpp"
#include "bgkmap/integrate/bucketing.hpp"
#include "bgkmap/integrate/observations.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/map_io.hpp"
#include "io/probability_map.hpp"
#include "map/block_store.hpp"
#include "methods/bgk/bgk_method.hpp"
#include "methods/gp/gp_regression.hpp"
#include "methods/gpoctomap/gpoctomap_method.hpp"
#include "core/parallel_errors.hpp"
#include "core/stage_clock.hpp"

namespace bgkmap {

namespace {

class GpOctomapMethod final : public MappingMethod {
 public:
  GpOctomapMethod(const BuildParams& params, const GpOctomapParams& method_params, int threads)
      : params_(params), grid_(params.grid), cells_(grid_), free_resolution_m_(method_params.free_resolution_m),
        threads_(threads > 0 ? threads : omp_get_max_threads()) {
    hp_.ell_m = params.kernel.ell_m;
    hp_.signal_var = params.kernel.sigma0;
    hp_.noise_std = method_params.gp_noise;
    hp_.squash = method_params.gp_squash;
  }

  std::string name() const override { return "gpoctomap"; }

  void check_output(const std::filesystem::path& file) const override {
    require_probability_map_output(file, "gpoctomap");
  }

  void insert_prepared(PreparedScan&& prepared) override {
    const Clock::time_point start = Clock::now();
    observations_from(prepared, params_.preprocess, beams_, counts_.preprocess);
    points_.origin = beams_.origin;
    points_.hits = beams_.hits;
    require_free_sample_memory(beams_, free_resolution_m_, sizeof(Vec3f), "gpoctomap", counts_.scans + 1);
    std::vector<Vec3f> free_points;
    for (const Vec3f& end : beams_.free_ends) sample_free_points(beams_.origin, end, free_resolution_m_, free_points);
    // Every beam starts at the sensor, so free points crowd around it; the GP's cubic solve per
    // block cannot take that, so they get the scan's voxel downsampling (--ds) too.
    if (params_.preprocess.downsample_m > 0 && !free_points.empty())
      free_points = voxel_downsample(free_points, params_.preprocess.downsample_m);
    points_.hits.insert(points_.hits.end(), free_points.begin(), free_points.end());
    const double preprocess_s = prepared.seconds + seconds_since(start);

    Clock::time_point t = Clock::now();
    bucket_scan(grid_, static_cast<float>(hp_.ell_m), points_, buckets_);
    // A planar map: the blocks of its layer, and in them the layer's cells (z is slowest).
    const int n = grid_.cells_per_side(), cells_per_block = grid_.cells_per_block();
    int first_cell = 0, test_cells = cells_per_block;
    if (params_.preprocess.planar) {
      const int32_t layer = params_.planar_layer(), block_z = floor_div(layer, n);
      keep_layer_blocks(buckets_, block_z);
      first_cell = (layer - block_z * n) * n * n;
      test_cells = n * n;
    }
    const double bucket_s = seconds_since(t);

    require_gp_memory();
    t = Clock::now();
    for (BlockWork& work : buckets_.blocks) work.slot = cells_.ensure_slot(work.key);
    const double update_s = seconds_since(t);

    t = Clock::now();
    const uint32_t hit_count = static_cast<uint32_t>(beams_.hits.size());
    const int64_t blocks = static_cast<int64_t>(buckets_.blocks.size());
    uint64_t pairs = 0;
    ParallelErrors errors;
#pragma omp parallel for schedule(dynamic) num_threads(threads_) \
    reduction(+ : pairs)
    for (int64_t b = 0; b < blocks; ++b)
      errors.run([&] {
        const BlockWork& work = buckets_.blocks[b];
        std::vector<Vec3d> train, test(test_cells);
        std::vector<double> labels;
        for (uint32_t k = work.hit_begin; k < work.hit_begin + work.hit_count; ++k) {
          const uint32_t id = buckets_.hit_ids[k];
          const Vec3f& p = points_.hits[id];
          train.push_back({p.x, p.y, p.z});
          labels.push_back(id < hit_count ? 1.0 : -1.0);
        }
        for (int i = 0; i < test_cells; ++i) test[i] = grid_.cell_center_d(grid_.cell_at(work.key, first_cell + i));
        const std::vector<GpPrediction> predictions = gp_predict(train, labels, test, hp_);
        BcmCell* cells = cells_.block(work.slot) + first_cell;
        for (int i = 0; i < test_cells; ++i)
          if (predictions[i].observed) cells[i].add(predictions[i]);
        pairs += uint64_t(train.size()) * test_cells;
      });
    errors.rethrow();
    counts_.integrate.pairs_evaluated += pairs;
    const double compute_s = seconds_since(t);

    ++counts_.scans;
    counts_.block_visits += buckets_.blocks.size();
    timing_.add_scan(preprocess_s, bucket_s, update_s, compute_s, prepared.seconds + seconds_since(start));
  }

  void finish() override {}

  void write_file(const std::filesystem::path& file, TreeValues ot_values) override {
    check_output(file);
    const CellProbabilities cells = [&](const CellProbabilityVisitor& visit) {
      for_each_known_cell([&](const CellIndex& c, const BcmCell& cell) { visit(c, cell.probability(hp_.squash)); });
    };
    write_probability_map(file, grid_.resolution(), params_.classify, cells, ot_values);
  }

  std::optional<CellEstimate> estimate_cell(double x, double y, double z) override {
    const CellIndex c = grid_.cell_of(x, y, z);
    const BcmCell* cell = cells_.find(c);
    if (!cell || cell->predictions == 0) return std::nullopt;
    // The BCM's prior is the GP prior at a test point: k(x, x).
    const double prior_var = gp_kernel(0, hp_);
    CellEstimate e;
    e.occupancy = cell->probability(hp_.squash);
    e.gp_mean = cell->mean(prior_var);
    e.variance = cell->variance(prior_var);
    return e;
  }

  const BuildParams& params() const override { return params_; }
  const BuildCounts& counts() const override { return counts_; }
  const InsertTiming& timing() const override { return timing_; }
  BackendInfo backend() const override {
    return {"cpu", "GP regression per block (Eigen, OpenMP)", threads_, ""};
  }
  uint64_t blocks_touched() override { return cells_.block_count(); }
  uint64_t known_cells() override {
    uint64_t known = 0;
    for (const BcmCell& cell : cells_.cells()) known += cell.predictions > 0;
    return known;
  }

 private:
  template <typename Visit>
  void for_each_known_cell(Visit&& visit) const {
    cells_.for_each_cell([&](const CellIndex& c, const BcmCell& cell) {
      if (cell.predictions > 0) visit(c, cell);
    });
  }

  // Each block's dense GP holds its n training points' kernel matrix and its Cholesky factor
  // (2 n^2 doubles) while it runs, threads_ blocks at a time: refused before they start when
  // the largest blocks would not fit the memory limit.
  void require_gp_memory() const {
    std::vector<double> sizes;
    sizes.reserve(buckets_.blocks.size());
    for (const BlockWork& work : buckets_.blocks) sizes.push_back(work.hit_count);
    const size_t running = std::min<size_t>(sizes.size(), static_cast<size_t>(threads_));
    std::partial_sort(sizes.begin(), sizes.begin() + running, sizes.end(), std::greater<double>());
    double bytes = 0;
    for (size_t i = 0; i < running; ++i) bytes += 2 * sizes[i] * sizes[i] * sizeof(double);
    if (running == 0 || bytes <= 0) return;
    require_memory(bytes,
                   "gpoctomap's GP per block (the largest of " + std::to_string(buckets_.blocks.size()) +
                       " blocks has " + std::to_string(static_cast<uint64_t>(sizes[0])) + " training points; " +
                       std::to_string(running) + " at a time)",
                   "give --ds (e.g. --ds 0.1, which thins the free points too) or a larger --free-resolution "
                   "(or raise --max-memory)");
  }

  BuildParams params_;
  Grid grid_;
  BlockStore<BcmCell> cells_;
  GpHyperParams hp_;
  double free_resolution_m_;
  int threads_;
  ScanObservations beams_, points_;
  ScanBuckets buckets_;
  BuildCounts counts_;
  InsertTiming timing_;
};

}  // namespace

std::unique_ptr<MappingMethod> make_gpoctomap_method(const BuildParams& params, const MethodParams& method_params,
                                                     int threads) {
  return std::make_unique<GpOctomapMethod>(params, gpoctomap_params(method_params), threads);
}

}  // namespace bgkmap
