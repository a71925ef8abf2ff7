#include "bgkmap/mapper.hpp"

#include <utility>

#include "core/stage_clock.hpp"

namespace bgkmap {

Mapper::Mapper(const BuildParams& params, std::unique_ptr<Integrator> integrator)
    : Mapper(BgkMap(params), std::move(integrator)) {}

Mapper::Mapper(BgkMap map, std::unique_ptr<Integrator> integrator)
    : map_(std::move(map)), integrator_(std::move(integrator)) {
  map_.params().validate();
  integrator_->prepare(map_);
}

void Mapper::insert(const Scan& scan) { insert_prepared(prepare_scan(scan, map_.params().preprocess)); }

void Mapper::insert_prepared(PreparedScan&& prepared) {
  const Clock::time_point start = Clock::now();
  const BuildParams& params = map_.params();

  Clock::time_point t = Clock::now();
  observations_from(prepared, params.preprocess, obs_, counts_.preprocess);
  const double preprocess_s = prepared.seconds + seconds_since(t);

  t = Clock::now();
  bucket_scan(map_.grid(), params.kernel.support_radius_m(params.grid.resolution_m), obs_, buckets_,
              integrator_->info().threads);
  const double bucket_s = seconds_since(t);

  t = Clock::now();
  for (BlockWork& work : buckets_.blocks) work.slot = map_.ensure_slot(work.key);
  const double update_s = seconds_since(t);

  t = Clock::now();
  integrator_->integrate(obs_, buckets_, map_, counts_.integrate);
  const double compute_s = seconds_since(t);

  ++counts_.scans;
  counts_.block_visits += buckets_.blocks.size();
  timing_.add_scan(preprocess_s, bucket_s, update_s, compute_s, prepared.seconds + seconds_since(start));
}

void Mapper::finish() {
  const Clock::time_point t = Clock::now();
  integrator_->finish(counts_.integrate);
  timing_.add_wait(seconds_since(t));
}

const BgkMap& Mapper::map() {
  finish();
  integrator_->synchronize(map_);
  return map_;
}

BgkMap& Mapper::mutable_map() {
  finish();
  integrator_->synchronize(map_);
  integrator_->host_map_changed();
  return map_;
}

}  // namespace bgkmap
