// The build pipeline for one BGK map: observe -> bucket -> allocate blocks -> integrate, per scan,
// with the counts and timings the CLI's JSON report publishes.
#pragma once

#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include "bgkmap/core/params.hpp"
#include "bgkmap/core/scan.hpp"
#include "bgkmap/integrate/bucketing.hpp"
#include "bgkmap/integrate/integrator.hpp"
#include "bgkmap/integrate/observation_stage.hpp"
#include "bgkmap/integrate/observations.hpp"
#include "bgkmap/map/expected_submap.hpp"
#include "bgkmap/map/bgk_map.hpp"

namespace bgkmap {

struct BuildCounts {
  uint64_t scans = 0;
  PreprocessCounts preprocess;
  uint64_t block_visits = 0;  // (scan, block) pairs: blocks touched summed over scans
  IntegrateStats integrate;
};

// Seconds spent from a parsed scan to an updated map, by stage.
struct InsertTiming {
  double insert_s = 0;  // time of insert(), a scan prepared ahead counted with its preparing; its parts below add up to it
  double preprocess_s = 0, bucket_s = 0, compute_s = 0, update_s = 0;
  std::vector<double> per_scan_insert_s;

  // Adds one scan's stage times and records its insert time per scan.
  void add_scan(double preprocess, double bucket, double update, double compute, double insert) {
    preprocess_s += preprocess;
    bucket_s += bucket;
    update_s += update;
    compute_s += compute;
    insert_s += insert;
    per_scan_insert_s.push_back(insert);
  }
  // Time spent waiting for a back end still working on the scans inserted last.
  void add_wait(double wait) {
    compute_s += wait;
    insert_s += wait;
    if (!per_scan_insert_s.empty()) per_scan_insert_s.back() += wait;
  }
};

class Mapper {
 public:
  // A new, empty map. `stage` turns scans into observations: BGK-L's segments when null.
  Mapper(const BuildParams& params, std::unique_ptr<Integrator> integrator,
         std::unique_ptr<ObservationStage> stage = nullptr);
  // Continues an existing map (e.g. one loaded from a .bgk file): new scans add to its counts.
  Mapper(BgkMap map, std::unique_ptr<Integrator> integrator, std::unique_ptr<ObservationStage> stage = nullptr);

  // Adds one scan's kernel-weighted counts (the recursive BGK update). A device back end may
  // still be working on the scan when this returns (the next insert() or finish() waits).
  void insert(const Scan& scan);
  // The same for a scan prepared ahead (prepare_scan with params().preprocess), maybe on another
  // thread; its preparing time counts as this scan's preprocessing and insert time. A scan with a
  // pose covariance is mapped under each sigma point's displacement (pose_sigma_points), each
  // copy bucketed exactly: by default the expected sub-map's counts are added (ExpectedSubmap;
  // a device back end's map is copied back and forth for each sigma point), with
  // PoseFusion::kExpectedKernel each copy's counts weighted by the point's weight.
  void insert_prepared(PreparedScan&& prepared);
  // The same for observations made elsewhere (a distributed build's share of a scan), mapping
  // only the blocks `keep` accepts (all when empty); a kept block gets exactly the sums it gets
  // from insert() of the whole scan when `obs` holds, in their order, every observation
  // bucketing gives it.
  void insert_observations(const ScanObservations& obs, const std::function<bool(const BlockKey&)>& keep);

  // Waits for the back end to finish every inserted scan; the wait counts as insert time.
  // counts() and timing() are final after it (map() calls it).
  void finish();

  // The map with every inserted scan applied (through a host view of every cell: a device back end finishes and copies it back first).
  // With forgetting, every block decayed to the map's time (a copy, kept until the next scan).
  const BgkMap& map();
  // The same as the map holds it: with forgetting, each block as its last scan left it, beside
  // its time (what a .bgk stores, so a resumed build continues exactly).
  const BgkMap& lazy_map();

  // Forgetting with this half-life in scans (map/forgetting.hpp); on a new map only.
  void set_forget_half_life(double half_life_scans) { map_.set_forget_half_life(half_life_scans); }

  const BuildParams& params() const { return map_.params(); }
  // Blocks in the map (new ones are created by insert, whatever the back end's progress).
  size_t block_count() const { return map_.block_count(); }
  const BuildCounts& counts() const { return counts_; }
  const InsertTiming& timing() const { return timing_; }
  const std::vector<double>& per_scan_insert_s() const { return timing_.per_scan_insert_s; }
  BackendInfo backend() const { return integrator_->info(); }

 private:
  void map_observations(const ScanObservations& obs, const std::function<bool(const BlockKey&)>& keep,
                        double preprocess_s, double prepared_s, std::chrono::steady_clock::time_point start);
  // A scan under pose uncertainty, its observations in obs_: the expected sub-map over `points`.
  void insert_expected_submap(const std::vector<PoseSigmaPoint>& points, double& bucket_s, double& update_s,
                              double& compute_s);
  // Bucketing, blocks and integration of one set of observations; adds the stage times.
  // Buckets `obs` into buckets_ (on a planar map only its layer's blocks; only the blocks `keep`
  // accepts, when given) and gives each block its slot.
  void bucket_into_slots(const ScanObservations& obs, const std::function<bool(const BlockKey&)>& keep,
                         double& bucket_s, double& update_s);
  void integrate_observations(const ScanObservations& obs, const std::function<bool(const BlockKey&)>& keep,
                              double& bucket_s, double& update_s, double& compute_s);
  // Forgetting: the blocks of buckets_ that are behind decayed to the map's time by the back end
  // (Integrator::decay_blocks: the same arithmetic on every back end, so their maps stay the same).
  void catch_up_blocks();

  BgkMap map_;
  std::unique_ptr<Integrator> integrator_;
  std::unique_ptr<ObservationStage> stage_;
  ScanObservations obs_;  // scratch reused across scans
  ScanObservations displaced_;  // obs_ displaced by one sigma point
  ScanBuckets buckets_;
  ExpectedSubmap submap_;        // a scan's cells under each sigma point
  std::vector<uint32_t> slots_;  // the slots of one sigma point's blocks
  std::vector<uint32_t> behind_;  // the slots of a scan's blocks to decay
  std::vector<float> factors_;    // and their factors
  std::optional<BgkMap> settled_;  // map() with forgetting, at settled_->forgetting().now
  BuildCounts counts_;
  InsertTiming timing_;
};

}  // namespace bgkmap
