// Bayesian Hilbert maps' numerics (Senanayake & Ramos): RBF features on a regular grid of hinge
// points, a Gaussian posterior over their weights learned by variational Bayesian logistic
// regression with the Jaakkola-Jordan bound, updated scan by scan (the posterior after one scan is
// the prior of the next). Internal header of the bhm method (tests include it).
//
// Local blocks: the hinges are tiled into blocks of block_side^dims supports, and the variational
// posterior is restricted to a product of one full Gaussian per block, q(w) = prod_b N(mu_b, S_b)
// (weights of different blocks uncorrelated; the only approximation beside truncating each
// feature where it is below kFeatureCutoff). Each scan runs coordinate ascent on the same bound:
// a block's update holds the other blocks' means fixed. With every support in one block it is
// the exact full-covariance update. Only the blocks a scan's points reach are touched, so time
// and memory per scan do not grow with the map.
//
// Bias (BhmParams::bias): the paper's constant feature phi_0 = 1, one weight w_0 for the whole
// map. It is its own factor of q, q(w) = N(m_0, s_0) prod_b N(mu_b, S_b), updated after the
// blocks in each EM iteration by the same coordinate ascent (the other factors' means held).
//
// Free beams (2-D): a segment every point of which is free, standing for free points at
// `beam_density` per metre in the limit of dense sampling, all of one beam sharing one xi. Its
// bound is then exact in closed form: the beam's features are the line integrals
// g = int phi(x(t)) dt and its Gram matrix G = int phi phi^T dt (erf), q's update adds
// 2 density lambda G to the precision and -density g / 2 to the right-hand side, and
// xi^2 = tr(G (S + m m^T)) / length (the mean of E[a^2] along the beam).
#pragma once

#include <Eigen/Dense>

#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "bgkmap/core/grid.hpp"
#include "integrate/block_gram.hpp"
#include "map/block_store.hpp"

namespace bgkmap {

struct BhmParams {
  double spacing_m = 0.25;  // distance between neighbouring hinges
  double gamma = 20.0;      // RBF exp(-gamma |x - h|^2), 1/m^2
  double support_var = 0;   // > 0: Gaussian supports, each hinge spread as N(h, support_var I)
  double support_side = 0;  // > 0: rectangle supports, each hinge spread uniformly over a square
                            // (cube in 3-D) of this side centred on it; not with support_var
  double prior_var = 1.0;   // prior of every weight: N(0, prior_var)
  int em_iterations = 3;    // q updates per scan (each after a xi update)
  int block_side = 8;       // supports per block side (block_side^dims per block)
  int dims = 2;             // 2: hinges on the plane z = plane_z; 3: a 3-D grid
  double plane_z = 0;
  int threads = 1;
  bool elbo = false;        // compute each update's evidence lower bound (BhmUpdateStats::elbo)
  bool bias = false;        // a bias feature phi_0 = 1 (its own factor of q, coupled to every block); not with beams
};

// The paper's values (Senanayake & Ramos 2018, "Experiments"): w ~ N(0, 10^4 I), and for the Intel
// dataset G = 0.15 I in k = exp(-(x - h) G^-1 (x - h)^T), i.e. gamma = 1 / 0.15.
constexpr double kPaperBhmPriorVar = 1e4, kPaperBhmGamma = 1.0 / 0.15;

// The weights' prior variances taken: its inverse, the prior precision, is added to every block's
// Gram matrix, so past these it swamps the data or is lost to it (and overflows at the extremes).
constexpr double kMinBhmPriorVar = 1e-6, kMaxBhmPriorVar = 1e6;

// The Gram matrices one update sums in one go (blocks of one colour): 8,192 blocks of 64 supports,
// or one of 4096.
constexpr size_t kMaxGramBatchBytes = size_t(256) << 20;

// Features below this are dropped (the RBF's reach: exp(-gamma' r^2) = kFeatureCutoff).
constexpr double kFeatureCutoff = 1e-3;

// lambda(xi) = tanh(xi / 2) / (4 xi), its limit 1/8 at 0.
double jj_lambda(double xi);

struct BhmBeam {
  Vec3d from, to;  // every point of the segment is free
};

struct BhmLogit {
  double mean = 0, variance = 0;  // of a = phi(x)^T w under q
};

struct BhmUpdateStats {
  uint64_t rows = 0;          // (point, block) and (beam, support) pairs
  uint64_t blocks = 0;        // blocks updated
  // With BhmParams::elbo: the variational lower bound on log p(this scan's labels | the prior),
  // the prior being the posterior before the scan: at the final q, with every xi at its optimum
  // (xi^2 = E[a^2]),
  //   sum_n [(y_n - 1/2) E[a_n] + log sigma(xi_n) - xi_n / 2]
  //   + sum_beams density [-1/2 int E[a] dt + length (log sigma(xi) - xi / 2)]
  //   - sum_blocks KL(q_b || prior_b),
  // KL = 1/2 [tr(P0 S) + (m - m0)^T P0 (m - m0) - M + log|P| - log|P0|] (P = S^-1). Summed over
  // scans it bounds the log evidence of the whole sequence under the model's factorised q.
  double elbo = 0;
};

class BhmModel {
 public:
  // Throws std::invalid_argument on bad params. gram: where each block's Phi^T Lambda Phi and
  // Phi^T (y - 1/2) are summed (integrate/block_gram.hpp); null: the CPU engine with params.threads.
  explicit BhmModel(const BhmParams& params, std::shared_ptr<BlockGramEngine> gram = nullptr);

  const BhmParams& params() const { return p_; }
  int supports_per_block() const { return m_; }
  double reach_m() const { return reach_; }

  // One scan: points with labels 1 (occupied) or 0 (free), and free beams (2-D only) each standing
  // for beam_density free points per metre; em_iterations of (xi, q) updates.
  // fixed_xi (tests): use these xi (the points', then the beams'), one q update, instead of EM.
  BhmUpdateStats update(const std::vector<Vec3d>& points, const std::vector<double>& labels,
                        const std::vector<BhmBeam>& beams, double beam_density,
                        const std::vector<double>* fixed_xi = nullptr);
  BhmUpdateStats update(const std::vector<Vec3d>& points, const std::vector<double>& labels,
                        const std::vector<double>* fixed_xi = nullptr) {
    return update(points, labels, {}, 0.0, fixed_xi);
  }

  // What update(points, beams, ...) allocates beyond what the model holds, in bytes, bounded
  // before it starts (the --max-memory check); `reached`: the blocks the points reach (counted
  // exactly unless they are too many to mark, then bounded above).
  double update_bytes(const std::vector<Vec3d>& points, const std::vector<BhmBeam>& beams = {},
                      size_t* reached = nullptr) const;

  // The logit's mean and variance at x; nullopt where no block the features reach was touched.
  std::optional<BhmLogit> logit(const Vec3d& x) const;
  // sigma(mean / sqrt(1 + pi variance / 8)).
  static double probability(const BhmLogit& a);

  // One feature: phi_h(x) for the hinge at h, whatever the support's shape (no cutoff).
  double feature(const Vec3d& x, const Vec3d& hinge) const;
  // The features of x: (global support number within its block's key, value) per reached block.
  // Exposed for the dense reference in the tests: every nonzero feature of x, with its hinge.
  struct Feature {
    BlockKey block;
    int local;
    double value;
    Vec3d hinge;
  };
  void features(const Vec3d& x, std::vector<Feature>& out) const;

  // A beam's supports (those within the features' reach of the segment, in the plane) with their
  // line integrals, and the pairs (a, b) of them (indices into supports; a <= b, each once) closer
  // than twice the reach with int phi_a phi_b dt. Exposed for the tests' quadrature reference.
  struct BeamPair {
    uint32_t a, b;
    double value;
  };
  void beam_integrals(const BhmBeam& beam, std::vector<Feature>& supports, std::vector<BeamPair>& pairs) const;

  BackendInfo backend() const { return gram_->info(); }

  size_t block_count() const { return index_.size(); }
  const BlockKey& block_key(size_t i) const { return index_.key(static_cast<uint32_t>(i)); }
  const Eigen::VectorXd& block_mean(size_t i) const { return blocks_[i].mean; }
  const Eigen::MatrixXd& block_cov(size_t i) const { return blocks_[i].cov; }
  // The bias weight's factor N(mean, variance) (the prior while no scan has updated it).
  double bias_mean() const { return bias_mean_; }
  double bias_variance() const { return bias_var_; }
  // The block a block key names, or -1.
  int64_t find_block(const BlockKey& key) const;
  // Where block key's hinges are: hinge (i, j, k) of the grid is at (i, j, k) * spacing.
  Vec3d hinge_position(const BlockKey& block, int local) const;

 private:
  struct Block {
    Eigen::VectorXd mean;
    Eigen::MatrixXd cov, precision;
  };
  class Update;  // one scan's update (bhm/bhm_update.cpp)
  uint32_t ensure_block(const BlockKey& key);
  // Hinge index range per axis reached from x.
  void hinge_range(const Vec3d& x, int32_t lo[3], int32_t hi[3]) const;
  double feature_value(double squared_distance) const { return amplitude_ * std::exp(-gamma_eff_ * squared_distance); }
  // A rectangle support's factor along one axis at offset delta from its hinge: the RBF's mean
  // over [-side/2, side/2], sqrt(pi) / (2 sqrt(gamma) side) [erf(sqrt(gamma)(delta + side/2)) -
  // erf(sqrt(gamma)(delta - side/2))].
  double rectangle_factor(double delta) const;

  BhmParams p_;
  double bias_mean_ = 0, bias_var_ = 1;  // with p_.bias; bias_var_ starts at prior_var
  int m_ = 0;              // supports per block
  double gamma_eff_ = 0, amplitude_ = 1, reach_ = 0;
  BlockIndex index_;  // block key -> number in blocks_
  std::vector<Block> blocks_;
  std::shared_ptr<BlockGramEngine> gram_;
};

}  // namespace bgkmap
