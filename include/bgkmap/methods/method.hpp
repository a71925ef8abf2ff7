// One mapping method as `bgkmap build --method` drives it: scans in, map files out, the counts and
// timings of the JSON report, and a probability (and variance) query for evaluation. BGK-L (the Mapper), the
// T-RO 2019 baselines (BGKOctoMap, counting sensor model, OctoMap, GPOctoMap) and GPOM (IJRR 2012) and WGPOM (RA-L 2017) implement
// it, so every method runs through the same readers, outputs and report.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "bgkmap/core/grid.hpp"
#include "bgkmap/core/params.hpp"
#include "bgkmap/core/progress.hpp"
#include "bgkmap/core/scan.hpp"
#include "bgkmap/integrate/backend.hpp"
#include "bgkmap/integrate/observations.hpp"
#include "bgkmap/io/map_io.hpp"
#include "bgkmap/map/bgk_map.hpp"
#include "bgkmap/mapper.hpp"
#include "bgkmap/methods/method_params.hpp"

namespace bgkmap {

// One method's estimate at a cell: its occupancy probability and, where the method has one, the
// variance it attaches to it. Which parts are set says what kind of estimate it is.
struct CellEstimate {
  double occupancy = 0;  // P(occupied), what occupancy() returns
  // bgkl, bgk, counting: the Beta posterior; occupancy is its mean and variance its variance.
  std::optional<CellPosterior> beta;
  // gpoctomap: the BCM-fused GP prediction of the latent label (+1 occupied, -1 free); variance is
  // its variance (T-RO 2019 eq. 20), occupancy the logistic squashing of mean / variance.
  // gpom: the local model's prediction of the latent label; variance is its variance, occupancy
  // its PLSC squashing. wgpom: the same in label space (the inverse warp's mean and variance).
  std::optional<double> gp_mean;
  // bhm: the mean of the logit a = phi(x)^T w under the weights' posterior; variance is a's
  // variance, occupancy sigma(mean / sqrt(1 + pi variance / 8)).
  std::optional<double> logit_mean;
  // None for octomap: a log-odds cell carries no variance.
  std::optional<double> variance;
};

class MappingMethod {
 public:
  virtual ~MappingMethod() = default;

  // Its name in method_names().
  virtual std::string name() const = 0;

  // Throws InputError naming the file when this method cannot write that format (checked before
  // any work is done).
  virtual void check_output(const std::filesystem::path& file) const = 0;

  // Maps one scan: prepare_scan, then insert_prepared (after check_pose_uncertainty).
  void insert(const Scan& scan) {
    PreparedScan prepared = prepare_scan(scan, params().preprocess);
    check_pose_uncertainty(prepared);
    insert_prepared(std::move(prepared));
  }
  // Whether it takes its scans' pose uncertainty (PreparedScan::pose_covariance) into account:
  // the BGK maps do, by the expected sub-map or kernel, gpom and wgpom by the expected sub-map
  // (docs/ALGORITHM.md).
  virtual bool uses_pose_uncertainty() const { return false; }
  // Throws std::invalid_argument when the scan carries a pose uncertainty and this method would
  // ignore it (callers of insert_prepared check first).
  void check_pose_uncertainty(const PreparedScan& prepared) const;
  // Maps a scan prepared ahead, maybe on another thread (`bgkmap build` reads and prepares the
  // next scan while this one is mapped), with params().preprocess. Its preparing time counts as
  // this scan's preprocessing and insert time, as if done here.
  virtual void insert_prepared(PreparedScan&& prepared) = 0;
  // Every inserted scan applied; counts() and timing() are final after it.
  virtual void finish() = 0;
  // Writes the map in the format the extension names, atomically; a .ot holds `ot_values`
  // (octomap writes liboctomap's own tree either way: its values are what OctoMap classifies by).
  void write(const std::filesystem::path& file, TreeValues ot_values = TreeValues::kClassified) {
    write_file(file, ot_values);
  }

  // The estimate of the cell holding a world point; nullopt where the method knows nothing,
  // and beyond the keys' reach (within_key_range, core/grid.hpp), where no map has cells.
  std::optional<CellEstimate> estimate(double x, double y, double z) {
    if (!within_key_range(x, y, z)) return std::nullopt;
    return estimate_cell(x, y, z);
  }
  // The height a query at z asks for: a planar map's plane (its one layer), else z.
  double query_z(double z) const { return params().preprocess.planar ? params().preprocess.plane_z_m : z; }
  // Its occupancy probability (a planar map's at its layer, whatever z is).
  std::optional<double> occupancy(double x, double y, double z) {
    const std::optional<CellEstimate> e = estimate(x, y, query_z(z));
    if (!e) return std::nullopt;
    return e->occupancy;
  }

  virtual const BuildParams& params() const = 0;
  virtual const BuildCounts& counts() const = 0;
  virtual const InsertTiming& timing() const = 0;
  const std::vector<double>& per_scan_insert_s() const { return timing().per_scan_insert_s; }
  virtual BackendInfo backend() const = 0;
  virtual uint64_t blocks_touched() = 0;
  // Cells with evidence (BGK maps) or known leaves at the finest resolution (OctoMap).
  virtual uint64_t known_cells() = 0;

  // Where the long phases inside the method (gpom's prediction, bhm's evidence search) report how
  // far they have come; none by default.
  void set_progress(ProgressCallback callback) { progress_ = std::move(callback); }

 protected:
  const ProgressCallback& progress() const { return progress_; }
  // write() of a checked path.
  virtual void write_file(const std::filesystem::path& file, TreeValues ot_values) = 0;
  // estimate() of a point within the keys' reach.
  virtual std::optional<CellEstimate> estimate_cell(double x, double y, double z) = 0;

 private:
  ProgressCallback progress_;
};

// The names make_method accepts (bgkl, bgk, counting, octomap, gpoctomap, ...), in --help's order:
// the registry's (method_descriptor.hpp).
const std::vector<std::string>& method_names();

// The method `name` names (one of method_names()); throws std::invalid_argument naming the
// accepted values for anything else. `params` must be valid.
std::unique_ptr<MappingMethod> make_method(const std::string& name, const BuildParams& params,
                                           const MethodParams& method_params, const BackendOptions& backend);

// The BGK-L method around an existing Mapper (e.g. one resuming a stored map).
std::unique_ptr<MappingMethod> make_bgkl_method(std::unique_ptr<Mapper> mapper);

}  // namespace bgkmap
