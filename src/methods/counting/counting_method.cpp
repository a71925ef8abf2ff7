// --method counting: the counting sensor model (T-RO 2019 §III). Each hit adds 1 to alpha of its
// cell; each beam's free segment (the same one BGK-L uses: origin to the hit less the end margin,
// or to max range) adds 1 to beta of every cell it passes through, found by 3-D DDA. That is
// BGK-L with the box kernel, computed by traversal instead of against every cell of a block. The
// map is a BgkMap (kernel recorded as "box"), so every output and query works on it.
#include <chrono>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "bgkmap/integrate/observations.hpp"
#include "bgkmap/io/map_io.hpp"
#include "methods/bgkl/bgk_map_method.hpp"
#include "methods/counting/counting_method.hpp"
#include "core/grid_traversal.hpp"
#include "core/stage_clock.hpp"

namespace bgkmap {

namespace {

BuildParams with_box_kernel(BuildParams params) {
  params.kernel.type = KernelType::kBox;
  return params;
}

class CountingMethod final : public MappingMethod {
 public:
  CountingMethod(const BuildParams& params, double forget_half_life) : map_(with_box_kernel(params)) {
    map_.set_forget_half_life(forget_half_life);
  }

  std::string name() const override { return "counting"; }
  void check_output(const std::filesystem::path& file) const override { map_format_from_path(file); }

  void insert_prepared(PreparedScan&& prepared) override {
    const Clock::time_point start = Clock::now();
    observations_from(prepared, map_.params().preprocess, obs_, counts_.preprocess);
    const double preprocess_s = prepared.seconds + seconds_since(start);

    const Clock::time_point t = Clock::now();
    const Grid& grid = map_.grid();
    map_.advance_time();
    const auto cell_ref = [&](const CellIndex& c) -> Cell& {
      const uint32_t slot = map_.ensure_slot(grid.block_of(c));
      map_.catch_up_block(slot);  // forgetting: decayed to this scan before its first count
      return map_.block_cells(slot)[grid.local_index(c)];
    };
    for (const Vec3f& hit : obs_.hits) {
      cell_ref(grid.cell_of(hit.x, hit.y, hit.z)).alpha += 1.0f;
      ++counts_.integrate.pairs_evaluated;
    }
    const Vec3d origin{obs_.origin.x, obs_.origin.y, obs_.origin.z};
    for (const Vec3f& end : obs_.free_ends) {
      for_each_cell_on_segment(grid, origin, Vec3d{end.x, end.y, end.z}, [&](const CellIndex& c) {
        cell_ref(c).beta += 1.0f;
        ++counts_.integrate.pairs_evaluated;
      });
    }
    counts_.integrate.pairs_within_support = counts_.integrate.pairs_evaluated;
    const double compute_s = seconds_since(t);

    ++counts_.scans;
    timing_.add_scan(preprocess_s, 0.0, 0.0, compute_s, prepared.seconds + seconds_since(start));
  }

  void finish() override {}
  void write_file(const std::filesystem::path& file, TreeValues ot_values) override {
    write_map(file, read_view(), name(), ot_values);
  }

  std::optional<CellEstimate> estimate_cell(double x, double y, double z) override {
    return beta_estimate(read_view().query(x, y, z));
  }

  const BuildParams& params() const override { return map_.params(); }
  const BuildCounts& counts() const override { return counts_; }
  const InsertTiming& timing() const override { return timing_; }
  BackendInfo backend() const override { return {"cpu", "3-D DDA (single thread)", 1, ""}; }
  uint64_t blocks_touched() override { return map_.block_count(); }
  uint64_t known_cells() override { return read_view().cells_with_evidence(); }

 private:
  // What a read sees: with forgetting, every block decayed to now (kept until the next scan).
  const BgkMap& read_view() { return bgkmap::read_view(map_, settled_); }

  BgkMap map_;
  std::optional<BgkMap> settled_;
  ScanObservations obs_;
  BuildCounts counts_;
  InsertTiming timing_;
};

}  // namespace

std::unique_ptr<MappingMethod> make_counting_method(const BuildParams& params, double forget_half_life) {
  return std::make_unique<CountingMethod>(params, forget_half_life);
}

}  // namespace bgkmap
