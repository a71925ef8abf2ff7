#include "bgkmap/mapper.hpp"

#include <chrono>
#include <utility>

namespace bgkmap {

namespace {
using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }
}  // namespace

Mapper::Mapper(const BuildParams& params, std::unique_ptr<Integrator> integrator)
    : Mapper(BgkMap(params), std::move(integrator)) {}

Mapper::Mapper(BgkMap map, std::unique_ptr<Integrator> integrator)
    : map_(std::move(map)), integrator_(std::move(integrator)) {
  map_.params().validate();
  integrator_->prepare(map_);
}

void Mapper::insert(const Scan& scan) {
  const Clock::time_point start = Clock::now();
  const BuildParams& params = map_.params();

  Clock::time_point t = Clock::now();
  preprocess_scan(scan, params.preprocess, obs_, counts_.preprocess);
  const double preprocess_s = seconds_since(t);

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
  const double insert_s = seconds_since(start);
  timing_.preprocess_s += preprocess_s;
  timing_.bucket_s += bucket_s;
  timing_.update_s += update_s;
  timing_.compute_s += compute_s;
  timing_.insert_s += insert_s;
  per_scan_insert_s_.push_back(insert_s);
}

void Mapper::finish() {
  const Clock::time_point t = Clock::now();
  integrator_->finish(counts_.integrate);
  const double wait_s = seconds_since(t);
  // Device work still running belongs to the scans inserted last.
  timing_.compute_s += wait_s;
  timing_.insert_s += wait_s;
  if (!per_scan_insert_s_.empty()) per_scan_insert_s_.back() += wait_s;
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
