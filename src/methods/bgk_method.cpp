// --method bgk: BGKOctoMap. Free space is observed as points sampled along each beam every
// --free-resolution instead of whole segments; hits and free points are all point observations
// under the same kernel and Beta update as BGK-L.
//
// Only the observations are new: a free point is a zero-length free segment, which the shared
// bucketing geometry (make_local_beam) and both back ends already evaluate as a point. The points
// are bucketed as points (bucket_scan with them as hits), then their pairs are turned into
// zero-length beams.
#include <chrono>
#include <cmath>
#include <memory>
#include <utility>
#include <vector>

#include "bgkmap/integrate/bucketing.hpp"
#include "bgkmap/integrate/observations.hpp"
#include "bgkmap/io/map_io.hpp"
#include "methods/bgk_map_method.hpp"
#include "methods/bgk_method.hpp"
#include "core/stage_clock.hpp"

namespace bgkmap {

void sample_free_points(const Vec3f& origin, const Vec3f& free_end, double spacing_m, std::vector<Vec3f>& out) {
  const double v[3] = {double(free_end.x) - origin.x, double(free_end.y) - origin.y, double(free_end.z) - origin.z};
  const double length = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  const auto samples = static_cast<int64_t>(std::floor(length / spacing_m));
  for (int64_t k = 1; k <= samples; ++k) {
    const double t = k * spacing_m / length;
    out.push_back({static_cast<float>(origin.x + t * v[0]), static_cast<float>(origin.y + t * v[1]),
                   static_cast<float>(origin.z + t * v[2])});
  }
}

namespace {

class BgkMethod final : public MappingMethod {
 public:
  BgkMethod(const BuildParams& params, const MethodParams& method_params, std::unique_ptr<Integrator> integrator)
      : map_(params), free_resolution_m_(method_params.free_resolution_m), integrator_(std::move(integrator)) {
    integrator_->prepare(map_);
  }

  std::string name() const override { return "bgk"; }
  void check_output(const std::filesystem::path& file) const override { map_format_from_path(file); }

  void insert_prepared(PreparedScan&& prepared) override {
    const Clock::time_point start = Clock::now();
    const BuildParams& params = map_.params();
    observations_from(prepared, params.preprocess, beams_, counts_.preprocess);
    // Hits first, then the free points, all as points: pairs with id >= hit_count are free.
    points_.origin = beams_.origin;
    points_.hits = beams_.hits;
    points_.free_ends.clear();
    for (const Vec3f& end : beams_.free_ends) sample_free_points(beams_.origin, end, free_resolution_m_, points_.hits);
    const double preprocess_s = prepared.seconds + seconds_since(start);

    Clock::time_point t = Clock::now();
    bucket_scan(map_.grid(), params.kernel.support_radius_m(params.grid.resolution_m), points_, point_buckets_,
                integrator_->info().threads);
    split_free_points(static_cast<uint32_t>(beams_.hits.size()));
    const double bucket_s = seconds_since(t);

    t = Clock::now();
    for (BlockWork& work : buckets_.blocks) work.slot = map_.ensure_slot(work.key);
    const double update_s = seconds_since(t);

    t = Clock::now();
    integrator_->integrate(points_, buckets_, map_, counts_.integrate);
    const double compute_s = seconds_since(t);

    ++counts_.scans;
    counts_.block_visits += buckets_.blocks.size();
    timing_.add_scan(preprocess_s, bucket_s, update_s, compute_s, prepared.seconds + seconds_since(start));
  }

  void finish() override {
    const Clock::time_point t = Clock::now();
    integrator_->finish(counts_.integrate);
    integrator_->synchronize(map_);
    timing_.add_wait(seconds_since(t));
  }

  void write(const std::filesystem::path& file) override {
    finish();
    write_map(file, map_);
  }

  std::optional<CellEstimate> estimate(double x, double y, double z) override {
    finish();
    return beta_estimate(map_.query(x, y, z));
  }

  const BuildParams& params() const override { return map_.params(); }
  const BuildCounts& counts() const override { return counts_; }
  const InsertTiming& timing() const override { return timing_; }
  BackendInfo backend() const override { return integrator_->info(); }
  uint64_t blocks_touched() override { return map_.block_count(); }
  uint64_t known_cells() override {
    finish();
    return map_.cells_with_evidence();
  }

 private:
  // point_buckets_ holds every point as a hit; buckets_ gets the real hits as hits and the free
  // points as zero-length beams, block by block.
  void split_free_points(uint32_t hit_count) {
    const Grid& grid = map_.grid();
    const double mid_offset = 0.5 * (grid.cells_per_side() - 1) * grid.resolution();
    buckets_.clear();
    for (const BlockWork& in : point_buckets_.blocks) {
      BlockWork out;
      out.key = in.key;
      out.hit_begin = static_cast<uint32_t>(buckets_.hit_ids.size());
      out.beam_begin = static_cast<uint32_t>(buckets_.beam_ids.size());
      const Vec3d c0 = grid.block_first_center_d(in.key);
      const Vec3d mid{c0.x + mid_offset, c0.y + mid_offset, c0.z + mid_offset};
      for (uint32_t k = in.hit_begin; k < in.hit_begin + in.hit_count; ++k) {
        const uint32_t id = point_buckets_.hit_ids[k];
        if (id < hit_count) {
          buckets_.hit_ids.push_back(id);
          buckets_.hits.push_back(point_buckets_.hits[k]);
        } else {
          const Vec3f& p = points_.hits[id];
          buckets_.beam_ids.push_back(id);
          buckets_.beams.push_back(make_local_beam(c0, mid, p, p));
        }
      }
      out.hit_count = static_cast<uint32_t>(buckets_.hit_ids.size()) - out.hit_begin;
      out.beam_count = static_cast<uint32_t>(buckets_.beam_ids.size()) - out.beam_begin;
      buckets_.blocks.push_back(out);
    }
  }

  BgkMap map_;
  double free_resolution_m_;
  std::unique_ptr<Integrator> integrator_;
  ScanObservations beams_, points_;  // scratch reused across scans
  ScanBuckets point_buckets_, buckets_;
  BuildCounts counts_;
  InsertTiming timing_;
};

}  // namespace

std::unique_ptr<MappingMethod> make_bgk_method(const BuildParams& params, const MethodParams& method_params,
                                               std::unique_ptr<Integrator> integrator) {
  return std::make_unique<BgkMethod>(params, method_params, std::move(integrator));
}

}  // namespace bgkmap
