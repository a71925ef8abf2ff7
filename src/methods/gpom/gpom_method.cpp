// --method gpom: Gaussian process occupancy maps (O'Callaghan & Ramos, IJRR 2012).
//
// Training data: every hit (label +1) and every beam's free segment (label -1). For a query the
// free observation of a beam is the segment's point nearest to the query (the paper's sensor
// model; the line-integral variant needs a numerical integral of the covariance per pair and
// buys nothing the nearest point does not give for the neighbours used here). Each query (a
// cell centre; in 2-D at the scans' plane) has its own local model: its k nearest hits and the
// nearest points of its k nearest beams (k = --gp-neighbours, the paper's 30), found in k-d trees
// (nanoflann) over every scan so far. GP regression on the local model (Matern 3/2, the sparse
// kernel, the squared exponential or the neural-network covariance, gp_regression) gives the
// latent mean and variance stored per cell (the neural-network covariance is not stationary: a
// local model's inputs are taken relative to its query, so the map does not move with the
// world's origin; it is solved on the CPU whatever the back end); occupancy is
// their PLSC squashing with alpha, beta fitted to leave-one-out predictions of sampled local
// models (plsc). Scans only mark the blocks near their observations dirty; a dirty block's cells
// are (re)evaluated when the map is next read (finish, write, estimate), in parallel over blocks
// (OpenMP). Cells farther than the length scale from every hit and beam stay unknown.
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
#include <omp.h>

#include <nanoflann.hpp>

#include <algorithm>
#include <atomic>
#include <limits>
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
#include "core/parallel_errors.hpp"
#include "core/progress_counter.hpp"
#include "core/stage_clock.hpp"
#include "io/probability_map.hpp"
#include "integrate/local_gp_batch.hpp"
#include "map/block_store.hpp"
#include "methods/gp/expected_kernel.hpp"
#include "methods/gp/gp_hyperparameters.hpp"
#include "methods/gp/gp_regression.hpp"
#include "methods/gpom/gpom_method.hpp"
#include "methods/gp/scan_plane.hpp"
#include "methods/gp/plsc.hpp"
#include "methods/gp/uncertain_inputs.hpp"
#include "methods/wgpom/warped_gp.hpp"

namespace bgkmap {

namespace {

// Every this many evaluated cells of a block (its first included) also give their local model's
// leave-one-out predictions to the PLSC fit; the pool is thinned by half beyond kMaxLooSamples.
constexpr int kLooEvery = 64;
constexpr size_t kMaxLooSamples = 100000;
// wgpom: the warp is learned from the local models of every kWarpStride-th cell of the dirty
// blocks (a prime, so the sample does not line up with the rows of a block), at most
// kMaxWarpModels of them; kQuadratureNodes Gauss-Hermite nodes unwarp a prediction.
// --gp-hyperparameters learn: the covariance is learned from the first kMaxHyperModels of them
// (evenly spread), before the warp.
constexpr int kWarpStride = 61;
constexpr size_t kMaxWarpModels = 256;
constexpr size_t kMaxHyperModels = 64;
constexpr int kQuadratureNodes = 20;

// nanoflann's dataset adaptor over a growing vector of points.
struct PointCloud {
  std::vector<Vec3f> points;
  size_t kdtree_get_point_count() const { return points.size(); }
  float kdtree_get_pt(size_t i, size_t dim) const {
    const Vec3f& p = points[i];
    return dim == 0 ? p.x : (dim == 1 ? p.y : p.z);
  }
  template <class Box>
  bool kdtree_get_bbox(Box&) const { return false; }
};
using PointTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, PointCloud>, PointCloud, 3,
                                                      uint32_t>;

// A k-d tree over points appended scan by scan, rebuilt (one static tree searches faster than
// nanoflann's dynamic forest) when it is next searched after points came.
class GrowingTree {
 public:
  GrowingTree() = default;
  // A copy holds the points; its tree is built when it is next searched (the tree refers to its
  // own cloud, so it is neither copied nor moved).
  GrowingTree(const GrowingTree& other) : cloud_(other.cloud_) {}
  GrowingTree& operator=(const GrowingTree&) = delete;
  void add(const std::vector<Vec3f>& points) { cloud_.points.insert(cloud_.points.end(), points.begin(), points.end()); }
  void build() {
    if (tree_ && built_size_ == cloud_.points.size()) return;
    tree_ = std::make_unique<PointTree>(3, cloud_, nanoflann::KDTreeSingleIndexAdaptorParams(16));
    tree_->buildIndex();
    built_size_ = cloud_.points.size();
    build_count_ = next_build_count();
  }
  size_t size() const { return cloud_.points.size(); }
  size_t capacity() const { return cloud_.points.capacity(); }
  const Vec3f& operator[](size_t i) const { return cloud_.points[i]; }
  // The (up to) k nearest points, nearest first: ids and squared distances. After build().
  // Queries come cell by cell, so the calling thread's previous search of this tree for k bounds
  // this one: its k nearest lie within (its k-th distance + |q - q_prev|) of q, and a search
  // that starts from that radius prunes from its first leaf. The result is the unbounded
  // search's (the same points visited in the same order, fewer branches); a bound that finds
  // fewer than k (rounding) repeats the search unbounded.
  size_t nearest(const Vec3d& q, size_t k, std::vector<uint32_t>& ids, std::vector<float>& d2) const {
    ids.resize(k);
    d2.resize(k);
    const float query[3] = {static_cast<float>(q.x), static_cast<float>(q.y), static_cast<float>(q.z)};
    size_t found = 0;
    if (!cloud_.points.empty()) {
      // A few trees and k per thread (gpom searches two trees with two k per query).
      thread_local PreviousSearch previous[4];
      thread_local unsigned replaced = 0;
      PreviousSearch* last = nullptr;
      for (PreviousSearch& p : previous)
        if (p.tree == this && p.build == build_count_ && p.k == k) last = &p;
      if (last && k <= cloud_.points.size()) {
        const double dx = q.x - last->q.x, dy = q.y - last->q.y, dz = q.z - last->q.z;
        const float radius = static_cast<float>((std::sqrt(double(last->kth_d2)) + std::sqrt(dx * dx + dy * dy + dz * dz)) *
                                                    (1 + 1e-5) + 1e-6);
        found = search(query, k, radius * radius, ids, d2);
      }
      if (!last) last = &previous[replaced++ % 4];
      if (found < std::min(k, cloud_.points.size())) found = search(query, k, std::numeric_limits<float>::max(), ids, d2);
      *last = {found == k ? this : nullptr, build_count_, k, q, found == k ? d2[k - 1] : 0.0f};
    }
    ids.resize(found);
    d2.resize(found);
    return found;
  }

 private:
  struct PreviousSearch {
    const GrowingTree* tree = nullptr;
    uint64_t build = 0;
    size_t k = 0;
    Vec3d q;
    float kth_d2 = 0;
  };

  // The k nearest within sqrt(worst_d2) (all of them when it is the float maximum).
  size_t search(const float query[3], size_t k, float worst_d2, std::vector<uint32_t>& ids, std::vector<float>& d2) const {
    nanoflann::KNNResultSet<float, uint32_t> result(k);
    result.init(ids.data(), d2.data());
    d2[k - 1] = worst_d2;  // the result set's initial worst distance: the search's starting radius
    tree_->findNeighbors(result, query, nanoflann::SearchParams());
    return result.size();
  }

  PointCloud cloud_;  // the tree keeps a reference to it
  std::unique_ptr<PointTree> tree_;
  size_t built_size_ = 0;
  uint64_t build_count_ = 0;  // which build of which tree a thread's previous search used
  static uint64_t next_build_count() {
    static std::atomic<uint64_t> count{0};
    return ++count;
  }
};

double distance2(const Vec3d& a, const Vec3d& b) {
  const double dx = a.x - b.x, dy = a.y - b.y, dz = a.z - b.z;
  return dx * dx + dy * dy + dz * dz;
}
Vec3d to_d(const Vec3f& p) { return {p.x, p.y, p.z}; }

// The training data of every scan so far, as one pose hypothesis places it.
struct TrainingData {
  GrowingTree hits, beam_samples;
  std::vector<Vec3f> beam_origins, beam_ends;  // per beam: its free segment
  std::vector<uint32_t> sample_beam;           // per beam sample: its beam
  // Under the expected kernel, once a scan is uncertain: per hit and per beam (zero for certain scans).
  std::vector<PositionCovariance> hit_cov;
  std::vector<BeamCovariance> beam_cov;
  // Under the expected kernel with correlated inputs: per hit and per beam its scan's motion
  // (GpomMethod::motions_), SharedMotion::kNoGroup for a certain scan.
  std::vector<uint32_t> hit_motion, beam_motion;
};

// The moment-matched Gaussian of an equal-weight mixture of predictions.
GpPrediction mixture_moments(const std::vector<GpPrediction>& parts) {
  const double n = double(parts.size());
  GpPrediction m;
  for (const GpPrediction& p : parts) m.mean += p.mean / n;
  for (const GpPrediction& p : parts) m.variance += (p.variance + (p.mean - m.mean) * (p.mean - m.mean)) / n;
  return m;
}

struct GpomCell {
  double mean = 0, variance = 0;
  bool known = false;
};

class GpomMethod final : public MappingMethod {
 public:
  // warped: wgpom, with `warp` as its warp if given, else learned at the first evaluation.
  GpomMethod(const BuildParams& params, const GpomParams& method_params, const BackendOptions& backend, bool warped,
             std::optional<TanhWarp> warp)
      : params_(params), grid_(params.grid), cells_(grid_), neighbours_(static_cast<size_t>(method_params.gp_neighbours)),
        threads_(backend.threads > 0 ? backend.threads : omp_get_max_threads()), warped_(warped), warp_(std::move(warp)) {
    warp_learning_.terms = static_cast<int>(method_params.wgp_terms);
    learn_hyperparameters_ = method_params.gp_hyperparameters == "learn";
    hp_.covariance = method_params.gp_covariance == "sparse" ? GpCovariance::kSparse
                     : method_params.gp_covariance == "se" ? GpCovariance::kSquaredExponential
                     : method_params.gp_covariance == "nn" ? GpCovariance::kNeuralNetwork
                                                           : GpCovariance::kMatern32;
    centred_ = hp_.covariance == GpCovariance::kNeuralNetwork;
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
    device_ = make_local_gp_device(backend, device_note_);
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
        displace_observations(obs_, points[h], planar_, displaced_);
        obs = &displaced_;
      }
      if (expected_kernel_) {  // the certain scans before the first uncertain one: zero
        sets_[h]->hit_cov.resize(sets_[h]->hits.size());
        sets_[h]->beam_cov.resize(sets_[h]->beam_ends.size());
        // Of the data this copy trains on: a displaced copy's own returns (displace_observations
        // may have dropped some), seen along its displaced beams.
        append_input_covariances(*obs, pose_kernel ? points : std::vector<PoseSigmaPoint>{}, planar_, sensor_noise_,
                                 sets_[h]->hit_cov, sets_[h]->beam_cov);
        if (pose_kernel && correlation_ != InputCorrelation::kIndependent) add_motion(points, *sets_[h]);
      }
      add_training(*obs, *sets_[h]);
      if (h > 0 && points.empty()) continue;  // the same observations: the same cells
      // The cells whose local model may change: those within reach of this scan's hits and beams
      // (the bucketing radius adds a cell, as 2-D queries sit at the plane, not the cell centre).
      Clock::time_point t = Clock::now();
      bucket_scan(grid_, static_cast<float>(reach_m_ + grid_.resolution()), *obs, buckets_, 1, "--gp-length");
      bucket_s += seconds_since(t);
      t = Clock::now();
      for (const BlockWork& work : buckets_.blocks) {
        if (planar_ && !block_holds_plane(work.key)) continue;
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
        if (cell.known) visit(c, plsc_probability(cell.mean, cell.variance, plsc_));
      });
    };
    write_probability_map(file, grid_.resolution(), params_.classify, cells, ot_values);
  }

  std::optional<CellEstimate> estimate_cell(double x, double y, double z) override {
    flush();
    const GpomCell* cell = cells_.find(grid_.cell_of(x, y, z));
    if (!cell || !cell->known) return std::nullopt;
    CellEstimate e;
    e.occupancy = plsc_probability(cell->mean, cell->variance, plsc_);
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
    if (hyperparameters_learned_) {
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
                               std::to_string(planar_ ? kExpectedKernelOrder2d : kExpectedKernelOrder3d) +
                               " nodes per axis)";
      if (!motions_.empty())
        description += correlation_ == InputCorrelation::kTrajectory
                           ? "; inputs moving with their scans, the scans' sigma points paired"
                           : "; inputs moving with their scans, the scans independent";
      if (device_) description += ", solved on the CPU";
      return {"cpu", description, threads_, device_note_};
    }
    if (centred_) {
      description += "; neural-network covariance, each local model centred at its query";
      if (device_) description += ", solved on the CPU";
      return {"cpu", description, threads_, device_note_};
    }
    if (device_) {
      const BackendInfo device = device_->info();
      if (device.name == "opencl") return {"opencl", description + "; local models solved on " + device.device, threads_, ""};
      return {"cpu", description, threads_, device.note};
    }
    return {"cpu", description, threads_, device_note_};
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
    planar_ = plane_.planar();
    plane_z_ = plane_.z();
    plane_cell_z_ = grid_.cell_of(0, 0, plane_z_).z;
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
      motions_.emplace_back(obs_.origin, points, planar_);
      motion_points_ = std::max(motion_points_, points.size());
    }
    set.hit_motion.insert(set.hit_motion.end(), obs_.hits.size(), motion);
    set.beam_motion.insert(set.beam_motion.end(), obs_.free_ends.size(), motion);
  }

  // Appends a scan's hits and beams (already placed by its hypothesis) to `set`.
  void add_training(const ScanObservations& obs, TrainingData& set) const {
    set.hits.add(obs.hits);
    std::vector<Vec3f> samples;
    for (const Vec3f& end : obs.free_ends) {
      const uint32_t beam = static_cast<uint32_t>(set.beam_ends.size());
      set.beam_ends.push_back(end);
      set.beam_origins.push_back(obs.origin);
      // The midpoints of equal pieces no longer than beam_step_m_: every point of the beam is
      // within beam_step_m_ / 2 of a sample (nearest_beams), and the scan's beams share no sample
      // at the origin (a k-d tree cannot split a pile of equal points).
      const Vec3d a = to_d(obs.origin), b = to_d(end);
      const int pieces = beam_pieces(a, b);
      for (int i = 0; i < pieces; ++i) {
        const double t = (i + 0.5) / pieces;
        samples.push_back({static_cast<float>(a.x + t * (b.x - a.x)), static_cast<float>(a.y + t * (b.y - a.y)),
                           static_cast<float>(a.z + t * (b.z - a.z))});
        set.sample_beam.push_back(beam);
      }
    }
    set.beam_samples.add(samples);
  }

  bool block_holds_plane(const BlockKey& key) const {
    const int n = grid_.cells_per_side();
    return plane_cell_z_ >= key.z * n && plane_cell_z_ < (key.z + 1) * n;
  }

  uint32_t ensure_slot(const BlockKey& key) {
    const uint32_t slot = cells_.ensure_slot(key);
    if (slot >= dirty_flag_.size()) dirty_flag_.resize(slot + 1, 0);
    return slot;
  }

  // The query's k nearest beams, nearest first, by their segment's exact distance to q, among the
  // candidates: the beams of the query's 4k nearest beam samples. Every point of a beam lies
  // within beam_step_m_ / 2 of one of its samples, so a beam left out is at most that much nearer
  // than the farthest candidate sample; with at most 4k samples in all, none is left out.
  // A candidate beam: its nearest point to the query, at fraction t, d2 away.
  struct NearBeam {
    double d2;
    uint32_t beam;
    double t;
    Vec3d point;
    bool operator<(const NearBeam& o) const { return d2 < o.d2 || (d2 == o.d2 && beam < o.beam); }
  };
  void nearest_beams(const TrainingData& set, const Vec3d& q, std::vector<NearBeam>& beams, std::vector<uint32_t>& ids,
                     std::vector<float>& d2) const {
    const size_t found = set.beam_samples.nearest(q, 4 * neighbours_, ids, d2);
    beams.clear();
    for (size_t i = 0; i < found; ++i) beams.push_back({0.0, set.sample_beam[ids[i]], 0.0, {}});
    std::sort(beams.begin(), beams.end(), [](const NearBeam& a, const NearBeam& b) { return a.beam < b.beam; });
    beams.erase(std::unique(beams.begin(), beams.end(), [](const NearBeam& a, const NearBeam& b) { return a.beam == b.beam; }),
                beams.end());
    for (NearBeam& b : beams) {
      b.t = beam_fraction(set, q, b.beam);
      b.point = point_on_beam(set, b.beam, b.t);
      b.d2 = distance2(q, b.point);
    }
    std::sort(beams.begin(), beams.end());
    if (beams.size() > neighbours_) beams.resize(neighbours_);
  }

  // The fraction t along the beam (origin 0, end 1) of its point nearest to q.
  double beam_fraction(const TrainingData& set, const Vec3d& q, uint32_t beam) const {
    const Vec3d a = to_d(set.beam_origins[beam]), b = to_d(set.beam_ends[beam]);
    const Vec3d ab{b.x - a.x, b.y - a.y, b.z - a.z};
    const double len2 = ab.x * ab.x + ab.y * ab.y + ab.z * ab.z;
    return len2 > 0 ? std::clamp(((q.x - a.x) * ab.x + (q.y - a.y) * ab.y + (q.z - a.z) * ab.z) / len2, 0.0, 1.0) : 0.0;
  }
  Vec3d point_on_beam(const TrainingData& set, uint32_t beam, double t) const {
    const Vec3d a = to_d(set.beam_origins[beam]), b = to_d(set.beam_ends[beam]);
    return {a.x + t * (b.x - a.x), a.y + t * (b.y - a.y), a.z + t * (b.z - a.z)};
  }

  struct Scratch {
    std::vector<uint32_t> ids;
    std::vector<float> d2;
    std::vector<NearBeam> beams;
    std::vector<Vec3d> train;
    std::vector<PositionCovariance> cov;  // expected kernel: per training input
    SharedMotion shared;                  // expected kernel with correlated inputs: their motions
    std::vector<PositionCovariance> pairs;  // ... and the covariances of their differences
    std::vector<double> labels, warped;
    std::vector<GpPrediction> parts;  // per hypothesis
    std::vector<LocalModel> models;   // per hypothesis
    std::vector<std::vector<PositionCovariance>> model_cov;  // expected kernel: per hypothesis, per input
    std::vector<std::vector<PositionCovariance>> model_pairs;  // ... per hypothesis, per pair of inputs
  };

  // Where a local model's inputs are measured from: its query for the neural-network covariance
  // (not stationary), the world's origin otherwise (x - 0 is x: the stationary maps unchanged).
  Vec3d model_origin(const Vec3d& q) const { return centred_ ? q : Vec3d{0, 0, 0}; }
  Vec3d in_model(const Vec3d& p, const Vec3d& q) const {
    const Vec3d o = model_origin(q);
    return {p.x - o.x, p.y - o.y, p.z - o.z};
  }

  // The query's local model in `set` in s.train / s.labels (inputs in_model): false when no hit
  // and no beam is within reach.
  bool local_model(const TrainingData& set, const Vec3d& q, Scratch& s) const {
    s.train.clear();
    s.labels.clear();
    s.cov.clear();
    s.pairs.clear();
    const bool correlated = expected_kernel_ && !motions_.empty();
    if (correlated) {
      s.shared.points = motion_points_;
      s.shared.group.clear();
      s.shared.weight.clear();
      s.shared.moves.clear();
    }
    double nearest2 = INFINITY;
    set.hits.nearest(q, neighbours_, s.ids, s.d2);
    for (const uint32_t id : s.ids) {
      const Vec3d hit = to_d(set.hits[id]);
      s.train.push_back(in_model(hit, q));
      s.labels.push_back(1.0);
      if (expected_kernel_) s.cov.push_back(set.hit_cov[id]);
      if (correlated) add_shared_motion(set.hit_motion[id], hit, Vec3d{}, s.shared);
      nearest2 = std::min(nearest2, distance2(q, hit));
    }
    if (set.beam_samples.size() > 0) nearest_beams(set, q, s.beams, s.ids, s.d2);
    else s.beams.clear();
    for (const NearBeam& b : s.beams) {
      s.train.push_back(in_model(b.point, q));
      s.labels.push_back(-1.0);
      if (expected_kernel_) {
        // Inside the segment the nearest point moves only across it (across_segment).
        Vec3d beam_direction{};
        PositionCovariance c = set.beam_cov[b.beam].at(b.t);
        if (b.t > 0 && b.t < 1) {
          beam_direction = unit_direction(to_d(set.beam_origins[b.beam]), to_d(set.beam_ends[b.beam]));
          c = across_segment(c, beam_direction);
        }
        s.cov.push_back(c);
        if (correlated) add_shared_motion(set.beam_motion[b.beam], b.point, beam_direction, s.shared);
      }
      nearest2 = std::min(nearest2, b.d2);
    }
    if (correlated) difference_covariances(s.cov, s.shared, s.pairs);
    return nearest2 <= reach_m_ * reach_m_;
  }

  // An input's centred displacements under its scan's sigma points (zero past their number;
  // their part along `beam_direction` removed: a segment's inner point, zero for a hit) and its
  // group: its scan's motion, or one group for every uncertain scan when they are paired
  // (trajectory).
  void add_shared_motion(uint32_t motion, const Vec3d& p, const Vec3d& beam_direction, SharedMotion& shared) const {
    const size_t first = shared.moves.size();
    shared.moves.resize(first + shared.points);
    if (motion == SharedMotion::kNoGroup) {
      shared.group.push_back(SharedMotion::kNoGroup);
      shared.weight.push_back(0.0);
      return;
    }
    const ScanMotion& m = motions_[motion];
    Vec3d* d = &shared.moves[first];
    m.displacements(p, d);
    Vec3d mean;
    for (size_t h = 0; h < m.size(); ++h) {
      const Vec3d& u = beam_direction;
      const double along = d[h].x * u.x + d[h].y * u.y + d[h].z * u.z;
      d[h] = {d[h].x - along * u.x, d[h].y - along * u.y, d[h].z - along * u.z};
      const double w = m.weights()[h];
      mean = {mean.x + w * d[h].x, mean.y + w * d[h].y, mean.z + w * d[h].z};
    }
    for (size_t h = 0; h < m.size(); ++h) d[h] = {d[h].x - mean.x, d[h].y - mean.y, d[h].z - mean.z};
    shared.group.push_back(correlation_ == InputCorrelation::kTrajectory ? 0 : motion);
    shared.weight.push_back(m.weights()[0]);
  }

  static Vec3d unit_direction(const Vec3d& a, const Vec3d& b) {
    const double n = std::sqrt(distance2(a, b));
    return {(b.x - a.x) / n, (b.y - a.y) / n, (b.z - a.z) / n};
  }

  Vec3d query_of(const CellIndex& c) const {
    Vec3d q = grid_.cell_center_d(c);
    if (planar_) q.z = plane_z_;
    return q;
  }

  // Calls visit(local, query) for every mapped cell of a block (only the plane's layer in 2-D),
  // `stride` cells apart (by index in the block).
  template <class Visit>
  void for_each_query(uint32_t slot, int stride, Visit&& visit) const {
    const int n = grid_.cells_per_side();
    for (int local = 0; local < grid_.cells_per_block(); local += stride) {
      const CellIndex c = grid_.cell_at(cells_.key_of_slot(slot), local);
      if (planar_ && c.z != plane_cell_z_) {  // skip to the plane's layer: only it is mapped
        const int layer_start = (plane_cell_z_ - cells_.key_of_slot(slot).z * n) * n * n;
        if (local > layer_start) break;
        local = layer_start - stride;
        continue;
      }
      visit(local, query_of(c));
    }
  }

  // The labels the GP models: y (gpom) or the warped g(y) (wgpom), in s.warped.
  const std::vector<double>& modelled_labels(Scratch& s) const {
    if (!warped_) return s.labels;
    s.warped.resize(s.labels.size());
    for (size_t i = 0; i < s.labels.size(); ++i) s.warped[i] = warp_->value(s.labels[i]);
    return s.warped;
  }
  // A latent prediction of the modelled labels in label space.
  GpPrediction label_space(const GpPrediction& latent) const {
    return warped_ ? unwarp_prediction(latent.mean, latent.variance, *warp_, quadrature_) : latent;
  }

  // The local models of every kWarpStride-th cell of the dirty blocks (under every hypothesis),
  // evenly thinned to at most `most`, in block order.
  std::vector<LocalModel> sample_local_models(size_t most) const {
    std::vector<std::vector<LocalModel>> sampled(dirty_.size());
    ParallelErrors errors;
#pragma omp parallel for schedule(dynamic) num_threads(threads_)
    for (int64_t b = 0; b < static_cast<int64_t>(dirty_.size()); ++b)
      errors.run([&] {
        Scratch s;
        for_each_query(dirty_[b], kWarpStride, [&](int, const Vec3d& q) {
          for (const auto& set : sets_)
            if (local_model(*set, q, s)) sampled[b].push_back({s.train, s.labels});
        });
      });
    errors.rethrow();
    std::vector<LocalModel> models;
    for (std::vector<LocalModel>& block : sampled)
      for (LocalModel& model : block) models.push_back(std::move(model));
    const size_t stride = (models.size() + most - 1) / most;
    std::vector<LocalModel> kept;
    for (size_t i = 0; i < models.size(); i += std::max<size_t>(stride, 1)) kept.push_back(std::move(models[i]));
    return kept;
  }

  // What is learned when the map is first evaluated with observations: the covariance
  // (--gp-hyperparameters learn), then wgpom's warp with it. Nothing observed yet: learned later.
  void learn() {
    if (!(learn_hyperparameters_ && !hyperparameters_learned_) && !(warped_ && !warp_)) return;
    std::vector<LocalModel> models = sample_local_models(kMaxWarpModels);
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

  // The local models of a query, one per hypothesis, in s.models: false (none kept) when some
  // hypothesis has no data within its reach, the cell then unknown.
  bool local_models(const Vec3d& q, Scratch& s) const {
    s.models.resize(sets_.size());
    s.model_cov.resize(sets_.size());
    s.model_pairs.resize(sets_.size());
    for (size_t h = 0; h < sets_.size(); ++h) {
      if (!local_model(*sets_[h], q, s)) return false;
      s.models[h].train.swap(s.train);
      s.models[h].labels.swap(s.labels);
      s.model_cov[h].swap(s.cov);
      s.model_pairs[h].swap(s.pairs);
    }
    return true;
  }

  // The leave-one-out samples of a cell's local models (every kLooEvery-th evaluated cell of a block).
  void sample_leave_one_out(const Scratch& s, std::vector<LooSample>& out) const {
    Scratch warped;
    for (size_t h = 0; h < s.models.size(); ++h) {
      const LocalModel& model = s.models[h];
      warped.labels = model.labels;
      const InputUncertainty uncertain{&s.model_cov[h], kernel_ ? &*kernel_ : nullptr,
                                           s.model_pairs[h].empty() ? nullptr : &s.model_pairs[h]};
      const std::vector<GpPrediction> held_out =
          gp_leave_one_out(model.train, modelled_labels(warped), hp_, kernel_ ? &uncertain : nullptr);
      for (size_t i = 0; i < held_out.size(); ++i) {
        const GpPrediction sample = label_space(held_out[i]);
        out.push_back({model.labels[i], sample.mean, sample.variance});
      }
    }
  }

  // A known cell from its hypotheses' latent predictions.
  GpomCell cell_of(const std::vector<GpPrediction>& latent, Scratch& s) const {
    s.parts.clear();
    for (const GpPrediction& p : latent) s.parts.push_back(label_space(p));
    const GpPrediction p = s.parts.size() == 1 ? s.parts[0] : mixture_moments(s.parts);
    return {p.mean, p.variance, true};
  }

  // Every cell of the dirty blocks, its local models solved here (Eigen), in parallel over blocks.
  void evaluate_on_cpu(std::vector<std::vector<LooSample>>& loo, uint64_t& pairs) {
    uint64_t evaluated_pairs = 0;
    ParallelErrors errors;
    ProgressCounter counter(progress(), prediction_phase(), "blocks", dirty_.size());
#pragma omp parallel for schedule(dynamic) num_threads(threads_) reduction(+ : evaluated_pairs)
    for (int64_t b = 0; b < static_cast<int64_t>(dirty_.size()); ++b)
      errors.run([&] {
        Scratch s;
        std::vector<GpPrediction> latent;
        GpomCell* cells = cells_.block(dirty_[b]);
        int evaluated = 0;
        for_each_query(dirty_[b], 1, [&](int local, const Vec3d& q) {
          if (!local_models(q, s)) {
            cells[local] = GpomCell{};
            return;
          }
          if (evaluated++ % kLooEvery == 0) sample_leave_one_out(s, loo[b]);
          latent.clear();
          for (size_t h = 0; h < s.models.size(); ++h) {
            const LocalModel& model = s.models[h];
            s.labels = model.labels;
            const InputUncertainty uncertain{&s.model_cov[h], kernel_ ? &*kernel_ : nullptr,
                                             s.model_pairs[h].empty() ? nullptr : &s.model_pairs[h]};
            latent.push_back(
                gp_predict(model.train, modelled_labels(s), {in_model(q, q)}, hp_, kernel_ ? &uncertain : nullptr)[0]);
            evaluated_pairs += model.train.size();
          }
          cells[local] = cell_of(latent, s);
        });
        counter.add();
      });
    errors.rethrow();
    counter.finish();
    pairs += evaluated_pairs;
  }

  // On the device: chunks of dirty blocks whose local models are gathered on the host (in parallel
  // over blocks), solved in one batch, and stored as the CPU path stores them. When the device
  // fails (its info().note says why), every block is evaluated on the CPU instead.
  void evaluate_on_device(std::vector<std::vector<LooSample>>& loo, uint64_t& pairs) {
    constexpr size_t kBlocksPerBatch = 64;
    const int max_n = static_cast<int>(2 * neighbours_);
    const LocalGpCovariance covariance{static_cast<int>(hp_.covariance), hp_.ell_m, hp_.signal_var,
                                       hp_.noise_std * hp_.noise_std};
    ProgressCounter counter(progress(), prediction_phase(), "blocks", dirty_.size());
    for (size_t first = 0; first < dirty_.size(); first += kBlocksPerBatch) {
      const size_t last = std::min(dirty_.size(), first + kBlocksPerBatch);
      // Per block: its batch of models and, per cell, its first model (-1: unknown).
      std::vector<LocalGpBatch> batches(last - first);
      std::vector<std::vector<int32_t>> first_model(last - first);
      ParallelErrors errors;
#pragma omp parallel for schedule(dynamic) num_threads(threads_)
      for (int64_t b = static_cast<int64_t>(first); b < static_cast<int64_t>(last); ++b)
        errors.run([&] {
          Scratch s;
          LocalGpBatch& batch = batches[b - first];
          batch.max_n = max_n;
          std::vector<int32_t>& model_of = first_model[b - first];
          model_of.assign(static_cast<size_t>(grid_.cells_per_block()), -1);
          int evaluated = 0;
          for_each_query(dirty_[b], 1, [&](int local, const Vec3d& q) {
            if (!local_models(q, s)) return;
            if (evaluated++ % kLooEvery == 0) sample_leave_one_out(s, loo[b]);
            model_of[local] = static_cast<int32_t>(batch.size());
            for (const LocalModel& model : s.models) {
              s.labels = model.labels;
              batch.add(model.train, modelled_labels(s), q);
            }
          });
        });
      errors.rethrow();
      LocalGpBatch all;
      all.max_n = max_n;
      for (const LocalGpBatch& batch : batches) all.append(batch);
      std::vector<double> mean(all.size()), variance(all.size());
      if (!device_->predict(all, covariance, mean.data(), variance.data())) {
        for (auto& samples : loo) samples.clear();
        pairs = 0;
        evaluate_on_cpu(loo, pairs);
        return;
      }
      size_t offset = 0;
      for (size_t b = first; b < last; ++b) {
        Scratch s;
        std::vector<GpPrediction> latent(sets_.size());
        GpomCell* cells = cells_.block(dirty_[b]);
        const std::vector<int32_t>& model_of = first_model[b - first];
        for (size_t local = 0; local < model_of.size(); ++local) {
          if (model_of[local] < 0) {
            cells[local] = GpomCell{};
            continue;
          }
          for (size_t h = 0; h < sets_.size(); ++h) {
            const size_t m = offset + static_cast<size_t>(model_of[local]) + h;
            if (!std::isfinite(mean[m])) throw GpNotPositiveDefinite();
            latent[h].mean = mean[m];
            latent[h].variance = variance[m];
            pairs += static_cast<uint64_t>(all.count[m]);
          }
          cells[local] = cell_of(latent, s);
        }
        offset += batches[b - first].size();
      }
      counter.add(last - first);
    }
    counter.finish();
  }

  std::string prediction_phase() const { return name() + " prediction"; }

  // Evaluates every cell of the dirty blocks, then refits the PLSC squashing.
  void flush() {
    if (dirty_.empty()) return;
    for (const auto& set : sets_) {
      set->hits.build();
      set->beam_samples.build();
    }
    std::sort(dirty_.begin(), dirty_.end(),
              [&](uint32_t a, uint32_t b) { return cells_.key_of_slot(a) < cells_.key_of_slot(b); });
    learn();
    if (warped_ && !warp_) warp_ = TanhWarp{};  // no local model anywhere: every cell stays unknown
    // The hyper-parameters and the warp are learned on the plain kernel (their gradients are the
    // plain kernel's); the expected kernel then uses them. The device solves plain kernels of the
    // distance only.
    if (expected_kernel_) kernel_.emplace(hp_, planar_ ? 2 : 3, planar_ ? kExpectedKernelOrder2d : kExpectedKernelOrder3d);
    std::vector<std::vector<LooSample>> loo(dirty_.size());
    uint64_t pairs = 0;
    // Once the device has failed (its info() then names the CPU) every later flush stays here,
    // rather than gathering its models for a device that refuses them.
    if (device_ && device_->info().name == "opencl" && !kernel_ && !centred_) evaluate_on_device(loo, pairs);
    else evaluate_on_cpu(loo, pairs);
    for (const uint32_t slot : dirty_) dirty_flag_[slot] = 0;
    dirty_.clear();
    counts_.integrate.pairs_evaluated += pairs;
    counts_.integrate.pairs_within_support += pairs;
    for (const std::vector<LooSample>& samples : loo) loo_pool_.insert(loo_pool_.end(), samples.begin(), samples.end());
    while (loo_pool_.size() > kMaxLooSamples) {
      size_t kept = 0;
      for (size_t i = 0; i < loo_pool_.size(); i += 2) loo_pool_[kept++] = loo_pool_[i];
      loo_pool_.resize(kept);
    }
    plsc_ = fit_plsc(loo_pool_, plsc_, threads_);
  }

  BuildParams params_;
  Grid grid_;
  BlockStore<GpomCell> cells_;
  std::unique_ptr<LocalGpDevice> device_;  // null: the CPU path solves the local models
  std::string device_note_;                // why not the OpenCL device that was asked for
  GpHyperParams hp_;
  size_t neighbours_;
  int threads_;
  int beam_pieces(const Vec3d& a, const Vec3d& b) const {
    return std::max(1, static_cast<int>(std::ceil(std::sqrt(distance2(a, b)) / beam_step_m_)));
  }
  // Every scan's hits and beam samples stay (with their k-d trees) for the whole build: a scan
  // whose points would take the process beyond the memory limit is refused before it is added.
  // A growing array holds its old and new buffers for a moment, so its doubling costs the whole
  // new buffer; each k-d tree keeps an index and nodes (about 10 bytes a point), and is rebuilt
  // with its new index (4 bytes a point) made while the old tree still stands.
  void require_training_memory() const {
    constexpr double kTreeBytesPerPoint = 10, kTreeIndexBytesPerPoint = 4;
    const Vec3d a = to_d(obs_.origin);
    double samples = 0;
    for (const Vec3f& end : obs_.free_ends) samples += beam_pieces(a, to_d(end));
    const double hits = double(obs_.hits.size()), beams = double(obs_.free_ends.size());
    const auto growth = [](size_t size, size_t capacity, double more, size_t element_bytes) {
      const double needed = double(size) + more;
      return needed > double(capacity) ? std::max(2.0 * double(capacity), needed) * double(element_bytes) : 0.0;
    };
    // Every hypothesis' copy grows alike.
    const TrainingData& d = *sets_.front();
    const double copies = double(sets_.size());
    // The expected kernel's covariances, from the first uncertain scan on (which fills in the
    // earlier scans' zeros).
    const double covariances =
        expected_kernel_ ? growth(d.hit_cov.size(), d.hit_cov.capacity(), double(d.hits.size() - d.hit_cov.size()) + hits,
                                  sizeof(PositionCovariance)) +
                               growth(d.beam_cov.size(), d.beam_cov.capacity(),
                                      double(d.beam_ends.size() - d.beam_cov.size()) + beams, sizeof(BeamCovariance))
                         : 0.0;
    const double motion_links =
        expected_kernel_ && correlation_ != InputCorrelation::kIndependent &&
                params_.preprocess.pose_fusion == PoseFusion::kExpectedKernel
            ? growth(d.hit_motion.size(), d.hit_motion.capacity(), double(d.hits.size() - d.hit_motion.size()) + hits,
                     sizeof(uint32_t)) +
                  growth(d.beam_motion.size(), d.beam_motion.capacity(),
                         double(d.beam_ends.size() - d.beam_motion.size()) + beams, sizeof(uint32_t))
            : 0.0;
    const double bytes = covariances + motion_links + copies * (growth(d.hits.size(), d.hits.capacity(), hits, sizeof(Vec3f)) +
                                   growth(d.beam_samples.size(), d.beam_samples.capacity(), samples, sizeof(Vec3f)) +
                                   growth(d.sample_beam.size(), d.sample_beam.capacity(), samples, sizeof(uint32_t)) +
                                   growth(d.beam_ends.size(), d.beam_ends.capacity(), beams, sizeof(Vec3f)) +
                                   growth(d.beam_origins.size(), d.beam_origins.capacity(), beams, sizeof(Vec3f)) +
                                   (hits + samples) * kTreeBytesPerPoint +
                                   (double(d.hits.size() + d.beam_samples.size()) + hits + samples) * kTreeIndexBytesPerPoint);
    require_memory(bytes,
                   "gpom's training points (scan " + std::to_string(counts_.scans + 1) + ": " +
                       std::to_string(obs_.hits.size()) + " hits and their beams' samples)",
                   "give a shorter --max-range or a coarser --ds (or raise --max-memory)");
  }

  double reach_m_ = 0, beam_step_m_ = 0;
  ScanPlane plane_;
  bool planar_ = false;
  bool warped_;
  bool learn_hyperparameters_ = false, hyperparameters_learned_ = false;
  std::optional<TanhWarp> warp_;  // wgpom: learned at the first evaluation unless given
  WarpLearning warp_learning_;
  GaussHermite quadrature_{kQuadratureNodes};
  double plane_z_ = 0;
  int32_t plane_cell_z_ = 0;

  // The training data: one set, or once a scan carries a pose covariance one per sigma point
  // (behind pointers: a built tree refers to its set's points, which must not move).
  std::vector<std::unique_ptr<TrainingData>> sets_;
  // The expected kernel: how the inputs' displacements are correlated (--gp-input-correlation);
  // unless independent, each uncertain scan's motion, and the most sigma points of one.
  enum class InputCorrelation { kIndependent, kScan, kTrajectory };
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
  std::optional<ExpectedKernel> kernel_;  // set at each evaluation while expected_kernel_

  std::vector<uint8_t> dirty_flag_;   // per slot
  std::vector<uint32_t> dirty_;       // slots to evaluate at the next flush
  std::vector<LooSample> loo_pool_;
  PlscParams plsc_;

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
