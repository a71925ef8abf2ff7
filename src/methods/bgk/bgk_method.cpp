// --method bgk: BGKOctoMap. Free space is observed as points sampled along each beam every
// --free-resolution instead of whole segments; hits and free points are all point observations
// under the same kernel and Beta update as BGK-L.
//
// Only the observations are new: it is the Mapper with another ObservationStage. A free point is
// a zero-length free segment, which the shared bucketing geometry (make_local_beam) and both back
// ends already evaluate as a point. The points are bucketed as points (bucket_scan with them as
// hits), then their pairs are turned into zero-length beams.
#include <cmath>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "bgkmap/core/memory_limit.hpp"
#include "bgkmap/integrate/bucketing.hpp"
#include "integrate/local_frames.hpp"
#include "bgkmap/integrate/observations.hpp"
#include "bgkmap/integrate/observation_stage.hpp"
#include "bgkmap/mapper.hpp"
#include "methods/bgkl/bgk_map_method.hpp"
#include "methods/bgk/bgk_method.hpp"

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

void require_free_sample_memory(const ScanObservations& beams, double spacing_m, double bytes_per_sample,
                                const std::string& method, uint64_t scan) {
  double samples = double(beams.hits.size());
  for (const Vec3f& end : beams.free_ends) {
    const double dx = end.x - beams.origin.x, dy = end.y - beams.origin.y, dz = end.z - beams.origin.z;
    samples += 1 + std::sqrt(dx * dx + dy * dy + dz * dz) / spacing_m;
  }
  require_memory(samples * bytes_per_sample,
                 method + "'s training points (scan " + std::to_string(scan) + ": " + std::to_string(beams.hits.size()) +
                     " hits and their beams' free samples)",
                 "give a shorter --max-range or a larger --free-resolution (or raise --max-memory)");
}

namespace {

// Hits first, then the free points, all as points: pairs with id >= the hit count are free.
class SampledFreePoints final : public ObservationStage {
 public:
  explicit SampledFreePoints(double spacing_m) : spacing_m_(spacing_m) {}

  void observe(const PreparedScan& prepared, const PreprocessParams& params, ScanObservations& out,
               PreprocessCounts& counts) override {
    observations_from(prepared, params, beams_, counts);
    out.origin = beams_.origin;
    out.hits = beams_.hits;
    out.free_ends.clear();
    // Each sample is a point, then a zero-length beam of a block it reaches (bucketing checks those).
    require_free_sample_memory(beams_, spacing_m_, sizeof(Vec3f), "bgk", ++scans_);
    for (const Vec3f& end : beams_.free_ends) sample_free_points(beams_.origin, end, spacing_m_, out.hits);
    hit_count_ = static_cast<uint32_t>(beams_.hits.size());
  }

  // Every point bucketed as a hit, then the free points' pairs turned into zero-length beams.
  void bucket(const Grid& grid, float support_radius_m, const ScanObservations& obs, ScanBuckets& out,
              int threads) override {
    bucket_scan(grid, support_radius_m, obs, point_buckets_, threads);
    const double mid_offset = 0.5 * (grid.cells_per_side() - 1) * grid.resolution();
    out.clear();
    for (const BlockWork& in : point_buckets_.blocks) {
      BlockWork block;
      block.key = in.key;
      block.hit_begin = static_cast<uint32_t>(out.hit_ids.size());
      block.beam_begin = static_cast<uint32_t>(out.beam_ids.size());
      const Vec3d c0 = grid.block_first_center_d(in.key);
      const Vec3d mid{c0.x + mid_offset, c0.y + mid_offset, c0.z + mid_offset};
      for (uint32_t k = in.hit_begin; k < in.hit_begin + in.hit_count; ++k) {
        const uint32_t id = point_buckets_.hit_ids[k];
        if (id < hit_count_) {
          out.hit_ids.push_back(id);
          out.hits.push_back(point_buckets_.hits[k]);
        } else {
          const Vec3f& p = obs.hits[id];
          out.beam_ids.push_back(id);
          out.beams.push_back(make_local_beam(c0, mid, p, p));
        }
      }
      block.hit_count = static_cast<uint32_t>(out.hit_ids.size()) - block.hit_begin;
      block.beam_count = static_cast<uint32_t>(out.beam_ids.size()) - block.beam_begin;
      out.blocks.push_back(block);
    }
  }

 private:
  double spacing_m_;
  uint64_t scans_ = 0;  // observed so far, for messages
  uint32_t hit_count_ = 0;
  ScanObservations beams_;     // scratch reused across scans
  ScanBuckets point_buckets_;
};

}  // namespace

std::unique_ptr<MappingMethod> make_bgk_method(const BuildParams& params, const MethodParams& method_params,
                                               std::unique_ptr<Integrator> integrator) {
  auto mapper = std::make_unique<Mapper>(params, std::move(integrator),
                                         std::make_unique<SampledFreePoints>(method_params.number("free-resolution")));
  mapper->set_forget_half_life(method_params.number(forget_half_life_param().key));
  return std::make_unique<BgkMapMethod>("bgk", std::move(mapper));
}

}  // namespace bgkmap
