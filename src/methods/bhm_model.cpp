#include "methods/bhm_model.hpp"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>


namespace bgkmap {

namespace {

constexpr int kMaxSupportsPerBlock = 4096;  // two dense 4096^2 matrices: 268 MB per block

// The rows one block sees in one scan: for each (point, block) pair, its nonzero features.
struct BlockRows {
  uint32_t block = 0;
  std::vector<uint32_t> point;       // row -> point
  std::vector<uint32_t> begin{0};    // row -> first entry; begin[rows] = entries
  std::vector<int> local;            // entry -> support within the block
  std::vector<double> value;         // entry -> feature value
  std::vector<double> mean, var;     // row -> this block's part of the logit's mean and variance
  std::vector<double> old_mean;      // mean before this colour's update
  Eigen::VectorXd prior_rhs;         // P0 mu0 (the scan's prior)
  Eigen::MatrixXd prior_precision;   // P0
  int colour = 0;
  size_t rows() const { return point.size(); }
};

}  // namespace

double jj_lambda(double xi) {
  xi = std::abs(xi);
  if (xi < 1e-6) return 0.125 - xi * xi / 96.0;  // Taylor: tanh(x/2)/(4x) = 1/8 - x^2/96 + ...
  return std::tanh(0.5 * xi) / (4.0 * xi);
}

double BhmModel::probability(const BhmLogit& a) {
  const double kappa = 1.0 / std::sqrt(1.0 + M_PI * a.variance / 8.0);
  return 1.0 / (1.0 + std::exp(-kappa * a.mean));
}

BhmModel::BhmModel(const BhmParams& params) : p_(params) {
  if (!(p_.spacing_m > 0)) throw std::invalid_argument("bhm-spacing must be > 0");
  if (!(p_.gamma > 0)) throw std::invalid_argument("bhm-gamma must be > 0");
  if (!(p_.support_var >= 0)) throw std::invalid_argument("bhm-support-var must be >= 0");
  if (!(p_.prior_var > 0)) throw std::invalid_argument("bhm-prior-var must be > 0");
  if (p_.em_iterations < 1) throw std::invalid_argument("bhm-em-iterations must be >= 1");
  if (p_.dims != 2 && p_.dims != 3) throw std::invalid_argument("bhm: dims must be 2 or 3");
  if (p_.block_side < 1) throw std::invalid_argument("bhm-block-side must be >= 1");
  const double supports = std::pow(double(p_.block_side), p_.dims);
  if (supports > kMaxSupportsPerBlock)
    throw std::invalid_argument("bhm-block-side " + std::to_string(p_.block_side) + " gives " +
                                std::to_string(int64_t(supports)) + " supports per block in " +
                                std::to_string(p_.dims) + "-D; at most " + std::to_string(kMaxSupportsPerBlock) +
                                " (two dense covariance-sized matrices per block)");
  m_ = static_cast<int>(supports);
  // E over h ~ N(h0, s I) of exp(-gamma |x - h|^2) = (1 + 2 gamma s)^(-d/2) exp(-gamma |x - h0|^2 / (1 + 2 gamma s)).
  const double spread = 1.0 + 2.0 * p_.gamma * p_.support_var;
  gamma_eff_ = p_.gamma / spread;
  amplitude_ = std::pow(spread, -0.5 * p_.dims);
  reach_ = amplitude_ > kFeatureCutoff ? std::sqrt(std::log(amplitude_ / kFeatureCutoff) / gamma_eff_) : 0.0;
  if (p_.threads < 1) p_.threads = 1;
}

void BhmModel::hinge_range(const Vec3d& x, int32_t lo[3], int32_t hi[3]) const {
  const double c[3] = {x.x, x.y, x.z};
  for (int a = 0; a < 3; ++a) {
    if (a == 2 && p_.dims == 2) {
      lo[a] = hi[a] = 0;
      continue;
    }
    lo[a] = static_cast<int32_t>(std::ceil((c[a] - reach_) / p_.spacing_m));
    hi[a] = static_cast<int32_t>(std::floor((c[a] + reach_) / p_.spacing_m));
  }
}

Vec3d BhmModel::hinge_position(const BlockKey& block, int local) const {
  const int s = p_.block_side;
  const int32_t i = block.x * s + local % s, j = block.y * s + (local / s) % s;
  if (p_.dims == 2) return {i * p_.spacing_m, j * p_.spacing_m, p_.plane_z};
  const int32_t k = block.z * s + local / (s * s);
  return {i * p_.spacing_m, j * p_.spacing_m, k * p_.spacing_m};
}

void BhmModel::features(const Vec3d& x, std::vector<Feature>& out) const {
  out.clear();
  int32_t lo[3], hi[3];
  hinge_range(x, lo, hi);
  const int s = p_.block_side;
  const double r2 = reach_ * reach_;
  for (int32_t k = lo[2]; k <= hi[2]; ++k) {
    const double dz = p_.dims == 2 ? 0.0 : x.z - k * p_.spacing_m;
    for (int32_t j = lo[1]; j <= hi[1]; ++j) {
      const double dy = x.y - j * p_.spacing_m;
      for (int32_t i = lo[0]; i <= hi[0]; ++i) {
        const double dx = x.x - i * p_.spacing_m;
        const double d2 = dx * dx + dy * dy + dz * dz;
        if (d2 > r2) continue;
        const BlockKey block{floor_div(i, s), floor_div(j, s), p_.dims == 2 ? 0 : floor_div(k, s)};
        const int local = (i - block.x * s) + s * ((j - block.y * s) + s * (k - block.z * s));
        out.push_back({block, local, feature_value(d2),
                       {i * p_.spacing_m, j * p_.spacing_m, p_.dims == 2 ? p_.plane_z : k * p_.spacing_m}});
      }
    }
  }
}

int64_t BhmModel::find_block(const BlockKey& key) const {
  const uint32_t b = index_.find(key);
  return b == BlockIndex::kAbsent ? -1 : int64_t{b};
}

uint32_t BhmModel::ensure_block(const BlockKey& key) {
  return index_.find_or_insert(key, [&] {
    Block block;  // the prior N(0, prior_var I)
    block.mean = Eigen::VectorXd::Zero(m_);
    block.cov = Eigen::MatrixXd::Identity(m_, m_) * p_.prior_var;
    block.precision = Eigen::MatrixXd::Identity(m_, m_) / p_.prior_var;
    blocks_.push_back(std::move(block));
  });
}

std::optional<BhmLogit> BhmModel::logit(const Vec3d& x) const {
  thread_local std::vector<Feature> f;
  features(x, f);
  BhmLogit a;
  bool known = false;
  std::vector<bool> done(f.size(), false);
  for (size_t i = 0; i < f.size(); ++i) {
    if (done[i]) continue;
    const int64_t b = find_block(f[i].block);
    // The features of this block: i and every later one with the same key.
    std::vector<size_t> same;
    for (size_t j = i; j < f.size(); ++j)
      if (!done[j] && f[j].block == f[i].block) {
        same.push_back(j);
        done[j] = true;
      }
    if (b < 0) {  // never updated: the prior N(0, prior_var I)
      for (size_t j : same) a.variance += p_.prior_var * f[j].value * f[j].value;
      continue;
    }
    known = true;
    const Block& block = blocks_[b];
    for (size_t u : same) {
      a.mean += f[u].value * block.mean[f[u].local];
      for (size_t v : same) a.variance += f[u].value * f[v].value * block.cov(f[u].local, f[v].local);
    }
  }
  if (!known) return std::nullopt;
  return a;
}

BhmUpdateStats BhmModel::update(const std::vector<Vec3d>& points, const std::vector<double>& labels,
                                const std::vector<double>* fixed_xi) {
  BhmUpdateStats stats;
  if (points.empty()) return stats;
  // Rows per touched block, points in order (a counting sort of (block, point, entry) by block).
  std::vector<int32_t> touched_of(blocks_.size(), -1);
  std::vector<BlockRows> rows;
  std::vector<Feature> f;
  for (uint32_t p = 0; p < points.size(); ++p) {
    features(points[p], f);
    for (const Feature& feature : f) {
      const uint32_t b = ensure_block(feature.block);
      if (b >= touched_of.size()) touched_of.resize(b + 1, -1);
      if (touched_of[b] < 0) {
        touched_of[b] = static_cast<int32_t>(rows.size());
        rows.emplace_back();
        rows.back().block = b;
      }
      BlockRows& r = rows[touched_of[b]];
      if (r.point.empty() || r.point.back() != p) {
        if (!r.point.empty()) r.begin.push_back(static_cast<uint32_t>(r.local.size()));
        r.point.push_back(p);
      }
      r.local.push_back(feature.local);
      r.value.push_back(feature.value);
    }
  }
  const int64_t touched = static_cast<int64_t>(rows.size());
  for (BlockRows& r : rows) {
    r.begin.push_back(static_cast<uint32_t>(r.local.size()));
    r.mean.assign(r.rows(), 0.0);
    r.var.assign(r.rows(), 0.0);
    const Block& block = blocks_[r.block];
    r.prior_precision = block.precision;
    r.prior_rhs = block.precision * block.mean;
    const BlockKey& k = index_.key(r.block);
    r.colour = (k.x & 1) | ((k.y & 1) << 1) | ((k.z & 1) << 2);
    stats.rows += r.rows();
  }
  stats.blocks = rows.size();

  // This block's part of each row's logit mean and variance under its current q.
  const auto refresh_rows = [&](BlockRows& r) {
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
  };
  // q_b given lambda and the other blocks' means (logit_mean - this block's part).
  const auto update_block = [&](BlockRows& r, const std::vector<double>& lambda, const std::vector<double>& logit_mean) {
    Eigen::MatrixXd precision = r.prior_precision;
    Eigen::VectorXd rhs = r.prior_rhs;
    for (size_t row = 0; row < r.rows(); ++row) {
      const uint32_t p = r.point[row];
      const double two_lambda = 2.0 * lambda[p];
      const double target = labels[p] - 0.5 - two_lambda * (logit_mean[p] - r.mean[row]);
      for (uint32_t u = r.begin[row]; u < r.begin[row + 1]; ++u) {
        rhs[r.local[u]] += r.value[u] * target;
        const double scaled = two_lambda * r.value[u];
        for (uint32_t v = r.begin[row]; v < r.begin[row + 1]; ++v) precision(r.local[v], r.local[u]) += scaled * r.value[v];
      }
    }
    const Eigen::LLT<Eigen::MatrixXd> llt(precision);
    if (llt.info() != Eigen::Success) throw std::runtime_error("bhm: a block's posterior precision is not positive definite");
    Block& block = blocks_[r.block];
    block.mean = llt.solve(rhs);
    block.cov = llt.solve(Eigen::MatrixXd::Identity(m_, m_));
    block.precision = std::move(precision);
    refresh_rows(r);
  };

  std::vector<double> logit_mean(points.size(), 0.0), logit_var(points.size(), 0.0), lambda(points.size());
#pragma omp parallel for schedule(dynamic) num_threads(p_.threads)
  for (int64_t t = 0; t < touched; ++t) refresh_rows(rows[t]);
  const auto sum_rows = [&]() {
    std::fill(logit_mean.begin(), logit_mean.end(), 0.0);
    std::fill(logit_var.begin(), logit_var.end(), 0.0);
    for (const BlockRows& r : rows)
      for (size_t row = 0; row < r.rows(); ++row) {
        logit_mean[r.point[row]] += r.mean[row];
        logit_var[r.point[row]] += r.var[row];
      }
  };
  sum_rows();
  const int iterations = fixed_xi ? 1 : p_.em_iterations;
  const int colours = p_.dims == 2 ? 4 : 8;
  for (int it = 0; it < iterations; ++it) {
    // E: xi^2 = E[a^2] = Var(a) + E[a]^2 under the current q.
    for (size_t p = 0; p < points.size(); ++p)
      lambda[p] = jj_lambda(fixed_xi ? (*fixed_xi)[p] : std::sqrt(logit_var[p] + logit_mean[p] * logit_mean[p]));
    // M: blocks of one colour (no two of them reached by one point when the reach is at most a
    // block's side) together, the colours in turn, each seeing the others' newest means.
    for (int c = 0; c < colours; ++c) {
#pragma omp parallel for schedule(dynamic) num_threads(p_.threads)
      for (int64_t t = 0; t < touched; ++t)
        if (rows[t].colour == c) {
          rows[t].old_mean = rows[t].mean;
          update_block(rows[t], lambda, logit_mean);
        }
      for (const BlockRows& r : rows)
        if (r.colour == c)
          for (size_t row = 0; row < r.rows(); ++row) logit_mean[r.point[row]] += r.mean[row] - r.old_mean[row];
    }
    sum_rows();
  }
  return stats;
}

}  // namespace bgkmap
