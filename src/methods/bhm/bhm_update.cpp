// One scan's variational update of a Bayesian Hilbert map (BhmModel::update): the rows of every
// block the scan's points and beams reach, then EM over the blocks, colour by colour.
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

#include "core/parallel_errors.hpp"
#include "methods/bhm/bhm_model.hpp"

namespace bgkmap {

namespace {

// The rows one block sees in one scan: for each (point, block) pair, its nonzero features.
struct BlockRows {
  uint32_t block = 0;
  std::vector<uint32_t> point;       // row -> point
  std::vector<uint32_t> begin{0};    // row -> first entry; begin[rows] = entries
  std::vector<int> local;            // entry -> support within the block
  std::vector<double> value;         // entry -> feature value
  std::vector<double> mean, var;     // row -> this block's part of the logit's mean and variance
  std::vector<double> old_mean;      // mean before this colour's update
  Eigen::VectorXd next_mean;         // this colour's new mean, committed once all its blocks are done
  // Free beams: the beams reaching this block (in scan order), their supports here with the line
  // integrals g, and their Gram entries G(u, v) for u here (other: the touched block of v; -1 here).
  struct Pair {
    int u, v;
    int32_t other;
    double value;
  };
  std::vector<uint32_t> beam;
  std::vector<uint32_t> g_begin, pair_begin;  // beam entry -> first g / pair; one past the last at the end
  std::vector<int> g_local;
  std::vector<double> g_value;
  std::vector<Pair> pairs;
  std::vector<double> beam_moment;    // beam entry -> this block's part of int E[a^2] dt
  Eigen::VectorXd prior_rhs;         // P0 mu0 (the scan's prior)
  Eigen::MatrixXd prior_precision;   // P0
  Eigen::VectorXd prior_mean;        // mu0 (for the ELBO)
  double log_det_precision = 0;      // log |P| of the last q update (for the ELBO)
  int colour = 0;
  size_t rows() const { return point.size(); }
};

}  // namespace

class BhmModel::Update {
 public:
  Update(BhmModel& model, const std::vector<Vec3d>& points, const std::vector<double>& labels,
         const std::vector<BhmBeam>& beams, double density, const std::vector<double>* fixed_xi)
      : model_(model), p_(model.p_), m_(model.m_), blocks_(model.blocks_), points_(points), labels_(labels),
        beams_(beams), density_(density), fixed_xi_(fixed_xi) {}

  BhmUpdateStats run() {
    integrate_beams();
    touched_of_.assign(blocks_.size(), -1);
    add_point_rows();
    add_beam_rows();
    close_rows();
    order_gram_rows();
    logit_mean_.assign(points_.size(), 0.0);
    logit_var_.assign(points_.size(), 0.0);
    lambda_.resize(points_.size());
    beam_moment_.assign(beams_.size(), 0.0);
    beam_lambda_.resize(beams_.size());
    const int64_t touched = static_cast<int64_t>(rows_.size());
#pragma omp parallel for schedule(dynamic) num_threads(p_.threads)
    for (int64_t t = 0; t < touched; ++t) refresh_rows(rows_[t]);
    bias_prior_precision_ = 1.0 / model_.bias_var_;
    bias_prior_mean_ = model_.bias_mean_;
    sum_rows(true);
    const int iterations = fixed_xi_ ? 1 : p_.em_iterations;
    for (int it = 0; it < iterations; ++it) {
      e_step();
      for (int c = 0; c < colours(); ++c) m_step(c);
      if (p_.bias) bias_step();
      sum_rows(it + 1 < iterations || (p_.elbo && !beams_.empty()));  // the beams' moments for an E step or the ELBO
    }
    if (p_.elbo) stats_.elbo = elbo();
    return stats_;
  }

 private:
  int colours() const { return p_.dims == 2 ? 4 : 8; }

  // The beams' line integrals first, in parallel: an exp and two erf per (beam, support) and per pair.
  void integrate_beams() {
    const int64_t beam_count = static_cast<int64_t>(beams_.size());
    beam_supports_.resize(beams_.size());
    beam_pairs_.resize(beams_.size());
    beam_length_.resize(beams_.size());
#pragma omp parallel for schedule(dynamic, 4) num_threads(p_.threads)
    for (int64_t k = 0; k < beam_count; ++k)
      errors_.run([&] {
        model_.beam_integrals(beams_[k], beam_supports_[k], beam_pairs_[k]);
        beam_length_[k] = std::hypot(beams_[k].to.x - beams_[k].from.x, beams_[k].to.y - beams_[k].from.y);
      });
    errors_.rethrow();
  }

  // The rows of block `key` (made, with the block, at its first touch).
  int32_t touch(const BlockKey& key) {
    const uint32_t b = model_.ensure_block(key);
    if (b >= touched_of_.size()) touched_of_.resize(b + 1, -1);
    if (touched_of_[b] < 0) {
      touched_of_[b] = static_cast<int32_t>(rows_.size());
      rows_.emplace_back();
      rows_.back().block = b;
    }
    return touched_of_[b];
  }

  // Rows per touched block, points in order (a counting sort of (block, point, entry) by block).
  void add_point_rows() {
    std::vector<BhmModel::Feature> f;
    for (uint32_t p = 0; p < points_.size(); ++p) {
      model_.features(points_[p], f);
      for (const BhmModel::Feature& feature : f) {
        BlockRows& r = rows_[touch(feature.block)];
        if (r.point.empty() || r.point.back() != p) {
          if (!r.point.empty()) r.begin.push_back(static_cast<uint32_t>(r.local.size()));
          r.point.push_back(p);
        }
        r.local.push_back(feature.local);
        r.value.push_back(feature.value);
      }
    }
  }

  void add_beam_rows() {
    std::vector<int32_t> support_row;
    for (uint32_t k = 0; k < beams_.size(); ++k) {
      support_row.resize(beam_supports_[k].size());
      for (size_t a = 0; a < beam_supports_[k].size(); ++a) {
        const BhmModel::Feature& support = beam_supports_[k][a];
        const int32_t t = support_row[a] = touch(support.block);
        BlockRows& r = rows_[t];
        if (r.beam.empty() || r.beam.back() != k) {
          r.beam.push_back(k);
          r.g_begin.push_back(static_cast<uint32_t>(r.g_local.size()));
          r.pair_begin.push_back(static_cast<uint32_t>(r.pairs.size()));
        }
        r.g_local.push_back(support.local);
        r.g_value.push_back(support.value);
      }
      for (const BhmModel::BeamPair& pair : beam_pairs_[k]) {
        const int32_t ta = support_row[pair.a], tb = support_row[pair.b];
        const int ua = beam_supports_[k][pair.a].local, ub = beam_supports_[k][pair.b].local;
        rows_[ta].pairs.push_back({ua, ub, ta == tb ? -1 : tb, pair.value});
        if (pair.a != pair.b) rows_[tb].pairs.push_back({ub, ua, ta == tb ? -1 : ta, pair.value});
      }
    }
  }

  // Ends every block's rows and takes its prior (the posterior before this scan) and colour.
  void close_rows() {
    for (BlockRows& r : rows_) {
      r.begin.push_back(static_cast<uint32_t>(r.local.size()));
      r.g_begin.push_back(static_cast<uint32_t>(r.g_local.size()));
      r.pair_begin.push_back(static_cast<uint32_t>(r.pairs.size()));
      r.mean.assign(r.rows(), 0.0);
      r.var.assign(r.rows(), 0.0);
      r.beam_moment.assign(r.beam.size(), 0.0);
      const Block& block = blocks_[r.block];
      r.prior_precision = block.precision;
      r.prior_rhs = block.precision * block.mean;
      if (p_.elbo) r.prior_mean = block.mean;
      const BlockKey& k = model_.index_.key(r.block);
      r.colour = (k.x & 1) | ((k.y & 1) << 1) | ((k.z & 1) << 2);
      stats_.rows += r.rows() + r.g_local.size();
    }
    stats_.blocks = rows_.size();
  }

  // This block's part of each row's logit mean and variance under the current q.
  void refresh_rows(BlockRows& r) const {
    const Block& block = blocks_[r.block];
    for (size_t row = 0; row < r.rows(); ++row) {
      double mean = 0, var = 0;
      for (uint32_t u = r.begin[row]; u < r.begin[row + 1]; ++u) {
        mean += r.value[u] * block.mean[r.local[u]];
        double inner = 0;
        for (uint32_t v = r.begin[row]; v < r.begin[row + 1]; ++v) inner += r.value[v] * block.cov(r.local[u], r.local[v]);
        var += r.value[u] * inner;
      }
      r.mean[row] = mean;
      r.var[row] = var;
    }
  }

  // This block's part of each beam's int E[a^2] dt under the current q.
  void refresh_beam_moments(BlockRows& r) const {
    const Block& block = blocks_[r.block];
    for (size_t e = 0; e < r.beam.size(); ++e) {
      double moment = 0;
      for (uint32_t q = r.pair_begin[e]; q < r.pair_begin[e + 1]; ++q) {
        const BlockRows::Pair& pair = r.pairs[q];
        const double other_mean = pair.other < 0 ? block.mean[pair.v] : blocks_[rows_[pair.other].block].mean[pair.v];
        moment += pair.value * ((pair.other < 0 ? block.cov(pair.u, pair.v) : 0.0) + block.mean[pair.u] * other_mean);
      }
      r.beam_moment[e] = moment;
    }
  }

  // The point rows of every touched block, blocks by colour (colour_begin_[c] is colour c's first),
  // for the Gram engine; gram_row_[t]: block t's first row there.
  void order_gram_rows() {
    colour_begin_.assign(colours() + 1, 0);
    gram_row_.resize(rows_.size());
    gram_rows_.m = m_;
    for (int c = 0; c < colours(); ++c) {
      colour_begin_[c] = static_cast<uint32_t>(gram_order_.size());
      for (size_t t = 0; t < rows_.size(); ++t) {
        if (rows_[t].colour != c) continue;
        const BlockRows& r = rows_[t];
        gram_order_.push_back(static_cast<uint32_t>(t));
        gram_row_[t] = static_cast<uint32_t>(gram_rows_.rows());
        for (size_t row = 0; row < r.rows(); ++row)
          gram_rows_.row_begin.push_back(gram_rows_.row_begin.back() + (r.begin[row + 1] - r.begin[row]));
        gram_rows_.column.insert(gram_rows_.column.end(), r.local.begin(), r.local.end());
        gram_rows_.value.insert(gram_rows_.value.end(), r.value.begin(), r.value.end());
        gram_rows_.block_row_begin.push_back(static_cast<uint32_t>(gram_rows_.rows()));
      }
    }
    colour_begin_[colours()] = static_cast<uint32_t>(gram_order_.size());
    model_.gram_->set_rows(gram_rows_);
    gram_weight_.resize(gram_rows_.rows());
    gram_target_.resize(gram_rows_.rows());
  }

  // Every point's logit mean and variance summed over its blocks; with `beam_moments`, the beams'.
  void sum_rows(bool beam_moments) {
    std::fill(logit_mean_.begin(), logit_mean_.end(), p_.bias ? model_.bias_mean_ : 0.0);
    std::fill(logit_var_.begin(), logit_var_.end(), p_.bias ? model_.bias_var_ : 0.0);
    for (const BlockRows& r : rows_)
      for (size_t row = 0; row < r.rows(); ++row) {
        logit_mean_[r.point[row]] += r.mean[row];
        logit_var_[r.point[row]] += r.var[row];
      }
    if (beams_.empty() || !beam_moments) return;
    const int64_t touched = static_cast<int64_t>(rows_.size());
#pragma omp parallel for schedule(dynamic) num_threads(p_.threads)
    for (int64_t t = 0; t < touched; ++t) refresh_beam_moments(rows_[t]);
    std::fill(beam_moment_.begin(), beam_moment_.end(), 0.0);
    for (const BlockRows& r : rows_)
      for (size_t e = 0; e < r.beam.size(); ++e) beam_moment_[r.beam[e]] += r.beam_moment[e];
  }

  // E: xi^2 = E[a^2] under the current q (a beam's: its mean along the beam).
  void e_step() {
    for (size_t p = 0; p < points_.size(); ++p)
      lambda_[p] = jj_lambda(fixed_xi_ ? (*fixed_xi_)[p] : std::sqrt(logit_var_[p] + logit_mean_[p] * logit_mean_[p]));
    for (size_t k = 0; k < beams_.size(); ++k)
      beam_lambda_[k] = jj_lambda(fixed_xi_ ? (*fixed_xi_)[points_.size() + k]
                                            : std::sqrt(std::max(0.0, beam_moment_[k]) / std::max(beam_length_[k], 1e-12)));
  }

  // M: blocks of one colour (no two of them reached by one point when the reach is at most a
  // block's side) together, the colours in turn, each seeing the others' newest means. A colour's
  // new means are committed after all its blocks are solved, so none reads a half-written one.
  void m_step(int c) {
    const uint32_t first = colour_begin_[c], last = colour_begin_[c + 1];
    if (first == last) return;
    // A point's row in block b: weight 2 lambda, target y - 1/2 - 2 lambda (the other blocks'
    // part of its logit mean).
    for (uint32_t g = first; g < last; ++g) {
      const BlockRows& r = rows_[gram_order_[g]];
      for (size_t row = 0; row < r.rows(); ++row) {
        const uint32_t p = r.point[row];
        const double two_lambda = 2.0 * lambda_[p];
        gram_weight_[gram_row_[gram_order_[g]] + row] = two_lambda;
        gram_target_[gram_row_[gram_order_[g]] + row] = labels_[p] - 0.5 - two_lambda * (logit_mean_[p] - r.mean[row]);
      }
    }
    // The colour's Gram matrices in batches of at most kMaxGramBatchBytes (one block at least).
    const size_t mm = size_t(m_) * size_t(m_);
    const uint32_t batch = static_cast<uint32_t>(std::max<size_t>(1, kMaxGramBatchBytes / (mm * sizeof(double))));
    for (uint32_t b0 = first; b0 < last; b0 += batch) {
      const uint32_t b1 = std::min(last, b0 + batch);
      gram_.resize((b1 - b0) * mm);
      gram_rhs_.resize((b1 - b0) * size_t(m_));
      model_.gram_->accumulate(b0, b1, gram_weight_, gram_target_, gram_.data(), gram_rhs_.data());
#pragma omp parallel for schedule(dynamic) num_threads(p_.threads)
      for (int64_t g = b0; g < int64_t{b1}; ++g)
        errors_.run([&] {
          update_block(rows_[gram_order_[g]], gram_.data() + (g - b0) * mm, gram_rhs_.data() + (g - b0) * size_t(m_));
        });
      errors_.rethrow();
    }
    commit_colour(c);
  }

  // q_b given its point rows' sums (gram, rhs: 2 Phi^T Lambda Phi and the targets' Phi^T t) and,
  // for beams, lambda and the other blocks' means.
  void update_block(BlockRows& r, const double* gram_b, const double* rhs_b) {
    Eigen::MatrixXd precision = r.prior_precision + Eigen::Map<const Eigen::MatrixXd>(gram_b, m_, m_);
    Eigen::VectorXd rhs = r.prior_rhs + Eigen::Map<const Eigen::VectorXd>(rhs_b, m_);
    for (size_t e = 0; e < r.beam.size(); ++e) {
      const double weight = 2.0 * density_ * beam_lambda_[r.beam[e]];
      for (uint32_t q = r.g_begin[e]; q < r.g_begin[e + 1]; ++q) rhs[r.g_local[q]] -= 0.5 * density_ * r.g_value[q];
      for (uint32_t q = r.pair_begin[e]; q < r.pair_begin[e + 1]; ++q) {
        const BlockRows::Pair& pair = r.pairs[q];
        if (pair.other < 0) precision(pair.u, pair.v) += weight * pair.value;
        else rhs[pair.u] -= weight * pair.value * blocks_[rows_[pair.other].block].mean[pair.v];
      }
    }
    const Eigen::LLT<Eigen::MatrixXd> llt(precision);
    if (llt.info() != Eigen::Success) throw std::runtime_error("bhm: a block's posterior precision is not positive definite");
    Block& block = blocks_[r.block];
    if (p_.elbo) r.log_det_precision = 2.0 * llt.matrixLLT().diagonal().array().log().sum();
    r.next_mean = llt.solve(rhs);
    block.cov = llt.solve(Eigen::MatrixXd::Identity(m_, m_));
    block.precision = std::move(precision);
  }

  // The colour's new means into its blocks, and its rows' parts of the logit means with them.
  void commit_colour(int c) {
    const int64_t touched = static_cast<int64_t>(rows_.size());
#pragma omp parallel for schedule(dynamic) num_threads(p_.threads)
    for (int64_t t = 0; t < touched; ++t)
      if (rows_[t].colour == c)
        errors_.run([&] {
          BlockRows& r = rows_[t];
          blocks_[r.block].mean.swap(r.next_mean);
          r.old_mean = r.mean;
          refresh_rows(r);
        });
    errors_.rethrow();
    for (const BlockRows& r : rows_)
      if (r.colour == c)
        for (size_t row = 0; row < r.rows(); ++row) logit_mean_[r.point[row]] += r.mean[row] - r.old_mean[row];
  }

  // q_0 of the bias given the blocks' means (the M step of a block with the one feature 1):
  // precision P0 + 2 sum lambda_n, mean (P0 m0 + sum [y_n - 1/2 - 2 lambda_n (E[a_n] - m_0)]) / precision.
  void bias_step() {
    const double old_mean = model_.bias_mean_;
    double precision = bias_prior_precision_, rhs = bias_prior_precision_ * bias_prior_mean_;
    for (size_t p = 0; p < points_.size(); ++p) {
      precision += 2.0 * lambda_[p];
      rhs += labels_[p] - 0.5 - 2.0 * lambda_[p] * (logit_mean_[p] - old_mean);
    }
    model_.bias_mean_ = rhs / precision;
    model_.bias_var_ = 1.0 / precision;
    for (double& a : logit_mean_) a += model_.bias_mean_ - old_mean;
  }

  // KL(q_0 || prior_0) of the bias.
  double bias_kl() const {
    const double d = model_.bias_mean_ - bias_prior_mean_;
    return 0.5 * (bias_prior_precision_ * model_.bias_var_ + bias_prior_precision_ * d * d - 1.0 -
                  std::log(model_.bias_var_ * bias_prior_precision_));
  }

  // The evidence lower bound at the final q (BhmUpdateStats::elbo).
  double elbo() {
    // log sigma(xi) - xi / 2 at xi = sqrt(E[a^2]), where the bound's lambda term vanishes.
    const auto log_sigmoid_minus_half = [](double xi) { return -std::log1p(std::exp(-xi)) - 0.5 * xi; };
    double elbo = 0;
    for (size_t p = 0; p < points_.size(); ++p)
      elbo += (labels_[p] - 0.5) * logit_mean_[p] +
              log_sigmoid_minus_half(std::sqrt(std::max(0.0, logit_var_[p] + logit_mean_[p] * logit_mean_[p])));
    std::vector<double> beam_mean(beams_.size(), 0.0);  // int E[a] dt
    for (const BlockRows& r : rows_)
      for (size_t e = 0; e < r.beam.size(); ++e)
        for (uint32_t q = r.g_begin[e]; q < r.g_begin[e + 1]; ++q)
          beam_mean[r.beam[e]] += r.g_value[q] * blocks_[r.block].mean[r.g_local[q]];
    for (size_t k = 0; k < beams_.size(); ++k) {
      const double length = std::max(beam_length_[k], 1e-12);
      elbo += density_ * (-0.5 * beam_mean[k] +
                          length * log_sigmoid_minus_half(std::sqrt(std::max(0.0, beam_moment_[k]) / length)));
    }
    for (double k : block_kl()) elbo -= k;
    if (p_.bias) elbo -= bias_kl();
    return elbo;
  }

  // Per touched block, KL(q_b || prior_b).
  std::vector<double> block_kl() {
    const int64_t touched = static_cast<int64_t>(rows_.size());
    std::vector<double> kl(rows_.size(), 0.0);
#pragma omp parallel for schedule(dynamic) num_threads(p_.threads)
    for (int64_t t = 0; t < touched; ++t)
      errors_.run([&] {
        const BlockRows& r = rows_[t];
        const Block& block = blocks_[r.block];
        const Eigen::LLT<Eigen::MatrixXd> prior(r.prior_precision);
        const double log_det_prior = 2.0 * prior.matrixLLT().diagonal().array().log().sum();
        const Eigen::VectorXd d = block.mean - r.prior_mean;
        kl[t] = 0.5 * (r.prior_precision.cwiseProduct(block.cov).sum() + d.dot(r.prior_precision * d) - m_ +
                       r.log_det_precision - log_det_prior);
      });
    errors_.rethrow();
    return kl;
  }

  BhmModel& model_;
  const BhmParams& p_;
  const int m_;
  std::vector<Block>& blocks_;
  const std::vector<Vec3d>& points_;
  const std::vector<double>& labels_;
  const std::vector<BhmBeam>& beams_;
  const double density_;
  const std::vector<double>* fixed_xi_;
  BhmUpdateStats stats_;
  ParallelErrors errors_;
  double bias_prior_precision_ = 1, bias_prior_mean_ = 0;  // the bias's prior for this scan

  std::vector<std::vector<BhmModel::Feature>> beam_supports_;  // per beam
  std::vector<std::vector<BhmModel::BeamPair>> beam_pairs_;
  std::vector<double> beam_length_;
  std::vector<int32_t> touched_of_;  // per block of the model: its rows in rows_, or -1
  std::vector<BlockRows> rows_;      // per touched block
  // Local to the update: the engines read the rows only within this update's calls.
  BlockGramRows gram_rows_;
  std::vector<uint32_t> gram_order_, colour_begin_, gram_row_;
  std::vector<double> gram_weight_, gram_target_, gram_, gram_rhs_;
  std::vector<double> logit_mean_, logit_var_, lambda_;  // per point
  std::vector<double> beam_moment_, beam_lambda_;        // per beam
};

BhmUpdateStats BhmModel::update(const std::vector<Vec3d>& points, const std::vector<double>& labels,
                                const std::vector<BhmBeam>& beams, double beam_density,
                                const std::vector<double>* fixed_xi) {
  if (points.empty() && beams.empty()) return {};
  if (!beams.empty() && p_.dims != 2) throw std::invalid_argument("bhm: free beams are for 2-D maps only");
  if (!beams.empty() && !(beam_density > 0)) throw std::invalid_argument("bhm: beam density must be > 0");
  if (!beams.empty() && p_.bias) throw std::invalid_argument("bhm: a bias with free beams is not implemented");
  if (!beams.empty() && p_.support_side > 0)
    throw std::invalid_argument("bhm: free beams need RBF or Gaussian supports, not rectangles");
  return Update(*this, points, labels, beams, beam_density, fixed_xi).run();
}

}  // namespace bgkmap
