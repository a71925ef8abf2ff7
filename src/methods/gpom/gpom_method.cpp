// --method gpom: Gaussian process occupancy maps (O'Callaghan & Ramos, IJRR 2012).
//
// Training data: every hit (label +1) and every beam's free segment (label -1). For a query the
// free observation of a beam is the segment's point nearest to the query (the paper's sensor
// model; the line-integral variant needs a numerical integral of the covariance per pair and
// buys nothing the nearest point does not give for the neighbours used here). Each query (a
// cell centre; in 2-D at the scans' plane) has its own local model: its k nearest hits and the
// nearest points of its k nearest beams (k = --gp-neighbours; the paper's 15 + 15), found in k-d trees
// (nanoflann) over every scan so far. GP regression on the local model (Matern 3/2, the sparse
// kernel, the squared exponential or the neural-network covariance, gp_regression) gives the
// latent mean and variance stored per cell (the neural-network covariance is not stationary: a
// local model's inputs are taken relative to its query, so the map does not move with the
// world's origin; it is solved on the CPU whatever the back end); occupancy is
// their PLSC squashing with alpha, beta fitted to leave-one-out predictions of sampled local
// models (plsc). Scans only mark the blocks near their observations dirty; a dirty block's cells
// are (re)evaluated when the map is next read (finish, write, estimate), in parallel over blocks
// (OpenMP). Cells farther than the length scale from every hit and beam stay unknown (default mode).
//
// --gp-mode paper: the IJRR model. The neural-network covariance of eq. 7 in the world's frame
// (nothing centred), its weight covariance S, s2 and sn learned once, when the map is first read,
// on a sample of the first scans (first_scans_sample, neural_network_learning); 15 + 15
// neighbours; every cell of the data's bounding box grown by the reach is mapped, those with no
// datum within reach at the GP prior (mapped_extent), without a search or a solve where no
// scan marked the block. Solved on the CPU.
//
// --method wgpom: warped GPOM (Ghaffari Jadidi et al., RA-L 2017) on the same local models. The
// GP models z = g(y), a monotonic sum-of-tanh warp of the labels (warped_gp) learned by maximising
// the warped marginal likelihood over the local models of a sample of cells when the map is first
// read (or given); a cell's mean and variance are those of g^-1(z) over its latent Gaussian
// (Gauss-Hermite quadrature), squashed by PLSC as gpom's, whose leave-one-out samples are
// unwarped the same way.
//
// Pose uncertainty (the expected sub-map of the WGPOM paper, for gpom and wgpom): once a scan
// carries a pose covariance, the training data is kept once per sigma point h of the cubature rule
// (pose_sigma_points, 2n points of equal weight), every uncertain scan displaced by its own h-th
// point, certain scans as they are. Each hypothesis' data gives a sub-map; a cell's mean and
// variance are those of the equal-weight mixture of the sub-maps' predictions (moment matched:
// mean of means; mean of variances plus variance of means). The h-th points of all scans are
// taken together, so their displacements are fully correlated, as a drift's are. A cell is known
// when every hypothesis has data within reach (where only some do, the data cannot be placed
// there: a hit displaced beyond a wall by some hypotheses is not evidence of occupancy there);
// PLSC is fitted to every hypothesis' leave-one-out samples. No uncertain scan: one copy, the
// plain map exactly.
//
// Pose uncertainty by the expected kernel (--pose-fusion kernel, GPPOL of the IJRR paper): one
// copy of the training data, each input with a Gaussian position uncertainty from its scan's
// sigma points (uncertain_inputs: per hit its covariance, per beam its ends' covariances, from
// which the nearest point's follows, across the beam inside it), and the local model's
// covariances their expectations (expected_kernel, the query certain), solved on the CPU. By
// --gp-input-correlation the inputs of a scan move together (each input's displacements under
// its scan's motion give the covariances of the differences) and the scans' sigma points are
// paired, or the inputs are independent. Leave-one-out samples and PLSC use the same expected
// matrix. Until a scan is uncertain the covariances are not stored.
//
// The pieces, in methods/gpom/: the training data and its k-d trees (training_set, growing_tree),
// a query's local models (local_models), a cell from them (cell_solver, with wgpom's warp hook,
// label_warp), the PLSC fit (calibration) and the evaluation of the dirty blocks on the CPU or a
// device (prediction). This file holds the method: scans in, blocks marked dirty, evaluation when read.
#include <omp.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <cmath>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "bgkmap/core/memory_limit.hpp"
#include "bgkmap/core/pose_covariance.hpp"
#include "bgkmap/integrate/bucketing.hpp"
#include "bgkmap/integrate/observations.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/map_io.hpp"
#include "core/gauss_hermite.hpp"
#include "core/stage_clock.hpp"
#include "io/probability_map.hpp"
#include "integrate/local_gp_batch.hpp"
#include "map/block_store.hpp"
#include "methods/gp/expected_kernel.hpp"
#include "methods/gp/gp_hyperparameters.hpp"
#include "methods/gp/neural_network_learning.hpp"
#include "methods/gp/gp_regression.hpp"
#include "methods/gp/scan_plane.hpp"
#include "methods/gp/uncertain_inputs.hpp"
#include "methods/gpom/calibration.hpp"
#include "methods/gpom/cell_queries.hpp"
#include "methods/gpom/cell_solver.hpp"
#include "methods/gpom/first_scans_sample.hpp"
#include "methods/gpom/gpom_method.hpp"
#include "methods/gpom/label_warp.hpp"
#include "methods/gpom/local_models.hpp"
#include "methods/gpom/mapped_extent.hpp"
#include "methods/gpom/prediction.hpp"
#include "methods/gpom/training_set.hpp"
#include "methods/wgpom/warped_gp.hpp"

namespace bgkmap {

namespace {

using namespace gpom;

// wgpom: the warp is learned from the local models of every kWarpStride-th cell of the dirty
// blocks (a prime, so the sample does not line up with the rows of a block), at most
// kMaxWarpModels of them; kQuadratureNodes Gauss-Hermite nodes unwarp a prediction.
// --gp-hyperparameters learn: the covariance is learned from the first kMaxHyperModels of them
// (evenly spread), before the warp.
constexpr int kWarpStride = 61;
constexpr size_t kMaxWarpModels = 256;
constexpr size_t kMaxHyperModels = 64;
constexpr int kQuadratureNodes = 20;
// --gp-neighbours 0: each mode's count (the paper's: IJRR sec. 4.1).
constexpr int kDefaultNeighbours = 30, kPaperNeighbours = 15;
constexpr uint64_t kPaperTrainingSeed = 1;

int neighbours_of(const GpomParams& p) {
  if (p.gp_neighbours > 0) return p.gp_neighbours;
  return p.gp_mode == "paper" ? kPaperNeighbours : kDefaultNeighbours;
}

class GpomMethod final : public MappingMethod {
 public:
  // warped: wgpom, with `warp` as its warp if given, else learned at the first evaluation.
  GpomMethod(const BuildParams& params, const GpomParams& method_params, const BackendOptions& backend, bool warped,
             std::optional<TanhWarp> warp)
      : params_(params), grid_(params.grid), cells_(grid_), queries_(grid_),
        neighbours_(static_cast<size_t>(neighbours_of(method_params))),
        threads_(backend.threads > 0 ? backend.threads : omp_get_max_threads()), warped_(warped), warp_(std::move(warp)) {
    warp_learning_.terms = static_cast<int>(method_params.wgp_terms);
    learn_hyperparameters_ = method_params.gp_hyperparameters == "learn";
    hp_.covariance = method_params.gp_covariance == "sparse" ? GpCovariance::kSparse
                     : method_params.gp_covariance == "se" ? GpCovariance::kSquaredExponential
                     : method_params.gp_covariance == "nn" ? GpCovariance::kNeuralNetwork
                                                           : GpCovariance::kMatern32;
    paper_ = method_params.gp_mode == "paper";
    if (paper_) check_paper_mode(method_params, params);
    if (paper_) hp_.covariance = GpCovariance::kNeuralNetwork;
    centred_ = hp_.covariance == GpCovariance::kNeuralNetwork && !paper_;
    train_scans_ = static_cast<uint64_t>(method_params.gp_train_scans);
    train_points_ = static_cast<size_t>(method_params.gp_train_points);
    if (centred_ && (params.preprocess.pose_fusion == PoseFusion::kExpectedKernel || method_params.gp_range_sigma > 0 ||
                     method_params.gp_bearing_sigma > 0))
      throw std::invalid_argument("--method " + name() + ": the expected kernel (--pose-fusion kernel, --gp-range-sigma, "
                                  "--gp-bearing-sigma) takes a covariance of the distance (--gp-covariance matern, "
                                  "sparse or se), not nn");
    hp_.ell_m = method_params.gp_length_m;
    hp_.signal_var = method_params.gp_signal_var;
    hp_.noise_std = method_params.gp_noise;
    reach_m_ = hp_.ell_m;
    sensor_noise_ = {method_params.gp_range_sigma, method_params.gp_bearing_sigma};
    correlation_ = method_params.gp_input_correlation == "independent" ? InputCorrelation::kIndependent
                   : method_params.gp_input_correlation == "scan"     ? InputCorrelation::kScan
                                                                      : InputCorrelation::kTrajectory;
    expected_kernel_ = sensor_noise_.any();  // every input uncertain from the first scan
    sets_.push_back(std::make_unique<TrainingData>());
    device_ = make_local_gp_device(ComputeDevice::choose(backend));
    beam_step_m_ = std::max(grid_.resolution(), 0.5 * hp_.ell_m);
  }

  std::string name() const override { return warped_ ? "wgpom" : "gpom"; }
  bool uses_pose_uncertainty() const override { return true; }

  void check_output(const std::filesystem::path& file) const override {
    require_probability_map_output(file, name());
  }

  void insert_prepared(PreparedScan&& prepared) override {
    const Clock::time_point start = Clock::now();
    check_dimension(prepared);
    const std::vector<PoseSigmaPoint> points = sigma_points_of(prepared);
    observations_from(prepared, params_.preprocess, obs_, counts_.preprocess);
    require_training_memory();
    double bucket_s = 0, update_s = 0;
    for (size_t h = 0; h < sets_.size(); ++h) {
      const ScanObservations* obs = &obs_;
      const bool pose_kernel = params_.preprocess.pose_fusion == PoseFusion::kExpectedKernel;
      if (!points.empty() && !pose_kernel) {  // the expected sub-map: this hypothesis' data
        displace_observations(obs_, points[h], queries_.planar(), displaced_);
        obs = &displaced_;
      }
      if (expected_kernel_) {  // the certain scans before the first uncertain one: zero
        sets_[h]->hit_cov.resize(sets_[h]->hits.size());
        sets_[h]->beam_cov.resize(sets_[h]->beam_ends.size());
        // Of the data this copy trains on: a displaced copy's own returns (displace_observations
        // may have dropped some), seen along its displaced beams.
        append_input_covariances(*obs, pose_kernel ? points : std::vector<PoseSigmaPoint>{}, queries_.planar(),
                                 sensor_noise_, sets_[h]->hit_cov, sets_[h]->beam_cov);
        if (pose_kernel && correlation_ != InputCorrelation::kIndependent) add_motion(points, *sets_[h]);
      }
      add_training(*obs, beam_step_m_, *sets_[h]);
      if (h == 0 && counts_.scans < train_scans_) first_ = {sets_[0]->hits.size(), sets_[0]->beam_origins.size()};
      if (h == 0 && paper_) extent_.add(*obs);
      if (h > 0 && points.empty()) continue;  // the same observations: the same cells
      // The cells whose local model may change: those within reach of this scan's hits and beams
      // (the bucketing radius adds a cell, as 2-D queries sit at the plane, not the cell centre).
      Clock::time_point t = Clock::now();
      bucket_scan(grid_, static_cast<float>(reach_m_ + grid_.resolution()), *obs, buckets_, 1, "--gp-length");
      bucket_s += seconds_since(t);
      t = Clock::now();
      for (const BlockWork& work : buckets_.blocks) {
        if (queries_.planar() && !queries_.block_holds_plane(work.key)) continue;
        const uint32_t slot = ensure_slot(work.key);
        if (!dirty_flag_[slot]) dirty_flag_[slot] = 1, dirty_.push_back(slot);
      }
      update_s += seconds_since(t);
      counts_.block_visits += buckets_.blocks.size();
    }
    const double preprocess_s = prepared.seconds + seconds_since(start) - bucket_s - update_s;

    ++counts_.scans;
    timing_.add_scan(preprocess_s, bucket_s, update_s, 0.0, prepared.seconds + seconds_since(start));
  }

  void finish() override {
    const Clock::time_point t = Clock::now();
    flush();
    timing_.add_wait(seconds_since(t));  // the deferred evaluation, counted as compute time
  }

  void write_file(const std::filesystem::path& file, TreeValues ot_values) override {
    check_output(file);
    flush();
    const CellProbabilities cells = [&](const CellProbabilityVisitor& visit) {
      cells_.for_each_cell([&](const CellIndex& c, const GpomCell& cell) {
        if (cell.known) visit(c, calibration_.probability(cell.mean, cell.variance));
      });
    };
    write_probability_map(file, grid_.resolution(), params_.classify, cells, ot_values);
  }

  std::optional<CellEstimate> estimate_cell(double x, double y, double z) override {
    flush();
    const GpomCell* cell = cells_.find(grid_.cell_of(x, y, z));
    if (!cell || !cell->known) return std::nullopt;
    CellEstimate e;
    e.occupancy = calibration_.probability(cell->mean, cell->variance);
    e.gp_mean = cell->mean;
    e.variance = cell->variance;
    return e;
  }

  const BuildParams& params() const override { return params_; }
  const BuildCounts& counts() const override { return counts_; }
  const InsertTiming& timing() const override { return timing_; }
  BackendInfo backend() const override {
    std::string description = std::string(warped_ ? "warped " : "") +
                              "GP regression per query on its local model (nanoflann, Eigen, OpenMP)";
    if (hyperparameters_learned_ && paper_) {
      char learned[320];
      const std::array<double, 4>& w = hp_.nn_sigma;
      std::snprintf(learned, sizeof learned,
                    "; the IJRR paper's neural-network covariance, learned: S = diag(%.6g, %.6g, %.6g, %.6g), signal "
                    "variance %.6g, noise %.6g; the GP prior beyond %.4g m of every datum",
                    w[0], w[1], w[2], w[3], hp_.signal_var, hp_.noise_std, reach_m_);
      description += learned;
    } else if (hyperparameters_learned_) {
      char learned[160];
      std::snprintf(learned, sizeof learned, "; learned covariance: length %.4g m, signal variance %.4g, noise %.4g",
                    hp_.ell_m, hp_.signal_var, hp_.noise_std);
      description += learned;
    }
    if (warped_ && warp_) description += "; warp " + describe(*warp_);
    if (sets_.size() > 1)
      description += "; expected sub-map over " + std::to_string(sets_.size()) + " pose sigma points";
    if (expected_kernel_) {
      description += hp_.covariance == GpCovariance::kSquaredExponential
                         ? std::string("; expected kernel over uncertain inputs (closed form)")
                         : "; expected kernel over uncertain inputs (Gauss-Hermite, " +
                               std::to_string(queries_.planar() ? kExpectedKernelOrder2d : kExpectedKernelOrder3d) +
                               " nodes per axis)";
      if (!motions_.empty())
        description += correlation_ == InputCorrelation::kTrajectory
                           ? "; inputs moving with their scans, the scans' sigma points paired"
                           : "; inputs moving with their scans, the scans independent";
      return on_cpu(description);
    }
    if (centred_) description += "; neural-network covariance, each local model centred at its query";
    if (hp_.covariance == GpCovariance::kNeuralNetwork) return on_cpu(description);
    const BackendInfo device = device_->info();
    if (device.kind == DeviceKind::kOpenCl)
      return backend_info(DeviceKind::kOpenCl, description + "; local models solved on " + device.device, threads_);
    return backend_info(DeviceKind::kCpu, description, threads_, device.note, device.reason);
  }
  // Kernels the device does not solve: the CPU path, saying so where the device was the choice.
  BackendInfo on_cpu(std::string description) const {
    const BackendInfo device = device_->info();
    if (device.kind == DeviceKind::kOpenCl) description += ", solved on the CPU";
    return backend_info(DeviceKind::kCpu, description, threads_, device.note, device.reason);
  }
  uint64_t blocks_touched() override { return cells_.block_count(); }
  uint64_t known_cells() override {
    flush();
    uint64_t known = 0;
    for (const GpomCell& cell : cells_.cells()) known += cell.known;
    return known;
  }

 private:
  // 2-D when every scan is planar at the same z, 3-D when none is; a mix is refused.
  void check_dimension(const PreparedScan& prepared) {
    const bool decided = plane_.known();
    plane_.check(name(), counts_.scans + 1, prepared.origin, prepared.points);
    if (decided || !plane_.known()) return;
    queries_.set_plane(plane_.planar(), plane_.z());
  }

  // The scan's pose sigma points (none for a certain scan). Expected kernel: the first uncertain
  // scan starts the inputs' covariances. Expected sub-map: the first uncertain scan makes one copy
  // of the training data per point; every later uncertain scan must have as many points.
  std::vector<PoseSigmaPoint> sigma_points_of(const PreparedScan& prepared) {
    if (!prepared.pose_covariance) return {};
    std::vector<PoseSigmaPoint> points = pose_sigma_points(*prepared.pose_covariance);
    if (points.empty()) return points;
    // Scans whose sigma points are paired must have covariances of one rank.
    const auto refuse_rank = [&](size_t earlier_points, const std::string& why) {
      const auto from = [](const std::string& source) { return source.empty() ? std::string() : " (" + source + ")"; };
      return std::invalid_argument("--method " + name() + ": scan " + std::to_string(counts_.scans + 1) +
                                   "'s pose covariance" + from(prepared.pose_covariance_source) + " has rank " +
                                   std::to_string(points.size() / 2) + ", the earlier uncertain scans' " +
                                   std::to_string(earlier_points / 2) + " (" +
                                   (first_uncertain_source_->empty() ? "" : "the first: " + *first_uncertain_source_ + "; ") +
                                   why + ")");
    };
    if (!first_uncertain_source_) first_uncertain_source_ = prepared.pose_covariance_source;
    if (params_.preprocess.pose_fusion == PoseFusion::kExpectedKernel) {
      expected_kernel_ = true;
      if (correlation_ == InputCorrelation::kTrajectory && motion_points_ && points.size() != motion_points_)
        throw refuse_rank(motion_points_, "--gp-input-correlation trajectory pairs their sigma points; scan or "
                                          "independent takes any");
      return points;
    }
    if (!uncertain_) {
      uncertain_ = true;
      for (size_t h = 1; h < points.size(); ++h) sets_.push_back(std::make_unique<TrainingData>(*sets_[0]));
    } else if (points.size() != sets_.size()) {
      throw refuse_rank(sets_.size(), "the expected sub-map pairs their sigma points");
    }
    return points;
  }

  // The expected kernel with correlated inputs: the scan's motion (none for a certain scan) and
  // each of its hits' and beams' link to it (kNoGroup filled in for the scans before the first
  // uncertain one).
  void add_motion(const std::vector<PoseSigmaPoint>& points, TrainingData& set) {
    set.hit_motion.resize(set.hits.size(), SharedMotion::kNoGroup);
    set.beam_motion.resize(set.beam_ends.size(), SharedMotion::kNoGroup);
    uint32_t motion = SharedMotion::kNoGroup;
    if (!points.empty()) {
      motion = static_cast<uint32_t>(motions_.size());
      motions_.emplace_back(obs_.origin, points, queries_.planar());
      motion_points_ = std::max(motion_points_, points.size());
    }
    set.hit_motion.insert(set.hit_motion.end(), obs_.hits.size(), motion);
    set.beam_motion.insert(set.beam_motion.end(), obs_.free_ends.size(), motion);
  }

  uint32_t ensure_slot(const BlockKey& key) {
    const uint32_t slot = cells_.ensure_slot(key);
    if (slot >= dirty_flag_.size()) dirty_flag_.resize(slot + 1, 0);
    return slot;
  }

  // Paper mode refuses what would change its covariance or how it is learned.
  void check_paper_mode(const GpomParams& p, const BuildParams& params) const {
    const auto refuse = [](const std::string& why) {
      return std::invalid_argument("--method gpom --gp-mode paper: " + why);
    };
    if (p.gp_covariance != "matern")
      throw refuse("its covariance is the paper's neural-network one with S learned; drop --gp-covariance " +
                   p.gp_covariance);
    if (p.gp_hyperparameters != "given")
      throw refuse("its hyper-parameters are learned as the paper's (--gp-train-scans, --gp-train-points); drop "
                   "--gp-hyperparameters " + p.gp_hyperparameters);
    if (params.preprocess.pose_fusion == PoseFusion::kExpectedKernel || p.gp_range_sigma > 0 || p.gp_bearing_sigma > 0)
      throw refuse("the expected kernel (--pose-fusion kernel, --gp-range-sigma, --gp-bearing-sigma) takes a "
                   "covariance of the distance, not the paper's neural-network one");
  }

  // Paper mode: S, s2 and sn maximise the likelihood of a sample of the first scans (IJRR sec. 3.2),
  // from S = diag(1, 1/l^2, ...), --gp-signal and --gp-noise.
  void learn_paper() {
    NeuralNetworkLearning options;
    options.dims = queries_.planar() ? 2 : 3;
    options.seed = kPaperTrainingSeed;
    GpHyperParams start = hp_;
    start.nn_sigma = neural_network_sigma_of_length(hp_.ell_m, options.dims);
    hp_ = learn_neural_network(first_scans_sample(*sets_[0], first_, train_points_, kPaperTrainingSeed), start,
                               options);
    hyperparameters_learned_ = true;
  }

  // What is learned when the map is first evaluated with observations: the covariance
  // (--gp-hyperparameters learn, or paper mode's), then wgpom's warp with it. Nothing observed
  // yet: learned later.
  void learn(const LocalModels& local_models) {
    if (paper_ && !hyperparameters_learned_) learn_paper();
    if (!(learn_hyperparameters_ && !hyperparameters_learned_) && !(warped_ && !warp_)) return;
    std::vector<BlockKey> blocks;
    for (const uint32_t slot : dirty_) blocks.push_back(cells_.key_of_slot(slot));
    std::vector<LocalModel> models = local_models.sample(queries_, blocks, kWarpStride, kMaxWarpModels, threads_);
    if (models.empty()) return;
    if (learn_hyperparameters_ && !hyperparameters_learned_) {
      std::vector<LocalModel> few;
      const size_t stride = (models.size() + kMaxHyperModels - 1) / kMaxHyperModels;
      for (size_t i = 0; i < models.size(); i += stride) few.push_back(models[i]);
      hp_ = learn_hyperparameters(few, hp_, HyperparameterLearning{});
      hyperparameters_learned_ = true;
    }
    if (warped_ && !warp_) warp_ = bgkmap::learn_warp(WarpTrainingSet(std::move(models), hp_), warp_learning_);
  }

  std::string prediction_phase() const { return name() + " prediction"; }

  // Every scan's hits and beam samples stay (with their k-d trees) for the whole build: a scan
  // whose points would take the process beyond the memory limit is refused before it is added.
  void require_training_memory() const {
    const bool motion_links = expected_kernel_ && correlation_ != InputCorrelation::kIndependent &&
                              params_.preprocess.pose_fusion == PoseFusion::kExpectedKernel;
    const double bytes =
        training_bytes(*sets_.front(), double(sets_.size()), obs_, beam_step_m_, expected_kernel_, motion_links);
    require_memory(bytes,
                   "gpom's training points (scan " + std::to_string(counts_.scans + 1) + ": " +
                       std::to_string(obs_.hits.size()) + " hits and their beams' samples)",
                   "give a shorter --max-range or a coarser --ds (or raise --max-memory)");
  }

  LocalModelRules model_rules() const {
    LocalModelRules rules;
    rules.neighbours = neighbours_;
    rules.reach_m = reach_m_;
    rules.expected_kernel = expected_kernel_;
    rules.centred = centred_;
    rules.correlation = correlation_;
    rules.motions = &motions_;
    rules.motion_points = motion_points_;
    return rules;
  }

  // Evaluates every cell of the dirty blocks, then refits the PLSC squashing.
  void flush() {
    if (dirty_.empty()) return;
    for (const auto& set : sets_) {
      set->hits.build();
      set->beam_samples.build();
    }
    std::sort(dirty_.begin(), dirty_.end(),
              [&](uint32_t a, uint32_t b) { return cells_.key_of_slot(a) < cells_.key_of_slot(b); });
    const LocalModels models(sets_, model_rules());
    learn(models);
    if (warped_ && !warp_) warp_ = TanhWarp{};  // no local model anywhere: every cell stays unknown
    // The hyper-parameters and the warp are learned on the plain kernel (their gradients are the
    // plain kernel's); the expected kernel then uses them. The device solves plain kernels of the
    // distance only.
    const bool planar = queries_.planar();
    if (expected_kernel_) kernel_.emplace(hp_, planar ? 2 : 3, planar ? kExpectedKernelOrder2d : kExpectedKernelOrder3d);
    const LabelWarp warp(warped_ ? &*warp_ : nullptr, quadrature_);
    const CellSolver solver(hp_, kernel_ ? &*kernel_ : nullptr, warp, models, paper_);
    const Evaluation evaluation{queries_, models, solver, cells_, dirty_, threads_, progress(), prediction_phase()};
    std::vector<std::vector<LooSample>> loo(dirty_.size());
    uint64_t pairs = 0;
    // Once the device has failed (its info().kind is then the CPU) every later flush stays here,
    // rather than gathering its models for a device that refuses them.
    const bool on_device =
        device_->info().kind == DeviceKind::kOpenCl && !kernel_ && hp_.covariance != GpCovariance::kNeuralNetwork;
    if (!on_device || !evaluate_on_device(evaluation, *device_, hp_, neighbours_, loo, pairs)) {
      for (auto& samples : loo) samples.clear();  // a failed device's part
      pairs = 0;
      evaluate_on_cpu(evaluation, loo, pairs);
    }
    if (paper_) fill_unreached_blocks(extent_.blocks(grid_, queries_, reach_m_), queries_, solver, cells_);
    for (const uint32_t slot : dirty_) dirty_flag_[slot] = 0;
    dirty_.clear();
    counts_.integrate.pairs_evaluated += pairs;
    counts_.integrate.pairs_within_support += pairs;
    calibration_.refit(loo, threads_);
  }

  BuildParams params_;
  Grid grid_;
  BlockStore<GpomCell> cells_;
  CellQueries queries_;  // where the cells are queried (in 2-D, the plane's layer)
  std::unique_ptr<LocalGpDevice> device_;  // kind kCpu: the CPU path solves the local models
  GpHyperParams hp_;
  size_t neighbours_;
  int threads_;
  double reach_m_ = 0, beam_step_m_ = 0;
  ScanPlane plane_;
  bool warped_;
  bool learn_hyperparameters_ = false, hyperparameters_learned_ = false;
  std::optional<TanhWarp> warp_;  // wgpom: learned at the first evaluation unless given
  WarpLearning warp_learning_;
  GaussHermite quadrature_{kQuadratureNodes};

  // The training data: one set, or once a scan carries a pose covariance one per sigma point
  // (behind pointers: a built tree refers to its set's points, which must not move).
  std::vector<std::unique_ptr<TrainingData>> sets_;
  // The expected kernel: how the inputs' displacements are correlated (--gp-input-correlation);
  // unless independent, each uncertain scan's motion, and the most sigma points of one.
  InputCorrelation correlation_ = InputCorrelation::kTrajectory;
  std::vector<ScanMotion> motions_;
  size_t motion_points_ = 0;
  bool uncertain_ = false;
  std::optional<std::string> first_uncertain_source_;  // where the first uncertain scan's covariance came from
  ScanObservations displaced_;  // obs_ under one sigma point
  // Inputs carry covariances: --pose-fusion kernel and some scan was uncertain, or sensor noise.
  bool expected_kernel_ = false;
  SensorNoise sensor_noise_;  // --gp-range-sigma, --gp-bearing-sigma
  bool centred_ = false;      // the neural-network covariance: local models centred at their query
  // --gp-mode paper: the IJRR model (the covariance's S learned in the world's frame on a sample of
  // the first train_scans_ scans, train_points_ points; the prior everywhere else in extent_).
  bool paper_ = false;
  uint64_t train_scans_ = 0;
  size_t train_points_ = 0;
  FirstScans first_;
  MappedExtent extent_;
  std::optional<ExpectedKernel> kernel_;  // set at each evaluation while expected_kernel_

  std::vector<uint8_t> dirty_flag_;   // per slot
  std::vector<uint32_t> dirty_;       // slots to evaluate at the next flush
  PlscCalibration calibration_;

  ScanObservations obs_;
  ScanBuckets buckets_;
  BuildCounts counts_;
  InsertTiming timing_;
};

}  // namespace

std::unique_ptr<MappingMethod> make_gpom_method(const BuildParams& params, const MethodParams& method_params,
                                                const BackendOptions& backend) {
  return std::make_unique<GpomMethod>(params, gpom_params(method_params), backend, false, std::nullopt);
}

std::unique_ptr<MappingMethod> make_wgpom_method(const BuildParams& params, const MethodParams& method_params,
                                                 const BackendOptions& backend, std::optional<TanhWarp> warp) {
  return std::make_unique<GpomMethod>(params, gpom_params(method_params), backend, true, std::move(warp));
}

}  // namespace bgkmap
