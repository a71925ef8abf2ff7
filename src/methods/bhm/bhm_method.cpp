// --method bhm: Bayesian Hilbert maps for moving robots (Senanayake & Ramos), numerics in
// methods/bhm/bhm_model.hpp. Training data per scan: hits labelled occupied, and free space either as
// in the paper (--bhm-free points: free points sampled every --free-resolution along each beam,
// labelled free, voxel downsampled with --ds > 0 as the scan's points are) or as BGK-L's free
// segments (--bhm-free beams, 2-D: each beam's exact line integral, worth 1 / --free-resolution
// free points per metre). Each scan's posterior is the next one's prior.
//
// 2-D or 3-D is decided by the first scan: planar scans (every point and the origin at one z
// within 1e-6 m, e.g. CARMEN logs) get hinges on that plane only; anything else a 3-D hinge grid.
// Mixing the two, or planar scans at different heights, is refused.
//
// --bhm-gamma 0: gamma is chosen by the evidence (methods/bhm/bhm_gamma_search.hpp): every candidate
// learns the first --bhm-evidence-scans scans, the one with the largest lower bound goes on; the
// choice and every candidate's bound are in the report's backend description.
//
// The map's cells are those whose centre lies in a touched block's tile of hinges (in 2-D, the
// cells of the scan plane's layer); .ot / .bt hold their probabilities, .bgk is refused.
#include <omp.h>

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdio>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "bgkmap/core/memory_limit.hpp"
#include "core/stage_clock.hpp"
#include "bgkmap/integrate/observations.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/map_io.hpp"
#include "io/probability_map.hpp"
#include "methods/bgk/bgk_method.hpp"
#include "methods/bhm/bhm_gamma_search.hpp"
#include "methods/bhm/bhm_method.hpp"
#include "methods/bhm/bhm_model.hpp"
#include "methods/gp/scan_plane.hpp"

namespace bgkmap {

namespace {

// The cells of one block's tile the map writes: 1,024 x 1,024 in 2-D (at the defaults, 20 x 20).
constexpr double kMaxCellsPerTile = double(1 << 20);

class BhmMethod final : public MappingMethod {
 public:
  BhmMethod(const BuildParams& params, const BhmMethodParams& method_params, const BackendOptions& backend)
      : params_(params), grid_(params.grid), free_resolution_m_(method_params.free_resolution_m),
        free_beams_(method_params.bhm_free == "beams"),
        threads_(backend.threads > 0 ? backend.threads : omp_get_max_threads()) {
    bhm_.spacing_m = method_params.bhm_spacing;
    bhm_.gamma = method_params.bhm_gamma;
    bhm_.support_var = method_params.bhm_support_var;
    bhm_.support_side = method_params.bhm_support_side;
    if (free_beams_ && bhm_.support_side > 0)
      throw std::invalid_argument("--bhm-free beams needs RBF or Gaussian supports, not --bhm-support-side");
    bhm_.prior_var = method_params.bhm_prior_var;
    bhm_.bias = method_params.bhm_bias;
    bhm_.em_iterations = static_cast<int>(method_params.bhm_em_iterations);
    block_side_ = static_cast<int>(method_params.bhm_block_side);
    bhm_.threads = threads_;
    // Checks the parameters before any scan (the dimension is the first scan's).
    choose_gamma_ = bhm_.gamma == 0;
    evidence_scans_ = static_cast<int>(method_params.bhm_evidence_scans);
    BhmParams check = bhm_;
    check.block_side = block_side_ > 0 ? block_side_ : 8;
    if (choose_gamma_) check.gamma = 1.25 / (check.spacing_m * check.spacing_m);
    BhmModel{check};
    BackendOptions gram = backend;
    gram.threads = threads_;
    gram_ = make_block_gram(ComputeDevice::choose(gram));
  }

  std::string name() const override { return "bhm"; }

  void check_output(const std::filesystem::path& file) const override {
    require_probability_map_output(file, "bhm");
  }

  void insert_prepared(PreparedScan&& prepared) override {
    const Clock::time_point start = Clock::now();
    observations_from(prepared, params_.preprocess, beams_, counts_.preprocess);
    plane_.check("bhm", counts_.scans + 1, prepared.origin, prepared.points);
    if (!model_ && !search_ && plane_.known()) {
      BhmParams p = bhm_;
      p.dims = plane_.planar() ? 2 : 3;
      p.plane_z = plane_.z();
      p.block_side = block_side_ > 0 ? block_side_ : (p.dims == 2 ? 8 : 4);
      if (free_beams_ && p.dims != 2)
        throw std::invalid_argument("--bhm-free beams is for planar scans (a 2-D map); scan " +
                                    std::to_string(counts_.scans + 1) + " is 3-D: use --bhm-free points");
      require_small_tiles(p);
      if (choose_gamma_) search_.emplace(p, gram_);
      else model_.emplace(p, gram_);
    }
    free_segments_.clear();
    // A training point is a float and a double point and a label: about 48 bytes.
    require_free_sample_memory(beams_, free_resolution_m_, 48, "bhm", counts_.scans + 1);
    std::vector<Vec3f> free_points;
    if (free_beams_) {
      const Vec3d o{beams_.origin.x, beams_.origin.y, beams_.origin.z};
      for (const Vec3f& end : beams_.free_ends) free_segments_.push_back({o, {end.x, end.y, end.z}});
    } else {
      for (const Vec3f& end : beams_.free_ends) sample_free_points(beams_.origin, end, free_resolution_m_, free_points);
    }
    // Every beam starts at the sensor, so free points crowd around it: the scan's downsampling too.
    if (params_.preprocess.downsample_m > 0 && !free_points.empty())
      free_points = voxel_downsample(free_points, params_.preprocess.downsample_m);
    points_.clear();
    labels_.clear();
    for (const Vec3f& p : beams_.hits) {
      points_.push_back({p.x, p.y, p.z});
      labels_.push_back(1.0);
    }
    for (const Vec3f& p : free_points) {
      points_.push_back({p.x, p.y, p.z});
      labels_.push_back(0.0);
    }
    const double preprocess_s = prepared.seconds + seconds_since(start);

    if (model_) require_update_memory();
    const Clock::time_point t = Clock::now();
    if (search_ && (!points_.empty() || !free_segments_.empty())) {
      search_->add_scan(points_, labels_, free_segments_, 1.0 / free_resolution_m_);
      if (search_->scans() >= evidence_scans_) settle_gamma();
    } else if (model_ && (!points_.empty() || !free_segments_.empty())) {
      const BhmUpdateStats stats = model_->update(points_, labels_, free_segments_, 1.0 / free_resolution_m_);
      counts_.block_visits += stats.blocks;
      counts_.integrate.pairs_evaluated += stats.rows;
    }
    const double compute_s = seconds_since(t);
    ++counts_.scans;
    timing_.add_scan(preprocess_s, 0.0, 0.0, compute_s, prepared.seconds + seconds_since(start));
  }

  void finish() override { settle_gamma(); }

  void write_file(const std::filesystem::path& file, TreeValues ot_values) override {
    check_output(file);
    settle_gamma();
    const CellProbabilities cells = [&](const CellProbabilityVisitor& visit) {
      for_each_cell([&](const CellIndex& c) {
        if (const std::optional<BhmLogit> a = model_->logit(centre_of(c))) visit(c, BhmModel::probability(*a));
      });
    };
    write_probability_map(file, grid_.resolution(), params_.classify, cells, ot_values);
  }

  std::optional<CellEstimate> estimate_cell(double x, double y, double z) override {
    settle_gamma();
    if (!model_) return std::nullopt;
    const std::optional<BhmLogit> a = model_->logit(centre_of(grid_.cell_of(x, y, z)));
    if (!a) return std::nullopt;
    CellEstimate e;
    e.occupancy = BhmModel::probability(*a);
    e.logit_mean = a->mean;
    e.variance = a->variance;
    return e;
  }

  const BuildParams& params() const override { return params_; }
  const BuildCounts& counts() const override { return counts_; }
  const InsertTiming& timing() const override { return timing_; }
  BackendInfo backend() const override {
    BackendInfo b = gram_->info();
    b.device = "variational logistic regression per support block (Eigen, OpenMP), Phi^T Lambda Phi on " +
               (b.kind == DeviceKind::kOpenCl ? b.device : std::string("the CPU"));
    if (!evidence_.empty()) {
      char text[96];
      std::snprintf(text, sizeof text, "; gamma %.4g m^-2 chosen by the evidence of %d scan(s), ELBO by gamma:",
                    model_->params().gamma, evidence_scans_seen_);
      b.device += text;
      for (const BhmGammaSearch::Candidate& c : evidence_) {
        std::snprintf(text, sizeof text, " %.4g %.6g", c.gamma, c.elbo);
        b.device += text;
      }
    }
    return b;
  }
  uint64_t blocks_touched() override {
    settle_gamma();
    return model_ ? model_->block_count() : 0;
  }
  uint64_t known_cells() override {
    settle_gamma();
    uint64_t cells = 0;
    for_each_cell([&](const CellIndex&) { ++cells; });
    return cells;
  }

 private:
  // With --bhm-gamma 0: the search's best model goes on (once).
  void settle_gamma() {
    if (!search_) return;
    evidence_scans_seen_ = search_->scans();
    if (evidence_scans_seen_ > 0) {
      BhmUpdateStats settled;
      model_.emplace(search_->choose(settled, progress()));
      counts_.block_visits += settled.blocks;  // the evidence scans, mapped by the chosen gamma
      counts_.integrate.pairs_evaluated += settled.rows;
      evidence_ = search_->candidates();
    }
    search_.reset();
  }

  // Where a cell is evaluated: its centre, on the scan plane in 2-D.
  Vec3d centre_of(const CellIndex& c) const {
    Vec3d x = grid_.cell_center_d(c);
    if (model_->params().dims == 2) x.z = model_->params().plane_z;
    return x;
  }

  // A block's tile of hinges is written cell by cell (for_each_cell): a spacing that makes it
  // more than kMaxCellsPerTile cells is refused before the first update.
  void require_small_tiles(const BhmParams& p) const {
    const double across = p.block_side * p.spacing_m / grid_.resolution();
    const double cells = std::pow(across, p.dims);
    if (cells <= kMaxCellsPerTile) return;
    char text[256];
    std::snprintf(text, sizeof text,
                  "--bhm-spacing %g m makes a block's tile (%d hinges a side) %.3g cells of --resolution %g m "
                  "across, %.3g cells in %d-D, at most %.0f: give a smaller --bhm-spacing",
                  p.spacing_m, p.block_side, across, grid_.resolution(), cells, p.dims, kMaxCellsPerTile);
    throw std::invalid_argument(text);
  }

  // The cells whose centre lies in a touched block's tile: hinges h * spacing with
  // h in [b * side, (b + 1) * side), the tile [(b * side - 1/2) spacing, ((b + 1) side - 1/2) spacing),
  // clamped to the cell indices a grid holds.
  template <typename Visit>
  void for_each_cell(Visit&& visit) const {
    if (!model_) return;
    const BhmParams& p = model_->params();
    const double r = grid_.resolution();
    const auto cell_index = [](double c) {
      return static_cast<int64_t>(std::clamp(c, double(INT32_MIN), double(INT32_MAX)));
    };
    const auto cells = [&](int32_t block, int64_t& first, int64_t& last) {
      const double lo = (double(block) * p.block_side - 0.5) * p.spacing_m;
      const double hi = (double(block + 1) * p.block_side - 0.5) * p.spacing_m;
      first = cell_index(std::ceil(lo / r - 0.5));
      last = cell_index(std::ceil(hi / r - 0.5) - 1);
    };
    for (size_t b = 0; b < model_->block_count(); ++b) {
      const BlockKey& key = model_->block_key(b);
      int64_t x0, x1, y0, y1, z0, z1;
      cells(key.x, x0, x1);
      cells(key.y, y0, y1);
      if (p.dims == 2) z0 = z1 = grid_.cell_of(0, 0, p.plane_z).z;
      else cells(key.z, z0, z1);
      for (int64_t z = z0; z <= z1; ++z)
        for (int64_t y = y0; y <= y1; ++y)
          for (int64_t x = x0; x <= x1; ++x)
            visit(CellIndex{static_cast<int32_t>(x), static_cast<int32_t>(y), static_cast<int32_t>(z)});
    }
  }

  BuildParams params_;
  Grid grid_;
  BhmParams bhm_;
  int block_side_ = 0;
  double free_resolution_m_;
  bool free_beams_;
  int threads_;
  ScanPlane plane_;
  std::shared_ptr<BlockGramEngine> gram_;
  bool choose_gamma_ = false;
  int evidence_scans_ = 1, evidence_scans_seen_ = 0;
  std::optional<BhmGammaSearch> search_;           // choosing gamma: the first evidence_scans_ scans kept
  std::vector<BhmGammaSearch::Candidate> evidence_;  // what chose it
  std::optional<BhmModel> model_;  // made when the first scan with points decides 2-D or 3-D
  ScanObservations beams_;
  // The update's working memory (BhmModel::update_bytes), checked before it is allocated.
  void require_update_memory() const {
    size_t reached = 0;
    const double bytes = model_->update_bytes(points_, free_segments_, &reached);
    require_memory(bytes,
                   "bhm's update (scan " + std::to_string(counts_.scans + 1) + ": " + std::to_string(points_.size()) +
                       " training points reaching " + std::to_string(reached) + " blocks of " +
                       std::to_string(model_->supports_per_block()) + " supports)",
                   "give a larger --free-resolution, a shorter --max-range or a coarser --ds (or raise --max-memory)");
  }

  std::vector<Vec3d> points_;
  std::vector<double> labels_;
  std::vector<BhmBeam> free_segments_;
  BuildCounts counts_;
  InsertTiming timing_;
};

}  // namespace

std::unique_ptr<MappingMethod> make_bhm_method(const BuildParams& params, const MethodParams& method_params,
                                               const BackendOptions& backend) {
  return std::make_unique<BhmMethod>(params, bhm_method_params(method_params), backend);
}

}  // namespace bgkmap
