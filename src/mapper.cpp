#include "bgkmap/mapper.hpp"

#include <algorithm>
#include <stdexcept>
#include <utility>

#include "core/stage_clock.hpp"

namespace bgkmap {

namespace {

class SegmentObservations final : public ObservationStage {
 public:
  void observe(const PreparedScan& prepared, const PreprocessParams& params, ScanObservations& out,
               PreprocessCounts& counts) override {
    observations_from(prepared, params, out, counts);
  }
  void bucket(const Grid& grid, float support_radius_m, const ScanObservations& obs, ScanBuckets& out,
              int threads) override {
    bucket_scan(grid, support_radius_m, obs, out, threads);
  }
};

}  // namespace

std::unique_ptr<ObservationStage> make_segment_observations() { return std::make_unique<SegmentObservations>(); }

Mapper::Mapper(const BuildParams& params, std::unique_ptr<Integrator> integrator,
               std::unique_ptr<ObservationStage> stage)
    : Mapper(BgkMap(params), std::move(integrator), std::move(stage)) {}

Mapper::Mapper(BgkMap map, std::unique_ptr<Integrator> integrator, std::unique_ptr<ObservationStage> stage)
    : map_(std::move(map)), integrator_(std::move(integrator)),
      stage_(stage ? std::move(stage) : make_segment_observations()) {
  map_.params().check_kernel_reach();
  integrator_->prepare(map_);
}

void Mapper::insert(const Scan& scan) { insert_prepared(prepare_scan(scan, map_.params().preprocess)); }

void Mapper::insert_prepared(PreparedScan&& prepared) {
  const Clock::time_point start = Clock::now();
  map_.advance_time();
  const Clock::time_point t = Clock::now();
  // Counted once the scan is mapped: a scan refused (e.g. for memory) leaves the counts as they were.
  PreprocessCounts scan_counts;
  stage_->observe(prepared, map_.params().preprocess, obs_, scan_counts);
  const double preprocess_s = prepared.seconds + seconds_since(t);
  if (!prepared.pose_covariance) {
    map_observations(obs_, {}, preprocess_s, prepared.seconds, start);
    counts_.preprocess += scan_counts;
    return;
  }

  const BuildParams& params = map_.params();
  if (params.kernel.type != KernelType::kSparse)
    throw std::invalid_argument("a pose uncertainty needs the sparse kernel (the box kernel counts, it has no expectation to take)");
  double bucket_s = 0, update_s = 0, compute_s = 0;
  const std::vector<PoseSigmaPoint> points = pose_sigma_points(*prepared.pose_covariance);
  if (params.preprocess.pose_fusion == PoseFusion::kExpectedKernel) {
    for (const PoseSigmaPoint& point : points) {
      displace_observations(obs_, point, params.preprocess.planar, displaced_);
      integrate_observations(displaced_, {}, bucket_s, update_s, compute_s);
    }
  } else {
    insert_expected_submap(points, bucket_s, update_s, compute_s);
  }
  counts_.preprocess += scan_counts;
  ++counts_.scans;
  timing_.add_scan(preprocess_s, bucket_s, update_s, compute_s, prepared.seconds + seconds_since(start));
}

void Mapper::insert_expected_submap(const std::vector<PoseSigmaPoint>& points, double& bucket_s, double& update_s,
                                    double& compute_s) {
  const BuildParams& params = map_.params();
  // The host reads and writes the cells of the blocks each hypothesis touches, through views of
  // just those slots (a device back end copies just those each way).
  submap_.clear();
  for (const PoseSigmaPoint& point : points) {
    displace_observations(obs_, point, params.preprocess.planar, displaced_);
    displaced_.kernel_weight = obs_.kernel_weight;  // each hypothesis' plain update, at full weight
    bucket_into_slots(displaced_, {}, bucket_s, update_s);
    slots_.clear();
    for (const BlockWork& work : buckets_.blocks) slots_.push_back(work.slot);
    Clock::time_point t = Clock::now();
    {
      // The slots as the map holds them (a slot an earlier hypothesis of this scan touched comes
      // back as that hypothesis' sub-map, but start_hypothesis remembered it before and sets it
      // to the prior again).
      const HostCells cells = integrator_->host_cells(map_, slots_, counts_.integrate, HostAccess::kReadWrite);
      compute_s += seconds_since(t);
      t = Clock::now();
      submap_.start_hypothesis(cells.map(), slots_);
      update_s += seconds_since(t);
    }
    // The back end adds the hypothesis' counts to the cells set to the prior; the host reads them.
    t = Clock::now();
    integrator_->integrate(displaced_, buckets_, map_, counts_.integrate);
    {
      const HostCells cells = integrator_->host_cells(map_, slots_, counts_.integrate, HostAccess::kRead);
      submap_.add_hypothesis(cells.map(), slots_, point.weight, integrator_->idle_host_threads());
    }
    compute_s += seconds_since(t);
    counts_.block_visits += buckets_.blocks.size();
  }
  const Clock::time_point t = Clock::now();
  {
    // Every cell of the sub-map's blocks is written from what the host kept: nothing to copy back.
    const HostCells cells = integrator_->host_cells(map_, submap_.slots(), counts_.integrate, HostAccess::kOverwrite);
    submap_.add_to_map(cells.map(), integrator_->idle_host_threads());
  }
  compute_s += seconds_since(t);
}

void Mapper::insert_observations(const ScanObservations& obs, const std::function<bool(const BlockKey&)>& keep) {
  const Clock::time_point start = Clock::now();
  map_.advance_time();
  map_observations(obs, keep, 0.0, 0.0, start);
}

void Mapper::map_observations(const ScanObservations& obs, const std::function<bool(const BlockKey&)>& keep,
                              double preprocess_s, double prepared_s, Clock::time_point start) {
  double bucket_s = 0, update_s = 0, compute_s = 0;
  integrate_observations(obs, keep, bucket_s, update_s, compute_s);
  ++counts_.scans;
  timing_.add_scan(preprocess_s, bucket_s, update_s, compute_s, prepared_s + seconds_since(start));
}

void Mapper::bucket_into_slots(const ScanObservations& obs, const std::function<bool(const BlockKey&)>& keep,
                               double& bucket_s, double& update_s) {
  const BuildParams& params = map_.params();
  Clock::time_point t = Clock::now();
  stage_->bucket(map_.grid(), params.kernel.support_radius_m(params.grid.resolution_m), obs, buckets_,
                 integrator_->info().threads);
  if (params.preprocess.planar) keep_layer_blocks(buckets_, map_.layer_block_z());
  if (keep) {  // each kept block's observations stay as bucketing gave them: its sums do not change
    auto& blocks = buckets_.blocks;
    blocks.erase(std::remove_if(blocks.begin(), blocks.end(), [&](const BlockWork& w) { return !keep(w.key); }),
                 blocks.end());
  }
  bucket_s += seconds_since(t);

  t = Clock::now();
  for (BlockWork& work : buckets_.blocks) work.slot = map_.ensure_slot(work.key);
  catch_up_blocks();
  update_s += seconds_since(t);
}

void Mapper::catch_up_blocks() {
  if (!map_.forgetting().on()) return;
  behind_.clear();
  factors_.clear();
  for (const BlockWork& work : buckets_.blocks) {
    if (!map_.block_behind(work.slot)) continue;
    behind_.push_back(work.slot);
    factors_.push_back(map_.take_decay(work.slot));
  }
  integrator_->decay_blocks(map_, behind_, factors_, counts_.integrate);
}

void Mapper::integrate_observations(const ScanObservations& obs, const std::function<bool(const BlockKey&)>& keep,
                                    double& bucket_s, double& update_s, double& compute_s) {
  bucket_into_slots(obs, keep, bucket_s, update_s);
  const Clock::time_point t = Clock::now();
  integrator_->integrate(obs, buckets_, map_, counts_.integrate);
  compute_s += seconds_since(t);
  counts_.block_visits += buckets_.blocks.size();
}

void Mapper::finish() {
  const Clock::time_point t = Clock::now();
  integrator_->finish(counts_.integrate);
  timing_.add_wait(seconds_since(t));
}

const BgkMap& Mapper::lazy_map() {
  finish();
  integrator_->host_cells(map_, counts_.integrate, HostAccess::kRead);
  return map_;
}

const BgkMap& Mapper::map() {
  return read_view(lazy_map(), settled_);
}

}  // namespace bgkmap
